//! GPU cost of voxelization, beside the cost of drawing the same scene's depth once.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin bench_voxelize -- <PATH or builtin:NAME>... [--res 128,256,512]
//!     [--frames 30] [--size 1280x720] [--mode centroid|conservative] [--pattern strips,uniform] [--cascades]
//! ```
//!
//! For each mesh and resolution, a headless app (Mesa's lavapipe on a machine without a GPU) shows the mesh
//! to a camera with a depth prepass, in a voxel volume fitted to it, and records GPU time spans for
//! `--frames` frames after a warm-up, in three phases of one run:
//!
//! 1. the mesh is a `StaticOccluder` and the static grid is rebuilt every frame (`RebuildStaticVoxels`):
//!    the cost of voxelizing the whole scene (`hao/voxelize_static`) and of resolving the full grid into the
//!    voxel texture (`hao/resolve`);
//! 2. the mesh is a `DynamicOccluder`: the per-frame cost of a moving scene (`hao/voxelize_dynamic`, which
//!    includes copying the static grid) and of resolving the region it covers;
//! 3. the same triangles as a skinned mesh (four joints a vertex, weights 0.25, joints at rest): the
//!    dynamic pass with every vertex skinned (the prepass then skins in its vertex shader too).
//!
//! Each is printed as a median beside the median of Bevy's depth prepass (`early prepass`) measured in the
//! same frames, and as a ratio to it. `--pattern` picks the subdivision pattern (`strips`, the default, or
//! `uniform`); a list measures each in turn, rows side by side.
//!
//! With `--cascades`, each mesh is also put in the plugin's default volume (4 cascades of 192^3 following
//! the camera) with the camera inside it, moving along its longest horizontal axis, in three phases: at
//! walking speed (1.4 units a second at 60 frames a second), at running speed (6 units a second), and
//! teleporting 500 units away and back every 10 frames. For each it prints the mean GPU time per frame of
//! the static updates (`hao/voxelize_static`: the slabs the cascades scroll into) and of the resolve, the
//! worst single frame, and the cells voxelized per frame, beside the depth prepass. Times on a software rasterizer such as lavapipe are not GPU times:
//! quote them only as ratios of one run, and absolute figures only from a real GPU.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::prepass::DepthPrepass;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use bevy_hao::RebuildStaticVoxels;
use bevy_hao::cpu::TriangleMesh;
use bevy_hao::prelude::*;
use bevy_hao_tools::meshes::load_mesh;
use clap::{Parser, ValueEnum};

/// GPU cost of voxelization, beside the cost of drawing the same scene's depth once.
#[derive(Parser)]
#[command(version)]
struct Cli {
    /// Meshes: paths of OBJ, glTF or GLB files, or builtin:NAME.
    #[arg(required = true)]
    inputs: Vec<String>,
    /// Grid resolutions (cells on the longest axis), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [128, 256])]
    res: Vec<u32>,
    /// Frames measured per phase.
    #[arg(long, default_value_t = 30)]
    frames: usize,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = bevy_hao_tools::harness::args::size)]
    size: UVec2,
    /// Injection mode.
    #[arg(long, value_enum, default_value_t = Mode::Centroid)]
    mode: Mode,
    /// Subdivision patterns, comma-separated: each is measured in turn.
    #[arg(long, value_delimiter = ',', default_value = "strips")]
    pattern: Vec<bevy_hao::cpu::SubdivisionPattern>,
    /// Also measure the default cascades with a moving camera (walking, running, teleporting).
    #[arg(long)]
    cascades: bool,
    /// Also measure the static voxelization with `VoxelFill::Solid`, with `PnTriangles` (on the welded
    /// mesh's smooth normals), and with `VoxelVolume::attributes` (multi-valued voxels: albedo and normal
    /// sums, and their resolve into two more textures).
    #[arg(long)]
    fills: bool,
}

#[derive(Clone, Copy, ValueEnum)]
enum Mode {
    Centroid,
    Conservative,
}

struct Args {
    inputs: Vec<String>,
    resolutions: Vec<u32>,
    frames: usize,
    size: UVec2,
    injection: VoxelInjection,
    patterns: Vec<VoxelSubdivision>,
    cascades: bool,
    fills: bool,
}

