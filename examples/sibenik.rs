//! A cathedral with hybrid ambient occlusion: the built-in procedural cathedral by default (no download),
//! or any OBJ or glTF given by path (the real Sibenik works: `../shared/models/sibenik/sibenik.obj`).
//!
//! ```text
//! cargo run --release --example sibenik -- [builtin:cathedral | PATH.obj | PATH.gltf | PATH.glb]
//!     [--ao hao|ssao|both|off] [--gi] [--view final|ao|voxels|counts|static-dynamic|cascades|albedo|normals|lit]
//!     [--res N]
//!     [--camera X,Y,Z --look X,Y,Z] [--headless --frames 30 --screenshot OUT.png [--size 960x540]]
//! ```
//!
//! In a window: hold the right mouse button and move to look around, WASD to fly (Q/E down and up, Shift
//! faster, the scroll wheel sets the speed); the inspector window edits every setting live and shows the
//! debug views and GPU times. With `--headless` the view is rendered off screen (on Mesa's lavapipe on a
//! machine without a GPU) for `--frames` frames and written to `--screenshot`: the README's pictures come
//! from this. Without `--headless`, `--screenshot` captures the window, inspector included, and exits.
//!
//! The light is a sun through the windows plus an ambient "sky": ambient light is what ambient occlusion
//! dims (direct sunlight is not), so an interior lit mostly by bounce light is where AO matters. `--gi`
//! adds `VoxelGlobalIllumination` to the camera: the sunlight that comes in through the windows bounces
//! off the floor and the walls (the sky's ambient light is then turned down, as the bounce replaces part of
//! it).

use bevy::camera::RenderTarget;
use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::args::View;
use bevy_hao_tools::scene::{SceneSource, default_camera, spawn_scene, sun};
use clap::Parser;

/// A cathedral with hybrid ambient occlusion, in a window with the inspector or rendered headless.
#[derive(Parser)]
struct Cli {
    /// The scene: builtin:cathedral (or another built-in shape), or the path of an OBJ, glTF or GLB file.
    #[arg(default_value = "builtin:cathedral")]
    scene: String,
    /// The ambient occlusion: HAO, Bevy's SSAO, both (HAO with the near field) or none.
    #[arg(long, default_value = "hao", value_parser = ["hao", "ssao", "both", "off"])]
    ao: String,
    /// Diffuse global illumination from the voxels (`VoxelGlobalIllumination` on the camera).
    #[arg(long)]
    gi: bool,
    /// What the view shows.
    #[arg(long, value_enum, default_value_t = View::Final)]
    view: View,
    /// One grid fitted to the scene with this many cells on its longest axis, instead of the cascades.
    #[arg(long)]
    res: Option<u32>,
    /// Camera position X,Y,Z (with --look).
    #[arg(long, value_parser = bevy_hao_tools::harness::args::vec3, requires = "look")]
    camera: Option<Vec3>,
    /// The point the camera looks at, X,Y,Z (with --camera).
    #[arg(long, value_parser = bevy_hao_tools::harness::args::vec3, requires = "camera")]
    look: Option<Vec3>,
    /// Render off screen (needs --screenshot).
    #[arg(long, requires = "screenshot")]
    headless: bool,
    /// Frames before the screenshot (30 headless, 120 in a window).
    #[arg(long)]
    frames: Option<usize>,
    /// Write a screenshot to this PNG and exit.
    #[arg(long)]
    screenshot: Option<String>,
    /// Image size when headless, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x540", value_parser = bevy_hao_tools::harness::args::size)]
    size: UVec2,
}

#[derive(Clone)]
struct Args {
    scene: String,
    ao: String,
    gi: bool,
    view: HaoDebugView,
    res: Option<u32>,
    camera: Option<(Vec3, Vec3)>,
    headless: bool,
    frames: usize,
    screenshot: Option<String>,
    size: UVec2,
}

