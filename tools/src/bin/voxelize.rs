//! Offline voxelization with the CPU reference: quality and speed against a conservative ground truth, in
//! the spirit of Figure 10 of Fei et al. 2012, and binvox export.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin voxelize -- <PATH or builtin:NAME>... [--res 128,256,512]
//!     [--gamma 1.0] [--mode centroid|conservative] [--pattern strips,uniform] [--target-bias PCT]
//!     [--export OUT.binvox] [--gamma-sweep] [--runs N] [--gpu] [--max-memory-mb 4096]
//!     [--point-budget 268435456] [--animation NAME|INDEX --time SECONDS] [--list-animations]   (--help)
//! ```
//!
//! For each mesh and resolution the grid is fitted to the mesh's bounds with the longest axis at the
//! resolution, the mesh is voxelized by point-tessellated injection and by the exact conservative voxelizer
//! (the ground truth), and one table row compares them: bias = ground-truth voxels missing / ground-truth
//! voxels (the paper's figure), of which the share the surface only grazes (touches, or enters less than
//! 1/1000 cell deep), excess voxels (set but overlapped by no triangle), the six-direction watertight test
//! (n/a when the mesh encloses no voxel), and the median times of both voxelizers on all cores.
//! `--pattern` picks the subdivision pattern (`strips`, the default, or `uniform`); a list runs each, one row
//! apiece, against the same ground truth, with the points each injects per voxel it sets side by side.
//! `--target-bias` fits equation 3 to the mesh (biases measured at gamma 1, 1.5, 2, 3, 4) and uses the
//! gamma it predicts for the target; `--gamma-sweep` prints bias and time against gamma (Figure 5d).
//!
//! Limits, checked before anything is allocated or voxelized: a run whose grids would take more than
//! `--max-memory-mb` (about 8 bytes a voxel, 32 to 56 with `--attributes`) or whose triangles subdivide into more than `--point-budget`
//! sub-triangles is refused with the figure; a `--gamma` out of range is replaced with a warning; the tool
//! exits non-zero when a run was refused or nothing was voxelized.
//!
//! With `--gpu` the point-tessellated voxelization runs on the GPU instead, through the plugin in a
//! headless Bevy app (Mesa's lavapipe on a machine without a GPU): the mesh is a `StaticOccluder` in a
//! `VoxelVolume` with the same fitted grid, the GPU's occupancy is read back, measured against the same
//! ground truth and exported the same way, and the time column is the median GPU time of the static
//! voxelization pass (`hao/voxelize_static`) over `--runs` forced rebuilds. The GPU's grid is also held
//! against the CPU voxelizer's on the same mesh: how many voxels differ is printed.
//!
//! Animated glTF files: `--list-animations` prints each file's clips; `--animation NAME|INDEX --time SECONDS`
//! poses the file before voxelizing, with the project's own sampler of the clip's channels (translation,
//! rotation, scale, morph weights; step, linear and cubic-spline interpolation), morph targets, and skinning
//! by the joints' world transforms. With `--gpu` the plugin plays the same clip instead: Bevy loads the file as a scene, its
//! `AnimationPlayer` is sought to the time and paused, the skinned and morphed meshes are voxelized as
//! dynamic occluders, and the GPU time is the dynamic pass's (`hao/voxelize_dynamic`). Morph targets are applied on
//! both sides (the clip's weight channels, or the mesh's own weights), before skinning.

use bevy::prelude::*;
use bevy_hao::cpu::attributes::MeshAlbedo;
use bevy_hao::cpu::*;
use bevy_hao::prelude::*;
use bevy_hao::{RebuildStaticVoxels, VoxelizeCounters};
use bevy_hao_tools::meshes::load_mesh;
use bevy_hao_tools::{
    compare, graze_split, ground_truth_mesh, ground_truth_mesh_with_cuts, watertight, write_attribute_ply, write_binvox,
};
use clap::Parser;
use std::time::Instant;

struct Args {
    inputs: Vec<String>,
    resolutions: Vec<u32>,
    gamma: f32,
    mode: InjectionMode,
    patterns: Vec<SubdivisionPattern>,
    target_bias: Option<f64>,
    export: Option<String>,
    gamma_sweep: bool,
    pn: bool,
    solid: bool,
    attributes: bool,
    runs: usize,
    gpu: bool,
    max_memory_mb: u64,
    point_budget: u64,
    animation: Option<String>,
    time: f32,
    list_animations: bool,
}

