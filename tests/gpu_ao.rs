//! Hybrid ambient occlusion rendered headless (lavapipe here) and read back: what AO must do.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;

const SIZE: UVec2 = UVec2::new(96, 64);

#[derive(Component)]
struct TheCamera;
#[derive(Component)]
struct Roof;
#[derive(Component)]
struct Mover;
/// Turned a quarter turn about the vertical every frame.
#[derive(Component)]
struct Spinner;

/// The radius of a `Spinner` sphere.
const SPINNER_RADIUS: f32 = 0.5;

#[derive(Resource, Clone)]
struct Targets {
    color: Handle<Image>,
    debug: HaoDebugImages,
}

/// `High` with the voxels' hits as they are: the tests that hold a part of the trace to its twin leave free
/// space out (`High` passes it by default), and the free-space test turns it on and off itself.
fn hao_settings() -> HybridAmbientOcclusion {
    HybridAmbientOcclusion {
        near_field: false,
        max_distance: 3.0,
        quality: HaoQuality::High,
        depth_free_space: Some(false),
        ..default()
    }
}

fn volume() -> VoxelVolume {
    VoxelVolume {
        bounds: VolumeBounds::World { min: Vec3::new(-8.0, -1.0, -8.0), max: Vec3::new(8.0, 7.0, 8.0) },
        resolution: VolumeResolution::Cells(64),
        point_counts: true,
        ..default()
    }
}

fn box_at(meshes: &mut Assets<Mesh>, size: Vec3) -> Mesh3d {
    Mesh3d(meshes.add(Cuboid::from_size(size)))
}

/// What ambient occlusion the camera has.
#[derive(Clone)]
enum Ao {
    Hao(HybridAmbientOcclusion),
    /// Bevy's SSAO alone.
    Ssao,
    None,
}

/// An app with a floor, the given extra setup, and a camera.
fn scene_app(
    camera: Transform,
    ao: Ao,
    extra: impl Fn(&mut Commands, &mut Assets<Mesh>, Handle<StandardMaterial>) + Send + Sync + 'static,
) -> App {
    scene_app_with(camera, ao, false, extra)
}

/// [`scene_app`], optionally rendering opaque materials deferred.
fn scene_app_with(
    camera: Transform,
    ao: Ao,
    deferred: bool,
    extra: impl Fn(&mut Commands, &mut Assets<Mesh>, Handle<StandardMaterial>) + Send + Sync + 'static,
) -> App {
    scene_app_in(camera, ao, deferred, volume(), extra)
}

/// [`scene_app_with`] with a given voxel volume.
fn scene_app_in(
    camera: Transform,
    ao: Ao,
    deferred: bool,
    volume: VoxelVolume,
    extra: impl Fn(&mut Commands, &mut Assets<Mesh>, Handle<StandardMaterial>) + Send + Sync + 'static,
) -> App {
    headless_app(move |app| {
        let ao = ao.clone();
        if deferred {
            app.insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred());
        }
        app.insert_resource(GlobalAmbientLight { brightness: 600.0, ..default() });
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                let material = materials.add(StandardMaterial {
                    base_color: Color::srgb(0.8, 0.8, 0.8),
                    perceptual_roughness: 1.0,
                    ..default()
                });
                commands.spawn(volume);
                commands.spawn((
                    box_at(&mut meshes, Vec3::new(16.0, 0.2, 16.0)),
                    MeshMaterial3d(material.clone()),
                    Transform::from_xyz(0.0, -0.1, 0.0),
                    StaticOccluder,
                ));
                extra(&mut commands, &mut meshes, material);
                let color = target_image(&mut images, SIZE);
                let debug = HaoDebugImages::new(&mut images, SIZE);
                let mut cam = commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(color.clone().into()),
                    Msaa::Off,
                    Tonemapping::None,
                    camera,
                    debug.clone(),
                    TheCamera,
                ));
                if deferred {
                    cam.insert(bevy::core_pipeline::prepass::DeferredPrepass);
                }
                match &ao {
                    Ao::Hao(h) => {
                        cam.insert(h.clone());
                    }
                    Ao::Ssao => {
                        cam.insert(bevy::pbr::ScreenSpaceAmbientOcclusion::default());
                    }
                    Ao::None => {}
                }
                commands.insert_resource(Targets { color, debug });
            },
        );
    })
}

/// The AO image.
fn ao_image(app: &mut App) -> (u32, u32, Vec<f32>) {
    let targets = app.world().resource::<Targets>().clone();
    read_image_f32(app, targets.debug.ao, 4)
}

/// Mean AO over the pixels within `radius` pixels of where `world` projects.
fn ao_at(app: &mut App, ao: &(u32, u32, Vec<f32>), world: Vec3, radius: i32) -> f32 {
    let (w, h, data) = ao;
    let mut q = app.world_mut().query_filtered::<(&Camera, &GlobalTransform), With<TheCamera>>();
    let (camera, transform) = q.single(app.world()).unwrap();
    let p = camera.world_to_viewport(transform, world).expect("point in view");
    let (cx, cy) = (p.x as i32, p.y as i32);
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in cy - radius..=cy + radius {
        for x in cx - radius..=cx + radius {
            if x >= 0 && y >= 0 && (x as u32) < *w && (y as u32) < *h {
                sum += data[(y as u32 * w + x as u32) as usize];
                n += 1.0;
            }
        }
    }
    sum / n
}

/// The camera's image with a debug view on, as RGB.
fn view_pixels(app: &mut App, cam: Entity, view: HaoDebugView) -> Vec<[u8; 3]> {
    app.world_mut().entity_mut(cam).insert(view);
    run(app, 3);
    let targets = app.world().resource::<Targets>().clone();
    let (_, _, _, bytes) = read_image(app, targets.color, 2);
    bytes.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect()
}

fn assert_valid(ao: &(u32, u32, Vec<f32>)) {
    for v in &ao.2 {
        assert!(v.is_finite() && (0.0..=1.0).contains(v), "AO value {v} out of [0, 1]");
    }
}

fn walls(commands: &mut Commands, meshes: &mut Assets<Mesh>, material: Handle<StandardMaterial>) {
    // An L of walls: one along x at z = -2, one along z at x = -2, 3 m high.
    commands.spawn((
        box_at(meshes, Vec3::new(10.0, 3.0, 0.3)),
        MeshMaterial3d(material.clone()),
        Transform::from_xyz(3.0, 1.5, -2.15),
        StaticOccluder,
    ));
    commands.spawn((
        box_at(meshes, Vec3::new(0.3, 3.0, 10.0)),
        MeshMaterial3d(material),
        Transform::from_xyz(-2.15, 1.5, 3.0),
        StaticOccluder,
    ));
}

#[test]
fn corners_and_wall_bases_are_darker_than_open_floor() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(1.5, 9.0, 5.5).looking_at(Vec3::new(1.0, 0.0, 0.5), Vec3::Y);
    let mut app = scene_app(camera, Ao::Hao(hao_settings()), walls);
    run(&mut app, 8);
    let ao = ao_image(&mut app);
    assert_valid(&ao);
    let corner = ao_at(&mut app, &ao, Vec3::new(-1.85, 0.0, -1.85), 1);
    let wall_base = ao_at(&mut app, &ao, Vec3::new(3.0, 0.0, -1.85), 1);
    let floor_near = ao_at(&mut app, &ao, Vec3::new(3.0, 0.0, 1.0), 1);
    let open = ao_at(&mut app, &ao, Vec3::new(4.0, 0.0, 4.0), 1);
    println!(
        "corner {corner:.3}, wall base {wall_base:.3}, floor 3 m from the wall {floor_near:.3}, open floor {open:.3}"
    );
    assert!(corner < wall_base, "corner {corner} vs wall base {wall_base}");
    assert!(wall_base < floor_near - 0.1, "wall base {wall_base} vs floor 3 m away {floor_near}");
    assert!(open > 0.95, "open floor {open}");
    assert!(take_render_errors().is_empty());
}

/// A roof 2 m over the floor; the camera sits under it at 1.6 m.
fn roof(commands: &mut Commands, meshes: &mut Assets<Mesh>, material: Handle<StandardMaterial>) {
    commands.spawn((
        box_at(meshes, Vec3::new(6.0, 0.3, 6.0)),
        MeshMaterial3d(material),
        Transform::from_xyz(0.0, 2.15, 0.0),
        StaticOccluder,
        Roof,
    ));
}

/// Settings that reach the roof.
fn roof_hao() -> HybridAmbientOcclusion {
    HybridAmbientOcclusion { max_distance: 5.0, ..hao_settings() }
}

#[test]
fn a_roof_outside_the_view_darkens_the_floor_with_hao_and_not_with_ssao() {
    let _gpu = gpu_lock();
    // The camera is under the roof, looking straight down: the roof is behind it, outside the frustum.
    let camera = Transform::from_xyz(0.0, 1.6, 0.0).looking_at(Vec3::new(0.0, 0.0, 0.01), Vec3::Y);
    let center = Vec3::new(0.0, 0.0, 0.0);
    let mean = |ao: Ao, with_roof: bool| {
        let mut app = scene_app(camera, ao, move |c, m, mat| {
            if with_roof {
                roof(c, m, mat)
            }
        });
        run(&mut app, 8);
        let ao = ao_image(&mut app);
        assert_valid(&ao);
        let v = ao_at(&mut app, &ao, center, 12);
        assert!(take_render_errors().is_empty());
        v
    };
    let hao_roof = mean(Ao::Hao(roof_hao()), true);
    let hao_open = mean(Ao::Hao(roof_hao()), false);
    let ssao_roof = mean(Ao::Ssao, true);
    let ssao_open = mean(Ao::Ssao, false);
    println!(
        "floor AO: HAO under the roof {hao_roof:.3}, HAO without it {hao_open:.3}; Bevy's SSAO under the roof {ssao_roof:.3}, without it {ssao_open:.3}"
    );
    assert!(hao_roof < hao_open - 0.2, "HAO: {hao_roof} under the roof vs {hao_open} without");
    assert!(hao_open > 0.95);
    assert!((ssao_roof - ssao_open).abs() < 0.02, "SSAO cannot see the roof: {ssao_roof} vs {ssao_open}");
}

