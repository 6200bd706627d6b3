//! PN triangles (Vlachos et al. 2001), as Fei 2012 section 3.4 voxelizes them: each triangle is replaced by
//! the cubic Bézier patch its corners and vertex normals define, the patch's parameter triangle is
//! subdivided as a flat triangle's would be (equation 1, with gamma raised by [`PnPatch::gamma_scale`] so
//! that the curved sub-triangles stay under a cell), and each sub-triangle's corners are moved onto the
//! patch before its centroid is injected. A coarse mesh of a curved shape voxelizes curved.
//!
//! The GPU voxelizer does the same for occluders marked [`crate::PnTriangles`]; this is its CPU twin.
//!
//! How close the patch comes to the shape depends on the mesh: for an icosphere with exact normals, the
//! patch's radius lies within 5.9% of the sphere's at 20 triangles, 0.63% at 80, 0.05% at 320 (the flat
//! triangles: 20.5%, 6.5%, 1.8%).

use super::attributes::{MeshAlbedo, TriangleAttributes, centroid_weights, interpolated_normal, point_sample};
use super::grid::VoxelOccupancy;
use super::mesh::TriangleMesh;
use super::overlap::OverlapTriangle;
use super::tessellation::*;
use super::voxelize::{
    InjectionMode, InjectionRegion, VoxelizeSettings, VoxelizeStats, grid_space_position, lattice_cell, storage_index,
    triangle_is_degenerate,
};
use glam::{Affine3A, Vec3};

/// The most [`PnPatch::gamma_scale`] may raise gamma (a patch whose normals fold it over itself).
pub const MAX_PN_GAMMA_SCALE: f32 = 4.0;

/// A PN triangle's ten control points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnPatch {
    /// `b300, b030, b003` (the corners), `b210, b120, b021, b012, b102, b201` (two per edge, from corner
    /// `i` toward corner `j`: `b_ij` sits by `i`) and `b111` (the middle).
    pub b: [Vec3; 10],
}

impl PnPatch {
    /// The patch of corners `p` with unit normals `n` (`n[i]` at `p[i]`).
    pub fn new(p: [Vec3; 3], n: [Vec3; 3]) -> Self {
        // The edge control point by corner i toward corner j: a third of the way, projected onto i's
        // tangent plane.
        let edge = |i: usize, j: usize| (2.0 * p[i] + p[j] - (p[j] - p[i]).dot(n[i]) * n[i]) / 3.0;
        let (b210, b120, b021, b012, b102, b201) =
            (edge(0, 1), edge(1, 0), edge(1, 2), edge(2, 1), edge(2, 0), edge(0, 2));
        let e = (b210 + b120 + b021 + b012 + b102 + b201) / 6.0;
        let v = (p[0] + p[1] + p[2]) / 3.0;
        let b111 = e + (e - v) / 2.0;
        Self { b: [p[0], p[1], p[2], b210, b120, b021, b012, b102, b201, b111] }
    }

    /// The point of the patch at barycentric weights `w` (of corners 0, 1, 2; they sum to 1).
    pub fn point(&self, w: Vec3) -> Vec3 {
        let [b300, b030, b003, b210, b120, b021, b012, b102, b201, b111] = self.b;
        let (w0, w1, w2) = (w.x, w.y, w.z);
        b300 * (w0 * w0 * w0)
            + b030 * (w1 * w1 * w1)
            + b003 * (w2 * w2 * w2)
            + b210 * (3.0 * w0 * w0 * w1)
            + b120 * (3.0 * w0 * w1 * w1)
            + b201 * (3.0 * w0 * w0 * w2)
            + b021 * (3.0 * w1 * w1 * w2)
            + b102 * (3.0 * w0 * w2 * w2)
            + b012 * (3.0 * w1 * w2 * w2)
            + b111 * (6.0 * w0 * w1 * w2)
    }

