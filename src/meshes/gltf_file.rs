//! glTF 2.0 (`.gltf` with external or embedded buffers, and `.glb`) read as a [`TriangleMesh`]: every mesh
//! primitive of the default scene (or of all scenes, if none is marked default), with node transforms
//! applied. Triangle strips and fans are unrolled into lists; point and line primitives are skipped with a
//! warning. Skinned meshes come in their bind pose.

use crate::cpu::TriangleMesh;
use base64::Engine;
use glam::{Affine3A, Mat4, Vec3};
use gltf::mesh::Mode;
use std::path::Path;

/// Reads a glTF or GLB file. Returns the mesh and any warnings.
pub fn load_gltf(path: &Path) -> Result<(TriangleMesh, Vec<String>), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or("GLB without a BIN chunk")?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let (_, b64) = rest
                        .split_once(";base64,")
                        .ok_or_else(|| format!("unsupported data URI in {}", path.display()))?;
                    base64::engine::general_purpose::STANDARD
                        .decode(b64)
                        .map_err(|e| format!("bad base64 buffer: {e}"))?
                } else {
                    let file = dir.join(uri.replace("%20", " "));
                    std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?
                }
            }
        };
        buffers.push(data);
    }
    let mut mesh = TriangleMesh::default();
    let mut warnings = Vec::new();
    let scenes: Vec<_> = match gltf.default_scene() {
        Some(s) => vec![s],
        None => gltf.scenes().collect(),
    };
    let mut stack: Vec<(gltf::Node, Affine3A)> =
        scenes.iter().flat_map(|s| s.nodes().map(|n| (n, Affine3A::IDENTITY))).collect();
    while let Some((node, parent)) = stack.pop() {
        let local = Affine3A::from_mat4(Mat4::from_cols_array_2d(&node.transform().matrix()));
        let world = parent * local;
        if let Some(m) = node.mesh() {
            for prim in m.primitives() {
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
                let Some(positions) = reader.read_positions() else {
                    warnings.push(format!("a primitive of mesh {:?} has no positions; skipped", m.name()));
                    continue;
                };
                let positions: Vec<Vec3> = positions.map(Vec3::from).collect();
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..positions.len() as u32).collect(),
                };
                let triangles: Vec<[u32; 3]> = match prim.mode() {
                    Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                    Mode::TriangleStrip => (2..indices.len())
                        .map(|k| {
                            if k % 2 == 0 {
                                [indices[k - 2], indices[k - 1], indices[k]]
                            } else {
                                [indices[k - 1], indices[k - 2], indices[k]]
                            }
                        })
                        .collect(),
                    Mode::TriangleFan => (2..indices.len()).map(|k| [indices[0], indices[k - 1], indices[k]]).collect(),
                    other => {
                        warnings.push(format!("a {other:?} primitive of mesh {:?} skipped (not triangles)", m.name()));
                        continue;
                    }
                };
                mesh.append(&TriangleMesh::new(positions, triangles), world);
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    Ok((mesh, warnings))
}
