//! Static and dynamic occluders side by side: the built-in cathedral (static, voxelized once) with objects
//! that move, and others that appear and vanish, marked `DynamicOccluder` (voxelized every frame on top of
//! the cached static grid), and an animated character walking among them (a skinned mesh: dynamic without
//! a marker, voxelized in the pose Bevy draws it each frame).
//!
//! ```text
//! cargo run --release --example dynamic -- [--view final|ao|voxels|counts|static-dynamic|cascades|albedo|normals]
//!     [--character PATH.glb|.gltf [--clip NAME|INDEX] [--character-scale S]]
//!     [--headless --frames 90 --screenshot OUT.png [--size 960x540]]
//! ```
//!
//! The character is a two-legged walker built in code (a skinned mesh with a pelvis and two hip joints),
//! or a glTF character given by path, playing a clip on a loop: the shared Fox with
//! `--character ../shared/models/fox-skinned/Fox.glb --clip Walk --character-scale 0.012`.
//!
//! Watch the occlusion under the rolling spheres and the sliding box move with them, and the shadows of the
//! falling crates appear and vanish; `--view static-dynamic` shows static voxels blue and dynamic ones orange.
//! In a window the inspector shows that the static grid is rebuilt once while the dynamic pass runs every
//! frame. Time advances 1/30 s per frame, so headless runs are reproducible.

use bevy::camera::RenderTarget;
use bevy::camera::visibility::DynamicSkinnedMeshBounds;
use bevy::light::GlobalAmbientLight;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hao::prelude::*;
use bevy_hao_tools::harness::args::View;
use bevy_hao_tools::scene::{SceneSource, spawn_scene, sun};
use clap::Parser;

#[derive(Component)]
struct Orbit {
    radius: f32,
    speed: f32,
    phase: f32,
    height: f32,
}

#[derive(Component)]
struct Slide;

#[derive(Component)]
struct Crate {
    age: f32,
}

#[derive(Resource)]
struct Assets3d {
    cube: Handle<Mesh>,
    material: Handle<StandardMaterial>,
}

#[derive(Resource)]
struct ScreenshotTarget(Handle<Image>);

/// The character to walk: built in code, or a glTF file's scene playing a clip.
#[derive(Resource, Clone)]
enum CharacterChoice {
    Builtin,
    Gltf { dir: String, file: String, clip: usize, scale: f32 },
}

/// The entity that walks (the built-in walker's pelvis, or the glTF scene's root).
#[derive(Component)]
struct Walker;

/// The built-in walker's hip joints, with the phase of their swing.
#[derive(Component)]
struct Hip(f32);

/// The clip the glTF character's animation players start, on a loop.
#[derive(Resource)]
struct CharacterClip {
    graph: Handle<AnimationGraph>,
    node: AnimationNodeIndex,
}

/// A box of `size` centred at `center` as a skinned piece wholly on `joint`: positions, normals and joint
/// data appended to the lists.
fn skinned_box(
    center: Vec3,
    size: Vec3,
    joint: u16,
    mesh: &mut (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u16; 4]>, Vec<u32>),
) {
    let m = Cuboid::from_size(size).mesh().build();
    let Some(VertexAttributeValues::Float32x3(p)) = m.attribute(Mesh::ATTRIBUTE_POSITION) else { return };
    let Some(VertexAttributeValues::Float32x3(n)) = m.attribute(Mesh::ATTRIBUTE_NORMAL) else { return };
    let base = mesh.0.len() as u32;
    mesh.0.extend(p.iter().map(|v| (Vec3::from(*v) + center).to_array()));
    mesh.1.extend(n.iter().copied());
    mesh.2.extend(std::iter::repeat_n([joint, 0, 0, 0], p.len()));
    mesh.3.extend(m.indices().into_iter().flat_map(|i| i.iter()).map(|i| base + i as u32));
}

