//! The plugin and nothing else: a camera with `HybridAmbientOcclusion`, a floor and a few pillars that
//! never move (`StaticOccluder`: voxelized once), and a sphere that does (`DynamicOccluder`: voxelized every
//! frame), whose occlusion follows it across the floor.
//!
//! ```sh
//! cargo run --release --example basic
//! ```

use bevy::prelude::*;
use bevy_hao::prelude::*;

fn main() {
    App::new().add_plugins((DefaultPlugins, HaoPlugin)).add_systems(Startup, setup).add_systems(Update, roll).run();
}

#[derive(Component)]
struct Rolling;

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    // Adding the component is enough: it brings the depth and normal prepasses (the camera keeps Bevy's
    // default MSAA). The voxel volume defaults to cascades following this camera.
    commands.spawn((
        Camera3d::default(),
        HybridAmbientOcclusion::default(),
        Transform::from_xyz(0.0, 5.0, 9.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let white = materials.add(Color::WHITE);
    commands.spawn((Mesh3d(meshes.add(Cuboid::new(12.0, 0.2, 12.0))), MeshMaterial3d(white.clone()), StaticOccluder));
    for x in [-3.0, 0.0, 3.0] {
        commands.spawn((
            Mesh3d(meshes.add(Cuboid::new(0.6, 3.0, 0.6))),
            MeshMaterial3d(white.clone()),
            Transform::from_xyz(x, 1.5, -2.0),
            StaticOccluder,
        ));
    }
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.8))),
        MeshMaterial3d(white),
        Transform::from_xyz(0.0, 0.9, 1.0),
        DynamicOccluder,
        Rolling,
    ));
    // AO dims indirect light only: ambient light shows it, the sun's direct light does not.
    commands.insert_resource(bevy::light::GlobalAmbientLight { brightness: 800.0, ..default() });
    commands.spawn((
        DirectionalLight { illuminance: 2000.0, ..default() },
        Transform::from_xyz(2.0, 6.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
}

fn roll(time: Res<Time>, mut spheres: Query<&mut Transform, With<Rolling>>) {
    for mut t in &mut spheres {
        t.translation.x = 3.5 * (time.elapsed_secs() * 0.6).sin();
    }
}
