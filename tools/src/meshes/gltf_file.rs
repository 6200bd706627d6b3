//! glTF 2.0 (`.gltf` with external or embedded buffers, and `.glb`) read as a [`TriangleMesh`]: every mesh
//! primitive of the scene Bevy would show (the default scene, else the first), with node transforms
//! applied. Triangle strips and fans are unrolled into lists; point and line primitives are skipped with a
//! warning. Skinned meshes are skinned by their joints' transforms and morphed meshes take their weights:
//! the nodes' own ([`read_gltf`]), or an animation clip's at a time ([`read_gltf_posed`]).
//!
//! Buffers are read here, not by `gltf::import_buffers`, whose limits are not this reader's. In gltf
//! 1.4.1's `src/import.rs`, a relative URI is percent-decoded with `urlencoding::decode(uri).unwrap()` (a
//! panic on an escape that is not UTF-8), a `file://` URI is read from anywhere on disk, and a file is read
//! whole whatever the buffer's declared length; its `import` feature also brings base64 0.13 beside the
//! 0.22 used here. Here a buffer file must lie in the glTF's folder and is read up to its declared length.

use super::gltf_animation;
use base64::Engine;
use bevy_hao::cpu::{TriangleMesh, VertexSkin, morphed_mesh, skinned_mesh};
use glam::{Affine3A, Mat4, Quat, Vec3};
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::Path;

/// Most node instances (a node reached along one path from a scene root) a file may expand to.
pub const MAX_NODE_INSTANCES: usize = 1 << 16;
/// Deepest node hierarchy followed.
pub const MAX_NODE_DEPTH: usize = 256;
/// Most vertices (or indices) one accessor may declare.
pub const MAX_ACCESSOR_COUNT: usize = 1 << 26;

/// A buffer's `uri` as a file inside `dir`: relative, with no `..` or root component (a file may not read
/// outside its own folder).
fn buffer_file(dir: &Path, uri: &str) -> Result<std::path::PathBuf, String> {
    let decoded = uri.replace("%20", " ");
    let rel = Path::new(&decoded);
    if uri.contains("://")
        || rel.components().any(|c| !matches!(c, std::path::Component::Normal(_) | std::path::Component::CurDir))
    {
        return Err(format!("buffer URI {uri:?} points outside the glTF's folder; refused"));
    }
    Ok(dir.join(rel))
}

/// A mesh as messages name it: its index, and its name if it has one.
fn mesh_label(m: &gltf::Mesh) -> String {
    match m.name() {
        Some(name) => format!("{} ({name:?})", m.index()),
        None => m.index().to_string(),
    }
}

/// Adds a warning unless the same one is already there: a file whose node graph reaches one broken mesh
/// 65,536 times gets one line, not 65,536.
fn push_once(warnings: &mut Vec<String>, warning: String) {
    if !warnings.contains(&warning) {
        warnings.push(warning);
    }
}

/// Parses and validates a glTF document. The `gltf` crate's own validation reads a primitive's POSITION
/// accessor by an unchecked index (a panic on a file naming an accessor that does not exist), so every
/// attribute index is checked before it runs.
fn parse_document(bytes: &[u8]) -> Result<gltf::Gltf, String> {
    use gltf::json::validation::Validate;
    let gltf = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())?;
    let root = gltf.document.as_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.values().find(|i| i.value() >= root.accessors.len()) {
                return Err(format!(
                    "mesh {m}, primitive {p} names accessor {} of {}",
                    index.value(),
                    root.accessors.len()
                ));
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| errors.push(format!("{}: {error}", path())));
    if let Some(first) = errors.first() {
        return Err(format!("invalid glTF ({} errors; the first: {first})", errors.len()));
    }
    Ok(gltf)
}

/// Reads a glTF or GLB file. Returns the mesh and any warnings.
pub fn load_gltf(path: &Path) -> Result<(TriangleMesh, Vec<String>), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    read_gltf(&bytes, path.parent().unwrap_or(Path::new("."))).map_err(|e| format!("{}: {e}", path.display()))
}

