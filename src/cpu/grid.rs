//! The voxel grid: world bounds cut into cubic cells, and the occupancy it holds.
//!
//! Grid space is world space translated to the grid's origin (its min corner) and scaled so that one cell has
//! side 1: cell `(x, y, z)` covers `[x, x+1] x [y, y+1] x [z, z+1]` in grid space. The WGSL side uses the same
//! space (`grid_from_local` matrices are composed on the CPU and uploaded).

use super::attributes::{SAMPLE_WORDS, VoxelAttributes, resolve_sample};
use glam::{Affine3A, UVec3, Vec3};
use std::sync::atomic::{AtomicU32, Ordering};

/// Why a [`VoxelGrid`] could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum GridError {
    /// The cell size is zero, negative or not finite.
    BadCellSize(f32),
    /// A dimension is zero.
    EmptyDimension(UVec3),
    /// The bounds are not finite or have no extent along any axis.
    BadBounds {
        /// The min corner given.
        min: Vec3,
        /// The max corner given.
        max: Vec3,
    },
    /// The grid would have more voxels than `u32` linear indices can address.
    TooManyVoxels(u64),
}

impl std::fmt::Display for GridError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GridError::BadCellSize(s) => write!(f, "voxel cell size must be finite and positive, got {s}"),
            GridError::EmptyDimension(d) => write!(f, "voxel grid dimensions must be at least 1, got {d}"),
            GridError::BadBounds { min, max } => {
                write!(f, "voxel grid bounds must be finite with a positive extent, got {min} .. {max}")
            }
            GridError::TooManyVoxels(n) => write!(f, "a voxel grid of {n} voxels exceeds 2^32 voxels"),
        }
    }
}

impl std::error::Error for GridError {}

/// Relative margin added to a fitted cell size so that the mesh's max corner falls inside the last cell
/// instead of exactly on (or, by rounding, just beyond) the grid's upper faces.
pub const FIT_MARGIN: f32 = 1.0e-5;

/// A regular grid of cubic cells: `dims` cells per axis (not necessarily a cube), side `cell_size`, min corner
/// at `origin` in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelGrid {
    /// World-space position of the grid's min corner.
    pub origin: Vec3,
    /// World-space side length of one cell (the paper's `l_cell`).
    pub cell_size: f32,
    /// Number of cells along x, y and z.
    pub dims: UVec3,
}

impl VoxelGrid {
    /// A grid with the given origin, cell size and dimensions.
    pub fn new(origin: Vec3, cell_size: f32, dims: UVec3) -> Result<Self, GridError> {
        // A cell size whose inverse is not finite (a denormal) would make grid space infinite.
        if !(cell_size.is_finite() && cell_size >= f32::MIN_POSITIVE && (1.0 / cell_size).is_finite()) {
            return Err(GridError::BadCellSize(cell_size));
        }
        if dims.min_element() == 0 {
            return Err(GridError::EmptyDimension(dims));
        }
        if !origin.is_finite() {
            return Err(GridError::BadBounds { min: origin, max: origin });
        }
        let count = dims.x as u128 * dims.y as u128 * dims.z as u128;
        if count > u32::MAX as u128 {
            return Err(GridError::TooManyVoxels(count.min(u64::MAX as u128) as u64));
        }
        // The corners in world space and in grid space (world / cell size) must be finite.
        let max = origin + dims.as_vec3() * cell_size;
        let inv = 1.0 / cell_size;
        if !(max.is_finite() && (origin * inv).is_finite() && (max * inv).is_finite()) {
            return Err(GridError::BadBounds { min: origin, max });
        }
        Ok(Self { origin, cell_size, dims })
    }