#[test]
fn a_moving_box_carries_its_occlusion() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 8.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y);
    let mut app = scene_app(camera, Ao::Hao(hao_settings()), |c, m, mat| {
        c.spawn((
            box_at(m, Vec3::new(1.0, 1.0, 1.0)),
            MeshMaterial3d(mat),
            Transform::from_xyz(-2.0, 0.5, 0.0),
            DynamicOccluder,
            Mover,
        ));
    });
    run(&mut app, 8);
    assert_occlusion_follows_the_mover(&mut app, "box");
}

/// The `Mover` (a 1 m occluder at x = -2) moves to x = 2 a metre a frame: the floor beside its first place
/// gets lighter and the floor beside its last place darker.
fn assert_occlusion_follows_the_mover(app: &mut App, what: &str) {
    let left = Vec3::new(-2.0, 0.0, 0.65);
    let right = Vec3::new(2.0, 0.0, 0.65);
    let ao = ao_image(app);
    let (l0, r0) = (ao_at(app, &ao, left, 1), ao_at(app, &ao, right, 1));
    for step in 1..=4 {
        let mut q = app.world_mut().query_filtered::<&mut Transform, With<Mover>>();
        q.single_mut(app.world_mut()).unwrap().translation.x = -2.0 + step as f32;
        run(app, 1);
    }
    let ao = ao_image(app);
    assert_valid(&ao);
    let (l1, r1) = (ao_at(app, &ao, left, 1), ao_at(app, &ao, right, 1));
    println!("beside the {what}'s first place: {l0:.3} -> {l1:.3}; beside its last place: {r0:.3} -> {r1:.3}");
    assert!(l0 < r0 - 0.1 && r1 < l1 - 0.1);
    assert!(take_render_errors().is_empty());
}

#[test]
fn a_walking_skinned_character_carries_its_occlusion() {
    use bevy::mesh::VertexAttributeValues;
    use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 8.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y);
    // A 1 m box skinned to one joint (no occluder marker: skinned meshes are dynamic); the joint walks.
    let mut app = scene_app(camera, Ao::Hao(hao_settings()), |c, m, mat| {
        let mesh = Mesh::from(Cuboid::from_size(Vec3::ONE));
        let n = mesh.count_vertices();
        let mesh = mesh
            .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(vec![[0; 4]; n]))
            .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0f32, 0.0, 0.0, 0.0]; n]);
        let mesh = m.add(mesh);
        c.queue(move |world: &mut World| {
            let bindposes = world.resource_mut::<Assets<SkinnedMeshInverseBindposes>>().add(vec![Mat4::IDENTITY]);
            let joint = world.spawn((Transform::from_xyz(-2.0, 0.5, 0.0), Mover)).id();
            world.spawn((
                Mesh3d(mesh),
                MeshMaterial3d(mat),
                SkinnedMesh { inverse_bindposes: bindposes, joints: vec![joint] },
            ));
        });
    });
    run(&mut app, 8);
    assert_eq!(stats(&app).dynamic_instances, 1, "the skinned mesh is a dynamic occluder");
    assert_occlusion_follows_the_mover(&mut app, "character");
}

#[test]
fn bevys_ssao_passes_are_skipped_where_hao_overwrites_them() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 8.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y);
    let mut app = scene_app(camera, Ao::Hao(hao_settings()), |c, m, mat| {
        c.spawn((box_at(m, Vec3::ONE), MeshMaterial3d(mat), Transform::from_xyz(0.0, 0.5, 0.0), StaticOccluder));
    });
    run(&mut app, 10);
    // The time of the latest measurement of a pass's GPU span (a span not recorded keeps its old one).
    let latest =
        |app: &App, span: &str| diagnostic_measurement(app, &format!("render/{span}/elapsed_gpu")).map(|m| m.0);
    let (ssao, trace) = (latest(&app, "ssao"), latest(&app, "hao/trace"));
    run(&mut app, 6);
    assert!(latest(&app, "hao/trace") != trace && trace.is_some(), "HAO's passes run");
    assert_eq!(latest(&app, "ssao"), ssao, "Bevy's SSAO passes ran, their result overwritten by HAO's");
    // With the near field on, SSAO's result is used: its passes run again.
    let mut q = app.world_mut().query_filtered::<&mut HybridAmbientOcclusion, With<TheCamera>>();
    q.single_mut(app.world_mut()).unwrap().near_field = true;
    run(&mut app, 6);
    let with_near_field = latest(&app, "ssao");
    assert!(with_near_field.is_some() && with_near_field != ssao, "the near field needs Bevy's SSAO passes");
    assert!(take_render_errors().is_empty());
}

fn luminance(app: &mut App) -> Vec<f32> {
    let targets = app.world().resource::<Targets>().clone();
    let (_, _, _, bytes) = read_image(app, targets.color, 4);
    bytes.chunks_exact(4).map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0).collect()
}

#[test]
fn ao_dims_indirect_light_only_and_removing_it_restores_bevys_behaviour() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 1.6, 0.0).looking_at(Vec3::new(0.0, 0.0, 0.01), Vec3::Y);
    // Direct light only: with the roof the floor is in its shadow unless the light comes from the side, so
    // light it from a low angle under the roof's edge; ambient off.
    let direct = |hao: bool| {
        let mut app = scene_app(camera, if hao { Ao::Hao(roof_hao()) } else { Ao::None }, |c, m, mat| {
            roof(c, m, mat);
            c.spawn((
                DirectionalLight { illuminance: 1500.0, shadow_maps_enabled: false, ..default() },
                Transform::from_xyz(1.0, 1.0, 0.0).looking_at(Vec3::ZERO, Vec3::Y),
            ));
        });
        app.insert_resource(GlobalAmbientLight { brightness: 0.0, ..default() });
        run(&mut app, 8);
        let l = luminance(&mut app);
        assert!(take_render_errors().is_empty());
        l
    };
    let (with, without) = (direct(true), direct(false));
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let diff = with.iter().zip(&without).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    println!(
        "direct light only: mean {:.1} with HAO, {:.1} without; largest difference {diff}",
        mean(&with),
        mean(&without)
    );
    assert!(mean(&with) > 20.0 && mean(&with) < 230.0, "the floor is lit, not saturated: {}", mean(&with));
    assert!(diff <= 1.0, "AO changed direct light by {diff}");

    // Ambient light only: HAO darkens it; removing HAO gives back the image of a camera that never had it.
    let mut app = scene_app(camera, Ao::Hao(roof_hao()), roof);
    run(&mut app, 8);
    let with_hao = luminance(&mut app);
    let cam = app.world_mut().query_filtered::<Entity, With<TheCamera>>().single(app.world()).unwrap();
    app.world_mut().entity_mut(cam).remove::<HybridAmbientOcclusion>();
    run(&mut app, 2);
    assert!(app.world().get::<bevy::pbr::ScreenSpaceAmbientOcclusion>(cam).is_none(), "the SSAO HAO added is gone");
    let removed = luminance(&mut app);
    let mut plain = scene_app(camera, Ao::None, roof);
    run(&mut plain, 8);
    let never = luminance(&mut plain);
    println!(
        "ambient only: mean {:.1} with HAO, {:.1} after removing it, {:.1} never had it",
        mean(&with_hao),
        mean(&removed),
        mean(&never)
    );
    assert!(mean(&with_hao) < mean(&removed) - 5.0, "HAO darkens ambient light");
    let diff = removed.iter().zip(&never).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(diff <= 1.0, "after removal the image differs from a camera without AO by {diff}");
    assert!(take_render_errors().is_empty());
}

/// The view's pixels as the trace sees them: world position and normal from the debug images (`None` for
/// the background).
fn view_samples(app: &mut App) -> (u32, u32, Vec<Option<(Vec3, Vec3)>>) {
    let targets = app.world().resource::<Targets>().clone();
    let camera = app.world_mut().query_filtered::<Entity, With<TheCamera>>().single(app.world()).unwrap();
    bevy_hao_tools::harness::view_samples(app, camera, &targets.debug)
}

/// The AO image with the surfaces the view shows (`view_samples`), pixel by pixel.
fn ao_and_samples(app: &mut App) -> (Vec<f32>, Vec<Option<(Vec3, Vec3)>>) {
    let targets = app.world().resource::<Targets>().clone();
    let (_, _, ao) = read_image_f32(app, targets.debug.ao.clone(), 2);
    (ao, view_samples(app).2)
}

/// The view's depth prepass as the trace reads it, for the twin's depth contacts.
fn view_depth(app: &mut App) -> bevy_hao::cpu::contacts::ViewDepth {
    let targets = app.world().resource::<Targets>().clone();
    let camera = app.world_mut().query_filtered::<Entity, With<TheCamera>>().single(app.world()).unwrap();
    bevy_hao_tools::harness::view_depth(app, camera, &targets.debug)
}

/// The CPU twin's noisy AO of every pixel with the noise of `frame` (NaN for the background), with the
/// depth contacts in `view`'s depth, the level each pixel's first ray starts in, and the work of all the
/// pixels' rays.
fn cpu_trace(
    samples: &[Option<(Vec3, Vec3)>],
    view: &bevy_hao::cpu::contacts::ViewDepth,
    settings: &HybridAmbientOcclusion,
    levels: &[bevy_hao::cpu::march::TraceLevel],
    frame: u32,
) -> (Vec<f32>, Vec<usize>, bevy_hao::cpu::ao::TraceWork) {
    cpu_trace_near_change(samples, view, settings, levels, frame, &vec![0.0; samples.len()])
}

