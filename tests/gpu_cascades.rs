//! Camera-following cascades on a headless Bevy app (lavapipe here): what scrolls, what is rebuilt, and
//! every cascade level held voxel for voxel against a fresh CPU voxelization of its window.

use bevy::math::Affine3A;
use bevy::prelude::*;
use bevy_hao::cpu::{self, TriangleMesh, VoxelOccupancy, voxelize_mesh_in_region};
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;
use bevy_hao_tools::meshes::builtin;

const CELLS: u32 = 32;
const FINEST: f32 = 0.25;
const LEVELS: u32 = 3;

fn cascades() -> VoxelVolume {
    VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: LEVELS, cells: CELLS, finest_cell_size: FINEST },
        ..default()
    }
}

#[derive(Component)]
struct TheCamera;

/// A corridor along x, 80 m long: floor, two walls, a roof with gaps, pillars every 4 m, a rotated torus
/// every 10 m; each part its own static entity (world-space vertices, identity transforms) so that the
/// CPU reference sees the same triangles.
fn corridor() -> Vec<TriangleMesh> {
    let mut parts = vec![
        builtin::cuboid(Vec3::new(-40.0, -0.2, -2.0), Vec3::new(40.0, 0.0, 2.0)),
        builtin::cuboid(Vec3::new(-40.0, 0.0, -2.3), Vec3::new(40.0, 3.0, -2.0)),
        builtin::cuboid(Vec3::new(-40.0, 0.0, 2.0), Vec3::new(40.0, 3.0, 2.3)),
    ];
    for k in 0..20 {
        let x = -40.0 + 4.0 * k as f32;
        parts.push(builtin::cuboid(Vec3::new(x + 0.2, 3.0, -2.3), Vec3::new(x + 3.0, 3.2, 2.3)));
        parts.push(builtin::cylinder(Vec3::new(x + 1.1, 0.0, 1.3), 0.3, 3.0, 10));
    }
    for k in 0..8 {
        let m = builtin::torus(0.6, 0.2, 20, 8);
        let t = Affine3A::from_rotation_translation(
            Quat::from_euler(EulerRot::XYZ, 0.4 + k as f32, 0.7, -0.2),
            Vec3::new(-35.0 + 10.0 * k as f32, 1.2, -0.8),
        );
        parts.push(TriangleMesh::new(m.positions.iter().map(|p| t.transform_point3(*p)).collect(), m.triangles));
    }
    parts
}

fn app_with(parts: Vec<TriangleMesh>, camera_x: f32) -> App {
    headless_app(move |app| {
        app.add_systems(Startup, move |mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>| {
            commands.spawn(cascades());
            for mesh in &parts {
                commands.spawn((Mesh3d(meshes.add(bevy_mesh(mesh, Layout::U32))), StaticOccluder));
            }
            spawn_camera(&mut commands, camera_x);
        });
    })
}

/// The camera the cascades follow, at `x` along the corridor, looking down it.
fn spawn_camera(commands: &mut Commands, x: f32) {
    commands.spawn((
        Camera3d::default(),
        HybridAmbientOcclusion::default(),
        Transform::from_xyz(x, 1.6, 0.0).looking_to(Vec3::X, Vec3::Y),
        TheCamera,
    ));
}

fn move_camera(app: &mut App, to: Vec3) {
    let mut q = app.world_mut().query_filtered::<&mut Transform, With<TheCamera>>();
    q.single_mut(app.world_mut()).unwrap().translation = to;
}

/// Every level's static occupancy, against a fresh CPU voxelization of the level's window (which must not
/// be empty). Returns the set voxels per level.
fn assert_levels_equal_cpu(app: &mut App, parts: &[TriangleMesh]) -> Vec<u64> {
    assert_levels_equal_cpu_with_solids(app, parts, &[]).0
}

