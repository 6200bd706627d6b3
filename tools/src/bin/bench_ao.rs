//! GPU cost of the hybrid ambient occlusion passes beside Bevy's SSAO pass, at the same resolution, in the
//! same frames.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin bench_ao -- [SCENE] [--size 1280x720] [--frames 10] [--rounds 3]
//!     [--quality low|medium|high|ultra ...] [--res N | --cascades L,CELLS,FINEST] [--attributes]
//!     [--no-depth-contacts] [--depth-free-space [on|off|both]] [--custom RAYS,STEPS ...]
//! ```
//!
//! One headless camera renders the scene in phases of one run, each measured over `--frames` frames after a
//! warm-up, in `--rounds` rounds:
//!
//! 1. Bevy's SSAO alone at each of its qualities (Low, Medium, High, Ultra), on a camera without HAO: the
//!    `ssao` span;
//! 2. for each HAO quality preset, the camera with `HybridAmbientOcclusion` at its defaults (near field
//!    off, 16 frames accumulated), then without accumulation (`accumulation_frames: 1`, the presets' rays
//!    before it): the spans `hao/trace`, `hao/neighborhood` (the windows and the denoiser), `hao/temporal`
//!    (which writes the AO PBR reads), `hao/apply` (with the near field only), and `ssao` if Bevy's SSAO
//!    passes ran (the plugin skips them when HAO overwrites their result; "not run" then).
//!
//! It prints their medians, the whole AO cost of a HAO frame (the HAO passes plus any SSAO pass that ran),
//! and its ratio to Bevy's SSAO alone at its default quality, High. Voxelization is not counted there (see
//! `bench_voxelize`).
//!
//! A second table times whole frames on the wall clock, the device waited for after each. Every round runs
//! a phase without AO before the first phase and after each one; a phase's cost in a round is the median of
//! its frames less the mean of the medians of the phases without AO on either side of it (which takes out a
//! drift of the machine's speed across the phase), and its cost is the median over the rounds. The ratio to
//! Bevy's SSAO High is taken between those costs, and the lowest and highest of the rounds' own ratios are
//! printed beside it: the spread to read before comparing two runs. This is the measure on lavapipe, whose
//! timestamps are taken when its rasterizer runs a scene and can miss compute passes between render passes
//! (the neighborhood pass reads about 0.05 ms there however long it ran); on a GPU the spans are the
//! measure. On a software rasterizer such as lavapipe the times are CPU times of the emulated GPU: compare
//! ratios within one run, not absolute figures.
//!
//! A last table counts the trace's work on its CPU twin (`bevy_hao::cpu::ao::voxel_ambient_occlusion_counted`),
//! over the view the GPU traced (its depth and normal, read back) and the GPU's voxels, for each row above:
//! rays per pixel a frame, texel visits per ray (the mean, and as a SIMD device pays them: each ray of a
//! warp of 8x4 texels of the trace at its slowest lane's visits, in the first march and again in each pass
//! past free space), voxel texels fetched per pixel a frame, the depth prepass samples a ray reads for its
//! contacts and free space (and the share of rays a contact stops, whose march is not run), the share of rays
//! that hit, of marches stopped by the step budget, and the hits passed as free space per ray. Unlike the
//! times, these do not depend on the device. `--no-depth-contacts` runs every preset without its depth contacts
//! (`HybridAmbientOcclusion::depth_contacts`), for a comparison run after run.
//!
//! With `--attributes` (and `--res`: the default cascades' attribute sums exceed some devices' binding limit)
//! the volume keeps multi-valued voxels, and a last table times the `Medium` trace with rays stopping at the
//! backs of surfaces and passing through them (`HybridAmbientOcclusion::ignore_back_hits`).
//!
//! With `--gi` (and `--cascades` or `--res` whose attributes the device can hold: lavapipe's storage binding
//! is 128 MiB, which 3 cascades of 112^3 fit) another table times voxel global illumination
//! (`VoxelGlobalIllumination` at its defaults) on top of `Medium`, in rounds of their own: `Medium` alone,
//! then with GI, each with the phases without AO around it, their spans (`hao/gi_lighting`,
//! `hao/gi_probes`, `hao/gi_write`) and wall-clock costs, and GI's own (the difference) against Bevy's SSAO
//! High of the main table.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::pbr::{ScreenSpaceAmbientOcclusion, ScreenSpaceAmbientOcclusionQualityLevel};
use bevy::prelude::*;
use bevy_hao::cpu::contacts::{ViewDepth, contact_jitter, ray_jitter};
use bevy_hao::prelude::*;
use bevy_hao_tools::scene::{SceneSource, default_camera, spawn_scene};
use clap::Parser;

#[derive(Component)]
struct BenchCamera;

