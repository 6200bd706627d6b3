//! Static and dynamic occluders side by side: the built-in cathedral (static, voxelized once) with objects
//! that move, and others that appear and vanish, marked `DynamicOccluder` (voxelized every frame on top of
//! the cached static grid).
//!
//! ```text
//! cargo run --release --example dynamic -- [--view final|ao|voxels|counts|static-dynamic|cascades]
//!     [--headless --frames 90 --screenshot OUT.png [--size 960x540]]
//! ```
//!
//! Watch the occlusion under the rolling spheres and the sliding box move with them, and the shadows of the
//! falling crates appear and vanish; `--view static-dynamic` shows static voxels blue and dynamic ones orange.
//! In a window the inspector shows that the static grid is rebuilt once while the dynamic pass runs every
//! frame. Time advances 1/30 s per frame, so headless runs are reproducible.
//!
//! Skinned meshes (animated characters) are not voxelized yet: the plugin skips them with a warning (Bevy
//! skins in the vertex shader, and the voxelizer reads the bind pose from the mesh slabs).

mod support;

use bevy::camera::RenderTarget;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hao::prelude::*;
use support::scene::{SceneSource, spawn_scene, sun};

#[derive(Component)]
struct Orbit {
    radius: f32,
    speed: f32,
    phase: f32,
    height: f32,
}

#[derive(Component)]
struct Slide;

#[derive(Component)]
struct Crate {
    age: f32,
}

#[derive(Resource)]
struct Assets3d {
    cube: Handle<Mesh>,
    material: Handle<StandardMaterial>,
}

#[derive(Resource)]
struct ScreenshotTarget(Handle<Image>);

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    server: Res<AssetServer>,
    target: Option<Res<ScreenshotTarget>>,
    view: Res<ViewChoice>,
) {
    spawn_scene(&SceneSource::Builtin("cathedral".into()), &mut commands, &mut meshes, &mut materials, &server)
        .expect("built-in scene");
    // The default volume (cascades following the camera), with point counts for the heat map view.
    commands.spawn(VoxelVolume { point_counts: true, ..default() });
    commands.spawn(sun());
    let red = materials.add(StandardMaterial { base_color: Color::srgb(0.7, 0.2, 0.15), ..default() });
    let sphere = meshes.add(Sphere::new(0.8).mesh().uv(32, 16));
    for k in 0..3 {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(red.clone()),
            Transform::default(),
            DynamicOccluder,
            Orbit { radius: 3.0, speed: 0.6, phase: k as f32 * std::f32::consts::TAU / 3.0, height: 0.8 },
        ));
    }
    let cube = meshes.add(Cuboid::new(1.0, 1.0, 1.0));
    let wood = materials.add(StandardMaterial { base_color: Color::srgb(0.55, 0.4, 0.25), ..default() });
    commands.spawn((
        Mesh3d(cube.clone()),
        MeshMaterial3d(wood.clone()),
        Transform::from_xyz(-9.0, 0.75, 0.0).with_scale(Vec3::new(1.5, 1.5, 3.0)),
        DynamicOccluder,
        Slide,
    ));
    commands.insert_resource(Assets3d { cube, material: wood });
    let mut camera = commands.spawn((
        Camera3d::default(),
        Msaa::Off,
        Transform::from_xyz(3.5, 4.5, 9.0).looking_at(Vec3::new(-2.0, 0.5, -1.0), Vec3::Y),
        HybridAmbientOcclusion::default(),
        view.0,
    ));
    if let Some(target) = target {
        camera.insert(RenderTarget::Image(target.0.clone().into()));
    }
}

#[derive(Resource, Clone, Copy)]
struct ViewChoice(HaoDebugView);

fn animate(
    time: Res<Time>,
    mut orbits: Query<(&mut Transform, &Orbit)>,
    mut slides: Query<&mut Transform, (With<Slide>, Without<Orbit>)>,
) {
    let t = time.elapsed_secs();
    for (mut transform, o) in &mut orbits {
        let a = o.phase + t * o.speed;
        transform.translation = Vec3::new(a.cos() * o.radius, o.height, a.sin() * o.radius - 2.0);
    }
    for mut transform in &mut slides {
        transform.translation.z = (t * 0.5).sin() * 8.0;
    }
}

