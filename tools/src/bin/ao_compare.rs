//! Hybrid ambient occlusion against Bevy's SSAO and a ray-traced reference, on one view of a scene.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin ao_compare -- [SCENE] [OPTIONS]   (--help lists them)
//! ```
//!
//! HAO accumulates its AO over frames (`--accumulation`, `HybridAmbientOcclusion::accumulation_frames`, 16
//! by default; 1 for none): the images are read after the scene has settled and then four times that many
//! frames more, when the history has converged (the frames are printed; a still view's history, which may
//! keep up to `still_accumulation_frames`, holds a quarter of those frames' traces by then and goes on
//! settling). `--hao-rays`, `--hao-steps` and
//! `--hao-resolution` trace that many rays and steps a frame, at that resolution, instead of the quality's;
//! `--denoise` sets the denoiser's width (`HybridAmbientOcclusion::denoise_radius`; 0: off).
//!
//! `--motion DEG` measures the AO of a moving camera, as a game's is: after the scene has settled, the
//! cameras swing to and fro about a point ahead of them (a quarter of the scene's extent away; a sine of
//! `MOTION_PERIOD` frames, at most DEG degrees a frame) for those frames rounded up to whole periods, and
//! the HAO image is read at the last of them, back at the still camera's pose and at its fastest. The
//! history is then reprojected every frame and the view keeps uncovering surfaces, so the error shows what
//! accumulation costs in motion; it is measured against the reference at the same pose as without
//! `--motion`. (The other two images are read in the still frames after it: Bevy's SSAO keeps no history;
//! the near field's image has had a few still frames.)
//!
//! `--volume` picks the voxel volume: `cascades` (the plugin's default: 4 cascades of 192^3 following the
//! camera) or `fit` (one grid fitted to the static scene, `--res` cells on its longest axis). `--world`
//! puts the scene inside a generated level 1 km across (a ground and distant buildings: see
//! `bevy_hao_tools::scene::big_world`), which the reference traces too.
//!
//! One headless app (Mesa's lavapipe on a machine without a GPU) renders the same view with three cameras:
//! HAO alone (voxel rays only), HAO with its near field (the minimum with Bevy's SSAO), and Bevy's SSAO
//! alone; each camera's AO is read back. The CPU reference traces `--rays` cosine-weighted rays per pixel
//! against the scene's real triangles (through a BVH) from the positions and normals the prepass produced,
//! with HAO's maximum distance, falloff and intensity. The tool prints the mean absolute error of each
//! against the reference, over all pixels that show geometry, over the pixels whose reference occlusion
//! comes mostly (over half) from occluders the view cannot see (off screen or hidden behind what it shows),
//! and over the contact band (the pixels whose reference is under 0.5: contacts and creases; where some of
//! the band is occluded mostly by the backs of faces in front of what the view shows, faces the camera looks
//! through as where one mesh passes through another, also over the band without them), the count of
//! isolated dark and light specks (`bevy_hao_tools::metrics::specks`: pixels more than 0.1 off the median
//! of their neighbours where the reference is not), and writes the four AO images side by side (HAO, HAO +
//! near field, SSAO, reference) as one PNG.
//! `--sparse N` traces the reference at every Nth pixel of each row and column only and measures the errors
//! there (the PNG's reference shows each block's sampled pixel), so that 1920x1080 stays affordable.
//!
//! `--bias` also prints where the trace's occlusion departs from the reference's, ray by ray: from each
//! pixel measured, 64 rays traced both by the CPU twin of the trace (`bevy_hao::cpu::ao::ray_occluder`, on
//! the frame's voxels read back and its depth) and against the triangles, their falloff weights compared by the
//! reference's occluder distance (in cells of the level the ray starts in) and by that level. Each row's
//! share of the mean AO difference sums to the twin's whole difference: the trace's bias, before the
//! accumulation and the denoiser, which move the mean little (on the three interiors the twin's difference
//! lies within 0.002 of the images').
//! Of the rays whose reference occluder lies within a cell that the twin misses and the view does not hide, it
//! prints where the first of the ray's contact samples past that occluder lies against the surface the view
//! shows (in front of it: the occluder ends before the sample), and writes a map of them beside the PNG
//! (`OUT.near-misses.png`: the reference in grey, red where a pixel's rays miss them).

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy_hao::cpu::SubdivisionPattern;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::args;
use bevy_hao_tools::reference::{OccluderView, ReferenceScene, hash, reference_ao};
use bevy_hao_tools::scene::{SceneSource, default_camera, spawn_scene};
use clap::{Parser, ValueEnum};

