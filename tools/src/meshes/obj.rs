//! A Wavefront OBJ reader: positions, texture coordinates, normals, polygonal faces (fan-triangulated),
//! negative indices, `usemtl` groups, and the `mtllib` materials' diffuse color and texture.

use bevy_hao::cpu::TriangleMesh;
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

/// One face corner: indices (0-based) into the position, texture-coordinate and normal lists.
type Corner = (u32, Option<u32>, Option<u32>);

/// An OBJ file, parsed.
#[derive(Debug, Clone, Default)]
pub struct ObjModel {
    /// The `v` lines.
    pub positions: Vec<Vec3>,
    /// The `vt` lines.
    pub uvs: Vec<Vec2>,
    /// The `vn` lines.
    pub normals: Vec<Vec3>,
    /// Faces grouped by material, in file order.
    pub groups: Vec<ObjGroup>,
    /// Materials from the `mtllib` files that could be read.
    pub materials: Vec<ObjMaterial>,
    /// Problems met while reading (skipped lines, missing material files).
    pub warnings: Vec<String>,
}

/// Triangles that share a material.
#[derive(Debug, Clone, Default)]
pub struct ObjGroup {
    /// The `usemtl` name, if any.
    pub material: Option<String>,
    /// Triangles as three corners each.
    triangles: Vec<[Corner; 3]>,
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

/// A group flattened for rendering: one vertex per distinct corner.
#[derive(Debug, Clone, Default)]
pub struct ObjMeshData {
    /// The group's material name.
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
    /// Reads an OBJ file and the MTL files it names.
    pub fn load(path: &Path) -> std::io::Result<Self> {
        // Read lossily: a stray non-UTF-8 byte (in a comment, a name) must not reject the file.
        let text = String::from_utf8_lossy(&std::fs::read(path)?).into_owned();
        let mut model = Self::parse(&text);
        let dir = path.parent().unwrap_or(Path::new("."));
        for lib in text.lines().filter_map(|l| l.trim().strip_prefix("mtllib ")) {
            let mtl_path = dir.join(lib.trim());
            match std::fs::read(&mtl_path) {
                Ok(mtl) => {
                    model.materials.extend(parse_mtl(&String::from_utf8_lossy(&mtl), mtl_path.parent().unwrap_or(dir)))
                }
                Err(e) => model.warnings.push(format!("material library {} not read: {e}", mtl_path.display())),
            }
        }
        Ok(model)
    }

    /// Parses OBJ text (materials are not loaded: see [`Self::load`]).
    pub fn parse(text: &str) -> Self {
        let mut m = Self::default();
        let mut skipped_elements = 0usize;
        let mut bad_faces = 0usize;
        m.groups.push(ObjGroup::default());
        for line in text.lines() {
            let line = line.trim();
            let mut words = line.split_whitespace();
            let Some(tag) = words.next() else { continue };
            let floats =
                |words: std::str::SplitWhitespace| words.filter_map(|w| w.parse::<f32>().ok()).collect::<Vec<_>>();
            match tag {
                "v" => {
                    let f = floats(words);
                    m.positions.push(Vec3::new(
                        *f.first().unwrap_or(&f32::NAN),
                        *f.get(1).unwrap_or(&f32::NAN),
                        *f.get(2).unwrap_or(&f32::NAN),
                    ));
                }
                "vt" => {
                    let f = floats(words);
                    m.uvs.push(Vec2::new(*f.first().unwrap_or(&0.0), *f.get(1).unwrap_or(&0.0)));
                }
                "vn" => {
                    let f = floats(words);
                    m.normals.push(Vec3::new(
                        *f.first().unwrap_or(&0.0),
                        *f.get(1).unwrap_or(&0.0),
                        *f.get(2).unwrap_or(&0.0),
                    ));
                }
                "f" => {
                    let corners: Option<Vec<Corner>> = words.map(|w| m.corner(w)).collect();
                    match corners {
                        Some(c) if c.len() >= 3 => {
                            let group = m.groups.last_mut().expect("there is always a group");
                            for k in 1..c.len() - 1 {
                                group.triangles.push([c[0], c[k], c[k + 1]]);
                            }
                        }
                        _ => bad_faces += 1,
                    }
                }
                "usemtl" => {
                    let name = line[6..].trim().to_string();
                    let last = m.groups.last_mut().expect("there is always a group");
                    if last.triangles.is_empty() {
                        last.material = Some(name);
                    } else {
                        m.groups.push(ObjGroup { material: Some(name), triangles: Vec::new() });
                    }
                }
                "l" | "p" => skipped_elements += 1,
                _ => {}
            }
        }
        m.groups.retain(|g| !g.triangles.is_empty());
        if skipped_elements > 0 {
            m.warnings.push(format!("{skipped_elements} line or point elements skipped (not triangles)"));
        }
        if bad_faces > 0 {
            m.warnings.push(format!("{bad_faces} faces skipped (fewer than 3 corners or an index out of range)"));
        }
        m
    }

