//! Scenes of contacts and moving props, scripted frame by frame, for measuring ambient occlusion where a
//! player looks first (`ao_motion`, the motion tests): a room corner with a floor, two walls, a crate in the
//! corner, a pole leaning on a wall, a step, and a sphere resting on the floor; or the same room with the
//! sphere rolling across the floor and a box sliding along the wall; or a skinned glTF character walking
//! across it ([`Character`], [`MotionScene::walk`]).
//!
//! Everything is a function of the script's frame number ([`MotionScript`]): the props' poses, and the
//! camera's when it swings, so that the Bevy app and the CPU reference ([`MotionScene::triangles_at`]) see
//! the same scene in every frame, and two runs see the same frames. Frame 0 is the scene's nominal pose: the
//! rolling sphere in the middle of the floor at full speed, a swinging camera at its start pose at its
//! fastest; measurements centre their frames on it.

use crate::meshes::builtin::{cuboid, cylinder, sphere};
use bevy::prelude::*;
use bevy_hao::cpu::TriangleMesh;
use std::f32::consts::TAU;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How a prop is voxelized.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Marker {
    /// `StaticOccluder`.
    Static,
    /// `DynamicOccluder`.
    Dynamic,
}

/// How a prop moves, frame by frame.
#[derive(Clone, Copy, Debug)]
pub enum PropPath {
    /// It stands at this pose.
    Still(Transform),
    /// To and fro along `direction` (unit, horizontal) through `center`, `half_length` either side, `speed`
    /// world units a frame, passing `center` at frame 0 going forward. With `roll_radius`, it rolls on the
    /// floor as a ball of that radius (no slipping); else it slides without turning.
    Shuttle { center: Vec3, direction: Vec3, half_length: f32, speed: f32, roll_radius: Option<f32> },
    /// Up and down through `center` as a sine, `amplitude` either side, one cycle in `period` frames,
    /// passing `center` at frame 0 going up (Bevy's `ssao` example: `sin(t / 1.7) * 0.7`).
    Bob { center: Vec3, amplitude: f32, period: f32 },
}

impl PropPath {
    /// The pose at script frame `frame`.
    pub fn pose(&self, frame: i32) -> Transform {
        match *self {
            PropPath::Still(t) => t,
            PropPath::Shuttle { center, direction, half_length, speed, roll_radius } => {
                let x = half_length * triangle_wave(frame as f32 * speed / half_length);
                let mut t = Transform::from_translation(center + direction * x);
                if let Some(r) = roll_radius {
                    // Rolling without slipping: the contact point stays still, so the ball turns by x / r
                    // about the horizontal axis across its path.
                    t.rotation = Quat::from_axis_angle(Vec3::Y.cross(direction).normalize(), x / r);
                }
                t
            }
            PropPath::Bob { center, amplitude, period } => {
                Transform::from_translation(center + Vec3::Y * amplitude * (TAU * frame as f32 / period).sin())
            }
        }
    }

    /// Whether it moves.
    pub fn moves(&self) -> bool {
        !matches!(self, PropPath::Still(_))
    }
}

/// A triangle wave of period 4 and amplitude 1, rising through 0 at 0.
fn triangle_wave(u: f32) -> f32 {
    let u = (u + 1.0).rem_euclid(4.0);
    if u < 2.0 { u - 1.0 } else { 3.0 - u }
}

/// A prop: a mesh in its own space, how it is voxelized and how it moves.
#[derive(Clone, Debug)]
pub struct Prop {
    /// Its name.
    pub name: &'static str,
    /// Its triangles, in its own space.
    pub mesh: TriangleMesh,
    /// Smooth normals (a sphere) or flat ones (a box).
    pub smooth: bool,
    /// How it is voxelized.
    pub marker: Marker,
    /// How it moves.
    pub path: PropPath,
}