/// GPU cost of the hybrid ambient occlusion passes beside Bevy's SSAO pass, at the same resolution, in the
/// same frames.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// The scene: builtin:cathedral (or another built-in shape), or the path of an OBJ, glTF or GLB file.
    #[arg(default_value = "builtin:cathedral")]
    scene: String,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = bevy_hao_tools::harness::args::size)]
    size: UVec2,
    /// Frames measured per phase.
    #[arg(long, default_value_t = 10)]
    frames: usize,
    /// Times every phase is measured, in turn: the spans' medians are over the frames of all rounds, the
    /// wall-clock costs the medians of the rounds' costs.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    rounds: u64,
    /// Only this preset (repeat for more; default: every preset).
    #[arg(long, value_enum)]
    quality: Vec<bevy_hao_tools::harness::args::Quality>,
    /// A single grid fitted to the scene with this many cells on its longest axis (default: the plugin's
    /// default volume, camera-following cascades).
    #[arg(long)]
    res: Option<u32>,
    /// Camera-following cascades of this shape instead of the default's (4,192,0.125): LEVELS,CELLS,
    /// FINEST_CELL_SIZE.
    #[arg(long, value_parser = bevy_hao_tools::harness::args::cascades, conflicts_with = "res")]
    cascades: Option<(u32, u32, f32)>,
    /// Multi-valued voxels (VoxelVolume::attributes), and the trace with and without ignore_back_hits.
    #[arg(long, requires = "res")]
    attributes: bool,
    /// The presets without their depth contacts (HybridAmbientOcclusion::depth_contacts off): the voxels
    /// alone.
    #[arg(long)]
    no_depth_contacts: bool,
    /// The presets passing the voxel hits the depth prepass shows in free space, or not, or each preset
    /// both ways side by side (HybridAmbientOcclusion::depth_free_space; `--depth-free-space` alone is on;
    /// default: each preset's own choice, on for High and Ultra).
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "on")]
    depth_free_space: Option<FreeSpace>,
    /// Also a `HaoQuality::Custom` preset, accumulated and at half resolution as the presets are, with
    /// RAYS rays a frame and STEPS steps a ray: RAYS,STEPS (repeat for more).
    #[arg(long, value_parser = rays_steps)]
    custom: Vec<(u32, u32)>,
    /// Also voxel global illumination on top of `Medium`, timed beside it (needs a volume whose attributes
    /// the device can hold: `--cascades` or `--res`).
    #[arg(long)]
    gi: bool,
}

/// `RAYS,STEPS`, both at least 1.
fn rays_steps(s: &str) -> Result<(u32, u32), String> {
    let (rays, steps) = s.split_once(',').ok_or("expected RAYS,STEPS")?;
    let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|&n| n >= 1).ok_or(format!("not a count: {v}"));
    Ok((parse(rays)?, parse(steps)?))
}

/// `--depth-free-space`: [`HybridAmbientOcclusion::depth_free_space`] for every preset.
#[derive(Clone, Copy, Debug, PartialEq, clap::ValueEnum)]
enum FreeSpace {
    /// `Some(true)`.
    On,
    /// `Some(false)`.
    Off,
    /// Each preset twice, without and with.
    Both,
}

impl FreeSpace {
    /// The settings a preset runs with.
    fn settings(choice: Option<Self>) -> Vec<Option<bool>> {
        match choice {
            None => vec![None],
            Some(Self::On) => vec![Some(true)],
            Some(Self::Off) => vec![Some(false)],
            Some(Self::Both) => vec![Some(false), Some(true)],
        }
    }
}

/// A preset's name in the tables: its quality, and whether it passes free space.
fn preset_name(settings: &HybridAmbientOcclusion) -> String {
    let free = if settings.uses_depth_free_space() { " + free space" } else { "" };
    format!("{:?}{free}", settings.quality)
}

