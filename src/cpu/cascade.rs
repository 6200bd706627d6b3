//! Camera-following cascades: the CPU twin of the plugin's default voxel volume.
//!
//! A cascade *level* is a window of `cells^3` cells of an unbounded lattice anchored half a finest cell below
//! the world origin on every axis ([`CascadeShape::lattice_origin`]: lattice cell `c` covers
//! `origin + [c, c + 1] * cell_size` in world space); level `l + 1` has twice the cell size of level `l`.
//! The half cell puts the planes that scenes are built on (a floor at y = 0, walls and boxes on whole or
//! eighth metres) in the middle of the finest cells rather than on their faces: a surface on a face fills
//! the whole cell on one side of it, a cell thicker toward that side, while in the middle it stands half a
//! cell out on each side, as the march's estimate (half a cell into the first occupied cell) takes it.
//! Each window is centred on the focus (the camera) and snapped to whole multiples of [`SCROLL_STEP`] cells
//! of its own level, so a voxel never moves relative to the world (no swimming) and
//! the windows nest: level `l` always lies inside level `l + 1`.
//!
//! On the GPU a level is stored toroidally (lattice cell `c` lives at `c mod cells`), so when the window
//! moves only the cells that came into it are voxelized again: [`entered_regions`] gives those slabs, at
//! most one per axis; a move of a whole window or more rebuilds the level. Because a point belongs to the
//! cell `floor(p)` of the lattice whatever region is being voxelized
//! ([`super::voxelize::lattice_cell`]), voxelizing the slabs gives the same cells as voxelizing the whole
//! window again: the tests hold a scrolled GPU level to a fresh CPU voxelization of its window.
//!
//! The snapping step is the texel of the coarsest mip of the voxel texture ([`CASCADE_MIP_LEVELS`]): with the
//! window's origin a multiple of it, every mip texel covers one contiguous block of the lattice, so the
//! march's empty-space skipping works on the wrapped storage as on a plain grid.

use super::grid::{GridError, VoxelGrid};
use super::voxelize::InjectionRegion;
use glam::{Affine3A, IVec3, UVec3, Vec3};

/// Mip levels of a cascade's voxel texture (level `m` covers `2^m` cells per axis per texel).
pub const CASCADE_MIP_LEVELS: u32 = 4;

/// The windows move in steps of this many cells of their own level (the coarsest mip texel).
pub const SCROLL_STEP: u32 = 1 << (CASCADE_MIP_LEVELS - 1);

/// Where the lattice is anchored, in finest cells below the world origin on each axis
/// ([`CascadeShape::lattice_origin`]).
pub const LATTICE_OFFSET_CELLS: f32 = 0.5;

/// Most cascade levels.
pub const MAX_CASCADES: u32 = 8;

/// Fewest cells per axis of a cascade level.
pub const MIN_CASCADE_CELLS: u32 = 2 * SCROLL_STEP;

/// The largest lattice coordinate a window may reach (so that lattice coordinates stay exact in `f32`).
pub const MAX_LATTICE_COORD: f32 = (1 << 23) as f32;

/// The shape of a set of cascades: how many levels, cells per axis, and the finest level's cell size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CascadeShape {
    /// Levels (1 to [`MAX_CASCADES`]).
    pub levels: u32,
    /// Cells per axis of every level (a multiple of [`SCROLL_STEP`], at least [`MIN_CASCADE_CELLS`]).
    pub cells: u32,
    /// World-space cell size of level 0; level `l` has `finest_cell_size * 2^l`.
    pub finest_cell_size: f32,
}

/// Why a [`CascadeShape`] or a window cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub enum CascadeError {
    /// The level count is 0 or above [`MAX_CASCADES`].
    BadLevelCount(u32),
    /// The cell count is below [`MIN_CASCADE_CELLS`] or not a multiple of [`SCROLL_STEP`].
    BadCellCount(u32),
    /// A level's grid is invalid (cell size not finite and positive, too many voxels).
    Grid(GridError),
    /// The focus is not finite, or so far from the world origin that the lattice loses precision.
    BadFocus(Vec3),
}

impl std::fmt::Display for CascadeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CascadeError::BadLevelCount(n) => write!(f, "cascade levels must be 1 to {MAX_CASCADES}, got {n}"),
            CascadeError::BadCellCount(n) => write!(
                f,
                "cascade cells per axis must be a multiple of {SCROLL_STEP} and at least {MIN_CASCADE_CELLS}, got {n}"
            ),
            CascadeError::Grid(e) => write!(f, "{e}"),
            CascadeError::BadFocus(p) => {
                write!(f, "the cascades' focus {p} is not finite or too far from the world origin for the lattice")
            }
        }
    }
}

impl std::error::Error for CascadeError {}