/// The same, with `solids` voxelized and then filled (`VoxelFill::Solid`); also returns the voxels the CPU
/// filled, per level.
fn assert_levels_equal_cpu_with_solids(
    app: &mut App,
    parts: &[TriangleMesh],
    solids: &[TriangleMesh],
) -> (Vec<u64>, Vec<u64>) {
    let settings = grid_assets(app).unwrap().settings;
    let levels = read_cascades(app, true);
    assert_eq!(levels.len(), LEVELS as usize);
    let mut counts = Vec::new();
    let mut filled = Vec::new();
    for (l, r) in levels.iter().enumerate() {
        let level = cpu::CascadeLevel {
            origin: r.level.origin,
            cell_size: r.level.cell_size,
            cells: CELLS,
            window_min: r.level.window_min,
        };
        let cpu = VoxelOccupancy::new(r.grid, false);
        for mesh in parts.iter().chain(solids) {
            voxelize_mesh_in_region(mesh, level.grid_from_world(), &settings, &level.region(), &cpu);
        }
        let mut level_filled = 0;
        for mesh in solids {
            level_filled += cpu::fill_solid_in_region(mesh, level.grid_from_world(), &level.region(), &cpu).filled;
        }
        filled.push(level_filled);
        let (only_gpu, only_cpu) = (r.occupancy.count_not_in(&cpu), cpu.count_not_in(&r.occupancy));
        let set = cpu.set_voxel_count();
        println!(
            "level {l} (cell {}, window at {}): {set} voxels on the CPU, {only_gpu} only on the GPU, {only_cpu} only on the CPU",
            r.level.cell_size, r.level.window_min
        );
        assert!(set > 0, "level {l} is empty");
        // Float ties at cell faces (fused multiply-adds on the GPU) may move a voxel in 10^4.
        assert!((only_gpu + only_cpu) * 10_000 <= set.max(1000), "level {l}: {only_gpu} + {only_cpu} of {set} differ");
        counts.push(set);
    }
    (counts, filled)
}

#[test]
fn a_camera_walking_down_a_corridor_voxelizes_only_the_slabs_it_enters() {
    let _gpu = gpu_lock();
    let parts = corridor();
    let mut app = app_with(parts.clone(), 0.0);
    run(&mut app, 6);
    let start = stats(&app);
    assert_eq!(start.cascades.len(), LEVELS as usize);
    for (l, c) in start.cascades.iter().enumerate() {
        assert_eq!(c.rebuilds, 1, "level {l} is built once at the start");
        assert_eq!(c.cell_size, FINEST * (1 << l) as f32);
    }
    // Walk 20 m at 0.25 m a frame (running speed at 60 frames a second is 0.1 m a frame: this is faster).
    let whole = (CELLS as u64).pow(3);
    let mut voxelized = vec![0u64; LEVELS as usize];
    for step in 1..=80 {
        move_camera(&mut app, Vec3::new(step as f32 * 0.25, 1.6, 0.0));
        app.update();
        let s = stats(&app);
        for (l, c) in s.cascades.iter().enumerate() {
            assert_eq!(c.rebuilds, 1, "level {l} was rebuilt at step {step}");
            // A slab one scroll step thick at most (the camera never moves a step in one frame here).
            assert!(c.static_cells_last_frame <= whole / CELLS as u64 * 8, "level {l}: {}", c.static_cells_last_frame);
            voxelized[l] += c.static_cells_last_frame;
        }
    }
    let s = stats(&app);
    for (l, c) in s.cascades.iter().enumerate() {
        // 20 m is 80, 40 and 20 cells: whole scroll steps of 8 cells, each a slab of 8 x 32 x 32.
        let expected = (20.0 / c.cell_size / 8.0).floor() as u64;
        println!(
            "level {l}: {} scrolls, {} cells voxelized ({} per scroll)",
            c.scrolls,
            voxelized[l],
            whole / CELLS as u64 * 8
        );
        assert!(
            c.scrolls >= expected.saturating_sub(1) && c.scrolls <= expected + 1,
            "level {l}: {} scrolls",
            c.scrolls
        );
        assert_eq!(voxelized[l], c.scrolls * whole / CELLS as u64 * 8);
    }
    // What scrolled in equals a fresh voxelization of every window.
    assert_levels_equal_cpu(&mut app, &parts);
    assert!(take_render_errors().is_empty());
}

