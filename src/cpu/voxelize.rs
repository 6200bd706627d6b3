//! The point-tessellated voxelizer (the CPU reference of the GPU passes): per triangle, equation 1 picks the
//! subdivision, the lattice pattern of [`super::tessellation`] cuts it into sub-triangles smaller than a cell,
//! and each sub-triangle is injected, in one of two modes:
//!
//! * [`InjectionMode::Centroid`], the paper's: the sub-triangle's centroid (equation 2) sets its cell and adds
//!   one to the cell's point count. Gap-free in practice, not conservative: a cell that a sub-triangle only
//!   grazes can be missed (the paper's Figure 9), which is the *bias*.
//! * [`InjectionMode::Conservative`], the paper's future work: a sub-triangle spans at most one cell per axis,
//!   so it touches at most the 8 cells of its (slightly padded) bounding box; each of those candidates is
//!   tested with the exact overlap test against the parent triangle and set if it overlaps. In exact arithmetic
//!   testing the parent is the same as testing the sub-triangle (the sub-triangles tile the parent, so every
//!   cell the parent overlaps is a candidate of a sub-triangle that overlaps it); in floating point it makes
//!   the result match the ground truth exactly, since both use the same test. The point count of a cell is
//!   then the number of sub-triangles that set it. The factor is computed with `max(gamma, 1)` in this mode,
//!   since the 8-cell bound needs it.
//!
//! Triangles with a non-finite vertex or zero area ([`triangle_is_degenerate`]) are skipped and counted;
//! so are triangles wholly outside the grid, and the ones needing more than
//! [`MAX_SUB_TRIANGLES_PER_TRIANGLE`] sub-triangles. Parts of a triangle outside the grid are clipped away
//! before enumeration ([`clipped_lattice_range`]), so a huge triangle costs only what lies inside.

use super::attributes::{MeshAlbedo, TriangleAttributes, centroid_weights, face_normal, point_sample};
use super::grid::{VoxelGrid, VoxelOccupancy};
use super::mesh::TriangleMesh;
use super::overlap::OverlapTriangle;
use super::tessellation::*;
use glam::{Affine3A, IVec3, UVec3, Vec3};
use std::ops::AddAssign;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How sub-triangles mark voxels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum InjectionMode {
    /// One point per sub-triangle at its centroid (the paper).
    #[default]
    Centroid,
    /// Every cell a sub-triangle's bounds touch is tested exactly (no voxel of the ground truth is missed).
    Conservative,
}

impl std::str::FromStr for InjectionMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "centroid" => Ok(Self::Centroid),
            "conservative" => Ok(Self::Conservative),
            _ => Err(format!("unknown injection mode '{s}' (expected centroid or conservative)")),
        }
    }
}

impl std::fmt::Display for InjectionMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Centroid => "centroid",
            Self::Conservative => "conservative",
        })
    }
}

/// The smallest and largest safety factor accepted; others are clamped into this range.
pub const GAMMA_RANGE: (f32, f32) = (1.0 / 16.0, 16.0);

/// Padding, in cells, of a sub-triangle's bounds when collecting conservative candidates; it absorbs the
/// rounding of the lattice points (a few ulp of coordinates up to 4096). WGSL: `CONSERVATIVE_PAD`.
pub const CONSERVATIVE_PAD: f32 = 1.0 / 256.0;

/// Settings of the point-tessellated voxelizer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelizeSettings {
    /// The safety factor gamma of equation 1 (clamped to [`GAMMA_RANGE`]).
    pub gamma: f32,
    /// Centroid or conservative injection.
    pub mode: InjectionMode,
    /// How triangles are cut into sub-triangles.
    pub pattern: SubdivisionPattern,
}

impl Default for VoxelizeSettings {
    fn default() -> Self {
        Self { gamma: 1.0, mode: InjectionMode::Centroid, pattern: SubdivisionPattern::Strips }
    }
}

impl VoxelizeSettings {
    /// The gamma actually used for the factors: clamped, and at least 1 in conservative mode.
    pub fn effective_gamma(&self) -> f32 {
        let g = if self.gamma.is_finite() { self.gamma } else { 1.0 };
        let g = g.clamp(GAMMA_RANGE.0, GAMMA_RANGE.1);
        match self.mode {
            InjectionMode::Centroid => g,
            InjectionMode::Conservative => g.max(1.0),
        }
    }
}