impl CascadeShape {
    /// Checks the shape: level and cell counts in range, every level's cell size finite and positive.
    pub fn validate(&self) -> Result<(), CascadeError> {
        if self.levels == 0 || self.levels > MAX_CASCADES {
            return Err(CascadeError::BadLevelCount(self.levels));
        }
        if self.cells < MIN_CASCADE_CELLS || !self.cells.is_multiple_of(SCROLL_STEP) {
            return Err(CascadeError::BadCellCount(self.cells));
        }
        let coarsest = self.cell_size(self.levels - 1);
        if !(self.finest_cell_size.is_finite() && self.finest_cell_size > 0.0 && coarsest.is_finite()) {
            return Err(CascadeError::Grid(GridError::BadCellSize(self.finest_cell_size)));
        }
        let voxels = self.cells as u64 * self.cells as u64 * self.cells as u64 * self.levels as u64;
        if voxels > u32::MAX as u64 {
            return Err(CascadeError::Grid(GridError::TooManyVoxels(voxels)));
        }
        Ok(())
    }

    /// The world position of every level's lattice cell 0 (its min corner): half a finest cell below the
    /// world origin on each axis, so that planes at whole multiples of the finest cell lie in the middle of
    /// their cells (see the module's documentation). The levels share it, so their lattices nest.
    pub fn lattice_origin(&self) -> Vec3 {
        Vec3::splat(-LATTICE_OFFSET_CELLS * self.finest_cell_size)
    }

    /// The world-space cell size of level `level`.
    pub fn cell_size(&self, level: u32) -> f32 {
        self.finest_cell_size * (1u64 << level.min(62)) as f32
    }

    /// The levels' windows around `focus` (see [`cascade_window`]).
    pub fn levels_at(&self, focus: Vec3) -> Result<Vec<CascadeLevel>, CascadeError> {
        self.validate()?;
        let origin = self.lattice_origin();
        (0..self.levels)
            .map(|l| {
                let cell_size = self.cell_size(l);
                let window_min =
                    cascade_window(focus - origin, cell_size, self.cells).map_err(|_| CascadeError::BadFocus(focus))?;
                Ok(CascadeLevel { origin, cell_size, cells: self.cells, window_min })
            })
            .collect()
    }
}

/// One level of a set of cascades: its cell size and the window of the lattice it holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CascadeLevel {
    /// World position of lattice cell 0's min corner ([`CascadeShape::lattice_origin`]).
    pub origin: Vec3,
    /// World-space cell size.
    pub cell_size: f32,
    /// Cells per axis.
    pub cells: u32,
    /// The lattice cell at the window's min corner (a multiple of [`SCROLL_STEP`]).
    pub window_min: IVec3,
}

impl CascadeLevel {
    /// One past the window's last lattice cell.
    pub fn window_max(&self) -> IVec3 {
        self.window_min + IVec3::splat(self.cells as i32)
    }

    /// The whole window as an injection region (half-open cells, no closed faces).
    pub fn region(&self) -> InjectionRegion {
        InjectionRegion {
            min: self.window_min,
            max: self.window_max(),
            window_min: self.window_min,
            closed_max: IVec3::MAX,
        }
    }

    /// World space to this level's lattice (anchored at [`Self::origin`], cells of side 1).
    pub fn grid_from_world(&self) -> Affine3A {
        Affine3A::from_scale(Vec3::splat(1.0 / self.cell_size)) * Affine3A::from_translation(-self.origin)
    }

    /// The window as a plain grid (origin at its min corner), e.g. for an occupancy stored relative to it.
    pub fn window_grid(&self) -> Result<VoxelGrid, GridError> {
        VoxelGrid::new(
            self.origin + self.window_min.as_vec3() * self.cell_size,
            self.cell_size,
            UVec3::splat(self.cells),
        )
    }
}

/// The lattice cell at the min corner of a window of `cells` cells of side `cell_size` around `focus` (relative
/// to the lattice's origin): the focus's cell snapped down to a multiple of [`SCROLL_STEP`], minus half the
/// window.
pub fn cascade_window(focus: Vec3, cell_size: f32, cells: u32) -> Result<IVec3, CascadeError> {
    let p = focus / cell_size;
    if !p.is_finite() || p.abs().max_element() > MAX_LATTICE_COORD - 2.0 * cells as f32 {
        return Err(CascadeError::BadFocus(focus));
    }
    let step = SCROLL_STEP as f32;
    let snapped = ((p / step).floor() * step).as_ivec3();
    Ok(snapped - IVec3::splat(cells as i32 / 2))
}

