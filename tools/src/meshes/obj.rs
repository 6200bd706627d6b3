//! Wavefront OBJ files, read by [`tobj`]: positions, texture coordinates, normals, polygonal faces
//! (fan-triangulated), negative indices, and one group per `o`/`g` name and `usemtl` change. The `mtllib`
//! materials' diffuse colour, opacity and texture are read by [`parse_mtl`].
//!
//! MTL files are not read by `tobj::load_mtl_buf`: tobj 4.0.5 panics on a colour line with fewer than
//! three numbers (`Kd 0.5`; checked), and a material file is as hostile as any other input. [`parse_mtl`]
//! reads what a PBR material can use and skips what it cannot parse.
//!
//! A face that tobj cannot read (an index out of range, a word that is not an index) refuses the whole
//! file with tobj's message; the hand-written reader this replaces skipped such faces with a warning.

use bevy_hao::cpu::TriangleMesh;
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// An OBJ file, read.
#[derive(Debug, Clone, Default)]
pub struct ObjModel {
    /// The file's groups, in file order, each flattened for rendering.
    pub groups: Vec<ObjMeshData>,
    /// Materials from the `mtllib` files that could be read.
    pub materials: Vec<ObjMaterial>,
    /// Problems met while reading (skipped elements, material files not read).
    pub warnings: Vec<String>,
}

/// A material from an MTL file (the parts a PBR material can use).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjMaterial {
    /// Its name.
    pub name: String,
    /// `Kd`, linear RGB.
    pub diffuse: [f32; 3],
    /// `map_Kd`, resolved against the MTL file's folder.
    pub diffuse_texture: Option<PathBuf>,
    /// `d` (or `1 - Tr`).
    pub opacity: f32,
}

/// One group's triangles with one vertex per distinct corner (position, texture coordinate and normal).
#[derive(Debug, Clone, Default)]
pub struct ObjMeshData {
    /// The group's material name, when its `usemtl` names a material that was read.
    pub material: Option<String>,
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Normals, if every corner had one.
    pub normals: Option<Vec<Vec3>>,
    /// Texture coordinates (OBJ's v flipped to top-left origin), if every corner had one.
    pub uvs: Option<Vec<Vec2>>,
    /// Triangles.
    pub indices: Vec<u32>,
}

impl ObjModel {
    /// Reads an OBJ file and the MTL files it names (looked up beside it).
    pub fn load(path: &Path) -> Result<Self, String> {
        // Read lossily: a stray non-UTF-8 byte (in a comment, a name) must not reject the file.
        let text = String::from_utf8_lossy(&std::fs::read(path).map_err(|e| e.to_string())?).into_owned();
        Self::read(&text, Some(path.parent().unwrap_or(Path::new("."))))
    }

    /// Reads OBJ text without its materials (see [`Self::load`]).
    pub fn parse(text: &str) -> Result<Self, String> {
        Self::read(text, None)
    }

    /// Reads OBJ text; `mtl_dir` is where its `mtllib` files are looked up (`None`: not read).
    fn read(text: &str, mtl_dir: Option<&Path>) -> Result<Self, String> {
        let materials = RefCell::new(Vec::<ObjMaterial>::new());
        let warnings = RefCell::new(Vec::<String>::new());
        let options =
            tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
        let (models, _) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |lib| {
            let Some(dir) = mtl_dir else { return Err(tobj::LoadError::OpenFileFailed) };
            let path = dir.join(lib);
            let parsed = match std::fs::read(&path) {
                Ok(bytes) => parse_mtl(&String::from_utf8_lossy(&bytes), path.parent().unwrap_or(dir)),
                Err(e) => {
                    warnings.borrow_mut().push(format!("material library {} not read: {e}", path.display()));
                    return Err(tobj::LoadError::OpenFileFailed);
                }
            };
            // tobj numbers a library's materials from the count it already holds, as `materials` does.
            let map = parsed.iter().enumerate().map(|(i, m)| (m.name.clone(), i)).collect::<HashMap<_, _>>();
            let names = parsed.iter().map(|m| tobj::Material { name: m.name.clone(), ..Default::default() }).collect();
            materials.borrow_mut().extend(parsed);
            Ok((names, map))
        })
        .map_err(|e| format!("not a readable OBJ file: {e}"))?;