/// [`cpu_trace`] where each pixel's occlusion can have changed by `change` since last frame
/// (`cpu::temporal::occlusion_change`): it traces `cpu::temporal::change_rays` rays.
fn cpu_trace_near_change(
    samples: &[Option<(Vec3, Vec3)>],
    view: &bevy_hao::cpu::contacts::ViewDepth,
    settings: &HybridAmbientOcclusion,
    levels: &[bevy_hao::cpu::march::TraceLevel],
    frame: u32,
    change: &[f32],
) -> (Vec<f32>, Vec<usize>, bevy_hao::cpu::ao::TraceWork) {
    use bevy_hao::cpu::ao::{TraceWork, ray_rotation, voxel_ambient_occlusion_counted};
    use bevy_hao::cpu::contacts::contact_jitter;
    use bevy_hao::cpu::march::ray_start_level;
    let trace = bevy_hao_tools::harness::cpu_trace_settings(settings);
    let w = view.size.x;
    let mut ao = vec![f32::NAN; samples.len()];
    let mut start = vec![0; samples.len()];
    let mut work = TraceWork::default();
    for (i, s) in samples.iter().enumerate() {
        let Some((world, normal)) = *s else { continue };
        let pf = Vec2::new((i as u32 % w) as f32, (i as u32 / w) as f32);
        let rotation = ray_rotation(pf, frame);
        start[i] = ray_start_level(levels, world, 0, rotation);
        let contacts = Some(bevy_hao::cpu::ao::DepthContacts { view, jitter: contact_jitter(pf, frame) });
        let rays = bevy_hao::cpu::temporal::change_rays(trace.rays, change[i]);
        ao[i] = voxel_ambient_occlusion_counted(
            levels,
            contacts,
            world,
            normal,
            rotation,
            &bevy_hao::cpu::ao::TraceSettings { rays, ..trace },
            &mut work,
        );
    }
    (ao, start, work)
}

/// Holds the GPU's noisy AO (no denoise, no accumulation) against the CPU twin traced through `levels`, pixel
/// by pixel. Returns the levels the pixels' first rays start in.
fn assert_trace_matches_cpu(
    app: &mut App,
    settings: &HybridAmbientOcclusion,
    levels: &[bevy_hao::cpu::march::TraceLevel],
) -> std::collections::BTreeMap<usize, usize> {
    let targets = app.world().resource::<Targets>().clone();
    let (_, _, gpu_ao) = read_image_f32(app, targets.debug.ao.clone(), 2);
    let (_, _, samples) = view_samples(app);
    let (cpu_ao, start, _) = cpu_trace(&samples, &view_depth(app), settings, levels, 0);
    let (mut sum, mut count, mut far) = (0.0, 0, 0);
    let mut used = std::collections::BTreeMap::new();
    for i in 0..samples.len() {
        if cpu_ao[i].is_nan() {
            continue;
        }
        *used.entry(start[i]).or_insert(0) += 1;
        let d = (cpu_ao[i] - gpu_ao[i]).abs();
        sum += d;
        count += 1;
        // A ray grazing a voxel edge may go either way: one ray of eight is 0.125 at most.
        if d > 0.13 {
            far += 1;
        }
    }
    let mean = sum / count as f32;
    println!("{count} pixels: mean |CPU - GPU| = {mean:.4}, {far} differ by more than one ray; start levels {used:?}");
    assert!(count > 1000);
    assert!(mean < 0.005, "{mean}");
    assert!(far * 100 <= count, "{far} of {count}");
    used
}

/// The walls seen from above with `settings`, after `frames` frames, and the GPU's voxels with their mips
/// (for a [`bevy_hao::cpu::march::TraceLevel`]).
fn walls_app_and_voxels(
    settings: &HybridAmbientOcclusion,
    frames: usize,
) -> (App, bevy_hao::cpu::march::VoxelMips, bevy_hao::cpu::VoxelGrid) {
    walls_app_and_voxels_with(settings, frames, None)
}

/// [`walls_app_and_voxels`], with a `Spinner` at `spinner` (a dynamic sphere turned a quarter turn a
/// frame) where given.
fn walls_app_and_voxels_with(
    settings: &HybridAmbientOcclusion,
    frames: usize,
    spinner: Option<Vec3>,
) -> (App, bevy_hao::cpu::march::VoxelMips, bevy_hao::cpu::VoxelGrid) {
    let camera = Transform::from_xyz(1.5, 9.0, 5.5).looking_at(Vec3::new(1.0, 0.0, 0.5), Vec3::Y);
    let mut app = scene_app(camera, Ao::Hao(settings.clone()), move |c, m, mat| {
        walls(c, m, mat.clone());
        if let Some(at) = spinner {
            // A UV sphere of 32 segments: a quarter turn maps its triangles onto each other, so its voxels stay
            // the same while it moves a metre (its box's corners) a frame.
            let sphere = Sphere::new(SPINNER_RADIUS).mesh().uv(32, 16);
            c.spawn((
                Mesh3d(m.add(sphere)),
                MeshMaterial3d(mat),
                Transform::from_translation(at),
                DynamicOccluder,
                Spinner,
            ));
        }
    });
    app.add_systems(Update, |mut q: Query<&mut Transform, With<Spinner>>| {
        for mut t in &mut q {
            t.rotate_y(std::f32::consts::FRAC_PI_2);
        }
    });
    run(&mut app, frames);
    let occupancy = read_occupancy(&mut app);
    let assets = grid_assets(&app).unwrap();
    (app, bevy_hao::cpu::march::VoxelMips::new(&occupancy, assets.mip_levels), assets.grid)
}

/// The CPU twin's trace of render frame `frame` as the GPU stores it: one texel per pixel, or per 2x2 block
/// at half resolution, traced from the block's pixel of the frame (`traced_pixel`) with that pixel's noise
/// (`noise_frame`), stored as the GPU stores it (`TracedTexel::stored`). In a checkerboard only the texels
/// the frame traces (`texel_traced`); the others are the `previous` frame's.
fn cpu_trace_frame(
    samples: &[Option<(Vec3, Vec3)>],
    view: &bevy_hao::cpu::contacts::ViewDepth,
    settings: &HybridAmbientOcclusion,
    levels: &[bevy_hao::cpu::march::TraceLevel],
    frame: u32,
    previous: Option<&bevy_hao::cpu::temporal::TraceFrame>,
    change: &[f32],
) -> bevy_hao::cpu::temporal::TraceFrame {
    use bevy_hao::cpu::ao::{noise_frame, texel_traced, trace_turn, traced_pixel};
    use bevy_hao::cpu::temporal::{TraceFrame, TracedTexel};
    let half_resolution = settings.trace_parameters().2;
    let checkerboard = settings.uses_checkerboard() && previous.is_some();
    let (size, w, view_from_world) = (view.size, view.size.x, view.view_from_world);
    let trace_size = if half_resolution { (size + UVec2::ONE) / 2 } else { size };
    let turn = trace_turn(frame, checkerboard);
    let pixel_of = |t: UVec2| {
        let p = traced_pixel(t, turn, size, half_resolution);
        (p.y * w + p.x) as usize
    };
    // `cpu_trace` over the pixels traced this frame only.
    let mut sparse = vec![None; samples.len()];
    for t in (0..trace_size.x * trace_size.y).map(|t| UVec2::new(t % trace_size.x, t / trace_size.x)) {
        if texel_traced(t, frame, checkerboard) {
            sparse[pixel_of(t)] = samples[pixel_of(t)];
        }
    }
    let (ao, _, _) = cpu_trace_near_change(&sparse, view, settings, levels, noise_frame(turn, half_resolution), change);
    TraceFrame::traced(frame, checkerboard, settings.trace_parameters().0, trace_size, previous, |t| {
        let pixel = pixel_of(t);
        samples[pixel].map(|(world, normal)| {
            // Where occluders moved near it, the texel says so and is filtered wider.
            let changed = bevy_hao::cpu::temporal::filters_wide(change[pixel]);
            TracedTexel { ao: ao[pixel], depth: -view_from_world.transform_point3(world).z, normal, changed }.stored()
        })
    })
}

/// Holds the GPU's temporal accumulation over a still camera, at full or half resolution, to the CPU
/// twin's: the trace of every frame (`cpu_trace_frame`) through `bevy_hao::cpu::temporal::accumulate_still`.
fn assert_accumulation_matches_cpu(quality: HaoQuality) {
    assert_accumulation_matches_cpu_with(quality, None, None);
}