/// The boxes of lattice cells `[min, max)` that a window of `cells` cells takes in when it moves from
/// `old_min` to `new_min`: at most one slab per axis, disjoint. `None` when the move is a window or more
/// along some axis (nothing is kept: rebuild the level).
pub fn entered_regions(old_min: IVec3, new_min: IVec3, cells: u32) -> Option<Vec<(IVec3, IVec3)>> {
    let n = cells as i32;
    if (new_min - old_min).abs().max_element() >= n {
        return None;
    }
    let old_max = old_min + IVec3::splat(n);
    let mut lo = new_min;
    let mut hi = new_min + IVec3::splat(n);
    let mut out = Vec::new();
    for axis in 0..3 {
        if lo[axis] < old_min[axis] {
            let mut max = hi;
            max[axis] = old_min[axis];
            out.push((lo, max));
            lo[axis] = old_min[axis];
        }
        if hi[axis] > old_max[axis] {
            let mut min = lo;
            min[axis] = old_max[axis];
            out.push((min, hi));
            hi[axis] = old_max[axis];
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> CascadeShape {
        CascadeShape { levels: 4, cells: 32, finest_cell_size: 0.25 }
    }

    #[test]
    fn planes_on_whole_cells_lie_in_the_middle_of_the_finest_cells() {
        let s = shape();
        let levels = s.levels_at(Vec3::new(0.3, 1.2, -0.7)).unwrap();
        let g = levels[0].grid_from_world();
        // A floor at y = 0 and a wall at x = 2 finest cells: half a cell into their cells.
        assert_eq!(g.transform_point3(Vec3::new(0.5, 0.0, 0.5 * 0.25)).y, 0.5);
        assert_eq!(g.transform_point3(Vec3::new(2.0 * 0.25, 0.1, 0.0)).x, 2.5);
        // The window's grid is the same lattice.
        let w = levels[0].window_grid().unwrap();
        let p = Vec3::new(0.3, 0.0, 0.1);
        assert!((w.world_to_grid(p) + levels[0].window_min.as_vec3() - g.transform_point3(p)).length() < 1.0e-4);
        // Coarser levels share the origin, so their lattices nest.
        for l in &levels {
            assert_eq!(l.origin, Vec3::splat(-0.125));
        }
    }

    #[test]
    fn windows_are_snapped_centred_and_nested() {
        let s = shape();
        for focus in [Vec3::ZERO, Vec3::new(3.3, -7.1, 100.9), Vec3::new(-1234.5, 2.0, 999.0)] {
            let levels = s.levels_at(focus).unwrap();
            for (l, level) in levels.iter().enumerate() {
                assert_eq!(level.cell_size, 0.25 * (1 << l) as f32);
                assert_eq!(level.window_min % SCROLL_STEP as i32, IVec3::ZERO);
                // The focus lies within a step of the window's centre.
                let centre = level.origin + (level.window_min.as_vec3() + Vec3::splat(16.0)) * level.cell_size;
                assert!(((focus - centre) / level.cell_size).abs().max_element() <= SCROLL_STEP as f32);
                if l > 0 {
                    // Level l-1's window lies inside level l's.
                    let inner = levels[l - 1];
                    assert!((inner.window_min).cmpge(level.window_min * 2).all());
                    assert!((inner.window_max()).cmple(level.window_max() * 2).all());
                }
            }
        }
        // Moving within a step keeps every window: voxels do not swim.
        let a = s.levels_at(Vec3::new(0.1, 0.1, 0.1)).unwrap();
        let b = s.levels_at(Vec3::new(1.8, 0.1, 0.1)).unwrap();
        assert_eq!(a, b);
        assert!(s.levels_at(Vec3::new(f32::NAN, 0.0, 0.0)).is_err());
        assert!(s.levels_at(Vec3::new(1.0e12, 0.0, 0.0)).is_err());
        assert!(CascadeShape { levels: 0, ..s }.validate().is_err());
        assert!(CascadeShape { cells: 20, ..s }.validate().is_err());
        assert!(CascadeShape { finest_cell_size: 0.0, ..s }.validate().is_err());
        assert!(CascadeShape { finest_cell_size: f32::NAN, ..s }.validate().is_err());
        assert!(CascadeShape { levels: 8, cells: 1024, ..s }.validate().is_err());
    }

    #[test]
    fn entered_regions_cover_exactly_the_new_cells() {
        let n = 16u32;
        let cases = [IVec3::new(8, 0, 0), IVec3::new(-8, 8, 0), IVec3::new(8, -8, 8), IVec3::ZERO];
        for d in cases {
            let old = IVec3::new(-8, 0, 16);
            let new = old + d;
            let boxes = entered_regions(old, new, n).unwrap();
            let in_box = |c: IVec3, min: IVec3, max: IVec3| c.cmpge(min).all() && c.cmplt(max).all();
            let mut count = 0;
            for z in new.z..new.z + 16 {
                for y in new.y..new.y + 16 {
                    for x in new.x..new.x + 16 {
                        let c = IVec3::new(x, y, z);
                        let covered = boxes.iter().filter(|(a, b)| in_box(c, *a, *b)).count();
                        let entered = !in_box(c, old, old + IVec3::splat(16));
                        assert_eq!(covered, entered as usize, "{c} for a move of {d}");
                        count += covered;
                    }
                }
            }
            let total: i32 = boxes.iter().map(|(a, b)| (*b - *a).element_product()).sum();
            assert_eq!(total as usize, count);
            assert!(boxes.len() <= 3);
        }
        assert_eq!(entered_regions(IVec3::ZERO, IVec3::new(0, 16, 0), n), None);
    }
}
