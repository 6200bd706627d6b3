//! The resolve passes planned: the frame's occupancy bits into the voxel texture and its mips, over the
//! cells that may have changed. Static regions and rebuilt levels resolve as boxes; scattered changes
//! (dynamic occluders now and last frame, static occluders streamed in) as a list of bricks, so that a
//! thousand small movers far apart cost their own cells, not the box around them all.

use super::levels::{BRICK_CELLS, CellBox, LevelLayout, cells, groups4};
use super::upload::uniform;
use crate::voxel::pipelines::GpuLevelRegion;
use bevy::math::IVec3;
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;

/// Bricks in one brick pass at most (one workgroup each along z, under WebGPU's 65535); a level with more
/// resolves the box around its changes instead.
pub(super) const MAX_BRICKS: usize = 16_384;

/// One box or brick list of one level to resolve into the texture.
pub struct ResolveWork {
    /// Bits to mip 0.
    pub bind_group: BindGroup,
    /// Workgroups of 4x4x4.
    pub workgroups: UVec3,
    /// One per further mip level.
    pub mips: Vec<(BindGroup, UVec3)>,
}

/// What the resolve passes of a frame bind, whatever the level.
pub(super) struct ResolveBindings<'a> {
    pub device: &'a RenderDevice,
    pub resolve_layout: &'a BindGroupLayout,
    pub mip_layout: &'a BindGroupLayout,
    /// One view per mip of the voxel texture.
    pub views: &'a [TextureView],
    pub occupancy: &'a Buffer,
    /// The frame's per-voxel records (a placeholder where point counts are off).
    pub records: &'a Buffer,
    pub albedo: &'a TextureView,
    pub normal: &'a TextureView,
    /// Words of a voxel's record where attributes are resolved, else 0.
    pub sample_words: u32,
    /// Bound as the brick list of box passes.
    pub dummy: &'a Buffer,
}

/// A box of a level at a mip, the same box at mip 0 rounded out to whole texels.
fn box_at_mip(b: CellBox, mip: u32) -> CellBox {
    let s = IVec3::splat(1 << mip);
    (b.0.div_euclid(s), (b.1 + s - IVec3::ONE).div_euclid(s))
}

/// The uniform of one resolve or mip pass of `level` over `b` (at `mip`; the clip of a brick pass).
fn params(level: &LevelLayout, b: CellBox, mip: u32, brick_pass: bool, sample_words: u32) -> GpuLevelRegion {
    GpuLevelRegion {
        region_min: b.0,
        texture_z: level.texture_z >> mip,
        region_max: b.1,
        voxel_base: level.voxel_base,
        window_min: level.window_min >> mip as i32,
        brick_pass: brick_pass as u32,
        wrap: level.wrap() >> mip,
        sample_words,
        dims: level.dims,
        _pad2: 0,
        size: level.size >> mip,
        _pad3: 0,
    }
}

/// The bricks of the mips of a level over a set of bricks at mip 0, one list per mip: a brick at mip `m + 1`
/// wherever one of its eight children is at mip `m`, so every brick pass runs whole workgroups.
pub(super) fn brick_mips(bricks: &HashSet<IVec3>, mip_levels: u32) -> Vec<Vec<IVec3>> {
    let mut lists: Vec<Vec<IVec3>> = Vec::with_capacity(mip_levels as usize);
    let mut list: Vec<IVec3> = bricks.iter().copied().collect();
    for _ in 0..mip_levels {
        list.sort_unstable_by_key(|b| (b.z, b.y, b.x));
        list.dedup();
        let next = list.iter().map(|b| b.div_euclid(IVec3::splat(2))).collect();
        lists.push(std::mem::replace(&mut list, next));
    }
    lists
}

/// Texels written by the brick passes of `lists` and by the box passes of `b`, over every mip.
pub(super) fn brick_and_box_texels(lists: &[Vec<IVec3>], b: CellBox) -> (u64, u64) {
    let per_brick = (BRICK_CELLS as u64).pow(3);
    let bricks = lists.iter().map(|l| l.len() as u64 * per_brick).sum();
    let boxes = (0..lists.len() as u32).map(|m| cells(box_at_mip(b, m))).sum();
    (bricks, boxes)
}

impl ResolveBindings<'_> {
    fn pass(&self, level: &LevelLayout, b: CellBox, bricks: Option<&Buffer>) -> BindGroup {
        let p =
            uniform(self.device, "hao_voxel_resolve_params", &params(level, b, 0, bricks.is_some(), self.sample_words));
        self.device.create_bind_group(
            "hao_voxel_resolve_bind_group",
            self.resolve_layout,
            &BindGroupEntries::sequential((
                p.as_entire_binding(),
                self.occupancy.as_entire_binding(),
                &self.views[0],
                self.records.as_entire_binding(),
                self.albedo,
                self.normal,
                bricks.unwrap_or(self.dummy).as_entire_binding(),
            )),
        )
    }

    fn mip(&self, level: &LevelLayout, b: CellBox, mip: u32, bricks: Option<&Buffer>) -> BindGroup {
        let p =
            uniform(self.device, "hao_voxel_mip_params", &params(level, b, mip, bricks.is_some(), self.sample_words));
        self.device.create_bind_group(
            "hao_voxel_mip_bind_group",
            self.mip_layout,
            &BindGroupEntries::sequential((
                p.as_entire_binding(),
                &self.views[mip as usize - 1],
                &self.views[mip as usize],
                bricks.unwrap_or(self.dummy).as_entire_binding(),
            )),
        )
    }

    /// The resolve of a box of cells of `level` and of its footprint in every mip.
    pub fn resolve_box(&self, level: &LevelLayout, b: CellBox) -> ResolveWork {
        let bind_group = self.pass(level, b, None);
        let mips = (1..self.views.len() as u32)
            .map(|mip| {
                let mb = box_at_mip(b, mip);
                (self.mip(level, mb, mip, None), groups4(mb))
            })
            .collect();
        ResolveWork { bind_group, workgroups: groups4(b), mips }
    }

    /// The resolve of bricks of `level`, one list per mip ([`brick_mips`]; each at most [`MAX_BRICKS`]),
    /// clipped to its window.
    pub fn resolve_bricks(&self, level: &LevelLayout, lists: &[Vec<IVec3>]) -> ResolveWork {
        let window = level.window();
        let mut passes = lists.iter().enumerate().map(|(mip, list)| {
            debug_assert!(!list.is_empty() && list.len() <= MAX_BRICKS);
            let data: Vec<IVec4> = list.iter().map(|b| b.extend(0)).collect();
            let buffer = self.device.create_buffer_with_data(&BufferInitDescriptor {
                label: Some("hao_voxel_resolve_bricks"),
                contents: bytemuck::cast_slice(&data),
                usage: BufferUsages::STORAGE,
            });
            let mip = mip as u32;
            let clip = box_at_mip(window, mip);
            let bind_group = if mip == 0 {
                self.pass(level, clip, Some(&buffer))
            } else {
                self.mip(level, clip, mip, Some(&buffer))
            };
            (bind_group, UVec3::new(1, 1, list.len() as u32))
        });
        let (bind_group, workgroups) = passes.next().expect("a list per mip");
        ResolveWork { bind_group, workgroups, mips: passes.collect() }
    }
}
