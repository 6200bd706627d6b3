//! The exact triangle/box overlap test (separating axes, after Akenine-Moeller 2001).
//!
//! Boxes are closed: a triangle that only touches a cell's face, edge or corner overlaps it. The CPU runs the
//! test in `f64` on the `f32` grid-space vertices, so for the inputs it sees the result is exact except in
//! ties far below a cell's precision; the WGSL twin (`triangle_box_overlap` in `voxelize_common.wgsl`) runs
//! the same axes in `f32`.

use glam::{DVec3, IVec3, UVec3, Vec3};

/// A triangle prepared for repeated overlap tests against unit cells of the grid.
#[derive(Debug, Clone, Copy)]
pub struct OverlapTriangle {
    v: [DVec3; 3],
    edges: [DVec3; 3],
    normal: DVec3,
}

impl OverlapTriangle {
    /// Prepares a grid-space triangle.
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        let v = [v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3()];
        let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
        Self { v, edges, normal: edges[0].cross(edges[1]) }
    }

    /// The triangle's (unnormalized) normal `(v1 - v0) x (v2 - v1)`.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The vertices in `f64`.
    pub fn vertices(&self) -> [DVec3; 3] {
        self.v
    }

    /// Whether the triangle overlaps the closed cell `[c, c+1]^3` (WGSL: `triangle_box_overlap`).
    #[inline]
    pub fn overlaps_cell(&self, cell: UVec3) -> bool {
        self.overlaps_lattice_cell(cell.as_ivec3())
    }

    /// [`Self::overlaps_cell`] for a cell of the lattice that may lie below the grid's origin (a cascade's).
    #[inline]
    pub fn overlaps_lattice_cell(&self, cell: IVec3) -> bool {
        let center = cell.as_dvec3() + DVec3::splat(0.5);
        triangle_box_overlap(&self.v, &self.edges, self.normal, center, 0.5)
    }

    /// How the triangle meets the closed cell `[c, c+1]^3`: not at all, only grazing it (touching its
    /// boundary or entering less than [`GRAZE_DEPTH`] deep), or cutting through it.
    pub fn overlap_kind(&self, cell: UVec3) -> OverlapKind {
        let center = cell.as_dvec3() + DVec3::splat(0.5);
        if !triangle_box_overlap(&self.v, &self.edges, self.normal, center, 0.5) {
            OverlapKind::None
        } else if triangle_box_overlap(&self.v, &self.edges, self.normal, center, 0.5 - GRAZE_DEPTH) {
            OverlapKind::Cut
        } else {
            OverlapKind::Graze
        }
    }
}

/// How deep (in cells) a surface must enter a cell for [`OverlapKind::Cut`].
pub const GRAZE_DEPTH: f64 = 1.0e-3;

/// How a triangle meets a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverlapKind {
    /// Disjoint.
    None,
    /// The triangle touches the cell's boundary or enters it by less than [`GRAZE_DEPTH`]: a triangle lying
    /// in a cell face, a plane through a cell edge, or one that misses an edge by a rounding error. A point
    /// inside a sub-triangle practically never lands in such a cell.
    Graze,
    /// The triangle passes through the cell shrunk by [`GRAZE_DEPTH`] on every side.
    Cut,
}

