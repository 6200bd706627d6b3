//! Ambient occlusion in motion and at contacts, rendered headless (lavapipe here) in the scripted scenes of
//! `bevy_hao_tools::motion` and read back frame by frame: a dynamic occluder standing still, props moving.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::*;
use bevy_hao_tools::motion::{Marker, MotionScene, MotionScript, MotionScriptPlugin, ScriptedCamera};

const SIZE: UVec2 = UVec2::new(128, 72);

#[derive(Resource, Clone)]
struct Debug(HaoDebugImages);

/// An app showing `scene` from a camera as a user spawns it (Bevy's default MSAA) with `hao`, its script at
/// `frame`, not running.
fn motion_app(scene: MotionScene, hao: HybridAmbientOcclusion, frame: i32) -> App {
    let mut app = headless_app(move |app| {
        app.add_plugins(MotionScriptPlugin);
        app.insert_resource(scene.clone());
        app.insert_resource(GlobalAmbientLight { brightness: 300.0, ..default() });
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                scene.spawn(&mut commands, &mut meshes, &mut materials);
                let debug = HaoDebugImages::new(&mut images, SIZE);
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target_image(&mut images, SIZE).into()),
                    Tonemapping::None,
                    scene.camera,
                    ScriptedCamera,
                    hao.clone(),
                    debug.clone(),
                ));
                commands.insert_resource(Debug(debug));
            },
        );
    });
    app.insert_resource(MotionScript { frame, running: false });
    app
}

/// `frames` consecutive frames' AO, and the depth of the first (0 where no geometry shows).
fn ao_frames(app: &mut App, frames: usize) -> (Vec<Vec<f32>>, Vec<f32>) {
    let debug = app.world().resource::<Debug>().0.clone();
    let read = read_frames(app, &[debug.ao, debug.depth], frames, |_, _| {});
    let floats = |b: &Vec<u8>| bytemuck::cast_slice::<u8, f32>(b).to_vec();
    (read[0].iter().map(floats).collect(), floats(&read[1][0]))
}

/// The mean absolute change of the AO from each frame to the next over the pixels that show geometry.
fn frame_to_frame(frames: &[Vec<f32>], depth: &[f32]) -> f32 {
    let pixels: Vec<usize> = (0..depth.len()).filter(|&i| depth[i] > 0.0).collect();
    let changes: f32 = frames.windows(2).map(|w| pixels.iter().map(|&i| (w[1][i] - w[0][i]).abs()).sum::<f32>()).sum();
    changes / (pixels.len() * (frames.len() - 1)).max(1) as f32
}

fn mean_difference(a: &[f32], b: &[f32], depth: &[f32]) -> f32 {
    let pixels: Vec<usize> = (0..depth.len()).filter(|&i| depth[i] > 0.0).collect();
    pixels.iter().map(|&i| (a[i] - b[i]).abs()).sum::<f32>() / pixels.len().max(1) as f32
}

#[test]
fn a_still_dynamic_occluder_converges_as_a_static_one() {
    let _gpu = gpu_lock();
    let hao = HybridAmbientOcclusion::default();
    // Four times the history a pixel keeps at half resolution.
    let converged = 4 * 4 * hao.accumulation_frames as usize + 30;
    let mut runs = Vec::new();
    for marker in [Marker::Static, Marker::Dynamic] {
        let mut app = motion_app(MotionScene::named("contacts", marker).unwrap(), hao.clone(), 0);
        run(&mut app, converged);
        let (frames, depth) = ao_frames(&mut app, 9);
        assert!(take_render_errors().is_empty());
        let noise = frame_to_frame(&frames, &depth);
        println!("sphere {marker:?}: frame-to-frame change {noise:.5}");
        runs.push((frames, depth, noise));
    }
    let (still, dynamic) = (&runs[0], &runs[1]);
    let difference = mean_difference(&still.0[8], &dynamic.0[8], &still.1);
    println!("mean difference of the converged AO: {difference:.5}");
    // Voxelized every frame, the still sphere's voxels are the static grid's: the same AO, as steady. (Before
    // only the occluders that move were flagged, the AO within max_distance of it kept 3 frames of noise: 19
    // times the static sphere's change from frame to frame on this scene.)
    assert!(difference < 0.002, "{difference}");
    assert!(dynamic.2 <= 1.1 * still.2 + 1e-4, "noise {} against {}", dynamic.2, still.2);
}