fn parse_args() -> Args {
    let cli = Cli::parse();
    Args {
        inputs: cli.inputs,
        resolutions: cli.res,
        frames: cli.frames.max(1),
        size: cli.size,
        injection: match cli.mode {
            Mode::Centroid => VoxelInjection::Centroid,
            Mode::Conservative => VoxelInjection::Conservative,
        },
        patterns: cli.pattern.into_iter().map(VoxelSubdivision::from).collect(),
        cascades: cli.cascades,
        fills: cli.fills,
    }
}

#[derive(Component)]
struct Subject;

#[derive(Component)]
struct TheCamera;

/// A camera path: the offset from the start at frame `k`.
type CameraPath = fn(usize) -> Vec3;

/// The cascades' phases: the camera moves along `axis` each frame as `path` says, for `frames` frames.
/// Returns, per span, the mean GPU ms per frame (frames without the pass count as 0) and the worst frame,
/// and the mean cells voxelized per frame.
fn measure_moving(
    app: &mut App,
    frames: usize,
    axis: Vec3,
    path: CameraPath,
    spans: &[&str],
) -> (Vec<(f64, f64)>, f64) {
    let start =
        app.world_mut().query_filtered::<&Transform, With<TheCamera>>().single(app.world()).unwrap().translation;
    let mut last: Vec<Option<std::time::Instant>> = spans
        .iter()
        .map(|s| bevy_hao_tools::harness::diagnostic_measurement(app, &format!("render/{s}/elapsed_gpu")).map(|m| m.0))
        .collect();
    let mut sums = vec![(0.0f64, 0.0f64); spans.len()];
    let mut cells = 0u64;
    // A few frames after the last move, for the timestamps to arrive.
    for k in 0..frames + 4 {
        if k < frames {
            let offset = path(k);
            let mut q = app.world_mut().query_filtered::<&mut Transform, With<TheCamera>>();
            q.single_mut(app.world_mut()).unwrap().translation = start + axis * offset.x + Vec3::Y * offset.y;
        }
        app.update();
        if k < frames {
            cells +=
                bevy_hao_tools::harness::stats(app).cascades.iter().map(|c| c.static_cells_last_frame).sum::<u64>();
        }
        for (i, span) in spans.iter().enumerate() {
            if let Some((t, v)) =
                bevy_hao_tools::harness::diagnostic_measurement(app, &format!("render/{span}/elapsed_gpu"))
                && last[i] != Some(t)
            {
                last[i] = Some(t);
                sums[i].0 += v;
                sums[i].1 = sums[i].1.max(v);
            }
        }
    }
    let mean = sums.into_iter().map(|(s, m)| (s / frames as f64, m)).collect();
    (mean, cells as f64 / frames as f64)
}

/// Builds the app for one mesh at one resolution (`res == 0`: the default cascades, the camera inside).
/// The Bevy mesh the benchmark draws and voxelizes: the triangles with flat normals.
fn bevy_mesh_of(mesh: &TriangleMesh) -> Mesh {
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let mut m = Mesh::new(bevy::mesh::PrimitiveTopology::TriangleList, bevy::asset::RenderAssetUsages::RENDER_WORLD)
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_indices(bevy::mesh::Indices::U32(indices));
    m.duplicate_vertices();
    m.compute_flat_normals();
    m
}

/// Makes the subject a skinned mesh: the same triangles with four joints per vertex (weights 0.25 each) on
/// four joints at rest, so that it stays in place and every vertex pays for a full blend of four matrices,
/// as in the vertex shader.
fn make_subject_skinned(app: &mut App, mesh: &TriangleMesh) {
    use bevy::mesh::VertexAttributeValues;
    use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
    let m = bevy_mesh_of(mesh);
    let n = m.count_vertices();
    let m = m
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(vec![[0, 1, 2, 3]; n]))
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[0.25f32; 4]; n]);
    let world = app.world_mut();
    let handle = world.resource_mut::<Assets<Mesh>>().add(m);
    let inverse_bindposes = world.resource_mut::<Assets<SkinnedMeshInverseBindposes>>().add(vec![Mat4::IDENTITY; 4]);
    let joints: Vec<Entity> = (0..4).map(|_| world.spawn(Transform::default()).id()).collect();
    let e = world.query_filtered::<Entity, With<Subject>>().single(world).unwrap();
    world
        .entity_mut(e)
        .remove::<(StaticOccluder, DynamicOccluder)>()
        .insert((Mesh3d(handle), SkinnedMesh { inverse_bindposes, joints }));
}