    /// The box of the control points, which holds the patch (a Bézier patch lies in its control points'
    /// convex hull).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let lo = self.b.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
        let hi = self.b.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
        (lo, hi)
    }

    /// How much faster than the flat triangle the patch can move per axis as its parameters run along any
    /// of the triangle's edge directions: for each direction, three times the largest step of the control
    /// net along it (which bounds the patch's derivative), over the flat edge's extent, on the axis where
    /// that is largest; the largest over the three directions, at least 1 and at most
    /// [`MAX_PN_GAMMA_SCALE`]. Gamma times this subdivides the patch as finely as equation 1 subdivides a
    /// flat triangle. 1 for a flat patch (every step is a third of the edge).
    pub fn gamma_scale(&self) -> f32 {
        let [b300, b030, b003, b210, b120, b021, b012, b102, b201, b111] = self.b;
        let direction = |chord: Vec3, steps: [(Vec3, Vec3); 6]| {
            let step = steps.iter().fold(Vec3::ZERO, |m, (a, b)| m.max((*b - *a).abs()));
            let chord = chord.abs().max_element();
            if chord > 0.0 { 3.0 * step.max_element() / chord } else { 1.0 }
        };
        let r01 = direction(
            b030 - b300,
            [(b300, b210), (b210, b120), (b120, b030), (b201, b111), (b111, b021), (b102, b012)],
        );
        let r02 = direction(
            b003 - b300,
            [(b300, b201), (b201, b102), (b102, b003), (b210, b111), (b111, b012), (b120, b021)],
        );
        let r12 = direction(
            b003 - b030,
            [(b030, b021), (b021, b012), (b012, b003), (b120, b111), (b111, b102), (b210, b201)],
        );
        let r = r01.max(r02).max(r12);
        if r.is_finite() { r.clamp(1.0, MAX_PN_GAMMA_SCALE) } else { MAX_PN_GAMMA_SCALE }
    }
}

/// Per-vertex normals of a mesh: the area-weighted sum of the normals of the triangles that share the
/// vertex (by index), normalized; `Vec3::ZERO` for a vertex no valid triangle uses.
pub fn smooth_vertex_normals(mesh: &TriangleMesh) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; mesh.positions.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let Some([a, b, c]) = mesh.triangle(t) else { continue };
        let n = (b - a).cross(c - a);
        if n.is_finite() {
            for &i in tri {
                normals[i as usize] += n;
            }
        }
    }
    normals.iter().map(|n| n.normalize_or_zero()).collect()
}

/// Voxelizes one grid-space PN triangle (corners `v`, unit normals `n` in grid space) into the cells of
/// `region` (see [`super::voxelize::voxelize_triangle_in_region`], the flat version). A corner whose normal
/// is not a unit vector (zero, non-finite) makes the triangle flat: it is voxelized by the flat version. In
/// conservative mode each curved sub-triangle is tested against the cells instead of the parent. WGSL: the
/// PN branch of `classify_triangle` and `inject_pn_sub_triangle`.
pub fn voxelize_pn_triangle_in_region(
    v: [Vec3; 3],
    n: [Vec3; 3],
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    voxelize_sampled_pn_triangle_in_region(v, n, &TriangleAttributes::WHITE, settings, region, out)
}

