//! Voxel global illumination on a headless Bevy app (lavapipe here), read back and held against its CPU
//! twin.

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy_hao::cpu::VoxelAttributes;
use bevy_hao::cpu::lighting::{Light, unpack_rgb9e5, voxel_radiance};
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;

const SIZE: UVec2 = UVec2::new(64, 48);

#[derive(Component)]
struct Bulb;

/// A room of parts in their colours: a floor, a roof over half of it, a box on the floor and a red wall; a
/// sun, a point light under the roof and a spot light; a camera with voxel GI.
fn lit_room(volume: VoxelVolume, lighting_frames: u32) -> App {
    headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                commands.spawn(volume);
                let mut part = |size: Vec3, at: Vec3, color: Color| {
                    commands.spawn((
                        Mesh3d(meshes.add(Cuboid::from_size(size))),
                        MeshMaterial3d(materials.add(StandardMaterial { base_color: color, ..default() })),
                        Transform::from_translation(at),
                        StaticOccluder,
                    ));
                };
                part(Vec3::new(6.0, 0.2, 6.0), Vec3::new(0.0, -2.1, 0.0), Color::srgb(0.8, 0.8, 0.8));
                part(Vec3::new(3.0, 0.2, 6.0), Vec3::new(-1.5, 0.1, 0.0), Color::srgb(0.7, 0.7, 0.7));
                part(Vec3::new(0.8, 0.8, 0.8), Vec3::new(1.2, -1.6, 0.6), Color::srgb(0.2, 0.3, 0.9));
                part(Vec3::new(0.2, 3.0, 6.0), Vec3::new(2.9, -0.5, 0.0), Color::srgb(0.9, 0.1, 0.1));
                commands.spawn((
                    DirectionalLight { illuminance: 10_000.0, color: Color::srgb(1.0, 0.95, 0.9), ..default() },
                    Transform::default().looking_to(Vec3::new(0.8, -1.5, 0.4), Vec3::Y),
                ));
                commands.spawn((
                    PointLight { intensity: 200_000.0, range: 8.0, color: Color::srgb(1.0, 0.6, 0.3), ..default() },
                    Transform::from_xyz(-1.5, -0.8, 1.0),
                    Bulb,
                ));
                commands.spawn((
                    SpotLight { intensity: 400_000.0, range: 10.0, inner_angle: 0.25, outer_angle: 0.5, ..default() },
                    Transform::from_xyz(1.0, 2.5, -1.5).looking_at(Vec3::new(1.2, -2.0, -1.0), Vec3::Y),
                ));
                let color = target_image(&mut images, SIZE);
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(color.into()),
                    Transform::from_xyz(0.0, 1.0, 3.5).looking_at(Vec3::new(0.0, -1.5, 0.0), Vec3::Y),
                    VoxelGlobalIllumination { lighting_frames },
                ));
            },
        );
    })
}

/// The lights of the app's world as the plugin extracts them (Bevy's components: linear colour, a light's
/// forward the way its light travels).
fn world_lights(app: &mut App) -> Vec<Light> {
    let linear = |c: Color| {
        let l = c.to_linear();
        Vec3::new(l.red, l.green, l.blue)
    };
    let world = app.world_mut();
    let mut lights = Vec::new();
    for (l, t) in world.query::<(&DirectionalLight, &GlobalTransform)>().iter(world) {
        lights.push(Light::Directional {
            direction: t.forward().as_vec3(),
            color: linear(l.color),
            illuminance: l.illuminance,
        });
    }
    for (l, t) in world.query::<(&PointLight, &GlobalTransform)>().iter(world) {
        lights.push(Light::Point {
            position: t.translation(),
            color: linear(l.color),
            intensity: l.intensity,
            range: l.range,
        });
    }
    for (l, t) in world.query::<(&SpotLight, &GlobalTransform)>().iter(world) {
        lights.push(Light::Spot {
            position: t.translation(),
            direction: t.forward().as_vec3(),
            color: linear(l.color),
            intensity: l.intensity,
            range: l.range,
            inner_angle: l.inner_angle,
            outer_angle: l.outer_angle,
        });
    }
    lights
}

/// What the lighting volume holds against its CPU twin: how many occupied voxels were compared, how many
/// are lit, how many agree, and the largest difference among those that agree (relative to the larger
/// channel).
struct Parity {
    voxels: u32,
    lit: u32,
    agree: u32,
    worst: f32,
}