#[test]
fn a_far_static_entity_waits_for_its_region_and_a_teleport_rebuilds_once() {
    let _gpu = gpu_lock();
    let mut parts = corridor();
    let mut app = app_with(parts.clone(), 0.0);
    // A second camera with HAO, rendered after the first: the cascades follow the first (lowest order).
    app.world_mut().spawn((
        Camera3d::default(),
        Camera { order: 1, ..default() },
        HybridAmbientOcclusion::default(),
        Transform::from_xyz(-30.0, 1.6, 0.0),
    ));
    run(&mut app, 6);
    let level0 = stats(&app).cascades[0];
    let centre = (level0.window_min.as_vec3() + Vec3::splat(CELLS as f32 / 2.0)) * level0.cell_size;
    assert!(centre.x.abs() <= 8.0 * FINEST, "the cascades follow the first camera: centred at {centre}");
    // A building 300 m away, spawned now: nothing to voxelize (it is in no window).
    let far = builtin::cuboid(Vec3::new(296.0, 0.0, -4.0), Vec3::new(304.0, 6.0, 4.0));
    let mesh = bevy_mesh(&far, Layout::U16WithAttributes);
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let far_entity = app.world_mut().spawn((Mesh3d(handle), StaticOccluder)).id();
    parts.push(far);
    run(&mut app, 2);
    let s = stats(&app);
    for (l, c) in s.cascades.iter().enumerate() {
        assert_eq!(c.static_cells_last_frame, 0, "level {l} did work for an entity outside it");
        assert_eq!(c.rebuilds, 1);
    }
    // Teleport next to it: every level is rebuilt, once.
    move_camera(&mut app, Vec3::new(299.0, 1.6, 0.0));
    run(&mut app, 3);
    let s = stats(&app);
    for (l, c) in s.cascades.iter().enumerate() {
        assert_eq!(c.rebuilds, 2, "level {l}: a teleport rebuilds once");
        assert_eq!(c.static_cells_last_frame, 0);
    }
    let counts = assert_levels_equal_cpu(&mut app, &parts);
    // The building is in the finest level, which holds nothing else out here.
    assert!(counts[0] > 200, "{counts:?}");
    // A transform touched but not changed: no work.
    app.world_mut().get_mut::<Transform>(far_entity).unwrap().translation.y += 0.0;
    app.update();
    assert!(stats(&app).cascades.iter().all(|c| c.static_cells_last_frame == 0));
    // A static entity moved by a metre re-voxelizes only around where it was and is.
    app.world_mut().get_mut::<Transform>(far_entity).unwrap().translation.z += 1.0;
    app.update();
    let s = stats(&app);
    let whole = (CELLS as u64).pow(3);
    for (l, c) in s.cascades.iter().enumerate() {
        println!("level {l}: {} cells voxelized again for the move", c.static_cells_last_frame);
        assert!(c.static_cells_last_frame > 0 && c.static_cells_last_frame < whole, "level {l}");
        assert_eq!(c.rebuilds, 2);
    }
    let far = parts.pop().unwrap();
    parts.push(TriangleMesh::new(far.positions.iter().map(|p| *p + Vec3::Z).collect(), far.triangles));
    assert_levels_equal_cpu(&mut app, &parts);
    assert!(take_render_errors().is_empty());
}