        let materials = materials.into_inner();
        let mut warnings = warnings.into_inner();
        let skipped = text.lines().filter(|l| matches!(l.split_whitespace().next(), Some("l" | "p"))).count();
        if skipped > 0 {
            warnings.push(format!("{skipped} line or point elements skipped (not triangles)"));
        }
        let groups =
            models.into_iter().map(|model| group(model.mesh, &materials)).filter(|g| !g.indices.is_empty()).collect();
        Ok(Self { groups, materials, warnings })
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.groups.iter().map(|g| g.indices.len() / 3).sum()
    }

    /// A linear albedo per vertex of [`Self::to_triangle_mesh`]: its group's material's diffuse colour
    /// (`Kd`, as the scenes give it to `StandardMaterial::base_color`; white without a material). Diffuse
    /// textures are not read.
    pub fn vertex_albedo(&self) -> Vec<glam::Vec4> {
        let mut out = Vec::new();
        for g in &self.groups {
            let m = g.material.as_ref().and_then(|name| self.materials.iter().find(|m| &m.name == name));
            let c = m.map_or(glam::Vec4::ONE, |m| glam::Vec3::from(m.diffuse).extend(1.0));
            out.extend(std::iter::repeat_n(c, g.positions.len()));
        }
        out
    }

    /// All groups' triangles in one mesh (what the voxelizers need).
    pub fn to_triangle_mesh(&self) -> TriangleMesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for g in &self.groups {
            let base = positions.len() as u32;
            positions.extend_from_slice(&g.positions);
            triangles.extend(g.indices.chunks_exact(3).map(|t| [base + t[0], base + t[1], base + t[2]]));
        }
        TriangleMesh::new(positions, triangles)
    }
}

/// A tobj mesh (single-indexed, triangulated) as a group.
fn group(mesh: tobj::Mesh, materials: &[ObjMaterial]) -> ObjMeshData {
    let vertices = mesh.positions.len() / 3;
    let vec3s = |v: &[f32]| v.chunks_exact(3).map(Vec3::from_slice).collect::<Vec<_>>();
    ObjMeshData {
        material: mesh.material_id.and_then(|i| materials.get(i)).map(|m| m.name.clone()),
        positions: vec3s(&mesh.positions),
        normals: (mesh.normals.len() == 3 * vertices).then(|| vec3s(&mesh.normals)),
        uvs: (mesh.texcoords.len() == 2 * vertices)
            .then(|| mesh.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], 1.0 - t[1])).collect()),
        indices: mesh.indices,
    }
}