fn main() {
    let Args {
        scene,
        size,
        frames,
        rounds,
        quality,
        res,
        cascades,
        attributes,
        no_depth_contacts,
        depth_free_space,
        custom,
        gi,
    } = Args::parse();
    let rounds = rounds as usize;
    let source = SceneSource::parse(&scene).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let triangles = source.triangles().unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let Some(bounds) = triangles.bounds() else {
        eprintln!("error: {scene}: no triangles to render");
        std::process::exit(1)
    };
    bevy_hao_tools::harness::set_asset_root(source.asset_root());
    let camera = default_camera(bounds, true);
    let setup_source = source.clone();
    let mut app = bevy_hao_tools::harness::headless_app(move |app| {
        let source = setup_source.clone();
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>,
                  server: Res<AssetServer>| {
                spawn_scene(&source, &mut commands, &mut meshes, &mut materials, &server).expect("scene");
                if let Some(res) = res {
                    commands.spawn(VoxelVolume {
                        bounds: VolumeBounds::FitStaticScene { margin: 0.0 },
                        resolution: VolumeResolution::Cells(res),
                        attributes,
                        ..default()
                    });
                } else if let Some((cascades, cells, finest_cell_size)) = cascades {
                    commands.spawn(VoxelVolume {
                        bounds: VolumeBounds::FollowCamera { cascades, cells, finest_cell_size },
                        ..default()
                    });
                }
                let target = bevy_hao_tools::harness::target_image(&mut images, size);
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target.into()),
                    Msaa::Off,
                    Tonemapping::None,
                    camera,
                    HybridAmbientOcclusion::default(),
                    BenchCamera,
                ));
            },
        );
    });
    let mut warm = 0;
    // Until the scene is voxelized and no static occluder waits to stream in.
    while warm < 300 && {
        let s = bevy_hao_tools::harness::stats(&app);
        s.static_rebuilds == 0 || s.static_queue > 0
    } {
        app.update();
        warm += 1;
    }
    let info = app.world().resource::<bevy::render::renderer::RenderAdapterInfo>();
    let (adapter, software) = (info.name.clone(), info.device_type == wgpu::DeviceType::Cpu);
    // The spans' samples, and the wall-clock time of each frame with the device waited for.
    let measure = |app: &mut App, warm_up: usize, spans: &[&str]| -> (Vec<Vec<f64>>, Vec<f64>) {
        bevy_hao_tools::harness::run(app, warm_up);
        bevy_hao_tools::harness::wait_for_gpu(app);
        let mut walls = Vec::new();
        // Only spans recorded since the last frame count: a diagnostic keeps its last value when a pass
        // stops running.
        let mut samples = vec![Vec::new(); spans.len()];
        let mut last = vec![None; spans.len()];
        for (l, span) in last.iter_mut().zip(spans) {
            *l = bevy_hao_tools::harness::diagnostic_measurement(app, &format!("render/{span}/elapsed_gpu"))
                .map(|m| m.0);
        }
        for _ in 0..frames {
            let start = std::time::Instant::now();
            app.update();
            bevy_hao_tools::harness::wait_for_gpu(app);
            walls.push(start.elapsed().as_secs_f64() * 1000.0);
            for ((s, l), span) in samples.iter_mut().zip(last.iter_mut()).zip(spans) {
                if let Some((at, v)) =
                    bevy_hao_tools::harness::diagnostic_measurement(app, &format!("render/{span}/elapsed_gpu"))
                    && Some(at) != *l
                {
                    *l = Some(at);
                    s.push(v);
                }
            }
        }
        (samples, walls)
    };
    let cam = app.world_mut().query_filtered::<Entity, With<BenchCamera>>().single(app.world()).unwrap();
    let presets: Vec<HybridAmbientOcclusion> = [HybridAmbientOcclusion::default().accumulation_frames, 1]
        .into_iter()
        .flat_map(|accumulation_frames| {
            [HaoQuality::Low, HaoQuality::Medium, HaoQuality::High, HaoQuality::Ultra].into_iter().flat_map(
                move |quality| {
                    FreeSpace::settings(depth_free_space).into_iter().map(move |depth_free_space| {
                        HybridAmbientOcclusion {
                            quality,
                            accumulation_frames,
                            depth_contacts: !no_depth_contacts,
                            depth_free_space,
                            ..default()
                        }
                    })
                },
            )
        })
        .filter(|settings| quality.is_empty() || quality.iter().any(|&q| HaoQuality::from(q) == settings.quality))
        .chain(custom.iter().flat_map(|&(rays, steps)| {
            FreeSpace::settings(depth_free_space).into_iter().map(move |depth_free_space| HybridAmbientOcclusion {
                quality: HaoQuality::Custom { rays, steps, half_resolution: true },
                depth_contacts: !no_depth_contacts,
                depth_free_space,
                ..default()
            })
        }))
        .collect();
    // Each round: Bevy's SSAO alone at each quality, then each preset with and without accumulation, with a
    // phase without AO before the first and after each: a phase's cost in a round is its frames' median less
    // the mean of the medians of the phases without AO on either side of it, which takes out the drift of the
    // device's speed across the phase (on a shared CPU, lavapipe's frames drift by a fifth within seconds). A
    // configuration's cost is the median of its rounds' costs; the spans' samples of every round are pooled.
    let ssao_qualities = [
        ScreenSpaceAmbientOcclusionQualityLevel::Low,
        ScreenSpaceAmbientOcclusionQualityLevel::Medium,
        ScreenSpaceAmbientOcclusionQualityLevel::High,
        ScreenSpaceAmbientOcclusionQualityLevel::Ultra,
    ];
    let phases = ssao_qualities.len() + presets.len();
    let bar = bevy_hao_tools::harness::progress_bar((rounds * (2 * phases + 1)) as u64, "bench_ao");
    let without_ao = |app: &mut App| {
        // The plugin takes the SSAO it added away with HAO (in the next frame).
        app.world_mut()
            .entity_mut(cam)
            .remove::<(HybridAmbientOcclusion, ScreenSpaceAmbientOcclusion, VoxelGlobalIllumination)>();
        app.update();
        let walls = measure(app, BASELINE_WARM_UP, &[]).1;
        bar.inc(1);
        walls
    };
    // Per phase (the SSAO qualities, then the presets): the spans' samples, the frames, the frames without
    // AO on either side, and the cost in each round.
    let mut measured: Vec<Measured> = (0..phases).map(|_| Measured::new(SPANS.len())).collect();
    for _ in 0..rounds {
        let mut before = without_ao(&mut app);
        for (phase, m) in measured.iter_mut().enumerate() {
            let mut entity = app.world_mut().entity_mut(cam);
            if let Some(quality_level) = ssao_qualities.get(phase) {
                // Bevy's SSAO alone, at this quality (HAO's spans record nothing then: only samples taken in
                // the phase count).
                entity.insert(ScreenSpaceAmbientOcclusion { quality_level: *quality_level, ..default() });
            } else {
                // HAO: the plugin adds its own (cheapest) SSAO.
                entity.insert(presets[phase - ssao_qualities.len()].clone());
            }
            let (s, w) = measure(&mut app, WARM_UP, &SPANS);
            bar.inc(1);
            let after = without_ao(&mut app);
            m.add_round(s, w, &before, &after);
            before = after;
        }
    }
    // Voxel GI on top of Medium, and Medium alone, in rounds of their own.
    let mut gi_measured: Vec<Measured> =
        if gi { (0..2).map(|_| Measured::new(GI_SPANS.len())).collect() } else { vec![] };
    for _ in 0..if gi { rounds } else { 0 } {
        let mut before = without_ao(&mut app);
        for (with_gi, m) in gi_measured.iter_mut().enumerate() {
            let mut entity = app.world_mut().entity_mut(cam);
            entity.insert(HybridAmbientOcclusion::default());
            if with_gi == 1 {
                entity.insert(VoxelGlobalIllumination::default());
            }
            let (s, w) = measure(&mut app, WARM_UP, &GI_SPANS);
            let after = without_ao(&mut app);
            m.add_round(s, w, &before, &after);
            before = after;
        }
    }
    // (The lighting pass's span is recorded only where GI ran.)
    let gi_on = gi_measured.get(1).is_some_and(|m| m.span(0).is_some());
    let median = bevy_hao_tools::harness::median;
    let (ssao_measured, preset_measured) = measured.split_at(ssao_qualities.len());
    // HAO is compared with Bevy's default quality, High.
    let ssao_high = &ssao_measured[2];
    let ssao_alone = ssao_high.span(SSAO_SPAN);
    let rows: Vec<(HybridAmbientOcclusion, &Measured)> = presets.into_iter().zip(preset_measured).collect();
    // With attributes: the Medium trace with rays stopping at backs, then passing through them.
    let mut backs = Vec::new();
    if attributes {
        for ignore_back_hits in [false, true] {
            app.world_mut().entity_mut(cam).insert(HybridAmbientOcclusion { ignore_back_hits, ..default() });
            backs.push((ignore_back_hits, median(measure(&mut app, WARM_UP, &["hao/trace"]).0.remove(0))));
        }
    }
    // The trace's work on the CPU twin, over the view the GPU traced and its voxels.
    let debug = {
        let mut images = app.world_mut().resource_mut::<Assets<Image>>();
        HaoDebugImages::new(&mut images, size)
    };
    app.world_mut().entity_mut(cam).insert((HybridAmbientOcclusion::default(), debug.clone()));
    bevy_hao_tools::harness::run(&mut app, 4);
    let (_, _, samples) = bevy_hao_tools::harness::view_samples(&mut app, cam, &debug);
    let view = bevy_hao_tools::harness::view_depth(&mut app, cam, &debug);
    let voxels = bevy_hao_tools::harness::read_trace_voxels(&mut app);
    let levels = bevy_hao_tools::harness::trace_levels(&voxels);
    let work: Vec<(HybridAmbientOcclusion, Work)> =
        rows.iter().map(|(settings, _)| (settings.clone(), trace_work(&samples, &view, &levels, settings))).collect();
    bar.finish_and_clear();
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
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    let grid = bevy_hao_tools::harness::grid_assets(&app).map(|g| g.grid.dims).unwrap_or_default();
    println!(
        "GPU: {adapter}; {scene} at {}x{}, voxel grid {}x{}x{}; medians of {} frames ({frames} in each of {rounds} \
         round(s))\n",
        size.x,
        size.y,
        grid.x,
        grid.y,
        grid.z,
        frames * rounds
    );
    println!(
        "Bevy's SSAO alone, at each of its qualities (its `ssao` span, and on the wall clock its frames less the \
         frames without AO on either side):\n"
    );
    println!("| Bevy SSAO quality | ssao ms | wall-clock cost ms | / SSAO High (span) |");
    println!("|---|---:|---:|---:|");
    for (quality_level, m) in ssao_qualities.iter().zip(ssao_measured) {
        let ratio = match (m.span(SSAO_SPAN), ssao_alone) {
            (Some(t), Some(s)) if s > 0.0 => format!("{:.2}", t / s),
            _ => "-".into(),
        };
        println!("| {quality_level:?} | {} | {} | {ratio} |", f(m.span(SSAO_SPAN)), f(m.cost()));
    }
    println!("\nEach HAO preset beside Bevy's SSAO High:\n");
    println!(
        "| HAO quality | frames accumulated | rays x steps a frame | trace ms | neighborhood ms | temporal ms \
         | apply ms | HAO passes ms | Bevy SSAO passes in the HAO frame ms | whole AO ms \
         | Bevy SSAO (High) alone ms | whole / SSAO |"
    );
    println!("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (settings, measured) in &rows {
        let m: Vec<Option<f64>> = (0..SPANS.len()).map(|i| measured.span(i)).collect();
        let (rays, steps, half) = settings.trace_parameters();
        // No `hao/apply` span: without the near field the temporal pass writes the AO PBR reads itself.
        let passes = match (m[0], m[1], m[2]) {
            (Some(a), Some(b), Some(c)) => Some(a + b + c + m[3].unwrap_or(0.0)),
            _ => None,
        };
        // No `ssao` span: the plugin skipped Bevy's SSAO passes (near field off), and they cost nothing.
        let kept = m[SSAO_SPAN].unwrap_or(0.0);
        let whole = passes.map(|p| p + kept);
        let ratio = match (whole, ssao_alone) {
            (Some(t), Some(s)) if s > 0.0 => format!("{:.2}", t / s),
            _ => "-".into(),
        };
        println!(
            "| {} | {} | {rays} x {steps}{} | {} | {} | {} | {} | {} | {} | {} | {} | {ratio} |",
            preset_name(settings),
            settings.accumulation_frames,
            match (half, settings.uses_checkerboard()) {
                (true, true) => ", half res, checkerboard",
                (true, false) => ", half res",
                _ => "",
            },
            f(m[0]),
            f(m[1]),
            f(m[2]),
            m[3].map_or("not run".to_string(), |v| format!("{v:.3}")),
            f(passes),
            m[SSAO_SPAN].map_or("not run".to_string(), |v| format!("{v:.3}")),
            f(whole),
            f(ssao_alone)
        );
    }
    // The wall-clock costs: each phase's frames less the frames without AO on either side, round by round.
    let ssao_cost = ssao_high.cost();
    println!(
        "\nWall-clock frames, the device waited for after each ({frames} frames a phase, {rounds} round(s)): a \
         phase's cost in a round is the median of its frames less the mean of the medians of the phases without \
         AO on either side (every pass and any CPU work it adds), and its cost is the median over the rounds. \
         Bevy's SSAO High alone: {} ms a frame against {} ms without AO, a cost of {} ms. The last column gives \
         the lowest and highest of the rounds' own ratios, each to SSAO High in the same round:\n",
        f(median(ssao_high.walls.clone())),
        f(median(ssao_high.baseline.clone())),
        f(ssao_cost),
    );
    println!(
        "| HAO quality | frames accumulated | frame ms | frame without AO ms | whole AO ms | whole / SSAO | rounds |"
    );
    println!("|---|---:|---:|---:|---:|---:|---|");
    for (settings, m) in &rows {
        let cost = m.cost();
        // No ratio where SSAO's cost came out at nothing or less (noise on a fast device).
        let ratio = match (cost, ssao_cost) {
            (Some(c), Some(s)) if s > 0.0 => format!("{:.2}", c / s),
            _ => "-".into(),
        };
        let per_round: Vec<f64> =
            m.costs.iter().zip(&ssao_high.costs).filter(|&(_, &s)| s > 0.0).map(|(c, s)| c / s).collect();
        let range = match (per_round.iter().copied().reduce(f64::min), per_round.iter().copied().reduce(f64::max)) {
            (Some(lo), Some(hi)) => format!("{lo:.2}-{hi:.2}"),
            _ => "-".into(),
        };
        println!(
            "| {} | {} | {} | {} | {} | {ratio} | {range} |",
            preset_name(settings),
            settings.accumulation_frames,
            f(median(m.walls.clone())),
            f(median(m.baseline.clone())),
            f(cost),
        );
    }
    println!(
        "\nThe trace's work, counted by its CPU twin over the same view and voxels (every {STRIDE}th pixel of \
         each row and column; per pixel that shows a surface, per frame; a warp's visits from every \
         {WARP_STRIDE}th warp of {}x{} texels of the trace along each axis):\n",
        WARP.0, WARP.1
    );
    println!(
        "| HAO quality | frames accumulated | rays per pixel | mean texel visits per ray | visits per ray, a warp's \
         slowest lane (lanes busy) | voxel texels fetched per pixel | depth samples per ray (rays stopped by a \
         contact) | rays that hit | marches out of steps | near hits passed as free space, per ray | other hits passed \
         as free space, per ray |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (settings, w) in &work {
        println!(
            "| {} | {} | {:.2} | {:.1} | {:.1} ({:.0} %) | {:.1} | {:.1} ({:.0} %) | {:.0} % | {:.1} % | {:.1} % | {:.1} % |",
            preset_name(settings),
            settings.accumulation_frames,
            w.rays_per_pixel,
            w.visits_per_ray,
            w.warp_visits_per_ray,
            100.0 * w.warp_lanes_busy,
            w.texels_per_pixel,
            w.depth_loads_per_ray,
            100.0 * w.contact_share,
            100.0 * w.hit_share,
            100.0 * w.out_of_steps_share,
            100.0 * w.near_free_space_share,
            100.0 * w.free_space_share
        );
    }
    println!("\nFor scale, Bevy's SSAO (GTAO) takes per pixel: Low 4, Medium 8, High 18, Ultra 54 depth samples (2D).");
    if gi {
        let defaults = VoxelGlobalIllumination::default();
        let c = defaults.probe_counts;
        println!(
            "\nVoxel global illumination at its defaults ({}x{}x{} probes {} m apart, {} rays a probe, one probe in {} \
             and one slab of voxels in {} a frame) on top of Medium, {rounds} round(s) of its own{}:\n",
            c.x,
            c.y,
            c.z,
            defaults.probe_spacing,
            defaults.rays,
            defaults.probe_frames,
            defaults.lighting_frames,
            if gi_on { "" } else { " (GI did not run: see the plugin's warning)" }
        );
        println!(
            "| phase | gi_lighting ms | gi_probes ms | gi_write ms | frame ms | frame without AO ms | cost ms | / SSAO \
             High (wall clock) |"
        );
        println!("|---|---:|---:|---:|---:|---:|---:|---:|");
        for (name, m) in ["Medium", "Medium + GI"].iter().zip(&gi_measured) {
            let ratio = match (m.cost(), ssao_cost) {
                (Some(c), Some(s)) if s > 0.0 => format!("{:.2}", c / s),
                _ => "-".into(),
            };
            println!(
                "| {name} | {} | {} | {} | {} | {} | {} | {ratio} |",
                f(m.span(0)),
                f(m.span(1)),
                f(m.span(2)),
                f(median(m.walls.clone())),
                f(median(m.baseline.clone())),
                f(m.cost())
            );
        }
        // GI's own: the rounds' differences between Medium with and without it.
        let own: Vec<f64> = gi_measured[1].costs.iter().zip(&gi_measured[0].costs).map(|(a, b)| a - b).collect();
        let own = median(own);
        let ratio = match (own, ssao_cost) {
            (Some(c), Some(s)) if s > 0.0 => format!("{:.2}", c / s),
            _ => "-".into(),
        };
        println!("| GI alone (the rounds' differences) | | | | | | {} | {ratio} |", f(own));
        if software {
            println!(
                "\n(On a CPU device such as lavapipe the GI spans do not measure GI's passes: skipping them takes \
                 hundreds of times their spans off the frame. Only the wall clock counts there: docs/figures.md, \
                 *A probe's rays shared by 8 lanes*.)"
            );
        }
    }
    if attributes {
        let kept = bevy_hao_tools::harness::grid_assets(&app).is_some_and(|g| g.attributes.is_some());
        println!(
            "\nMedium, accumulated, with the volume's attributes{}:\n",
            if kept { "" } else { " (turned off by the plugin!)" }
        );
        println!("| rays at the backs of surfaces | trace ms |");
        println!("|---|---:|");
        for (ignore, t) in backs {
            println!("| {} | {} |", if ignore { "pass through (the default)" } else { "stop" }, f(t));
        }
    }
}

