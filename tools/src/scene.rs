//! Scenes for the examples: the built-in meshes (the procedural cathedral by default) or an OBJ/glTF file
//! given by path, spawned as Bevy entities with materials, and the same triangles for the CPU reference.

use crate::meshes::{self, obj::ObjModel};
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_hao::cpu::TriangleMesh;
use std::path::{Path, PathBuf};

/// Where a scene comes from.
#[derive(Clone, Debug)]
pub enum SceneSource {
    /// `builtin:NAME`.
    Builtin(String),
    /// An OBJ file (materials from its MTL).
    Obj(PathBuf),
    /// A glTF or GLB file (loaded by Bevy's glTF loader, with its materials).
    Gltf(PathBuf),
}

impl SceneSource {
    /// Parses `builtin:NAME` or a path.
    pub fn parse(s: &str) -> Result<Self, String> {
        if let Some(name) = s.strip_prefix("builtin:") {
            if meshes::builtin(name).is_none() {
                return Err(format!("unknown built-in mesh {name} (known: {})", meshes::BUILTIN_NAMES.join(", ")));
            }
            return Ok(Self::Builtin(name.into()));
        }
        let path = PathBuf::from(s);
        if !path.exists() {
            return Err(format!("{s}: no such file"));
        }
        match path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).as_deref() {
            Some("obj") => Ok(Self::Obj(path)),
            Some("gltf" | "glb") => Ok(Self::Gltf(path)),
            _ => Err(format!("{s}: expected .obj, .gltf, .glb or builtin:NAME")),
        }
    }

    /// The folder the app's `AssetServer` must read from for this scene's textures, if any.
    pub fn asset_root(&self) -> Option<String> {
        match self {
            Self::Builtin(_) => None,
            Self::Obj(p) | Self::Gltf(p) => {
                Some(std::fs::canonicalize(p).ok()?.parent()?.to_string_lossy().into_owned())
            }
        }
    }

    /// The scene's triangles in world space (for the CPU reference and for framing the camera).
    pub fn triangles(&self) -> Result<TriangleMesh, String> {
        let s = match self {
            Self::Builtin(n) => format!("builtin:{n}"),
            Self::Obj(p) | Self::Gltf(p) => p.to_string_lossy().into_owned(),
        };
        Ok(meshes::load_mesh(&s)?.mesh)
    }
}

/// A Bevy mesh from triangles: flat-shaded (vertices split per face) or smooth.
pub fn bevy_mesh(mesh: &TriangleMesh, smooth: bool) -> Mesh {
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let mut m = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_indices(Indices::U32(indices));
    if smooth {
        m.compute_smooth_normals();
    } else {
        m.duplicate_vertices();
        m.compute_flat_normals();
    }
    m
}

/// The cathedral's materials, by part.
fn cathedral_material(part: &str) -> StandardMaterial {
    let (color, roughness) = match part {
        "floor" => (Color::srgb(0.62, 0.58, 0.52), 0.8),
        "columns" | "arcades" | "ribs" => (Color::srgb(0.85, 0.82, 0.76), 0.7),
        "walls" => (Color::srgb(0.80, 0.76, 0.70), 0.9),
        "vaults" | "ceilings" => (Color::srgb(0.88, 0.85, 0.80), 0.9),
        _ => (Color::srgb(0.45, 0.30, 0.20), 0.6),
    };
    StandardMaterial { base_color: color, perceptual_roughness: roughness, ..default() }
}