/// [`assert_accumulation_matches_cpu`], with a `Spinner` at `spinner` where given: a dynamic occluder that moves
/// every frame and leaves the voxels as they are, so that the twin's trace of the last voxels still holds,
/// while the history near it is capped (`cpu::temporal::change_cap`) and the trace traces more rays there
/// (`change_rays`), as the twin must. With `still_history` (`still_accumulation_frames`, longer than the 8
/// frames a moving view keeps), the AO is turned off for two frames once the grid is built and the history
/// starts again from that frame: a pixel of a still view then shows the AO it showed while its history
/// strays little (`cpu::temporal::stable_ao`), which depends on every frame of the history, and the twin
/// follows them all from the restart.
fn assert_accumulation_matches_cpu_with(quality: HaoQuality, spinner: Option<Vec3>, still_history: Option<u32>) {
    use bevy_hao::cpu::march::TraceLevel;
    use bevy_hao::cpu::temporal::{MovedVoxels, accumulate_still, occlusion_change};
    let _gpu = gpu_lock();
    // With the filter (`cpu::temporal::prefilter`), wider than its default.
    // The history as long still as in motion (8 frames), so that the frames traced while the grid was being
    // built leave it (`a_still_view_keeps_a_longer_history_and_shimmers_less` holds the longer one); with
    // `still_history`, that long, from the restart.
    let still_count = still_history.unwrap_or(8);
    let settings = HybridAmbientOcclusion {
        denoise_radius: 2,
        accumulation_frames: 8,
        still_accumulation_frames: still_count,
        quality,
        ..hao_settings()
    };
    let half_resolution = settings.trace_parameters().2;
    let frames_per_trace = settings.frames_per_trace() as usize;
    // Long enough for the first frames, traced while the grid was still being built, to have left the
    // history (their weight is (7/8)^50 by the end).
    let frames_run = 20 + 50 * frames_per_trace;
    let (mut app, mips, grid) = walls_app_and_voxels_with(&settings, frames_run, spinner);
    // The render frame the history started again from (the twin's first frame, up to the latency).
    let restart = still_history.map(|_| {
        let mut q = app.world_mut().query_filtered::<Entity, With<TheCamera>>();
        let camera = q.single(app.world()).unwrap();
        app.world_mut().entity_mut(camera).remove::<HybridAmbientOcclusion>();
        run(&mut app, 2);
        app.world_mut().entity_mut(camera).insert(settings.clone());
        let restart = app.world().resource::<bevy::diagnostic::FrameCount>().0 as usize;
        run(&mut app, 100 * frames_per_trace);
        restart
    });
    let levels = [TraceLevel { origin: grid.origin, cell_size: grid.cell_size, window_min: IVec3::ZERO, mips: &mips }];
    // The spinner as the voxel grid lists it: its box, whose corners a quarter turn moves by its diagonal's
    // side (2 r).
    let moved: Vec<MovedVoxels> = spinner
        .map(|c| MovedVoxels { min: c - SPINNER_RADIUS, max: c + SPINNER_RADIUS, motion: 2.0 * SPINNER_RADIUS })
        .into_iter()
        .collect();
    let targets = app.world().resource::<Targets>().clone();
    let (_, _, gpu) = read_image_f32(&mut app, targets.debug.ao.clone(), 2);
    let rendered = app.world().resource::<bevy::diagnostic::FrameCount>().0 as usize;
    let (w, h, samples) = view_samples(&mut app);
    // The noise turns every frame with the render frame's number: the twin's frames for the frames this run
    // may have read back.
    let mut q = app.world_mut().query_filtered::<&GlobalTransform, With<TheCamera>>();
    let view_from_world = q.single(app.world()).unwrap().to_matrix().inverse();
    let view = view_depth(&mut app);
    let change: Vec<f32> = samples
        .iter()
        .map(|s| s.map_or(0.0, |(p, n)| occlusion_change(p, n, &moved, settings.max_distance, settings.falloff)))
        .collect();
    let near = change.iter().filter(|&&c| c > 0.0).count();
    let more_rays = change.iter().filter(|&&c| c >= bevy_hao::cpu::temporal::CHANGE_RAYS_FROM).count();
    if spinner.is_some() {
        println!("{near} pixels near the spinner, {more_rays} of them with more rays");
        assert!(more_rays > 200 && near > more_rays, "{near} {more_rays}");
    }
    let mut frames: Vec<bevy_hao::cpu::temporal::TraceFrame> = Vec::new();
    for f in 0..rendered + 2 {
        let frame = cpu_trace_frame(&samples, &view, &settings, &levels, f as u32, frames.last(), &change);
        frames.push(frame);
    }
    let pixels: Vec<Option<(f32, Vec3)>> =
        samples.iter().map(|s| s.map(|(p, n)| (-view_from_world.transform_point3(p).z, n))).collect();
    let accumulate = |frames| {
        let size = UVec2::new(w, h);
        let still = still_count as f32;
        accumulate_still(frames, &pixels, &change, size, half_resolution, 8.0, still, settings.denoise_radius)
    };
    let error = |cpu: &[f32]| {
        let (mut sum, mut n) = (0.0f64, 0);
        for (i, g) in gpu.iter().enumerate() {
            if samples[i].is_none() || cpu[i].is_nan() {
                continue;
            }
            sum += (cpu[i] - g).abs() as f64;
            n += 1;
        }
        sum / n as f64
    };
    // The GPU's image is the twin's accumulation of the frames first..=last for some last frame near the
    // end (the readback's latency is not known) and a first frame long enough before it.
    let back = [24, 32].map(|b| b * frames_per_trace);
    let (mut best, mut best_run, mut single) = (f64::MAX, (0, 0), f64::MAX);
    for last in frames.len().saturating_sub(12)..frames.len() {
        single = single.min(error(&accumulate(&frames[last..=last])));
        let firsts: Vec<usize> = match restart {
            Some(r) => (r.saturating_sub(3)..=r + 3).collect(),
            None => back.map(|b| last.saturating_sub(b)).to_vec(),
        };
        for first in firsts {
            let e = error(&accumulate(&frames[first..=last]));
            if e < best {
                (best, best_run) = (e, (first, last));
            }
        }
    }
    println!("accumulated frames {best_run:?}: mean |twin - GPU| = {best:.5}; the closest single frame: {single:.5}");
    assert!(best < 0.0005, "{best}");
    assert!(single > 5.0 * best, "{single} against {best}: the GPU did not accumulate");
    assert!(take_render_errors().is_empty());
}

#[test]
fn temporal_accumulation_matches_its_cpu_twin() {
    assert_accumulation_matches_cpu(HaoQuality::Custom { rays: 4, steps: 48, half_resolution: false });
}

/// Near an occluder that moves, the history is capped by how much the occlusion can have changed and the
/// trace traces more rays: the twin must cap and trace the same pixels alike.
#[test]
fn accumulation_near_a_moving_occluder_matches_its_cpu_twin() {
    assert_accumulation_matches_cpu_with(
        HaoQuality::Custom { rays: 2, steps: 48, half_resolution: true },
        Some(Vec3::new(1.0, SPINNER_RADIUS, 0.5)),
        None,
    );
}

/// Where the view stands still its history keeps up to `still_accumulation_frames`, and a pixel whose
/// history strays little from the AO it showed shows it again (`cpu::temporal::stable_ao`): the twin must
/// keep the same AO at the same pixels.
#[test]
fn a_still_views_shown_ao_matches_its_cpu_twin() {
    assert_accumulation_matches_cpu_with(
        HaoQuality::Custom { rays: 4, steps: 48, half_resolution: false },
        None,
        Some(32),
    );
}

/// At half resolution each block traces one of its pixels a frame, in turn, and each pixel accumulates its
/// own traces; the twin must pick the same pixels, noise and stand-ins frame by frame to match.
#[test]
fn half_resolution_accumulation_matches_its_cpu_twin() {
    assert_accumulation_matches_cpu(HaoQuality::Custom { rays: 2, steps: 48, half_resolution: true });
}

/// `Low` traces half its blocks a frame, in a checkerboard, and keeps the others' last trace: the twin must
/// keep the same texels and turn the same pixels and noise to match.
#[test]
fn checkerboard_accumulation_matches_its_cpu_twin() {
    let settings = HybridAmbientOcclusion { accumulation_frames: 8, quality: HaoQuality::Low, ..default() };
    assert!(settings.uses_checkerboard());
    assert_accumulation_matches_cpu(HaoQuality::Low);
}

#[test]
fn the_gpu_trace_matches_its_cpu_twin() {
    use bevy_hao::cpu::march::TraceLevel;
    let _gpu = gpu_lock();
    let mut mean_ao = Vec::new();
    for depth_contacts in [false, true] {
        let settings =
            HybridAmbientOcclusion { denoise_radius: 0, accumulation_frames: 1, depth_contacts, ..hao_settings() };
        let (mut app, mips, grid) = walls_app_and_voxels(&settings, 8);
        let levels =
            [TraceLevel { origin: grid.origin, cell_size: grid.cell_size, window_min: IVec3::ZERO, mips: &mips }];
        assert_trace_matches_cpu(&mut app, &settings, &levels);
        let (ao, samples) = ao_and_samples(&mut app);
        let open: Vec<f32> = samples.iter().zip(&ao).filter(|(s, _)| s.is_some()).map(|(_, a)| *a).collect();
        mean_ao.push(open.iter().sum::<f32>() / open.len() as f32);
        assert!(take_render_errors().is_empty());
    }
    // The walls' feet and corners hold contacts closer than the voxels see: the depth contacts darken them.
    println!("mean AO without depth contacts {:.4}, with {:.4}", mean_ao[0], mean_ao[1]);
    assert!(mean_ao[1] < mean_ao[0] - 0.002, "{mean_ao:?}");
}

/// Small things lying on the floor, each thinner than a voxel (0.25 m): slabs 4 and 8 cm thick, a
/// 12 cm cube, a rod, a step: their contacts with the floor are closer than the voxels can tell.
fn clutter(commands: &mut Commands, meshes: &mut Assets<Mesh>, material: Handle<StandardMaterial>) {
    for (size, at) in [
        (Vec3::new(0.6, 0.04, 0.5), Vec3::new(-0.6, 0.02, 0.0)),
        (Vec3::new(0.5, 0.08, 0.7), Vec3::new(0.3, 0.04, -0.4)),
        (Vec3::splat(0.12), Vec3::new(0.5, 0.06, 0.5)),
        (Vec3::new(1.2, 0.06, 0.06), Vec3::new(-0.2, 0.03, 0.8)),
        (Vec3::new(0.8, 0.15, 0.4), Vec3::new(-0.4, 0.075, -0.9)),
    ] {
        commands.spawn((
            box_at(meshes, size),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at),
            StaticOccluder,
        ));
    }
}

/// The mean AO of `scene` seen from `camera` with one frame of HAO (`settings`, no denoiser, no
/// accumulation), after checking that the trace matches its CPU twin pixel by pixel over at least `pixels`
/// pixels that show a surface (on average, and at most one pixel in a thousand apart by over 0.05), and the
/// twin's work. `name` labels the printed line.
fn traced_like_the_twin(
    name: &str,
    camera: Transform,
    settings: HybridAmbientOcclusion,
    scene: fn(&mut Commands, &mut Assets<Mesh>, Handle<StandardMaterial>),
    pixels: usize,
) -> (f32, bevy_hao::cpu::ao::TraceWork) {
    use bevy_hao::cpu::march::TraceLevel;
    let settings = HybridAmbientOcclusion { denoise_radius: 0, accumulation_frames: 1, ..settings };
    let mut app = scene_app(camera, Ao::Hao(settings.clone()), scene);
    run(&mut app, 8);
    let occupancy = read_occupancy(&mut app);
    let assets = grid_assets(&app).unwrap();
    let mips = bevy_hao::cpu::march::VoxelMips::new(&occupancy, assets.mip_levels);
    let grid = assets.grid;
    let levels = [TraceLevel { origin: grid.origin, cell_size: grid.cell_size, window_min: IVec3::ZERO, mips: &mips }];
    let (gpu, samples) = ao_and_samples(&mut app);
    let (cpu, _, work) = cpu_trace(&samples, &view_depth(&mut app), &settings, &levels, 0);
    let (mut difference, mut ao, mut n, mut apart) = (0.0, 0.0, 0, 0);
    for (g, c) in gpu.iter().zip(&cpu).filter(|(_, c)| !c.is_nan()) {
        difference += (g - c).abs();
        apart += usize::from((g - c).abs() > 0.05);
        ao += g;
        n += 1;
    }
    let (difference, ao) = (difference / n as f32, ao / n as f32);
    println!(
        "{name}: {n} pixels, mean |CPU - GPU| {difference:.4}, {apart} pixels apart by over 0.05, mean AO {ao:.4}"
    );
    assert!(n > pixels, "{n} pixels");
    assert!(difference < 0.002, "{difference}");
    // A few pixels may tip one ray either way (a point on a depth edge); a rule applied differently tips many.
    assert!(apart * 1000 <= n, "{apart} of {n} pixels apart");
    assert!(take_render_errors().is_empty());
    (ao, work)
}