/// Parses MTL text; texture paths are resolved against `dir`. Lines it cannot parse are skipped.
pub fn parse_mtl(text: &str, dir: &Path) -> Vec<ObjMaterial> {
    let mut out: Vec<ObjMaterial> = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        let Some(tag) = line.split_whitespace().next() else { continue };
        let floats: Vec<f32> = line.split_whitespace().skip(1).filter_map(|w| w.parse().ok()).collect();
        match tag {
            "newmtl" => out.push(ObjMaterial {
                name: line[6..].trim().to_string(),
                diffuse: [0.8; 3],
                diffuse_texture: None,
                opacity: 1.0,
            }),
            "Kd" if floats.len() >= 3 => {
                if let Some(m) = out.last_mut() {
                    m.diffuse = [floats[0], floats[1], floats[2]];
                }
            }
            "d" if !floats.is_empty() => {
                if let Some(m) = out.last_mut() {
                    m.opacity = floats[0];
                }
            }
            "Tr" if !floats.is_empty() => {
                if let Some(m) = out.last_mut() {
                    m.opacity = 1.0 - floats[0];
                }
            }
            "map_Kd" => {
                if let (Some(m), Some(file)) = (out.last_mut(), line.split_whitespace().last()) {
                    m.diffuse_texture = Some(dir.join(file.replace('\\', "/")));
                }
            }
            _ => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD_AND_TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                                     g quad\nusemtl a\nf 1/1/1 2/1/1 3/1/1 4/1/1\ng tri\nusemtl b\nf -4 -3 -1\nl 1 2\np 3\n";

    #[test]
    fn polygons_negative_indices_and_groups() {
        let m = ObjModel::parse(QUAD_AND_TRIANGLE).unwrap();
        assert_eq!(m.triangle_count(), 3);
        assert_eq!(m.groups.len(), 2, "one group per `g`");
        // The quad, fanned from its first corner: (0,0) (1,0) (1,1) and (0,0) (1,1) (0,1).
        let t = m.to_triangle_mesh();
        let corners = |k: usize| t.triangles[k].map(|i| t.positions[i as usize].truncate());
        assert_eq!(corners(0), [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0)]);
        assert_eq!(corners(1), [Vec2::new(0.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]);
        // -4 -3 -1: the first, second and fourth positions.
        assert_eq!(corners(2), [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)]);
        assert_eq!(m.warnings, ["2 line or point elements skipped (not triangles)"]);
        assert!(m.groups[0].normals.is_some() && m.groups[0].uvs.is_some());
        assert_eq!(m.groups[0].uvs.as_ref().unwrap()[0], Vec2::new(0.0, 1.0), "v flipped");
        assert!(m.groups[1].normals.is_none() && m.groups[1].uvs.is_none());
        assert_eq!(m.groups[0].positions.len(), 4);
    }

    #[test]
    fn bad_faces_refuse_the_file_with_a_message() {
        for bad in ["v 0 0 0\nf 1 2 9\n", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "v 0 0\nf 1 1 1\n"] {
            let e = ObjModel::parse(bad).unwrap_err();
            assert!(e.starts_with("not a readable OBJ file"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn materials_are_named_by_usemtl_and_read_beside_the_file() {
        let dir = std::env::temp_dir().join(format!("bevy_hao_obj_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("m.mtl"), "newmtl a\nKd 0.5 0.4 0.3\nmap_Kd tex\\a.png\nnewmtl b\nKd 0.5\n").unwrap();
        std::fs::write(dir.join("m.obj"), format!("mtllib m.mtl\nmtllib missing.mtl\n{QUAD_AND_TRIANGLE}")).unwrap();
        let m = ObjModel::load(&dir.join("m.obj")).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert_eq!(m.groups[0].material.as_deref(), Some("a"));
        assert_eq!(m.groups[1].material.as_deref(), Some("b"));
        assert_eq!(m.materials[0].diffuse, [0.5, 0.4, 0.3]);
        assert_eq!(m.materials[0].diffuse_texture.as_deref(), Some(dir.join("tex/a.png").as_path()));
        assert_eq!(m.materials[1].diffuse, [0.8; 3], "a short Kd line is skipped");
        assert!(m.warnings.iter().any(|w| w.contains("missing.mtl")), "{:?}", m.warnings);
    }

    #[test]
    fn mtl_colors_and_textures() {
        let mats =
            parse_mtl("newmtl stone\nKd 0.5 0.4 0.3\nmap_Kd tex\\kamen.png\nnewmtl glass\nd 0.25\n", Path::new("/m"));
        assert_eq!(mats.len(), 2);
        assert_eq!(mats[0].diffuse, [0.5, 0.4, 0.3]);
        assert_eq!(mats[0].diffuse_texture.as_deref(), Some(Path::new("/m/tex/kamen.png")));
        assert_eq!(mats[1].opacity, 0.25);
    }
}