/// A parsed and validated document with its buffers' bytes.
struct Loaded {
    gltf: gltf::Gltf,
    buffers: Vec<Vec<u8>>,
    buffer_bytes: u64,
}

/// Parses a document and reads its buffers (external ones only from `dir`).
fn load_document(bytes: &[u8], dir: &Path) -> Result<Loaded, String> {
    let gltf = parse_document(bytes)?;
    // The bytes every accessor must fit in: no accessor (sparse ones included) may declare more data than
    // the file's buffers hold, so that a count in a tiny file cannot make a huge allocation.
    let mut buffer_bytes = 0u64;
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or("GLB without a BIN chunk")?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let (_, b64) = rest
                        .split_once(";base64,")
                        .ok_or_else(|| "unsupported data URI (base64 expected)".to_string())?;
                    base64::engine::general_purpose::STANDARD
                        .decode(b64)
                        .map_err(|e| format!("bad base64 buffer: {e}"))?
                } else {
                    // At most the declared length is read (a path like /dev/zero cannot get here, and a
                    // big file is not read whole).
                    use std::io::Read;
                    let file = buffer_file(dir, uri)?;
                    let mut data = Vec::new();
                    std::fs::File::open(&file)
                        .and_then(|f| f.take(buffer.length() as u64).read_to_end(&mut data))
                        .map_err(|e| format!("{}: {e}", file.display()))?;
                    data
                }
            }
        };
        buffer_bytes += data.len() as u64;
        buffers.push(data);
    }
    Ok(Loaded { gltf, buffers, buffer_bytes })
}

/// Reads a glTF or GLB file from its bytes; external buffers are looked up in `dir` (and nowhere else).
/// Skinned meshes are posed by their joints' own transforms (as Bevy draws a glTF that is not animated).
/// Returns the mesh and any warnings.
pub fn read_gltf(bytes: &[u8], dir: &Path) -> Result<(TriangleMesh, Vec<String>), String> {
    read_gltf_posed(bytes, dir, None)
}