/// A scripted scene: static parts in world space, props, and the camera.
#[derive(Clone, Debug, Resource)]
pub struct MotionScene {
    /// The static parts (`StaticOccluder`), in world space.
    pub statics: Vec<(&'static str, TriangleMesh)>,
    /// The props.
    pub props: Vec<Prop>,
    /// The camera at frame 0.
    pub camera: Transform,
    /// The point the camera swings about, and its swing: at most this many degrees a frame (0: still).
    pub camera_center: Vec3,
    /// Degrees a frame at the fastest of the camera's swing (0: the camera stands still).
    pub camera_speed: f32,
    /// A skinned character walking through it, if any.
    pub character: Option<Character>,
    /// The props are voxelized filled (`VoxelFill::Solid`: they are closed meshes), not as surfaces.
    pub solid_props: bool,
}

/// Frames a second of the script: a character's clip plays at this rate.
pub const SCRIPT_FPS: f32 = 60.0;

/// A skinned glTF character: posed by one of its clips at the script's time (looped), scaled to a height,
/// standing on the floor, carried along a path. Bevy's `AnimationPlayer` is sought to the same time each
/// frame (paused), and the reference is posed by the lab's own sampler and skinning of the file
/// (`meshes::gltf_file::read_gltf_posed`, held voxel for voxel against the GPU's by `voxelize --animation`).
#[derive(Clone, Debug)]
pub struct Character {
    /// The file, absolute.
    pub file: PathBuf,
    /// The clip's index in the file.
    pub clip: usize,
    /// The clip's length in seconds.
    pub duration: f32,
    /// The scene of the file spawned (its default, else the first).
    pub scene: usize,
    /// How its root moves (its feet on the floor at y = 0, its bounds centred on the path).
    pub path: PropPath,
    /// Its scale.
    pub scale: f32,
    /// Added to its root's translation: its feet on the floor, centred on the path.
    offset: Vec3,
    bytes: Arc<Vec<u8>>,
}

impl Character {
    /// Loads `file` to walk along `path` by the clip named (or numbered) `clip`, scaled to `height` world
    /// units tall (in its pose at time 0).
    pub fn load(file: &Path, clip: &str, height: f32, path: PropPath) -> Result<Self, String> {
        use crate::meshes::gltf_file;
        let file = std::fs::canonicalize(file).map_err(|e| format!("{}: {e}", file.display()))?;
        let (mesh, clip, _) = gltf_file::load_gltf_posed(&file, clip, 0.0)?;
        let duration = gltf_file::gltf_animations(&file)?.iter().find(|a| a.index == clip).map_or(0.0, |a| a.duration);
        let scene = gltf_file::gltf_scene_index(&file)?.unwrap_or(0);
        let (lo, hi) = mesh.bounds().ok_or_else(|| format!("{}: no triangles", file.display()))?;
        if !(hi.y - lo.y > 0.0) || !(height > 0.0) {
            return Err(format!(
                "{}: a character of height {} cannot be scaled to {height}",
                file.display(),
                hi.y - lo.y
            ));
        }
        let scale = height / (hi.y - lo.y);
        let center = (lo + hi) * 0.5;
        let offset = Vec3::new(-center.x, -lo.y, -center.z) * scale;
        let bytes = Arc::new(std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?);
        Ok(Self { file, clip, duration, scene, path, scale, offset, bytes })
    }

    /// The clip's time at script frame `frame`, looped.
    pub fn time_at(&self, frame: i32) -> f32 {
        let t = frame as f32 / SCRIPT_FPS;
        if self.duration > 0.0 { t.rem_euclid(self.duration) } else { 0.0 }
    }

    /// Its root's transform at script frame `frame`.
    pub fn root_at(&self, frame: i32) -> Transform {
        let mut t = self.path.pose(frame);
        t.translation += self.offset;
        t.scale = Vec3::splat(self.scale);
        t
    }