/// Drops a crate every second and despawns each after three.
fn crates(
    mut commands: Commands,
    time: Res<Time>,
    assets: Res<Assets3d>,
    mut crates: Query<(Entity, &mut Transform, &mut Crate)>,
    mut timer: Local<f32>,
    mut count: Local<u32>,
) {
    *timer += time.delta_secs();
    if *timer >= 1.0 {
        *timer -= 1.0;
        *count += 1;
        let x = ((*count * 37) % 9) as f32 - 4.0;
        commands.spawn((
            Mesh3d(assets.cube.clone()),
            MeshMaterial3d(assets.material.clone()),
            Transform::from_xyz(x, 6.0, 6.0 + ((*count * 53) % 5) as f32),
            DynamicOccluder,
            Crate { age: 0.0 },
        ));
    }
    for (entity, mut transform, mut c) in &mut crates {
        c.age += time.delta_secs();
        transform.translation.y = (6.0 - 4.9 * c.age * c.age).max(0.5);
        if c.age > 3.0 {
            commands.entity(entity).despawn();
        }
    }
}

fn main() {
    let mut view = HaoDebugView::Final;
    let (mut headless, mut frames, mut screenshot, mut size) = (false, 90usize, None, UVec2::new(960, 540));
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--view" => {
                view = match it.next().as_deref() {
                    Some("final") => HaoDebugView::Final,
                    Some("ao") => HaoDebugView::AmbientOcclusion,
                    Some("voxels") => HaoDebugView::Voxels,
                    Some("counts") => HaoDebugView::PointCounts,
                    Some("static-dynamic") => HaoDebugView::StaticDynamic,
                    Some("cascades") => HaoDebugView::Cascades,
                    v => {
                        eprintln!("unknown --view {v:?}");
                        std::process::exit(2);
                    }
                }
            }
            "--headless" => headless = true,
            "--frames" => frames = it.next().and_then(|v| v.parse().ok()).expect("--frames N"),
            "--screenshot" => screenshot = it.next(),
            "--size" => {
                size = support::args::size(&it.next().unwrap_or_default()).unwrap_or_else(|e| {
                    eprintln!("{e}");
                    std::process::exit(2)
                })
            }
            _ => {
                eprintln!(
                    "usage: dynamic [--view final|ao|voxels|counts|static-dynamic|cascades] [--headless --frames 90 --screenshot OUT.png [--size 960x540]]"
                );
                std::process::exit(2);
            }
        }
    }
    let configure = move |app: &mut App| {
        app.insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.95, 0.93, 0.88),
            brightness: 700.0,
            ..default()
        })
        .insert_resource(ClearColor(Color::srgb(0.55, 0.68, 0.85)))
        .insert_resource(TimeUpdateStrategy::ManualDuration(std::time::Duration::from_secs_f32(1.0 / 30.0)))
        .insert_resource(ViewChoice(view))
        .add_systems(Startup, setup)
        .add_systems(Update, (animate, crates));
    };
    if headless {
        let Some(out) = screenshot else {
            eprintln!("--headless needs --screenshot OUT.png");
            std::process::exit(2);
        };
        let mut app = support::headless_app(|app| {
            let target = support::target_image(&mut app.world_mut().resource_mut::<Assets<Image>>(), size);
            app.insert_resource(ScreenshotTarget(target));
            configure(app);
        });
        support::run(&mut app, frames);
        let target = app.world().resource::<ScreenshotTarget>().0.clone();
        if let Err(e) = support::save_screenshot(&mut app, target, &out) {
            eprintln!("error: no screenshot ({e})");
            std::process::exit(1);
        }
        let s = support::stats(&app);
        println!(
            "wrote {out}: static grid built {} times in {frames} frames; {} dynamic instances ({} triangles) this frame",
            s.static_rebuilds, s.dynamic_instances, s.dynamic_triangles
        );
        return;
    }
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window { title: "bevy_hao: dynamic occluders".into(), ..default() }),
            ..default()
        }),
        HaoPlugin,
        bevy_hao::inspector::HaoInspectorPlugin,
    ));
    configure(&mut app);
    app.run();
}