/// What a voxelization run did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VoxelizeStats {
    /// Triangles read.
    pub triangles: u64,
    /// Triangles skipped for a non-finite vertex or an index out of range.
    pub invalid: u64,
    /// Triangles skipped for zero area.
    pub degenerate: u64,
    /// Triangles wholly outside the grid.
    pub outside: u64,
    /// Triangles skipped for needing more than [`MAX_SUB_TRIANGLES_PER_TRIANGLE`] sub-triangles.
    pub oversize: u64,
    /// Triangles wholly inside the grid with at most [`INLINE_SUB_TRIANGLES`] sub-triangles (the GPU injects
    /// these in the pass that reads them).
    pub small: u64,
    /// Sub-triangles generated (centroid mode: points generated).
    pub sub_triangles: u64,
    /// Injections that landed in the grid: points (centroid) or sub-triangle/cell overlaps (conservative).
    pub injected: u64,
    /// Exact overlap tests run (conservative mode).
    pub overlap_tests: u64,
}

impl AddAssign for VoxelizeStats {
    fn add_assign(&mut self, o: Self) {
        self.triangles += o.triangles;
        self.invalid += o.invalid;
        self.degenerate += o.degenerate;
        self.outside += o.outside;
        self.oversize += o.oversize;
        self.small += o.small;
        self.sub_triangles += o.sub_triangles;
        self.injected += o.injected;
        self.overlap_tests += o.overlap_tests;
    }
}

/// Whether a grid-space triangle has zero area: its edge cross product, in `f64` on the `f32` vertices (so
/// nearly exact), is zero. WGSL: `triangle_is_degenerate`, the same test in `f32`, which can also call a
/// sliver of area below `f32` precision degenerate.
#[inline]
pub fn triangle_is_degenerate(v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
    let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    (b - a).cross(c - a) == glam::DVec3::ZERO
}

/// Transforms a triangle to grid space with `grid_from_local` (WGSL: `grid_space_position`, which spells
/// out the same sum `x_axis * p.x + y_axis * p.y + z_axis * p.z + translation`).
#[inline]
pub fn grid_space_position(grid_from_local: &Affine3A, p: Vec3) -> Vec3 {
    let m = &grid_from_local.matrix3;
    Vec3::from(m.x_axis * p.x + m.y_axis * p.y + m.z_axis * p.z + grid_from_local.translation)
}

/// The box of lattice cells a voxelization writes, and how lattice cells map to the occupancy's storage:
/// the whole grid ([`InjectionRegion::whole`]), or a part of a cascade level whose window may start anywhere
/// in an unbounded lattice (WGSL: the region fields of `VoxelizeParams`).
///
/// A point belongs to the cell `floor(p)` whatever the region: voxelizing a box in pieces sets the same
/// cells as voxelizing it whole, which is what lets a cascade re-voxelize only the slabs it scrolls into.
/// The one exception is the closed upper faces of a single grid (`closed_max`): a point exactly on them
/// belongs to the last cell, as [`super::grid::cell_of_point`] has it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InjectionRegion {
    /// First lattice cell of the box.
    pub min: IVec3,
    /// One past the last lattice cell of the box.
    pub max: IVec3,
    /// The lattice cell stored at cell `(0, 0, 0)` of the occupancy (a level's window min corner).
    pub window_min: IVec3,
    /// Planes on which a point belongs to the cell below (a grid's upper faces); `IVec3::MAX` for none.
    pub closed_max: IVec3,
}

impl InjectionRegion {
    /// The whole of a single grid of `dims` cells, closed on its upper faces.
    pub fn whole(dims: UVec3) -> Self {
        let d = dims.as_ivec3();
        Self { min: IVec3::ZERO, max: d, window_min: IVec3::ZERO, closed_max: d }
    }

    /// The box as grid-space floats, for placement and clipping.
    #[inline]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.min.as_vec3(), self.max.as_vec3())
    }

    /// Whether the box holds no cell.
    pub fn is_empty(&self) -> bool {
        self.max.cmple(self.min).any()
    }
}

/// The lattice cell a grid-space point injects into, or `None` if it lies outside the region (or is NaN)
/// (WGSL: `lattice_cell`).
#[inline]
pub fn lattice_cell(p: Vec3, region: &InjectionRegion) -> Option<IVec3> {
    let (lo, hi) = region.bounds();
    // Written so that NaN fails every comparison and is rejected.
    if !(p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z) {
        return None;
    }
    let floor = p.floor().as_ivec3();
    let cell = IVec3::select(p.cmpeq(region.closed_max.as_vec3()), floor - IVec3::ONE, floor);
    (cell.cmpge(region.min).all() && cell.cmplt(region.max).all()).then_some(cell)
}

/// The index in an occupancy of `dims` cells of a lattice cell inside the region.
#[inline]
pub(crate) fn storage_index(cell: IVec3, region: &InjectionRegion, dims: UVec3) -> u32 {
    linear_index((cell - region.window_min).as_uvec3(), dims)
}