    /// Its triangles in world space as posed at script frame `frame`.
    pub fn triangles_at(&self, frame: i32) -> TriangleMesh {
        let dir = self.file.parent().unwrap_or(Path::new("."));
        match crate::meshes::gltf_file::read_gltf_posed(&self.bytes, dir, Some((self.clip, self.time_at(frame)))) {
            Ok((mesh, _)) => mesh.transformed(self.root_at(frame).compute_affine()),
            // (`load` posed it once already: a file that reads then and not now changed on disk.)
            Err(e) => {
                eprintln!("warning: {}: the character cannot be posed at frame {frame}: {e}", self.file.display());
                TriangleMesh::default()
            }
        }
    }
}

/// The scenes by name: `contacts` (everything still), `roll` (a sphere rolling, a box sliding) and `bob`
/// (Bevy's own `ssao` example: three cubes and a sphere bobbing between them).
pub const MOTION_SCENES: [&str; 3] = ["contacts", "roll", "bob"];

/// Frames of one swing of the camera, to and fro.
pub const CAMERA_PERIOD: i32 = 240;

/// The radius of the scenes' sphere.
pub const SPHERE_RADIUS: f32 = 0.5;

/// The room both scenes share: a floor (its top at y = 0), a back wall (its face at z = -2), a side wall
/// (its face at x = -3), a crate in their corner, a step along the back wall and a pole leaning on it.
pub fn room() -> Vec<(&'static str, TriangleMesh)> {
    let mut pole = cylinder(Vec3::ZERO, 0.05, 2.3, 16);
    // Leaning on the back wall: from the floor 0.8 m out to the wall about 2.1 m up.
    let lean = Quat::from_rotation_x(-(0.8f32 / 2.3).asin());
    pole = pole.transformed(bevy::math::Affine3A::from_rotation_translation(lean, Vec3::new(2.3, 0.0, -1.2)));
    vec![
        ("floor", cuboid(Vec3::new(-3.2, -0.2, -2.2), Vec3::new(4.0, 0.0, 4.0))),
        ("back wall", cuboid(Vec3::new(-3.2, 0.0, -2.2), Vec3::new(4.0, 3.0, -2.0))),
        ("side wall", cuboid(Vec3::new(-3.2, 0.0, -2.0), Vec3::new(-3.0, 3.0, 4.0))),
        ("crate", cuboid(Vec3::new(-3.0, 0.0, -2.0), Vec3::new(-2.2, 0.8, -1.2))),
        ("step", cuboid(Vec3::new(-1.6, 0.0, -2.0), Vec3::new(-0.2, 0.2, -1.4))),
        ("pole", pole),
    ]
}

fn ball() -> TriangleMesh {
    sphere(SPHERE_RADIUS, 48, 24)
}

impl MotionScene {
    /// The scene `name` (one of [`MOTION_SCENES`]); in `contacts` the sphere is voxelized as `marker` says
    /// (the moving props of `roll` and `bob` are dynamic).
    pub fn named(name: &str, marker: Marker) -> Option<Self> {
        if name == "bob" {
            return Some(Self::bevy_ssao_example());
        }
        let camera = Transform::from_xyz(0.4, 2.4, 4.0).looking_at(Vec3::new(0.0, 0.4, -0.6), Vec3::Y);
        let camera_center = Vec3::new(0.0, 0.4, -0.2);
        let props = match name {
            "contacts" => vec![Prop {
                name: "sphere",
                mesh: ball(),
                smooth: true,
                marker,
                path: PropPath::Still(Transform::from_xyz(0.6, SPHERE_RADIUS, -0.2)),
            }],
            "roll" => vec![
                Prop {
                    name: "sphere",
                    mesh: ball(),
                    smooth: true,
                    marker: Marker::Dynamic,
                    // 1.5 m/s at 60 frames a second.
                    path: PropPath::Shuttle {
                        center: Vec3::new(0.2, SPHERE_RADIUS, 0.2),
                        direction: Vec3::X,
                        half_length: 1.8,
                        speed: 0.025,
                        roll_radius: Some(SPHERE_RADIUS),
                    },
                },
                Prop {
                    name: "box",
                    mesh: cuboid(Vec3::splat(-0.25), Vec3::splat(0.25)),
                    smooth: false,
                    marker: Marker::Dynamic,
                    // Along the back wall, touching it and the floor, 1 m/s.
                    path: PropPath::Shuttle {
                        center: Vec3::new(0.9, 0.25, -1.75),
                        direction: Vec3::X,
                        half_length: 0.8,
                        speed: 1.0 / 60.0,
                        roll_radius: None,
                    },
                },
            ],
            _ => return None,
        };
        Some(Self {
            statics: room(),
            props,
            camera,
            camera_center,
            camera_speed: 0.0,
            character: None,
            solid_props: false,
        })
    }