/// The GPU spans read each frame: HAO's passes, and Bevy's SSAO (`SSAO_SPAN`).
const SPANS: [&str; 5] = ["hao/trace", "hao/neighborhood", "hao/temporal", "hao/apply", "ssao"];
/// The GPU spans of voxel GI.
const GI_SPANS: [&str; 3] = ["hao/gi_lighting", "hao/gi_probes", "hao/gi_write"];
/// Where Bevy's SSAO is in `SPANS`.
const SSAO_SPAN: usize = 4;

/// Frames run after a change of settings before a phase is measured: a preset's pipelines, its history (at
/// half resolution every pixel is traced once in four frames, in a checkerboard once in eight) and Bevy's SSAO
/// textures settle.
const WARM_UP: usize = 8;
/// Frames run before a phase without AO is measured: only passes stop running.
const BASELINE_WARM_UP: usize = 2;

/// One phase's measurements over the rounds.
struct Measured {
    /// Each span's samples, pooled over the rounds.
    spans: Vec<Vec<f64>>,
    /// The wall-clock frames, pooled.
    walls: Vec<f64>,
    /// The frames without AO on either side of the phase, pooled.
    baseline: Vec<f64>,
    /// The phase's wall-clock cost in each round: its frames' median less the mean of the medians of the
    /// phases without AO before and after it.
    costs: Vec<f64>,
}