/// Spawns a scene (static occluders), returning the entities spawned at its root.
pub fn spawn_scene(
    source: &SceneSource,
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
    asset_server: &AssetServer,
) -> Result<Vec<Entity>, String> {
    let mut spawned = Vec::new();
    match source {
        SceneSource::Builtin(name) if name == "cathedral" => {
            for (part, mesh) in crate::meshes::cathedral_parts() {
                spawned.push(
                    commands
                        .spawn((
                            Mesh3d(meshes.add(bevy_mesh(&mesh, false))),
                            MeshMaterial3d(materials.add(cathedral_material(part))),
                            bevy_hao::StaticOccluder,
                            Name::new(part),
                        ))
                        .id(),
                );
            }
        }
        SceneSource::Builtin(name) if crate::meshes::gi_rooms::gi_parts(name).is_some() => {
            let parts = crate::meshes::gi_rooms::gi_parts(name).expect("checked in the guard");
            for (k, (albedo, mesh)) in parts.into_iter().enumerate() {
                let color = Color::linear_rgb(albedo.x, albedo.y, albedo.z);
                spawned.push(
                    commands
                        .spawn((
                            Mesh3d(meshes.add(bevy_mesh(&mesh, false))),
                            MeshMaterial3d(materials.add(StandardMaterial { base_color: color, ..default() })),
                            bevy_hao::StaticOccluder,
                            Name::new(format!("{name} part {k}")),
                        ))
                        .id(),
                );
            }
        }
        SceneSource::Builtin(name) => {
            let mesh = crate::meshes::builtin(name).expect("checked in parse");
            let smooth = matches!(name.as_str(), "sphere" | "torus");
            spawned.push(
                commands
                    .spawn((
                        Mesh3d(meshes.add(bevy_mesh(&mesh, smooth))),
                        MeshMaterial3d(
                            materials.add(StandardMaterial { base_color: Color::srgb(0.8, 0.78, 0.74), ..default() }),
                        ),
                        bevy_hao::StaticOccluder,
                        Name::new(name.clone()),
                    ))
                    .id(),
            );
        }
        SceneSource::Obj(path) => {
            let model = ObjModel::load(path).map_err(|e| format!("{}: {e}", path.display()))?;
            for w in &model.warnings {
                warn!("{}: {w}", path.display());
            }
            let dir = path.parent().unwrap_or(Path::new("."));
            for data in &model.groups {
                let mut m = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
                    .with_inserted_attribute(
                        Mesh::ATTRIBUTE_POSITION,
                        data.positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
                    )
                    .with_inserted_indices(Indices::U32(data.indices.clone()));
                match &data.normals {
                    Some(n) => m.insert_attribute(
                        Mesh::ATTRIBUTE_NORMAL,
                        n.iter().map(|v| v.normalize_or(Vec3::Y).to_array()).collect::<Vec<_>>(),
                    ),
                    None => m.compute_smooth_normals(),
                }
                if let Some(uv) = &data.uvs {
                    m.insert_attribute(Mesh::ATTRIBUTE_UV_0, uv.iter().map(|v| v.to_array()).collect::<Vec<_>>());
                }
                let material = data.material.as_ref().and_then(|name| model.materials.iter().find(|m| &m.name == name));
                let mut std = StandardMaterial { perceptual_roughness: 0.8, ..default() };
                if let Some(mat) = material {
                    std.base_color = Color::linear_rgba(mat.diffuse[0], mat.diffuse[1], mat.diffuse[2], mat.opacity);
                    if mat.opacity < 1.0 {
                        std.alpha_mode = AlphaMode::Blend;
                    }
                    if let Some(texture) = &mat.diffuse_texture
                        && data.uvs.is_some()
                        && texture.exists()
                    {
                        // The asset root is the OBJ's folder (see `SceneSource::asset_root`).
                        let relative = texture.strip_prefix(dir).unwrap_or(texture);
                        std.base_color_texture = Some(asset_server.load(relative.to_string_lossy().into_owned()));
                        std.base_color = Color::WHITE;
                    }
                } else {
                    std.base_color = Color::srgb(0.75, 0.72, 0.68);
                }
                spawned.push(
                    commands
                        .spawn((
                            Mesh3d(meshes.add(m)),
                            MeshMaterial3d(materials.add(std)),
                            bevy_hao::StaticOccluder,
                            Name::new(data.material.clone().unwrap_or_default()),
                        ))
                        .id(),
                );
            }
        }
        SceneSource::Gltf(path) => {
            let file = path.file_name().ok_or("no file name")?.to_string_lossy().into_owned();
            spawned.push(
                commands.spawn(WorldAssetRoot(asset_server.load(GltfAssetLabel::Scene(0).from_asset(file)))).id(),
            );
        }
    }
    Ok(spawned)
}

