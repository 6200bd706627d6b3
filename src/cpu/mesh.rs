//! A plain indexed triangle mesh: what the CPU voxelizers read.

use glam::{Affine3A, Vec3};

/// Positions and triangles (three indices into `positions` each). No normals or attributes: voxelization
/// needs positions only.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as index triples.
    pub triangles: Vec<[u32; 3]>,
}

/// Summary figures of a mesh, for equation 5 and reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshStats {
    /// Number of triangles.
    pub triangles: u64,
    /// Triangle sizes for the point-count estimate (the mean edge length is the paper's `l_avg`).
    pub sizes: super::tessellation::TriangleSizes,
    /// Axis-aligned bounds of the referenced vertices (`None` for an empty mesh).
    pub bounds: Option<(Vec3, Vec3)>,
}

impl TriangleMesh {
    /// A mesh from positions and triangles.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Self {
        Self { positions, triangles }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corners of triangle `t`, or `None` if `t` or one of its indices is out of range.
    #[inline]
    pub fn triangle(&self, t: usize) -> Option<[Vec3; 3]> {
        let [a, b, c] = *self.triangles.get(t)?;
        Some([*self.positions.get(a as usize)?, *self.positions.get(b as usize)?, *self.positions.get(c as usize)?])
    }

    /// Bounds of the finite vertices that triangles reference (`None` if there are none).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for t in &self.triangles {
            for &i in t {
                if let Some(p) = self.positions.get(i as usize).filter(|p| p.is_finite()) {
                    lo = lo.min(*p);
                    hi = hi.max(*p);
                }
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Triangle count, mean edge length and bounds.
    pub fn stats(&self) -> MeshStats {
        let valid =
            (0..self.triangles.len()).filter_map(|t| self.triangle(t)).filter(|v| v.iter().all(|p| p.is_finite()));
        MeshStats {
            triangles: self.triangles.len() as u64,
            sizes: super::tessellation::TriangleSizes::of(self.triangles.len() as u64, valid),
            bounds: self.bounds(),
        }
    }

    /// Appends another mesh, transformed.
    pub fn append(&mut self, other: &TriangleMesh, transform: Affine3A) {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions.iter().map(|p| transform.transform_point3(*p)));
        // An index past u32 stays invalid (u32::MAX is past any vertex list) rather than overflowing.
        self.triangles.extend(other.triangles.iter().map(|t| t.map(|i| i.saturating_add(base))));
    }

    /// A transformed copy.
    pub fn transformed(&self, transform: Affine3A) -> TriangleMesh {
        let mut out = TriangleMesh::default();
        out.append(self, transform);
        out
    }

    /// Triangles whose indices point past the vertex list.
    pub fn invalid_triangle_count(&self) -> usize {
        let n = self.positions.len() as u32;
        self.triangles.iter().filter(|t| t.iter().any(|&i| i >= n)).count()
    }
}