/// Separating-axis test of a triangle against the closed box `center +- half` (all axes equal). `edges` are
/// `v1 - v0, v2 - v1, v0 - v2` and `normal` their cross product, precomputed by the caller. A separating axis
/// needs a strict gap, so touching counts as overlap.
#[inline]
pub fn triangle_box_overlap(v: &[DVec3; 3], edges: &[DVec3; 3], normal: DVec3, center: DVec3, half: f64) -> bool {
    let a = v[0] - center;
    let b = v[1] - center;
    let c = v[2] - center;
    // 1. The box's face normals: the triangle's bounding box against the box.
    let lo = a.min(b).min(c);
    let hi = a.max(b).max(c);
    if lo.x > half || lo.y > half || lo.z > half || hi.x < -half || hi.y < -half || hi.z < -half {
        return false;
    }
    // 2. The triangle's normal: the plane against the box.
    let d = normal.dot(a);
    let r = half * (normal.x.abs() + normal.y.abs() + normal.z.abs());
    if d > r || d < -r {
        return false;
    }
    // 3. The nine cross products of the box axes with the triangle's edges.
    for e in edges {
        for axis in [DVec3::new(0.0, -e.z, e.y), DVec3::new(e.z, 0.0, -e.x), DVec3::new(-e.y, e.x, 0.0)] {
            let pa = axis.dot(a);
            let pb = axis.dot(b);
            let pc = axis.dot(c);
            let r = half * (axis.x.abs() + axis.y.abs() + axis.z.abs());
            if pa.min(pb).min(pc) > r || pa.max(pb).max(pc) < -r {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> OverlapTriangle {
        OverlapTriangle::new(Vec3::from(a), Vec3::from(b), Vec3::from(c))
    }

    #[test]
    fn inside_touching_and_separated() {
        let inside = tri([0.2, 0.2, 0.5], [0.8, 0.2, 0.5], [0.2, 0.8, 0.5]);
        assert!(inside.overlaps_cell(UVec3::ZERO));
        assert!(!inside.overlaps_cell(UVec3::new(1, 0, 0)));
        // A triangle in the plane z = 1 touches both cell layers z = 0 and z = 1 (closed boxes).
        let on_face = tri([0.2, 0.2, 1.0], [0.8, 0.2, 1.0], [0.2, 0.8, 1.0]);
        assert!(on_face.overlaps_cell(UVec3::new(0, 0, 0)));
        assert!(on_face.overlaps_cell(UVec3::new(0, 0, 1)));
        assert!(!on_face.overlaps_cell(UVec3::new(0, 0, 2)));
        assert_eq!(on_face.overlap_kind(UVec3::new(0, 0, 0)), OverlapKind::Graze);
        assert_eq!(on_face.overlap_kind(UVec3::new(0, 0, 1)), OverlapKind::Graze);
        assert_eq!(inside.overlap_kind(UVec3::ZERO), OverlapKind::Cut);
        assert_eq!(inside.overlap_kind(UVec3::new(1, 0, 0)), OverlapKind::None);
        // A plane through a cell edge: interior for the cells it cuts, contact for the one it grazes.
        let through_edge = tri([0.0, 0.0, 0.0], [8.0, 0.0, 0.0], [0.0, 6.0, 4.0]); // y = 1.5 z
        assert_eq!(through_edge.overlap_kind(UVec3::new(1, 2, 1)), OverlapKind::Cut);
        assert_eq!(through_edge.overlap_kind(UVec3::new(1, 2, 2)), OverlapKind::Graze);
        assert_eq!(through_edge.overlap_kind(UVec3::new(1, 3, 2)), OverlapKind::Cut);
    }

    #[test]
    fn the_cross_axes_separate_what_the_bounding_boxes_and_the_plane_cannot() {
        // In the plane z = 0.5 (which cuts the cell) with a bounding box covering the cell's xy square, but
        // lying beyond the diagonal x + y = 2.2 while the cell reaches x + y = 2 only: an edge axis separates.
        let t = tri([2.2, 0.0, 0.5], [0.0, 2.2, 0.5], [2.2, 2.2, 0.5]);
        assert!(!t.overlaps_cell(UVec3::ZERO));
        assert!(t.overlaps_cell(UVec3::new(1, 1, 0)));
        // The same triangle moved onto the diagonal x + y = 2 touches the cell's vertical edge: overlap.
        let t = tri([2.0, 0.0, 0.5], [0.0, 2.0, 0.5], [2.0, 2.0, 0.5]);
        assert!(t.overlaps_cell(UVec3::ZERO));
        // A plane x + y + z = 3.2 misses the cell (max 3) although the bounding boxes overlap.
        let t = tri([3.2, 0.0, 0.0], [0.0, 3.2, 0.0], [0.0, 0.0, 3.2]);
        assert!(!t.overlaps_cell(UVec3::ZERO));
        assert!(t.overlaps_cell(UVec3::new(1, 1, 0)));
    }
}
