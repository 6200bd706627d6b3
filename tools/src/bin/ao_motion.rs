//! Ambient occlusion in motion and at contacts: HAO and Bevy's SSAO in the same frames of a scripted scene,
//! against a ray-traced reference on the triangles as drawn in each frame.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin ao_motion -- [contacts|roll|walk] [OPTIONS]   (--help lists them)
//! ```
//!
//! The scenes are `bevy_hao_tools::motion`'s: `contacts`, a room corner with a crate, a step, a pole leaning
//! on the wall and a sphere resting on the floor, all still (`--marker dynamic` makes the sphere a
//! `DynamicOccluder`, as a prop that could move is); `roll`, the same room with the sphere rolling across
//! the floor at 1.5 m/s and a box sliding along the wall at 1 m/s (both `DynamicOccluder`); `walk`, the
//! room with a skinned glTF character (`--character FILE`, its clip `--clip`, scaled to `--height` metres)
//! walking across the floor at 1 m/s, posed by its clip at the script's time (the reference posed by the
//! lab's own sampler and skinning of the file); `bob`, Bevy 0.19's own `ssao` example (three unit cubes
//! and a sphere of 0.4 m bobbing between them; run it with `--taa`, as the example has TAA and no MSAA).
//! `--motion DEG` swings the camera about the scene at up to DEG degrees a frame.
//!
//! One headless app renders two cameras of the same view in the same frames: HAO on a camera as a user
//! spawns it (Bevy's default MSAA, 4 samples; `--msaa 1` for none), and Bevy's SSAO (`High`, which needs
//! `Msaa::Off`). `--taa` puts Bevy's TAA on both (it needs `Msaa::Off`: HAO's camera too). The scene runs
//! until voxelized and converged (four times HAO's history, in motion as measured), then `--frames`
//! consecutive frames (32) are read back, centred on the scene's nominal pose. Then the script stops at the
//! last of them and HAO converges there: the same frame, still and converged, for comparison.
//!
//! With `AO_MOTION_DUMP=DIR` set, each measured frame's HAO and reference are written to `DIR/frameNN.f32`
//! (little-endian f32, the HAO image then the reference's, row by row) and the last frame still and
//! converged to `DIR/still.f32`.
//!
//! The reference traces `--rays` cosine-weighted rays per pixel against the frame's triangles (the props
//! posed) from the positions and normals of each camera's own prepass, with HAO's maximum distance and
//! falloff; a pixel's rays are the same in every frame, so that its reference changes only where the scene
//! or the surface under it does. Printed, for each: the mean absolute error over the view, over the contact
//! band (the pixels whose reference AO is under 0.5: contacts and creases), and over the pixels within 1 m of
//! a moving prop (of any prop where none moves); and the temporal noise, the mean absolute change of the AO
//! from one frame to the next at pixels whose reference does not change (by under 0.002; 0.01 with
//! `--motion`), near the props (within 1 m) and away from them; beside it the reference's own change at those
//! pixels (a prop's shadow reaches further than the threshold tells: an AO that follows the reference
//! exactly changes that much), the noise where the reference does not change at all, and the change beyond
//! the reference's (|change - the reference's change|, the noise of an AO that follows a changing truth).
//! The PNG shows the last four frames of each
//! camera and the reference, one row each, and HAO still and converged in the last frame's pose.

use bevy::anti_alias::taa::TemporalAntiAliasing;
use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::view::Msaa;
use bevy_hao::cpu::TriangleMesh;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::{self, args};
use bevy_hao_tools::motion::{Character, Marker, MotionScene, MotionScript, MotionScriptPlugin, ScriptedCamera};
use bevy_hao_tools::reference::{OccluderView, ReferenceScene, hash, reference_ao};
use clap::Parser;