/// A two-legged walker built in code: a body on the pelvis joint (0) and a leg on each hip joint (1, 2),
/// bound with the pelvis at the origin and the hips at (+-0.25, 0.9, 0).
fn spawn_builtin_walker(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
    bindposes: &mut Assets<SkinnedMeshInverseBindposes>,
) {
    let hips = [Vec3::new(-0.25, 0.9, 0.0), Vec3::new(0.25, 0.9, 0.0)];
    let mut parts = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    skinned_box(Vec3::new(0.0, 1.45, 0.0), Vec3::new(0.8, 1.1, 0.45), 0, &mut parts);
    skinned_box(Vec3::new(0.0, 2.2, 0.0), Vec3::splat(0.4), 0, &mut parts);
    for (k, hip) in hips.iter().enumerate() {
        skinned_box(*hip - Vec3::Y * 0.45, Vec3::new(0.25, 0.9, 0.25), k as u16 + 1, &mut parts);
    }
    let (positions, normals, joints, indices) = parts;
    let weights = vec![[1.0f32, 0.0, 0.0, 0.0]; positions.len()];
    let mesh = Mesh::new(bevy::mesh::PrimitiveTopology::TriangleList, bevy::asset::RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(joints))
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights)
        .with_inserted_indices(bevy::mesh::Indices::U32(indices))
        .with_generated_skinned_mesh_bounds()
        .expect("the walker's skin is valid");
    let pelvis = commands.spawn((Transform::default(), Visibility::default(), Walker)).id();
    let legs: Vec<Entity> = hips
        .iter()
        .enumerate()
        .map(|(k, hip)| {
            commands
                .spawn((Transform::from_translation(*hip), Hip(k as f32 * std::f32::consts::PI), ChildOf(pelvis)))
                .id()
        })
        .collect();
    let inverse_bindposes =
        bindposes.add(vec![Mat4::IDENTITY, Mat4::from_translation(-hips[0]), Mat4::from_translation(-hips[1])]);
    commands.spawn((
        Mesh3d(meshes.add(mesh)),
        MeshMaterial3d(materials.add(StandardMaterial { base_color: Color::srgb(0.2, 0.35, 0.7), ..default() })),
        SkinnedMesh { inverse_bindposes, joints: vec![pelvis, legs[0], legs[1]] },
        DynamicSkinnedMeshBounds,
        ChildOf(pelvis),
    ));
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    server: Res<AssetServer>,
    target: Option<Res<ScreenshotTarget>>,
    view: Res<ViewChoice>,
    character: Res<CharacterChoice>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
) {
    spawn_scene(&SceneSource::Builtin("cathedral".into()), &mut commands, &mut meshes, &mut materials, &server)
        .expect("built-in scene");
    // The default volume (cascades following the camera), with point counts for the heat map view; the
    // albedo and normal views need the voxels' attributes, whose sums must fit one storage binding (128 MiB
    // on lavapipe): 3 cascades of 112^3 then.
    if matches!(view.0, HaoDebugView::Albedo | HaoDebugView::Normals) {
        let bounds = VolumeBounds::FollowCamera { cascades: 3, cells: 112, finest_cell_size: 0.125 };
        commands.spawn(VoxelVolume { bounds, attributes: true, ..default() });
    } else {
        commands.spawn(VoxelVolume { point_counts: true, ..default() });
    }
    commands.spawn(sun());
    let red = materials.add(StandardMaterial { base_color: Color::srgb(0.7, 0.2, 0.15), ..default() });
    let sphere = meshes.add(Sphere::new(0.8).mesh().uv(32, 16));
    for k in 0..3 {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(red.clone()),
            Transform::default(),
            DynamicOccluder,
            Orbit { radius: 3.0, speed: 0.6, phase: k as f32 * std::f32::consts::TAU / 3.0, height: 0.8 },
        ));
    }
    let cube = meshes.add(Cuboid::new(1.0, 1.0, 1.0));
    let wood = materials.add(StandardMaterial { base_color: Color::srgb(0.55, 0.4, 0.25), ..default() });
    commands.spawn((
        Mesh3d(cube.clone()),
        MeshMaterial3d(wood.clone()),
        Transform::from_xyz(-9.0, 0.75, 0.0).with_scale(Vec3::new(1.5, 1.5, 3.0)),
        DynamicOccluder,
        Slide,
    ));
    commands.insert_resource(Assets3d { cube, material: wood });
    match &*character {
        CharacterChoice::Builtin => spawn_builtin_walker(&mut commands, &mut meshes, &mut materials, &mut bindposes),
        CharacterChoice::Gltf { file, clip, scale, .. } => {
            let clip = GltfAssetLabel::Animation(*clip).from_asset(file.clone());
            let file = file.clone();
            let (graph, node) = AnimationGraph::from_clip(server.load(clip));
            commands.insert_resource(CharacterClip { graph: graphs.add(graph), node });
            commands.spawn((
                WorldAssetRoot(server.load(GltfAssetLabel::Scene(0).from_asset(file))),
                Transform::from_scale(Vec3::splat(*scale)),
                Walker,
            ));
        }
    }
    let mut camera = commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(3.5, 4.5, 9.0).looking_at(Vec3::new(-2.0, 0.5, -1.0), Vec3::Y),
        HybridAmbientOcclusion::default(),
        view.0,
    ));
    if let Some(target) = target {
        camera.insert(RenderTarget::Image(target.0.clone().into()));
    }
}

