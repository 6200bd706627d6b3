//! Skinned and morphed meshes on a headless Bevy app (lavapipe here): the voxelizer morphs and skins each
//! vertex with Bevy's morph weights and joint matrices before voxelizing, and the GPU's grid is held against
//! the CPU twin (`cpu::skinning`).

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy_hao::cpu::{TriangleMesh, VertexSkin, VoxelOccupancy, skinned_mesh, voxelize_mesh};
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;

/// A square bar along +y from 0 to 4, 0.6 wide, in rings every 0.25 (so that it can bend), with caps; and
/// its skin: joint 0 below y = 1.5, joint 1 above y = 2.5, blended linearly between.
fn bar() -> (TriangleMesh, VertexSkin) {
    let corners = [Vec2::new(-0.3, -0.3), Vec2::new(0.3, -0.3), Vec2::new(0.3, 0.3), Vec2::new(-0.3, 0.3)];
    let rings = 17u32;
    let mut m = TriangleMesh::default();
    let mut skin = VertexSkin::default();
    for r in 0..rings {
        let y = 0.25 * r as f32;
        let t = ((y - 1.5) / 1.0).clamp(0.0, 1.0);
        for c in corners {
            m.positions.push(Vec3::new(c.x, y, c.y));
            skin.joints.push([0, 1, 0, 0]);
            skin.weights.push([1.0 - t, t, 0.0, 0.0]);
        }
    }
    for r in 0..rings - 1 {
        for k in 0..4 {
            let (a, b) = (4 * r + k, 4 * r + (k + 1) % 4);
            let (c, d) = (a + 4, b + 4);
            m.triangles.push([a, c, b]);
            m.triangles.push([b, c, d]);
        }
    }
    let top = 4 * (rings - 1);
    m.triangles.extend([[0, 1, 2], [0, 2, 3], [top, top + 2, top + 1], [top, top + 3, top + 2]]);
    (m, skin)
}

/// The Bevy mesh of a [`TriangleMesh`] with joint indices and weights.
fn skinned_bevy_mesh(mesh: &TriangleMesh, skin: &VertexSkin) -> Mesh {
    bevy_mesh(mesh, Layout::U32)
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(skin.joints.clone()))
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, skin.weights.clone())
}

#[derive(Component)]
struct Bone;

#[derive(Component)]
struct Character;

/// The upper joint's rest transform: 2 up from the root.
const BONE_REST: Vec3 = Vec3::new(0.0, 2.0, 0.0);

/// An app with a fixed 64^3 volume over [-4, 4]^3, a camera that sees the bar (Bevy uploads joint
/// matrices only for skins visible to a view), and the bar skinned by a root joint and a bone bent by
/// `bend` radians about z; the mesh carries `skin`'s joint data, and the `SkinnedMesh` component only if
/// `with_skin`.
fn skinned_app(bend: f32, mesh: TriangleMesh, skin: VertexSkin, with_skin: bool) -> App {
    headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut images: ResMut<Assets<Image>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>| {
                commands.spawn(VoxelVolume {
                    bounds: VolumeBounds::World { min: Vec3::splat(-4.0), max: Vec3::splat(4.0) },
                    resolution: VolumeResolution::Cells(64),
                    ..default()
                });
                let root = commands.spawn(Transform::default()).id();
                let bone = commands
                    .spawn((Transform::from_translation(BONE_REST).with_rotation(Quat::from_rotation_z(bend)), Bone))
                    .insert(ChildOf(root))
                    .id();
                let inverse_bindposes = bindposes.add(vec![Mat4::IDENTITY, Mat4::from_translation(-BONE_REST)]);
                let mut e = commands.spawn((
                    Mesh3d(meshes.add(skinned_bevy_mesh(&mesh, &skin))),
                    Transform::default(),
                    Character,
                ));
                if with_skin {
                    e.insert((
                        SkinnedMesh { inverse_bindposes, joints: vec![root, bone] },
                        MeshMaterial3d(materials.add(StandardMaterial::default())),
                    ));
                }
                // Without a skin it gets no material: Bevy 0.19 cannot draw a mesh with joint attributes and
                // no `SkinnedMesh` (its skinned pipeline meets an unskinned bind group, a validation error).
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target_image(&mut images, UVec2::new(64, 48)).into()),
                    Msaa::Off,
                    Tonemapping::None,
                    Transform::from_xyz(0.0, 2.0, 9.0).looking_at(Vec3::new(0.0, 2.0, 0.0), Vec3::Y),
                ));
            },
        );
    })
}

/// The joint matrices Bevy computes for the bar's skin (joint global transform times inverse bind pose).
fn joint_matrices(app: &mut App) -> Vec<Mat4> {
    let bone = app.world_mut().query_filtered::<&GlobalTransform, With<Bone>>().single(app.world()).unwrap().affine();
    vec![Mat4::IDENTITY, bone * Mat4::from_translation(-BONE_REST)]
}