/// The command line; [`parse_args`] checks it into [`Args`].
#[derive(Parser)]
#[command(
    version,
    about = "Point-tessellated voxelization of meshes on the CPU (or the GPU), against an exact conservative ground truth"
)]
struct Cli {
    /// Meshes: paths of OBJ, glTF or GLB files, or builtin:NAME.
    #[arg(required = true)]
    inputs: Vec<String>,
    /// Grid resolutions (cells on the longest axis, 1..=2048), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [128])]
    res: Vec<u32>,
    /// Sub-triangle size factor: pieces are at most 1/gamma cell per axis.
    #[arg(long, default_value_t = 1.0)]
    gamma: f32,
    /// Injection mode: centroid (the paper's) or conservative.
    #[arg(long, default_value = "centroid")]
    mode: InjectionMode,
    /// Subdivision patterns, comma-separated: each runs in turn, rows side by side.
    #[arg(long, value_delimiter = ',', default_value = "strips")]
    pattern: Vec<SubdivisionPattern>,
    /// Choose gamma for this centroid bias, a percentage in (0, 100) (equation 3).
    #[arg(long)]
    target_bias: Option<f64>,
    /// Write the grid to this binvox file (with several meshes or resolutions, `OUT-<mesh>-<res>.binvox`).
    /// One pattern at a time.
    #[arg(long)]
    export: Option<String>,
    /// Bias and points over a sweep of gamma.
    #[arg(long)]
    gamma_sweep: bool,
    /// Voxelize PN triangles (Fei 2012 section 3.4): each triangle curved by the vertex normals of the
    /// welded mesh (smooth everywhere: hard edges are rounded, a box balloons), by the CPU twin; the grid is
    /// fitted to the patches' control points. Bias, excess and the watertight
    /// test still compare with the flat mesh's ground truth.
    #[arg(long)]
    pn: bool,
    /// Fill the inside of closed meshes (Dong et al. 2004: parity of crossings along z), by the CPU twin. A mesh
    /// that is not closed gets a warning, and its columns with an odd number of crossings stay hollow. The
    /// voxels-set, points-per-voxel and excess columns then count the inside, and the bias falls where the
    /// fill covers surface voxels that centroid injection missed; `--export` writes the solid. Not with
    /// `--gamma-sweep` or `--target-bias`.
    #[arg(long)]
    solid: bool,
    /// Multi-valued voxels: each voxel also keeps the average albedo (an OBJ's material colours, `Kd`;
    /// white for built-ins, glTF files and with `--pn`) and the average normal of its points. Adds the
    /// columns `voxels with attributes`, `mean albedo` and `normal agreement` (the mean length of the voxels'
    /// average normals: 1 where every voxel's points agree), and `--export` also writes `OUT.ply`, the
    /// voxels' centres, normals and colours. With `--gpu` the GPU's sums are held against the CPU twin's.
    #[arg(long)]
    attributes: bool,
    /// Timed runs per measurement (the median is printed).
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Voxelize on the GPU too (a headless Bevy app) and compare voxel for voxel.
    #[arg(long)]
    gpu: bool,
    /// Refuse a run whose grids would take more memory than this, MiB.
    #[arg(long, default_value_t = 4096)]
    max_memory_mb: u64,
    /// Refuse a run with more points than this.
    #[arg(long, default_value_t = 1 << 28)]
    point_budget: u64,
    /// Pose a glTF by this animation clip (name or index) before voxelizing.
    #[arg(long)]
    animation: Option<String>,
    /// The time in the clip, seconds.
    #[arg(long, default_value_t = 0.0, requires = "animation")]
    time: f32,
    /// List the glTF's animation clips and exit.
    #[arg(long)]
    list_animations: bool,
}

fn parse_args() -> Result<Args, String> {
    let c = Cli::parse();
    let mut a = Args {
        inputs: c.inputs,
        resolutions: c.res,
        gamma: c.gamma,
        mode: c.mode,
        patterns: c.pattern,
        target_bias: None,
        export: c.export,
        gamma_sweep: c.gamma_sweep,
        pn: c.pn,
        solid: c.solid,
        attributes: c.attributes,
        max_memory_mb: c.max_memory_mb,
        point_budget: c.point_budget,
        runs: c.runs.max(1),
        gpu: c.gpu,
        animation: c.animation,
        time: c.time,
        list_animations: c.list_animations,
    };
    if a.resolutions.iter().any(|&r| r == 0 || r > 2048) {
        return Err("resolutions must be in 1..=2048".into());
    }
    if let Some(p) = c.target_bias {
        if !(p > 0.0 && p < 100.0) {
            return Err("--target-bias is a percentage in (0, 100)".into());
        }
        a.target_bias = Some(p / 100.0);
    }
    if !a.time.is_finite() {
        return Err("--time must be a finite number of seconds".into());
    }
    if !(a.gamma.is_finite() && a.gamma > 0.0) {
        return Err("--gamma must be positive".into());
    }
    if a.export.is_some() && a.patterns.len() > 1 {
        return Err("--export writes one grid per mesh and resolution: give one --pattern".into());
    }
    let used = VoxelizeSettings { gamma: a.gamma, mode: a.mode, ..Default::default() }.effective_gamma();
    if used != a.gamma {
        eprintln!("warning: --gamma {} is out of range for {} mode; using {used}", a.gamma, a.mode);
        a.gamma = used;
    }
    if a.solid && (a.gamma_sweep || a.target_bias.is_some()) {
        return Err("--solid fills one grid: leave out --gamma-sweep and --target-bias".into());
    }
    if a.gpu && a.solid {
        return Err(
            "--solid is measured on the CPU twin (the GPU tests hold the plugin's fill to it); leave out --gpu".into(),
        );
    }
    if a.gpu && a.pn {
        return Err(
            "--pn is measured on the CPU twin (the GPU tests hold the plugin's PN triangles to it); leave out --gpu"
                .into(),
        );
    }
    if a.gpu && a.attributes && a.animation.is_some() {
        return Err("--attributes with --gpu voxelizes a mesh, not a posed glTF scene; leave out --animation".into());
    }
    if a.gpu && (a.gamma_sweep || a.target_bias.is_some()) {
        return Err("--gamma-sweep and --target-bias run on the CPU reference; leave out --gpu".into());
    }
    Ok(a)
}