#[derive(Resource, Clone, Copy)]
struct ViewChoice(HaoDebugView);

fn animate(
    time: Res<Time>,
    mut orbits: Query<(&mut Transform, &Orbit)>,
    mut slides: Query<&mut Transform, (With<Slide>, Without<Orbit>)>,
) {
    let t = time.elapsed_secs();
    for (mut transform, o) in &mut orbits {
        let a = o.phase + t * o.speed;
        transform.translation = Vec3::new(a.cos() * o.radius, o.height, a.sin() * o.radius - 2.0);
    }
    for mut transform in &mut slides {
        transform.translation.z = (t * 0.5).sin() * 8.0;
    }
}

/// Walks the character around a loop between the pillars and the rolling spheres, facing where it goes;
/// the built-in walker swings its legs.
fn walk(
    time: Res<Time>,
    mut walkers: Query<&mut Transform, With<Walker>>,
    mut hips: Query<(&mut Transform, &Hip), Without<Walker>>,
) {
    let t = time.elapsed_secs();
    let a = t * 0.35;
    let at = |a: f32| Vec3::new(5.5 * a.cos(), 0.0, 3.0 * a.sin() - 2.0);
    for mut transform in &mut walkers {
        let scale = transform.scale;
        let (here, ahead) = (at(a), at(a + 0.01));
        *transform = Transform::from_translation(here).looking_to(here - ahead, Vec3::Y).with_scale(scale);
    }
    for (mut transform, hip) in &mut hips {
        transform.rotation = Quat::from_rotation_x(0.5 * (t * 4.0 + hip.0).sin());
    }
}

/// Starts the glTF character's clip on a loop when its animation player appears.
fn play_character_clip(
    mut commands: Commands,
    clip: Option<Res<CharacterClip>>,
    mut players: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
) {
    let Some(clip) = clip else { return };
    for (entity, mut player) in &mut players {
        player.play(clip.node).repeat();
        commands.entity(entity).insert(AnimationGraphHandle(clip.graph.clone()));
    }
}

/// Drops a crate every second and despawns each after three.
fn crates(
    mut commands: Commands,
    time: Res<Time>,
    assets: Res<Assets3d>,
    mut crates: Query<(Entity, &mut Transform, &mut Crate)>,
    mut timer: Local<f32>,
    mut count: Local<u32>,
) {
    *timer += time.delta_secs();
    if *timer >= 1.0 {
        *timer -= 1.0;
        *count += 1;
        let x = ((*count * 37) % 9) as f32 - 4.0;
        commands.spawn((
            Mesh3d(assets.cube.clone()),
            MeshMaterial3d(assets.material.clone()),
            Transform::from_xyz(x, 6.0, 6.0 + ((*count * 53) % 5) as f32),
            DynamicOccluder,
            Crate { age: 0.0 },
        ));
    }
    for (entity, mut transform, mut c) in &mut crates {
        c.age += time.delta_secs();
        transform.translation.y = (6.0 - 4.9 * c.age * c.age).max(0.5);
        if c.age > 3.0 {
            commands.entity(entity).despawn();
        }
    }
}

/// Moving geometry and an animated character with hybrid ambient occlusion.
#[derive(Parser)]
struct Cli {
    /// What the view shows.
    #[arg(long, value_enum, default_value_t = View::Final)]
    view: View,
    /// A glTF or GLB character to walk around instead of the built-in walker.
    #[arg(long)]
    character: Option<std::path::PathBuf>,
    /// The character's animation clip, by name or index.
    #[arg(long, default_value = "0", requires = "character")]
    clip: String,
    /// The character's scale.
    #[arg(long, default_value_t = 1.0, requires = "character", value_parser = positive)]
    character_scale: f32,
    /// Render off screen (needs --screenshot).
    #[arg(long, requires = "screenshot")]
    headless: bool,
    /// Frames before the screenshot.
    #[arg(long, default_value_t = 90)]
    frames: usize,
    /// Write a screenshot to this PNG and exit.
    #[arg(long)]
    screenshot: Option<String>,
    /// Image size when headless, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x540", value_parser = bevy_hao_tools::harness::args::size)]
    size: UVec2,
}

