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
//!
//! # Strips: the per-edge pattern ([`SubdivisionPattern::Strips`], the default)
//!
//! The uniform pattern cuts a long thin triangle (a *sliver*) for its longest edge: `n * n` sub-triangles
//! that are themselves slivers, most of them far thinner than a cell. The strip pattern gives each edge its
//! own count instead. The triangle is rotated so that `v0` is the *apex*, the corner opposite the shortest
//! edge (factor `T_s`); the two long edges are `e1 = v1 - v0` and `e2 = v2 - v0`. Then:
//!
//! 1. the uniform lattice with a *coarse* count `n` (at least `T_s`) cuts it into `n * n` slivers similar
//!    to it, whose short edges span at most one cell;
//! 2. each coarse sliver is cut across its length into `q` *strips* by lines parallel to its short edge,
//!    at `1/q, 2/q, ...` of the way from its apex: a triangle at the apex and `q - 1` trapezoids, each cut
//!    in two along one diagonal, `2q - 1` sub-triangles in all.
//!
//! Every corner is a point of the fine lattice with `n * q` segments per edge, `p(a, b)` as above with `n`
//! replaced by `n * q`, so positions and centroids stay integer numerators over one denominator. With
//! `L_k` and `R_k` the points `k` fine steps from the coarse apex along `e1` and `e2` (towards the coarse
//! triangle's inside: `+` for an up triangle, `-` for a down one, whose apex is its corner `(i+1, j+1)`):
//!
//! ```text
//!        apex        piece 0:        (apex, L_1, R_1)
//!        /  \        piece 2k - 1:   (L_k, R_k, R_k+1)   diagonal 0     (L_k, R_k, L_k+1)   diagonal 1
//!     L_1----R_1     piece 2k:       (L_k, R_k+1, L_k+1)                (R_k, R_k+1, L_k+1)
//!     /  \    \
//!   L_2----\---R_2    k = 1 .. q-1; the edges are e1/(nq), e2/(nq) (rails), k s/(nq) (rungs, s = e2 - e1)
//!   ...                and the diagonal (e2 + k s)/(nq) or (e1 - k s)/(nq).
//! ```
//!
//! [`subdivision`] picks `n`, `q` and the diagonal so that every one of these edges spans at most `1/gamma`
//! cell per axis (the diagonal is affine in `k`, so its ends `k = 1` and `k = q - 1` bound it), trying
//! `n` in `{c, c + 1, 2c}` with `c = max(1, ceil(T_s))` and both diagonals, and keeps the strip pattern only
//! where it has fewer sub-triangles than the uniform one (`q = 1` *is* the uniform pattern: one piece per
//! coarse triangle, with the triangle's own vertex order). A sliver `L` cells long and less than one wide
//! gets about `2L` sub-triangles instead of `L^2`. Sub-triangle index `s` is coarse triangle `s / (2q - 1)`
//! (numbered as above, full or clipped) and piece `s % (2q - 1)`.

use glam::{UVec2, Vec2, Vec3};

/// The largest subdivision count `n` (segments per edge) the voxelizer accepts; larger triangles are
/// skipped and counted as oversize.
pub const MAX_SUBDIVISION: u32 = 1 << 20;

/// Sub-triangles a triangle inside the grid may have and still be injected by the GPU invocation that reads
/// it (`n <= 4`), rather than queued for the expand pass; [`crate::cpu::VoxelizeStats::small`] counts these.
pub const INLINE_SUB_TRIANGLES: u64 = 16;

/// The most sub-triangles one triangle may produce (2^28); more is skipped and counted as oversize.
pub const MAX_SUB_TRIANGLES_PER_TRIANGLE: u64 = 1 << 28;

/// The largest coarse count the strip pattern tries (larger triangles use the uniform pattern); with the
/// fine count `n * q` at most [`MAX_SUBDIVISION`], a strip triangle's sub-triangle count fits in 31 bits.
pub const STRIPS_MAX_COARSE: u32 = 1 << 10;

/// How triangles are cut into sub-triangles (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum SubdivisionPattern {
    /// The `n x n` lattice for the longest edge: a long thin triangle gets `n^2` sub-triangles. Kept to
    /// compare against.
    Uniform,
    /// A count per edge: slivers are cut into strips along their length (about `2L` sub-triangles for a
    /// sliver `L` cells long), other triangles as by `Uniform`, whichever has fewer sub-triangles.
    #[default]
    Strips,
}

