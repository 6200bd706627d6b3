//! The CPU cost of the plugin in a game level, beside Bevy alone in the same run.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin bench_level -- [--statics 1000,10000,100000]
//!     [--movers 0,100,1000] [--frames 30] [--size 64x48] [--stream 10000] [--stream-budget N]
//! ```
//!
//! A level of unmarked static cubes (one mesh, one material, laid on a square grid one unit apart) on a
//! floor, a camera with `HybridAmbientOcclusion::default()` (the default cascades follow it) looking over
//! them at a small off-screen target (so that the GPU's share of the frame stays small), and `--movers`
//! cubes marked `DynamicOccluder` circling above them. For each level size and number of movers, three
//! apps are built in the same process: Bevy alone, Bevy with the depth and normal prepasses on the camera
//! (which HAO, like Bevy's SSAO, needs: their cost is Bevy's, and the plugin's is measured against it), and
//! Bevy with `HaoPlugin`. After a warm-up (with the plugin, until the level has streamed in), their frames are run interleaved (one frame of each in turn) so
//! that the machine's drift falls on all three alike. The table prints the median wall time of
//! `App::update` of each, the plugin's addition over Bevy with prepasses, the plugin's own CPU time per
//! frame in the main world and in the render world (medians of `VoxelizeCpuTime`, each system measured
//! around its body), and the median GPU time of the voxel passes (`hao/voxelize_static`,
//! `hao/voxelize_dynamic`, `hao/resolve`, from Bevy's render diagnostics). `--stream-budget` sets
//! `VoxelVolume::stream_budget` in the streaming table (default: the component's default).
//!
//! With `--stream N`, a last table spawns N more static cubes in one frame (a chunk of a level arriving)
//! into the largest level without movers, and prints the usual frame, the worst of the next 60 frames, and
//! the frames until the plugin's static work is done. On a machine without a GPU, lavapipe renders on the
//! same cores as the CPU work, so the GPU's share inflates the wall times: read the plugin's figures as an
//! upper bound, and quote ratios of one run.

use bevy::camera::RenderTarget;
use bevy::core_pipeline::prepass::{DepthPrepass, NormalPrepass};
use bevy::prelude::*;
use bevy_hao::VoxelizationStats;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::{diagnostic_measurement, headless_app_with, median, target_image};
use clap::Parser;
use std::time::{Duration, Instant};

/// The CPU cost of the plugin in a game level, beside Bevy alone in the same run.
#[derive(Parser)]
#[command(version)]
struct Cli {
    /// Static mesh entities of the level, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1000, 10000, 100000])]
    statics: Vec<usize>,
    /// Moving `DynamicOccluder` cubes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [0, 100, 1000])]
    movers: Vec<usize>,
    /// Frames measured per app, after the warm-up.
    #[arg(long, default_value_t = 30)]
    frames: usize,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "64x48", value_parser = bevy_hao_tools::harness::args::size)]
    size: UVec2,
    /// Static cubes spawned in one frame for the streaming table (0: no streaming table).
    #[arg(long, default_value_t = 10000)]
    stream: usize,
    /// `VoxelVolume::stream_budget` (triangles a frame) of the streaming table; the default volume's when
    /// not given.
    #[arg(long)]
    stream_budget: Option<u32>,
}

#[derive(Component)]
struct Mover(f32);

#[derive(Resource, Clone)]
struct Level {
    statics: usize,
    movers: usize,
    size: UVec2,
    hao: bool,
    /// The depth and normal prepasses HAO requires, on the camera of an app without the plugin.
    prepass: bool,
    /// A volume with this streaming budget (else the default volume).
    stream_budget: Option<u32>,
}

/// Places `n` cubes on a square grid one unit apart, centred on the origin, from index `first`.
fn grid_position(i: usize, side: usize) -> Vec3 {
    let half = side as f32 * 0.5;
    Vec3::new((i % side) as f32 - half, 0.0, (i / side) as f32 - half)
}

fn side_of(n: usize) -> usize {
    (n as f64).sqrt().ceil().max(1.0) as usize
}