    /// Bevy 0.19's `examples/3d/ssao.rs` as its scene stands: unit cubes at (0, 0, 1), (0, -1, 0) and
    /// (1, 0, 0), a sphere of radius 0.4 (72 x 36) bobbing between them (`sin(t / 1.7) * 0.7` at 60 frames a
    /// second: at most 0.41 m/s), the camera at (-2, 2, -2) looking at the origin. The example marks nothing:
    /// the plugin promotes the moving sphere to dynamic on its first move, so here it is dynamic from the start.
    fn bevy_ssao_example() -> Self {
        let unit = |c: Vec3| cuboid(c - Vec3::splat(0.5), c + Vec3::splat(0.5));
        Self {
            statics: vec![
                ("cube z", unit(Vec3::new(0.0, 0.0, 1.0))),
                ("cube y", unit(Vec3::new(0.0, -1.0, 0.0))),
                ("cube x", unit(Vec3::new(1.0, 0.0, 0.0))),
            ],
            props: vec![Prop {
                name: "sphere",
                mesh: sphere(0.4, 72, 36),
                smooth: true,
                marker: Marker::Dynamic,
                path: PropPath::Bob { center: Vec3::ZERO, amplitude: 0.7, period: TAU * 1.7 * SCRIPT_FPS },
            }],
            camera: Transform::from_xyz(-2.0, 2.0, -2.0).looking_at(Vec3::ZERO, Vec3::Y),
            camera_center: Vec3::ZERO,
            camera_speed: 0.0,
            character: None,
            solid_props: false,
        }
    }

    /// The room with `character` walking across the floor in front of the step at 1 m/s (and no props),
    /// seen from the same camera.
    pub fn walk(character: Character) -> Self {
        let mut scene = Self::named("contacts", Marker::Dynamic).expect("a known scene");
        scene.props.clear();
        scene.character = Some(character);
        scene
    }

    /// The path [`MotionScene::walk`]'s character takes: along x through the middle of the floor, 1 m/s.
    pub fn walk_path() -> PropPath {
        PropPath::Shuttle {
            center: Vec3::new(0.2, 0.0, -0.4),
            direction: Vec3::X,
            half_length: 1.8,
            speed: 1.0 / SCRIPT_FPS,
            roll_radius: None,
        }
    }

    /// The camera's pose at script frame `frame`: swung about the vertical through `camera_center` by a
    /// sine of [`CAMERA_PERIOD`] frames whose fastest turn (at frame 0) is `camera_speed` degrees a frame.
    pub fn camera_at(&self, frame: i32) -> Transform {
        if self.camera_speed <= 0.0 {
            return self.camera;
        }
        let amplitude = self.camera_speed.to_radians() * CAMERA_PERIOD as f32 / TAU;
        let phase = TAU * frame as f32 / CAMERA_PERIOD as f32;
        let mut pose = self.camera;
        pose.rotate_around(self.camera_center, Quat::from_rotation_y(amplitude * phase.sin()));
        pose
    }

    /// The scene's triangles in world space as drawn at script frame `frame`.
    pub fn triangles_at(&self, frame: i32) -> TriangleMesh {
        let mut out = TriangleMesh::default();
        for (_, mesh) in &self.statics {
            out.append(mesh, bevy::math::Affine3A::IDENTITY);
        }
        for prop in &self.props {
            out.append(&prop.mesh, prop.path.pose(frame).compute_affine());
        }
        if let Some(c) = &self.character {
            out.append(&c.triangles_at(frame), bevy::math::Affine3A::IDENTITY);
        }
        out
    }

    /// The world bounds of the props at script frame `frame`: of those that move, or of every prop where
    /// none does.
    pub fn prop_bounds_at(&self, frame: i32) -> Vec<(Vec3, Vec3)> {
        let any_moves = self.character.is_some() || self.props.iter().any(|p| p.path.moves());
        let mut bounds: Vec<(Vec3, Vec3)> = self
            .props
            .iter()
            .filter(|p| p.path.moves() || !any_moves)
            .filter_map(|p| p.mesh.transformed(p.path.pose(frame).compute_affine()).bounds())
            .collect();
        bounds.extend(self.character.as_ref().and_then(|c| c.triangles_at(frame).bounds()));
        bounds
    }