/// Runs `f` on a cleared `grid` `runs` times; returns the median time (ms) and the last result.
fn median_ms<T>(runs: usize, grid: &mut VoxelOccupancy, f: impl Fn(&VoxelOccupancy) -> T) -> (f64, T) {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        grid.clear();
        let start = Instant::now();
        last = Some(f(grid));
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.expect("at least one run"))
}

/// The same voxelization on the GPU: returns the grid read back, the GPU's counters, the median GPU time of
/// the static pass over `runs` rebuilds, and the adapter's name.
/// What the GPU voxelizes: a mesh as one static occluder, or a glTF file's scene played by Bevy's animation
/// player at a clip's time (its skinned meshes dynamic).
enum GpuSource<'a> {
    Mesh(&'a TriangleMesh),
    Posed { path: &'a std::path::Path, clip: usize, time: f32 },
}

/// Starts the posed clip on every animation player the scene spawns: sought to the time and paused.
#[derive(Resource, Clone)]
struct PosedClip {
    graph: Handle<AnimationGraph>,
    node: AnimationNodeIndex,
    time: f32,
}

fn start_posed_clip(
    mut commands: Commands,
    clip: Res<PosedClip>,
    mut players: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
) {
    for (entity, mut player) in &mut players {
        player.play(clip.node).seek_to(clip.time).pause();
        commands.entity(entity).insert(AnimationGraphHandle(clip.graph.clone()));
    }
}

fn gpu_voxelize(
    source: GpuSource,
    bounds: (Vec3, Vec3),
    res: u32,
    settings: &VoxelizeSettings,
    runs: usize,
    attributes: Option<&[Vec4]>,
) -> Result<(VoxelOccupancy, VoxelizeCounters, Option<f64>, String), String> {
    if let GpuSource::Posed { path, clip, time } = source {
        return gpu_voxelize_posed(path, clip, time, bounds, res, settings, runs);
    }
    let GpuSource::Mesh(mesh) = source else { unreachable!("handled above") };
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    // With attributes: the vertex colours (white where there are none) under a white material.
    let colors: Option<Vec<[f32; 4]>> =
        attributes.map(|c| (0..positions.len()).map(|i| c.get(i).copied().unwrap_or(Vec4::ONE).to_array()).collect());
    let volume = VoxelVolume { attributes: attributes.is_some(), ..gpu_volume(bounds, res, settings) };
    let mut app = bevy_hao_tools::harness::headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>| {
                let mut m = Mesh::new(
                    bevy::mesh::PrimitiveTopology::TriangleList,
                    bevy::asset::RenderAssetUsages::RENDER_WORLD,
                )
                .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions.clone())
                .with_inserted_indices(bevy::mesh::Indices::U32(indices.clone()));
                if let Some(c) = &colors {
                    m.insert_attribute(Mesh::ATTRIBUTE_COLOR, c.clone());
                }
                commands.spawn(volume);
                commands.spawn((
                    Mesh3d(meshes.add(m)),
                    MeshMaterial3d(materials.add(StandardMaterial::default())),
                    StaticOccluder,
                ));
            },
        );
    });
    let mut frames = 0;
    while !(bevy_hao_tools::harness::stats(&app).static_rebuilds >= 1
        && bevy_hao_tools::harness::stats(&app).counter_readbacks >= 3)
    {
        app.update();
        frames += 1;
        if frames > 120 {
            return Err("the GPU voxelization did not complete within 120 frames".into());
        }
    }
    let errors = bevy_hao_tools::harness::take_render_errors();
    if !errors.is_empty() {
        return Err(format!("wgpu errors: {errors:?}"));
    }
    let occupancy = if attributes.is_some() {
        bevy_hao_tools::harness::read_records(&mut app)
    } else {
        bevy_hao_tools::harness::read_occupancy(&mut app)
    };
    let counters = bevy_hao_tools::harness::stats(&app).static_counters;
    // Each forced rebuild records one `hao/voxelize_static` span, whose timestamps arrive a few frames
    // later: rebuild and collect each new measurement until `runs` have arrived (a rebuild whose span never
    // arrives is made up for by another, up to 30 frames more).
    let span = "render/hao/voxelize_static/elapsed_gpu";
    let mut last = bevy_hao_tools::harness::diagnostic_measurement(&app, span).map(|m| m.0);
    let mut times = Vec::with_capacity(runs);
    let mut frames = 0;
    while times.len() < runs && frames < runs + 30 {
        if frames < runs || frames % 4 == 0 {
            app.world_mut().write_message(RebuildStaticVoxels);
        }
        app.update();
        frames += 1;
        if let Some((t, v)) = bevy_hao_tools::harness::diagnostic_measurement(&app, span)
            && last != Some(t)
        {
            last = Some(t);
            times.push(v);
        }
    }
    let adapter = app.world().resource::<bevy::render::renderer::RenderAdapterInfo>().name.clone();
    Ok((occupancy, counters, bevy_hao_tools::harness::median(times), adapter))
}

