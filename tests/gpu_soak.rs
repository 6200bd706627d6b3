//! Soak: hundreds of frames of voxelization work after warm-up, with the process's resident memory and the
//! device's allocations held flat. Three workloads, each run for `FRAMES` frames: a dynamic occluder that
//! moves every frame (a new dirty box and a new dynamic pass each frame); the same seen by a moving camera
//! (new view uniforms, scrolling cascades); and occluders spawned and despawned every ten frames with meshes
//! made fresh each time (mesh allocator slabs, instance buffers and static rebuilds come and go).
//!
//! The bound: resident memory may grow by at most `RSS_BOUND_MB` between the median of the first and the
//! last `WINDOW` samples of a workload (one sample per frame), and the bytes the device has allocated
//! (wgpu's allocator report) must end where they started, within `GPU_BOUND_MB`. A leak of the size this
//! test was written against (2 MB per frame on Mesa lavapipe) grows resident memory by 600 MB here.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::renderer::RenderDevice;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;
use bevy_hao_tools::meshes::builtin;

const WARMUP: usize = 60;
const FRAMES: usize = 300;
const WINDOW: usize = 40;
const RSS_BOUND_MB: f64 = 24.0;
const GPU_BOUND_MB: f64 = 4.0;

/// Resident memory of this process in MiB (Linux: /proc/self/statm).
fn resident_mb() -> f64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("the soak test reads /proc/self/statm (Linux)");
    let pages: f64 = statm.split_whitespace().nth(1).and_then(|s| s.parse().ok()).expect("statm's resident field");
    pages * 4096.0 / (1024.0 * 1024.0)
}

/// Bytes the device has allocated, in MiB, if the backend reports them.
fn device_allocated_mb(app: &mut App) -> Option<f64> {
    let render = app.sub_app(bevy::render::RenderApp);
    let device = render.world().resource::<RenderDevice>();
    device.wgpu_device().generate_allocator_report().map(|r| r.total_allocated_bytes as f64 / (1024.0 * 1024.0))
}

#[derive(Component)]
struct Mover;

#[derive(Component)]
struct Transient;

fn app() -> App {
    headless_app(|app| {
        app.add_systems(
            Startup,
            |mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut images: ResMut<Assets<Image>>| {
                commands.spawn(VoxelVolume {
                    bounds: VolumeBounds::FollowCamera { cascades: 2, cells: 32, finest_cell_size: 0.25 },
                    ..default()
                });
                let floor = builtin::cuboid(Vec3::new(-8.0, -0.2, -8.0), Vec3::new(8.0, 0.0, 8.0));
                commands.spawn((Mesh3d(meshes.add(bevy_mesh(&floor, Layout::U32))), StaticOccluder));
                let ball = builtin::sphere(0.8, 24, 12);
                commands.spawn((
                    Mesh3d(meshes.add(bevy_mesh(&ball, Layout::U16WithAttributes))),
                    Transform::from_xyz(0.0, 1.0, 0.0),
                    DynamicOccluder,
                    Mover,
                ));
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target_image(&mut images, UVec2::new(64, 48)).into()),
                    Msaa::Off,
                    Tonemapping::None,
                    HybridAmbientOcclusion::default(),
                    Transform::from_xyz(0.0, 3.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
            },
        );
    })
}

/// Moves the ball along a circle (a new position, so a new dirty box, every frame).
fn move_ball(app: &mut App, frame: usize) {
    let a = frame as f32 * 0.07;
    let mut q = app.world_mut().query_filtered::<&mut Transform, With<Mover>>();
    for mut t in q.iter_mut(app.world_mut()) {
        t.translation = Vec3::new(3.0 * a.cos(), 1.0 + 0.5 * (3.0 * a).sin(), 3.0 * a.sin());
    }
}

/// Moves the camera back and forth along x by 12 m (new view uniforms every frame, and cascade windows
/// that scroll).
fn move_camera(app: &mut App, frame: usize) {
    let x = 6.0 * (frame as f32 * 0.05).sin();
    let mut q = app.world_mut().query_filtered::<&mut Transform, With<Camera3d>>();
    for mut t in q.iter_mut(app.world_mut()) {
        *t = Transform::from_xyz(x, 3.0, 6.0).looking_at(Vec3::new(x, 0.0, 0.0), Vec3::Y);
    }
}