/// The depth contacts on the GPU as on the CPU twin (`bevy_hao::cpu::contacts`), on a view close enough
/// that a voxel spans several pixels and full of contacts: the trace matches the twin's pixel by pixel, with
/// `High`'s 8 points a ray and `Medium`'s 4, and the contacts darken the floor around the things lying on it.
/// From farther back, where a pixel is over a quarter of a cell, the points are lifted an eighth of a cell
/// rather than half a pixel (`contact_lift`), on both: with the half pixel alone in WGSL, 127 pixels of that view
/// came out apart.
#[test]
fn the_gpu_depth_contacts_match_their_cpu_twin() {
    let _gpu = gpu_lock();
    let near = Transform::from_xyz(0.0, 1.6, 1.8).looking_at(Vec3::new(0.0, 0.0, -0.1), Vec3::Y);
    let far = Transform::from_xyz(0.0, 4.8, 5.4).looking_at(Vec3::new(0.0, 0.0, -0.1), Vec3::Y);
    let cases = [
        (false, HaoQuality::High, near),
        (true, HaoQuality::High, near),
        (true, HaoQuality::Medium, near),
        (true, HaoQuality::High, far),
    ];
    let mean_ao = cases.map(|(depth_contacts, quality, camera)| {
        let settings = HybridAmbientOcclusion { depth_contacts, quality, ..hao_settings() };
        assert_eq!(settings.contact_samples(), if quality == HaoQuality::High { 8 } else { 4 });
        let label = format!("depth contacts {depth_contacts}, {quality:?}, camera at {}", camera.translation);
        traced_like_the_twin(&label, camera, settings, clutter, 5000).0
    });
    assert!(mean_ao[1] < mean_ao[0] - 0.01, "{mean_ao:?}");
}

/// Thin poles and a rail, each a fraction of a voxel (0.25 m) thick: rays that pass beside them cross
/// their voxels, whose emptier part the view sees through to the floor and the wall behind.
fn poles(commands: &mut Commands, meshes: &mut Assets<Mesh>, material: Handle<StandardMaterial>) {
    for (size, at) in [
        (Vec3::new(0.04, 2.0, 0.04), Vec3::new(-0.9, 1.0, -0.3)),
        (Vec3::new(0.04, 2.0, 0.04), Vec3::new(0.1, 1.0, 0.2)),
        (Vec3::new(0.04, 2.0, 0.04), Vec3::new(1.1, 1.0, -0.6)),
        (Vec3::new(2.4, 0.04, 0.04), Vec3::new(0.1, 1.2, -0.3)),
        (Vec3::new(4.0, 2.5, 0.3), Vec3::new(0.0, 1.25, -2.5)),
    ] {
        commands.spawn((
            box_at(meshes, size),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at),
            StaticOccluder,
        ));
    }
}

/// The voxel hits the view shows in free space are passed on the GPU as on the CPU twin
/// (`ViewDepth::shows_free_space`): the trace matches the twin pixel by pixel with and without, and passing
/// them lightens the floor beside the poles, whose voxels are far wider than they are.
#[test]
fn the_gpu_free_space_passes_match_their_cpu_twin() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.3, 1.5, 3.5).looking_at(Vec3::new(0.0, 0.6, -0.5), Vec3::Y);
    let mean_ao = [false, true].map(|depth_free_space| {
        // Without depth contacts, whose near passes pass the hits near the surface the view shows in free
        // space whatever `depth_free_space` says.
        let settings = HybridAmbientOcclusion {
            depth_free_space: Some(depth_free_space),
            depth_contacts: false,
            ..hao_settings()
        };
        traced_like_the_twin(&format!("free space {depth_free_space}"), camera, settings, poles, 4000).0
    });
    assert!(mean_ao[1] > mean_ao[0] + 0.005, "{mean_ao:?}");
}

/// A ball resting on the floor, as in the README's quick start (radius 0.5 m, two cells of this volume).
fn resting_ball(commands: &mut Commands, meshes: &mut Assets<Mesh>, material: Handle<StandardMaterial>) {
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.5).mesh().uv(48, 24))),
        MeshMaterial3d(material),
        Transform::from_xyz(0.0, 0.5, 0.0),
        StaticOccluder,
    ));
}

/// Where the view hides a ray's march start (`bevy_hao::cpu::near`: the floor within a cell under a resting
/// ball, the ball's own underside), the GPU measures its depth contacts along the shown surface's normal and
/// marches the first cells past the surface's own as the CPU twin does: the trace matches the twin pixel by
/// pixel on a close view where thousands of rays take that way and hundreds stop in those cells (a near march
/// the GPU took otherwise would move the mean by several times the bound).
#[test]
fn under_a_resting_ball_the_gpu_marches_the_first_cells_as_its_cpu_twin() {
    let _gpu = gpu_lock();
    // Low and close, the floor around the contact and the ball's underside fill the view.
    let camera = Transform::from_xyz(0.3, 0.25, 0.9).looking_at(Vec3::new(0.0, 0.1, 0.3), Vec3::Y);
    let (_, work) = traced_like_the_twin("resting ball", camera, hao_settings(), resting_ball, 5000);
    println!("{work:?}");
    // (Measured: 5187 of 46784 rays marched there, 734 stopped, against 14278 stopped by contacts.)
    assert!(work.near_voxel_marches > 3000, "{work:?}");
    assert!(work.near_voxel_hits > 300, "{work:?}");
}

/// The denoiser on the GPU as on its CPU twin (`bevy_hao::cpu::temporal::prefilter`): without accumulation
/// each pixel's AO is this frame's trace filtered over its 3x3 neighbours, and the AO PBR reads is the twin's
/// filter over the twin's trace.
#[test]
fn the_gpu_denoiser_matches_its_cpu_twin() {
    use bevy_hao::cpu::march::TraceLevel;
    use bevy_hao::cpu::temporal::{TracedTexel, prefilter};
    let _gpu = gpu_lock();
    let settings = HybridAmbientOcclusion { denoise_radius: 2, accumulation_frames: 1, ..hao_settings() };
    let (mut app, mips, grid) = walls_app_and_voxels(&settings, 8);
    let levels = [TraceLevel { origin: grid.origin, cell_size: grid.cell_size, window_min: IVec3::ZERO, mips: &mips }];
    let targets = app.world().resource::<Targets>().clone();
    let (_, _, gpu) = read_image_f32(&mut app, targets.debug.ao.clone(), 2);
    let (w, h, samples) = view_samples(&mut app);
    let mut q = app.world_mut().query_filtered::<&GlobalTransform, With<TheCamera>>();
    let view_from_world = q.single(app.world()).unwrap().to_matrix().inverse();
    let (noisy, _, _) = cpu_trace(&samples, &view_depth(&mut app), &settings, &levels, 0);
    // The trace as the GPU stores it: AO, view depth, normal, in its 64 bits (`TracedTexel::stored`).
    let trace: Vec<Option<TracedTexel>> = samples
        .iter()
        .zip(&noisy)
        .map(|(s, &ao)| {
            s.map(|(world, normal)| {
                let depth = -view_from_world.transform_point3(world).z;
                TracedTexel { ao, depth, normal, changed: false }.stored()
            })
        })
        .collect();
    let size = UVec2::new(w, h);
    let (mut filtered_error, mut noisy_error, mut n) = (0.0f64, 0.0f64, 0);
    for i in 0..samples.len() {
        if trace[i].is_none() {
            continue;
        }
        let twin = prefilter(&trace, size, UVec2::new(i as u32 % w, i as u32 / w), settings.denoise_radius);
        filtered_error += (twin - gpu[i]).abs() as f64;
        noisy_error += (noisy[i] - gpu[i]).abs() as f64;
        n += 1;
    }
    let (filtered_error, noisy_error) = (filtered_error / n as f64, noisy_error / n as f64);
    println!(
        "{n} pixels: mean |twin - GPU| = {filtered_error:.5}; the unfiltered trace against the GPU: {noisy_error:.5}"
    );
    assert!(n > 1000);
    assert!(filtered_error < 0.002, "{filtered_error}");
    assert!(noisy_error > 3.0 * filtered_error, "{noisy_error} against {filtered_error}: the GPU did not filter");
    assert!(take_render_errors().is_empty());
}