/// The volume the GPU voxelizes into: the CPU's fitted grid.
fn gpu_volume(bounds: (Vec3, Vec3), res: u32, settings: &VoxelizeSettings) -> VoxelVolume {
    VoxelVolume {
        bounds: VolumeBounds::World { min: bounds.0, max: bounds.1 },
        resolution: VolumeResolution::Cells(res),
        gamma: settings.gamma,
        target_bias: None,
        injection: match settings.mode {
            InjectionMode::Centroid => VoxelInjection::Centroid,
            InjectionMode::Conservative => VoxelInjection::Conservative,
        },
        subdivision: settings.pattern.into(),
        point_budget: u32::MAX,
        point_counts: false,
        attributes: false,
        // The whole model at once: the grid is compared with the CPU's on the first frames.
        stream_budget: u32::MAX,
    }
}

/// The GPU side of `--animation`: Bevy loads the file as a scene, plays the clip sought to the time and
/// paused, and the plugin voxelizes it (a camera looks at it: Bevy uploads joint matrices only for skins a
/// view sees). The grid is read once the pose has held for a few frames.
fn gpu_voxelize_posed(
    path: &std::path::Path,
    clip: usize,
    time: f32,
    bounds: (Vec3, Vec3),
    res: u32,
    settings: &VoxelizeSettings,
    runs: usize,
) -> Result<(VoxelOccupancy, VoxelizeCounters, Option<f64>, String), String> {
    // Bevy resolves a relative asset root against the executable's folder: give it an absolute one.
    let path = std::fs::canonicalize(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let file = path.file_name().ok_or("no file name")?.to_string_lossy().into_owned();
    let dir = path.parent().ok_or("no folder")?.to_string_lossy().into_owned();
    bevy_hao_tools::harness::set_asset_root(Some(dir));
    // The scene the CPU side reads: the file's default, else the first.
    let scene = bevy_hao_tools::meshes::gltf_file::gltf_scene_index(&path)?.unwrap_or(0);
    let volume = gpu_volume(bounds, res, settings);
    let center = (bounds.0 + bounds.1) * 0.5;
    let extent = (bounds.1 - bounds.0).max_element().max(1e-3);
    let mut app = bevy_hao_tools::harness::headless_app(move |app| {
        app.add_systems(Update, start_posed_clip.run_if(resource_exists::<PosedClip>));
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  asset_server: Res<AssetServer>,
                  mut graphs: ResMut<Assets<AnimationGraph>>,
                  mut images: ResMut<Assets<Image>>| {
                let (graph, node) = AnimationGraph::from_clip(
                    asset_server.load(GltfAssetLabel::Animation(clip).from_asset(file.clone())),
                );
                commands.insert_resource(PosedClip { graph: graphs.add(graph), node, time });
                commands.spawn(volume);
                commands
                    .spawn(WorldAssetRoot(asset_server.load(GltfAssetLabel::Scene(scene).from_asset(file.clone()))));
                commands.spawn((
                    Camera3d::default(),
                    bevy::camera::RenderTarget::Image(
                        bevy_hao_tools::harness::target_image(&mut images, UVec2::new(64, 64)).into(),
                    ),
                    Msaa::Off,
                    Transform::from_translation(center + Vec3::new(0.0, 0.0, 2.5 * extent)).looking_at(center, Vec3::Y),
                ));
            },
        );
    });
    // The pose has held once something was voxelized and the static grid (rigid nodes the clip moves are
    // static occluders) has not been rebuilt for 6 frames.
    let (mut held, mut rebuilds) = (0, 0);
    for _ in 0..600 {
        app.update();
        let s = bevy_hao_tools::harness::stats(&app);
        let voxelized = (s.dynamic_instances > 0 || s.static_instances > 0) && s.counter_readbacks > 0;
        held = if voxelized && s.static_rebuilds == rebuilds { held + 1 } else { 0 };
        rebuilds = s.static_rebuilds;
        if held >= 6 {
            break;
        }
    }
    bevy_hao_tools::harness::set_asset_root(None);
    if held < 6 {
        return Err("the posed scene was not voxelized within 600 frames".into());
    }
    let errors = bevy_hao_tools::harness::take_render_errors();
    if !errors.is_empty() {
        return Err(format!("wgpu errors: {errors:?}"));
    }
    let occupancy = bevy_hao_tools::harness::read_occupancy(&mut app);
    // Skinned or morphed meshes make it a dynamic pass every frame; a clip of rigid nodes only, a static one
    // (timed over forced rebuilds, as for a plain mesh).
    let stats = bevy_hao_tools::harness::stats(&app);
    let dynamic = stats.dynamic_instances > 0;
    let (counters, span) = if dynamic {
        (stats.dynamic_counters, "render/hao/voxelize_dynamic/elapsed_gpu")
    } else {
        (stats.static_counters, "render/hao/voxelize_static/elapsed_gpu")
    };
    let before = bevy_hao_tools::harness::diagnostic_history(&app, span).len();
    for _ in 0..runs {
        if !dynamic {
            app.world_mut().write_message(RebuildStaticVoxels);
        }
        app.update();
    }
    bevy_hao_tools::harness::run(&mut app, 4);
    let history = bevy_hao_tools::harness::diagnostic_history(&app, span);
    let times: Vec<f64> = history.iter().skip(before).copied().collect();
    let adapter = app.world().resource::<bevy::render::renderer::RenderAdapterInfo>().name.clone();
    Ok((occupancy, counters, bevy_hao_tools::harness::median(times), adapter))
}