    /// Spawns the scene's static parts and props (the props tagged [`ScriptedProp`]); the app needs
    /// [`MotionScriptPlugin`] to move them.
    pub fn spawn(&self, commands: &mut Commands, meshes: &mut Assets<Mesh>, materials: &mut Assets<StandardMaterial>) {
        let material = materials.add(StandardMaterial {
            base_color: Color::srgb(0.8, 0.78, 0.74),
            perceptual_roughness: 0.9,
            ..default()
        });
        for (name, mesh) in &self.statics {
            commands.spawn((
                Mesh3d(meshes.add(crate::scene::bevy_mesh(mesh, false))),
                MeshMaterial3d(material.clone()),
                bevy_hao::StaticOccluder,
                Name::new(*name),
            ));
        }
        for (k, prop) in self.props.iter().enumerate() {
            let mut e = commands.spawn((
                Mesh3d(meshes.add(crate::scene::bevy_mesh(&prop.mesh, prop.smooth))),
                MeshMaterial3d(material.clone()),
                prop.path.pose(0),
                ScriptedProp(k),
                Name::new(prop.name),
            ));
            match prop.marker {
                Marker::Static => e.insert(bevy_hao::StaticOccluder),
                Marker::Dynamic => e.insert(bevy_hao::DynamicOccluder),
            };
            if self.solid_props {
                e.insert(bevy_hao::VoxelFill::Solid);
            }
        }
    }
}

impl MotionScene {
    /// Spawns its character, if any, at script frame 0 (tagged [`ScriptedCharacter`]), its clip started
    /// paused on the animation players its scene spawns. The app's asset root must be the file's folder
    /// (`harness::set_asset_root`).
    pub fn spawn_character(
        &self,
        commands: &mut Commands,
        asset_server: &AssetServer,
        graphs: &mut Assets<AnimationGraph>,
    ) {
        let Some(c) = &self.character else { return };
        let file = c.file.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        let (graph, node) =
            AnimationGraph::from_clip(asset_server.load(GltfAssetLabel::Animation(c.clip).from_asset(file.clone())));
        commands.insert_resource(CharacterClip { graph: graphs.add(graph), node });
        commands.spawn((
            WorldAssetRoot(asset_server.load(GltfAssetLabel::Scene(c.scene).from_asset(file))),
            c.root_at(0),
            ScriptedCharacter,
            Name::new("character"),
        ));
    }
}

/// The root of the [`MotionScene`]'s character.
#[derive(Component, Clone, Copy, Debug)]
pub struct ScriptedCharacter;

/// The character's clip, started on each animation player its scene spawns.
#[derive(Resource, Clone)]
struct CharacterClip {
    graph: Handle<AnimationGraph>,
    node: AnimationNodeIndex,
}

/// A prop of the [`MotionScene`] resource, by its index.
#[derive(Component, Clone, Copy, Debug)]
pub struct ScriptedProp(pub usize);

/// A camera the script swings ([`MotionScene::camera_at`]).
#[derive(Component, Clone, Copy, Debug)]
pub struct ScriptedCamera;

/// The script's frame: advanced by one each frame while `running`; the props and scripted cameras take
/// their poses of it in `Update`.
#[derive(Resource, Clone, Copy, Debug)]
pub struct MotionScript {
    /// The frame the scene shows (set before the first update to start elsewhere than 0).
    pub frame: i32,
    /// Whether the frame advances.
    pub running: bool,
}

/// Moves the [`ScriptedProp`]s and [`ScriptedCamera`]s of the [`MotionScene`] resource by the
/// [`MotionScript`] resource, every frame.
pub struct MotionScriptPlugin;

impl Plugin for MotionScriptPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Update, (start_character_clip, play_script).chain());
    }
}

fn start_character_clip(
    mut commands: Commands,
    clip: Option<Res<CharacterClip>>,
    mut players: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
) {
    let Some(clip) = clip else { return };
    for (entity, mut player) in &mut players {
        player.play(clip.node).pause();
        commands.entity(entity).insert(AnimationGraphHandle(clip.graph.clone()));
    }
}