fn app_for(
    mesh: &TriangleMesh,
    res: u32,
    size: UVec2,
    injection: VoxelInjection,
    subdivision: VoxelSubdivision,
) -> App {
    let (lo, hi) = mesh.bounds().expect("a mesh with triangles");
    let subject = bevy_mesh_of(mesh);
    bevy_hao_tools::harness::headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                let m = subject.clone();
                let bounds = if res == 0 { VolumeBounds::default() } else { VolumeBounds::World { min: lo, max: hi } };
                commands.spawn(VoxelVolume {
                    bounds,
                    resolution: VolumeResolution::Cells(res.max(1)),
                    injection,
                    subdivision,
                    point_budget: u32::MAX,
                    ..default()
                });
                commands.spawn((
                    Mesh3d(meshes.add(m)),
                    MeshMaterial3d(materials.add(StandardMaterial::default())),
                    StaticOccluder,
                    Subject,
                ));
                let center = (lo + hi) / 2.0;
                let radius = (hi - lo).length() / 2.0;
                let target = images.add(Image::new_target_texture(size.x, size.y, TextureFormat::Rgba8UnormSrgb, None));
                let transform = if res == 0 {
                    bevy_hao_tools::scene::default_camera((lo, hi), true)
                } else {
                    Transform::from_translation(center + Vec3::new(0.6, 0.4, 1.0).normalize() * radius * 2.2)
                        .looking_at(center, Vec3::Y)
                };
                let mut camera = commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target.into()),
                    DepthPrepass,
                    Msaa::Off,
                    Tonemapping::None,
                    transform,
                    TheCamera,
                ));
                if res == 0 {
                    // The cascades follow a camera with HAO.
                    camera.insert(HybridAmbientOcclusion::default());
                }
                commands.spawn((
                    DirectionalLight::default(),
                    Transform::from_xyz(1.0, 2.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
            },
        );
    })
}

/// Runs `frames` frames (after a warm-up) and returns the medians of the named spans (ms).
fn measure(app: &mut App, frames: usize, rebuild: bool, spans: &[&str]) -> Vec<Option<f64>> {
    let mut samples = vec![Vec::new(); spans.len()];
    for k in 0..frames + 5 {
        if rebuild {
            app.world_mut().write_message(RebuildStaticVoxels);
        }
        app.update();
        if k >= 5 {
            for (s, span) in samples.iter_mut().zip(spans) {
                if let Some(v) = bevy_hao_tools::harness::diagnostic(app, &format!("render/{span}/elapsed_gpu")) {
                    s.push(v);
                }
            }
        }
    }
    samples.into_iter().map(bevy_hao_tools::harness::median).collect()
}