/// Reads the grid (its levels, attributes and the lighting volume) back and holds every occupied voxel's
/// radiance against `cpu::lighting::voxel_radiance` with the GPU's own attributes (as their textures hold
/// them) and the world's lights.
fn lighting_parity(app: &mut App) -> Parity {
    let grid = grid_assets(app).expect("a voxel grid");
    let gi = app.world().get_resource::<bevy_hao::GiAssets>().cloned().expect("voxel GI's assets");
    let [albedo_image, normal_image] = grid.attributes.clone().expect("attributes kept for GI");
    // The lighting volume first, as the next frame leaves it; the scene's voxels do not change after.
    let (w, h, radiance_texel, radiance) = read_image(app, gi.radiance, 0);
    let voxels = read_trace_voxels(app);
    let levels = trace_levels(&voxels);
    let (_, _, texel, albedo) = read_image(app, albedo_image, 0);
    let (_, _, _, normal) = read_image(app, normal_image, 0);
    assert_eq!((texel, radiance_texel), (4, 4));
    let lights = world_lights(app);
    let windows: Vec<IVec3> = match grid.cascades {
        Some(_) => stats(app).cascades.iter().map(|c| c.window_min).collect(),
        None => vec![IVec3::ZERO],
    };
    let size = grid.texture_size;
    let mut p = Parity { voxels: 0, lit: 0, agree: 0, worst: 0.0 };
    for (l, level) in levels.iter().enumerate() {
        let dims = level.mips.dims();
        let wrap = windows[l].rem_euclid(dims.as_ivec3()).as_uvec3();
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let cell = UVec3::new(x, y, z);
                    let stored = (cell + wrap) % dims + UVec3::new(0, 0, l as u32 * size.z);
                    let t = (((stored.z * h + stored.y) * w + stored.x) * 4) as usize;
                    let gpu = unpack_rgb9e5(u32::from_le_bytes(radiance[t..t + 4].try_into().unwrap()));
                    if !level.mips.occupied(cell.as_ivec3()) {
                        assert_eq!(gpu, Vec3::ZERO, "level {l} cell {cell}: an empty voxel is unlit");
                        continue;
                    }
                    let a = &albedo[t..t + 4];
                    let n = &normal[t..t + 4];
                    let snorm = |b: u8| (b as i8).max(-127) as f32 / 127.0;
                    let attributes = VoxelAttributes {
                        albedo: Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32) / 255.0,
                        normal: Vec3::new(snorm(n[0]), snorm(n[1]), snorm(n[2])),
                    };
                    let cpu = voxel_radiance(&levels, l, cell.as_ivec3(), &attributes, &lights);
                    p.voxels += 1;
                    p.lit += (cpu.max_element() > 0.0) as u32;
                    // rgb9e5 keeps 1/512 of the largest channel; the rest is the GPU's rounding.
                    let scale = cpu.max_element().max(gpu.max_element()).max(1.0e-6);
                    let d = (gpu - cpu).abs().max_element() / scale;
                    if d <= 4.0 / 512.0 {
                        p.agree += 1;
                        p.worst = p.worst.max(d);
                    }
                }
            }
        }
    }
    p
}

/// The lighting volume on the GPU equals its CPU twin voxel for voxel, in one grid and in cascades (which
/// store their windows toroidally): every occupied voxel's radiance under a sun, a point light and a spot,
/// shadows included, from the voxels' own albedo and normal, within rgb9e5's precision, but for a few whose
/// shadow rays graze an occluder; empty voxels hold nothing. A light taken away leaves the voxels within
/// `lighting_frames` frames.
#[test]
fn the_lighting_volume_on_the_gpu_equals_its_cpu_twin() {
    let _gpu = gpu_lock();
    let single = VoxelVolume {
        bounds: VolumeBounds::World { min: Vec3::splat(-4.0), max: Vec3::splat(4.0) },
        resolution: VolumeResolution::Cells(64),
        ..default()
    };
    let cascades = VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: 2, cells: 32, finest_cell_size: 0.125 },
        ..default()
    };
    for (name, volume) in [("one grid", single), ("cascades", cascades)] {
        let lighting_frames = 3;
        let mut app = lit_room(volume, lighting_frames);
        run(&mut app, 10);
        let p = lighting_parity(&mut app);
        println!(
            "{name}: {} occupied voxels, {} lit by the CPU twin, {} within rgb9e5's precision of it (largest {:.5})",
            p.voxels, p.lit, p.agree, p.worst
        );
        assert!(p.voxels > 2_000 && p.lit * 4 > p.voxels, "{name}: {} voxels, {} lit", p.voxels, p.lit);
        assert!(p.agree * 1000 >= p.voxels * 995, "{name}: {} of {} voxels agree", p.agree, p.voxels);
        // The point light goes: within `lighting_frames` frames its light has left every voxel.
        let mut bulbs = app.world_mut().query_filtered::<Entity, With<Bulb>>();
        let bulb = bulbs.single(app.world()).unwrap();
        app.world_mut().despawn(bulb);
        run(&mut app, lighting_frames as usize - 1);
        let after = lighting_parity(&mut app);
        println!("{name}, the bulb gone: {} of {} voxels agree", after.agree, after.voxels);
        assert!(after.lit < p.lit, "{name}: {} lit with the bulb, {} without", p.lit, after.lit);
        assert!(after.agree * 1000 >= after.voxels * 995, "{name}: {} of {} agree", after.agree, after.voxels);
        assert!(take_render_errors().is_empty());
    }
}