impl Measured {
    fn new(spans: usize) -> Self {
        Self { spans: vec![Vec::new(); spans], walls: Vec::new(), baseline: Vec::new(), costs: Vec::new() }
    }

    /// A round: the spans' samples, the frames, and the frames without AO before and after them.
    fn add_round(&mut self, spans: Vec<Vec<f64>>, walls: Vec<f64>, before: &[f64], after: &[f64]) {
        let median = bevy_hao_tools::harness::median;
        if let (Some(w), Some(b), Some(a)) = (median(walls.clone()), median(before.to_vec()), median(after.to_vec())) {
            self.costs.push(w - 0.5 * (b + a));
        }
        for (all, new) in self.spans.iter_mut().zip(spans) {
            all.extend(new);
        }
        self.walls.extend(walls);
        self.baseline.extend(before.iter().chain(after));
    }

    /// The median of span `i`'s samples.
    fn span(&self, i: usize) -> Option<f64> {
        bevy_hao_tools::harness::median(self.spans[i].clone())
    }

    /// The wall-clock cost: the median of the rounds' costs.
    fn cost(&self) -> Option<f64> {
        bevy_hao_tools::harness::median(self.costs.clone())
    }
}

/// Pixels sampled along each row and column for the work table.
const STRIDE: u32 = 4;