fn main() {
    let args = parse_args();
    let mut adapter = String::new();
    let mut rows = Vec::new();
    let mut cascade_rows: Vec<String> = Vec::new();
    let mut memory = String::new();
    let runs = args.resolutions.len() * args.patterns.len() + usize::from(args.cascades);
    let bar = bevy_hao_tools::harness::progress_bar((args.inputs.len() * runs) as u64, "bench_voxelize");
    for input in &args.inputs {
        let loaded = match load_mesh(input) {
            Ok(l) if l.mesh.bounds().is_some() => l,
            Ok(l) => {
                eprintln!("error: {}: no triangles to voxelize", l.name);
                std::process::exit(1);
            }
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(1);
            }
        };
        if args.cascades {
            bar.set_message(format!("{} in the default cascades", loaded.name));
            let mut app = app_for(&loaded.mesh, 0, args.size, args.injection, args.patterns[0]);
            let mut frames = 0;
            while bevy_hao_tools::harness::stats(&app).static_rebuilds == 0 && frames < 120 {
                app.update();
                frames += 1;
            }
            bevy_hao_tools::harness::run(&mut app, 5);
            let (lo, hi) = loaded.mesh.bounds().unwrap();
            let axis = if hi.x - lo.x >= hi.z - lo.z { -Vec3::X } else { -Vec3::Z };
            let prepass = "early prepass";
            let spans = ["hao/voxelize_static", "hao/resolve", prepass];
            let walk: CameraPath = |k| Vec3::X * (1.4 / 60.0) * k as f32;
            let run: CameraPath = |k| Vec3::X * (6.0 / 60.0) * k as f32;
            let teleport: CameraPath = |k| if (k / 10) % 2 == 1 { Vec3::X * 500.0 } else { Vec3::ZERO };
            for (phase, path) in
                [("walking, 1.4/s", walk), ("running, 6/s", run), ("teleport 500 every 10 frames", teleport)]
            {
                let (m, cells) = measure_moving(&mut app, args.frames.max(60), axis, path, &spans);
                let p = m[2].0;
                for (pass, (mean, worst)) in [("voxelize_static (scroll)", m[0]), ("resolve", m[1])] {
                    cascade_rows.push(format!(
                        "| {} | {phase} | {pass} | {cells:.0} | {mean:.3} | {worst:.3} | {p:.3} | {:.2} | {:.2} |",
                        loaded.name,
                        if p > 0.0 { mean / p } else { f64::NAN },
                        if p > 0.0 { worst / p } else { f64::NAN },
                    ));
                }
                // Back to the start, settled.
                measure_moving(&mut app, 8, axis, |_| Vec3::ZERO, &spans);
            }
            let s = bevy_hao_tools::harness::stats(&app);
            let bytes: u64 = s.cascades.iter().map(|c| c.bytes.total()).sum();
            memory = format!(
                "{} cascades of {}^3, {:.1} MB in all (occupancy bits {:.1} MB, texture with mips {:.1} MB, point counts {:.1} MB)",
                s.cascades.len(),
                s.grid.map_or(0, |g| g.dims.x),
                bytes as f64 / 1.0e6,
                s.cascades.iter().map(|c| c.bytes.occupancy).sum::<u64>() as f64 / 1.0e6,
                s.cascades.iter().map(|c| c.bytes.texture).sum::<u64>() as f64 / 1.0e6,
                s.cascades.iter().map(|c| c.bytes.point_counts).sum::<u64>() as f64 / 1.0e6,
            );
            let errors = bevy_hao_tools::harness::take_render_errors();
            if !errors.is_empty() {
                eprintln!("error: wgpu errors: {errors:?}");
                std::process::exit(1);
            }
            bar.inc(1);
        }
        for &res in &args.resolutions {
            for &pattern in &args.patterns {
                bar.set_message(format!("{} at {res}, {pattern:?}", loaded.name));
                let mut app = app_for(&loaded.mesh, res, args.size, args.injection, pattern);
                // Warm up until the pipelines are compiled and the grid is built.
                let mut frames = 0;
                while bevy_hao_tools::harness::stats(&app).static_rebuilds == 0 && frames < 120 {
                    app.update();
                    frames += 1;
                }
                adapter = app.world().resource::<bevy::render::renderer::RenderAdapterInfo>().name.clone();
                let prepass = "early prepass";
                let a = measure(&mut app, args.frames, true, &["hao/voxelize_static", "hao/resolve", prepass]);
                let counters = bevy_hao_tools::harness::stats(&app).static_counters;
                let e = app.world_mut().query_filtered::<Entity, With<Subject>>().single(app.world()).unwrap();
                // The same static mesh filled solid, then as PN triangles.
                let mut fills = Vec::new();
                if args.fills {
                    let spans = ["hao/voxelize_static", "hao/resolve", prepass];
                    app.world_mut().entity_mut(e).insert(VoxelFill::Solid);
                    let s = measure(&mut app, args.frames, true, &spans);
                    let points = bevy_hao_tools::harness::stats(&app).static_counters.sub_triangles as u64;
                    fills.push(("voxelize_static (VoxelFill::Solid)", s[0], s[2], points));
                    app.world_mut().entity_mut(e).remove::<VoxelFill>();
                    let welded = bevy_hao_tools::meshes::builtin::weld(loaded.mesh.clone());
                    let normals = bevy_hao::cpu::smooth_vertex_normals(&welded);
                    let smooth = Mesh::new(
                        bevy::mesh::PrimitiveTopology::TriangleList,
                        bevy::asset::RenderAssetUsages::RENDER_WORLD,
                    )
                    .with_inserted_attribute(
                        Mesh::ATTRIBUTE_POSITION,
                        welded.positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
                    )
                    .with_inserted_attribute(
                        Mesh::ATTRIBUTE_NORMAL,
                        normals.iter().map(|n| n.to_array()).collect::<Vec<_>>(),
                    )
                    .with_inserted_indices(bevy::mesh::Indices::U32(
                        welded.triangles.iter().flatten().copied().collect(),
                    ));
                    let original = app.world().get::<Mesh3d>(e).unwrap().clone();
                    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(smooth);
                    app.world_mut().entity_mut(e).insert((Mesh3d(handle), PnTriangles));
                    let p = measure(&mut app, args.frames, true, &spans);
                    let points = bevy_hao_tools::harness::stats(&app).static_counters.sub_triangles as u64;
                    fills.push(("voxelize_static (PnTriangles, smooth normals)", p[0], p[2], points));
                    app.world_mut().entity_mut(e).remove::<PnTriangles>().insert(original);
                    // Multi-valued voxels: the volume's assets are replaced, then the same rebuilds.
                    let set_attributes = |app: &mut App, on: bool| {
                        let before = bevy_hao_tools::harness::stats(app).static_rebuilds;
                        app.world_mut().query::<&mut VoxelVolume>().single_mut(app.world_mut()).unwrap().attributes =
                            on;
                        let mut frames = 0;
                        while bevy_hao_tools::harness::stats(app).static_rebuilds == before && frames < 60 {
                            app.update();
                            frames += 1;
                        }
                    };
                    set_attributes(&mut app, true);
                    let v = measure(&mut app, args.frames, true, &spans);
                    let points = bevy_hao_tools::harness::stats(&app).static_counters.sub_triangles as u64;
                    fills.push(("voxelize_static (VoxelVolume::attributes)", v[0], v[2], points));
                    fills.push(("resolve (full grid, VoxelVolume::attributes)", v[1], v[2], points));
                    set_attributes(&mut app, false);
                }
                app.world_mut().entity_mut(e).remove::<StaticOccluder>().insert(DynamicOccluder);
                let b = measure(&mut app, args.frames, false, &["hao/voxelize_dynamic", "hao/resolve", prepass]);
                // The same mesh skinned (four joints a vertex), voxelized in its pose every frame.
                make_subject_skinned(&mut app, &loaded.mesh);
                let mut frames = 0;
                while bevy_hao_tools::harness::stats(&app).dynamic_instances == 0 && frames < 60 {
                    app.update();
                    frames += 1;
                }
                let c = measure(&mut app, args.frames, false, &["hao/voxelize_dynamic", "hao/resolve", prepass]);
                let errors = bevy_hao_tools::harness::take_render_errors();
                if !errors.is_empty() {
                    eprintln!("error: wgpu errors: {errors:?}");
                    std::process::exit(1);
                }
                let grid = bevy_hao_tools::harness::grid_assets(&app).map(|g| g.grid.dims).unwrap_or_default();
                let name = &loaded.name;
                let tris = loaded.mesh.triangle_count();
                let points = counters.sub_triangles as u64;
                for (pass, t, p, points) in [
                    ("voxelize_static (whole mesh)", a[0], a[2], points),
                    ("resolve (full grid)", a[1], a[2], points),
                    ("voxelize_dynamic (whole mesh, with the copy)", b[0], b[2], points),
                    ("resolve (dynamic region)", b[1], b[2], points),
                    ("voxelize_dynamic (whole mesh skinned, 4 joints a vertex)", c[0], c[2], points),
                ]
                .into_iter()
                .chain(fills)
                {
                    rows.push(format!(
                        "| {name} | {res} | {}x{}x{} | {tris} | {pattern:?} | {points} | {pass} | {} | {} | {} |",
                        grid.x,
                        grid.y,
                        grid.z,
                        t.map_or("-".into(), |t| format!("{t:.3}")),
                        p.map_or("-".into(), |p| format!("{p:.3}")),
                        match (t, p) {
                            (Some(t), Some(p)) if p > 0.0 => format!("{:.2}", t / p),
                            _ => "-".into(),
                        }
                    ));
                }
                bar.inc(1);
            }
        }
    }
    bar.finish_and_clear();
    println!(
        "GPU: {adapter}; {} frames per phase; depth prepass at {}x{}; {:?} injection\n",
        args.frames, args.size.x, args.size.y, args.injection
    );
    println!(
        "| mesh | res | grid | triangles | pattern | points | pass | median GPU ms | depth prepass median GPU ms | ratio to prepass |"
    );
    println!("|---|---:|---|---:|---|---:|---|---:|---:|---:|");
    for r in rows {
        println!("{r}");
    }
    if !cascade_rows.is_empty() {
        println!("\nThe default cascades, the camera moving ({memory}):\n");
        println!(
            "| mesh | camera | pass | cells voxelized per frame | mean GPU ms per frame | worst frame ms | depth prepass median ms | mean / prepass | worst / prepass |"
        );
        println!("|---|---|---|---:|---:|---:|---:|---:|---:|");
        for r in cascade_rows {
            println!("{r}");
        }
    }
}