fn setup(
    mut commands: Commands,
    level: Res<Level>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
) {
    let cube = meshes.add(Cuboid::new(0.5, 0.5, 0.5));
    let material = materials.add(StandardMaterial::default());
    let side = side_of(level.statics);
    commands.spawn_batch(
        (0..level.statics)
            .map(move |i| {
                (
                    Mesh3d(cube.clone()),
                    MeshMaterial3d(material.clone()),
                    Transform::from_translation(grid_position(i, side)),
                )
            })
            .collect::<Vec<_>>(),
    );
    // The floor the level stands on, wider than the view, so that every level size fills the image and the
    // per-pixel passes cost the same whatever the size.
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(1000.0, 0.5, 1000.0))),
        MeshMaterial3d(materials.add(StandardMaterial::default())),
        Transform::from_xyz(0.0, -0.5, 0.0),
    ));
    let cube = meshes.add(Cuboid::new(0.4, 0.4, 0.4));
    let material = materials.add(StandardMaterial::default());
    for i in 0..level.movers {
        commands.spawn((
            Mesh3d(cube.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_xyz(0.0, 1.0, 0.0),
            DynamicOccluder,
            Mover(i as f32),
        ));
    }
    commands.spawn((DirectionalLight::default(), Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y)));
    let target = target_image(&mut images, level.size);
    let mut camera = commands.spawn((
        Camera3d::default(),
        RenderTarget::Image(target.into()),
        Msaa::Off,
        Transform::from_xyz(0.0, 6.0, 12.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    if level.prepass {
        camera.insert((DepthPrepass, NormalPrepass));
    }
    if level.hao {
        camera.insert(HybridAmbientOcclusion::default());
        if let Some(stream_budget) = level.stream_budget {
            commands.spawn(VoxelVolume { stream_budget, ..default() });
        }
    }
}

/// The movers circle the middle of the level, each on its own radius and phase.
fn move_movers(mut movers: Query<(&Mover, &mut Transform)>, mut frame: Local<u32>) {
    *frame += 1;
    let t = *frame as f32 * 0.05;
    for (m, mut transform) in &mut movers {
        let r = 2.0 + (m.0 * 0.37) % 20.0;
        let a = t + m.0 * 0.61;
        transform.translation = Vec3::new(r * a.cos(), 1.0 + (m.0 % 3.0), r * a.sin());
    }
}

fn app(level: Level) -> App {
    let hao = level.hao;
    let mut app = headless_app_with(hao, |app| {
        app.insert_resource(level).add_systems(Startup, setup).add_systems(Update, move_movers);
    });
    // Bevy's first frames after a level spawns are slow (pipelines, buffers growing): past them, and with
    // the plugin past the frames that stream the level in (`VoxelVolume::stream_budget` a frame).
    for frame in 0.. {
        let streaming = hao && app.world().resource::<VoxelizationStats>().get().static_queue > 0;
        if frame >= WARM_UP && (!streaming || frame >= MAX_WARM_UP) {
            break;
        }
        app.update();
    }
    app
}

/// Frames an app with the plugin runs at most before it is measured, waiting for the level to stream in.
const MAX_WARM_UP: usize = 600;

/// Frames each app runs before it is measured.
const WARM_UP: usize = 30;

/// What one app measured: median frame wall time, and with the plugin its CPU and GPU times.
#[derive(Default)]
struct Measured {
    frame: f64,
    main: f64,
    render: f64,
    gpu: f64,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Measures the apps of `levels` side by side: each warmed up, then their frames interleaved (one frame of
/// each in turn), so that a drift of the machine's speed falls on all of them alike.
fn measure(levels: Vec<Level>, frames: usize) -> Vec<Measured> {
    let mut apps: Vec<(bool, App)> = levels.into_iter().map(|l| (l.hao, app(l))).collect();
    let mut samples: Vec<[Vec<f64>; 4]> = apps.iter().map(|_| Default::default()).collect();
    for _ in 0..frames {
        for ((hao, app), [walls, main, render, gpu]) in apps.iter_mut().zip(&mut samples) {
            let t = Instant::now();
            app.update();
            walls.push(ms(t.elapsed()));
            if *hao {
                let cpu = app.world().resource::<VoxelizationStats>().get().cpu_time;
                main.push(ms(cpu.main_world()));
                render.push(ms(cpu.render_world()));
                // GPU spans arrive a few frames late, and only for passes that ran: those measured since.
                gpu.push(
                    ["hao/voxelize_static", "hao/voxelize_dynamic", "hao/resolve"]
                        .iter()
                        .filter_map(|p| diagnostic_measurement(app, &format!("render/{p}/elapsed_gpu")))
                        .filter(|(at, _)| *at >= t)
                        .fold(0.0, |sum, (_, v)| sum + v),
                );
            }
        }
    }
    samples
        .into_iter()
        .map(|[walls, main, render, gpu]| Measured {
            frame: median(walls).unwrap_or(f64::NAN),
            main: median(main).unwrap_or(0.0),
            render: median(render).unwrap_or(0.0),
            gpu: median(gpu).unwrap_or(0.0),
        })
        .collect()
}

fn main() {
    let cli = Cli::parse();
    println!(
        "Level of unmarked static cubes, camera {}x{}; medians of {} frames (ms)\n",
        cli.size.x, cli.size.y, cli.frames
    );
    println!(
        "| static entities | moving occluders | Bevy alone | Bevy, prepasses | Bevy + HaoPlugin | added | added / Bevy, prepasses | plugin CPU, main world | plugin CPU, render world | voxel passes GPU |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for &statics in &cli.statics {
        let mut bevy_still = None;
        for &movers in &cli.movers {
            let level = |hao, prepass| Level { statics, movers, size: cli.size, hao, prepass, stream_budget: None };
            let [alone, prepasses, with]: [Measured; 3] =
                measure(vec![level(false, false), level(false, true), level(true, false)], cli.frames)
                    .try_into()
                    .unwrap_or_else(|_| unreachable!("three apps"));
            let added = with.frame - prepasses.frame;
            println!(
                "| {statics} | {movers} | {:.2} | {:.2} | {:.2} | {added:.2} | {:.1} % | {:.3} | {:.3} | {:.3} |",
                alone.frame,
                prepasses.frame,
                with.frame,
                100.0 * added / prepasses.frame,
                with.main,
                with.render,
                with.gpu
            );
            if movers == 0 {
                bevy_still = Some(alone.frame);
            } else if let Some(still) = bevy_still {
                eprintln!(
                    "  {statics} statics, {movers} movers: Bevy's own cost of moving them {:.2} ms; the plugin's CPU {:.3} ms",
                    alone.frame - still,
                    with.main + with.render
                );
            }
        }
    }
    if cli.stream > 0 {
        let statics = cli.statics.iter().copied().max().unwrap_or(1000);
        println!("\nStreaming: {} static cubes spawned in one frame into a level of {statics} (ms)\n", cli.stream);
        println!(
            "| | usual frame (median) | worst of the next 60 frames | worst / usual | frames until the static work is done |"
        );
        println!("|---|---:|---:|---:|---:|");
        for hao in [false, true] {
            let mut app =
                app(Level { statics, movers: 0, size: cli.size, hao, prepass: !hao, stream_budget: cli.stream_budget });
            let mut usual = Vec::new();
            for _ in 0..cli.frames {
                let t = Instant::now();
                app.update();
                usual.push(ms(t.elapsed()));
            }
            let usual = median(usual).unwrap_or(f64::NAN);
            let (stream, side) = (cli.stream, side_of(cli.stream));
            let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(Cuboid::new(0.5, 0.5, 0.5));
            // The chunk: beside the level, two units up.
            let offset = Vec3::new(side_of(statics) as f32 * 0.5 + side as f32 * 0.5 + 2.0, 2.0, 0.0);
            app.world_mut().spawn_batch(
                (0..stream)
                    .map(|i| (Mesh3d(mesh.clone()), Transform::from_translation(grid_position(i, side) + offset)))
                    .collect::<Vec<_>>(),
            );
            let (mut worst, mut done) = (0.0f64, None);
            for f in 0..60 {
                let t = Instant::now();
                app.update();
                worst = worst.max(ms(t.elapsed()));
                if hao && done.is_none() {
                    let s = app.world().resource::<VoxelizationStats>().get();
                    if s.static_queue == 0 && s.cascades.iter().all(|c| c.static_cells_last_frame == 0) {
                        done = Some(f + 1);
                    }
                }
            }
            println!(
                "| {} | {usual:.2} | {worst:.2} | {:.2} | {} |",
                if hao { "Bevy + HaoPlugin" } else { "Bevy alone" },
                worst / usual,
                done.map_or("-".to_string(), |d| d.to_string())
            );
        }
    }
}