/// Ambient occlusion in motion and at contacts: HAO and Bevy's SSAO against a ray-traced reference.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// The scene: contacts (everything still), roll (a sphere rolling, a box sliding), bob (Bevy's own
    /// ssao example: three cubes, a sphere bobbing between them) or walk (the `--character` walking across
    /// the room).
    #[arg(default_value = "contacts")]
    scene: String,
    /// In `walk`, the skinned glTF character (a .gltf or .glb file with a clip).
    #[arg(long, value_name = "FILE")]
    character: Option<std::path::PathBuf>,
    /// In `walk`, the character's clip, by name or index.
    #[arg(long, default_value = "0")]
    clip: String,
    /// In `walk`, the character's height in metres (in its pose at time 0).
    #[arg(long, default_value_t = 1.7)]
    height: f32,
    /// In `contacts`, how the sphere is voxelized.
    #[arg(long, value_enum, default_value_t = Marker::Dynamic)]
    marker: Marker,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "320x180", value_parser = args::size)]
    size: UVec2,
    /// Rays per pixel of the ray-traced reference.
    #[arg(long, default_value_t = 256)]
    rays: u32,
    /// Consecutive frames measured.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(2..=256))]
    frames: u32,
    /// HAO's quality preset.
    #[arg(long, value_enum, default_value_t = args::Quality::Medium)]
    quality: args::Quality,
    /// Swing the camera at up to DEG degrees a frame (at most 3).
    #[arg(long, value_name = "DEG")]
    motion: Option<f32>,
    /// MSAA samples of HAO's camera (1, 2, 4 or 8; Bevy's default is 4). Bevy's SSAO needs none.
    #[arg(long, default_value_t = 4)]
    msaa: u32,
    /// Bevy's TAA on both cameras (HAO's then without MSAA).
    #[arg(long)]
    taa: bool,
    /// Frames HAO's history keeps where the view stands still
    /// (HybridAmbientOcclusion::still_accumulation_frames; at least its accumulation_frames, 16).
    #[arg(long, default_value_t = HybridAmbientOcclusion::default().still_accumulation_frames)]
    still_accumulation: u32,
    /// The props voxelized filled (`VoxelFill::Solid`; they are closed meshes), not as surfaces.
    #[arg(long)]
    solid: bool,
    /// The denoiser's width, texels of the trace (HybridAmbientOcclusion::denoise_radius; 0: off).
    #[arg(long)]
    denoise: Option<u32>,
    /// HAO without its depth contacts (HybridAmbientOcclusion::depth_contacts off): the voxels alone.
    #[arg(long)]
    no_depth_contacts: bool,
    /// HAO passing the voxel hits the depth prepass shows in free space, or not
    /// (HybridAmbientOcclusion::depth_free_space; `--depth-free-space` alone is on; default: each preset's
    /// own choice, on for High and Ultra).
    #[arg(long, value_name = "on|off", num_args = 0..=1, default_missing_value = "on",
        value_parser = clap::builder::BoolishValueParser::new())]
    depth_free_space: Option<bool>,
    /// The PNG written.
    #[arg(long, default_value = "ao_motion.png")]
    out: String,
    /// Also write the last frame's crop X,Y,W,H (pixels), four times enlarged, beside the PNG (`-zoom.png`):
    /// HAO, HAO still and converged, Bevy's SSAO, the reference, and HAO less the reference (mid-grey where
    /// they agree, lighter where HAO is lighter).
    #[arg(long, value_parser = args::crop)]
    zoom: Option<[u32; 4]>,
}

/// One camera's frame: AO, depth and world normal per pixel.
struct View {
    ao: Vec<f32>,
    depth: Vec<f32>,
    normal: Vec<Vec3>,
}

impl View {
    fn new(ao: &[u8], depth: &[u8], normal: &[u8]) -> Self {
        let floats = |d: &[u8]| bytemuck::cast_slice::<u8, f32>(d).to_vec();
        let normal = normal
            .chunks_exact(8)
            .map(|c| Vec3::new(harness::f16_at(c, 0), harness::f16_at(c, 2), harness::f16_at(c, 4)).normalize_or_zero())
            .collect();
        Self { ao: floats(ao), depth: floats(depth), normal }
    }