/// Every ten frames: despawns the transient occluders and spawns new ones, each with a mesh made for it
/// (alternately static and dynamic, so that static rebuilds come and go too).
fn cycle_transients(app: &mut App, frame: usize) {
    if !frame.is_multiple_of(10) {
        return;
    }
    let world = app.world_mut();
    let old: Vec<Entity> = world.query_filtered::<Entity, With<Transient>>().iter(world).collect();
    for e in old {
        world.despawn(e);
    }
    let cycle = frame / 10;
    for k in 0..3 {
        let x = -4.0 + 4.0 * k as f32;
        let mesh = builtin::torus(0.6 + 0.05 * (cycle % 5) as f32, 0.2, 16 + (cycle % 3) as u32 * 4, 8);
        let handle = world.resource_mut::<Assets<Mesh>>().add(bevy_mesh(&mesh, Layout::U32));
        let mut e = world.spawn((Mesh3d(handle), Transform::from_xyz(x, 0.8, -3.0), Transient));
        if (cycle + k).is_multiple_of(2) {
            e.insert(StaticOccluder);
        } else {
            e.insert(DynamicOccluder);
        }
    }
}

fn median_of(v: &[f64]) -> f64 {
    median(v.to_vec()).unwrap_or(f64::NAN)
}

/// Runs one workload: warm-up, then `FRAMES` frames sampling resident memory after each.
fn soak(name: &str, step: fn(&mut App, usize)) {
    let _gpu = gpu_lock();
    let mut app = app();
    for frame in 0..WARMUP {
        step(&mut app, frame);
        app.update();
    }
    let gpu_before = device_allocated_mb(&mut app);
    let voxelized_before = stats(&app).frames_voxelized;
    let mut rss = Vec::with_capacity(FRAMES);
    for frame in WARMUP..WARMUP + FRAMES {
        step(&mut app, frame);
        app.update();
        rss.push(resident_mb());
    }
    let gpu_after = device_allocated_mb(&mut app);
    let voxelized = stats(&app).frames_voxelized - voxelized_before;
    let errors = take_render_errors();
    assert!(errors.is_empty(), "{name}: render errors: {errors:?}");
    // The workload must have voxelized in most measured frames, or it measures nothing (with the moving
    // camera the ball is sometimes outside every cascade, and there is nothing to voxelize).
    assert!(voxelized as usize >= FRAMES * 3 / 4, "{name}: voxelized in only {voxelized} of {FRAMES} frames");
    let first = median_of(&rss[..WINDOW]);
    let last = median_of(&rss[rss.len() - WINDOW..]);
    println!(
        "{name}: resident {first:.1} -> {last:.1} MiB over {FRAMES} frames ({:+.3} MiB/frame); device {gpu_before:?} -> {gpu_after:?} MiB",
        (last - first) / (FRAMES - WINDOW) as f64
    );
    assert!(
        last - first <= RSS_BOUND_MB,
        "{name}: resident memory grew {:.1} MiB over {FRAMES} frames (bound {RSS_BOUND_MB} MiB)",
        last - first
    );
    let (Some(before), Some(after)) = (gpu_before, gpu_after) else {
        panic!("{name}: the device gave no allocator report, so its allocations cannot be held flat");
    };
    assert!(
        (after - before).abs() <= GPU_BOUND_MB,
        "{name}: device allocations went from {before:.1} to {after:.1} MiB (bound {GPU_BOUND_MB} MiB)"
    );
}

#[test]
fn moving_dynamic_occluder_keeps_memory_flat() {
    soak("moving occluder", move_ball);
}

#[test]
fn moving_camera_keeps_memory_flat() {
    soak("moving camera", |app, frame| {
        move_ball(app, frame);
        move_camera(app, frame);
    });
}

#[test]
fn spawn_despawn_cycles_keep_memory_flat() {
    soak("spawn/despawn", |app, frame| {
        move_ball(app, frame);
        cycle_transients(app, frame);
    });
}