/// `scene` in motion from long enough before frame 0 to converge in motion, with `hao`; frames 0..4 read,
/// then the script stops and HAO runs two histories (`accumulation_frames` traces each) on frame 3's pose:
/// converged where the history keeps `accumulation_frames`, most of the way where a still view keeps more.
/// Returns the mean difference between frame 3
/// in motion and still, the frame-to-frame change in motion and that of the still view.
fn moving_against_still(scene: MotionScene, hao: HybridAmbientOcclusion) -> (f32, f32, f32) {
    // A pixel's history spans accumulation_frames traces, one every frames_per_trace frames.
    let history = (hao.accumulation_frames * hao.frames_per_trace()) as usize;
    let mut app = motion_app(scene, hao, -(2 * history as i32));
    run(&mut app, 30);
    app.world_mut().resource_mut::<MotionScript>().running = true;
    run(&mut app, 2 * history - 1);
    let debug = app.world().resource::<Debug>().0.clone();
    let mut script_frames = Vec::new();
    let read = read_frames(&mut app, &[debug.ao, debug.depth], 4, |app, k| {
        let mut script = app.world_mut().resource_mut::<MotionScript>();
        script_frames.push(script.frame);
        script.running = k < 3;
    });
    assert_eq!(script_frames, [0, 1, 2, 3]);
    let floats = |b: &Vec<u8>| bytemuck::cast_slice::<u8, f32>(b).to_vec();
    let moving: Vec<Vec<f32>> = read[0].iter().map(floats).collect();
    let depth = floats(&read[1][3]);
    run(&mut app, 2 * history);
    let (still, _) = ao_frames(&mut app, 1);
    assert!(take_render_errors().is_empty());
    let difference = mean_difference(&moving[3], &still[0], &depth);
    let noise = frame_to_frame(&moving, &depth);
    let still_noise = frame_to_frame(&ao_frames(&mut app, 4).0, &depth);
    println!(
        "in motion against the same frame still and converged: mean difference {difference:.5}; frame-to-frame \
         change {noise:.5} (still {still_noise:.5})"
    );
    (difference, noise, still_noise)
}

#[test]
fn the_ao_around_moving_props_stays_near_that_of_the_same_frame_still() {
    let _gpu = gpu_lock();
    // A still view's history as long as a moving one's (`still_accumulation_frames`), so that the noise in
    // motion is held to that of a still view with the same history (a still view keeping more is
    // `gpu_ao.rs`'s `a_still_view_keeps_a_longer_history_and_shimmers_less`; with 127, still 0.00049).
    let hao = HybridAmbientOcclusion { still_accumulation_frames: 16, ..default() };
    // The ball rolling at 1.5 m/s and the box sliding at 1 m/s. Where the AO in motion and still differ:
    // around the props, and where the noise of a short history shows.
    let (difference, noise, still_noise) =
        moving_against_still(MotionScene::named("roll", Marker::Dynamic).unwrap(), hao);
    // The history around the props follows the change of their occlusion (`change_cap`): no trail where they
    // were, no lag where they are, and the 4x rays there keep the short history's noise down. (On lavapipe
    // 0.0157, 0.0166 with 4x rays from a change of 0.005 only, most of it on the props' own surfaces, whose
    // history is short; with the history kept as long as a still view's near them, the trails read 0.0299.)
    assert!(difference < 0.024, "{difference}");
    // The filter and the stand-in reach twice as far there (`cpu::temporal::filters_wide`): on lavapipe
    // 0.00301 against 0.00117 still (0.00314 against 0.00124 with 4x rays from 0.005 only); filtered as far
    // as elsewhere, 0.00387.
    assert!(noise < 3.0 * still_noise, "noise {noise} against {still_noise} still");
}

#[test]
fn the_walls_follow_a_sphere_bobbing_past_them_without_lag() {
    let _gpu = gpu_lock();
    // Bevy's own ssao example (`ao_motion bob`): a sphere bobbing at up to 0.41 m/s in a corner of three
    // cubes, 0.1 m from two of them, its shadow creeping up and down the walls. A still camera, so the
    // walls' pixels keep up to 127 frames where the sphere's change does not cap them.
    let hao = HybridAmbientOcclusion::default();
    let (difference, _, _) = moving_against_still(MotionScene::named("bob", Marker::Dynamic).unwrap(), hao);
    // A pixel whose cap (`change_cap`) is above `accumulation_frames` waits for its own trace, every fourth
    // frame, and blends it with a cap that balances blends that far apart (`cpu::temporal::waiting_cap`).
    // On lavapipe 0.0148; 0.0139 blending the stand-in every frame instead; 0.0226 with the every-frame cap.
    assert!(difference < 0.018, "{difference}");
}