fn parse_args() -> Args {
    let c = Cli::parse();
    Args {
        frames: c.frames.unwrap_or(if c.headless || c.screenshot.is_none() { 30 } else { 120 }),
        scene: c.scene,
        ao: c.ao,
        gi: c.gi,
        view: c.view.into(),
        res: c.res,
        camera: c.camera.zip(c.look),
        headless: c.headless,
        screenshot: c.screenshot,
        size: c.size,
    }
}

/// The fly camera's state.
#[derive(Component)]
struct FlyCamera {
    yaw: f32,
    pitch: f32,
    speed: f32,
}

/// Spawns the scene, the lights, the voxel volume and the camera (rendering to `target` when headless).
fn setup_scene(app: &mut App, args: &Args, source: SceneSource, camera: Transform, target: Option<UVec2>) {
    let args = args.clone();
    // With voxel GI the sun's bounce lights the interior, and the ambient "sky" is turned down.
    let ambient = if args.gi { 150.0 } else { 700.0 };
    app.insert_resource(GlobalAmbientLight { color: Color::srgb(0.95, 0.93, 0.88), brightness: ambient, ..default() })
        .insert_resource(ClearColor(Color::srgb(0.55, 0.68, 0.85)))
        .add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>,
                  mut images: ResMut<Assets<Image>>,
                  server: Res<AssetServer>| {
                if let Err(e) = spawn_scene(&source, &mut commands, &mut meshes, &mut materials, &server) {
                    error!("{e}");
                    std::process::exit(1);
                }
                // The default volume (cascades that follow the camera), or with --res one grid fitted to the
                // scene. Point counts for the heat map; the albedo and normal views need the voxels'
                // attributes, whose sums (28 bytes a voxel) must fit one storage binding (128 MiB on
                // lavapipe): 3 cascades of 112^3 rather than 4 of 192^3.
                // (Voxel GI turns the attributes on itself.)
                let attributes = args.gi
                    || matches!(args.view, HaoDebugView::Albedo | HaoDebugView::Normals | HaoDebugView::LitVoxels);
                commands.spawn(match args.res {
                    Some(n) => VoxelVolume {
                        bounds: VolumeBounds::FitStaticScene { margin: 0.5 },
                        resolution: VolumeResolution::Cells(n),
                        point_counts: true,
                        attributes,
                        ..default()
                    },
                    None if attributes => VoxelVolume {
                        bounds: VolumeBounds::FollowCamera { cascades: 3, cells: 112, finest_cell_size: 0.125 },
                        attributes,
                        ..default()
                    },
                    None => VoxelVolume { point_counts: true, ..default() },
                });
                // A low sun, so that it reaches in through the windows.
                commands.spawn(sun());
                let (yaw, pitch, _) = camera.rotation.to_euler(EulerRot::YXZ);
                let image = target.map(|size| bevy_hao_tools::harness::target_image(&mut images, size));
                if let Some(image) = &image {
                    commands.insert_resource(ScreenshotTarget(image.clone()));
                }
                let mut cam =
                    commands.spawn((Camera3d::default(), camera, args.view, FlyCamera { yaw, pitch, speed: 4.0 }));
                if let Some(image) = image {
                    cam.insert(RenderTarget::Image(image.into()));
                }
                match args.ao.as_str() {
                    "hao" => {
                        cam.insert(HybridAmbientOcclusion::default());
                    }
                    // Bevy's SSAO, alone or as HAO's near field, needs MSAA off; HAO alone keeps Bevy's default.
                    "both" => {
                        cam.insert((HybridAmbientOcclusion { near_field: true, ..default() }, Msaa::Off));
                    }
                    "ssao" => {
                        cam.insert((bevy::pbr::ScreenSpaceAmbientOcclusion::default(), Msaa::Off));
                    }
                    _ => {}
                }
                if args.gi {
                    cam.insert(VoxelGlobalIllumination::default());
                }
            },
        );
}

#[derive(Resource)]
struct ScreenshotTarget(Handle<Image>);

