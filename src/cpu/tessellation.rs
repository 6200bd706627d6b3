//! Triangle subdivision and point generation: equations 1, 2 and 5 of Fei et al. 2012, and the subdivision
//! pattern that replaces the hardware tessellator.
//!
//! Everything here works in grid space (cells of side 1, so the paper's `l_cell` is 1) and in `f32`, in the
//! order of operations that `voxelize_common.wgsl` uses; functions carry the names of their WGSL twins.
//!
//! # The subdivision pattern
//!
//! A triangle `v0 v1 v2` with `n` segments per edge is cut into the `n * n` congruent sub-triangles of the
//! regular lattice `p(a, b) = v0 + e1 * (a / n) + e2 * (b / n)` with `e1 = v1 - v0`, `e2 = v2 - v0` and
//! integer `a, b >= 0`, `a + b <= n`. Lattice cell `(i, j)` holds an *up* sub-triangle with corners
//! `(i, j), (i+1, j), (i, j+1)` (for `i + j <= n - 1`) and a *down* one with corners
//! `(i+1, j), (i, j+1), (i+1, j+1)` (for `i + j <= n - 2`). Every sub-triangle edge is an edge of the parent
//! divided by `n`, so with `n >= gamma * (largest axis extent of any edge)` and `gamma >= 1` each
//! sub-triangle spans at most one cell along every axis and touches at most 8 cells.
//!
//! Sub-triangles are numbered so that one index maps to one sub-triangle with integer arithmetic only:
//!
//! * [`LatticeRange`] *full* (the whole triangle is inside the grid): index `s` in `0..n*n`, `a = s / n`,
//!   `b = s % n`; if `a + b < n` it is the up triangle of cell `(b, a)`, otherwise the down triangle of cell
//!   `(n-1-b, n-1-a)`. This folds the `n x n` square of indices onto the triangle with no gaps.
//! * *clipped* (the triangle crosses the grid boundary): only the lattice cells of a rectangle
//!   `[u_start, u_start+width) x [v_start, v_start+height)` covering the part of the triangle inside the
//!   grid are enumerated: `s` in `0..2*width*height`, cell `(u_start + (s/2) % width, v_start + (s/2) /
//!   width)`, up if `s` is even. Indices whose sub-triangle lies outside the parent triangle are skipped.
//!
//! The centroid (equation 2) of the up triangle of cell `(i, j)` is the lattice point
//! `((3i+1)/3, (3j+1)/3)`, of the down triangle `((3i+2)/3, (3j+2)/3)`: integer numerators over `3n`.

use glam::{Vec2, Vec3};

/// The largest subdivision count `n` (segments per edge) the voxelizer accepts; larger triangles are
/// skipped and counted as oversize.
pub const MAX_SUBDIVISION: u32 = 1 << 20;

/// Sub-triangles a triangle inside the grid may have and still be injected by the GPU invocation that reads
/// it (`n <= 4`), rather than queued for the expand pass; [`crate::cpu::VoxelizeStats::small`] counts these.
pub const INLINE_SUB_TRIANGLES: u64 = 16;

/// The most sub-triangles one triangle may produce (2^28); more is skipped and counted as oversize.
pub const MAX_SUB_TRIANGLES_PER_TRIANGLE: u64 = 1 << 28;

/// Equation 1: the edge factors `T_1, T_2, T_3` and their mean `T_C`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TessellationFactors {
    /// `T_1` (edge v0-v1), `T_2` (edge v1-v2), `T_3` (edge v0-v2): gamma times the largest axis extent of
    /// the edge, in cells.
    pub edges: [f32; 3],
    /// `T_C = (T_1 + T_2 + T_3) / 3`, the paper's inner factor. The uniform pattern does not need it; it is
    /// kept for comparison with the paper.
    pub inner: f32,
}

/// Equation 1 in grid space (`l_cell = 1`): `E_ij = gamma * |P_i - P_j|`, `T = max over x, y, z of E`.
#[inline]
pub fn tessellation_factors(v0: Vec3, v1: Vec3, v2: Vec3, gamma: f32) -> TessellationFactors {
    let t1 = gamma * (v0 - v1).abs().max_element();
    let t2 = gamma * (v1 - v2).abs().max_element();
    let t3 = gamma * (v0 - v2).abs().max_element();
    TessellationFactors { edges: [t1, t2, t3], inner: (t1 + t2 + t3) / 3.0 }
}