    fn shows(&self, i: usize) -> bool {
        self.depth[i] > 0.0 && self.normal[i] != Vec3::ZERO
    }
}

/// What is measured of one camera over the frames.
#[derive(Default, Clone, Copy)]
struct Errors {
    view: Mean,
    contact: Mean,
    /// The mean of AO - reference in the contact band (positive: lighter than the reference).
    contact_bias: Mean,
    near: Mean,
    noise_near: Mean,
    noise_away: Mean,
    /// The reference's own mean change from frame to frame at the pixels of `noise_near` and `noise_away`:
    /// what an AO that follows the truth exactly changes there.
    reference_change_near: Mean,
    reference_change_away: Mean,
    /// The noise where the reference does not change at all (no ray of it changes its hit).
    unchanged_near: Mean,
    unchanged_away: Mean,
    /// At the same pixels, the change that the reference's does not explain: |change - reference's change|.
    excess_near: Mean,
    excess_away: Mean,
}

#[derive(Default, Clone, Copy)]
struct Mean {
    sum: f64,
    n: u64,
}

impl Mean {
    fn add(&mut self, v: f32) {
        self.sum += f64::from(v);
        self.n += 1;
    }
    fn get(&self) -> f64 {
        if self.n == 0 { f64::NAN } else { self.sum / self.n as f64 }
    }
}

/// Where sample 0 of a pixel lies (from its top left corner) with `samples` MSAA samples: Vulkan's standard
/// sample locations, which the prepasses' sample 0 (what HAO and the debug images read) was rendered at.
fn sample_zero(samples: u32) -> Vec2 {
    match samples {
        2 => Vec2::new(0.75, 0.75),
        4 => Vec2::new(0.375, 0.125),
        8 => Vec2::new(0.5625, 0.3125),
        _ => Vec2::splat(0.5),
    }
}

/// Where a pixel's sample lies (from its top left corner, in the unjittered projection) in render frame
/// `frame` under Bevy's TAA: its centre plus the frame's jitter (`bevy_anti_alias`'s Halton (2, 3) sequence
/// of 8 offsets, by the frame count; found by reconstructing the floor of `roll` from the depth, which lies
/// on it to 1e-5 with this sample and 2-14 mm off with the others).
fn taa_sample(frame: u32) -> Vec2 {
    const HALTON: [Vec2; 8] = [
        Vec2::new(0.0, 0.0),
        Vec2::new(0.0, -0.16666666),
        Vec2::new(-0.25, 0.16666669),
        Vec2::new(0.25, -0.3888889),
        Vec2::new(-0.375, -0.055555552),
        Vec2::new(0.125, 0.2777778),
        Vec2::new(-0.125, -0.2777778),
        Vec2::new(0.375, 0.055555582),
    ];
    Vec2::splat(0.5) + HALTON[frame as usize % HALTON.len()]
}

