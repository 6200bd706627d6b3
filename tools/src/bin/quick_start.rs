//! The README's quick start as a user pastes it (a sphere `DynamicOccluder` resting on a `StaticOccluder`
//! floor, the camera with `HybridAmbientOcclusion` at its defaults and Bevy's default MSAA, an ambient light
//! of 500), rendered headless and written to a PNG at a frame of your choice: the first thing a new user
//! sees, to be looked at.
//!
//! ```text
//! cargo run --release -p bevy_hao_tools --bin quick_start -- [OPTIONS]   (--help lists them)
//! ```
//!
//! `--view ao` shows the AO alone (`HaoDebugView::AmbientOcclusion`), `--camera close` looks at the
//! sphere's contact from 2.6 m, and `--zoom X,Y,W,H` also writes that crop of the frame, four times
//! enlarged, beside the PNG. Variations a user might try: `--solid` (the sphere `VoxelFill::Solid`),
//! `--no-depth-contacts` (`HybridAmbientOcclusion::depth_contacts: false`) and `--ssao` (Bevy's SSAO on the
//! camera instead, with `Msaa::Off`, which it needs).

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::{self, args};
use clap::Parser;

#[derive(Parser, Clone)]
#[command(about = "The README's quick start, rendered headless to a PNG")]
struct Cli {
    /// Frames rendered before the screenshot.
    #[arg(long, default_value_t = 150)]
    frames: u32,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x540", value_parser = args::size)]
    size: UVec2,
    /// What the camera shows.
    #[arg(long, value_enum, default_value_t = args::View::Final)]
    view: args::View,
    /// The camera: the README's (from 6 m, 3 m up) or close to the sphere's contact.
    #[arg(long, value_enum, default_value_t = CameraChoice::Readme)]
    camera: CameraChoice,
    /// The sphere voxelized filled (`VoxelFill::Solid`).
    #[arg(long)]
    solid: bool,
    /// `depth_contacts: false` on the camera.
    #[arg(long)]
    no_depth_contacts: bool,
    /// Bevy's SSAO (`High`, `Msaa::Off`) on the camera instead of HAO.
    #[arg(long)]
    ssao: bool,
    /// The PNG written.
    #[arg(long, default_value = "quick_start.png")]
    out: String,
    /// Also write this crop X,Y,W,H (pixels), four times enlarged, beside the PNG (`-zoom.png`).
    #[arg(long, value_parser = args::crop)]
    zoom: Option<[u32; 4]>,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum CameraChoice {
    /// The README's: from (0, 3, 6), looking at the origin.
    Readme,
    /// From (0, 0.9, 2.6), looking at the floor just in front of the sphere.
    Close,
}

#[derive(Resource)]
struct Setup(Cli, Handle<Image>);

fn main() {
    let cli = Cli::parse();
    let (out, zoom, frames) = (cli.out.clone(), cli.zoom, cli.frames);
    let mut app = harness::headless_app(|app| {
        let target = harness::target_image(&mut app.world_mut().resource_mut::<Assets<Image>>(), cli.size);
        app.insert_resource(Setup(cli, target)).add_systems(Startup, setup);
    });
    harness::run(&mut app, frames as usize);
    let target = app.world().resource::<Setup>().1.clone();
    if let Err(e) = harness::save_screenshot(&mut app, target, &out) {
        eprintln!("error: no screenshot ({e})");
        std::process::exit(1);
    }
    println!("wrote {out} (frame {frames})");
    if let Some([x, y, w, h]) = zoom {
        const SCALE: u32 = 4;
        let written = match image::open(&out) {
            Ok(i) => i.to_rgb8(),
            Err(e) => {
                eprintln!("error: reading {out} back: {e}");
                std::process::exit(1);
            }
        };
        if x + w > written.width() || y + h > written.height() {
            eprintln!("error: --zoom {x},{y},{w},{h} lies outside the {}x{} image", written.width(), written.height());
            std::process::exit(2);
        }
        let crop = image::imageops::crop_imm(&written, x, y, w, h).to_image();
        let big = image::imageops::resize(&crop, w * SCALE, h * SCALE, image::imageops::FilterType::Nearest);
        let path = format!("{}-zoom.png", out.trim_end_matches(".png"));
        if let Err(e) = big.save(&path) {
            eprintln!("error: writing {path}: {e}");
            std::process::exit(1);
        }
        println!("wrote {path}");
    }
}

/// The README's quick start, with the tool's choices.
fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    setup: Res<Setup>,
) {
    let Setup(cli, target) = &*setup;
    let transform = match cli.camera {
        CameraChoice::Readme => Transform::from_xyz(0.0, 3.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
        CameraChoice::Close => Transform::from_xyz(0.0, 0.9, 2.6).looking_at(Vec3::new(0.0, 0.15, 0.0), Vec3::Y),
    };
    let mut camera = commands.spawn((Camera3d::default(), transform, RenderTarget::Image(target.clone().into())));
    if cli.ssao {
        camera.insert((bevy::pbr::ScreenSpaceAmbientOcclusion::default(), Msaa::Off));
    } else {
        camera.insert((
            HybridAmbientOcclusion { depth_contacts: !cli.no_depth_contacts, ..default() },
            HaoDebugView::from(cli.view),
        ));
    }
    commands.spawn(VoxelVolume {
        bounds: VolumeBounds::FollowCamera { cascades: 4, cells: 192, finest_cell_size: 0.125 },
        ..default()
    });
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(20.0, 0.2, 20.0))),
        MeshMaterial3d(materials.add(Color::WHITE)),
        StaticOccluder,
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(1.0))),
        MeshMaterial3d(materials.add(Color::WHITE)),
        Transform::from_xyz(0.0, 1.0, 0.0),
        DynamicOccluder,
        if cli.solid { VoxelFill::Solid } else { VoxelFill::Surface },
    ));
    commands.insert_resource(bevy::light::GlobalAmbientLight { brightness: 500.0, ..default() });
}