/// The number of segments per edge of the uniform pattern: `n = max(1, ceil(max(T_1, T_2, T_3)))`, capped
/// at `MAX_SUBDIVISION + 1` (a value the caller treats as oversize).
#[inline]
pub fn subdivision_count(factors: &TessellationFactors) -> u32 {
    let t = factors.edges[0].max(factors.edges[1]).max(factors.edges[2]).ceil();
    if t.is_nan() || t < 1.0 {
        1
    } else if t > MAX_SUBDIVISION as f32 {
        MAX_SUBDIVISION + 1
    } else {
        t as u32
    }
}

/// Equation 5: the expected number of surfels `N_e = 3 N_tri l_avg^2 / (2 l_cell^2)`, times `gamma^2` for a
/// safety factor other than 1 (the pattern's point count grows with the square of the factors).
/// `avg_edge_length` and `cell_size` in the same unit.
pub fn expected_point_count(triangles: u64, avg_edge_length: f64, cell_size: f64, gamma: f64) -> f64 {
    let l = gamma * avg_edge_length / cell_size;
    1.5 * triangles as f64 * l * l
}

/// Which sub-triangles of a subdivided triangle are enumerated (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LatticeRange {
    /// Segments per edge.
    pub n: u32,
    /// First lattice column of the clipped rectangle (0 for a full range).
    pub u_start: u32,
    /// First lattice row of the clipped rectangle (0 for a full range).
    pub v_start: u32,
    /// Columns of the clipped rectangle; 0 means the full triangle.
    pub width: u32,
    /// Rows of the clipped rectangle; 0 for a full range.
    pub height: u32,
}

impl LatticeRange {
    /// The whole triangle, `n * n` sub-triangles.
    pub fn full(n: u32) -> Self {
        Self { n, u_start: 0, v_start: 0, width: 0, height: 0 }
    }

    /// Whether this is the full range.
    pub fn is_full(&self) -> bool {
        self.width == 0
    }

    /// Number of sub-triangle indices to enumerate (WGSL: `sub_triangle_count`). Some indices of a clipped
    /// range map to no sub-triangle.
    pub fn sub_triangle_count(&self) -> u64 {
        if self.is_full() { self.n as u64 * self.n as u64 } else { 2 * self.width as u64 * self.height as u64 }
    }
}

/// One sub-triangle: lattice cell `(i, j)`, up or down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubTriangle {
    /// Lattice column.
    pub i: u32,
    /// Lattice row.
    pub j: u32,
    /// Up (`(i,j), (i+1,j), (i,j+1)`) or down (`(i+1,j), (i,j+1), (i+1,j+1)`).
    pub up: bool,
}

/// The sub-triangle with index `s` of a range, or `None` if a clipped range's index falls outside the
/// parent triangle (WGSL: `sub_triangle`, which returns a `valid` flag instead).
#[inline]
pub fn sub_triangle(range: &LatticeRange, s: u32) -> Option<SubTriangle> {
    let n = range.n;
    if range.is_full() {
        let a = s / n;
        let b = s % n;
        if a + b < n {
            Some(SubTriangle { i: b, j: a, up: true })
        } else {
            Some(SubTriangle { i: n - 1 - b, j: n - 1 - a, up: false })
        }
    } else {
        let cell = s >> 1;
        let up = (s & 1) == 0;
        let i = range.u_start + cell % range.width;
        let j = range.v_start + cell / range.width;
        let inside = if up { i + j < n } else { i + j + 1 < n };
        inside.then_some(SubTriangle { i, j, up })
    }
}

/// Equation 2: the centroid of a sub-triangle, in grid space (WGSL: `sub_triangle_centroid`).
/// `inv_3n` is `1.0 / (3.0 * n as f32)`, computed once per triangle.
#[inline]
pub fn sub_triangle_centroid(v0: Vec3, e1: Vec3, e2: Vec3, inv_3n: f32, sub: SubTriangle) -> Vec3 {
    let c = if sub.up { 1 } else { 2 };
    let a = (3 * sub.i + c) as f32 * inv_3n;
    let b = (3 * sub.j + c) as f32 * inv_3n;
    v0 + e1 * a + e2 * b
}