/// The reference at each pixel of `view` that shows geometry (1 elsewhere), and each pixel's world position
/// (at `sample`, where in the pixel its depth was taken).
fn reference(
    scene: &ReferenceScene,
    view: &View,
    world_from_clip: Mat4,
    size: UVec2,
    sample: Vec2,
    rays: u32,
    max_distance: f32,
    falloff: f32,
) -> (Vec<f32>, Vec<Vec3>) {
    let (w, h) = (size.x as usize, size.y as usize);
    let epsilon = 1.0e-3;
    let position = |i: usize| {
        let (x, y) = ((i % w) as f32, (i / w) as f32);
        let ndc =
            Vec3::new((x + sample.x) / w as f32 * 2.0 - 1.0, 1.0 - (y + sample.y) / h as f32 * 2.0, view.depth[i]);
        world_from_clip.project_point3(ndc)
    };
    let positions: Vec<Vec3> = (0..w * h).map(position).collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let pixels: Vec<usize> = (0..w * h).collect();
    let chunks: Vec<&[usize]> = pixels.chunks((w * h).div_ceil(threads)).collect();
    let ao: Vec<f32> = std::thread::scope(|s| {
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|chunk| {
                let positions = &positions;
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&i| {
                            if !view.shows(i) {
                                return 1.0;
                            }
                            let rotation = Vec2::new(hash(i as u32 * 2 + 1), hash(i as u32 * 2 + 2));
                            let r = reference_ao(
                                scene,
                                positions[i],
                                view.normal[i],
                                rays,
                                rotation,
                                max_distance,
                                falloff,
                                1.0,
                                epsilon,
                                |_, _| OccluderView::Seen,
                            );
                            r.ao
                        })
                        .collect::<Vec<f32>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    (ao, positions)
}

/// The distance from `p` to the box `(lo, hi)` (0 inside).
fn box_distance(p: Vec3, (lo, hi): (Vec3, Vec3)) -> f32 {
    (lo - p).max(p - hi).max(Vec3::ZERO).length()
}

/// How far from a prop a pixel counts as near it.
const NEAR: f32 = 1.0;
/// Reference AO under which a pixel is in the contact band.
const CONTACT_BAND: f32 = 0.5;

fn main() {
    let args = Args::parse();
    let mut scene = if args.scene == "walk" {
        let Some(file) = &args.character else {
            eprintln!("error: walk needs --character FILE (a skinned glTF with a clip)");
            std::process::exit(1)
        };
        let character = Character::load(file, &args.clip, args.height, MotionScene::walk_path()).unwrap_or_else(|e| {
            eprintln!("error: {e}");
            std::process::exit(1)
        });
        // Bevy loads the file from its folder.
        harness::set_asset_root(character.file.parent().map(|d| d.to_string_lossy().into_owned()));
        MotionScene::walk(character)
    } else {
        let Some(scene) = MotionScene::named(&args.scene, args.marker) else {
            eprintln!(
                "error: unknown scene {} (known: {}, walk)",
                args.scene,
                bevy_hao_tools::motion::MOTION_SCENES.join(", ")
            );
            std::process::exit(1)
        };
        scene
    };
    scene.solid_props = args.solid;
    if let Some(d) = args.motion {
        if !(d > 0.0 && d <= 3.0) {
            eprintln!("error: --motion {d}: expected above 0 and at most 3 degrees a frame");
            std::process::exit(1);
        }
        scene.camera_speed = d;
    }
    if ![1, 2, 4, 8].contains(&args.msaa) {
        eprintln!("error: --msaa {}: expected 1, 2, 4 or 8", args.msaa);
        std::process::exit(1);
    }
    let msaa = if args.taa { Msaa::Off } else { Msaa::from_samples(args.msaa) };
    let hao = HybridAmbientOcclusion {
        quality: args.quality.into(),
        still_accumulation_frames: args.still_accumulation,
        denoise_radius: args.denoise.unwrap_or(HybridAmbientOcclusion::default().denoise_radius),
        depth_contacts: !args.no_depth_contacts,
        depth_free_space: args.depth_free_space,
        ..default()
    };
    let sanitized = hao.sanitized().0;
    let size = args.size;
    let frames = args.frames as i32;
    let setup_scene = scene.clone();
    let (setup_hao, taa) = (hao.clone(), args.taa);
    let mut app = harness::headless_app(move |app| {
        app.add_plugins(MotionScriptPlugin);
        app.insert_resource(setup_scene.clone());
        app.insert_resource(bevy::light::GlobalAmbientLight { brightness: 300.0, ..default() });
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>,
                  asset_server: Res<AssetServer>,
                  mut graphs: ResMut<Assets<AnimationGraph>>| {
                setup_scene.spawn(&mut commands, &mut meshes, &mut materials);
                setup_scene.spawn_character(&mut commands, &asset_server, &mut graphs);
                let mut outputs = Vec::new();
                for k in 0..2 {
                    let debug = HaoDebugImages::new(&mut images, size);
                    outputs.push(debug.clone());
                    let target = harness::target_image(&mut images, size);
                    let mut cam = commands.spawn((
                        Camera3d::default(),
                        Camera { order: k as isize, ..default() },
                        RenderTarget::Image(target.into()),
                        Tonemapping::None,
                        setup_scene.camera,
                        ScriptedCamera,
                        debug,
                    ));
                    if k == 0 {
                        cam.insert((setup_hao.clone(), msaa));
                    } else {
                        cam.insert((bevy::pbr::ScreenSpaceAmbientOcclusion::default(), Msaa::Off));
                    }
                    if taa {
                        cam.insert(TemporalAntiAliasing::default());
                    }
                }
                commands.insert_resource(Outputs(outputs));
            },
        );
    });
    // Until the static scene is voxelized, then four times HAO's history in motion, ending just before the
    // first frame measured.
    let warmup = 4 + 4 * sanitized.accumulation_frames as i32 * sanitized.frames_per_trace() as i32;
    let first = -frames / 2;
    app.insert_resource(MotionScript { frame: first - warmup, running: false });
    for _ in 0..30 {
        app.update();
    }
    app.world_mut().resource_mut::<MotionScript>().running = true;
    harness::run(&mut app, warmup as usize - 1);
    let outputs = app.world().resource::<Outputs>().0.clone();
    let images: Vec<Handle<Image>> =
        outputs.iter().flat_map(|o| [o.ao.clone(), o.depth.clone(), o.normal.clone()]).collect();
    let mut script_frames = Vec::new();
    let mut render_frames = Vec::new();
    let recorded = harness::read_frames(&mut app, &images, frames as usize, |app, k| {
        // The frame number the render world drew it with (it picks TAA's jitter).
        render_frames.push(app.world().resource::<bevy::diagnostic::FrameCount>().0);
        let mut script = app.world_mut().resource_mut::<MotionScript>();
        script_frames.push(script.frame);
        // The last frame's readbacks arrive in the frames after it: the script stays at the last frame.
        script.running = k + 1 < frames as usize;
    });
    assert_eq!(script_frames[0], first, "the frames measured are centred on the nominal pose");
    let moving_spans = span_medians(&app, frames as usize);
    // The last frame, still and converged.
    harness::run(&mut app, warmup as usize);
    let still_spans = span_medians(&app, frames as usize);
    let still_ao = harness::read_image_f32(&mut app, outputs[0].ao.clone(), 2).2;
    let errors = harness::take_render_errors();
    if !errors.is_empty() {
        eprintln!("error: wgpu errors: {errors:?}");
        std::process::exit(1);
    }
    let failed = harness::failed_pipelines(&app);
    if !failed.is_empty() {
        eprintln!("error: pipelines failed to compile, so their passes did not run: {failed:?}");
        std::process::exit(1);
    }
    let clip_from_view = {
        let mut q = app.world_mut().query::<&Camera>();
        q.iter(app.world()).next().unwrap().clip_from_view()
    };

    // The reference, frame by frame, from each camera's own prepass.
    let n = (size.x * size.y) as usize;
    let bar = harness::progress_bar(frames as u64, "reference frames");
    let mut measured = [Errors::default(); 2];
    let mut near_still = [Mean::default(); 3]; // still HAO in the last frame: near, contact band, view
    let mut near_moving = [Mean::default(); 3];
    let mut last: [Option<(View, Vec<f32>)>; 2] = [None, None];
    let mut strip: [Vec<(Vec<f32>, Vec<f32>, Vec<f32>)>; 2] = [Vec::new(), Vec::new()];
    let mut cache: [Option<((TriangleMesh, Mat4, Vec<f32>), (Vec<f32>, Vec<Vec3>))>; 2] = [None, None];
    let threshold = if args.motion.is_some() { 0.01 } else { 0.002 };
    for (f, &frame) in script_frames.iter().enumerate() {
        let frame_triangles = scene.triangles_at(frame);
        let triangles = ReferenceScene::new(&frame_triangles);
        let world_from_clip = scene.camera_at(frame).to_matrix() * clip_from_view.inverse();
        let props = scene.prop_bounds_at(frame);
        for k in 0..2 {
            let view = View::new(&recorded[3 * k][f], &recorded[3 * k + 1][f], &recorded[3 * k + 2][f]);
            // A still scene seen from a still camera has the same reference every frame: traced once.
            let key = (frame_triangles.clone(), world_from_clip, view.depth.clone());
            let (reference, positions) = match &cache[k] {
                Some((cached_key, r)) if *cached_key == key => r.clone(),
                _ => {
                    let r = reference(
                        &triangles,
                        &view,
                        world_from_clip,
                        size,
                        if args.taa {
                            taa_sample(render_frames[f])
                        } else {
                            sample_zero(if k == 0 { msaa.samples() } else { 1 })
                        },
                        args.rays,
                        hao.max_distance,
                        hao.falloff,
                    );
                    cache[k] = Some((key, r.clone()));
                    r
                }
            };
            // For a look at single pixels over the frames: HAO's frame then the reference, row by row.
            if k == 0
                && let Ok(dir) = std::env::var("AO_MOTION_DUMP")
            {
                let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
                let mut files =
                    vec![(format!("{dir}/frame{f:02}.f32"), floats(&[&view.ao[..], &reference[..]].concat()))];
                if f + 1 == script_frames.len() {
                    files.push((format!("{dir}/still.f32"), floats(&still_ao)));
                }
                for (file, bytes) in files {
                    if let Err(e) = std::fs::write(&file, bytes) {
                        eprintln!("warning: AO_MOTION_DUMP: {file}: {e}");
                    }
                }
            }
            let near = |i: usize| props.iter().any(|b| box_distance(positions[i], *b) <= NEAR);
            let m = &mut measured[k];
            for i in (0..n).filter(|&i| view.shows(i)) {
                let e = (view.ao[i] - reference[i]).abs();
                m.view.add(e);
                if reference[i] < CONTACT_BAND {
                    m.contact.add(e);
                    m.contact_bias.add(view.ao[i] - reference[i]);
                }
                if near(i) {
                    m.near.add(e);
                }
            }
            if let Some((prev, prev_ref)) = &last[k] {
                for i in (0..n).filter(|&i| view.shows(i) && prev.shows(i)) {
                    let reference_change = (reference[i] - prev_ref[i]).abs();
                    if reference_change <= threshold {
                        let change = (view.ao[i] - prev.ao[i]).abs();
                        let excess = (view.ao[i] - prev.ao[i] - (reference[i] - prev_ref[i])).abs();
                        let (noise, reference_moved, beyond, unchanged) = if near(i) {
                            (&mut m.noise_near, &mut m.reference_change_near, &mut m.excess_near, &mut m.unchanged_near)
                        } else {
                            (&mut m.noise_away, &mut m.reference_change_away, &mut m.excess_away, &mut m.unchanged_away)
                        };
                        noise.add(change);
                        reference_moved.add(reference_change);
                        beyond.add(excess);
                        if reference_change == 0.0 {
                            unchanged.add(change);
                        }
                    }
                }
            }
            if k == 0 && f + 1 == script_frames.len() {
                for i in (0..n).filter(|&i| view.shows(i)) {
                    let (e_still, e_moving) = ((still_ao[i] - reference[i]).abs(), (view.ao[i] - reference[i]).abs());
                    let sets = [near(i), reference[i] < CONTACT_BAND, true];
                    for (s, inside) in sets.into_iter().enumerate() {
                        if inside {
                            near_still[s].add(e_still);
                            near_moving[s].add(e_moving);
                        }
                    }
                }
            }
            if f + 4 >= script_frames.len() {
                let shown = |img: &[f32]| (0..n).map(|i| if view.shows(i) { img[i] } else { 1.0 }).collect();
                strip[k].push((shown(&view.ao), shown(&reference), if k == 0 { shown(&still_ao) } else { vec![] }));
            }
            last[k] = Some((view, reference));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();

    let stats = harness::stats(&app);
    println!(
        "scene: {} ({}{}), {}x{}, {} frames measured (script frames {}..={}), camera {}; HAO {:?} with {} MSAA \
         samples{}; reference: {} rays per pixel; {} dynamic occluders",
        args.scene,
        if args.scene == "contacts" { format!("sphere {:?}", args.marker) } else { "props moving".into() },
        if args.solid { ", props solid" } else { "" },
        size.x,
        size.y,
        frames,
        script_frames[0],
        script_frames[script_frames.len() - 1],
        args.motion.map_or("still".into(), |d| format!("swinging at up to {d} degrees a frame")),
        hao.quality,
        if args.taa { 1 } else { args.msaa },
        if args.taa { ", TAA on both cameras" } else { "" },
        args.rays,
        stats.dynamic_instances,
    );
    println!(
        "\n| AO | error, view | error, contact band (reference < {CONTACT_BAND}) | error, within {NEAR} m of the props | \
         noise near the props | noise away from them |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for (k, name) in ["HAO", "Bevy SSAO (High)"].iter().enumerate() {
        let m = measured[k];
        println!(
            "| {name} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
            m.view.get(),
            m.contact.get(),
            m.near.get(),
            m.noise_near.get(),
            m.noise_away.get()
        );
    }
    println!(
        "\nThe reference's own change at those pixels, near / away: {:.4} / {:.4} (an AO that follows it exactly \
         changes as much). Where the reference does not change at all (no ray of it changes its hit), near / \
         away: HAO {:.4} / {:.4}, Bevy SSAO (High) {:.4} / {:.4} ({} and {} frame pairs x pixels for HAO). The \
         change beyond the reference's (|change - the reference's change|), near / away: HAO {:.4} / {:.4}, \
         Bevy SSAO (High) {:.4} / {:.4}",
        measured[0].reference_change_near.get(),
        measured[0].reference_change_away.get(),
        measured[0].unchanged_near.get(),
        measured[0].unchanged_away.get(),
        measured[1].unchanged_near.get(),
        measured[1].unchanged_away.get(),
        measured[0].unchanged_near.n,
        measured[0].unchanged_away.n,
        measured[0].excess_near.get(),
        measured[0].excess_away.get(),
        measured[1].excess_near.get(),
        measured[1].excess_away.get(),
    );
    println!(
        "\nHAO in the last frame: in motion / the same frame still and converged: within {NEAR} m of the props \
         {:.4} / {:.4} ({:.2}x), contact band {:.4} / {:.4}, view {:.4} / {:.4}",
        near_moving[0].get(),
        near_still[0].get(),
        near_moving[0].get() / near_still[0].get().max(1e-9),
        near_moving[1].get(),
        near_still[1].get(),
        near_moving[2].get(),
        near_still[2].get(),
    );
    println!(
        "In the contact band, the mean of AO - reference (positive: lighter): HAO {:+.4}, Bevy SSAO {:+.4}",
        measured[0].contact_bias.get(),
        measured[1].contact_bias.get()
    );
    let ms = |v: Option<f64>| v.map_or("not run".to_string(), |v| format!("{v:.3} ms"));
    println!(
        "GPU spans, medians of the last {frames} frames, in motion / still and converged: HAO trace {} / {}, HAO \
         passes (trace, neighborhood, temporal) {} / {}; Bevy SSAO (High) {} / {}",
        ms(moving_spans[0]),
        ms(still_spans[0]),
        ms(moving_spans[1]),
        ms(still_spans[1]),
        ms(moving_spans[2]),
        ms(still_spans[2]),
    );
    println!(
        "(pixels: noise near {} and away {} frame pairs x pixels for HAO; contact band {} pixel-frames)",
        measured[0].noise_near.n, measured[0].noise_away.n, measured[0].contact.n
    );

    // The PNG: rows HAO, SSAO, reference (HAO's camera); the last four frames; HAO still and converged last.
    let (w, h) = (size.x, size.y);
    let columns = strip[0].len() as u32 + 1;
    let mut png = image::GrayImage::from_pixel(columns * (w + 4), 3 * (h + 4), image::Luma([255]));
    let mut put = |col: u32, row: u32, img: &[f32]| {
        for y in 0..h {
            for x in 0..w {
                let v = (img[(y * w + x) as usize].clamp(0.0, 1.0) * 255.0).round() as u8;
                png.put_pixel(col * (w + 4) + x, row * (h + 4) + y, image::Luma([v]));
            }
        }
    };
    for (c, ((hao_ao, reference, _), (ssao_ao, _, _))) in strip[0].iter().zip(&strip[1]).enumerate() {
        put(c as u32, 0, hao_ao);
        put(c as u32, 1, ssao_ao);
        put(c as u32, 2, reference);
    }
    if let Some((_, reference, still)) = strip[0].last() {
        put(columns - 1, 0, still);
        put(columns - 1, 2, reference);
    }
    if let Err(e) = png.save(&args.out) {
        eprintln!("error: writing {}: {e}", args.out);
        std::process::exit(1);
    }
    if let (Some([x0, y0, cw, ch]), Some((hao_ao, reference, still)), Some((ssao_ao, _, _))) =
        (args.zoom, strip[0].last(), strip[1].last())
    {
        const SCALE: u32 = 4;
        let (cw, ch) = (cw.min(w.saturating_sub(x0)), ch.min(h.saturating_sub(y0)));
        // The last panel: HAO - reference, mid-grey where they agree, lighter where HAO is lighter.
        let difference: Vec<f32> = hao_ao.iter().zip(reference).map(|(a, r)| 0.5 + (a - r)).collect();
        let panels = [hao_ao, still, ssao_ao, reference, &difference];
        let mut zoom =
            image::GrayImage::from_pixel(panels.len() as u32 * (cw * SCALE + 4), ch * SCALE, image::Luma([255]));
        for (k, img) in panels.iter().enumerate() {
            for y in 0..ch * SCALE {
                for x in 0..cw * SCALE {
                    let v = img[((y0 + y / SCALE) * w + x0 + x / SCALE) as usize];
                    let v = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                    zoom.put_pixel(k as u32 * (cw * SCALE + 4) + x, y, image::Luma([v]));
                }
            }
        }
        let out = args.out.strip_suffix(".png").unwrap_or(&args.out).to_string() + "-zoom.png";
        if let Err(e) = zoom.save(&out) {
            eprintln!("error: writing {out}: {e}");
            std::process::exit(1);
        }
        eprintln!("wrote {out} (HAO, HAO still and converged, Bevy SSAO, reference, 0.5 + HAO - reference)");
    }
    eprintln!(
        "wrote {} (rows: HAO, Bevy SSAO, reference; columns: the last {} frames, then HAO still and converged in the \
         last frame's pose)",
        args.out,
        columns - 1
    );
}

#[derive(Resource, Clone)]
struct Outputs(Vec<HaoDebugImages>);

/// The medians of the last `frames` GPU spans of HAO's trace, of its passes (the sum of the trace's,
/// neighborhood's and temporal pass's medians), and of Bevy's SSAO, as the render diagnostics recorded them
/// (`None` where a pass never ran).
fn span_medians(app: &App, frames: usize) -> [Option<f64>; 3] {
    let median = |span: &str| {
        let h = harness::diagnostic_history(app, &format!("render/{span}/elapsed_gpu"));
        harness::median(h[h.len().saturating_sub(frames)..].to_vec())
    };
    let trace = median("hao/trace");
    let passes = trace.zip(median("hao/neighborhood")).zip(median("hao/temporal")).map(|((t, n), m)| t + n + m);
    [trace, passes, median("ssao")]
}