impl std::str::FromStr for SubdivisionPattern {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "uniform" => Ok(Self::Uniform),
            "strips" => Ok(Self::Strips),
            _ => Err(format!("unknown subdivision pattern '{s}' (expected strips or uniform)")),
        }
    }
}

impl std::fmt::Display for SubdivisionPattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Uniform => "uniform",
            Self::Strips => "strips",
        })
    }
}

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

/// How one triangle is subdivided (WGSL: `Subdivision`): `n` coarse segments per edge, each coarse
/// sub-triangle cut into `strips` strips (1: the uniform pattern) along `diagonal` (0 or 1), after rotating
/// the vertices so that vertex `apex` comes first ([`rotate_to_apex`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Subdivision {
    /// Coarse segments per edge; above [`MAX_SUBDIVISION`] the triangle is oversize.
    pub n: u32,
    /// Strips per coarse sub-triangle (`q`), at least 1.
    pub strips: u32,
    /// Which diagonal cuts the trapezoids: 0 from `L_k` to `R_k+1`, 1 from `R_k` to `L_k+1`.
    pub diagonal: u32,
    /// The vertex that becomes `v0`.
    pub apex: u32,
}

impl Subdivision {
    /// The uniform pattern with `n` segments per edge.
    pub fn uniform(n: u32) -> Self {
        Self { n, strips: 1, diagonal: 0, apex: 0 }
    }

    /// Sub-triangles of the whole triangle (`n^2 (2q - 1)`).
    pub fn sub_triangle_count(&self) -> u64 {
        LatticeRange::whole(self).sub_triangle_count()
    }
}

/// The vertices rotated so that vertex `apex` comes first (WGSL: `rotate_to_apex`).
#[inline]
pub fn rotate_to_apex(v: [Vec3; 3], apex: u32) -> [Vec3; 3] {
    match apex {
        1 => [v[1], v[2], v[0]],
        2 => [v[2], v[0], v[1]],
        _ => v,
    }
}

#[inline]
fn l_inf(v: Vec3) -> f32 {
    v.abs().max_element()
}

/// Whether `q` strips with coarse count `nc` keep every edge within one cell per axis (WGSL:
/// `strips_fit`); `e1`, `e2`, `s` are the apex-rotated edges times gamma.
#[inline]
pub fn strips_fit(e1: Vec3, e2: Vec3, s: Vec3, nc: u32, q: u32, diagonal: u32) -> bool {
    let d = (nc * q) as f32;
    if !(l_inf(e1).max(l_inf(e2)) <= d && l_inf(s) <= nc as f32) {
        return false;
    }
    let far = (q - 1) as f32;
    if diagonal == 0 {
        l_inf(e2 + s) <= d && l_inf(e2 + s * far) <= d
    } else {
        l_inf(e1 - s) <= d && l_inf(e1 - s * far) <= d
    }
}

/// The fewest strips (at least 2) that fit with coarse count `nc` and a diagonal, or `None` (WGSL:
/// `strip_count`). An estimate in closed form (per axis, the far diagonal `w + q t` with `w = e1, t = s`
/// or `w = e2, t = -s` must stay within `nc q`), then a walk to the smallest `q` that [`strips_fit`], so
/// that a division rounded differently on the GPU cannot change the result.
pub fn strip_count(e1: Vec3, e2: Vec3, s: Vec3, nc: u32, diagonal: u32) -> Option<u32> {
    let ncf = nc as f32;
    let (w, t, near) = if diagonal == 0 { (e1, s, e2 + s) } else { (e2, -s, e1 - s) };
    let mut estimate = l_inf(e1).max(l_inf(e2)).max(l_inf(near)) / ncf;
    for axis in 0..3 {
        // Where the denominator is not positive this axis never fits: no strips for this coarse count.
        if w[axis] > 0.0 {
            let den = ncf - t[axis];
            if !(den > 0.0) {
                return None;
            }
            estimate = estimate.max(w[axis] / den);
        } else if w[axis] < 0.0 {
            let den = ncf + t[axis];
            if !(den > 0.0) {
                return None;
            }
            estimate = estimate.max(-w[axis] / den);
        }
    }
    let most = MAX_SUBDIVISION / nc;
    if !(estimate <= most as f32) {
        return None;
    }
    let mut q = (estimate.ceil() as u32).clamp(2, most.max(2));
    for _ in 0..4 {
        if q > 2 && strips_fit(e1, e2, s, nc, q - 1, diagonal) {
            q -= 1;
        }
    }
    for _ in 0..4 {
        if nc * q > MAX_SUBDIVISION {
            return None;
        }
        if strips_fit(e1, e2, s, nc, q, diagonal) {
            return Some(q);
        }
        q += 1;
    }
    None
}

