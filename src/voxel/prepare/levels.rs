//! The volume's levels as placed this frame (a single grid, or the cascades around the camera), and boxes
//! of their lattice cells.

use super::super::volume::VoxelGridAssets;
use crate::cpu::{self, VoxelGrid};
use bevy::math::{Affine3A, IVec3};
use bevy::platform::collections::HashSet;
use bevy::prelude::*;

/// A box of lattice cells, `[min, max)`.
pub(crate) type CellBox = (IVec3, IVec3);

pub(super) fn union(a: CellBox, b: CellBox) -> CellBox {
    (a.0.min(b.0), a.1.max(b.1))
}

pub(super) fn intersect(a: CellBox, b: CellBox) -> Option<CellBox> {
    let r = (a.0.max(b.0), a.1.min(b.1));
    r.0.cmplt(r.1).all().then_some(r)
}

/// Workgroups of 4x4x4 covering a box.
pub(super) fn groups4(b: CellBox) -> UVec3 {
    ((b.1 - b.0).max(IVec3::ZERO).as_uvec3() + UVec3::splat(3)) / 4
}

pub(super) fn cells(b: CellBox) -> u64 {
    (b.1 - b.0).max(IVec3::ZERO).as_u64vec3().element_product()
}

/// Cells along each side of a brick (texels, at a mip): the unit in which small scattered changes (dynamic
/// occluders, static ones streamed in) are resolved into the texture, so that a few occluders far apart
/// cost their own cells rather than the box around them all; one workgroup of 4x4x4 each. WGSL:
/// `voxelize_common.wgsl`, `BRICK_CELLS`.
pub(super) const BRICK_CELLS: i32 = 4;

/// Adds the bricks (lattice cell / `BRICK_CELLS`) a box of cells touches to `out`.
pub(super) fn add_bricks(b: CellBox, out: &mut HashSet<IVec3>) {
    let lo = b.0.div_euclid(IVec3::splat(BRICK_CELLS));
    let hi = (b.1 - IVec3::ONE).div_euclid(IVec3::splat(BRICK_CELLS));
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                out.insert(IVec3::new(x, y, z));
            }
        }
    }
}

/// The bricks a box of cells touches, without listing them.
pub(super) fn brick_count(b: CellBox) -> u64 {
    let lo = b.0.div_euclid(IVec3::splat(BRICK_CELLS));
    let hi = (b.1 - IVec3::ONE).div_euclid(IVec3::splat(BRICK_CELLS));
    (hi - lo + IVec3::ONE).max(IVec3::ZERO).as_u64vec3().element_product()
}

/// One level of the volume as placed this frame: a single grid, or a cascade with its window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LevelLayout {
    /// World position of lattice cell 0.
    pub origin: Vec3,
    /// World-space cell size.
    pub cell_size: f32,
    /// Cells of the window.
    pub dims: UVec3,
    /// Texels of the level in the texture at mip 0.
    pub size: UVec3,
    /// The lattice cell at the window's min corner.
    pub window_min: IVec3,
    /// Stored toroidally (a cascade) rather than as a plain grid.
    pub toroidal: bool,
    /// The level's first voxel in the occupancy and count buffers.
    pub voxel_base: u32,
    /// The level's first texel along z in the texture.
    pub texture_z: u32,
}

impl LevelLayout {
    /// World space to the level's lattice.
    pub fn grid_from_world(&self) -> Affine3A {
        VoxelGrid { origin: self.origin, cell_size: self.cell_size, dims: self.dims }.grid_from_world()
    }

    /// Where the window's min corner is stored.
    pub fn wrap(&self) -> UVec3 {
        if self.toroidal { self.window_min.rem_euclid(self.dims.as_ivec3()).as_uvec3() } else { UVec3::ZERO }
    }

    /// The window as a box of cells.
    pub fn window(&self) -> CellBox {
        (self.window_min, self.window_min + self.dims.as_ivec3())
    }

    /// The injection region of a box of the window (cpu: `InjectionRegion`).
    pub fn region(&self, b: CellBox) -> cpu::InjectionRegion {
        cpu::InjectionRegion {
            min: b.0,
            max: b.1,
            window_min: self.window_min,
            closed_max: if self.toroidal { IVec3::MAX } else { self.dims.as_ivec3() },
        }
    }

    /// The cells of the window a world-space box touches, padded by a cell.
    pub fn cells_of_box(&self, min: Vec3, max: Vec3) -> Option<CellBox> {
        let g = self.grid_from_world();
        let lo = g.transform_point3(min).floor() - Vec3::ONE;
        let hi = g.transform_point3(max).ceil() + Vec3::ONE;
        if !(lo.is_finite() && hi.is_finite()) {
            return Some(self.window());
        }
        let (w0, w1) = self.window();
        let lo = lo.clamp(w0.as_vec3(), w1.as_vec3()).as_ivec3();
        let hi = hi.clamp(w0.as_vec3(), w1.as_vec3()).as_ivec3();
        lo.cmplt(hi).all().then_some((lo, hi))
    }

    /// The world-space box of a box of cells.
    pub(super) fn world_box(&self, b: CellBox) -> (Vec3, Vec3) {
        let inv = self.grid_from_world().inverse();
        (inv.transform_point3(b.0.as_vec3()), inv.transform_point3(b.1.as_vec3()))
    }
}

/// This frame's levels: a single grid, or the cascades placed around the focus. `None` while the cascades
/// have no focus (no camera with HAO) or it is unusable.
pub(crate) fn place_levels(assets: &VoxelGridAssets, focus: Option<Vec3>) -> Option<Vec<LevelLayout>> {
    let g = assets.grid;
    let level_voxels = g.voxel_count() as u32;
    match assets.cascades {
        None => Some(vec![LevelLayout {
            origin: g.origin,
            cell_size: g.cell_size,
            dims: g.dims,
            size: assets.texture_size,
            window_min: IVec3::ZERO,
            toroidal: false,
            voxel_base: 0,
            texture_z: 0,
        }]),
        Some(shape) => {
            let levels = shape.levels_at(focus?).ok()?;
            Some(
                levels
                    .iter()
                    .enumerate()
                    .map(|(l, c)| LevelLayout {
                        origin: c.origin,
                        cell_size: c.cell_size,
                        dims: UVec3::splat(c.cells),
                        size: assets.texture_size,
                        window_min: c.window_min,
                        toroidal: true,
                        voxel_base: l as u32 * level_voxels,
                        texture_z: l as u32 * assets.texture_size.z,
                    })
                    .collect(),
            )
        }
    }
}