/// The examples' sun: a low, warm directional light with shadows, so that it reaches in through the
/// cathedral's windows and leaves the rest to ambient light, where AO shows.
pub fn sun() -> impl Bundle {
    (
        DirectionalLight {
            illuminance: 25_000.0,
            color: Color::srgb(1.0, 0.93, 0.8),
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(0.4, 0.55, 0.25).looking_at(Vec3::ZERO, Vec3::Y),
    )
}

/// A camera position inside a scene's bounds, looking along its longest horizontal axis: right for the
/// interiors (the cathedral, Sibenik, Sponza), and a view from outside for an object.
pub fn default_camera(bounds: (Vec3, Vec3), interior: bool) -> Transform {
    let (lo, hi) = bounds;
    let size = hi - lo;
    let center = (lo + hi) / 2.0;
    if !interior {
        let radius = size.length() / 2.0;
        return Transform::from_translation(center + Vec3::new(0.6, 0.45, 1.0).normalize() * radius * 2.0)
            .looking_at(center, Vec3::Y);
    }
    let along_x = size.x >= size.z;
    let axis = if along_x { Vec3::X } else { Vec3::Z };
    let length = if along_x { size.x } else { size.z };
    let eye = center + axis * (0.38 * length) + Vec3::Y * (lo.y + 0.22 * size.y - center.y);
    let target = center - axis * (0.3 * length) + Vec3::Y * (lo.y + 0.3 * size.y - center.y);
    Transform::from_translation(eye).looking_at(target, Vec3::Y)
}

/// A generated game-sized level around a building whose bounds are `building`: a ground `size` world
/// units square under it (its top just below the building's lowest point) and a ring of blocky buildings
/// 150 to 450 units away. The parts are world-space meshes: the level is `size` across (1 km for
/// `ao_compare --world`), far larger than any cascade.
pub fn big_world(building: (Vec3, Vec3), size: f32) -> Vec<TriangleMesh> {
    use crate::meshes::builtin::cuboid;
    let (lo, hi) = building;
    let center = (lo + hi) / 2.0;
    let half = size / 2.0;
    let ground_top = lo.y - 0.01 * (hi - lo).max_element().max(1.0);
    // The ground: a flat grid of 20-unit tiles, as a terrain is built (a plane cut into long strips
    // would cost the uniform subdivision pattern n^2 points per sliver).
    let tiles = (size / 20.0).ceil().max(1.0) as u32;
    let tile = size / tiles as f32;
    let mut ground = TriangleMesh::default();
    for i in 0..=tiles {
        for j in 0..=tiles {
            let (x, z) = (center.x - half + i as f32 * tile, center.z - half + j as f32 * tile);
            ground.positions.push(Vec3::new(x, ground_top, z));
        }
    }
    for i in 0..tiles {
        for j in 0..tiles {
            let k = |a: u32, b: u32| a * (tiles + 1) + b;
            ground.triangles.push([k(i, j), k(i, j + 1), k(i + 1, j)]);
            ground.triangles.push([k(i + 1, j), k(i, j + 1), k(i + 1, j + 1)]);
        }
    }
    let mut parts = vec![ground];
    let far = (150.0f32).min(half * 0.3);
    for k in 0..12 {
        let angle = k as f32 * 0.52 + 0.3;
        let distance = far + (k % 4) as f32 * (half - far) * 0.25;
        let (w, h) = (12.0 + (k % 3) as f32 * 8.0, 8.0 + (k % 5) as f32 * 6.0);
        let c = Vec3::new(center.x + angle.cos() * distance, ground_top, center.z + angle.sin() * distance);
        parts.push(cuboid(c - Vec3::new(w, 0.0, w) / 2.0, c + Vec3::new(w / 2.0, h, w / 2.0)));
    }
    parts
}
