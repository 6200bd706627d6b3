//! The conservative voxelizer used as ground truth: every cell that a triangle overlaps, by the exact
//! triangle/box test, and nothing else.
//!
//! It shares only the overlap test and the input checks with the point-tessellated voxelizer; cells are found
//! independently: for each triangle, the columns of its bounding box along the two minor axes of its normal
//! are walked, and in each column the cells between the heights where the triangle's plane crosses the
//! column (plus one cell of margin each way) are tested. That makes the cost proportional to the triangle's
//! area in cells, not to the volume of its bounding box.

use bevy_hao::cpu::{
    OverlapKind, OverlapTriangle, TriangleMesh, VoxelOccupancy, for_each_grid_triangle, triangle_is_degenerate,
};
use glam::{Affine3A, DVec3, IVec3, UVec3, Vec3};
use std::ops::AddAssign;

/// What a ground-truth run did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GroundTruthStats {
    /// Triangles read.
    pub triangles: u64,
    /// Triangles skipped: non-finite vertex, index out of range, or zero area (the same rule as the
    /// voxelizer's).
    pub skipped: u64,
    /// Exact overlap tests run.
    pub overlap_tests: u64,
    /// Overlaps found (a cell is counted once per triangle overlapping it).
    pub overlaps: u64,
}

impl AddAssign for GroundTruthStats {
    fn add_assign(&mut self, o: Self) {
        self.triangles += o.triangles;
        self.skipped += o.skipped;
        self.overlap_tests += o.overlap_tests;
        self.overlaps += o.overlaps;
    }
}

/// Sets in `out` every cell that a grid-space triangle overlaps, and in `cut` (if given) the cells it cuts
/// through rather than grazes ([`OverlapKind`]).
pub fn ground_truth_triangle(v: [Vec3; 3], out: &VoxelOccupancy, cut: Option<&VoxelOccupancy>) -> GroundTruthStats {
    let mut stats = GroundTruthStats { triangles: 1, ..Default::default() };
    let [v0, v1, v2] = v;
    if !(v0.is_finite() && v1.is_finite() && v2.is_finite()) || triangle_is_degenerate(v0, v1, v2) {
        stats.skipped = 1;
        return stats;
    }
    let dims = out.grid().dims;
    let tri = OverlapTriangle::new(v0, v1, v2);
    let [a, b, c] = tri.vertices();
    let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
    // Closed cells: a bound exactly on a cell face also touches the cell below it.
    let cell_lo = (lo.ceil() - DVec3::ONE).as_ivec3().max(IVec3::ZERO);
    let cell_hi = hi.floor().as_ivec3().min(dims.as_ivec3() - IVec3::ONE);
    if cell_lo.cmpgt(cell_hi).any() {
        return stats;
    }
    let normal = tri.normal();
    let w = normal.abs().max_position();
    if normal[w] == 0.0 {
        stats.skipped = 1;
        return stats;
    }
    let (u, v) = ((w + 1) % 3, (w + 2) % 3);
    let d = normal.dot(a);
    for cu in cell_lo[u]..=cell_hi[u] {
        for cv in cell_lo[v]..=cell_hi[v] {
            // The plane's height along w at the column's four corner lines.
            let mut w_lo = f64::INFINITY;
            let mut w_hi = f64::NEG_INFINITY;
            for (du, dv) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                let h = (d - normal[u] * (cu as f64 + du) - normal[v] * (cv as f64 + dv)) / normal[w];
                w_lo = w_lo.min(h);
                w_hi = w_hi.max(h);
            }
            // (`as i64` saturates for a plane nearly parallel to w; the +-1 must not overflow then.)
            let from = ((w_lo.floor() as i64).saturating_sub(1).max(cell_lo[w] as i64)) as i32;
            let to = ((w_hi.floor() as i64).saturating_add(1).min(cell_hi[w] as i64)) as i32;
            for cw in from..=to {
                let mut cell = IVec3::ZERO;
                cell[u] = cu;
                cell[v] = cv;
                cell[w] = cw;
                let cell = cell.as_uvec3();
                stats.overlap_tests += 1;
                match cut {
                    None => {
                        if tri.overlaps_cell(cell) {
                            out.set(cell);
                            stats.overlaps += 1;
                        }
                    }
                    Some(cut) => match tri.overlap_kind(cell) {
                        OverlapKind::None => {}
                        kind => {
                            out.set(cell);
                            stats.overlaps += 1;
                            if kind == OverlapKind::Cut {
                                cut.set(cell);
                            }
                        }
                    },
                }
            }
        }
    }
    stats
}

/// Conservative ground truth of a mesh into `out` (not cleared first), on all cores.
pub fn ground_truth_mesh(mesh: &TriangleMesh, grid_from_local: Affine3A, out: &VoxelOccupancy) -> GroundTruthStats {
    ground_truth_mesh_with_cuts(mesh, grid_from_local, out, None)
}

/// [`ground_truth_mesh`] that also records in `cut` the cells some triangle cuts through; `out` minus `cut`
/// are the cells the surface only grazes ([`OverlapKind::Graze`]).
pub fn ground_truth_mesh_with_cuts(
    mesh: &TriangleMesh,
    grid_from_local: Affine3A,
    out: &VoxelOccupancy,
    cut: Option<&VoxelOccupancy>,
) -> GroundTruthStats {
    for_each_grid_triangle(mesh, grid_from_local, |v| match v {
        Some(v) => ground_truth_triangle(v, out, cut),
        None => GroundTruthStats { triangles: 1, skipped: 1, ..Default::default() },
    })
}

/// The cells of a box `lo..=hi` (helper for tests).
pub fn cells_in(lo: UVec3, hi: UVec3) -> impl Iterator<Item = UVec3> {
    (lo.z..=hi.z).flat_map(move |z| (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| UVec3::new(x, y, z))))
}