/// Equation 1 and the pattern: how a grid-space triangle is subdivided (WGSL: `subdivision`). The uniform
/// pattern's `n` is [`subdivision_count`]; the strip pattern is tried for `n` in `{c, c + 1, 2c}`
/// (`c = max(1, ceil(T_s))`) and both diagonals, and kept if it has fewer sub-triangles.
pub fn subdivision(v: [Vec3; 3], gamma: f32, pattern: SubdivisionPattern) -> Subdivision {
    let factors = tessellation_factors(v[0], v[1], v[2], gamma);
    let n = subdivision_count(&factors);
    let mut best = Subdivision::uniform(n);
    if pattern == SubdivisionPattern::Uniform || n <= 1 || n > MAX_SUBDIVISION {
        return best;
    }
    let [t1, t2, t3] = factors.edges;
    let apex = if t2 <= t1 && t2 <= t3 {
        0
    } else if t3 <= t1 {
        1
    } else {
        2
    };
    let [a, b, c] = rotate_to_apex(v, apex);
    let e1 = (b - a) * gamma;
    let e2 = (c - a) * gamma;
    let s = (c - b) * gamma;
    let short = l_inf(s).ceil().max(1.0) as u32;
    let mut best_count = best.sub_triangle_count();
    for nc in [short, short + 1, 2 * short] {
        if nc > STRIPS_MAX_COARSE {
            continue;
        }
        // A lower bound on the strips (`floor` of a quotient that may be rounded up on the GPU still bounds
        // the exact `ceil` from below): a candidate that cannot win is not searched. Skipping it only saves
        // time, so the CPU and the GPU choose alike even where their quotients differ.
        let least = ((l_inf(e1).max(l_inf(e2)) / nc as f32).floor() as u32).max(2);
        if nc as u64 * nc as u64 * (2 * least as u64 - 1) >= best_count {
            continue;
        }
        for diagonal in 0..2 {
            let Some(q) = strip_count(e1, e2, s, nc, diagonal) else { continue };
            let candidate = Subdivision { n: nc, strips: q, diagonal, apex };
            if candidate.sub_triangle_count() < best_count {
                best_count = candidate.sub_triangle_count();
                best = candidate;
            }
        }
    }
    best
}

/// The triangle sizes the point-count estimate needs (lengths in the mesh's units): means over the valid
/// triangles of the longest edge `L`, its square, and its product with the shortest edge `S`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TriangleSizes {
    /// Triangles (every one, valid or not: each costs at least a point).
    pub triangles: u64,
    /// Mean longest edge, `mean(L)`.
    pub mean_longest_edge: f64,
    /// Mean square of the longest edge, `mean(L^2)`.
    pub mean_longest_squared: f64,
    /// Mean product of the longest and shortest edges, `mean(L S)`.
    pub mean_longest_times_shortest: f64,
}

impl TriangleSizes {
    /// The sizes of `count` triangles, of which `valid` yields the finite ones.
    pub fn of(count: u64, valid: impl Iterator<Item = [Vec3; 3]>) -> Self {
        let (mut longest, mut squared, mut product, mut n) = (0.0f64, 0.0f64, 0.0f64, 0u64);
        for [a, b, c] in valid {
            let l = [a.distance(b) as f64, b.distance(c) as f64, c.distance(a) as f64];
            let (lo, hi) = (l[0].min(l[1]).min(l[2]), l[0].max(l[1]).max(l[2]));
            longest += hi;
            squared += hi * hi;
            product += hi * lo;
            n += 1;
        }
        let mean = |x: f64| if n > 0 { x / n as f64 } else { 0.0 };
        Self {
            triangles: count,
            mean_longest_edge: mean(longest),
            mean_longest_squared: mean(squared),
            mean_longest_times_shortest: mean(product),
        }
    }

