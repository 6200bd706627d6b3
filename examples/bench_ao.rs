//! GPU cost of the hybrid ambient occlusion passes beside Bevy's SSAO pass, at the same resolution, in the
//! same frames.
//!
//! ```text
//! cargo run --release --example bench_ao -- [builtin:cathedral | PATH.obj | PATH.gltf | PATH.glb]
//!     [--size 1280x720] [--frames 20] [--res 128]
//! ```
//!
//! One headless camera renders the scene with `HybridAmbientOcclusion` and its near field on, so that
//! Bevy's SSAO runs at its default quality (High) in the same frames. For each HAO quality preset the tool
//! records the GPU time spans `hao/trace`, `hao/denoise`, `hao/apply` and Bevy's `ssao` over `--frames`
//! frames and prints their medians and the ratio of HAO's total to SSAO. On a software rasterizer such as
//! lavapipe the times are CPU times of the emulated GPU: compare ratios within one run, not absolute figures.

mod support;

use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy_hao::prelude::*;
use support::scene::{SceneSource, default_camera, spawn_scene};

#[derive(Component)]
struct BenchCamera;

fn main() {
    let mut scene = "builtin:cathedral".to_string();
    let (mut size, mut frames, mut res) = (UVec2::new(1280, 720), 20usize, 128u32);
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--size" => {
                size = support::args::size(&it.next().unwrap_or_default()).unwrap_or_else(|e| {
                    eprintln!("{e}");
                    std::process::exit(2)
                })
            }
            "--frames" => frames = it.next().and_then(|v| v.parse().ok()).expect("--frames N"),
            "--res" => res = it.next().and_then(|v| v.parse().ok()).expect("--res N"),
            s if s.starts_with("--") => {
                eprintln!("usage: bench_ao [SCENE] [--size 1280x720] [--frames 20] [--res 128]");
                std::process::exit(2);
            }
            s => scene = s.to_string(),
        }
    }
    let source = SceneSource::parse(&scene).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let bounds = source.triangles().ok().and_then(|t| t.bounds()).expect("a scene with triangles");
    support::set_asset_root(source.asset_root());
    let camera = default_camera(bounds, true);
    let setup_source = source.clone();
    let mut app = support::headless_app(move |app| {
        let source = setup_source.clone();
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>,
                  server: Res<AssetServer>| {
                spawn_scene(&source, &mut commands, &mut meshes, &mut materials, &server).expect("scene");
                commands.spawn(VoxelVolume { resolution: VolumeResolution::Cells(res), ..default() });
                let target = support::target_image(&mut images, size);
                commands.spawn((
                    Camera3d::default(),
                    RenderTarget::Image(target.into()),
                    Msaa::Off,
                    Tonemapping::None,
                    camera,
                    HybridAmbientOcclusion {
                        near_field: true,
                        near_field_quality: bevy::pbr::ScreenSpaceAmbientOcclusionQualityLevel::High,
                        ..default()
                    },
                    BenchCamera,
                ));
            },
        );
    });
    let mut warm = 0;
    while support::stats(&app).static_rebuilds == 0 && warm < 300 {
        app.update();
        warm += 1;
    }
    let adapter = app.world().resource::<bevy::render::renderer::RenderAdapterInfo>().name.clone();
    let spans = ["hao/trace", "hao/denoise", "hao/apply", "ssao"];
    let mut rows = Vec::new();
    for quality in [HaoQuality::Low, HaoQuality::Medium, HaoQuality::High, HaoQuality::Ultra] {
        let cam = app.world_mut().query_filtered::<Entity, With<BenchCamera>>().single(app.world()).unwrap();
        app.world_mut().get_mut::<HybridAmbientOcclusion>(cam).unwrap().quality = quality;
        support::run(&mut app, 4);
        let mut samples = vec![Vec::new(); spans.len()];
        for _ in 0..frames {
            app.update();
            for (s, span) in samples.iter_mut().zip(spans) {
                if let Some(v) = support::diagnostic(&app, &format!("render/{span}/elapsed_gpu")) {
                    s.push(v);
                }
            }
        }
        let m: Vec<Option<f64>> = samples.into_iter().map(support::median).collect();
        rows.push((quality, m));
    }
    let errors = support::take_render_errors();
    if !errors.is_empty() {
        eprintln!("error: wgpu errors: {errors:?}");
        std::process::exit(1);
    }
    let grid = support::grid_assets(&app).map(|g| g.grid.dims).unwrap_or_default();
    println!(
        "GPU: {adapter}; {scene} at {}x{}, voxel grid {}x{}x{}; medians of {frames} frames\n",
        size.x, size.y, grid.x, grid.y, grid.z
    );
    println!(
        "| HAO quality | rays x steps | trace ms | denoise ms | apply ms | HAO total ms | Bevy SSAO (High) ms | HAO / SSAO |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    for (quality, m) in rows {
        let (rays, steps, half) = quality.parameters();
        let total = match (m[0], m[1], m[2]) {
            (Some(a), Some(b), Some(c)) => Some(a + b + c),
            _ => None,
        };
        let ratio = match (total, m[3]) {
            (Some(t), Some(s)) if s > 0.0 => format!("{:.2}", t / s),
            _ => "-".into(),
        };
        println!(
            "| {quality:?} | {rays} x {steps}{} | {} | {} | {} | {} | {} | {ratio} |",
            if half { ", half res" } else { "" },
            f(m[0]),
            f(m[1]),
            f(m[2]),
            f(total),
            f(m[3])
        );
    }
}