/// The CPU twin's grid of a world-space mesh in the app's grid.
fn cpu_grid(app: &App, world_mesh: &TriangleMesh) -> VoxelOccupancy {
    let assets = grid_assets(app).unwrap();
    let out = VoxelOccupancy::new(assets.grid, false);
    voxelize_mesh(world_mesh, assets.grid.grid_from_world(), &assets.settings, &out);
    out
}

#[test]
fn a_bent_two_bone_bar_voxelizes_as_the_cpu_twin_skins_it() {
    let _gpu = gpu_lock();
    let (mesh, skin) = bar();
    let mut app = skinned_app(std::f32::consts::FRAC_PI_2, mesh.clone(), skin.clone(), true);
    run(&mut app, 8);
    let gpu = read_occupancy(&mut app);
    let posed = skinned_mesh(&mesh, &skin, &joint_matrices(&mut app));
    let cpu = cpu_grid(&app, &posed);
    let bind_pose = cpu_grid(&app, &mesh);
    let (only_gpu, only_cpu) = (gpu.count_not_in(&cpu), cpu.count_not_in(&gpu));
    let set = cpu.set_voxel_count();
    let moved = bind_pose.count_not_in(&gpu) + gpu.count_not_in(&bind_pose);
    println!(
        "bent bar: {set} voxels on the CPU, {only_gpu} only on the GPU, {only_cpu} only on the CPU; {moved} differ from the bind pose"
    );
    assert!(set > 500, "{set}");
    assert!((only_gpu + only_cpu) * 1000 <= set, "{only_gpu} + {only_cpu} of {set} differ");
    // The bend moves the upper half: far from the bind pose there, the same at the foot.
    assert!(moved > set / 3, "only {moved} voxels differ from the bind pose");
    let grid = grid_assets(&app).unwrap().grid;
    let cell = |p: Vec3| grid.cell_of_point(grid.world_to_grid(p)).unwrap();
    assert!(gpu.is_set(cell(Vec3::new(0.0, 0.5, 0.3))) || gpu.is_set(cell(Vec3::new(0.0, 0.5, -0.3))));
    assert!(gpu.is_set(cell(Vec3::new(-1.8, 2.0, 0.299))), "the bent upper half lies along -x");
    assert!(!gpu.is_set(cell(Vec3::new(0.3, 3.6, 0.0))), "nothing left where the bind pose's top was");
    // Skinned meshes are dynamic without a marker.
    let s = stats(&app);
    assert_eq!((s.dynamic_instances, s.static_instances), (1, 0));
    assert!(take_render_errors().is_empty());

    // The bone moves back: the voxels follow, frame by frame.
    let mut q = app.world_mut().query_filtered::<&mut Transform, With<Bone>>();
    q.single_mut(app.world_mut()).unwrap().rotation = Quat::IDENTITY;
    run(&mut app, 2);
    let straight = read_occupancy(&mut app);
    let matrices = joint_matrices(&mut app);
    let cpu = cpu_grid(&app, &skinned_mesh(&mesh, &skin, &matrices));
    let differ = straight.count_not_in(&cpu) + cpu.count_not_in(&straight);
    assert!(differ * 1000 <= cpu.set_voxel_count(), "{differ} differ after straightening");
    assert!(straight.is_set(cell(Vec3::new(0.3, 3.6, 0.0))) || straight.is_set(cell(Vec3::new(0.299, 3.6, 0.0))));
    assert!(take_render_errors().is_empty());
}

#[test]
fn bad_skin_data_is_voxelized_as_drawn_or_skipped_without_errors() {
    let _gpu = gpu_lock();
    let (mesh, mut skin) = bar();
    // Weights that sum to 0.5 on the lowest ring, and a joint past the skin's two on the top ring.
    for w in &mut skin.weights[..4] {
        *w = [0.5, 0.0, 0.0, 0.0];
    }
    let top = skin.joints.len() - 4;
    for j in &mut skin.joints[top..] {
        *j = [7, 0, 0, 0];
    }
    let mut app = skinned_app(0.0, mesh.clone(), skin.clone(), true);
    run(&mut app, 8);
    let gpu = read_occupancy(&mut app);
    let matrices = joint_matrices(&mut app);
    let cpu = cpu_grid(&app, &skinned_mesh(&mesh, &skin, &matrices));
    let differ = gpu.count_not_in(&cpu) + cpu.count_not_in(&gpu);
    assert!(differ * 1000 <= cpu.set_voxel_count(), "{differ} of {} differ", cpu.set_voxel_count());
    let s = stats(&app);
    // The triangles touching the top ring (its 8 sides and the cap's 2) are invalid; the others are drawn.
    assert_eq!(s.dynamic_counters.invalid, 10, "{:?}", s.dynamic_counters);
    assert!(cpu.set_voxel_count() > 300);
    assert!(take_render_errors().is_empty());

    // Joints but no SkinnedMesh: voxelized unskinned where Bevy draws it (a static occluder by default).
    let mut app = skinned_app(0.0, mesh.clone(), skin, false);
    run(&mut app, 8);
    let gpu = read_occupancy(&mut app);
    let cpu = cpu_grid(&app, &mesh);
    let differ = gpu.count_not_in(&cpu) + cpu.count_not_in(&gpu);
    assert!(differ * 1000 <= cpu.set_voxel_count(), "{differ} differ");
    assert_eq!(stats(&app).static_instances, 1);
    assert!(take_render_errors().is_empty());
}