/// A lattice point `p(a, b)` in grid space (WGSL: `lattice_point`). `inv_n` is `1.0 / n as f32`.
#[inline]
pub fn lattice_point(v0: Vec3, e1: Vec3, e2: Vec3, inv_n: f32, a: u32, b: u32) -> Vec3 {
    v0 + e1 * (a as f32 * inv_n) + e2 * (b as f32 * inv_n)
}

/// The three corners of a sub-triangle in grid space (WGSL: `sub_triangle_vertices`).
#[inline]
pub fn sub_triangle_vertices(v0: Vec3, e1: Vec3, e2: Vec3, inv_n: f32, sub: SubTriangle) -> [Vec3; 3] {
    let (i, j) = (sub.i, sub.j);
    if sub.up {
        [
            lattice_point(v0, e1, e2, inv_n, i, j),
            lattice_point(v0, e1, e2, inv_n, i + 1, j),
            lattice_point(v0, e1, e2, inv_n, i, j + 1),
        ]
    } else {
        [
            lattice_point(v0, e1, e2, inv_n, i + 1, j),
            lattice_point(v0, e1, e2, inv_n, i, j + 1),
            lattice_point(v0, e1, e2, inv_n, i + 1, j + 1),
        ]
    }
}

/// Where a grid-space triangle stands against a box of the lattice (the grid box `[0, dims]`, or the
/// region of it being voxelized).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridPlacement {
    /// Entirely inside (closed box).
    Inside,
    /// Entirely outside: nothing to voxelize.
    Outside,
    /// Crossing the boundary: clip.
    Crossing,
}

/// Classifies a triangle's bounding box against the closed box `[box_min, box_max]` of grid space (WGSL:
/// `grid_placement`).
#[inline]
pub fn grid_placement(v0: Vec3, v1: Vec3, v2: Vec3, box_min: Vec3, box_max: Vec3) -> GridPlacement {
    let lo = v0.min(v1).min(v2);
    let hi = v0.max(v1).max(v2);
    let (b, d) = (box_min, box_max);
    if hi.x < b.x || hi.y < b.y || hi.z < b.z || lo.x > d.x || lo.y > d.y || lo.z > d.z {
        GridPlacement::Outside
    } else if lo.x >= b.x && lo.y >= b.y && lo.z >= b.z && hi.x <= d.x && hi.y <= d.y && hi.z <= d.z {
        GridPlacement::Inside
    } else {
        GridPlacement::Crossing
    }
}

/// Most vertices a triangle clipped by 6 half-planes can have.
pub const CLIP_MAX_VERTICES: usize = 9;