/// `VoxelFill::Solid` occluders in cascades: filled when their levels are built, and filled again slab by
/// slab as the camera walks across them (the slabs cut them in every direction, so crossings below a slab
/// count at its bottom), equal to the CPU twin's fill of each window.
#[test]
fn solid_occluders_fill_slab_by_slab_as_the_camera_walks() {
    let _gpu = gpu_lock();
    let parts = corridor();
    let solids: Vec<TriangleMesh> = (0..4)
        .map(|k| {
            let m = builtin::icosphere(1.1, 2);
            let at = Vec3::new(-2.5 + 2.8 * k as f32, 1.1 + 0.3 * k as f32, -0.9 + 0.6 * k as f32);
            TriangleMesh::new(m.positions.iter().map(|p| *p + at).collect(), m.triangles)
        })
        .collect();
    let (spawn_parts, spawn_solids) = (parts.clone(), solids.clone());
    let mut app = headless_app(move |app| {
        app.add_systems(Startup, move |mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>| {
            commands.spawn(cascades());
            for mesh in &spawn_parts {
                commands.spawn((Mesh3d(meshes.add(bevy_mesh(mesh, Layout::U32))), StaticOccluder));
            }
            for mesh in &spawn_solids {
                commands.spawn((Mesh3d(meshes.add(bevy_mesh(mesh, Layout::U32))), StaticOccluder, VoxelFill::Solid));
            }
            spawn_camera(&mut commands, 0.0);
        });
    });
    run(&mut app, 6);
    let (_, built) = assert_levels_equal_cpu_with_solids(&mut app, &parts, &solids);
    assert!(built[0] > 300, "filled at the build: {built:?}");
    // Walk diagonally (x, y and z scroll) in steps of a quarter metre.
    for step in 1..=24 {
        let s = step as f32 * 0.25;
        move_camera(&mut app, Vec3::new(s, 1.6 + 0.5 * s, -0.6 * s));
        app.update();
    }
    run(&mut app, 2);
    let s = stats(&app);
    assert!(s.cascades[0].scrolls >= 2 && s.cascades.iter().all(|c| c.rebuilds == 1), "{:?}", s.cascades);
    let (_, walked) = assert_levels_equal_cpu_with_solids(&mut app, &parts, &solids);
    println!("voxels filled per level: {built:?} when built, {walked:?} after the walk");
    assert!(walked.iter().sum::<u64>() > 0);
    assert!(take_render_errors().is_empty());
}