/// The trace's work per frame, per pixel that shows a surface.
struct Work {
    rays_per_pixel: f64,
    visits_per_ray: f64,
    /// Visits a ray as a warp pays them (its slowest lane's).
    warp_visits_per_ray: f64,
    /// Share of a warp's lanes' visits spent on their own rays.
    warp_lanes_busy: f64,
    texels_per_pixel: f64,
    /// Depth prepass samples a ray reads for its contacts.
    depth_loads_per_ray: f64,
    /// Share of the rays a contact in the depth prepass stopped (their march is not run).
    contact_share: f64,
    hit_share: f64,
    out_of_steps_share: f64,
    /// Voxel hits passed because the view shows them in free space, per ray.
    free_space_share: f64,
    near_free_space_share: f64,
}

/// The CPU twin's trace of every `STRIDE`th pixel (at half resolution, of the blocks those pixels start)
/// with the rays and steps `settings` trace a frame, counted.
fn trace_work(
    samples: &[Option<(Vec3, Vec3)>],
    view: &ViewDepth,
    levels: &[bevy_hao::cpu::march::TraceLevel],
    settings: &HybridAmbientOcclusion,
) -> Work {
    use bevy_hao::cpu::ao::{DepthContacts, TraceWork, ray_rotation, voxel_ambient_occlusion_counted};
    let (w, h) = (view.size.x, view.size.y);
    let half = settings.trace_parameters().2;
    let trace = bevy_hao_tools::harness::cpu_trace_settings(settings);
    // The sampled rows, shared out between threads (at 4K the twin traces half a million pixels).
    let rows: Vec<u32> = (0..h).step_by(STRIDE as usize).collect();
    let parts = on_every_core(&rows, |rows| {
        let mut work = TraceWork::default();
        let mut pixels = 0u64;
        for &y in rows {
            for x in (0..w).step_by(STRIDE as usize) {
                let Some((world, normal)) = samples[(y * w + x) as usize] else { continue };
                pixels += 1;
                let pixel = Vec2::new(x as f32, y as f32);
                let contacts = Some(DepthContacts { view, jitter: contact_jitter(pixel, 0) });
                let rotation = ray_rotation(pixel, 0);
                voxel_ambient_occlusion_counted(levels, contacts, world, normal, rotation, &trace, &mut work);
            }
        }
        (work, pixels)
    });
    let (mut work, mut pixels) = (TraceWork::default(), 0u64);
    for (part, n) in parts {
        work.rays += part.rays;
        work.texel_visits += part.texel_visits;
        work.normal_loads += part.normal_loads;
        work.hits += part.hits;
        work.depth_loads += part.depth_loads;
        work.contacts += part.contacts;
        work.out_of_steps += part.out_of_steps;
        work.free_space_passes += part.free_space_passes;
        work.near_free_space_passes += part.near_free_space_passes;
        pixels += n;
    }
    // At half resolution a traced sample serves a 2x2 block; in a checkerboard half the blocks trace a frame.
    let per_block = if settings.uses_checkerboard() { 0.125 } else { 0.25 };
    let per_pixel = if half { per_block } else { 1.0 } / pixels.max(1) as f64;
    let rays = work.rays.max(1) as f64;
    let (warp_visits, warp_lanes) = warp_work(samples, view, levels, settings);
    Work {
        rays_per_pixel: work.rays as f64 * per_pixel,
        visits_per_ray: work.texel_visits as f64 / rays,
        warp_visits_per_ray: warp_visits,
        warp_lanes_busy: warp_lanes,
        texels_per_pixel: (work.texel_visits + work.normal_loads) as f64 * per_pixel,
        depth_loads_per_ray: work.depth_loads as f64 / rays,
        contact_share: work.contacts as f64 / rays,
        hit_share: work.hits as f64 / rays,
        out_of_steps_share: work.out_of_steps as f64 / rays,
        free_space_share: work.free_space_passes as f64 / rays,
        near_free_space_share: work.near_free_space_passes as f64 / rays,
    }
}