    /// The sizes of the same triangles scaled by `s`.
    pub fn scaled(&self, s: f64) -> Self {
        Self {
            triangles: self.triangles,
            mean_longest_edge: self.mean_longest_edge * s,
            mean_longest_squared: self.mean_longest_squared * s * s,
            mean_longest_times_shortest: self.mean_longest_times_shortest * s * s,
        }
    }
}

/// Equation 5 brought up to date: the expected number of points (sub-triangles) for triangles of these sizes
/// in cells of `cell_size`, at least one per triangle. With `L` and `S` in cells times gamma:
///
/// * `Uniform`: a triangle costs `ceil(L)^2 ~ L^2 + L`, so `N_e = N_tri (gamma^2 mean(L^2) + gamma mean(L))`.
///   The paper's `3 N_tri l_avg^2 / 2` is the same for equilateral triangles but counts a sliver by its mean
///   edge, not its longest: on Sponza at 128^3 it says 0.24 M points where the pattern makes 1.87 M.
/// * `Strips`: a sliver costs `n^2 (2q - 1)`, about `2 L S` for `S >= 1` and `2 L` below (coarse count
///   `n ~ S`, `q ~ L / n`), so `N_e = N_tri (2 gamma^2 mean(L S) + gamma mean(L))`, or the uniform figure where
///   that is lower (the pattern falls back to uniform triangle by triangle).
pub fn expected_point_count(sizes: &TriangleSizes, cell_size: f64, gamma: f64, pattern: SubdivisionPattern) -> f64 {
    let n = sizes.triangles as f64;
    let c = gamma / cell_size;
    let uniform = n * (c * c * sizes.mean_longest_squared + c * sizes.mean_longest_edge);
    let estimate = match pattern {
        SubdivisionPattern::Uniform => uniform,
        SubdivisionPattern::Strips => {
            uniform.min(n * (2.0 * c * c * sizes.mean_longest_times_shortest + c * sizes.mean_longest_edge))
        }
    };
    estimate.max(n)
}

/// Which sub-triangles of a subdivided triangle are enumerated (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LatticeRange {
    /// Coarse segments per edge.
    pub n: u32,
    /// Strips per coarse sub-triangle (1: the uniform pattern).
    pub strips: u32,
    /// Which diagonal cuts the strips' trapezoids (see [`Subdivision::diagonal`]).
    pub diagonal: u32,
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
    /// The whole triangle by the uniform pattern, `n * n` sub-triangles.
    pub fn full(n: u32) -> Self {
        Self { n, strips: 1, diagonal: 0, u_start: 0, v_start: 0, width: 0, height: 0 }
    }

    /// The whole triangle, subdivided as `sub` says.
    pub fn whole(sub: &Subdivision) -> Self {
        Self { strips: sub.strips, diagonal: sub.diagonal, ..Self::full(sub.n) }
    }

    /// Whether this is the full range.
    pub fn is_full(&self) -> bool {
        self.width == 0
    }

    /// Sub-triangles per coarse sub-triangle, `2q - 1`.
    pub fn pieces(&self) -> u32 {
        2 * self.strips - 1
    }

    /// Segments per edge of the fine lattice that holds every corner, `n * q`.
    pub fn fine(&self) -> u32 {
        self.n * self.strips
    }

    /// Number of sub-triangle indices to enumerate (WGSL: `sub_triangle_count`). Some indices of a clipped
    /// range map to no sub-triangle.
    pub fn sub_triangle_count(&self) -> u64 {
        let coarse =
            if self.is_full() { self.n as u64 * self.n as u64 } else { 2 * self.width as u64 * self.height as u64 };
        coarse * self.pieces() as u64
    }
}

/// One sub-triangle: lattice cell `(i, j)` of the coarse lattice, up or down, and the piece of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubTriangle {
    /// Lattice column.
    pub i: u32,
    /// Lattice row.
    pub j: u32,
    /// Up (`(i,j), (i+1,j), (i,j+1)`) or down (`(i+1,j), (i,j+1), (i+1,j+1)`).
    pub up: bool,
    /// Which of the coarse triangle's `2q - 1` pieces (always 0 for the uniform pattern).
    pub piece: u32,
}