/// Voxelizes one grid-space triangle into `out`. Returns what it did.
pub fn voxelize_triangle(v: [Vec3; 3], settings: &VoxelizeSettings, out: &VoxelOccupancy) -> VoxelizeStats {
    voxelize_triangle_in_region(v, settings, &InjectionRegion::whole(out.grid().dims), out)
}

/// Voxelizes one grid-space triangle into the cells of `region`, stored in `out` relative to the region's
/// window. Returns what it did. Its points sample white (see [`voxelize_sampled_triangle_in_region`]).
pub fn voxelize_triangle_in_region(
    v: [Vec3; 3],
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    voxelize_sampled_triangle_in_region(v, &TriangleAttributes::WHITE, settings, region, out)
}

/// [`voxelize_triangle_in_region`] for a triangle with attributes: where `out` keeps attribute sums, each
/// point adds its albedo and normal ([`super::attributes`]).
pub fn voxelize_sampled_triangle_in_region(
    v: [Vec3; 3],
    attributes: &TriangleAttributes,
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    let mut stats = VoxelizeStats { triangles: 1, ..Default::default() };
    let [v0, v1, v2] = v;
    if !(v0.is_finite() && v1.is_finite() && v2.is_finite()) {
        stats.invalid = 1;
        return stats;
    }
    if triangle_is_degenerate(v0, v1, v2) {
        stats.degenerate = 1;
        return stats;
    }
    let dims = out.grid().dims;
    let (box_min, box_max) = region.bounds();
    let placement = grid_placement(v0, v1, v2, box_min, box_max);
    if placement == GridPlacement::Outside {
        stats.outside = 1;
        return stats;
    }
    let sub = subdivision(v, settings.effective_gamma(), settings.pattern);
    let n = sub.n;
    if n > MAX_SUBDIVISION {
        stats.oversize = 1;
        return stats;
    }
    let sub_apex = sub.apex;
    let [v0, v1, v2] = rotate_to_apex(v, sub.apex);
    let (e1, e2) = (v1 - v0, v2 - v0);
    let range = match placement {
        GridPlacement::Inside => LatticeRange::whole(&sub),
        _ => match clipped_lattice_range(v0, e1, e2, n, box_min, box_max) {
            Some(r) => LatticeRange { strips: sub.strips, diagonal: sub.diagonal, ..r },
            None => {
                stats.outside = 1;
                return stats;
            }
        },
    };
    let count = range.sub_triangle_count();
    if count > MAX_SUB_TRIANGLES_PER_TRIANGLE {
        stats.oversize = 1;
        return stats;
    }
    if placement == GridPlacement::Inside && count <= INLINE_SUB_TRIANGLES {
        stats.small = 1;
    }
    // Only where the sums are kept: a plain voxelization pays nothing for them.
    let normal = if out.has_attributes() { face_normal(v, attributes) } else { Vec3::ZERO };
    let inv_3n = 1.0 / (3.0 * range.fine() as f32);
    let sample = |sub| point_sample(attributes, centroid_weights(&range, sub, sub_apex, inv_3n), normal);
    match settings.mode {
        InjectionMode::Centroid => {
            for s in 0..count as u32 {
                let Some(sub) = sub_triangle(&range, s) else { continue };
                stats.sub_triangles += 1;
                let p = sub_triangle_centroid(v0, e1, e2, inv_3n, &range, sub);
                if let Some(cell) = lattice_cell(p, region) {
                    out.inject_point(storage_index(cell, region, dims), || sample(sub));
                    stats.injected += 1;
                }
            }
        }
        InjectionMode::Conservative => {
            // The parent in its own vertex order, so that the test is the ground truth's to the last bit.
            let parent = OverlapTriangle::new(v[0], v[1], v[2]);
            let inv_n = 1.0 / range.fine() as f32;
            for s in 0..count as u32 {
                let Some(sub) = sub_triangle(&range, s) else { continue };
                stats.sub_triangles += 1;
                let [a, b, c] = sub_triangle_vertices(v0, e1, e2, inv_n, &range, sub);
                let (lo, hi) = conservative_candidate_cells(a, b, c, region);
                for z in lo.z..=hi.z {
                    for y in lo.y..=hi.y {
                        for x in lo.x..=hi.x {
                            let cell = IVec3::new(x, y, z);
                            stats.overlap_tests += 1;
                            if parent.overlaps_lattice_cell(cell) {
                                out.inject_point(storage_index(cell, region, dims), || sample(sub));
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

/// The inclusive cell range a sub-triangle can touch: its bounds padded by [`CONSERVATIVE_PAD`], clamped to
/// the region (empty, `lo > hi`, if it misses it). WGSL: `conservative_candidate_cells`.
#[inline]
pub fn conservative_candidate_cells(a: Vec3, b: Vec3, c: Vec3, region: &InjectionRegion) -> (IVec3, IVec3) {
    let lo = (a.min(b).min(c) - Vec3::splat(CONSERVATIVE_PAD)).floor().as_ivec3().max(region.min);
    let hi = (a.max(b).max(c) + Vec3::splat(CONSERVATIVE_PAD)).floor().as_ivec3().min(region.max - IVec3::ONE);
    (lo, hi)
}

#[inline]
fn linear_index(c: UVec3, dims: UVec3) -> u32 {
    c.x + dims.x * (c.y + dims.y * c.z)
}

/// Triangles handed to a thread at a time.
const CHUNK: usize = 512;

/// Runs `per_triangle` over every triangle of `mesh` (transformed to grid space by `grid_from_local`) on all
/// available cores, summing the stats (`None` for a degenerate or non-finite triangle). Shared by the
/// voxelizer and the ground truth of `bevy_hao_tools`.
pub fn for_each_grid_triangle<S: Default + AddAssign + Send>(
    mesh: &TriangleMesh,
    grid_from_local: Affine3A,
    per_triangle: impl Fn(Option<[Vec3; 3]>) -> S + Sync,
) -> S {
    for_each_indexed_grid_triangle(mesh, grid_from_local, |_, v| per_triangle(v))
}

/// [`for_each_grid_triangle`], with each triangle's index.
fn for_each_indexed_grid_triangle<S: Default + AddAssign + Send>(
    mesh: &TriangleMesh,
    grid_from_local: Affine3A,
    per_triangle: impl Fn(usize, Option<[Vec3; 3]>) -> S + Sync,
) -> S {
    let next = AtomicUsize::new(0);
    let total = mesh.triangles.len();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(total.div_ceil(CHUNK)).max(1);
    let work = || {
        let mut stats = S::default();
        loop {
            let start = next.fetch_add(CHUNK, Ordering::Relaxed);
            if start >= total {
                break;
            }
            for t in start..(start + CHUNK).min(total) {
                let v = mesh.triangle(t).map(|v| v.map(|p| grid_space_position(&grid_from_local, p)));
                stats += per_triangle(t, v);
            }
        }
        stats
    };
    if threads == 1 {
        return work();
    }
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads).map(|_| scope.spawn(work)).collect();
        let mut sum = S::default();
        for h in handles {
            sum += h.join().expect("voxelizer thread panicked");
        }
        sum
    })
}

/// Voxelizes a mesh into `out` (which is not cleared first), on all cores. `grid_from_local` maps the
/// mesh's positions to grid space, e.g. `grid.grid_from_world() * world_from_local`.
pub fn voxelize_mesh(
    mesh: &TriangleMesh,
    grid_from_local: Affine3A,
    settings: &VoxelizeSettings,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    for_each_grid_triangle(mesh, grid_from_local, |v| match v {
        Some(v) => voxelize_triangle(v, settings, out),
        None => VoxelizeStats { triangles: 1, invalid: 1, ..Default::default() },
    })
}

/// Voxelizes a mesh into the cells of `region` of `out` (see [`InjectionRegion`]), on all cores.
pub fn voxelize_mesh_in_region(
    mesh: &TriangleMesh,
    grid_from_local: Affine3A,
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    for_each_grid_triangle(mesh, grid_from_local, |v| match v {
        Some(v) => voxelize_triangle_in_region(v, settings, region, out),
        None => VoxelizeStats { triangles: 1, invalid: 1, ..Default::default() },
    })
}

/// [`voxelize_mesh_in_region`] with the mesh's albedo: where `out` keeps attribute sums
/// ([`VoxelOccupancy::with_attributes`]), each point adds its albedo and normal. On all cores.
pub fn voxelize_sampled_mesh_in_region(
    mesh: &TriangleMesh,
    albedo: &MeshAlbedo,
    grid_from_local: Affine3A,
    settings: &VoxelizeSettings,
    region: &InjectionRegion,
    out: &VoxelOccupancy,
) -> VoxelizeStats {
    for_each_indexed_grid_triangle(mesh, grid_from_local, |t, v| match v {
        Some(v) => {
            let attributes = albedo.triangle(mesh.triangles[t], &grid_from_local);
            voxelize_sampled_triangle_in_region(v, &attributes, settings, region, out)
        }
        None => VoxelizeStats { triangles: 1, invalid: 1, ..Default::default() },
    })
}

/// Convenience: voxelizes a world-space mesh into a fresh occupancy grid (with point counts).
pub fn voxelize(mesh: &TriangleMesh, grid: &VoxelGrid, settings: &VoxelizeSettings) -> (VoxelOccupancy, VoxelizeStats) {
    let out = VoxelOccupancy::new(*grid, true);
    let stats = voxelize_mesh(mesh, grid.grid_from_world(), settings, &out);
    (out, stats)
}