    /// The grid that covers `min..max` with `resolution` cells along the longest axis and cubic cells, so
    /// the other axes get as many cells as their extent needs (at least one). The cell size carries a
    /// relative margin of [`FIT_MARGIN`] so that geometry on the max faces lands inside the grid.
    pub fn fit_to_bounds(min: Vec3, max: Vec3, resolution: u32) -> Result<Self, GridError> {
        let extent = max - min;
        if !min.is_finite() || !max.is_finite() || extent.max_element() <= 0.0 || extent.min_element() < 0.0 {
            return Err(GridError::BadBounds { min, max });
        }
        let resolution = resolution.max(1);
        let cell_size = extent.max_element() / resolution as f32 * (1.0 + FIT_MARGIN);
        let cells = (extent / cell_size).ceil().max(Vec3::ONE);
        let dims = cells.as_uvec3().min(UVec3::splat(resolution));
        Self::new(min, cell_size, dims)
    }

    /// The grid covering the world-space box `min..max` with cells of side `cell_size` (dimensions rounded up).
    pub fn from_bounds_and_cell_size(min: Vec3, max: Vec3, cell_size: f32) -> Result<Self, GridError> {
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(GridError::BadCellSize(cell_size));
        }
        let extent = max - min;
        if !min.is_finite() || !max.is_finite() || extent.min_element() < 0.0 {
            return Err(GridError::BadBounds { min, max });
        }
        let dims = (extent / cell_size).ceil().max(Vec3::ONE);
        if !dims.is_finite() || dims.max_element() > u32::MAX as f32 {
            return Err(GridError::TooManyVoxels(u64::MAX));
        }
        Self::new(min, cell_size, dims.as_uvec3())
    }

    /// Number of voxels (cells) in the grid.
    pub fn voxel_count(&self) -> u64 {
        self.dims.x as u64 * self.dims.y as u64 * self.dims.z as u64
    }

    /// Number of 32-bit words of a bit-packed occupancy grid (one bit per voxel).
    pub fn occupancy_word_count(&self) -> usize {
        self.voxel_count().div_ceil(32) as usize
    }

    /// World-space max corner.
    pub fn world_max(&self) -> Vec3 {
        self.origin + self.dims.as_vec3() * self.cell_size
    }

    /// The affine map from world space to grid space (cells of side 1, origin at the grid's min corner).
    pub fn grid_from_world(&self) -> Affine3A {
        let inv = 1.0 / self.cell_size;
        Affine3A::from_scale(Vec3::splat(inv)) * Affine3A::from_translation(-self.origin)
    }

    /// World space to grid space.
    pub fn world_to_grid(&self, p: Vec3) -> Vec3 {
        self.grid_from_world().transform_point3(p)
    }

    /// Grid space to world space.
    pub fn grid_to_world(&self, g: Vec3) -> Vec3 {
        self.origin + g * self.cell_size
    }

    /// World-space center of a cell.
    pub fn cell_center_world(&self, cell: UVec3) -> Vec3 {
        self.grid_to_world(cell.as_vec3() + Vec3::splat(0.5))
    }

    /// The cell holding a grid-space point, the grid being closed on its upper faces (a point exactly on the
    /// max face belongs to the last cell). `None` outside the grid or for a non-finite point. The WGSL twin is
    /// `cell_of_point` in `voxelize_common.wgsl`.
    pub fn cell_of_point(&self, p: Vec3) -> Option<UVec3> {
        cell_of_point(p, self.dims)
    }

    /// Linear index `x + dims.x * (y + dims.y * z)` of a cell (x fastest, z slowest).
    pub fn linear_index(&self, cell: UVec3) -> u32 {
        cell.x + self.dims.x * (cell.y + self.dims.y * cell.z)
    }

    /// Inverse of [`Self::linear_index`].
    pub fn cell_of_index(&self, index: u32) -> UVec3 {
        let x = index % self.dims.x;
        let yz = index / self.dims.x;
        UVec3::new(x, yz % self.dims.y, yz / self.dims.y)
    }
}

/// See [`VoxelGrid::cell_of_point`]; the same rule as WGSL `cell_of_point`.
#[inline]
pub fn cell_of_point(p: Vec3, dims: UVec3) -> Option<UVec3> {
    let d = dims.as_vec3();
    // Written so that NaN fails every comparison and is rejected.
    if !(p.x >= 0.0 && p.y >= 0.0 && p.z >= 0.0 && p.x <= d.x && p.y <= d.y && p.z <= d.z) {
        return None;
    }
    Some(p.floor().as_uvec3().min(dims - UVec3::ONE))
}