/// Reads a glTF file posed by animation clip `pose.0` at `pose.1` seconds (see [`gltf_animation`]): the
/// animated node transforms replace the nodes' own, and skinned meshes are skinned by the joints' resulting
/// world transforms times their inverse bind matrices, as Bevy's `AnimationPlayer` and skinning do.
pub fn read_gltf_posed(
    bytes: &[u8],
    dir: &Path,
    pose: Option<(usize, f32)>,
) -> Result<(TriangleMesh, Vec<String>), String> {
    let Loaded { gltf, buffers, buffer_bytes } = load_document(bytes, dir)?;
    let mut mesh = TriangleMesh::default();
    let mut warnings = Vec::new();
    let poses = match pose {
        Some((animation, time)) => {
            gltf_animation::sample_animation(&gltf.document, &buffers, animation, time, &mut warnings)
        }
        None => Default::default(),
    };
    // Each node's world transform (its first instance's), for the joints of skins.
    let mut globals: HashMap<usize, Affine3A> = HashMap::new();
    let mut deferred: Vec<(gltf::Node, Affine3A)> = Vec::new();
    let weights_of = |node: &gltf::Node| poses.get(&node.index()).and_then(|p| p.weights.as_deref());
    // The scene Bevy would show: the default one, else the first.
    let scenes: Vec<_> = gltf.default_scene().or_else(|| gltf.scenes().next()).into_iter().collect();
    // Each entry carries its ancestors, so that a node that is its own ancestor (a cycle) is refused; the
    // depth and the number of instances are bounded (a DAG can expand to exponentially many paths).
    let mut stack: Vec<(gltf::Node, Affine3A, Vec<usize>)> =
        scenes.iter().flat_map(|s| s.nodes().map(|n| (n, Affine3A::IDENTITY, Vec::new()))).collect();
    let mut instances = 0usize;
    while let Some((node, parent, ancestors)) = stack.pop() {
        if ancestors.contains(&node.index()) {
            push_once(
                &mut warnings,
                format!("node {} is its own ancestor (a cycle); its subtree is skipped", node.index()),
            );
            continue;
        }
        if ancestors.len() >= MAX_NODE_DEPTH {
            push_once(
                &mut warnings,
                format!("the node hierarchy is deeper than {MAX_NODE_DEPTH}; deeper nodes are skipped"),
            );
            continue;
        }
        instances += 1;
        if instances > MAX_NODE_INSTANCES {
            return Err(format!("the scene expands to more than {MAX_NODE_INSTANCES} node instances"));
        }
        let local = match poses.get(&node.index()) {
            // Animated: the clip's values over the node's own, as a scale-rotation-translation (Bevy's
            // `Transform`).
            Some(p) => {
                let (t, r, s) = node.transform().decomposed();
                Affine3A::from_scale_rotation_translation(
                    p.scale.unwrap_or(Vec3::from(s)),
                    p.rotation.unwrap_or(Quat::from_array(r)),
                    p.translation.unwrap_or(Vec3::from(t)),
                )
            }
            None => Affine3A::from_mat4(Mat4::from_cols_array_2d(&node.transform().matrix())),
        };
        let world = parent * local;
        globals.entry(node.index()).or_insert(world);
        if node.mesh().is_some() {
            if node.skin().is_some() {
                deferred.push((node.clone(), world));
            } else {
                emit_node(&node, world, &globals, &buffers, buffer_bytes, weights_of(&node), &mut mesh, &mut warnings)?;
            }
        }
        let mut path = ancestors;
        path.push(node.index());
        stack.extend(node.children().map(|c| (c, world, path.clone())));
    }
    // Skinned nodes last: their joints' world transforms are all known once the walk is done.
    for (node, world) in deferred {
        emit_node(&node, world, &globals, &buffers, buffer_bytes, weights_of(&node), &mut mesh, &mut warnings)?;
    }
    Ok((mesh, warnings))
}