/// The sub-triangle with index `s` of a range, or `None` if a clipped range's index falls outside the
/// parent triangle (WGSL: `sub_triangle`, which returns a `valid` flag instead).
#[inline]
pub fn sub_triangle(range: &LatticeRange, s: u32) -> Option<SubTriangle> {
    let n = range.n;
    let pieces = range.pieces();
    let piece = s % pieces;
    let s = s / pieces;
    if range.is_full() {
        let a = s / n;
        let b = s % n;
        if a + b < n {
            Some(SubTriangle { i: b, j: a, up: true, piece })
        } else {
            Some(SubTriangle { i: n - 1 - b, j: n - 1 - a, up: false, piece })
        }
    } else {
        let cell = s >> 1;
        let up = (s & 1) == 0;
        let i = range.u_start + cell % range.width;
        let j = range.v_start + cell / range.width;
        let inside = if up { i + j < n } else { i + j + 1 < n };
        inside.then_some(SubTriangle { i, j, up, piece })
    }
}

/// The corners of a sub-triangle on the fine lattice of [`LatticeRange::fine`] segments per edge (WGSL:
/// `sub_triangle_corners`): for the uniform pattern the up triangle `(i,j), (i+1,j), (i,j+1)` and the
/// down one `(i+1,j+1), (i,j+1), (i+1,j)`; for strips, the pieces of the module docs.
#[inline]
pub fn sub_triangle_corners(range: &LatticeRange, sub: SubTriangle) -> [UVec2; 3] {
    let q = range.strips;
    // The coarse apex and the fine-lattice points k steps from it along e1 (L) and e2 (R).
    let up = sub.up;
    let apex = if up { UVec2::new(sub.i * q, sub.j * q) } else { UVec2::new((sub.i + 1) * q, (sub.j + 1) * q) };
    let l = |k: u32| if up { UVec2::new(apex.x + k, apex.y) } else { UVec2::new(apex.x - k, apex.y) };
    let r = |k: u32| if up { UVec2::new(apex.x, apex.y + k) } else { UVec2::new(apex.x, apex.y - k) };
    if sub.piece == 0 {
        return [l(0), l(1), r(1)];
    }
    let k = sub.piece.div_ceil(2);
    match (sub.piece % 2 == 1, range.diagonal == 0) {
        (true, true) => [l(k), r(k), r(k + 1)],
        (false, true) => [l(k), r(k + 1), l(k + 1)],
        (true, false) => [l(k), r(k), l(k + 1)],
        (false, false) => [r(k), r(k + 1), l(k + 1)],
    }
}

/// Equation 2: the centroid of a sub-triangle, in grid space (WGSL: `sub_triangle_centroid`): the sum of
/// its corners' fine-lattice coordinates times `inv_3n`, which is `1.0 / (3.0 * range.fine() as f32)`,
/// computed once per triangle. For the uniform pattern this is `((3i+1)/3n, (3j+1)/3n)` (up) or
/// `((3i+2)/3n, (3j+2)/3n)` (down).
#[inline]
pub fn sub_triangle_centroid(
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    inv_3n: f32,
    range: &LatticeRange,
    sub: SubTriangle,
) -> Vec3 {
    let [p, q, r] = sub_triangle_corners(range, sub);
    let sum = p + q + r;
    let a = sum.x as f32 * inv_3n;
    let b = sum.y as f32 * inv_3n;
    v0 + e1 * a + e2 * b
}

/// A lattice point `p(a, b)` in grid space (WGSL: `lattice_point`). `inv_n` is `1.0 / n as f32`.
#[inline]
pub fn lattice_point(v0: Vec3, e1: Vec3, e2: Vec3, inv_n: f32, a: u32, b: u32) -> Vec3 {
    v0 + e1 * (a as f32 * inv_n) + e2 * (b as f32 * inv_n)
}