/// The trace's texels one warp runs: 8 x 4, the first or second half of an 8 x 8 workgroup as NVIDIA's
/// 32-lane warps take it (the invocation index runs along x first).
const WARP: (u32, u32) = (8, 4);
/// Warps sampled along each row and column of warps for [`warp_work`].
const WARP_STRIDE: u32 = 4;

/// The march visits a ray as a SIMD device pays them: every `WARP_STRIDE`th warp of the trace's invocations
/// (its texels, or in a checkerboard every other texel of a row) along each axis is traced by the CPU twin with the rays and steps `settings` trace a frame, and each of a warp's
/// rays costs the visits of its slowest lane (lanes that finish wait for it; lanes on the background trace
/// nothing), in the first march, again in the passes past near hits in free space (all together, as one
/// march: they share its steps), and again in each pass past other hits in free space, each of which comes
/// after the march before it. (The marches through the backs of surfaces, a loop of their own too, count
/// with the first.) Returns
/// those visits per ray, and the share of them that a lane spends on its own ray (the lanes busy).
fn warp_work(
    samples: &[Option<(Vec3, Vec3)>],
    view: &ViewDepth,
    levels: &[bevy_hao::cpu::march::TraceLevel],
    settings: &HybridAmbientOcclusion,
) -> (f64, f64) {
    use bevy_hao::cpu::ao::{
        DepthContacts, TraceWork, checkerboard_texel, hemisphere_direction, orthonormal_basis, ray_occluder,
        ray_rotation, traced_pixel,
    };
    use bevy_hao::cpu::march::ray_start_level;
    let (w, h) = (view.size.x, view.size.y);
    let half = settings.trace_parameters().2;
    let trace = bevy_hao_tools::harness::cpu_trace_settings(settings);
    let (tw, th) = if half { (w.div_ceil(2), h.div_ceil(2)) } else { (w, h) };
    // The trace's invocations: in a checkerboard, half the texels of each row (`checkerboard_texel`).
    let checkerboard = settings.uses_checkerboard();
    let iw = if checkerboard { tw.div_ceil(2) } else { tw };
    let warp_rows: Vec<u32> = (0..th.div_ceil(WARP.1)).step_by(WARP_STRIDE as usize).collect();
    // Per part: the slowest lanes' visits summed over rays, the busy lanes' own visits, and the lanes' rays.
    let parts = on_every_core(&warp_rows, |warp_rows| {
        let (mut slowest, mut own, mut lane_rays) = (0u64, 0u64, 0u64);
        for &wy in warp_rows {
            for wx in (0..iw.div_ceil(WARP.0)).step_by(WARP_STRIDE as usize) {
                // Each busy lane's visits, ray by ray: in the first march, then in each pass past free space.
                let mut lanes: Vec<Vec<Vec<u64>>> = Vec::new();
                for ty in wy * WARP.1..((wy + 1) * WARP.1).min(th) {
                    for ix in wx * WARP.0..((wx + 1) * WARP.0).min(iw) {
                        let texel = checkerboard_texel(UVec2::new(ix, ty), 0, checkerboard);
                        if texel.x >= tw {
                            continue;
                        }
                        let p = traced_pixel(texel, 0, UVec2::new(w, h), half);
                        let Some((world, normal)) = samples[(p.y * w + p.x) as usize] else { continue };
                        let rotation = ray_rotation(p.as_vec2(), 0);
                        let jitter = contact_jitter(p.as_vec2(), 0);
                        let basis = orthonormal_basis(normal);
                        let visits = (0..trace.rays)
                            .map(|i| {
                                let dir = hemisphere_direction(basis, i, trace.rays, rotation);
                                let start = ray_start_level(levels, world, i, rotation);
                                let mut work = TraceWork::default();
                                let contact = Some(DepthContacts { view, jitter: ray_jitter(jitter, i) });
                                ray_occluder(levels, contact, world, normal, dir, start, &trace, &mut work);
                                let past = work.free_space_visits;
                                let near = work.near_free_space_visits;
                                let first = work.texel_visits - near - past.iter().sum::<u64>();
                                [first, near].into_iter().chain(past).collect()
                            })
                            .collect();
                        lanes.push(visits);
                    }
                }
                // Each pass past free space runs after every lane has left the march before it: the warp
                // pays its slowest lane in the first march and again in each pass.
                for i in 0..trace.rays as usize {
                    let marches = lanes.first().map_or(0, |l| l[i].len());
                    let warp: u64 = (0..marches).map(|k| lanes.iter().map(|l| l[i][k]).max().unwrap_or(0)).sum();
                    slowest += warp * lanes.len() as u64;
                    own += lanes.iter().map(|l| l[i].iter().sum::<u64>()).sum::<u64>();
                }
                lane_rays += lanes.len() as u64 * u64::from(trace.rays);
            }
        }
        (slowest, own, lane_rays)
    });
    let (slowest, own, rays) = parts.iter().fold((0, 0, 0), |a, p| (a.0 + p.0, a.1 + p.1, a.2 + p.2));
    (slowest as f64 / rays.max(1) as f64, own as f64 / slowest.max(1) as f64)
}

/// `work` over `items` shared out in one chunk per core, the chunks' results in order.
fn on_every_core<T: Send>(items: &[u32], work: impl Fn(&[u32]) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|s| {
        let handles: Vec<_> =
            items.chunks(items.len().div_ceil(threads).max(1)).map(|chunk| s.spawn(|| work(chunk))).collect();
        handles.into_iter().map(|h| h.join().expect("work thread")).collect()
    })
}