/// `HybridAmbientOcclusion::ignore_back_hits` on the GPU as on the CPU twin: a single-sided plane 1.5 m
/// over the floor, facing up, seen from the side. Under it, rays that reach its back within 60 degrees of its
/// normal pass with the setting and stop without it; the GPU's noisy AO equals the twin's (traced through
/// the GPU's voxels and their normals) both ways, and the floor under the plane is lighter with it.
#[test]
fn rays_pass_through_the_backs_of_surfaces_on_the_gpu_as_on_its_cpu_twin() {
    use bevy_hao::cpu::march::{TraceLevel, VoxelMips};
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 1.0, 5.0).looking_at(Vec3::new(0.0, 0.0, 0.0), Vec3::Y);
    let mut under = Vec::new();
    for ignore_back_hits in [false, true] {
        // Without the depth prepass's part (its near passes would let the floor's rays through the plane's
        // back too, which the view does not draw): the voxels alone.
        let settings = HybridAmbientOcclusion {
            denoise_radius: 0,
            accumulation_frames: 1,
            ignore_back_hits,
            depth_contacts: false,
            ..hao_settings()
        };
        let volume = VoxelVolume { attributes: true, ..volume() };
        let mut app = scene_app_in(camera, Ao::Hao(settings.clone()), false, volume, |c, m, mat| {
            c.spawn((
                Mesh3d(m.add(Plane3d::default().mesh().size(4.0, 4.0))),
                MeshMaterial3d(mat),
                Transform::from_xyz(0.0, 1.5, 0.0),
                StaticOccluder,
            ));
        });
        run(&mut app, 8);
        let records = read_records(&mut app);
        let assets = grid_assets(&app).unwrap();
        let mips = VoxelMips::new(&records, assets.mip_levels);
        let grid = assets.grid;
        let levels =
            [TraceLevel { origin: grid.origin, cell_size: grid.cell_size, window_min: IVec3::ZERO, mips: &mips }];
        assert_trace_matches_cpu(&mut app, &settings, &levels);
        // The floor under the plane, away from its edges.
        let (ao, samples) = ao_and_samples(&mut app);
        let values: Vec<f32> = samples
            .iter()
            .zip(&ao)
            .filter_map(|(s, a)| s.filter(|(p, _)| p.y < 0.05 && p.x.abs() < 1.2 && p.z.abs() < 1.2).map(|_| *a))
            .collect();
        assert!(values.len() > 200, "{} floor pixels under the plane", values.len());
        under.push(values.iter().sum::<f32>() / values.len() as f32);
        assert!(take_render_errors().is_empty());
    }
    println!(
        "floor under a single-sided plane: AO {:.3} stopping at its back, {:.3} passing through",
        under[0], under[1]
    );
    assert!(under[1] > under[0] + 0.2, "{under:?}");
}

/// Cascades of 64^3 with 0.25 m cells at the finest: 16, 32 and 64 m across.
fn small_cascades() -> VoxelVolume {
    VoxelVolume { bounds: VolumeBounds::FollowCamera { cascades: 3, cells: 64, finest_cell_size: 0.25 }, ..default() }
}

/// A long floor with a wall along its left side and a row of pillars going away from the camera.
fn walls_and_pillars(commands: &mut Commands, meshes: &mut Assets<Mesh>, material: Handle<StandardMaterial>) {
    commands.spawn((
        box_at(meshes, Vec3::new(0.3, 3.0, 60.0)),
        MeshMaterial3d(material.clone()),
        Transform::from_xyz(-3.15, 1.5, -28.0),
        StaticOccluder,
    ));
    commands.spawn((
        box_at(meshes, Vec3::new(8.0, 0.2, 60.0)),
        MeshMaterial3d(material.clone()),
        Transform::from_xyz(0.0, -0.1, -30.0),
        StaticOccluder,
    ));
    for k in 0..10 {
        commands.spawn((
            box_at(meshes, Vec3::new(0.6, 2.5, 0.6)),
            MeshMaterial3d(material.clone()),
            Transform::from_xyz(1.5 - (k % 2) as f32 * 3.0, 1.25, -2.0 - 4.0 * k as f32),
            StaticOccluder,
        ));
    }
}

#[test]
fn the_gpu_trace_matches_its_cpu_twin_across_cascades() {
    use bevy_hao::cpu::march::{TraceLevel, VoxelMips};
    let _gpu = gpu_lock();
    let settings = HybridAmbientOcclusion { denoise_radius: 0, accumulation_frames: 1, ..hao_settings() };
    // Low over the floor, looking down the row of pillars: the view reaches from the finest cascade to the
    // coarsest.
    let camera = Transform::from_xyz(0.5, 2.0, 4.0).looking_at(Vec3::new(0.0, 0.0, -20.0), Vec3::Y);
    let mut app = scene_app_in(camera, Ao::Hao(settings.clone()), false, small_cascades(), walls_and_pillars);
    run(&mut app, 8);
    let cascades = read_cascades(&mut app, false);
    let mips: Vec<VoxelMips> =
        cascades.iter().map(|c| VoxelMips::new(&c.occupancy, bevy_hao::cpu::cascade::CASCADE_MIP_LEVELS)).collect();
    let levels: Vec<TraceLevel> = cascades
        .iter()
        .zip(&mips)
        .map(|(c, m)| TraceLevel {
            origin: c.level.origin,
            cell_size: c.level.cell_size,
            window_min: c.level.window_min,
            mips: m,
        })
        .collect();
    let used = assert_trace_matches_cpu(&mut app, &settings, &levels);
    assert!(used.len() >= 2, "the view spans {used:?}");
    assert!(take_render_errors().is_empty());
}

#[test]
fn debug_views_show_ao_voxels_point_counts_and_the_static_dynamic_split() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(1.5, 6.0, 7.5).looking_at(Vec3::new(0.5, 0.5, 0.0), Vec3::Y);
    let volume = VoxelVolume { attributes: true, ..volume() };
    let mut app = scene_app_in(camera, Ao::Hao(hao_settings()), false, volume, |c, m, mat| {
        walls(c, m, mat.clone());
        c.spawn((
            box_at(m, Vec3::new(1.5, 1.5, 1.5)),
            MeshMaterial3d(mat),
            Transform::from_xyz(1.0, 0.75, 1.0),
            DynamicOccluder,
        ));
    });
    run(&mut app, 6);
    let cam = app.world_mut().query_filtered::<Entity, With<TheCamera>>().single(app.world()).unwrap();
    let pixels = |app: &mut App, view: HaoDebugView| view_pixels(app, cam, view);
    let gray = |p: &[u8; 3]| p[0].abs_diff(p[1]) <= 2 && p[1].abs_diff(p[2]) <= 2;
    let final_image = pixels(&mut app, HaoDebugView::Final);
    let ao = pixels(&mut app, HaoDebugView::AmbientOcclusion);
    assert!(ao.iter().all(gray), "the AO view is grayscale");
    assert!(
        ao.iter().any(|p| p[0] < 230) && ao.iter().any(|p| p[0] > 250),
        "the AO view shows occlusion and open surfaces"
    );
    assert_ne!(ao, final_image);
    let voxels = pixels(&mut app, HaoDebugView::Voxels);
    let pale = |p: &&[u8; 3]| p.iter().max().unwrap() - p.iter().min().unwrap() <= 30 && p[0] > 100;
    assert!(voxels.iter().filter(pale).count() * 2 > voxels.len(), "the voxel view shows pale boxes");
    assert_ne!(voxels, final_image);
    let split = pixels(&mut app, HaoDebugView::StaticDynamic);
    let c = |p: &[u8; 3]| p.map(i32::from);
    let orange = split.iter().map(c).filter(|p| p[0] > p[1] + 30 && p[1] > p[2] + 30).count();
    let blue = split.iter().map(c).filter(|p| p[2] > p[0] + 30).count();
    assert!(orange > 20 && blue > 200, "dynamic voxels orange ({orange}) and static ones blue ({blue})");
    let counts = pixels(&mut app, HaoDebugView::PointCounts);
    assert!(counts.iter().filter(|p| !gray(p)).count() * 2 > counts.len(), "the heat map is colored");
    // Every surface has the one material, sRGB 0.8 grey: the albedo view is grey, darker than the voxel view's
    // pale boxes (linear 0.6 against 0.9), shaded by face.
    let albedo = pixels(&mut app, HaoDebugView::Albedo);
    let lit = |p: &&[u8; 3]| p[0] > 40;
    assert!(albedo.iter().filter(lit).all(gray), "the albedo view is grey");
    let mean =
        |v: &[[u8; 3]]| v.iter().filter(lit).map(|p| p[0] as f32).sum::<f32>() / v.iter().filter(lit).count() as f32;
    assert!(mean(&albedo) < mean(&voxels) - 30.0, "albedo {} voxels {}", mean(&albedo), mean(&voxels));
    // The normals view (n * 0.5 + 0.5, into an sRGB target): the boxes' tops face up (green), the walls
    // toward the camera (+z, blue) and to the side (+x, red); the floor, 0.2 thick in 0.25 cells, has its
    // top and bottom in one voxel layer: their normals cancel (grey).
    let normals = pixels(&mut app, HaoDebugView::Normals);
    let c = |p: &[u8; 3]| p.map(i32::from);
    let facing =
        |axis: usize| normals.iter().map(c).filter(|p| (0..3).all(|k| k == axis || p[axis] > p[k] + 30)).count();
    let cancelled = normals.iter().map(c).filter(|p| gray(&p.map(|x| x as u8)) && (150..200).contains(&p[0])).count();
    let (x, y, z) = (facing(0), facing(1), facing(2));
    println!("normals view: {x} +x, {y} +y, {z} +z, {cancelled} cancelled of {} pixels", normals.len());
    assert!(x > 200 && y > 30 && z > 400 && cancelled > 600, "{x} +x, {y} +y, {z} +z, {cancelled} cancelled");
    assert!(take_render_errors().is_empty());
}

#[test]
fn hao_dims_ambient_light_in_deferred_rendering_too() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 1.6, 0.0).looking_at(Vec3::new(0.0, 0.0, 0.01), Vec3::Y);
    let render = |hao: bool| {
        let mut app = scene_app_with(camera, if hao { Ao::Hao(roof_hao()) } else { Ao::None }, true, roof);
        run(&mut app, 8);
        let l = luminance(&mut app);
        assert!(take_render_errors().is_empty());
        l
    };
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let (with, without) = (render(true), render(false));
    println!("deferred, ambient only: mean {:.1} with HAO, {:.1} without", mean(&with), mean(&without));
    assert!(mean(&without) > 20.0, "the deferred image is lit");
    assert!(mean(&with) < mean(&without) - 5.0, "HAO darkens ambient light in deferred rendering");
}