fn fly_camera(
    time: Res<Time>,
    keys: Res<ButtonInput<KeyCode>>,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut cameras: Query<(&mut Transform, &mut FlyCamera)>,
) {
    for (mut transform, mut fly) in &mut cameras {
        fly.speed = (fly.speed * 1.1f32.powf(scroll.delta.y)).clamp(0.2, 100.0);
        if buttons.pressed(MouseButton::Right) {
            fly.yaw -= motion.delta.x * 0.003;
            fly.pitch = (fly.pitch - motion.delta.y * 0.003).clamp(-1.5, 1.5);
        }
        transform.rotation = Quat::from_euler(EulerRot::YXZ, fly.yaw, fly.pitch, 0.0);
        let mut dir = Vec3::ZERO;
        for (key, d) in [
            (KeyCode::KeyW, transform.forward().as_vec3()),
            (KeyCode::KeyS, transform.back().as_vec3()),
            (KeyCode::KeyA, transform.left().as_vec3()),
            (KeyCode::KeyD, transform.right().as_vec3()),
            (KeyCode::KeyE, Vec3::Y),
            (KeyCode::KeyQ, -Vec3::Y),
        ] {
            if keys.pressed(key) {
                dir += d;
            }
        }
        let boost = if keys.pressed(KeyCode::ShiftLeft) { 4.0 } else { 1.0 };
        transform.translation += dir.normalize_or_zero() * fly.speed * boost * time.delta_secs();
    }
}

fn main() {
    let args = parse_args();
    let source = SceneSource::parse(&args.scene).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let bounds = source.triangles().ok().and_then(|t| t.bounds()).unwrap_or((Vec3::splat(-10.0), Vec3::splat(10.0)));
    let camera = match args.camera {
        Some((eye, look)) => Transform::from_translation(eye).looking_at(look, Vec3::Y),
        None => default_camera(bounds, true),
    };

    if args.headless {
        let out = args.screenshot.clone().expect("checked");
        bevy_hao_tools::harness::set_asset_root(source.asset_root());
        let setup_args = args.clone();
        let mut app =
            bevy_hao_tools::harness::headless_app(|app| setup_scene(app, &setup_args, source, camera, Some(args.size)));
        bevy_hao_tools::harness::run(&mut app, args.frames);
        let target = app.world().resource::<ScreenshotTarget>().0.clone();
        if let Err(e) = bevy_hao_tools::harness::save_screenshot(&mut app, target, &out) {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
        let s = bevy_hao_tools::harness::stats(&app);
        println!(
            "wrote {out}: {} static triangles voxelized into {:?}, {} points",
            s.static_triangles,
            s.grid.map(|g| g.dims),
            s.static_counters.injected
        );
        return;
    }

    let mut app = App::new();
    let mut plugins = DefaultPlugins.set(WindowPlugin {
        primary_window: Some(Window { title: "bevy_hao: hybrid ambient occlusion".into(), ..default() }),
        ..default()
    });
    if let Some(root) = source.asset_root() {
        plugins =
            plugins.set(AssetPlugin { file_path: root, meta_check: bevy::asset::AssetMetaCheck::Never, ..default() });
    }
    app.add_plugins((plugins, HaoPlugin, bevy_hao::inspector::HaoInspectorPlugin)).add_systems(Update, fly_camera);
    if let Some(out) = args.screenshot.clone() {
        // In a window, --screenshot captures the window (inspector included) after --frames frames, then exits.
        let frames = args.frames;
        app.add_systems(
            Update,
            move |mut commands: Commands, mut n: Local<usize>, mut exit: MessageWriter<AppExit>| {
                *n += 1;
                if *n == frames {
                    commands.spawn(Screenshot::primary_window()).observe(save_to_disk(out.clone()));
                }
                if *n == frames + 30 {
                    exit.write(AppExit::Success);
                }
            },
        );
    }
    setup_scene(&mut app, &args, source, camera, None);
    app.run();
}