fn positive(s: &str) -> Result<f32, String> {
    s.parse::<f32>().ok().filter(|v| *v > 0.0 && v.is_finite()).ok_or_else(|| format!("{s} is not a positive number"))
}

fn main() {
    let Cli { view, character: character_path, clip, character_scale, headless, frames, screenshot, size } =
        Cli::parse();
    let view = HaoDebugView::from(view);
    // A glTF character is loaded from its own folder (Bevy resolves a relative asset root against the
    // executable's folder, so the path is made absolute).
    let character = match character_path {
        None => CharacterChoice::Builtin,
        Some(p) => {
            let found = std::fs::canonicalize(&p).map_err(|e| e.to_string()).and_then(|abs| {
                let clips = bevy_hao_tools::meshes::gltf_file::gltf_animations(&abs)?;
                let index = clips
                    .iter()
                    .find(|c| c.name.as_deref() == Some(clip.as_str()) || c.index.to_string() == clip)
                    .map(|c| c.index)
                    .ok_or_else(|| format!("no clip {clip:?} (see voxelize --list-animations)"))?;
                let dir = abs.parent().map(|d| d.to_string_lossy().into_owned()).unwrap_or_default();
                let file = abs.file_name().unwrap_or_default().to_string_lossy().into_owned();
                Ok(CharacterChoice::Gltf { dir, file, clip: index, scale: character_scale })
            });
            match found {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("--character {}: {e}", p.display());
                    std::process::exit(2);
                }
            }
        }
    };
    // A glTF character's textures and buffers are read from its own folder.
    let asset_dir = match &character {
        CharacterChoice::Gltf { dir, .. } => Some(dir.clone()),
        CharacterChoice::Builtin => None,
    };
    bevy_hao_tools::harness::set_asset_root(asset_dir.clone());
    let configure = move |app: &mut App| {
        app.insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.95, 0.93, 0.88),
            brightness: 700.0,
            ..default()
        })
        .insert_resource(ClearColor(Color::srgb(0.55, 0.68, 0.85)))
        .insert_resource(TimeUpdateStrategy::ManualDuration(std::time::Duration::from_secs_f32(1.0 / 30.0)))
        .insert_resource(ViewChoice(view))
        .insert_resource(character.clone())
        .add_systems(Startup, setup)
        .add_systems(Update, (animate, crates, walk, play_character_clip));
    };
    if headless {
        let Some(out) = screenshot else {
            eprintln!("--headless needs --screenshot OUT.png");
            std::process::exit(2);
        };
        let mut app = bevy_hao_tools::harness::headless_app(|app| {
            let target =
                bevy_hao_tools::harness::target_image(&mut app.world_mut().resource_mut::<Assets<Image>>(), size);
            app.insert_resource(ScreenshotTarget(target));
            configure(app);
        });
        bevy_hao_tools::harness::run(&mut app, frames);
        let target = app.world().resource::<ScreenshotTarget>().0.clone();
        if let Err(e) = bevy_hao_tools::harness::save_screenshot(&mut app, target, &out) {
            eprintln!("error: no screenshot ({e})");
            std::process::exit(1);
        }
        let s = bevy_hao_tools::harness::stats(&app);
        println!(
            "wrote {out}: static grid built {} times in {frames} frames; {} dynamic instances ({} triangles) this frame",
            s.static_rebuilds, s.dynamic_instances, s.dynamic_triangles
        );
        return;
    }
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: Some(Window { title: "bevy_hao: dynamic occluders".into(), ..default() }),
                ..default()
            })
            .set(AssetPlugin {
                file_path: asset_dir.unwrap_or_else(|| "assets".into()),
                meta_check: bevy::asset::AssetMetaCheck::Never,
                ..default()
            }),
        HaoPlugin,
        bevy_hao::inspector::HaoInspectorPlugin,
    ));
    configure(&mut app);
    app.run();
}
