//! GPU cost of voxelization, beside the cost of drawing the same scene's depth once.
//!
//! ```text
//! cargo run --release --example bench_voxelize -- <PATH or builtin:NAME>... [--res 128,256,512]
//!     [--frames 30] [--size 1280x720] [--mode centroid|conservative]
//! ```
//!
//! For each mesh and resolution, a headless app (Mesa's lavapipe on a machine without a GPU) shows the mesh
//! to a camera with a depth prepass, in a voxel volume fitted to it, and records GPU time spans for
//! `--frames` frames after a warm-up, in two phases of one run:
//!
//! 1. the mesh is a `StaticOccluder` and the static grid is rebuilt every frame (`RebuildStaticVoxels`):
//!    the cost of voxelizing the whole scene (`hao/voxelize_static`) and of resolving the full grid into the
//!    voxel texture (`hao/resolve`);
//! 2. the mesh is a `DynamicOccluder`: the per-frame cost of a moving scene (`hao/voxelize_dynamic`, which
//!    includes copying the static grid) and of resolving the region it covers.
//!
//! Each is printed as a median beside the median of Bevy's depth prepass (`early prepass`) measured in the
//! same frames, and as a ratio to it. Times on a software rasterizer such as lavapipe are not GPU times:
//! quote them only as ratios of one run, and absolute figures only from a real GPU.

mod support;

use bevy::camera::RenderTarget;
use bevy::core_pipeline::prepass::DepthPrepass;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use bevy_hao::cpu::TriangleMesh;
use bevy_hao::meshes::load_mesh;
use bevy_hao::prelude::*;
use bevy_hao::voxel::RebuildStaticVoxels;

const USAGE: &str = "usage: bench_voxelize <PATH or builtin:NAME>... [--res 128,256,512] [--frames 30] [--size 1280x720] \
[--mode centroid|conservative]";

struct Args {
    inputs: Vec<String>,
    resolutions: Vec<u32>,
    frames: usize,
    size: UVec2,
    injection: VoxelInjection,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        inputs: Vec::new(),
        resolutions: vec![128, 256],
        frames: 30,
        size: UVec2::new(1280, 720),
        injection: VoxelInjection::Centroid,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match arg.as_str() {
            "--res" => a.resolutions = support::args::resolutions(&value("--res")?)?,
            "--frames" => {
                a.frames = value("--frames")?.parse::<usize>().map_err(|e| format!("bad --frames: {e}"))?.max(1)
            }
            "--size" => a.size = support::args::size(&value("--size")?)?,
            "--mode" => {
                a.injection = match value("--mode")?.as_str() {
                    "centroid" => VoxelInjection::Centroid,
                    "conservative" => VoxelInjection::Conservative,
                    m => return Err(format!("unknown mode {m}")),
                }
            }
            "-h" | "--help" => return Err(USAGE.into()),
            s if s.starts_with("--") => return Err(format!("unknown option {s}\n{USAGE}")),
            s => a.inputs.push(s.to_string()),
        }
    }
    if a.inputs.is_empty() {
        return Err(USAGE.into());
    }
    Ok(a)
}

#[derive(Component)]
struct Subject;

/// Builds the app for one mesh at one resolution.
fn app_for(mesh: &TriangleMesh, res: u32, size: UVec2, injection: VoxelInjection) -> App {
    let (lo, hi) = mesh.bounds().expect("a mesh with triangles");
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    support::headless_app(move |app| {
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>| {
                let mut m = Mesh::new(
                    bevy::mesh::PrimitiveTopology::TriangleList,
                    bevy::asset::RenderAssetUsages::RENDER_WORLD,
                )
                .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions.clone())
                .with_inserted_indices(bevy::mesh::Indices::U32(indices.clone()));
                m.duplicate_vertices();
                m.compute_flat_normals();
                commands.spawn(VoxelVolume {
                    bounds: VolumeBounds::World { min: lo, max: hi },
                    resolution: VolumeResolution::Cells(res),
                    injection,
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
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target.into()),
                    DepthPrepass,
                    Msaa::Off,
                    Tonemapping::None,
                    Transform::from_translation(center + Vec3::new(0.6, 0.4, 1.0).normalize() * radius * 2.2)
                        .looking_at(center, Vec3::Y),
                ));
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
                if let Some(v) = support::diagnostic(app, &format!("render/{span}/elapsed_gpu")) {
                    s.push(v);
                }
            }
        }
    }
    samples.into_iter().map(support::median).collect()
}

fn main() {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let mut adapter = String::new();
    let mut rows = Vec::new();
    for input in &args.inputs {
        let loaded = match load_mesh(input) {
            Ok(l) => l,
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(1);
            }
        };
        for &res in &args.resolutions {
            eprintln!("{} at {res}...", loaded.name);
            let mut app = app_for(&loaded.mesh, res, args.size, args.injection);
            // Warm up until the pipelines are compiled and the grid is built.
            let mut frames = 0;
            while support::stats(&app).static_rebuilds == 0 && frames < 120 {
                app.update();
                frames += 1;
            }
            adapter = app.world().resource::<bevy::render::renderer::RenderAdapterInfo>().name.clone();
            let prepass = "early prepass";
            let a = measure(&mut app, args.frames, true, &["hao/voxelize_static", "hao/resolve", prepass]);
            let counters = support::stats(&app).static_counters;
            let e = app.world_mut().query_filtered::<Entity, With<Subject>>().single(app.world()).unwrap();
            app.world_mut().entity_mut(e).remove::<StaticOccluder>().insert(DynamicOccluder);
            let b = measure(&mut app, args.frames, false, &["hao/voxelize_dynamic", "hao/resolve", prepass]);
            let errors = support::take_render_errors();
            if !errors.is_empty() {
                eprintln!("error: wgpu errors: {errors:?}");
                std::process::exit(1);
            }
            let grid = support::grid_assets(&app).map(|g| g.grid.dims).unwrap_or_default();
            let name = &loaded.name;
            let tris = loaded.mesh.triangle_count();
            let points = counters.sub_triangles as u64;
            for (pass, t, p) in [
                ("voxelize_static (whole mesh)", a[0], a[2]),
                ("resolve (full grid)", a[1], a[2]),
                ("voxelize_dynamic (whole mesh, with the copy)", b[0], b[2]),
                ("resolve (dynamic region)", b[1], b[2]),
            ] {
                rows.push(format!(
                    "| {name} | {res} | {}x{}x{} | {tris} | {points} | {pass} | {} | {} | {} |",
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
        }
    }
    println!(
        "GPU: {adapter}; {} frames per phase; depth prepass at {}x{}; {:?} injection\n",
        args.frames, args.size.x, args.size.y, args.injection
    );
    println!(
        "| mesh | res | grid | triangles | points | pass | median GPU ms | depth prepass median GPU ms | ratio to prepass |"
    );
    println!("|---|---:|---|---:|---:|---|---:|---:|---:|");
    for r in rows {
        println!("{r}");
    }
}