/// A bit-packed occupancy grid (one bit per voxel, 32 voxels per `u32` word in linear-index order) plus an
/// optional per-voxel point count and, optionally with it, per-voxel albedo and normal sums (see
/// [`super::attributes`]): the multi-valued result of point-tessellated voxelization.
///
/// Words and counts are atomics so that several threads inject into one grid, as GPU invocations do with
/// `atomicOr` and `atomicAdd`; read them once the writers are done.
#[derive(Debug)]
pub struct VoxelOccupancy {
    grid: VoxelGrid,
    words: Vec<AtomicU32>,
    counts: Option<Vec<AtomicU32>>,
    /// Albedo and normal sums, `SAMPLE_WORDS - 1` words per voxel (kept with counts only).
    attributes: Option<Vec<AtomicU32>>,
}

const ATTRIBUTE_WORDS: usize = SAMPLE_WORDS as usize - 1;

fn snapshot(v: &[AtomicU32]) -> Vec<u32> {
    v.iter().map(|w| w.load(Ordering::Relaxed)).collect()
}

fn atomics(v: impl IntoIterator<Item = u32>) -> Vec<AtomicU32> {
    v.into_iter().map(AtomicU32::new).collect()
}

impl Clone for VoxelOccupancy {
    fn clone(&self) -> Self {
        Self {
            grid: self.grid,
            words: self.words.iter().map(|w| AtomicU32::new(w.load(Ordering::Relaxed))).collect(),
            counts: self.counts.as_ref().map(|c| atomics(snapshot(c))),
            attributes: self.attributes.as_ref().map(|c| atomics(snapshot(c))),
        }
    }
}

impl VoxelOccupancy {
    /// An empty occupancy grid; `with_counts` also allocates one `u32` point count per voxel.
    pub fn new(grid: VoxelGrid, with_counts: bool) -> Self {
        let words = (0..grid.occupancy_word_count()).map(|_| AtomicU32::new(0)).collect();
        let counts = with_counts.then(|| (0..grid.voxel_count()).map(|_| AtomicU32::new(0)).collect());
        Self { grid, words, counts, attributes: None }
    }

    /// An empty occupancy grid with point counts and albedo and normal sums per voxel.
    pub fn with_attributes(grid: VoxelGrid) -> Self {
        let attributes = Some(atomics(std::iter::repeat_n(0, grid.voxel_count() as usize * ATTRIBUTE_WORDS)));
        Self { attributes, ..Self::new(grid, true) }
    }

    /// An occupancy grid from bit-packed words and the GPU's per-voxel records (`sample_words` words per
    /// voxel: 1 for point counts, [`SAMPLE_WORDS`] for counts and attribute sums). `None` if a slice is too
    /// short or `sample_words` is neither.
    pub fn from_records(grid: VoxelGrid, words: &[u32], records: &[u32], sample_words: u32) -> Option<Self> {
        let n = grid.voxel_count() as usize;
        let stride = sample_words as usize;
        if !(stride == 1 || stride == SAMPLE_WORDS as usize) || records.len() < n * stride {
            return None;
        }
        let counts: Vec<u32> = records[..n * stride].iter().step_by(stride).copied().collect();
        let mut occ = Self::from_words(grid, words, Some(&counts))?;
        if stride > 1 {
            let sums = records[..n * stride].chunks_exact(stride).flat_map(|r| r[1..].iter().copied());
            occ.attributes = Some(atomics(sums));
        }
        Some(occ)
    }
    /// An occupancy grid from bit-packed words (e.g. read back from the GPU). Bits past the last voxel are
    /// ignored. Returns `None` if `words` is too short.
    pub fn from_words(grid: VoxelGrid, words: &[u32], counts: Option<&[u32]>) -> Option<Self> {
        let n = grid.occupancy_word_count();
        if words.len() < n || counts.is_some_and(|c| (c.len() as u64) < grid.voxel_count()) {
            return None;
        }
        let occ = Self {
            grid,
            words: words[..n].iter().map(|&w| AtomicU32::new(w)).collect(),
            counts: counts.map(|c| c[..grid.voxel_count() as usize].iter().map(|&w| AtomicU32::new(w)).collect()),
            attributes: None,
        };
        occ.mask_tail();
        Some(occ)
    }