#[test]
fn a_skinned_static_occluder_keeps_the_pose_it_was_voxelized_in() {
    let _gpu = gpu_lock();
    let (mesh, skin) = bar();
    let mut app = skinned_app(std::f32::consts::FRAC_PI_2, mesh.clone(), skin.clone(), true);
    app.update();
    let e = app.world_mut().query_filtered::<Entity, With<Character>>().single(app.world()).unwrap();
    app.world_mut().entity_mut(e).insert(StaticOccluder);
    run(&mut app, 8);
    let s = stats(&app);
    assert_eq!((s.static_instances, s.dynamic_instances), (1, 0), "marked static");
    let bent = read_occupancy(&mut app);
    let matrices = joint_matrices(&mut app);
    let cpu = cpu_grid(&app, &skinned_mesh(&mesh, &skin, &matrices));
    let differ = bent.count_not_in(&cpu) + cpu.count_not_in(&bent);
    assert!(differ * 1000 <= cpu.set_voxel_count(), "{differ} differ from the bent pose");
    // The bone straightens: the static voxels keep the bent pose, and nothing is rebuilt.
    let rebuilds = stats(&app).static_rebuilds;
    let mut q = app.world_mut().query_filtered::<&mut Transform, With<Bone>>();
    q.single_mut(app.world_mut()).unwrap().rotation = Quat::IDENTITY;
    run(&mut app, 4);
    let later = read_occupancy(&mut app);
    assert_eq!(later.words(), bent.words(), "the static voxels changed with the pose");
    assert_eq!(stats(&app).static_rebuilds, rebuilds);
    assert!(take_render_errors().is_empty());
}

#[test]
fn a_morph_target_moves_its_face_in_the_voxels() {
    use bevy::mesh::morph::{MeshMorphWeights, MorphAttributes};
    let _gpu = gpu_lock();
    let (mesh, _) = bar();
    // One target: the top ring and cap slide 1.5 along +x (a shear of the upper bar); weight 0.8.
    let top = mesh.positions.len() - 4;
    let deltas: Vec<Vec3> =
        (0..mesh.positions.len()).map(|v| if v >= top { Vec3::X * 1.5 } else { Vec3::ZERO }).collect();
    let weight = 0.8;
    let targets: Vec<MorphAttributes> =
        deltas.iter().map(|d| MorphAttributes::new(*d, Vec3::ZERO, Vec3::ZERO)).collect();
    let bevy_mesh_with_target = {
        let mut m = bevy_mesh(&mesh, Layout::U32);
        m.set_morph_targets(targets);
        m
    };
    let mut app = headless_app(move |app| {
        let m = bevy_mesh_with_target.clone();
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut images: ResMut<Assets<Image>>,
                  mut materials: ResMut<Assets<StandardMaterial>>| {
                commands.spawn(VoxelVolume {
                    bounds: VolumeBounds::World { min: Vec3::splat(-4.0), max: Vec3::splat(4.0) },
                    resolution: VolumeResolution::Cells(64),
                    ..default()
                });
                commands.spawn((
                    Mesh3d(meshes.add(m.clone())),
                    MeshMaterial3d(materials.add(StandardMaterial::default())),
                    MeshMorphWeights::Value { weights: vec![weight] },
                    Character,
                ));
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target_image(&mut images, UVec2::new(64, 48)).into()),
                    Msaa::Off,
                    Tonemapping::None,
                    Transform::from_xyz(0.0, 2.0, 9.0).looking_at(Vec3::new(0.0, 2.0, 0.0), Vec3::Y),
                ));
            },
        );
    });
    run(&mut app, 8);
    let gpu = read_occupancy(&mut app);
    let cpu = cpu_grid(&app, &bevy_hao::cpu::morphed_mesh(&mesh, &[deltas], &[weight]));
    let base = cpu_grid(&app, &mesh);
    let (only_gpu, only_cpu) = (gpu.count_not_in(&cpu), cpu.count_not_in(&gpu));
    let moved = base.count_not_in(&gpu) + gpu.count_not_in(&base);
    println!(
        "morphed bar: {} voxels on the CPU, {only_gpu} only on the GPU, {only_cpu} only on the CPU; {moved} differ from the base shape",
        cpu.set_voxel_count()
    );
    assert!((only_gpu + only_cpu) * 1000 <= cpu.set_voxel_count(), "{only_gpu} + {only_cpu} differ");
    assert!(moved > 50, "only {moved} voxels differ from the base shape");
    let grid = grid_assets(&app).unwrap().grid;
    let cell = |p: Vec3| grid.cell_of_point(grid.world_to_grid(p)).unwrap();
    assert!(gpu.is_set(cell(Vec3::new(1.2, 4.0, 0.0))), "the top face moved 1.2 along x");
    let s = stats(&app);
    assert_eq!((s.dynamic_instances, s.static_instances), (1, 0), "morphed meshes are dynamic");
    assert!(take_render_errors().is_empty());
}