/// Appends the triangles of a node's mesh at `world` (or, for a skinned node, skinned by its joints' world
/// transforms in `globals`).
#[allow(clippy::too_many_arguments)]
fn emit_node(
    node: &gltf::Node,
    world: Affine3A,
    globals: &HashMap<usize, Affine3A>,
    buffers: &[Vec<u8>],
    buffer_bytes: u64,
    morph_weights: Option<&[f32]>,
    mesh: &mut TriangleMesh,
    warnings: &mut Vec<String>,
) -> Result<(), String> {
    let Some(m) = node.mesh() else { return Ok(()) };
    // A skinned node: each joint's world transform times its inverse bind matrix (the node's own
    // transform is not applied, as the spec and Bevy have it).
    if let Some(ibm) = node.skin().and_then(|s| s.inverse_bind_matrices())
        && !gltf_animation::accessor_fits(&ibm, buffers)
    {
        return Err(format!("skin {} declares more inverse bind matrices than the file holds", ibm.index()));
    }
    let joint_matrices: Option<Vec<Mat4>> = node.skin().map(|skin| {
        let reader = skin.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
        let inverse: Vec<Mat4> = reader
            .read_inverse_bind_matrices()
            .map(|m| m.map(|c| Mat4::from_cols_array_2d(&c)).collect())
            .unwrap_or_default();
        skin.joints()
            .enumerate()
            .map(|(j, joint)| {
                let g = globals.get(&joint.index()).copied().unwrap_or(Affine3A::IDENTITY);
                g * inverse.get(j).copied().unwrap_or(Mat4::IDENTITY)
            })
            .collect()
    });
    {
        for prim in m.primitives() {
            // Every accessor the primitive reads: attributes, indices, morph-target positions.
            let accessors = || {
                prim.attributes()
                    .map(|(_, a)| a)
                    .chain(prim.indices())
                    .chain(prim.morph_targets().filter_map(|t| t.positions()))
            };
            if let Some(count) = accessors().map(|a| a.count()).find(|&c| c > MAX_ACCESSOR_COUNT) {
                return Err(format!(
                    "mesh {} has an accessor of {count} elements, over the limit of {MAX_ACCESSOR_COUNT}",
                    mesh_label(&m)
                ));
            }
            let declared = accessors().map(|a| a.count() as u64 * a.size() as u64).max().unwrap_or(0);
            if declared > buffer_bytes {
                return Err(format!(
                    "mesh {} has an accessor of {declared} bytes, but the file's buffers hold only {buffer_bytes}",
                    mesh_label(&m)
                ));
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
            let Some(positions) = reader.read_positions() else {
                push_once(
                    warnings,
                    format!(
                        "a primitive of mesh {} has no positions, or its position accessor does not fit its buffer; \
                     skipped",
                        mesh_label(&m)
                    ),
                );
                continue;
            };
            let mut positions: Vec<Vec3> = positions.map(Vec3::from).collect();
            // Morph targets, weighted by the clip's weights for this node or else the mesh's own (as Bevy's
            // glTF loader starts them), before skinning.
            let targets: Vec<Vec<Vec3>> = reader
                .read_morph_targets()
                .map(|(p, _, _)| p.map(|p| p.map(Vec3::from).collect()).unwrap_or_default())
                .collect();
            // (Bevy's loader starts from the mesh's weights and ignores a node's own `weights`; so does this.)
            let weights: &[f32] = morph_weights.or(m.weights()).unwrap_or(&[]);
            if !targets.is_empty() && weights.iter().any(|w| *w != 0.0) {
                positions = morphed_mesh(&TriangleMesh::new(positions, Vec::new()), &targets, weights).positions;
            }
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
                    push_once(
                        warnings,
                        format!("a {other:?} primitive of mesh {} skipped (not triangles)", mesh_label(&m)),
                    );
                    continue;
                }
            };
            let skin = joint_matrices.as_ref().and_then(|matrices| {
                let joints = reader.read_joints(0)?.into_u16().collect::<Vec<_>>();
                let weights = reader.read_weights(0)?.into_f32().collect::<Vec<_>>();
                Some((VertexSkin { joints, weights }, matrices))
            });
            match skin {
                Some((skin, matrices)) => {
                    let posed = skinned_mesh(&TriangleMesh::new(positions, triangles), &skin, matrices);
                    mesh.append(&posed, Affine3A::IDENTITY);
                }
                None => {
                    if joint_matrices.is_some() {
                        push_once(
                            warnings,
                            format!(
                                "a primitive of skinned mesh {} has no JOINTS_0/WEIGHTS_0; placed unskinned",
                                mesh_label(&m)
                            ),
                        );
                    }
                    mesh.append(&TriangleMesh::new(positions, triangles), world);
                }
            }
        }
    }
    Ok(())
}

/// The index of the scene [`read_gltf`] reads: the file's default scene, else the first (`None`: no scene).
pub fn gltf_scene_index(path: &Path) -> Result<Option<usize>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let gltf = parse_document(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(gltf.default_scene().or_else(|| gltf.scenes().next()).map(|s| s.index()))
}

/// The animation clips of a glTF file.
pub fn gltf_animations(path: &Path) -> Result<Vec<gltf_animation::AnimationInfo>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let loaded = load_document(&bytes, path.parent().unwrap_or(Path::new(".")))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(gltf_animation::animation_infos(&loaded.gltf.document, &loaded.buffers))
}