    fn corner(&self, word: &str) -> Option<Corner> {
        let mut parts = word.split('/');
        let resolve = |s: Option<&str>, len: usize| -> Option<Option<u32>> {
            match s {
                None | Some("") => Some(None),
                Some(s) => {
                    let i: i64 = s.parse().ok()?;
                    let idx = if i < 0 { len as i64 + i } else { i - 1 };
                    (0..len as i64).contains(&idx).then_some(Some(idx as u32))
                }
            }
        };
        let v = resolve(parts.next(), self.positions.len())??;
        let vt = resolve(parts.next(), self.uvs.len())?;
        let vn = resolve(parts.next(), self.normals.len())?;
        Some((v, vt, vn))
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.groups.iter().map(|g| g.triangles.len()).sum()
    }

    /// All triangles on the shared position list (what the voxelizers need).
    pub fn to_triangle_mesh(&self) -> TriangleMesh {
        TriangleMesh::new(
            self.positions.clone(),
            self.groups.iter().flat_map(|g| g.triangles.iter().map(|t| t.map(|c| c.0))).collect(),
        )
    }

    /// Each group flattened for rendering (one vertex per distinct corner).
    pub fn mesh_data(&self) -> Vec<ObjMeshData> {
        self.groups
            .iter()
            .map(|g| {
                let mut map = std::collections::HashMap::new();
                let mut d = ObjMeshData { material: g.material.clone(), ..Default::default() };
                let (mut normals, mut uvs) = (Vec::new(), Vec::new());
                let (mut all_n, mut all_uv) = (true, true);
                for t in &g.triangles {
                    for c in t {
                        let index = *map.entry(*c).or_insert_with(|| {
                            d.positions.push(self.positions[c.0 as usize]);
                            match c.2 {
                                Some(n) => normals.push(self.normals[n as usize]),
                                None => all_n = false,
                            }
                            match c.1 {
                                Some(t) => uvs.push(self.uvs[t as usize] * Vec2::new(1.0, -1.0) + Vec2::Y),
                                None => all_uv = false,
                            }
                            d.positions.len() as u32 - 1
                        });
                        d.indices.push(index);
                    }
                }
                d.normals = all_n.then_some(normals);
                d.uvs = all_uv.then_some(uvs);
                d
            })
            .collect()
    }
}

/// Parses MTL text; texture paths are resolved against `dir`.
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

    #[test]
    fn polygons_negative_indices_groups_and_bad_faces() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                    usemtl a\nf 1/1/1 2/1/1 3/1/1 4/1/1\nusemtl b\nf -4 -3 -1\nf 1 2 9\nl 1 2\n";
        let m = ObjModel::parse(text);
        assert_eq!(m.triangle_count(), 3);
        assert_eq!(m.groups.len(), 2);
        assert_eq!(m.groups[0].material.as_deref(), Some("a"));
        let t = m.to_triangle_mesh();
        assert_eq!(t.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
        assert_eq!(m.warnings.len(), 2);
        let data = m.mesh_data();
        assert!(data[0].normals.is_some() && data[0].uvs.is_some());
        assert!(data[1].normals.is_none());
        assert_eq!(data[0].positions.len(), 4);
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