/// [`voxelize_pn_triangle_in_region`] for a triangle with attributes: where `out` keeps attribute sums, each
/// point adds its albedo and its interpolated vertex normal ([`super::attributes`]).
pub fn voxelize_sampled_pn_triangle_in_region(
    v: [Vec3; 3],
    n: [Vec3; 3],
    attributes: &TriangleAttributes,
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    let mut stats = VoxelizeStats { triangles: 1, ..Default::default() };
    if !v.iter().all(|p| p.is_finite()) {
        stats.invalid = 1;
        return stats;
    }
    if triangle_is_degenerate(v[0], v[1], v[2]) {
        stats.degenerate = 1;
        return stats;
    }
    if n.iter().any(|n| !n.is_finite() || n.length_squared() < 0.5) {
        return super::voxelize::voxelize_sampled_triangle_in_region(v, attributes, settings, region, out);
    }
    let patch = PnPatch::new(v, n);
    let (lo, hi) = patch.bounds();
    let (box_min, box_max) = region.bounds();
    if lo.cmpgt(box_max).any() || hi.cmplt(box_min).any() {
        stats.outside = 1;
        return stats;
    }
    let sub = subdivision(v, settings.effective_gamma() * patch.gamma_scale(), settings.pattern);
    if sub.n > MAX_SUBDIVISION {
        stats.oversize = 1;
        return stats;
    }
    // The whole lattice: the patch may bulge out of the flat triangle's clip of the region, so cells are
    // tested one by one.
    let range = LatticeRange::whole(&sub);
    let count = range.sub_triangle_count();
    if count > MAX_SUB_TRIANGLES_PER_TRIANGLE {
        stats.oversize = 1;
        return stats;
    }
    // Lattice coordinates are along the edges from the subdivision's apex corner: weights in that order.
    let order = [sub.apex as usize % 3, (sub.apex as usize + 1) % 3, (sub.apex as usize + 2) % 3];
    let inv_n = 1.0 / range.fine() as f32;
    let dims = out.grid().dims;
    let corner = |c: glam::UVec2| {
        let (a, b) = (c.x as f32 * inv_n, c.y as f32 * inv_n);
        let mut w = [0.0f32; 3];
        w[order[0]] = 1.0 - a - b;
        w[order[1]] = a;
        w[order[2]] = b;
        patch.point(Vec3::from(w))
    };
    let inv_3n = 1.0 / (3.0 * range.fine() as f32);
    let sample = |st| {
        let w = centroid_weights(&range, st, sub.apex, inv_3n);
        point_sample(attributes, w, interpolated_normal(n, w))
    };
    for s in 0..count as u32 {
        let Some(st) = sub_triangle(&range, s) else { continue };
        stats.sub_triangles += 1;
        let [a, b, c] = sub_triangle_corners(&range, st).map(corner);
        match settings.mode {
            InjectionMode::Centroid => {
                if let Some(cell) = lattice_cell((a + b + c) / 3.0, region) {
                    out.inject_point(storage_index(cell, region, dims), || sample(st));
                    stats.injected += 1;
                }
            }
            InjectionMode::Conservative => {
                let piece = OverlapTriangle::new(a, b, c);
                let (lo, hi) = super::voxelize::conservative_candidate_cells(a, b, c, region);
                for z in lo.z..=hi.z {
                    for y in lo.y..=hi.y {
                        for x in lo.x..=hi.x {
                            let cell = glam::IVec3::new(x, y, z);
                            stats.overlap_tests += 1;
                            if piece.overlaps_lattice_cell(cell) {
                                out.inject_point(storage_index(cell, region, dims), || sample(st));
                                stats.injected += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    stats
}

/// Voxelizes a mesh as PN triangles into `out` (not cleared first), with the vertex normals `normals`
/// (local space, one per position: [`smooth_vertex_normals`] when the mesh has none). `grid_from_local`
/// maps positions to grid space; normals follow by its inverse transpose.
pub fn voxelize_mesh_pn(
    mesh: &TriangleMesh,
    normals: &[Vec3],
    grid_from_local: Affine3A,
    settings: &VoxelizeSettings,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    let region = InjectionRegion::whole(out.grid().dims);
    voxelize_sampled_mesh_pn_in_region(mesh, normals, &MeshAlbedo::WHITE, grid_from_local, settings, &region, out)
}

/// [`voxelize_mesh_pn`] into the cells of `region`, with the mesh's albedo: where `out` keeps attribute sums,
/// each point adds its albedo and normal.
pub fn voxelize_sampled_mesh_pn_in_region(
    mesh: &TriangleMesh,
    normals: &[Vec3],
    albedo: &MeshAlbedo,
    grid_from_local: Affine3A,
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    let normal_matrix = grid_from_local.matrix3.inverse().transpose();
    let mut stats = VoxelizeStats::default();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        stats += match mesh.triangle(t) {
            Some(v) => {
                let v = v.map(|p| grid_space_position(&grid_from_local, p));
                let n = tri
                    .map(|i| normals.get(i as usize).map_or(Vec3::ZERO, |&n| (normal_matrix * n).normalize_or_zero()));
                let attributes = albedo.triangle(*tri, &grid_from_local);
                voxelize_sampled_pn_triangle_in_region(v, n, &attributes, settings, region, out)
            }
            None => VoxelizeStats { triangles: 1, invalid: 1, ..Default::default() },
        };
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_normals_give_the_flat_triangle() {
        let p = [Vec3::ZERO, Vec3::X * 3.0, Vec3::Y * 2.0];
        let patch = PnPatch::new(p, [Vec3::Z; 3]);
        for w in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.2, 0.3, 0.5), Vec3::splat(1.0 / 3.0)] {
            let flat = p[0] * w.x + p[1] * w.y + p[2] * w.z;
            assert!(patch.point(w).distance(flat) < 1e-5, "{w}");
        }
        assert!((patch.gamma_scale() - 1.0).abs() < 1e-5);
    }

    #[test]
    fn corners_and_edges_interpolate_and_bulge_along_the_normals() {
        // A triangle on the unit sphere with its exact normals: the patch passes through the corners and
        // bulges outward, toward the sphere.
        let p = [Vec3::X, Vec3::Y, Vec3::Z];
        let patch = PnPatch::new(p, p);
        assert_eq!(patch.point(Vec3::X), p[0]);
        assert_eq!(patch.point(Vec3::Z), p[2]);
        let middle = patch.point(Vec3::splat(1.0 / 3.0)).length();
        let flat_middle = (Vec3::ONE / 3.0).length();
        assert!(middle > flat_middle + 0.15 && middle < 1.0, "{middle} (flat {flat_middle})");
        assert!(patch.gamma_scale() > 1.0);
    }
}