/// Reads a glTF file posed by the clip named (or numbered) `animation` at `time` seconds. Returns the mesh,
/// the clip's index, and any warnings.
pub fn load_gltf_posed(path: &Path, animation: &str, time: f32) -> Result<(TriangleMesh, usize, Vec<String>), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let loaded = load_document(&bytes, dir).map_err(|e| format!("{}: {e}", path.display()))?;
    let index = gltf_animation::find_animation(&loaded.gltf.document, animation)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let (mesh, warnings) =
        read_gltf_posed(&bytes, dir, Some((index, time))).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((mesh, index, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use base64::Engine;

    /// A glTF document with one triangle's positions in a buffer at `uri` (a data URI if `None`), and the
    /// given nodes and scene roots.
    fn document(uri: Option<&str>, nodes: &str, roots: &str, count: usize) -> String {
        let bytes: Vec<u8> =
            [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|f| f.to_le_bytes()).collect();
        let uri = uri.map(str::to_string).unwrap_or_else(|| {
            format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes))
        });
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":{roots}}}],"nodes":{nodes},
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}}],"buffers":[{{"uri":"{uri}","byteLength":36}}]}}"#
        )
    }

    fn load(doc: &str, name: &str) -> Result<(TriangleMesh, Vec<String>), String> {
        let dir = std::env::temp_dir().join(format!("bevy_hao_gltf_{}_{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("scene.gltf");
        std::fs::write(&path, doc).unwrap();
        load_gltf(&path)
    }

    #[test]
    fn hostile_gltf_files_end_with_an_error_or_a_warning() {
        // A good file: one triangle.
        let (m, w) = load(&document(None, r#"[{"mesh":0}]"#, "[0]", 3), "good").unwrap();
        assert_eq!((m.triangle_count(), w.len()), (1, 0));
        // A node that is its own child, and a two-node cycle: skipped with a warning, no hang.
        let (m, w) = load(&document(None, r#"[{"mesh":0,"children":[0]}]"#, "[0]", 3), "self").unwrap();
        assert_eq!(m.triangle_count(), 1);
        assert!(w.iter().any(|w| w.contains("cycle")), "{w:?}");
        let (_, w) =
            load(&document(None, r#"[{"mesh":0,"children":[1]},{"children":[0]}]"#, "[0]", 3), "cycle").unwrap();
        assert!(w.iter().any(|w| w.contains("cycle")), "{w:?}");
        // A DAG of 40 levels with two edges each: 2^40 paths, refused at the instance limit.
        let nodes: Vec<String> = (0..40).map(|k| format!(r#"{{"mesh":0,"children":[{},{}]}}"#, k + 1, k + 1)).collect();
        let nodes = format!("[{},{{\"mesh\":0}}]", nodes.join(","));
        let e = load(&document(None, &nodes, "[0]", 3), "dag").unwrap_err();
        assert!(e.contains("node instances"), "{e}");
        // Buffers outside the file's folder are refused; none is read.
        for (k, uri) in ["../secret.bin", "/dev/zero", "sub/../../x.bin", "file:///etc/passwd"].iter().enumerate() {
            let e = load(&document(Some(uri), r#"[{"mesh":0}]"#, "[0]", 3), &format!("uri{k}")).unwrap_err();
            assert!(e.contains("outside"), "{uri}: {e}");
        }
        // An accessor that claims more than the file's buffers hold, or an absurd count: an error that says so.
        let e = load(&document(None, r#"[{"mesh":0}]"#, "[0]", 30), "short").unwrap_err();
        assert!(e.contains("buffers hold only 36"), "{e}");
        assert!(load(&document(None, r#"[{"mesh":0}]"#, "[0]", 2_000_000_000), "huge").is_err());
    }

    /// A two-joint skin with an animated bone, written in code: posed by the clip, the upper triangle turns
    /// about the bone as `cpu::skinning` skins it, the lower one stays.
    #[test]
    fn a_posed_skinned_gltf_matches_the_skinning_twin() {
        use glam::{Quat, UVec4, Vec4};
        let positions =
            [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 3.0, 0.0], [1.0, 3.0, 0.0], [0.0, 4.0, 0.0]];
        let joints: [[u16; 4]; 6] =
            [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]];
        let weights = [[1.0f32, 0.0, 0.0, 0.0]; 6];
        let ibm = [Mat4::IDENTITY, Mat4::from_translation(Vec3::new(0.0, -2.0, 0.0))];
        let times = [0.0f32, 1.0];
        let rotations = [Quat::IDENTITY, Quat::from_rotation_z(std::f32::consts::FRAC_PI_2)];
        let mut bin: Vec<u8> = Vec::new();
        let mut view = |bytes: &[u8]| {
            let offset = bin.len();
            bin.extend_from_slice(bytes);
            (offset, bytes.len())
        };
        let views = [
            view(bytemuck::cast_slice(&positions)),
            view(bytemuck::cast_slice(&joints)),
            view(bytemuck::cast_slice(&weights)),
            view(bytemuck::cast_slice(&ibm.map(|m| m.to_cols_array()))),
            view(bytemuck::cast_slice(&times)),
            view(bytemuck::cast_slice(&rotations.map(|q| q.to_array()))),
        ];
        let uri =
            format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
        let buffer_views: Vec<String> =
            views.iter().map(|(o, l)| format!(r#"{{"buffer":0,"byteOffset":{o},"byteLength":{l}}}"#)).collect();
        let doc = format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
            "nodes":[{{"mesh":0,"skin":0}},{{"children":[2]}},{{"translation":[0,2,0]}}],
            "skins":[{{"joints":[1,2],"inverseBindMatrices":3}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"JOINTS_0":1,"WEIGHTS_0":2}}}}]}}],
            "animations":[{{"name":"bend","channels":[{{"sampler":0,"target":{{"node":2,"path":"rotation"}}}}],
                "samplers":[{{"input":4,"output":5,"interpolation":"LINEAR"}}]}}],
            "accessors":[
              {{"bufferView":0,"componentType":5126,"count":6,"type":"VEC3","min":[0,0,0],"max":[1,4,0]}},
              {{"bufferView":1,"componentType":5123,"count":6,"type":"VEC4"}},
              {{"bufferView":2,"componentType":5126,"count":6,"type":"VEC4"}},
              {{"bufferView":3,"componentType":5126,"count":2,"type":"MAT4"}},
              {{"bufferView":4,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[1]}},
              {{"bufferView":5,"componentType":5126,"count":2,"type":"VEC4"}}],
            "bufferViews":[{}],"buffers":[{{"uri":"{uri}","byteLength":{}}}]}}"#,
            buffer_views.join(","),
            bin.len()
        );
        let dir = std::env::temp_dir();
        let (rest, w) = read_gltf(doc.as_bytes(), &dir).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(rest.positions, positions.map(Vec3::from).to_vec(), "at rest, the bind pose");
        let (posed, w) = read_gltf_posed(doc.as_bytes(), &dir, Some((0, 0.5))).unwrap();
        assert!(w.is_empty(), "{w:?}");
        let bone =
            Affine3A::from_rotation_translation(Quat::IDENTITY.slerp(rotations[1], 0.5), Vec3::new(0.0, 2.0, 0.0));
        let matrices = [Mat4::IDENTITY, bone * ibm[1]];
        for (v, p) in positions.iter().enumerate() {
            let j = UVec4::from_array(joints[v].map(u32::from));
            let expected =
                bevy_hao::cpu::skin_position(Vec3::from(*p), j, Vec4::from_array(weights[v]), &matrices).unwrap();
            assert!(posed.positions[v].abs_diff_eq(expected, 1e-5), "vertex {v}: {} vs {expected}", posed.positions[v]);
        }
        // Half of a quarter turn about z at (0, 2, 0): the top vertex at (0, 4) goes to (-sqrt 2, 2 + sqrt 2).
        let s = std::f32::consts::SQRT_2;
        assert!(posed.positions[5].abs_diff_eq(Vec3::new(-s, 2.0 + s, 0.0), 1e-5), "{}", posed.positions[5]);
        assert_eq!(posed.positions[0], Vec3::ZERO);
        let clips = crate::meshes::gltf_animation::animation_infos(&parse_document(doc.as_bytes()).unwrap(), &[bin]);
        assert_eq!((clips.len(), clips[0].name.as_deref(), clips[0].duration), (1, Some("bend"), 1.0));
    }

    /// A mesh with one morph target and a clip of its weight: at rest the mesh's own weight applies, posed
    /// the clip's, each as `cpu::morph_position` adds it.
    #[test]
    fn a_posed_morphed_gltf_follows_its_weights() {
        let positions = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let target = [[0.0f32, 0.0, 0.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let times = [0.0f32, 1.0];
        let weights = [0.0f32, 1.0];
        let bin: Vec<u8> = [&positions[..], &target[..]]
            .concat()
            .iter()
            .flatten()
            .chain(times.iter())
            .chain(weights.iter())
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let uri =
            format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
        let doc = format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "meshes":[{{"weights":[0.25],"primitives":[{{"attributes":{{"POSITION":0}},"targets":[{{"POSITION":1}}]}}]}}],
            "animations":[{{"channels":[{{"sampler":0,"target":{{"node":0,"path":"weights"}}}}],
                "samplers":[{{"input":2,"output":3,"interpolation":"LINEAR"}}]}}],
            "accessors":[
              {{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
              {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[2,0,0]}},
              {{"bufferView":2,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[1]}},
              {{"bufferView":3,"componentType":5126,"count":2,"type":"SCALAR"}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":36}},
              {{"buffer":0,"byteOffset":72,"byteLength":8}},{{"buffer":0,"byteOffset":80,"byteLength":8}}],
            "buffers":[{{"uri":"{uri}","byteLength":{}}}]}}"#,
            bin.len()
        );
        let dir = std::env::temp_dir();
        let (rest, w) = read_gltf(doc.as_bytes(), &dir).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(rest.positions[2], Vec3::new(0.5, 1.0, 0.0), "the mesh's own weight, 0.25");
        let (posed, w) = read_gltf_posed(doc.as_bytes(), &dir, Some((0, 0.75))).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(posed.positions[2], Vec3::new(1.5, 1.0, 0.0), "the clip's weight at 0.75 s");
        assert_eq!(&posed.positions[..2], &rest.positions[..2]);
    }

    /// An animation whose keyframe accessor is sparse, with no data behind its base and a count of two
    /// billion: skipped with a warning at once, not read as two billion zeros.
    #[test]
    fn an_animation_cannot_make_a_tiny_file_allocate() {
        let doc = document(None, r#"[{"mesh":0}]"#, "[0]", 3).replacen(
            r#""accessors":["#,
            r#""animations":[{"channels":[{"sampler":0,"target":{"node":0,"path":"translation"}}],
              "samplers":[{"input":1,"output":1}]}],
              "accessors":[{"componentType":5126,"count":2000000000,"type":"SCALAR","min":[0],"max":[1],
                "sparse":{"count":1,"indices":{"bufferView":0,"componentType":5125},"values":{"bufferView":0}}},"#,
            1,
        );
        // The position accessor is now the second: point the mesh at it.
        let doc = doc.replacen(r#""POSITION":0"#, r#""POSITION":1"#, 1).replacen(
            r#""input":1,"output":1"#,
            r#""input":0,"output":0"#,
            1,
        );
        let start = std::time::Instant::now();
        let (mesh, warnings) = read_gltf_posed(doc.as_bytes(), &std::env::temp_dir(), Some((0, 0.5))).unwrap();
        assert_eq!(mesh.triangle_count(), 1);
        assert!(warnings.iter().any(|w| w.contains("more keyframes than the file holds")), "{warnings:?}");
        let loaded = load_document(doc.as_bytes(), &std::env::temp_dir()).unwrap();
        let clips = gltf_animation::animation_infos(&loaded.gltf.document, &loaded.buffers);
        assert_eq!(clips[0].duration, 0.0);
        assert!(start.elapsed().as_secs() < 2);
    }
}