/// A room 10 x 4 x 10 m with a doorway, a skylight and two pillars (world-space parts), on the test floor.
fn room() -> Vec<bevy_hao::cpu::TriangleMesh> {
    use bevy_hao_tools::meshes::builtin::cuboid;
    vec![
        cuboid(Vec3::new(-5.0, 0.0, -5.3), Vec3::new(5.0, 4.0, -5.0)),
        cuboid(Vec3::new(-5.3, 0.0, -5.3), Vec3::new(-5.0, 4.0, 5.3)),
        cuboid(Vec3::new(5.0, 0.0, -5.3), Vec3::new(5.3, 4.0, 5.3)),
        cuboid(Vec3::new(-5.0, 0.0, 5.0), Vec3::new(1.0, 4.0, 5.3)),
        cuboid(Vec3::new(2.5, 0.0, 5.0), Vec3::new(5.0, 4.0, 5.3)),
        cuboid(Vec3::new(1.0, 2.5, 5.0), Vec3::new(2.5, 4.0, 5.3)),
        cuboid(Vec3::new(-5.3, 4.0, -5.3), Vec3::new(5.3, 4.3, -1.0)),
        cuboid(Vec3::new(-5.3, 4.0, 1.0), Vec3::new(5.3, 4.3, 5.3)),
        cuboid(Vec3::new(-5.3, 4.0, -1.0), Vec3::new(-1.0, 4.3, 1.0)),
        cuboid(Vec3::new(1.0, 4.0, -1.0), Vec3::new(5.3, 4.3, 1.0)),
        cuboid(Vec3::new(-2.5, 0.0, -2.5), Vec3::new(-1.9, 4.0, -1.9)),
        cuboid(Vec3::new(1.9, 0.0, -2.5), Vec3::new(2.5, 4.0, -1.9)),
        cuboid(Vec3::new(-1.0, 0.0, -4.0), Vec3::new(1.0, 0.8, -3.0)),
    ]
}

/// HAO (denoised, as PBR reads it) against a ray-traced reference of `parts` plus the test floor, from a
/// camera inside the room: the mean absolute error over the view.
fn room_error(parts: Vec<bevy_hao::cpu::TriangleMesh>, volume: VoxelVolume) -> f32 {
    use bevy_hao_tools::meshes::builtin::cuboid;
    use bevy_hao_tools::reference::{OccluderView, ReferenceScene, reference_ao};
    let hao = HybridAmbientOcclusion::default();
    let camera = Transform::from_xyz(3.5, 1.7, 3.5).looking_at(Vec3::new(-3.0, 0.6, -3.0), Vec3::Y);
    let spawn_parts = parts.clone();
    let mut app = scene_app_in(camera, Ao::Hao(hao.clone()), false, volume, move |commands, meshes, material| {
        for p in &spawn_parts {
            commands.spawn((
                Mesh3d(meshes.add(bevy_mesh(p, Layout::U32))),
                MeshMaterial3d(material.clone()),
                StaticOccluder,
            ));
        }
    });
    run(&mut app, 10);
    let targets = app.world().resource::<Targets>().clone();
    let (w, h, ao) = read_image_f32(&mut app, targets.debug.ao.clone(), 2);
    let (_, _, depth) = read_image_f32(&mut app, targets.debug.depth.clone(), 0);
    let (_, _, _, normal_bytes) = read_image(&mut app, targets.debug.normal.clone(), 0);
    let mut q = app.world_mut().query_filtered::<(&Camera, &GlobalTransform), With<TheCamera>>();
    let (cam, transform) = q.single(app.world()).unwrap();
    let world_from_clip = transform.to_matrix() * cam.clip_from_view().inverse();
    assert!(take_render_errors().is_empty());
    let mut all = bevy_hao::cpu::TriangleMesh::default();
    all.append(&cuboid(Vec3::new(-8.0, -0.2, -8.0), Vec3::new(8.0, 0.0, 8.0)), Default::default());
    for p in &parts {
        all.append(p, Default::default());
    }
    let scene = ReferenceScene::new(&all);
    let (mut sum, mut n) = (0.0, 0);
    for i in 0..(w * h) as usize {
        if depth[i] <= 0.0 {
            continue;
        }
        let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
        let ndc = Vec3::new((x + 0.5) / w as f32 * 2.0 - 1.0, 1.0 - (y + 0.5) / h as f32 * 2.0, depth[i]);
        let c = &normal_bytes[i * 8..i * 8 + 6];
        let f = |k: usize| f16_at(c, k);
        let normal = Vec3::new(f(0), f(2), f(4)).normalize();
        let rotation = Vec2::new((i as f32 * 0.618_034).fract(), (i as f32 * 0.414_213_5).fract());
        let r = reference_ao(
            &scene,
            world_from_clip.project_point3(ndc),
            normal,
            64,
            rotation,
            hao.max_distance,
            hao.falloff,
            hao.intensity,
            1.0e-3,
            |_, _| OccluderView::Seen,
        );
        sum += (ao[i] - r.ao).abs();
        n += 1;
    }
    assert!(n > 1000);
    sum / n as f32
}

#[test]
fn a_building_in_a_one_kilometre_world_keeps_its_hao() {
    let _gpu = gpu_lock();
    let building = (Vec3::new(-8.0, -0.2, -8.0), Vec3::new(8.0, 4.3, 8.0));
    let mut world = room();
    world.extend(bevy_hao_tools::scene::big_world(building, 1000.0));
    let alone = room_error(room(), VoxelVolume::default());
    let in_world = room_error(world.clone(), VoxelVolume::default());
    // What the cascades replace: one grid fitted to the whole static scene, whose cells are now 8 m wide.
    let fitted = room_error(world, VoxelVolume { bounds: VolumeBounds::FitStaticScene { margin: 0.5 }, ..default() });
    println!(
        "HAO error against the reference: room alone {alone:.4}, in a 1 km world {in_world:.4}; one fitted grid {fitted:.4}"
    );
    assert!(in_world <= alone * 1.1, "in the world {in_world} vs alone {alone}");
    assert!(fitted > in_world * 1.5, "a fitted grid ({fitted}) should lose the room's occlusion");
}

#[test]
fn debug_views_and_hao_work_under_an_orthographic_projection() {
    use bevy::camera::{OrthographicProjection, Projection, ScalingMode};
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(1.5, 6.0, 7.5).looking_at(Vec3::new(0.5, 0.5, 0.0), Vec3::Y);
    let mut app = scene_app_in(camera, Ao::Hao(hao_settings()), false, small_cascades(), walls);
    run(&mut app, 1);
    let cam = app.world_mut().query_filtered::<Entity, With<TheCamera>>().single(app.world()).unwrap();
    app.world_mut().entity_mut(cam).insert(Projection::Orthographic(OrthographicProjection {
        scaling_mode: ScalingMode::FixedVertical { viewport_height: 12.0 },
        ..OrthographicProjection::default_3d()
    }));
    run(&mut app, 6);
    let pixels = |app: &mut App, view: HaoDebugView| view_pixels(app, cam, view);
    let final_image = pixels(&mut app, HaoDebugView::Final);
    let ao = pixels(&mut app, HaoDebugView::AmbientOcclusion);
    assert!(ao.iter().any(|p| p[0] < 230) && ao.iter().any(|p| p[0] > 250), "HAO shows occlusion and open floor");
    // The voxel views march from the near plane along the view direction: boxes, not the shaded scene.
    let voxels = pixels(&mut app, HaoDebugView::Voxels);
    let pale = |p: &&[u8; 3]| p.iter().max().unwrap() - p.iter().min().unwrap() <= 30 && p[0] > 100;
    assert!(voxels.iter().filter(pale).count() * 2 > voxels.len(), "the voxel view shows pale boxes");
    assert_ne!(voxels, final_image);
    let cascades = pixels(&mut app, HaoDebugView::Cascades);
    let colored = cascades.iter().filter(|p| p.iter().max().unwrap() - p.iter().min().unwrap() > 40).count();
    assert!(colored * 2 > cascades.len(), "the cascade view tints voxels ({colored} of {})", cascades.len());
    assert!(take_render_errors().is_empty());
}

/// Mean absolute difference over the pixels both images show geometry in (AO below 1 somewhere near).
fn mean_difference(a: &[f32], b: &[f32]) -> f32 {
    let d: Vec<f32> = a.iter().zip(b).map(|(x, y)| (x - y).abs()).collect();
    d.iter().sum::<f32>() / d.len() as f32
}

/// The AO of `camera`'s view of the walls after `frames` frames, with `rays` rays a frame.
fn walls_ao(camera: Transform, rays: u32, accumulation_frames: u32, frames: usize, depth_contacts: bool) -> Vec<f32> {
    let settings = HybridAmbientOcclusion {
        quality: HaoQuality::Custom { rays, steps: 48, half_resolution: false },
        denoise_radius: 0,
        accumulation_frames,
        depth_contacts,
        ..hao_settings()
    };
    let mut app = scene_app(camera, Ao::Hao(settings), walls);
    run(&mut app, frames);
    let ao = ao_image(&mut app).2;
    assert!(take_render_errors().is_empty());
    ao
}

#[test]
fn two_rays_a_frame_accumulated_converge_towards_many_rays() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(1.5, 9.0, 5.5).looking_at(Vec3::new(1.0, 0.0, 0.5), Vec3::Y);
    let reference = walls_ao(camera, 64, 1, 10, true);
    let single = walls_ao(camera, 2, 1, 10, true);
    let accumulated = walls_ao(camera, 2, 16, 40, true);
    let (e1, e16) = (mean_difference(&single, &reference), mean_difference(&accumulated, &reference));
    println!("two rays against 64: one frame {e1:.4}, accumulated over 16 frames {e16:.4}");
    // 16 frames of 2 rays are 32 rays: the noise falls by about sqrt(16) = 4.
    assert!(e16 < 0.4 * e1, "{e16} against {e1}");
}

/// Two rays a frame at full resolution with no filter, accumulated over `accumulation_frames`.
fn two_rays_accumulated(accumulation_frames: u32) -> HybridAmbientOcclusion {
    HybridAmbientOcclusion {
        quality: HaoQuality::Custom { rays: 2, steps: 48, half_resolution: false },
        denoise_radius: 0,
        accumulation_frames,
        ..hao_settings()
    }
}