/// `--list-animations`: each file's clips.
fn list_animations(inputs: &[String]) -> Result<(), String> {
    println!("| file | index | name | duration s | channels |");
    println!("|---|---:|---|---:|---:|");
    for input in inputs {
        for a in bevy_hao_tools::meshes::gltf_file::gltf_animations(std::path::Path::new(input))? {
            println!("| {input} | {} | {} | {:.3} | {} |", a.index, a.name.unwrap_or_default(), a.duration, a.channels);
        }
    }
    Ok(())
}

fn main() {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    if args.list_animations {
        if let Err(e) = list_animations(&args.inputs) {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
        return;
    }
    let several_outputs = args.inputs.len() * args.resolutions.len() > 1;
    // A progress bar over the mesh/resolution runs when there are several (drawn only on a terminal);
    // messages are printed above it.
    let bar = if several_outputs {
        bevy_hao_tools::harness::progress_bar((args.inputs.len() * args.resolutions.len()) as u64, "voxelize")
    } else {
        indicatif::ProgressBar::hidden()
    };
    macro_rules! note {
        ($($arg:tt)*) => { bar.suspend(|| eprintln!($($arg)*)) };
    }
    // Columns of the options that add them: --solid, --attributes.
    let mut extra_header = String::new();
    let mut extra_rule = String::new();
    if args.solid {
        extra_header += " inside voxels | open edges |";
        extra_rule += "---:|---:|";
    }
    if args.attributes {
        extra_header += " voxels with attributes | mean albedo | normal agreement |";
        extra_rule += "---:|---|---:|";
    }
    println!(
        "| mesh | res | grid | triangles | gamma | mode | pattern | points injected | estimated points | voxels set \
         | points per voxel | ground-truth voxels | bias % | grazed share of bias % | excess voxels | watertight \
         | voxelize ms (median) | ground truth ms (median) |{extra_header}"
    );
    println!("|---|---:|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|{extra_rule}");
    let mut sweeps = Vec::new();
    let (mut failures, mut voxelized) = (0usize, false);
    for input in &args.inputs {
        // Posed by a clip (glTF only), or as the file has it.
        let (loaded, clip) = match &args.animation {
            Some(anim) => {
                let path = std::path::Path::new(input);
                match bevy_hao_tools::meshes::gltf_file::load_gltf_posed(path, anim, args.time) {
                    Ok((mesh, clip, warnings)) => {
                        let stem = path.file_stem().map_or_else(|| input.clone(), |s| s.to_string_lossy().into_owned());
                        let name = format!("{stem} (clip {clip} at {}s)", args.time);
                        (bevy_hao_tools::meshes::LoadedMesh { name, mesh, warnings, albedo: None }, Some(clip))
                    }
                    Err(e) => {
                        note!("error: {e}");
                        std::process::exit(1);
                    }
                }
            }
            None => match load_mesh(input) {
                Ok(l) => (l, None),
                Err(e) => {
                    note!("error: {e}");
                    std::process::exit(1);
                }
            },
        };
        for w in &loaded.warnings {
            note!("warning: {}: {w}", loaded.name);
        }
        // PN triangles need a normal per vertex: the welded mesh's, smooth (and its vertices are not the
        // file's: its points sample white).
        let vertex_albedo = if args.pn { None } else { loaded.albedo.clone() };
        let mesh = if args.pn { bevy_hao_tools::meshes::builtin::weld(loaded.mesh) } else { loaded.mesh };
        let albedo = MeshAlbedo { base: 0x00ff_ffff, vertex_colors: vertex_albedo.as_deref() };
        let mut open_edges = 0;
        let pn_normals = args.pn.then(|| smooth_vertex_normals(&mesh));
        if args.solid {
            let open = open_edge_count(&mesh);
            open_edges = open;
            if open > 0 {
                note!(
                    "warning: {}: not closed ({open} edges lack their twin); --solid leaves columns with an odd number of crossings hollow",
                    loaded.name
                );
            }
        }
        let stats = mesh.stats();
        let Some((mut lo, mut hi)) = stats.bounds else {
            note!("warning: {}: no triangles with finite vertices; skipped", loaded.name);
            bar.inc(args.resolutions.len() as u64);
            continue;
        };
        // PN patches bulge out of the flat mesh: the grid holds their control points (which hold them).
        if let Some(normals) = &pn_normals {
            for (t, tri) in mesh.triangles.iter().enumerate() {
                if let Some(v) = mesh.triangle(t) {
                    let n = tri.map(|i| normals[i as usize]);
                    if n.iter().all(|n| n.length_squared() > 0.5) {
                        let (plo, phi) = PnPatch::new(v, n).bounds();
                        if plo.is_finite() && phi.is_finite() {
                            (lo, hi) = (lo.min(plo), hi.max(phi));
                        }
                    }
                }
            }
        }
        for &res in &args.resolutions {
            let _tick = Tick(&bar);
            let grid = match VoxelGrid::fit_to_bounds(lo, hi, res) {
                Ok(g) => g,
                Err(e) => {
                    note!("warning: {} at {res}: {e}; skipped", loaded.name);
                    continue;
                }
            };
            let to_grid = grid.grid_from_world();
            // Refuse before allocating: the grids this run keeps (ground truth, its cuts, a check, the result
            // with point counts, the watertight test's flood fill) take about 8 bytes a voxel; attribute sums
            // 24 more in the result and as many in the GPU twin's check.
            let per_voxel = if args.attributes { 8 + 24 * (1 + args.gpu as u64) } else { 8 };
            let need_mb = grid.voxel_count().saturating_mul(per_voxel) / (1 << 20);
            if need_mb > args.max_memory_mb {
                note!(
                    "error: {} at {res}: a {}x{}x{} grid needs about {need_mb} MB, over --max-memory-mb {}; skipped",
                    loaded.name,
                    grid.dims.x,
                    grid.dims.y,
                    grid.dims.z,
                    args.max_memory_mb
                );
                failures += 1;
                continue;
            }
            // The point budget, as the plugin has one: every triangle's subdivision (equation 1 and the
            // pattern), counted before any is voxelized.
            let mut points = 0u64;
            for t in 0..mesh.triangle_count() {
                if let Some(v) = mesh.triangle(t) {
                    let v = v.map(|p| to_grid.transform_point3(p));
                    // The largest gamma this run may use: a sweep goes to 8, equation 3's fit up to 16.
                    let most = if args.target_bias.is_some() {
                        16.0
                    } else if args.gamma_sweep {
                        args.gamma.max(8.0)
                    } else {
                        args.gamma
                    };
                    let gamma =
                        VoxelizeSettings { gamma: most, mode: args.mode, ..Default::default() }.effective_gamma();
                    // A PN patch raises gamma by up to MAX_PN_GAMMA_SCALE.
                    let gamma = if args.pn { gamma * bevy_hao::cpu::pn::MAX_PN_GAMMA_SCALE } else { gamma };
                    let most_points = args.patterns.iter().map(|&p| subdivision(v, gamma, p).sub_triangle_count());
                    points = points.saturating_add(most_points.max().unwrap_or(0));
                }
            }
            if points > args.point_budget {
                note!(
                    "error: {} at {res}: voxelizing needs up to {points} sub-triangles, over --point-budget {}; skipped",
                    loaded.name,
                    args.point_budget
                );
                failures += 1;
                continue;
            }
            note!(
                "{} at {res}: {} triangles, grid {}x{}x{}",
                loaded.name,
                stats.triangles,
                grid.dims.x,
                grid.dims.y,
                grid.dims.z
            );
            // Ground truth (and which of its cells the surface only grazes).
            let mut truth = VoxelOccupancy::new(grid, false);
            let (t_truth, _) = median_ms(args.runs.min(3), &mut truth, |out| ground_truth_mesh(&mesh, to_grid, out));
            let cut = VoxelOccupancy::new(grid, false);
            let check = VoxelOccupancy::new(grid, false);
            ground_truth_mesh_with_cuts(&mesh, to_grid, &check, Some(&cut));
            let region = InjectionRegion::whole(grid.dims);
            let fresh = || {
                if args.attributes { VoxelOccupancy::with_attributes(grid) } else { VoxelOccupancy::new(grid, true) }
            };
            for &pattern in &args.patterns {
                let mut result = fresh();
                let run = |gamma: f32, runs: usize, result: &mut VoxelOccupancy| {
                    let settings = VoxelizeSettings { gamma, mode: args.mode, pattern };
                    median_ms(runs, result, |out| match &pn_normals {
                        Some(normals) => voxelize_sampled_mesh_pn_in_region(
                            &mesh, normals, &albedo, to_grid, &settings, &region, out,
                        ),
                        None => voxelize_sampled_mesh_in_region(&mesh, &albedo, to_grid, &settings, &region, out),
                    })
                };
                let mut gamma = args.gamma;
                if let Some(target) = args.target_bias {
                    let samples: Vec<(f32, f64)> = [1.0f32, 1.5, 2.0, 3.0, 4.0]
                        .iter()
                        .map(|&g| {
                            run(g, 1, &mut result);
                            (g, compare(&result, &truth).bias())
                        })
                        .collect();
                    match BiasModel::fit(&samples) {
                        Some(model) => {
                            gamma = model.gamma_for_bias(target, 16.0);
                            note!(
                                "  equation 3 fitted: p1 = {:.3}%, A = {:.2}, B = {:.3}; gamma for {:.3}% = {gamma:.3}",
                                model.p1 * 100.0,
                                model.a,
                                model.b,
                                target * 100.0
                            );
                        }
                        None => {
                            gamma = 1.0;
                            note!(
                                "  equation 3 cannot be fitted (bias at gamma 1 is {:.3}% and does not fall); gamma = 1",
                                samples[0].1 * 100.0
                            );
                        }
                    }
                }
                let (t_vox, injected) = if args.gpu {
                    let settings = VoxelizeSettings { gamma, mode: args.mode, pattern };
                    let source = match clip {
                        Some(clip) => GpuSource::Posed { path: std::path::Path::new(input), clip, time: args.time },
                        None => GpuSource::Mesh(&mesh),
                    };
                    let colors = args.attributes.then_some(albedo.vertex_colors.unwrap_or(&[]));
                    match gpu_voxelize(source, (lo, hi), res, &settings, args.runs, colors) {
                        Ok((occ, counters, t, adapter)) => {
                            if occ.grid() != &grid {
                                note!("error: the GPU grid {:?} differs from the CPU's {:?}", occ.grid(), grid);
                                std::process::exit(1);
                            }
                            // The CPU twin on the same mesh and grid: how many voxels the two disagree on.
                            let twin = fresh();
                            voxelize_sampled_mesh_in_region(&mesh, &albedo, to_grid, &settings, &region, &twin);
                            let (only_gpu, only_cpu) = (occ.count_not_in(&twin), twin.count_not_in(&occ));
                            note!(
                                "  GPU vs CPU twin: {only_gpu} voxels only on the GPU, {only_cpu} only on the CPU, of {} ({:.3} per 1000)",
                                twin.set_voxel_count(),
                                1000.0 * (only_gpu + only_cpu) as f64 / twin.set_voxel_count().max(1) as f64
                            );
                            if args.attributes {
                                let (same, differ, equal, worst) = compare_records(&occ, &twin);
                                note!(
                                    "  GPU vs CPU twin attributes: {same} voxels with the same point count ({differ} with another), {equal} of \
                                     them with equal sums; largest difference {worst} units (a point's rounding is 1)",
                                );
                            }
                            note!(
                                "  GPU ({adapter}): {} triangles read, {} injected at once, {} queued for expansion, {} invalid, {} degenerate, {} oversize",
                                counters.triangles,
                                counters.small,
                                counters.big_triangles,
                                counters.invalid,
                                counters.degenerate,
                                counters.oversize
                            );
                            result = occ;
                            (t.unwrap_or(f64::NAN), counters.injected as u64)
                        }
                        Err(e) => {
                            note!("error: {} at {res} on the GPU: {e}", loaded.name);
                            std::process::exit(1);
                        }
                    }
                } else {
                    let (t, vstats) = run(gamma, args.runs, &mut result);
                    if vstats.invalid + vstats.degenerate + vstats.oversize > 0 {
                        note!(
                            "  skipped triangles: {} invalid, {} degenerate, {} oversize",
                            vstats.invalid,
                            vstats.degenerate,
                            vstats.oversize
                        );
                    }
                    (t, vstats.injected)
                };
                let mut extra = String::new();
                if args.solid {
                    let f = fill_solid(&mesh, to_grid, &result);
                    note!(
                        "  solid: {} voxels filled inside ({} crossings; {} columns with an odd number left hollow)",
                        f.filled,
                        f.crossings,
                        f.odd_columns
                    );
                    extra += &format!(" {} | {open_edges} |", f.filled);
                }
                if args.attributes {
                    let (n, albedo_sum, agreement) = attribute_summary(&result);
                    let mean = albedo_sum / n.max(1) as f32;
                    extra += &format!(
                        " {n} | {:.3} {:.3} {:.3} | {:.3} |",
                        mean.x,
                        mean.y,
                        mean.z,
                        agreement / n.max(1) as f32
                    );
                }
                let cmp = compare(&result, &truth);
                voxelized |= cmp.result_voxels > 0;
                let split = graze_split(&result, &truth, &cut);
                let wt = watertight(&result, &truth);
                let estimate = expected_point_count(&stats.sizes, grid.cell_size as f64, gamma as f64, pattern);
                let watertight_cell = if !wt.applies() {
                    "n/a".to_string()
                } else if wt.is_watertight() {
                    "yes".to_string()
                } else {
                    format!("no ({} of {} rays leak)", wt.leaks, wt.rays)
                };
                println!(
                    "| {} | {res} | {}x{}x{} | {} | {:.2} | {} | {pattern} | {} | {:.0} | {} | {:.2} | {} | {:.3} | {:.3} | {} | {} | {:.1} | {:.1} |{extra}",
                    loaded.name,
                    grid.dims.x,
                    grid.dims.y,
                    grid.dims.z,
                    stats.triangles,
                    gamma,
                    if args.gpu {
                        format!("{} (gpu)", args.mode)
                    } else if args.pn {
                        format!("{} (pn)", args.mode)
                    } else {
                        args.mode.to_string()
                    },
                    injected,
                    estimate,
                    cmp.result_voxels,
                    injected as f64 / cmp.result_voxels.max(1) as f64,
                    cmp.truth_voxels,
                    100.0 * cmp.bias(),
                    if cmp.truth_voxels == 0 {
                        0.0
                    } else {
                        100.0 * split.missing_grazed as f64 / cmp.truth_voxels as f64
                    },
                    cmp.excess,
                    watertight_cell,
                    t_vox,
                    t_truth
                );
                if let Some(out) = &args.export {
                    let path = if several_outputs {
                        let stem = out.strip_suffix(".binvox").unwrap_or(out);
                        format!("{stem}-{}-{res}.binvox", loaded.name)
                    } else {
                        out.clone()
                    };
                    let written = std::fs::File::create(&path)
                        .and_then(|f| write_binvox(&result, &mut std::io::BufWriter::new(f)));
                    match written {
                        Ok(()) => note!("  wrote {path}"),
                        Err(e) => {
                            note!("error: writing {path}: {e}");
                            std::process::exit(1);
                        }
                    }
                    if args.attributes {
                        let ply = format!("{}.ply", path.strip_suffix(".binvox").unwrap_or(&path));
                        let written = std::fs::File::create(&ply)
                            .and_then(|f| write_attribute_ply(&result, &mut std::io::BufWriter::new(f)));
                        match written {
                            Ok(n) => note!("  wrote {ply} ({n} voxels with attributes)"),
                            Err(e) => {
                                note!("error: writing {ply}: {e}");
                                std::process::exit(1);
                            }
                        }
                    }
                }
                if args.gamma_sweep {
                    let mut rows = Vec::new();
                    for g in [0.5f32, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0] {
                        note!("  sweep gamma {g}");
                        let (t, s) = run(g, args.runs.min(3), &mut result);
                        rows.push((
                            g,
                            compare(&result, &truth).bias(),
                            graze_split(&result, &truth, &cut).missing_grazed,
                            s.injected,
                            t,
                        ));
                    }
                    sweeps.push((loaded.name.clone(), res, pattern, cmp.truth_voxels, rows));
                }
            }
        }
    }
    bar.finish_and_clear();
    for (name, res, pattern, truth_voxels, rows) in sweeps {
        println!(
            "\nGamma sweep, {name} at {res} ({} mode, {pattern} pattern): bias and time against gamma (Figure 5d)\n",
            args.mode
        );
        println!("| gamma | bias % | grazed share % | points injected | voxelize ms (median) |");
        println!("|---:|---:|---:|---:|---:|");
        for (g, bias, grazed, points, t) in rows {
            println!(
                "| {g} | {:.3} | {:.3} | {points} | {t:.1} |",
                100.0 * bias,
                if truth_voxels == 0 { 0.0 } else { 100.0 * grazed as f64 / truth_voxels as f64 }
            );
        }
    }
    if !voxelized {
        note!("error: nothing was voxelized");
        std::process::exit(1);
    }
    if failures > 0 {
        note!("error: {failures} mesh/resolution run(s) were refused (see above)");
        std::process::exit(1);
    }
}

/// Voxels with attributes, the sum of their average albedos and the sum of their average normals' lengths.
fn attribute_summary(occ: &VoxelOccupancy) -> (u64, Vec3, f32) {
    let (mut n, mut albedo, mut agreement) = (0u64, Vec3::ZERO, 0.0f32);
    occ.for_each_set_index(|i| {
        if let Some(a) = occ.attributes(occ.grid().cell_of_index(i)) {
            n += 1;
            albedo += a.albedo;
            agreement += a.normal.length();
        }
    });
    (n, albedo, agreement)
}

/// Of the voxels either grid has points in: how many have the same point count, how many another, how many
/// of the first the same sums, and the largest difference of a sum among them.
fn compare_records(a: &VoxelOccupancy, b: &VoxelOccupancy) -> (u64, u64, u64, i64) {
    let (mut same, mut differ, mut equal, mut worst) = (0u64, 0u64, 0u64, 0i64);
    for i in 0..a.grid().voxel_count() as u32 {
        let (x, y) = (a.record(i), b.record(i));
        if x[0] == 0 && y[0] == 0 {
            continue;
        }
        if x[0] != y[0] {
            differ += 1;
            continue;
        }
        same += 1;
        equal += (x == y) as u64;
        worst = worst.max((1..7).map(|k| (x[k] as i32 as i64 - y[k] as i32 as i64).abs()).max().unwrap_or(0));
    }
    (same, differ, equal, worst)
}

/// Advances the progress bar when a mesh/resolution run ends, however it ends.
struct Tick<'a>(&'a indicatif::ProgressBar);

impl Drop for Tick<'_> {
    fn drop(&mut self) {
        self.0.inc(1);
    }
}
