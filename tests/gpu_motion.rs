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