/// Multi-valued voxels in the cascades: each part of the corridor with its own colour, the camera walking
/// diagonally so that scrolled slabs (their records cleared by the clear pass) cut the parts; every level's
/// point counts and albedo and normal sums, unwrapped from its toroidal storage, equal a fresh CPU
/// voxelization of its window with the same colours.
#[test]
fn multi_valued_voxels_scroll_with_the_cascades() {
    use bevy_hao::cpu::attributes::{MeshAlbedo, SAMPLE_WORDS, pack_albedo};
    let _gpu = gpu_lock();
    // The corridor moved off the lattice by 7-14 mm. At its own coordinates (faces at whole metres,
    // cells of 0.25, 0.5 and 1 m) many points' centroids fall exactly on cell faces, and there the cell
    // depends on how the device rounds `v0 + e1 * a + e2 * b`: an NVIDIA H100 fuses it into multiply-adds
    // (WGSL allows that), and 168 of level 0's 2,914 voxels then counted points their CPU twin put in the
    // next voxel (the CPU twin with `mul_add` there gives the same 168). The occupancy tests above tolerate
    // such ties; point counts move with every one.
    let offset = Affine3A::from_translation(Vec3::new(0.0137, 0.0071, 0.0093));
    let parts: Vec<TriangleMesh> = corridor().iter().map(|m| m.transformed(offset)).collect();
    let color = |k: usize| {
        let c = Color::hsl(k as f32 * 47.0 % 360.0, 0.7, 0.5).to_linear();
        Vec3::new(c.red, c.green, c.blue)
    };
    let spawned = parts.clone();
    let mut app = headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>| {
                commands.spawn(VoxelVolume { attributes: true, ..cascades() });
                for (k, mesh) in spawned.iter().enumerate() {
                    let c = color(k);
                    commands.spawn((
                        Mesh3d(meshes.add(bevy_mesh(mesh, Layout::U32))),
                        MeshMaterial3d(
                            materials
                                .add(StandardMaterial { base_color: Color::linear_rgb(c.x, c.y, c.z), ..default() }),
                        ),
                        StaticOccluder,
                    ));
                }
                spawn_camera(&mut commands, 0.0);
            },
        );
    });
    run(&mut app, 6);
    for step in 1..=24 {
        move_camera(&mut app, Vec3::new(step as f32 * 0.3, 1.6, step as f32 * 0.1));
        app.update();
    }
    run(&mut app, 2);
    let assets = grid_assets(&app).unwrap();
    assert_eq!(assets.sample_words, SAMPLE_WORDS);
    let records: Vec<u32> =
        bytemuck::cast_slice(&read_buffer(&mut app, assets.static_point_counts.clone().unwrap(), 3)).to_vec();
    let levels = read_cascades(&mut app, true);
    let d = assets.grid.dims;
    let level_voxels = assets.grid.voxel_count() as usize;
    let stride = SAMPLE_WORDS as usize;
    for (l, r) in levels.iter().enumerate() {
        // 7.2 m along x: the two finer levels scroll (by 2 m and 4 m steps), the coarsest (8 m) does not.
        assert!(l == 2 || r.level.scrolls > 0, "level {l} never scrolled");
        // The level's records in window order.
        let wrap = r.level.window_min.rem_euclid(d.as_ivec3()).as_uvec3();
        let mut window = vec![0u32; level_voxels * stride];
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    let p = (UVec3::new(x, y, z) + wrap) % d;
                    let from = (l * level_voxels + (p.x + d.x * (p.y + d.y * p.z)) as usize) * stride;
                    let to = r.grid.linear_index(UVec3::new(x, y, z)) as usize * stride;
                    window[to..to + stride].copy_from_slice(&records[from..from + stride]);
                }
            }
        }
        let gpu = VoxelOccupancy::from_records(r.grid, &r.occupancy.words(), &window, SAMPLE_WORDS).unwrap();
        let level = cpu::CascadeLevel {
            origin: r.level.origin,
            cell_size: r.level.cell_size,
            cells: CELLS,
            window_min: r.level.window_min,
        };
        let cpu = VoxelOccupancy::with_attributes(r.grid);
        for (k, mesh) in parts.iter().enumerate() {
            let albedo = MeshAlbedo { base: pack_albedo(color(k)), vertex_colors: None };
            let region = level.region();
            cpu::voxelize_sampled_mesh_in_region(
                mesh,
                &albedo,
                level.grid_from_world(),
                &assets.settings,
                &region,
                &cpu,
            );
        }
        let (mut voxels, mut equal, mut within) = (0u64, 0u64, 0u64);
        for i in 0..level_voxels as u32 {
            let (g, c) = (gpu.record(i), cpu.record(i));
            if g[0] == 0 && c[0] == 0 {
                continue;
            }
            voxels += 1;
            equal += (g == c) as u64;
            within +=
                (g[0] == c[0] && (1..7).all(|k| (g[k] as i32 as i64 - c[k] as i32 as i64).abs() <= g[0] as i64)) as u64;
        }
        println!("level {l}: {voxels} voxels with points, {equal} with equal records, {within} within rounding");
        assert!(voxels > 500, "level {l}: {voxels}");
        // Float ties at cell faces may move a point or round a value the other way, rarely.
        assert!(within * 1000 >= voxels * 998, "level {l}: {within} of {voxels}");
        assert!(equal * 100 >= voxels * 95, "level {l}: {equal} of {voxels}");
    }
    assert!(take_render_errors().is_empty());
}