/// The lattice rectangle covering the part of a triangle that lies inside the box `[box_min, box_max]` of
/// grid space, padded by one lattice cell on each side against rounding (WGSL: `clipped_lattice_range`). The
/// triangle (in lattice coordinates `(a, b)`) is clipped by the six half-planes
/// `box_min_k <= p_k(a, b) <= box_max_k` with Sutherland-Hodgman; `None` if nothing is left.
pub fn clipped_lattice_range(
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    n: u32,
    box_min: Vec3,
    box_max: Vec3,
) -> Option<LatticeRange> {
    let nf = n as f32;
    let inv_n = 1.0 / nf;
    let mut poly = [Vec2::ZERO; CLIP_MAX_VERTICES + 1];
    let mut next = [Vec2::ZERO; CLIP_MAX_VERTICES + 1];
    poly[0] = Vec2::new(0.0, 0.0);
    poly[1] = Vec2::new(nf, 0.0);
    poly[2] = Vec2::new(0.0, nf);
    let mut count = 3usize;
    for plane in 0..6u32 {
        let axis = (plane >> 1) as usize;
        let upper = (plane & 1) == 1;
        // f(a, b) = c0 + c1 a + c2 b >= 0
        let (c0, c1, c2) = if upper {
            (box_max[axis] - v0[axis], -e1[axis] * inv_n, -e2[axis] * inv_n)
        } else {
            (v0[axis] - box_min[axis], e1[axis] * inv_n, e2[axis] * inv_n)
        };
        let mut out = 0usize;
        for k in 0..count {
            let p = poly[k];
            let q = poly[(k + 1) % count];
            let fp = c0 + c1 * p.x + c2 * p.y;
            let fq = c0 + c1 * q.x + c2 * q.y;
            if fp >= 0.0 {
                next[out] = p;
                out += 1;
            }
            if (fp >= 0.0) != (fq >= 0.0) {
                let t = fp / (fp - fq);
                next[out] = p + (q - p) * t;
                out += 1;
            }
        }
        count = out.min(CLIP_MAX_VERTICES);
        if count == 0 {
            return None;
        }
        poly[..count].copy_from_slice(&next[..count]);
    }
    let mut lo = poly[0];
    let mut hi = poly[0];
    for p in &poly[1..count] {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let u0 = (lo.x.floor() - 1.0).clamp(0.0, nf) as u32;
    let u1 = (hi.x.ceil() + 1.0).clamp(0.0, nf) as u32;
    let v0r = (lo.y.floor() - 1.0).clamp(0.0, nf) as u32;
    let v1 = (hi.y.ceil() + 1.0).clamp(0.0, nf) as u32;
    if u1 <= u0 || v1 <= v0r {
        return None;
    }
    Some(LatticeRange { n, u_start: u0, v_start: v0r, width: u1 - u0, height: v1 - v0r })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn factors_on_hand_computed_triangles() {
        // Edge extents: v0-v1 (3, 0, 0) -> 3; v1-v2 (-3, 2, 0.5) -> 3; v0-v2 (0, 2, 0.5) -> 2.
        let f = tessellation_factors(Vec3::ZERO, Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.5), 1.0);
        assert_eq!(f.edges, [3.0, 3.0, 2.0]);
        assert!((f.inner - 8.0 / 3.0).abs() < 1e-6);
        assert_eq!(subdivision_count(&f), 3);
        // gamma scales every factor; ceil rounds 1.5 * 3 = 4.5 up to 5.
        let f = tessellation_factors(Vec3::ZERO, Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.5), 1.5);
        assert_eq!(f.edges, [4.5, 4.5, 3.0]);
        assert_eq!(subdivision_count(&f), 5);
        // A diagonal edge counts its largest axis extent, not its length.
        let f = tessellation_factors(Vec3::ZERO, Vec3::new(2.0, 2.0, 2.0), Vec3::new(0.0, 0.5, 0.0), 1.0);
        assert_eq!(f.edges, [2.0, 2.0, 0.5]);
        assert_eq!(subdivision_count(&f), 2);
        // A triangle inside one cell is not subdivided.
        let f = tessellation_factors(Vec3::splat(0.1), Vec3::splat(0.2), Vec3::new(0.1, 0.3, 0.2), 1.0);
        assert_eq!(subdivision_count(&f), 1);
        // A zero-size triangle still gets one point.
        let f = tessellation_factors(Vec3::ONE, Vec3::ONE, Vec3::ONE, 1.0);
        assert_eq!(subdivision_count(&f), 1);
    }

    #[test]
    fn equation_5_matches_the_paper() {
        // 1000 triangles of average edge 2 cells: 3 * 1000 * 4 / 2 = 6000.
        assert_eq!(expected_point_count(1000, 2.0, 1.0, 1.0), 6000.0);
        assert_eq!(expected_point_count(1000, 0.2, 0.1, 2.0), 24000.0);
    }

    #[test]
    fn full_enumeration_is_a_bijection_onto_the_n_squared_sub_triangles() {
        for n in 1..=12u32 {
            let range = LatticeRange::full(n);
            let mut seen = HashSet::new();
            for s in 0..range.sub_triangle_count() as u32 {
                let t = sub_triangle(&range, s).unwrap();
                if t.up {
                    assert!(t.i + t.j < n);
                } else {
                    assert!(t.i + t.j + 1 < n);
                }
                assert!(seen.insert((t.i, t.j, t.up)));
            }
            assert_eq!(seen.len() as u32, n * n);
        }
    }

    #[test]
    fn clipped_enumeration_of_the_whole_lattice_finds_every_sub_triangle_once() {
        let n = 7;
        let range = LatticeRange { n, u_start: 0, v_start: 0, width: n, height: n };
        let subs: Vec<_> = (0..range.sub_triangle_count() as u32).filter_map(|s| sub_triangle(&range, s)).collect();
        let full: HashSet<_> =
            (0..n * n).map(|s| sub_triangle(&LatticeRange::full(n), s).unwrap()).map(|t| (t.i, t.j, t.up)).collect();
        assert_eq!(subs.len(), full.len());
        assert_eq!(subs.iter().map(|t| (t.i, t.j, t.up)).collect::<HashSet<_>>(), full);
    }

    #[test]
    fn centroids_are_the_mean_of_the_sub_triangle_corners_and_tile_the_parent() {
        let (v0, v1, v2) = (Vec3::new(0.5, 1.0, 2.0), Vec3::new(6.0, 1.5, 2.0), Vec3::new(1.0, 5.0, 3.0));
        let (e1, e2) = (v1 - v0, v2 - v0);
        let n = subdivision_count(&tessellation_factors(v0, v1, v2, 1.0));
        assert_eq!(n, 6);
        let (inv_n, inv_3n) = (1.0 / n as f32, 1.0 / (3.0 * n as f32));
        let mut area = 0.0;
        for s in 0..n * n {
            let t = sub_triangle(&LatticeRange::full(n), s).unwrap();
            let [a, b, c] = sub_triangle_vertices(v0, e1, e2, inv_n, t);
            let centroid = sub_triangle_centroid(v0, e1, e2, inv_3n, t);
            assert!((centroid - (a + b + c) / 3.0).length() < 1e-5);
            // Every sub-triangle spans at most one cell per axis.
            let extent = a.max(b).max(c) - a.min(b).min(c);
            assert!(extent.max_element() <= 1.0 + 1e-5, "{extent}");
            area += (b - a).cross(c - a).length() / 2.0;
        }
        assert!((area - e1.cross(e2).length() / 2.0).abs() < 1e-3);
    }

    #[test]
    fn placement_and_clipping() {
        let dims = (Vec3::ZERO, Vec3::splat(8.0));
        let inside = [Vec3::splat(1.0), Vec3::new(7.0, 1.0, 1.0), Vec3::new(1.0, 8.0, 1.0)];
        assert_eq!(grid_placement(inside[0], inside[1], inside[2], dims.0, dims.1), GridPlacement::Inside);
        let outside = [Vec3::splat(-3.0), Vec3::new(-1.0, -3.0, -3.0), Vec3::new(-3.0, -1.0, -3.0)];
        assert_eq!(grid_placement(outside[0], outside[1], outside[2], dims.0, dims.1), GridPlacement::Outside);
        // A huge floor triangle at y = 4 covering the grid, whose lattice is mostly outside it.
        let (v0, v1, v2) =
            (Vec3::new(-1000.0, 4.0, -1000.0), Vec3::new(3000.0, 4.0, -1000.0), Vec3::new(-1000.0, 4.0, 3000.0));
        assert_eq!(grid_placement(v0, v1, v2, dims.0, dims.1), GridPlacement::Crossing);
        let n = subdivision_count(&tessellation_factors(v0, v1, v2, 1.0));
        assert_eq!(n, 4000);
        let r = clipped_lattice_range(v0, v1 - v0, v2 - v0, n, dims.0, dims.1).unwrap();
        // The 8 x 8 cells of the grid at lattice 1000..1008, padded by one (and by rounding at most one more):
        // about 10 x 10 cells, not 4000 x 4000.
        for (start, len) in [(r.u_start, r.width), (r.v_start, r.height)] {
            assert!((998..=999).contains(&start) && start + len >= 1009 && len <= 11, "{r:?}");
        }
        // A triangle crossing the boundary only in its bounding box can still miss the grid after clipping.
        let (a, b, c) = (Vec3::new(-10.0, 0.5, 4.0), Vec3::new(-10.0, 0.5, -10.0), Vec3::new(4.0, 0.5, -10.0));
        assert_eq!(grid_placement(a, b, c, dims.0, dims.1), GridPlacement::Crossing);
        let n = subdivision_count(&tessellation_factors(a, b, c, 1.0));
        assert_eq!(clipped_lattice_range(a, b - a, c - a, n, dims.0, dims.1), None);
        // A box away from the origin (a cascade's slab): the floor clipped to x in [1000, 1008] covers
        // lattice columns near 2000.
        let r =
            clipped_lattice_range(v0, v1 - v0, v2 - v0, 4000, Vec3::new(1000.0, 0.0, 0.0), Vec3::new(1008.0, 8.0, 8.0))
                .unwrap();
        assert!((1998..=1999).contains(&r.u_start) && r.width <= 11, "{r:?}");
    }
}