    fn mask_tail(&self) {
        let rem = (self.grid.voxel_count() % 32) as u32;
        if rem != 0 {
            let last = self.words.last().expect("a grid has at least one voxel");
            last.fetch_and((1u32 << rem) - 1, Ordering::Relaxed);
        }
    }

    /// The grid this occupancy lives on.
    pub fn grid(&self) -> &VoxelGrid {
        &self.grid
    }

    /// Whether per-voxel point counts are kept.
    pub fn has_counts(&self) -> bool {
        self.counts.is_some()
    }

    /// Whether per-voxel albedo and normal sums are kept.
    pub fn has_attributes(&self) -> bool {
        self.attributes.is_some()
    }

    /// Sets the voxel with linear index `index` and, if counts are kept, adds 1 to its count
    /// (WGSL: `inject_voxel`, for a grid without attribute sums).
    #[inline]
    pub fn inject_voxel(&self, index: u32) {
        self.words[(index >> 5) as usize].fetch_or(1u32 << (index & 31), Ordering::Relaxed);
        if let Some(counts) = &self.counts {
            counts[index as usize].fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Injects a point: [`Self::inject_voxel`], and if attribute sums are kept, adds the point's sample
    /// (`sample` is called only then; see [`super::attributes::point_sample`]). WGSL: `inject_voxel`.
    #[inline]
    pub fn inject_point(&self, index: u32, sample: impl FnOnce() -> [u32; 6]) {
        self.inject_voxel(index);
        if let Some(sums) = &self.attributes {
            let base = index as usize * ATTRIBUTE_WORDS;
            for (k, v) in sample().into_iter().enumerate() {
                sums[base + k].fetch_add(v, Ordering::Relaxed);
            }
        }
    }

    /// The record of the voxel with linear index `index` as the GPU keeps it: its point count and attribute
    /// sums ([`SAMPLE_WORDS`] words; zeros where not kept).
    pub fn record(&self, index: u32) -> [u32; SAMPLE_WORDS as usize] {
        let mut r = [0; SAMPLE_WORDS as usize];
        if let Some(c) = &self.counts {
            r[0] = c[index as usize].load(Ordering::Relaxed);
        }
        if let Some(a) = &self.attributes {
            let base = index as usize * ATTRIBUTE_WORDS;
            for (k, w) in r[1..].iter_mut().enumerate() {
                *w = a[base + k].load(Ordering::Relaxed);
            }
        }
        r
    }

    /// A voxel's average albedo and normal (`None` without attribute sums or points).
    pub fn attributes(&self, cell: UVec3) -> Option<VoxelAttributes> {
        self.attributes.as_ref()?;
        resolve_sample(&self.record(self.grid.linear_index(cell)))
    }

    /// Sets one voxel (no count change).
    pub fn set(&self, cell: UVec3) {
        let i = self.grid.linear_index(cell);
        self.words[(i >> 5) as usize].fetch_or(1u32 << (i & 31), Ordering::Relaxed);
    }

    /// Whether a voxel is set.
    pub fn is_set(&self, cell: UVec3) -> bool {
        self.is_set_index(self.grid.linear_index(cell))
    }

    /// Whether the voxel with a linear index is set.
    #[inline]
    pub fn is_set_index(&self, index: u32) -> bool {
        self.words[(index >> 5) as usize].load(Ordering::Relaxed) >> (index & 31) & 1 == 1
    }

    /// Point count of a voxel (0 when counts are not kept).
    pub fn count(&self, cell: UVec3) -> u32 {
        self.counts.as_ref().map_or(0, |c| c[self.grid.linear_index(cell) as usize].load(Ordering::Relaxed))
    }

    /// Number of set voxels.
    pub fn set_voxel_count(&self) -> u64 {
        self.words.iter().map(|w| w.load(Ordering::Relaxed).count_ones() as u64).sum()
    }

    /// Sum of all point counts (0 when counts are not kept).
    pub fn total_count(&self) -> u64 {
        self.counts.as_ref().map_or(0, |c| c.iter().map(|w| w.load(Ordering::Relaxed) as u64).sum())
    }

    /// Largest point count of any voxel (0 when counts are not kept).
    pub fn max_count(&self) -> u32 {
        self.counts.as_ref().map_or(0, |c| c.iter().map(|w| w.load(Ordering::Relaxed)).max().unwrap_or(0))
    }

    /// A snapshot of the bit-packed words.
    pub fn words(&self) -> Vec<u32> {
        self.words.iter().map(|w| w.load(Ordering::Relaxed)).collect()
    }

    /// A snapshot of the per-voxel counts, if kept.
    pub fn counts(&self) -> Option<Vec<u32>> {
        self.counts.as_ref().map(|c| snapshot(c))
    }

    /// Clears all bits, counts and sums.
    pub fn clear(&mut self) {
        self.words.iter_mut().for_each(|w| *w.get_mut() = 0);
        for c in [&mut self.counts, &mut self.attributes].into_iter().flatten() {
            c.iter_mut().for_each(|w| *w.get_mut() = 0);
        }
    }

    /// Number of voxels set here and not in `other` (same grid dimensions required).
    pub fn count_not_in(&self, other: &VoxelOccupancy) -> u64 {
        assert_eq!(self.grid.dims, other.grid.dims, "occupancy grids of different dimensions");
        self.words
            .iter()
            .zip(&other.words)
            .map(|(a, b)| (a.load(Ordering::Relaxed) & !b.load(Ordering::Relaxed)).count_ones() as u64)
            .sum()
    }

    /// The cells set here and not in `other`.
    pub fn cells_not_in(&self, other: &VoxelOccupancy) -> Vec<UVec3> {
        assert_eq!(self.grid.dims, other.grid.dims, "occupancy grids of different dimensions");
        let mut out = Vec::new();
        for (wi, (a, b)) in self.words.iter().zip(&other.words).enumerate() {
            let mut diff = a.load(Ordering::Relaxed) & !b.load(Ordering::Relaxed);
            while diff != 0 {
                let bit = diff.trailing_zeros();
                diff &= diff - 1;
                out.push(self.grid.cell_of_index(wi as u32 * 32 + bit));
            }
        }
        out
    }

    /// Calls `f` with the linear index of every set voxel, in increasing order.
    pub fn for_each_set_index(&self, mut f: impl FnMut(u32)) {
        for (wi, w) in self.words.iter().enumerate() {
            let mut bits = w.load(Ordering::Relaxed);
            while bits != 0 {
                let bit = bits.trailing_zeros();
                bits &= bits - 1;
                f(wi as u32 * 32 + bit);
            }
        }
    }

    /// The set cells, in linear-index order.
    pub fn set_cells(&self) -> Vec<UVec3> {
        let mut out = Vec::new();
        self.for_each_set_index(|i| out.push(self.grid.cell_of_index(i)));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_puts_longest_axis_at_resolution_and_keeps_cells_cubic() {
        let g = VoxelGrid::fit_to_bounds(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 1.0, 4.0), 64).unwrap();
        assert_eq!(g.dims, UVec3::new(64, 16, 32));
        assert!((g.cell_size - 4.0 / 64.0).abs() < 1e-6);
        // The max corner lands inside the last cell, not on or past its face.
        let top = g.world_to_grid(Vec3::new(3.0, 1.0, 4.0));
        assert_eq!(g.cell_of_point(top), Some(UVec3::new(63, 15, 31)));
        assert_eq!(g.cell_of_point(g.world_to_grid(Vec3::new(-1.0, 0.0, 2.0))), Some(UVec3::ZERO));
    }

    #[test]
    fn transforms_round_trip() {
        let g = VoxelGrid::new(Vec3::new(1.0, 2.0, 3.0), 0.5, UVec3::new(4, 5, 6)).unwrap();
        let p = Vec3::new(1.7, 2.2, 5.9);
        assert!((g.grid_to_world(g.world_to_grid(p)) - p).length() < 1e-5);
        assert_eq!(g.cell_of_point(g.world_to_grid(p)), Some(UVec3::new(1, 0, 5)));
        assert_eq!(g.cell_of_index(g.linear_index(UVec3::new(3, 4, 5))), UVec3::new(3, 4, 5));
    }

    #[test]
    fn cell_of_point_is_closed_on_upper_faces_and_rejects_outside_and_nan() {
        let d = UVec3::new(4, 4, 4);
        assert_eq!(cell_of_point(Vec3::new(4.0, 0.0, 2.5), d), Some(UVec3::new(3, 0, 2)));
        assert_eq!(cell_of_point(Vec3::new(4.001, 0.0, 0.0), d), None);
        assert_eq!(cell_of_point(Vec3::new(-0.001, 0.0, 0.0), d), None);
        assert_eq!(cell_of_point(Vec3::new(f32::NAN, 0.0, 0.0), d), None);
    }

    #[test]
    fn bad_grids_are_refused() {
        assert!(VoxelGrid::new(Vec3::ZERO, 0.0, UVec3::ONE).is_err());
        assert!(VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::new(1, 0, 1)).is_err());
        assert!(VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(4096)).is_err());
        assert!(VoxelGrid::fit_to_bounds(Vec3::ZERO, Vec3::ZERO, 8).is_err());
        assert!(VoxelGrid::fit_to_bounds(Vec3::ZERO, Vec3::splat(f32::NAN), 8).is_err());
    }

