//! Meshes for examples, tests and tools, with no Bevy types: the built-in shapes and the procedural
//! cathedral ([`mod@builtin`]), the scenes of diffuse global illumination with their albedo ([`gi_rooms`]),
//! and OBJ and glTF files read from disk ([`obj`], [`gltf_file`]).

pub mod builtin;
pub mod gi_rooms;
pub mod gltf_animation;
pub mod gltf_file;
pub mod obj;

pub use builtin::{BUILTIN_NAMES, CLOSED_BUILTINS, builtin, cathedral, cathedral_parts};

use bevy_hao::cpu::TriangleMesh;
use std::path::Path;

/// A mesh loaded by [`load_mesh`], with a short name for reports.
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// `builtin:NAME` or the file's stem.
    pub name: String,
    /// The triangles, in the file's units and axes (node transforms applied for glTF).
    pub mesh: TriangleMesh,
    /// Problems met while loading.
    pub warnings: Vec<String>,
    /// A linear albedo per vertex for multi-valued voxels, where the file gives one (OBJ: the materials'
    /// diffuse colours); `None`: white.
    pub albedo: Option<Vec<glam::Vec4>>,
}

/// Loads `builtin:NAME` or an `.obj`, `.gltf` or `.glb` file.
pub fn load_mesh(source: &str) -> Result<LoadedMesh, String> {
    if let Some(name) = source.strip_prefix("builtin:") {
        let mesh = builtin(name)
            .ok_or_else(|| format!("unknown built-in mesh '{name}' (known: {})", BUILTIN_NAMES.join(", ")))?;
        return Ok(LoadedMesh { name: name.to_string(), mesh, warnings: Vec::new(), albedo: None });
    }
    let path = Path::new(source);
    let name = path.file_stem().map_or_else(|| source.to_string(), |s| s.to_string_lossy().into_owned());
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let (mesh, warnings, albedo) = match ext.as_str() {
        "obj" => {
            let model = obj::ObjModel::load(path).map_err(|e| format!("{source}: {e}"))?;
            let albedo = Some(model.vertex_albedo());
            (model.to_triangle_mesh(), model.warnings, albedo)
        }
        "gltf" | "glb" => {
            let (mesh, warnings) = gltf_file::load_gltf(path)?;
            (mesh, warnings, None)
        }
        _ => return Err(format!("{source}: unknown mesh format (expected .obj, .gltf, .glb or builtin:NAME)")),
    };
    Ok(LoadedMesh { name, mesh, warnings, albedo })
}