/// The converged AO (default settings, the scene still) at floor points `points` (normal +Y) of `scene`, and
/// the reference's there (1024 rays on the scene's triangles).
fn floor_profile<const N: usize>(scene: MotionScene, points: [Vec3; N]) -> ([f32; N], [f32; N]) {
    use bevy_hao_tools::reference::{OccluderView, ReferenceScene, reference_ao};
    let hao = HybridAmbientOcclusion::default();
    let reference = ReferenceScene::new(&scene.triangles_at(0));
    let converged = (4 * hao.accumulation_frames * hao.frames_per_trace()) as usize + 30;
    let (max_distance, falloff) = (hao.max_distance, hao.falloff);
    let mut app = motion_app(scene, hao, 0);
    run(&mut app, converged);
    let (frames, _) = ao_frames(&mut app, 1);
    assert!(take_render_errors().is_empty());
    let ao = &frames[0];
    let mut q = app.world_mut().query::<(&Camera, &GlobalTransform)>();
    let (camera, transform) = q.single(app.world()).unwrap();
    let profile = points.map(|p| {
        let v = camera.world_to_viewport(transform, p).expect("in view");
        let (x, y) = (v.x as u32, v.y as u32);
        ao[(y.min(SIZE.y - 1) * SIZE.x + x.min(SIZE.x - 1)) as usize]
    });
    let expected = points.map(|p| {
        reference_ao(&reference, p, Vec3::Y, 1024, Vec2::ZERO, max_distance, falloff, 1.0, 1e-4, |_, _| {
            OccluderView::Seen
        })
        .ao
    });
    (profile, expected)
}

#[test]
fn the_floor_darkens_toward_a_resting_balls_contact() {
    let _gpu = gpu_lock();
    let mut scene = MotionScene::named("contacts", Marker::Dynamic).unwrap();
    // Low and from the side: the floor beside the contact, under the ball's overhang, is in view nearly to
    // the contact; the profile runs across the view.
    let contact = Vec3::new(0.6, 0.0, -0.2);
    scene.camera = Transform::from_translation(contact + Vec3::new(3.0, 0.3, 0.0)).looking_at(contact, Vec3::Y);
    let distances = [0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.2];
    let (profile, expected) = floor_profile(scene, distances.map(|r| contact + Vec3::Z * r));
    println!("floor AO at {distances:?} m from the contact: {profile:.3?} (reference {expected:.3?})");
    // Darkest at the contact and lighter outward: no ring detached from it, no lighter band inside it.
    for (k, w) in profile.windows(2).enumerate() {
        assert!(w[1] >= w[0] - 0.03, "lighter at {} m than at {} m: {profile:?}", distances[k], distances[k + 1]);
    }
    assert!(profile[0] < profile[6] - 0.2, "{profile:?}");
}

/// The README's quick start (a unit sphere, `DynamicOccluder`, sunk a tenth into a floor 0.2 thick; the
/// default cascades; the camera's MSAA), seen close from above the sphere's front: the floor under its
/// silhouette darkens toward the contact. The march's start a cell off the floor lies inside the sphere
/// there; before the trace's near cells (`cpu::near`) the floor right under the silhouette came out lighter
/// than a hand's breadth further out, which the picture shows as a light band between the sphere and its
/// shadow.
#[test]
fn the_floor_under_the_quick_starts_sphere_darkens_toward_its_silhouette() {
    use bevy_hao_tools::meshes::builtin::{cuboid, sphere};
    use bevy_hao_tools::motion::{Prop, PropPath};
    let _gpu = gpu_lock();
    let scene = MotionScene {
        statics: vec![("floor", cuboid(Vec3::new(-10.0, -0.1, -10.0), Vec3::new(10.0, 0.1, 10.0)))],
        props: vec![Prop {
            name: "sphere",
            mesh: sphere(1.0, 64, 32),
            smooth: true,
            marker: Marker::Dynamic,
            path: PropPath::Still(Transform::from_xyz(0.0, 1.0, 0.0)),
        }],
        camera: Transform::from_xyz(0.0, 0.9, 2.6).looking_at(Vec3::new(0.0, 0.15, 0.0), Vec3::Y),
        camera_center: Vec3::ZERO,
        camera_speed: 0.0,
        character: None,
        solid_props: false,
    };
    // Outward on the floor's top from the sphere's axis, 35 degrees off the view's: the floor there shows
    // from 0.5 m out (the sphere meets the floor 0.436 m out), under the sphere's overhang.
    let out = Vec3::new(35f32.to_radians().sin(), 0.0, 35f32.to_radians().cos());
    let radii = [0.5, 0.55, 0.62, 0.7, 0.85, 1.0, 1.3];
    let (profile, expected) = floor_profile(scene, radii.map(|r| Vec3::Y * 0.1 + out * r));
    println!("floor AO at {radii:?} m from the sphere's axis: {profile:.3?} (reference {expected:.3?})");
    for (k, w) in profile.windows(2).enumerate() {
        assert!(w[1] >= w[0] - 0.03, "lighter at {} m than at {} m: {profile:?}", radii[k], radii[k + 1]);
    }
    // Dark at the silhouette, as the reference is (0.18 there).
    assert!(profile[0] < expected[0] + 0.15, "{profile:?} against {expected:?}");
}