#[test]
fn a_still_view_keeps_a_longer_history_and_shimmers_less() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(1.5, 9.0, 5.5).looking_at(Vec3::new(1.0, 0.0, 0.5), Vec3::Y);
    // The mean change of the AO from one frame to the next after 60 frames of two rays, at full resolution,
    // with 8 frames accumulated: still, the history keeps `still_accumulation_frames` (about 55 frames by
    // then at 64, against 8), and the change falls as one over them. And the share of the view's pixels
    // whose AO changed at all: a pixel whose history is longer than 8 frames shows the AO it showed while
    // its history strays little (`cpu::temporal::stable_ao`), so few change; with 8 every traced pixel
    // follows its history.
    let shimmer = |still_accumulation_frames: u32| {
        let settings = HybridAmbientOcclusion { still_accumulation_frames, ..two_rays_accumulated(8) };
        let mut app = scene_app(camera, Ao::Hao(settings), walls);
        run(&mut app, 60);
        let a = ao_image(&mut app).2;
        run(&mut app, 1);
        let b = ao_image(&mut app).2;
        assert!(take_render_errors().is_empty());
        let changed = a.iter().zip(&b).filter(|(x, y)| x != y).count() as f32 / a.len() as f32;
        (mean_difference(&a, &b), changed)
    };
    let ((short, short_changed), (long, long_changed)) = (shimmer(8), shimmer(64));
    println!(
        "frame-to-frame change of a still view: history of 8 frames {short:.5} ({:.1} % of the pixels \
         changed), of up to 64 {long:.5} ({:.1} %)",
        100.0 * short_changed,
        100.0 * long_changed
    );
    assert!(short > 0.0 && long < 0.4 * short, "{long} against {short}");
    // Measured on lavapipe: 59.0 % and 12.4 % (a pixel shows a new AO where its history doubled or left it).
    assert!(short_changed > 0.5 && long_changed < 0.3 * short_changed, "{long_changed} against {short_changed}");
}

#[test]
fn an_occluder_that_leaves_leaves_no_trail() {
    let _gpu = gpu_lock();
    let camera = Transform::from_xyz(0.0, 8.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y);
    let settings = HybridAmbientOcclusion {
        quality: HaoQuality::Custom { rays: 2, steps: 48, half_resolution: false },
        accumulation_frames: 16,
        ..hao_settings()
    };
    let mut app = scene_app(camera, Ao::Hao(settings), |c, m, mat| {
        c.spawn((
            box_at(m, Vec3::new(1.0, 1.0, 1.0)),
            MeshMaterial3d(mat),
            Transform::from_xyz(-2.0, 0.5, 0.0),
            DynamicOccluder,
            Mover,
        ));
    });
    run(&mut app, 30);
    let beside = Vec3::new(-2.0, 0.0, 0.65);
    let ao = ao_image(&mut app);
    let with_box = ao_at(&mut app, &ao, beside, 1);
    // The box jumps away: four frames later the floor beside its old place is as open as it will be.
    let mut q = app.world_mut().query_filtered::<&mut Transform, With<Mover>>();
    q.single_mut(app.world_mut()).unwrap().translation.x = 5.0;
    run(&mut app, 4);
    let ao = ao_image(&mut app);
    let soon = ao_at(&mut app, &ao, beside, 1);
    run(&mut app, 40);
    let ao = ao_image(&mut app);
    let settled = ao_at(&mut app, &ao, beside, 1);
    println!("beside the box {with_box:.3}; 4 frames after it left {soon:.3}; settled {settled:.3}");
    assert!(settled > with_box + 0.1, "the box occluded");
    assert!((settled - soon).abs() < 0.03, "a trail: {soon} against {settled}");
    assert!(take_render_errors().is_empty());
}

#[test]
fn a_moving_camera_keeps_its_history_without_trails() {
    let _gpu = gpu_lock();
    // Without the depth contacts (the voxels alone), and with them: their contacts change from pixel to pixel
    // along the walls' feet (at 96x64 a pixel is wider than a voxel), where the history's reprojection
    // blurs them; measured 99th percentiles 0.133 and 0.154.
    for (depth_contacts, p99_bound) in [(false, 0.15), (true, 0.18)] {
        let settings = HybridAmbientOcclusion { depth_contacts, ..two_rays_accumulated(16) };
        moving_camera_against_many_rays(settings, p99_bound);
    }
    // `Medium` as a game gets it (1 ray a frame at half resolution, the denoiser): each pixel traces every
    // fourth frame, so where the view moves on, the pixels newly shown start from their block's traced
    // neighbours; measured 0.0157 (99th percentile 0.229), and 0.0155 (0.228) with 2 rays a frame.
    let medium = HybridAmbientOcclusion { quality: HaoQuality::Medium, ..hao_settings() };
    moving_camera_against_many_rays(medium, 0.25);
}

/// The camera slides 5 cm a frame for 30 frames with `settings`; its last view is compared with 64 rays
/// traced there: the accumulated AO is much closer to it than one frame of 2 rays, and its 99th percentile
/// error is under `p99_bound`.
fn moving_camera_against_many_rays(settings: HybridAmbientOcclusion, p99_bound: f32) {
    let start = Transform::from_xyz(0.0, 9.0, 5.5).looking_at(Vec3::new(-0.5, 0.0, 0.5), Vec3::Y);
    let end = Transform { translation: start.translation + Vec3::new(1.5, 0.0, 0.0), ..start };
    let (quality, depth_contacts) = (settings.quality, settings.depth_contacts);
    let mut app = scene_app(start, Ao::Hao(settings), walls);
    run(&mut app, 10);
    for k in 1..=30 {
        let mut q = app.world_mut().query_filtered::<&mut Transform, With<TheCamera>>();
        q.single_mut(app.world_mut()).unwrap().translation = start.translation + Vec3::new(0.05 * k as f32, 0.0, 0.0);
        run(&mut app, 1);
    }
    let moving = ao_image(&mut app).2;
    assert!(take_render_errors().is_empty());
    let reference = walls_ao(end, 64, 1, 10, depth_contacts);
    let single = walls_ao(end, 2, 1, 10, depth_contacts);
    let (e1, em) = (mean_difference(&single, &reference), mean_difference(&moving, &reference));
    let mut errors: Vec<f32> = moving.iter().zip(&reference).map(|(a, b)| (a - b).abs()).collect();
    errors.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let p99 = errors[errors.len() * 99 / 100];
    println!(
        "{quality:?}, depth contacts {depth_contacts}: against 64 rays after 30 moving frames: one frame of two rays \
         {e1:.4}, accumulated {em:.4} (99th percentile {p99:.3})"
    );
    assert!(em < 0.6 * e1, "{em} against {e1}");
    assert!(p99 < p99_bound, "{p99}");
}

#[test]
fn under_taa_the_converged_ao_equals_the_ao_without_taa() {
    let _gpu = gpu_lock();
    // Without the depth contacts (the voxels alone), and with them (the default). Under TAA every frame is
    // traced from pixel centres moved by up to half a pixel, and the history is read where the previous frame
    // (with its own jitter) traced it: the converged AO is the still view's averaged over half a pixel, and
    // differs from it at edges. At 96x64 a pixel is wider than a voxel, so the contacts along the walls' feet
    // differ more. Measured, the code as it is: 0.0083-0.0085 and 0.0097-0.0101 on lavapipe (with 2, 4 or 8
    // rays a frame: not noise), 0.0087 without the contacts on an NVIDIA H100; the history read without the
    // previous frame's jitter: 0.0115-0.0118 and 0.0135 on lavapipe. The bounds lie between. (0.0078 and
    // 0.0093 before fc45ada, from which a pixel whose history holds under 3 frames blends in its traced
    // neighbours' AO: under the jitter, histories are cut short at edges.)
    let measured: Vec<_> = [(false, 0.0100), (true, 0.0117)]
        .into_iter()
        .map(|(depth_contacts, bound)| (depth_contacts, bound, taa_against_still(depth_contacts)))
        .collect();
    for (depth_contacts, bound, (difference, darkness_change)) in measured {
        assert!(
            difference < bound,
            "depth contacts {depth_contacts}: TAA's converged AO is {difference} from the still view's"
        );
        assert!(
            darkness_change < 0.01,
            "depth contacts {depth_contacts}: TAA changes the mean occlusion by {darkness_change}"
        );
    }
}

/// The mean difference of the converged AO under TAA from the still view's, and the change of their mean
/// occlusion (each case printed before any is asserted, so that a failure shows them all).
fn taa_against_still(depth_contacts: bool) -> (f32, f32) {
    let camera = Transform::from_xyz(1.5, 9.0, 5.5).looking_at(Vec3::new(1.0, 0.0, 0.5), Vec3::Y);
    let converged = |taa: bool| {
        // Two rays a frame at half resolution, as `Medium` traced before it went to one.
        let quality = HaoQuality::Custom { rays: 2, steps: 32, half_resolution: true };
        let hao = HybridAmbientOcclusion { quality, depth_contacts, ..default() };
        let mut app = scene_app(camera, Ao::Hao(hao), walls);
        run(&mut app, 1);
        if taa {
            let mut q = app.world_mut().query_filtered::<Entity, With<TheCamera>>();
            let cam = q.single(app.world()).unwrap();
            app.world_mut().entity_mut(cam).insert(bevy::anti_alias::taa::TemporalAntiAliasing::default());
        }
        run(&mut app, 40);
        let ao = ao_image(&mut app);
        assert_valid(&ao);
        assert!(take_render_errors().is_empty());
        ao.2
    };
    let still = converged(false);
    let jittered = converged(true);
    let difference = mean_difference(&jittered, &still);
    let darkness = |ao: &[f32]| ao.iter().map(|v| 1.0 - v).sum::<f32>() / ao.len() as f32;
    println!(
        "depth contacts {depth_contacts}: converged AO, TAA against none: mean difference {difference:.4}; mean \
         occlusion {:.4} with TAA, {:.4} without",
        darkness(&jittered),
        darkness(&still)
    );
    (difference, (darkness(&jittered) - darkness(&still)).abs())
}