/// The three corners of a sub-triangle in grid space (WGSL: `sub_triangle_vertices`). `inv_n` is
/// `1.0 / range.fine() as f32`.
#[inline]
pub fn sub_triangle_vertices(
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    inv_n: f32,
    range: &LatticeRange,
    sub: SubTriangle,
) -> [Vec3; 3] {
    sub_triangle_corners(range, sub).map(|c| lattice_point(v0, e1, e2, inv_n, c.x, c.y))
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

/// The coarse-lattice rectangle covering the part of a triangle that lies inside the box `[box_min, box_max]` of
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
    Some(LatticeRange { u_start: u0, v_start: v0r, width: u1 - u0, height: v1 - v0r, ..LatticeRange::full(n) })
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
    fn the_estimate_follows_each_pattern() {
        // Slivers 100 cells long and half a cell wide: 199 points each by strips, 10^4 by the uniform pattern.
        let v = [Vec3::ZERO, Vec3::new(100.0, 0.0, 0.0), Vec3::new(100.0, 0.5, 0.0)];
        let sizes = TriangleSizes::of(10, std::iter::repeat_n(v, 10));
        for pattern in [SubdivisionPattern::Strips, SubdivisionPattern::Uniform] {
            let actual = 10.0 * subdivision(v, 1.0, pattern).sub_triangle_count() as f64;
            let estimate = expected_point_count(&sizes, 1.0, 1.0, pattern);
            assert!(estimate >= actual && estimate < 1.5 * actual, "{pattern}: {estimate} vs {actual}");
        }
        // A right triangle with legs of 10 cells: 100 points either way; L = 14.1 and S = 10 estimate 214.
        let v = [Vec3::ZERO, Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 10.0, 0.0)];
        let sizes = TriangleSizes::of(1, std::iter::once(v));
        let estimate = expected_point_count(&sizes, 1.0, 1.0, SubdivisionPattern::Strips);
        assert!((200.0..=215.0).contains(&estimate), "{estimate}");
        // Scaling the mesh is halving the cells is doubling gamma; at least a point per triangle.
        let uniform =
            |sizes: &TriangleSizes, cell, gamma| expected_point_count(sizes, cell, gamma, SubdivisionPattern::Uniform);
        assert_eq!(uniform(&sizes.scaled(2.0), 1.0, 1.0), uniform(&sizes, 0.5, 1.0));
        assert_eq!(uniform(&sizes, 1.0, 2.0), uniform(&sizes, 0.5, 1.0));
        assert_eq!(expected_point_count(&sizes, 1000.0, 1.0, SubdivisionPattern::Strips), 1.0);
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
        let range = LatticeRange { u_start: 0, v_start: 0, width: n, height: n, ..LatticeRange::full(n) };
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
        let range = LatticeRange::full(n);
        for s in 0..n * n {
            let t = sub_triangle(&range, s).unwrap();
            let [a, b, c] = sub_triangle_vertices(v0, e1, e2, inv_n, &range, t);
            let centroid = sub_triangle_centroid(v0, e1, e2, inv_3n, &range, t);
            // The uniform pattern's centroids, as before the strip pattern.
            let k = if t.up { 1 } else { 2 };
            let old = v0 + e1 * ((3 * t.i + k) as f32 * inv_3n) + e2 * ((3 * t.j + k) as f32 * inv_3n);
            assert_eq!(centroid, old);
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

    /// Twice the signed area of a fine-lattice triangle, in lattice units.
    fn doubled_area(c: [UVec2; 3]) -> i64 {
        let [p, q, r] = c.map(|c| c.as_i64vec2());
        (q - p).perp_dot(r - p)
    }

    /// A small deterministic generator (no dependency for one test).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
        fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * scale
        }
    }

    /// Triangles of every shape: slivers along the axes and the diagonals (where the trapezoids' diagonals
    /// are longest), needles, well-shaped ones and tiny ones.
    fn test_triangles() -> Vec<[Vec3; 3]> {
        let mut rng = Lcg(7);
        let mut out = vec![
            // A 100-cell sliver half a cell wide along x.
            [Vec3::ZERO, Vec3::new(100.0, 0.0, 0.0), Vec3::new(100.0, 0.5, 0.0)],
            // The same along the xy diagonal, its short edge across it: both diagonals are long.
            [Vec3::ZERO, Vec3::new(60.0, 60.0, 0.0), Vec3::new(60.5, 59.5, 0.0)],
            // A 40-cell sliver 3.5 cells wide (coarse count 4 or more).
            [Vec3::ZERO, Vec3::new(40.0, 0.0, 3.5), Vec3::new(40.0, 3.5, -0.25)],
        ];
        for _ in 0..400 {
            let a = rng.vec(8.0);
            let (l, w) = (120.0 * rng.next(), 6.0 * rng.next());
            let long = rng.vec(l);
            let short = rng.vec(w);
            let b = a + long;
            let c = match out.len() % 3 {
                0 => b + short,
                1 => a + long * rng.next() + short,
                _ => a + rng.vec(30.0),
            };
            out.push([a, b, c]);
        }
        out
    }

    #[test]
    fn strip_pieces_tile_the_parent_and_span_at_most_one_cell_per_axis() {
        let mut rng = Lcg(11);
        let mut fewer = 0;
        for (t, v) in test_triangles().into_iter().enumerate() {
            let gamma = [1.0, 1.0, 1.5, 2.0][t % 4];
            let uniform = subdivision(v, gamma, SubdivisionPattern::Uniform);
            let sub = subdivision(v, gamma, SubdivisionPattern::Strips);
            assert!(sub.sub_triangle_count() <= uniform.sub_triangle_count(), "{v:?}");
            fewer += (sub.strips > 1) as u32;
            let range = LatticeRange::whole(&sub);
            let fine = range.fine();
            let [v0, v1, v2] = rotate_to_apex(v, sub.apex);
            let (e1, e2) = (v1 - v0, v2 - v0);
            let inv_n = 1.0 / fine as f32;
            let mut pieces = Vec::new();
            let mut area = 0i64;
            for s in 0..range.sub_triangle_count() as u32 {
                let piece = sub_triangle(&range, s).unwrap();
                let c = sub_triangle_corners(&range, piece);
                for p in c {
                    assert!(p.x + p.y <= fine, "{v:?} {sub:?} {piece:?} {c:?}");
                }
                let a = doubled_area(c);
                assert!(a != 0, "a degenerate piece {c:?} of {sub:?}");
                area += a.abs();
                // The pattern's promise: every piece spans at most 1/gamma cell per axis (so at most 8 cells).
                let [a, b, c3] = sub_triangle_vertices(v0, e1, e2, inv_n, &range, piece);
                let extent = a.max(b).max(c3) - a.min(b).min(c3);
                assert!(extent.max_element() * gamma <= 1.0 + 1e-3, "{v:?} {sub:?} {piece:?}: {extent}");
                pieces.push(c.map(|c| c.as_i64vec2()));
            }
            // The pieces cover the parent's area exactly...
            assert_eq!(area, fine as i64 * fine as i64, "{v:?} {sub:?}");
            // ... and do not overlap: a point strictly inside one piece is inside no other.
            for _ in 0..20 {
                let p = &pieces[(rng.next() * pieces.len() as f32) as usize % pieces.len()];
                // A point strictly inside p, in lattice units times 6: weights of at least 1 summing to 6.
                let w0 = 1 + (rng.next() * 3.0) as i64;
                let w1 = 1 + (rng.next() * (5 - w0) as f32) as i64;
                let x = p[0] * w0 + p[1] * w1 + p[2] * (6 - w0 - w1);
                let inside = |q: &[glam::I64Vec2; 3]| {
                    let [a, b, c] = q.map(|c| c * 6);
                    let s = |p: glam::I64Vec2, q: glam::I64Vec2| (q - p).perp_dot(x - p).signum();
                    let o = (b - a).perp_dot(c - a).signum();
                    s(a, b) == o && s(b, c) == o && s(c, a) == o
                };
                assert_eq!(pieces.iter().filter(|q| inside(q)).count(), 1, "{v:?} {sub:?}");
            }
        }
        assert!(fewer > 100, "only {fewer} triangles used strips");
    }

    #[test]
    fn slivers_get_a_count_per_edge() {
        // 100 cells long, half a cell wide, along x: the uniform pattern needs 100^2 pieces, strips 2 * 100 - 1.
        let v = [Vec3::ZERO, Vec3::new(100.0, 0.0, 0.0), Vec3::new(100.0, 0.5, 0.0)];
        assert_eq!(subdivision(v, 1.0, SubdivisionPattern::Uniform).sub_triangle_count(), 10_000);
        let sub = subdivision(v, 1.0, SubdivisionPattern::Strips);
        assert_eq!((sub.n, sub.strips, sub.apex), (1, 100, 0), "{sub:?}");
        assert_eq!(sub.sub_triangle_count(), 199);
        // Along the diagonal with the short edge across it, each trapezoid's diagonal is a rail plus a rung:
        // the strips get shorter (here twice as many) so that it still fits in a cell.
        let v = [Vec3::ZERO, Vec3::new(60.0, 60.0, 0.0), Vec3::new(60.5, 59.5, 0.0)];
        let sub = subdivision(v, 1.0, SubdivisionPattern::Strips);
        assert!(sub.strips > 60 && sub.sub_triangle_count() < 400, "{sub:?}");
        // A well-shaped triangle keeps the uniform pattern, vertex order and all.
        let v = [Vec3::ZERO, Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 10.0, 0.0)];
        assert_eq!(subdivision(v, 1.0, SubdivisionPattern::Strips), Subdivision::uniform(10));
    }

    /// The figure of both patterns (docs/how-it-works.md) on one sliver, drawn from this module: cells, sub-triangles and
    /// their centroids (the cells they set shaded).
    fn pattern_figure() -> String {
        let v = [Vec3::new(0.3, 0.4, 0.0), Vec3::new(12.6, 1.1, 0.0), Vec3::new(12.2, 2.4, 0.0)];
        let (px, w, h) = (40.0f32, 14, 3);
        let mut svg = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"15\">\n\
             <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
            w as f32 * px + 20.0,
            2.0 * (h as f32 * px + 40.0) + 10.0
        );
        for (panel, pattern) in [SubdivisionPattern::Uniform, SubdivisionPattern::Strips].into_iter().enumerate() {
            let top = 10.0 + panel as f32 * (h as f32 * px + 40.0);
            let map = |p: Vec3| (10.0 + p.x * px, top + 24.0 + (h as f32 - p.y) * px);
            let sub = subdivision(v, 1.0, pattern);
            let range = LatticeRange::whole(&sub);
            let [v0, v1, v2] = rotate_to_apex(v, sub.apex);
            let (e1, e2) = (v1 - v0, v2 - v0);
            let (inv_n, inv_3n) = (1.0 / range.fine() as f32, 1.0 / (3.0 * range.fine() as f32));
            let pieces: Vec<_> =
                (0..range.sub_triangle_count() as u32).map(|s| sub_triangle(&range, s).unwrap()).collect();
            let mut set = HashSet::new();
            for &p in &pieces {
                let c = sub_triangle_centroid(v0, e1, e2, inv_3n, &range, p);
                set.insert((c.x.floor() as i32, c.y.floor() as i32));
            }
            svg += &format!(
                "<text x=\"10\" y=\"{}\">{pattern}: {} sub-triangles, {} cells set</text>\n",
                top + 16.0,
                pieces.len(),
                set.len()
            );
            for y in 0..h {
                for x in 0..w {
                    let (sx, sy) = map(Vec3::new(x as f32, (y + 1) as f32, 0.0));
                    let fill = if set.contains(&(x, y)) { "#cfe3ff" } else { "none" };
                    svg += &format!(
                        "<rect x=\"{sx}\" y=\"{sy}\" width=\"{px}\" height=\"{px}\" fill=\"{fill}\" stroke=\"#bbb\"/>\n"
                    );
                }
            }
            for &p in &pieces {
                let corners = sub_triangle_vertices(v0, e1, e2, inv_n, &range, p).map(map);
                let points: Vec<String> = corners.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
                svg += &format!(
                    "<polygon points=\"{}\" fill=\"none\" stroke=\"#2a6\" stroke-width=\"0.6\"/>\n",
                    points.join(" ")
                );
                let (cx, cy) = map(sub_triangle_centroid(v0, e1, e2, inv_3n, &range, p));
                svg += &format!("<circle cx=\"{cx:.1}\" cy=\"{cy:.1}\" r=\"1.6\" fill=\"#c33\"/>\n");
            }
        }
        svg + "</svg>\n"
    }

    #[test]
    fn the_readme_figure_is_drawn_from_this_module() {
        // Rewrite it after a change to the pattern with BLESS=1.
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/images/subdivision_patterns.svg");
        let svg = pattern_figure();
        if std::env::var_os("BLESS").is_some() {
            std::fs::write(path, &svg).unwrap();
        }
        let committed = std::fs::read_to_string(path).unwrap_or_default();
        assert!(committed == svg, "{path} is out of date: run this test with BLESS=1 and commit it");
    }
}