#[allow(clippy::type_complexity)]
fn play_script(
    scene: Option<Res<MotionScene>>,
    script: Option<ResMut<MotionScript>>,
    clip: Option<Res<CharacterClip>>,
    mut props: Query<(&ScriptedProp, &mut Transform), (Without<ScriptedCamera>, Without<ScriptedCharacter>)>,
    mut cameras: Query<&mut Transform, (With<ScriptedCamera>, Without<ScriptedCharacter>)>,
    mut characters: Query<&mut Transform, With<ScriptedCharacter>>,
    mut players: Query<&mut AnimationPlayer>,
) {
    let (Some(scene), Some(mut script)) = (scene, script) else { return };
    if script.running {
        script.frame += 1;
    }
    let frame = script.frame;
    for (prop, mut t) in &mut props {
        if let Some(p) = scene.props.get(prop.0) {
            let pose = p.path.pose(frame);
            if *t != pose {
                *t = pose;
            }
        }
    }
    let pose = scene.camera_at(frame);
    for mut t in &mut cameras {
        if *t != pose {
            *t = pose;
        }
    }
    if let (Some(c), Some(clip)) = (&scene.character, clip) {
        let root = c.root_at(frame);
        for mut t in &mut characters {
            if *t != root {
                *t = root;
            }
        }
        // Sought every frame (paused): the pose is the script's, whatever the app's clock.
        let time = c.time_at(frame);
        for mut player in &mut players {
            if let Some(active) = player.animation_mut(clip.node)
                && active.seek_time() != time
            {
                active.seek_to(time);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shuttle_passes_its_centre_at_frame_zero_and_turns_at_its_ends() {
        let path = PropPath::Shuttle {
            center: Vec3::new(1.0, 0.5, 0.0),
            direction: Vec3::X,
            half_length: 2.0,
            speed: 0.1,
            roll_radius: Some(0.5),
        };
        assert!(path.pose(0).translation.distance(Vec3::new(1.0, 0.5, 0.0)) < 1e-6);
        assert!((path.pose(1).translation.x - 1.1).abs() < 1e-5);
        // 20 frames to an end, 20 back.
        assert!((path.pose(20).translation.x - 3.0).abs() < 1e-4);
        assert!((path.pose(30).translation.x - 2.0).abs() < 1e-4);
        assert!((path.pose(-20).translation.x + 1.0).abs() < 1e-4);
        // Rolling: 0.1 m a frame on a ball of radius 0.5 turns it 0.2 rad a frame, forward about -z.
        let turn = path.pose(1).rotation * path.pose(0).rotation.inverse();
        let (axis, angle) = turn.to_axis_angle();
        assert!((angle - 0.2).abs() < 1e-4 && axis.dot(-Vec3::Z) > 0.999, "{axis} {angle}");
        // The contact point (straight below the centre) stays where it was to second order (sliding, it would
        // move 0.1).
        let contact =
            |f: i32| path.pose(f).transform_point(path.pose(0).rotation.inverse() * Vec3::new(0.0, -0.5, 0.0));
        assert!(contact(0).distance(contact(1)) < 0.011, "{} {}", contact(0), contact(1));
    }

    #[test]
    fn the_scenes_rest_on_the_floor_and_the_reference_moves_with_the_props() {
        for name in MOTION_SCENES {
            let scene = MotionScene::named(name, Marker::Dynamic).unwrap();
            for frame in [-16, 0, 15] {
                // (Bevy's ssao example bobs its sphere between the cubes, dipping into the lower one.)
                for b in scene
                    .props
                    .iter()
                    .filter(|_| name != "bob")
                    .filter_map(|p| p.mesh.transformed(p.path.pose(frame).compute_affine()).bounds())
                {
                    assert!(b.0.y.abs() < 0.01, "{name}: a prop floats or sinks: {b:?}");
                }
            }
            let moving = scene.props.iter().any(|p| p.path.moves());
            assert_eq!(scene.triangles_at(0) != scene.triangles_at(5), moving, "{name}");
        }
        // The bob: at frame 0 through the origin going up, 0.7 m up a quarter period later (1.7 s x pi / 2).
        let bob = &MotionScene::named("bob", Marker::Dynamic).unwrap().props[0].path;
        assert!(bob.pose(0).translation.length() < 1e-6 && bob.pose(1).translation.y > 0.0);
        let quarter = (1.7 * SCRIPT_FPS * TAU / 4.0).round() as i32;
        assert!((bob.pose(quarter).translation.y - 0.7).abs() < 1e-3, "{}", bob.pose(quarter).translation);
        assert!(MotionScene::named("nothing", Marker::Static).is_none());
    }

    #[test]
    fn the_camera_swings_at_its_speed_through_its_start_pose() {
        let mut scene = MotionScene::named("contacts", Marker::Static).unwrap();
        assert_eq!(scene.camera_at(17), scene.camera);
        scene.camera_speed = 0.5;
        assert!(scene.camera_at(0).translation.distance(scene.camera.translation) < 1e-5);
        let turn = scene.camera_at(1).rotation.angle_between(scene.camera_at(0).rotation).to_degrees();
        assert!((turn - 0.5).abs() < 0.01, "{turn}");
    }
}