/// Hybrid ambient occlusion against Bevy's SSAO and a ray-traced reference, on one view of a scene.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// The scene: builtin:cathedral (or another built-in shape), or the path of an OBJ, glTF or GLB file.
    #[arg(default_value = "builtin:cathedral")]
    scene: String,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "320x180", value_parser = args::size)]
    size: UVec2,
    /// Rays per pixel of the ray-traced reference.
    #[arg(long, default_value_t = 256)]
    rays: u32,
    /// Cells on the longest axis of the fitted grid (--volume fit).
    #[arg(long, default_value_t = 128)]
    res: u32,
    /// How far rays look for occluders, world units (HAO and the reference).
    #[arg(long, default_value_t = 3.0)]
    max_distance: f32,
    /// HAO's start offset, voxels (HybridAmbientOcclusion::start_offset).
    #[arg(long, default_value_t = HybridAmbientOcclusion::default().start_offset)]
    start_offset: f32,
    /// HAO's quality preset.
    #[arg(long, value_enum, default_value_t = args::Quality::Medium)]
    quality: args::Quality,
    /// Camera position X,Y,Z (with --look; default: inside, down the long axis).
    #[arg(long, value_parser = args::vec3, requires = "look")]
    camera: Option<Vec3>,
    /// The point the camera looks at, X,Y,Z (with --camera).
    #[arg(long, value_parser = args::vec3, requires = "camera")]
    look: Option<Vec3>,
    /// The default camera outside the scene rather than inside.
    #[arg(long)]
    outside: bool,
    /// The voxel volume: the plugin's default cascades, or one grid fitted to the static scene.
    #[arg(long, value_enum, default_value_t = Volume::Cascades)]
    volume: Volume,
    /// The cascades' shape: LEVELS,CELLS,FINEST_CELL_SIZE.
    #[arg(long, value_parser = args::cascades)]
    cascades: Option<(u32, u32, f32)>,
    /// Put the scene inside a generated level 1 km across, which the reference traces too.
    #[arg(long)]
    world: bool,
    /// The subdivision pattern: strips or uniform.
    #[arg(long, default_value = "strips")]
    pattern: SubdivisionPattern,
    /// Frames HAO accumulates (HybridAmbientOcclusion::accumulation_frames; 1 for none).
    #[arg(long, default_value_t = HybridAmbientOcclusion::default().accumulation_frames)]
    accumulation: u32,
    /// Frames HAO's history keeps where the view stands still
    /// (HybridAmbientOcclusion::still_accumulation_frames; at least --accumulation).
    #[arg(long, default_value_t = HybridAmbientOcclusion::default().still_accumulation_frames)]
    still_accumulation: u32,
    /// Rays a frame instead of the quality's.
    #[arg(long)]
    hao_rays: Option<u32>,
    /// Steps a ray instead of the quality's.
    #[arg(long)]
    hao_steps: Option<u32>,
    /// Trace at this resolution instead of the quality's.
    #[arg(long, value_enum)]
    hao_resolution: Option<Resolution>,
    /// The denoiser's width, texels of the trace (HybridAmbientOcclusion::denoise_radius; 0: off).
    #[arg(long)]
    denoise: Option<u32>,
    /// Multi-valued voxels (VoxelVolume::attributes): the voxels keep their average albedo and normal.
    #[arg(long)]
    attributes: bool,
    /// Rays stop at the backs of surfaces too (HybridAmbientOcclusion::ignore_back_hits off; it is on by
    /// default and acts only with --attributes).
    #[arg(long, requires = "attributes")]
    stop_at_back_hits: bool,
    /// HAO without its depth contacts (HybridAmbientOcclusion::depth_contacts off): the voxels alone.
    #[arg(long)]
    no_depth_contacts: bool,
    /// HAO passing the voxel hits the depth prepass shows in free space, or not
    /// (HybridAmbientOcclusion::depth_free_space; `--depth-free-space` alone is on; default: each preset's
    /// own choice, on for High and Ultra).
    #[arg(long, value_name = "on|off", num_args = 0..=1, default_missing_value = "on",
        value_parser = clap::builder::BoolishValueParser::new())]
    depth_free_space: Option<bool>,
    /// Trace the reference (and measure the errors) at every Nth pixel of each row and column only: a
    /// sparse set that keeps the reference affordable at 1920x1080 and above.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    sparse: u32,
    /// Also print where HAO's occlusion departs from the reference's, ray by ray: the CPU twin of the trace
    /// (on the frame's voxels) and the reference along the same rays from the same pixels, by the
    /// reference's occluder distance in the cells of the level the ray starts in, and by that level.
    #[arg(long)]
    bias: bool,
    /// Swing the cameras about a point ahead at up to DEG degrees a frame (at most 3) while HAO accumulates,
    /// and read HAO's image in motion (see the tool's documentation).
    #[arg(long, value_name = "DEG", value_parser = motion_speed)]
    motion: Option<f32>,
    /// The PNG written: HAO, HAO + near field, SSAO and the reference side by side.
    #[arg(long, default_value = "ao_compare.png")]
    out: String,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum Volume {
    Cascades,
    Fit,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum Resolution {
    Full,
    Half,
}

#[derive(Component)]
struct View(usize);

/// Frames of one swing of `--motion`, to and fro.
const MOTION_PERIOD: u32 = 120;

/// `--motion`: the cameras' pose `frame` frames into the motion, swung about `center` (a sine of amplitude
/// `amplitude` radians about the vertical over `MOTION_PERIOD` frames), until frame `end`, where it stops.
#[derive(Resource, Clone, Copy)]
struct Motion {
    start: Transform,
    center: Vec3,
    amplitude: f32,
    frame: u32,
    end: u32,
}

impl Motion {
    /// A swing about `center` of `end` frames from the pose `start`, at most `speed` degrees a frame.
    fn new(start: Transform, center: Vec3, speed: f32, end: u32) -> Self {
        let amplitude = speed.to_radians() * MOTION_PERIOD as f32 / std::f32::consts::TAU;
        Self { start, center, amplitude, frame: 0, end }
    }

    /// The cameras' pose `frame` frames into the motion.
    fn pose(&self, frame: u32) -> Transform {
        let phase = std::f32::consts::TAU * frame as f32 / MOTION_PERIOD as f32;
        let mut pose = self.start;
        pose.rotate_around(self.center, Quat::from_rotation_y(self.amplitude * phase.sin()));
        pose
    }
}

/// Each frame of `--motion`, the next pose of every view's camera.
fn swing_cameras(motion: Option<ResMut<Motion>>, mut cameras: Query<&mut Transform, With<View>>) {
    let Some(mut motion) = motion else { return };
    if motion.frame >= motion.end {
        return;
    }
    motion.frame += 1;
    let pose = motion.pose(motion.frame);
    for mut t in &mut cameras {
        *t = pose;
    }
}

/// `--motion`'s speed: degrees a frame, above 0 and at most 3 (a swing of 57 degrees either side).
fn motion_speed(v: &str) -> Result<f32, String> {
    let d: f32 = v.parse().map_err(|_| format!("expected degrees a frame, got {v}"))?;
    if d > 0.0 && d <= 3.0 { Ok(d) } else { Err(format!("--motion {v}: expected above 0 and at most 3")) }
}

#[derive(Resource, Clone)]
struct Outputs(Vec<HaoDebugImages>);

const NAMES: [&str; 3] = ["HAO", "HAO + near field", "Bevy SSAO"];

fn main() {
    let args = Args::parse();
    let source = SceneSource::parse(&args.scene).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let mut triangles = source.triangles().unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let Some(bounds) = triangles.bounds() else {
        eprintln!("error: {}: no triangles to render", args.scene);
        std::process::exit(1)
    };
    let world_parts = if args.world { bevy_hao_tools::scene::big_world(bounds, 1000.0) } else { Vec::new() };
    for p in &world_parts {
        triangles.append(p, Default::default());
    }
    let camera = match args.camera.zip(args.look) {
        Some((eye, look)) => Transform::from_translation(eye).looking_at(look, Vec3::Y),
        None => default_camera(bounds, !args.outside),
    };
    eprintln!(
        "scene {} ({} triangles), camera at {} looking {}",
        args.scene,
        triangles.triangle_count(),
        camera.translation,
        camera.forward().as_vec3()
    );
    bevy_hao_tools::harness::set_asset_root(source.asset_root());
    let preset = HaoQuality::from(args.quality);
    let quality = if args.hao_rays.is_some() || args.hao_steps.is_some() || args.hao_resolution.is_some() {
        let (rays, steps, half) =
            HybridAmbientOcclusion { quality: preset, accumulation_frames: args.accumulation, ..default() }
                .trace_parameters();
        HaoQuality::Custom {
            rays: args.hao_rays.unwrap_or(rays),
            steps: args.hao_steps.unwrap_or(steps),
            half_resolution: args.hao_resolution.map_or(half, |r| r == Resolution::Half),
        }
    } else {
        preset
    };
    let hao = HybridAmbientOcclusion {
        quality,
        max_distance: args.max_distance,
        start_offset: args.start_offset,
        near_field: false,
        accumulation_frames: args.accumulation,
        still_accumulation_frames: args.still_accumulation,
        denoise_radius: args.denoise.unwrap_or(HybridAmbientOcclusion::default().denoise_radius),
        ignore_back_hits: !args.stop_at_back_hits,
        depth_contacts: !args.no_depth_contacts,
        depth_free_space: args.depth_free_space,
        ..default()
    };
    let attributes = args.attributes;
    let sanitized = hao.sanitized().0;
    let accumulation = sanitized.accumulation_frames as usize;
    let (size, res) = (args.size, args.res);
    // At half resolution a pixel traces every fourth frame (every eighth in a checkerboard), so its history
    // spans four (eight) times the frames.
    let frames_per_trace = sanitized.frames_per_trace() as usize;
    let setup_source = source.clone();
    let setup_hao = hao.clone();
    let fit = args.volume == Volume::Fit;
    let cascades = args.cascades;
    let subdivision = VoxelSubdivision::from(args.pattern);
    let mut app = bevy_hao_tools::harness::headless_app(move |app| {
        let source = setup_source.clone();
        let hao = setup_hao.clone();
        let world_parts = world_parts.clone();
        app.insert_resource(bevy::light::GlobalAmbientLight { brightness: 300.0, ..default() });
        app.add_systems(Update, swing_cameras);
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>,
                  server: Res<AssetServer>| {
                if let Err(e) = spawn_scene(&source, &mut commands, &mut meshes, &mut materials, &server) {
                    panic!("{e}");
                }
                let ground = materials.add(StandardMaterial { perceptual_roughness: 1.0, ..default() });
                for p in &world_parts {
                    commands.spawn((
                        Mesh3d(meshes.add(bevy_hao_tools::scene::bevy_mesh(p, false))),
                        MeshMaterial3d(ground.clone()),
                        StaticOccluder,
                    ));
                }
                if fit {
                    let margin = (bounds.1 - bounds.0).max_element() * 0.02;
                    commands.spawn(VoxelVolume {
                        bounds: VolumeBounds::FitStaticScene { margin },
                        resolution: VolumeResolution::Cells(res),
                        subdivision,
                        attributes,
                        ..default()
                    });
                } else if let Some((cascades, cells, finest_cell_size)) = cascades {
                    commands.spawn(VoxelVolume {
                        bounds: VolumeBounds::FollowCamera { cascades, cells, finest_cell_size },
                        subdivision,
                        attributes,
                        ..default()
                    });
                } else {
                    commands.spawn(VoxelVolume { subdivision, attributes, ..default() });
                }
                let mut outputs = Vec::new();
                for k in 0..3 {
                    let debug = HaoDebugImages::new(&mut images, size);
                    outputs.push(debug.clone());
                    let target = bevy_hao_tools::harness::target_image(&mut images, size);
                    let mut cam = commands.spawn((
                        Camera3d::default(),
                        Camera { order: k as isize, ..default() },
                        RenderTarget::Image(target.into()),
                        Msaa::Off,
                        Tonemapping::None,
                        camera,
                        debug,
                        View(k),
                    ));
                    match k {
                        0 => cam.insert(hao.clone()),
                        1 => cam.insert(HybridAmbientOcclusion { near_field: true, ..hao.clone() }),
                        _ => cam.insert(bevy::pbr::ScreenSpaceAmbientOcclusion::default()),
                    };
                }
                commands.insert_resource(Outputs(outputs));
            },
        );
    });
    // Until the scene (glTF scenes load asynchronously) is voxelized and settled.
    let mut last = (u64::MAX, 0);
    for frame in 0..600 {
        app.update();
        let s = bevy_hao_tools::harness::stats(&app);
        let key = (s.static_triangles, s.static_rebuilds);
        // (Statics stream in within `VoxelVolume::stream_budget` a frame: settled once none wait.)
        if frame > 20 && key == last && s.static_triangles > 0 && s.static_queue == 0 {
            break;
        }
        last = key;
    }
    // Then until the temporal history has converged: four times its length (the frames before weigh
    // (1 - 1/n)^(4n), under 2 %).
    let mut settled = 4 + 4 * accumulation * frames_per_trace;
    if let Some(speed) = args.motion {
        // Whole swings, so that the last frame is back at the still pose, at its fastest; the last of them
        // runs in the first read below.
        settled = settled.div_ceil(MOTION_PERIOD as usize) * MOTION_PERIOD as usize;
        let extent = (bounds.1 - bounds.0).max_element();
        let center = camera.translation + camera.forward().as_vec3() * (0.25 * extent);
        app.insert_resource(Motion::new(camera, center, speed, settled as u32));
        bevy_hao_tools::harness::run(&mut app, settled - 1);
    } else {
        bevy_hao_tools::harness::run(&mut app, settled);
    }
    let errors = bevy_hao_tools::harness::take_render_errors();
    if !errors.is_empty() {
        eprintln!("error: wgpu errors: {errors:?}");
        std::process::exit(1);
    }
    let failed = bevy_hao_tools::harness::failed_pipelines(&app);
    if !failed.is_empty() {
        eprintln!("error: pipelines failed to compile, so their passes did not run: {failed:?}");
        std::process::exit(1);
    }
    // Whether the plugin kept the attributes asked for (it turns them off where they exceed the device's
    // binding limit).
    let attributes_kept = bevy_hao_tools::harness::grid_assets(&app).is_some_and(|g| g.attributes.is_some());
    if args.attributes && !attributes_kept {
        eprintln!("warning: --attributes: the plugin turned the volume's attributes off (see its warning above)");
    }
    let outputs = app.world().resource::<Outputs>().clone();
    // In motion, HAO's image from the frame that ends it (read with no frame to settle: the last swing's
    // frame is the first this read runs).
    let settle = if args.motion.is_some() { 0 } else { 2 };
    let ao: Vec<Vec<f32>> = outputs
        .0
        .iter()
        .enumerate()
        .map(|(k, o)| {
            bevy_hao_tools::harness::read_image_f32(&mut app, o.ao.clone(), if k == 0 { settle } else { 2 }).2
        })
        .collect();
    let (w, h, depth) = bevy_hao_tools::harness::read_image_f32(&mut app, outputs.0[0].depth.clone(), 0);
    let (_, _, _, normal_bytes) = bevy_hao_tools::harness::read_image(&mut app, outputs.0[0].normal.clone(), 0);
    let normals: Vec<Vec3> = normal_bytes
        .chunks_exact(8)
        .map(|c| {
            let f = |i: usize| bevy_hao_tools::harness::f16_at(c, i);
            Vec3::new(f(0), f(2), f(4)).normalize_or_zero()
        })
        .collect();
    let mut q = app.world_mut().query::<(&Camera, &GlobalTransform, &View)>();
    let (cam, cam_transform, _) = q.iter(app.world()).find(|(_, _, v)| v.0 == 0).unwrap();
    let clip_from_view = cam.clip_from_view();
    let world_from_clip = cam_transform.to_matrix() * clip_from_view.inverse();
    let clip_from_world = world_from_clip.inverse();
    let view_from_clip = clip_from_view.inverse();
    let view_from_world = cam_transform.to_matrix().inverse();
    let linear = |ndc_z: f32| -view_from_clip.project_point3(Vec3::new(0.0, 0.0, ndc_z)).z;

    // The reference.
    eprintln!("tracing the reference: {w}x{h} pixels, {} rays each...", args.rays);
    let scene = ReferenceScene::new(&triangles);
    let epsilon = (bounds.1 - bounds.0).max_element() * 1.0e-4;
    let camera_position = cam_transform.translation();
    // What the view makes of an occluder at `p` whose face's normal is `n`: off screen or behind what the
    // view shows (by 2 % of the depth), or the back of a face the camera sees through culled faces only:
    // one it looks through.
    let occluder_view = |p: Vec3, n: Vec3| {
        let ndc = clip_from_world.project_point3(p);
        if !(ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0 && ndc.z > 0.0) {
            return OccluderView::Hidden;
        }
        let px = (((ndc.x + 1.0) / 2.0 * w as f32) as u32).min(w - 1);
        let py = (((1.0 - ndc.y) / 2.0 * h as f32) as u32).min(h - 1);
        let d = depth[(py * w + px) as usize];
        if d > 0.0 && linear(ndc.z) > linear(d) * 1.02 + epsilon * 10.0 {
            OccluderView::Hidden
        } else if n.dot(p - camera_position) > 0.0 && scene.seen_through_culled(camera_position, p, epsilon) {
            OccluderView::Culled
        } else {
            OccluderView::Seen
        }
    };
    let sparse = args.sparse as usize;
    let sampled = |i: usize| (i % w as usize).is_multiple_of(sparse) && (i / w as usize).is_multiple_of(sparse);
    // A pixel that shows geometry: depth and a normal.
    let geometry = |i: usize| depth[i] > 0.0 && normals[i] != Vec3::ZERO;
    let pixels: Vec<usize> = (0..(w * h) as usize).filter(|&i| sampled(i) && geometry(i)).collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bar = bevy_hao_tools::harness::progress_bar(pixels.len() as u64, "reference");
    let results: Vec<(usize, f32, f32, f32)> = std::thread::scope(|s| {
        let chunks: Vec<&[usize]> = pixels.chunks(pixels.len().div_ceil(threads).max(1)).collect();
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|chunk| {
                let (scene, occluder_view, depth, normals) = (&scene, &occluder_view, &depth, &normals);
                let (hao, bar) = (&hao, &bar);
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&i| {
                            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
                            let ndc =
                                Vec3::new((x + 0.5) / w as f32 * 2.0 - 1.0, 1.0 - (y + 0.5) / h as f32 * 2.0, depth[i]);
                            let p = world_from_clip.project_point3(ndc);
                            let rotation = Vec2::new(hash(i as u32 * 2 + 1), hash(i as u32 * 2 + 2));
                            let r = reference_ao(
                                scene,
                                p,
                                normals[i],
                                args.rays,
                                rotation,
                                hao.max_distance,
                                hao.falloff,
                                hao.intensity,
                                epsilon,
                                occluder_view,
                            );
                            bar.inc(1);
                            (i, r.ao, r.hidden_share, r.culled_share)
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    bar.finish_and_clear();
    let mut reference = vec![1.0f32; (w * h) as usize];
    let mut offscreen = Vec::new();
    // The contact band: contacts and creases, where the reference is darker than 0.5.
    let mut band = Vec::new();
    // The band without its pixels occluded mostly by faces the view culls.
    let mut band_seen = Vec::new();
    for &(i, ao, hidden_share, culled_share) in &results {
        reference[i] = ao;
        if hidden_share > 0.5 && ao < 0.99 {
            offscreen.push(i);
        }
        if ao < 0.5 {
            band.push(i);
            if culled_share <= 0.5 {
                band_seen.push(i);
            }
        }
    }
    // Sparse: each pixel shows its block's sampled pixel in the picture.
    if sparse > 1 {
        for i in 0..(w * h) as usize {
            let (x, y) = (i % w as usize, i / w as usize);
            reference[i] = reference[(y - y % sparse) * w as usize + x - x % sparse];
        }
    }
    let mae = |img: &[f32], set: &[usize]| {
        set.iter().map(|&i| (img[i] - reference[i]).abs()).sum::<f32>() / set.len().max(1) as f32
    };
    println!(
        "scene: {} | view {w}x{h}{}, {} pixels of geometry, {} of them occluded mostly by what the view cannot see",
        args.scene,
        if sparse > 1 { format!(" (every {sparse}th pixel of each row and column)") } else { String::new() },
        pixels.len(),
        offscreen.len()
    );
    let volume = if fit {
        format!("one grid fitted to the static scene, {} cells on its longest axis", args.res)
    } else if let Some((n, cells, size)) = args.cascades {
        format!("{n} cascades of {cells}^3 following the camera, finest cell {size}")
    } else {
        "cascades following the camera (the default: 4 of 192^3, finest cell 0.125)".to_string()
    };
    let world = match (args.world, attributes_kept, args.stop_at_back_hits) {
        (w, true, stop) => format!(
            "{}, with attributes (rays {} the backs of surfaces)",
            if w { ", inside a generated 1 km level" } else { "" },
            if stop { "stop at" } else { "pass through" }
        ),
        (true, false, _) => ", inside a generated 1 km level".to_string(),
        _ => String::new(),
    };
    println!(
        "HAO: {:?}{}, max distance {}, accumulation over {accumulation} frames ({} where the view stands still; \
         measured {settled} frames after the scene settled{}), voxel volume: {volume}{world}; reference: {} rays \
         per pixel\n",
        hao.quality,
        if hao.uses_depth_free_space() { " with free space from the depth prepass" } else { "" },
        args.max_distance,
        hao.still_history_frames(),
        args.motion.map_or(String::new(), |d| format!(", the camera swinging at up to {d} degrees a frame")),
        args.rays
    );
    println!(
        "| AO | mean abs. error, all pixels | mean abs. error, off-screen/hidden occluders | mean abs. error, contact \
         band ({:.1} % of the pixels) | isolated specks, dark / light | mean AO |",
        100.0 * band.len() as f32 / pixels.len().max(1) as f32
    );
    println!("|---|---:|---:|---:|---:|---:|");
    // Specks need every pixel's reference: not with --sparse.
    let specks = |img: &[f32]| {
        if sparse > 1 {
            "-".to_string()
        } else {
            let (dark, light) = bevy_hao_tools::metrics::specks(img, &reference, w as usize, geometry);
            format!("{dark} / {light}")
        }
    };
    for (k, name) in NAMES.iter().enumerate() {
        let mean = pixels.iter().map(|&i| ao[k][i]).sum::<f32>() / pixels.len().max(1) as f32;
        println!(
            "| {name} | {:.4} | {:.4} | {:.4} | {} | {mean:.3} |",
            mae(&ao[k], &pixels),
            mae(&ao[k], &offscreen),
            mae(&ao[k], &band),
            specks(&ao[k])
        );
    }
    let ref_mean = pixels.iter().map(|&i| reference[i]).sum::<f32>() / pixels.len().max(1) as f32;
    println!("| reference | 0 | 0 | 0 | 0 / 0 | {ref_mean:.3} |");
    let culled = band.len() - band_seen.len();
    if culled > 0 {
        println!(
            "\n{} of the contact band's pixels ({:.1} %) are occluded mostly by the backs of faces in front of what \
             the view shows (faces the camera looks through: one mesh passing through another); the band without \
             them: HAO {:.4}, HAO + near field {:.4}, Bevy SSAO {:.4}",
            culled,
            100.0 * culled as f32 / band.len() as f32,
            mae(&ao[0], &band_seen),
            mae(&ao[1], &band_seen),
            mae(&ao[2], &band_seen)
        );
    }
    let (e_hao, e_ssao) = (mae(&ao[0], &pixels), mae(&ao[2], &pixels));
    println!("\nHAO's error is {:.2}x Bevy SSAO's", e_hao / e_ssao.max(1e-6));
    if args.bias {
        let voxels = bevy_hao_tools::harness::read_trace_voxels(&mut app);
        let levels = bevy_hao_tools::harness::trace_levels(&voxels);
        let surfaces: Vec<(u32, Vec3, Vec3)> = pixels
            .iter()
            .map(|&i| {
                let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
                let ndc = Vec3::new((x + 0.5) / w as f32 * 2.0 - 1.0, 1.0 - (y + 0.5) / h as f32 * 2.0, depth[i]);
                (i as u32, world_from_clip.project_point3(ndc), normals[i])
            })
            .collect();
        let view = bevy_hao::cpu::contacts::ViewDepth {
            size: UVec2::new(w, h),
            depth: depth.clone(),
            clip_from_world,
            view_from_world,
            view_from_clip,
            normals: normals.clone(),
        };
        let trace = bevy_hao_tools::harness::cpu_trace_settings(&sanitized);
        let misses = print_bias(&scene, &levels, &view, &surfaces, &trace, epsilon, &occluder_view);
        // The reference in grey, red where the twin misses occluders within a cell that the view shows.
        let map = image::RgbImage::from_fn(w, h, |x, y| {
            let i = (y * w + x) as usize;
            let grey = (reference[i].clamp(0.0, 1.0) * 200.0) as u8;
            let red = (misses[i] as f32 / BIAS_RAYS as f32 * 4.0).min(1.0);
            image::Rgb([
                grey.saturating_add((red * 255.0) as u8),
                (grey as f32 * (1.0 - red)) as u8,
                (grey as f32 * (1.0 - red)) as u8,
            ])
        });
        let path = std::path::Path::new(&args.out).with_extension("near-misses.png");
        match map.save(&path) {
            Ok(()) => eprintln!(
                "wrote {} (red: rays whose occluder within a cell the view shows and HAO misses)",
                path.display()
            ),
            Err(e) => eprintln!("error: writing {}: {e}", path.display()),
        }
    }

    // The PNG: HAO | HAO + near field | SSAO | reference.
    let panels = [&ao[0], &ao[1], &ao[2], &reference];
    let mut png = image::GrayImage::new(w * 4 + 3 * 4, h);
    for (k, panel) in panels.iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                let v = if depth[(y * w + x) as usize] > 0.0 { panel[(y * w + x) as usize] } else { 1.0 };
                png.put_pixel(k as u32 * (w + 4) + x, y, image::Luma([(v.clamp(0.0, 1.0) * 255.0).round() as u8]));
            }
        }
    }
    match png.save(&args.out) {
        Ok(()) => {
            eprintln!("wrote {} (left to right: HAO, HAO + near field, Bevy SSAO, ray-traced reference)", args.out)
        }
        Err(e) => {
            eprintln!("error: writing {}: {e}", args.out);
            std::process::exit(1);
        }
    }
}

/// Rays a pixel of the `--bias` table.
const BIAS_RAYS: u32 = 64;

/// How the first contact sample past a missed occluder lies against the view ([`near_miss_kind`]).
const MISS_KINDS: [&str; 7] = [
    "none (all before it)",
    "off the view or over the background",
    "in front of the view's surface",
    "on it, to the prepass's precision (CONTACT_DEPTH_EPSILON)",
    "1-2 cells behind it",
    "2-4 cells behind it",
    "4+ cells behind it",
];

/// Which of [`MISS_KINDS`] ray `r` (direction `dir` from the surface point `world`, normal `normal`, `cell` the
/// size of the level it starts in) falls in, its reference occluder at distance `reference`: its contact
/// samples placed as the trace's twin places them (`cpu::contacts::depth_contact`, `pixel_jitter` turned for
/// ray `r`).
#[allow(clippy::too_many_arguments)]
fn near_miss_kind(
    view: &bevy_hao::cpu::contacts::ViewDepth,
    world: Vec3,
    normal: Vec3,
    dir: Vec3,
    cell: f32,
    s: &bevy_hao::cpu::ao::TraceSettings,
    pixel_jitter: f32,
    r: u32,
    reference: Option<f32>,
) -> usize {
    use bevy_hao::cpu::contacts::{CONTACT_LENGTH, contact_lift, ray_jitter};
    let lift = contact_lift(view.pixel_size((view.clip_from_world * world.extend(1.0)).w), cell);
    let length = CONTACT_LENGTH * s.start_offset * cell;
    let jitter = ray_jitter(pixel_jitter, r);
    let samples = s.contact_samples.max(1);
    let reference = reference.unwrap_or(0.0);
    let Some(t) = (0..samples).map(|k| length * (k as f32 + jitter) / samples as f32).find(|&t| t > reference) else {
        return 0;
    };
    match view.depth_behind(world + normal * lift + dir * t) {
        None => 1,
        Some(d) if d <= 0.0 => 2,
        Some(d) => 3 + [1.0, 2.0, 4.0].iter().take_while(|&&edge| d / cell >= edge).count(),
    }
}

/// The `--bias` table: along `BIAS_RAYS` rays from each surface point (pixel, world position, normal), the
/// occluder the CPU twin of HAO's trace finds on `levels` against the reference's nearest triangle, their
/// falloff weights compared by the reference's distance in cells of the level the ray starts in, and by
/// that level. Each row's share of the mean AO difference (HAO - reference; positive: HAO lighter) sums
/// to the twin's whole difference, the trace's bias before accumulation and the denoiser. `occluder_view`
/// tells which of the reference's occluders the twin misses the view hides (which only the voxels can find).
fn print_bias(
    scene: &ReferenceScene,
    levels: &[bevy_hao::cpu::march::TraceLevel],
    view: &bevy_hao::cpu::contacts::ViewDepth,
    surfaces: &[(u32, Vec3, Vec3)],
    s: &bevy_hao::cpu::ao::TraceSettings,
    epsilon: f32,
    occluder_view: &dyn Fn(Vec3, Vec3) -> OccluderView,
) -> Vec<u32> {
    use bevy_hao::cpu::ao::{TraceWork, ao_falloff, hemisphere_direction, orthonormal_basis, ray_occluder};
    use bevy_hao::cpu::contacts::CONTACT_THICKNESS;
    use bevy_hao::cpu::march::ray_start_level;
    const BINS: [&str; 8] =
        ["no occluder", "0-1/4 cell", "1/4-1 cell", "1-2 cells", "2-4 cells", "4-8 cells", "8-16 cells", "16+ cells"];
    // Per row: rays, rays HAO finds no occluder on, sum of the reference's weights, sum of HAO's.
    #[derive(Clone, Copy, Default)]
    struct Row {
        rays: u64,
        missed: u64,
        // Of those, the rays whose reference occluder the view hides (off screen or behind what it shows).
        missed_hidden: u64,
        found: u64,
        parallel: u64,
        reference: f64,
        hao: f64,
    }
    impl std::ops::AddAssign for Row {
        fn add_assign(&mut self, o: Row) {
            (self.rays, self.missed, self.found, self.parallel) =
                (self.rays + o.rays, self.missed + o.missed, self.found + o.found, self.parallel + o.parallel);
            self.missed_hidden += o.missed_hidden;
            (self.reference, self.hao) = (self.reference + o.reference, self.hao + o.hao);
        }
    }
    let mut by_distance = [Row::default(); BINS.len()];
    // The rays whose reference occluder lies within a cell that the twin misses and the view does not hide:
    // where the first contact sample past that occluder lies against the view's surface (`MISS_KINDS`).
    let mut near_misses = [0u64; MISS_KINDS.len()];
    // Of those, the rays whose occluder is the back of a face the camera looks through.
    let mut near_misses_culled = [0u64; MISS_KINDS.len()];
    // Those rays, per pixel (row by row).
    let mut miss_map = vec![0u32; view.size.x as usize * view.size.y as usize];
    let mut by_level = vec![Row::default(); levels.len()];
    let mut work = TraceWork::default();
    // The mean absolute difference of the pixels' AO, from these rays.
    let mut pixel_error = 0.0f64;
    // The contact band (the pixels whose reference AO from these rays is under 0.5): the sum of their
    // absolute differences, their count, and the sum of HAO's AO less the reference's.
    let mut band = (0.0f64, 0u64, 0.0f64);
    for &(i, world, normal) in surfaces {
        let rotation = Vec2::new(hash(i * 2 + 1), hash(i * 2 + 2));
        let jitter = hash(i * 2 + 3);
        let basis = orthonormal_basis(normal);
        let mut pixel_difference = 0.0f64;
        let mut pixel_reference = 0.0f64;
        for r in 0..BIAS_RAYS {
            let dir = hemisphere_direction(basis, r, BIAS_RAYS, rotation);
            let start = ray_start_level(levels, world, r, rotation);
            let origin = world + normal * epsilon;
            let hit = scene.closest_hit_normal(origin, dir, epsilon, s.max_distance);
            let reference = hit.map(|(t, _)| t);
            // An occluder on a surface within 25 degrees of parallel to the pixel's (its own surface curving
            // back, or a layer lying on it) rather than one across the ray's way.
            let parallel = hit.is_some_and(|(_, n)| n.dot(normal).abs() > 0.906);
            let contact =
                Some(bevy_hao::cpu::ao::DepthContacts { view, jitter: bevy_hao::cpu::contacts::ray_jitter(jitter, r) });
            let hao = ray_occluder(levels, contact, world, normal, dir, start, s, &mut work);
            let w_ref = reference.map_or(0.0, |d| ao_falloff(d, s.max_distance, s.falloff));
            let w_hao = hao.map_or(0.0, |d| ao_falloff(d, s.max_distance, s.falloff));
            let bin = match reference {
                None => 0,
                Some(d) => {
                    let cells = d / levels[start].cell_size;
                    1 + [0.25, 1.0, 2.0, 4.0, 8.0, 16.0].iter().take_while(|&&edge| cells >= edge).count()
                }
            };
            pixel_difference += f64::from(w_hao - w_ref);
            pixel_reference += f64::from(w_ref);
            let ray = Row {
                rays: 1,
                missed: u64::from(reference.is_some() && hao.is_none()),
                missed_hidden: u64::from(
                    hao.is_none()
                        && hit.is_some_and(|(t, n)| occluder_view(origin + dir * t, n) == OccluderView::Hidden),
                ),
                found: u64::from(reference.is_none() && hao.is_some()),
                parallel: u64::from(parallel),
                reference: f64::from(w_ref),
                hao: f64::from(w_hao),
            };
            if ray.missed == 1 && ray.missed_hidden == 0 && (bin == 1 || bin == 2) {
                let kind = near_miss_kind(view, world, normal, dir, levels[start].cell_size, s, jitter, r, reference);
                near_misses[kind] += 1;
                miss_map[i as usize] += 1;
                near_misses_culled[kind] +=
                    u64::from(hit.is_some_and(|(t, n)| occluder_view(origin + dir * t, n) == OccluderView::Culled));
            }
            by_distance[bin] += ray;
            by_level[start] += ray;
        }
        // HAO's AO less the reference's (AO is one less the occlusion).
        let lighter = -f64::from(s.intensity) * pixel_difference / f64::from(BIAS_RAYS);
        pixel_error += lighter.abs();
        if 1.0 - pixel_reference / f64::from(BIAS_RAYS) < 0.5 {
            band = (band.0 + lighter.abs(), band.1 + 1, band.2 + lighter);
        }
    }
    let total = (surfaces.len() as u64 * u64::from(BIAS_RAYS)).max(1) as f64;
    let print = |name: String, row: &Row| {
        let n = row.rays.max(1) as f64;
        println!(
            "| {name} | {:.1} % | {:.1} % | {:.3} | {:.3} | {:.1} % | {:.0} % | {:.1} % | {:+.4} |",
            100.0 * row.rays as f64 / total,
            100.0 * row.parallel as f64 / n,
            row.reference / n,
            row.hao / n,
            100.0 * row.missed as f64 / n,
            100.0 * row.missed_hidden as f64 / row.missed.max(1) as f64,
            100.0 * row.found as f64 / n,
            s.intensity as f64 * (row.reference - row.hao) / total,
        );
    };
    println!(
        "\nWhere the trace departs from the reference, ray by ray ({BIAS_RAYS} rays from each pixel above, the CPU twin \
         of the trace on this frame's voxels, {} rays, {} steps; before accumulation and the denoiser). By the \
         reference's occluder distance, in cells of the level the ray starts in:\n",
        s.rays, s.steps
    );
    let header = "| rays | reference occluder within 25 degrees of parallel to the pixel | mean reference occlusion | mean HAO occlusion | HAO finds none | of those, the view hides the occluder | HAO finds one where the reference has none | share of mean AO, HAO - reference |";
    println!("| reference occluder {header}\n|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut sum = Row::default();
    for (name, row) in BINS.iter().zip(&by_distance) {
        print(name.to_string(), row);
        sum += *row;
    }
    print("all".to_string(), &sum);
    println!(
        "\nThe pixels' AO from these {BIAS_RAYS} rays: mean absolute difference from the reference {:.4}",
        pixel_error / surfaces.len().max(1) as f64
    );
    println!(
        "Where the reference's AO from these rays is under 0.5 (the contact band): {} pixels ({:.1} %), mean absolute difference {:.4}, mean HAO - reference {:+.4}",
        band.1,
        100.0 * band.1 as f64 / surfaces.len().max(1) as f64,
        band.0 / band.1.max(1) as f64,
        band.2 / band.1.max(1) as f64
    );
    let misses = near_misses.iter().sum::<u64>().max(1) as f64;
    println!(
        "\nOf the rays whose reference occluder lies within a cell, those HAO misses and the view does not hide \
         ({}): where the first of the ray's contact samples past the occluder lies against the surface the view \
         shows at its pixel (in cells of the level the ray starts in; the contacts take 0-{CONTACT_THICKNESS} \
         along the view):\n\n| first sample past the occluder | share | of those, the occluder a face's back the camera \
         looks through |\n|---|---:|---:|",
        near_misses.iter().sum::<u64>()
    );
    for ((kind, n), culled) in MISS_KINDS.iter().zip(near_misses).zip(near_misses_culled) {
        println!("| {kind} | {:.1} % | {:.0} % |", 100.0 * n as f64 / misses, 100.0 * culled as f64 / n.max(1) as f64);
    }
    println!(
        "\nBy the level the ray starts in:\n\n| level (cell size) {header}\n|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for (l, row) in by_level.iter().enumerate() {
        print(format!("{l} ({})", levels[l].cell_size), row);
    }
    miss_map
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_motion_ends_at_the_still_pose_at_its_fastest() {
        let start = Transform::from_xyz(1.0, 2.0, 3.0).looking_at(Vec3::new(-4.0, 1.0, 0.0), Vec3::Y);
        let speed = 0.5f32;
        let motion = Motion::new(start, start.translation + start.forward().as_vec3() * 5.0, speed, 3 * MOTION_PERIOD);
        let end = motion.pose(motion.end);
        assert!(
            end.translation.distance(start.translation) < 1e-4 && end.rotation.angle_between(start.rotation) < 1e-4
        );
        // The turn of one frame: DEG at the end, none at the swing's far ends.
        let turn = |f: u32| motion.pose(f).rotation.angle_between(motion.pose(f - 1).rotation).to_degrees();
        assert!((turn(motion.end) - speed).abs() < 0.01, "{}", turn(motion.end));
        assert!(turn(MOTION_PERIOD / 4) < 0.1 * speed, "{}", turn(MOTION_PERIOD / 4));
        // The camera keeps looking at the centre.
        let mid = motion.pose(MOTION_PERIOD / 4);
        let to_center = (motion.center - mid.translation).normalize();
        assert!(mid.forward().as_vec3().dot(to_center) > 0.9999);
    }

    #[test]
    fn motion_speeds_outside_the_range_are_refused() {
        assert_eq!(motion_speed("0.5"), Ok(0.5));
        for bad in ["0", "-1", "NaN", "3.5", "fast"] {
            assert!(motion_speed(bad).is_err(), "{bad}");
        }
    }
}