    #[test]
    fn occupancy_bits_counts_and_differences() {
        let g = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::new(5, 3, 3)).unwrap();
        let a = VoxelOccupancy::new(g, true);
        let b = VoxelOccupancy::new(g, false);
        for c in [UVec3::new(0, 0, 0), UVec3::new(4, 2, 2), UVec3::new(1, 1, 1)] {
            a.inject_voxel(g.linear_index(c));
        }
        a.inject_voxel(g.linear_index(UVec3::new(1, 1, 1)));
        b.set(UVec3::new(4, 2, 2));
        assert_eq!(a.set_voxel_count(), 3);
        assert_eq!(a.count(UVec3::new(1, 1, 1)), 2);
        assert_eq!(a.total_count(), 4);
        assert_eq!(a.count_not_in(&b), 2);
        assert_eq!(b.count_not_in(&a), 0);
        assert_eq!(a.cells_not_in(&b), vec![UVec3::ZERO, UVec3::new(1, 1, 1)]);
        let copy = VoxelOccupancy::from_words(g, &a.words(), a.counts().as_deref()).unwrap();
        assert_eq!(copy.words(), a.words());
        assert_eq!(copy.set_cells(), a.set_cells());
    }

    #[test]
    fn extreme_grid_arguments_are_refused_not_panicked_on() {
        let vals = [0.0, -1.0, 1.0e-45, 1.0e-40, 1.0e-6, 1.0, 1.0e6, 1.0e30, f32::MAX, f32::INFINITY, f32::NAN];
        let counts = [0, 1, 7, 128, 1 << 20, u32::MAX];
        for &a in &vals {
            for &b in &vals {
                let (lo, hi) = (Vec3::splat(-a), Vec3::new(b, a, b));
                for &n in &counts {
                    if let Ok(g) = VoxelGrid::fit_to_bounds(lo, hi, n) {
                        assert!(g.voxel_count() <= u32::MAX as u64 && g.grid_from_world().is_finite());
                    }
                }
                for &c in &vals {
                    if let Ok(g) = VoxelGrid::from_bounds_and_cell_size(lo, hi, c) {
                        assert!(g.voxel_count() <= u32::MAX as u64 && g.grid_from_world().is_finite());
                    }
                }
            }
        }
        assert!(VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(u32::MAX)).is_err());
        assert!(VoxelGrid::fit_to_bounds(Vec3::ZERO, Vec3::splat(1.0e-40), 128).is_err());
        assert!(VoxelGrid::from_bounds_and_cell_size(Vec3::ZERO, Vec3::ONE, 1.0e-6).is_err());
    }
}
