//! The one outward interface of the voxel grid: a bind group with the levels' texture and a uniform that
//! describes them (`voxel_grid.wgsl`), prepared once per frame for every sampling pass (HAO, the debug
//! views, and any pass of the user's) to bind at [`VOXEL_GRID_GROUP`].

use super::extract::ExtractedVoxelGrid;
use super::prepare::{LevelLayout, MovedOccluder, VoxelizeState};
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{texture_3d, uniform_buffer};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy::render::texture::GpuImage;

/// The bind group index at which `voxel_grid.wgsl` declares its bindings.
pub const VOXEL_GRID_GROUP: u32 = 2;

/// Most levels the uniform describes (WGSL `MAX_VOXEL_LEVELS`).
pub const MAX_VOXEL_LEVELS: usize = crate::cpu::cascade::MAX_CASCADES as usize;

/// One level (WGSL `VoxelLevel`).
#[derive(ShaderType, Clone, Copy, Default, Debug)]
pub struct GpuVoxelLevel {
    /// World position of lattice cell 0 (for cascades half a finest cell below the world origin, the grid's
    /// min corner otherwise).
    pub origin: Vec3,
    /// World-space cell size.
    pub cell_size: f32,
    /// The lattice cell at the window's min corner.
    pub window_min: IVec3,
    /// The level's first texel along z in the texture.
    pub texture_z: u32,
    /// Where the window's min corner is stored (`window_min mod dims` for a cascade, 0 otherwise).
    pub wrap: UVec3,
    #[doc(hidden)]
    pub _pad0: u32,
    /// Cells of the window.
    pub dims: UVec3,
    #[doc(hidden)]
    pub _pad1: u32,
    /// Texels of the level at mip 0 (the dims rounded up to the coarsest mip's texel).
    pub size: UVec3,
    #[doc(hidden)]
    pub _pad2: u32,
}

/// Most moved occluders the uniform lists (WGSL `MAX_MOVED_OCCLUDERS`); more are merged with their
/// neighbours.
pub const MAX_MOVED_OCCLUDERS: usize = 8;

/// The motion a moved occluder is listed with where it is not known (WGSL reads it as "all of it moved").
pub const UNKNOWN_MOTION: f32 = 1.0e30;

/// An occluder whose voxels changed in the last few frames (WGSL `MovedOccluder`; CPU twin
/// [`crate::cpu::temporal::MovedVoxels`]): the world box around it now and last frame, and how far its
/// points moved.
#[derive(ShaderType, Clone, Copy, Default, Debug)]
pub struct GpuMovedOccluder {
    /// Min corner.
    pub min: Vec3,
    /// The farthest any of its points moved since last frame (world units; [`UNKNOWN_MOTION`] where not
    /// known).
    pub motion: f32,
    /// Max corner.
    pub max: Vec3,
    #[doc(hidden)]
    pub _pad: f32,
}

/// The levels (WGSL `VoxelGrid`).
#[derive(ShaderType, Clone, Copy, Default, Debug)]
pub struct GpuVoxelGrid {
    /// The levels, finest first; `level_count` of them are valid.
    pub levels: [GpuVoxelLevel; MAX_VOXEL_LEVELS],
    /// 0 while there is no grid.
    pub level_count: u32,
    /// Mip levels of the texture.
    pub mip_levels: u32,
    /// How many of `moved` are valid.
    pub moved_count: u32,
    /// 1 where the albedo and normal textures hold the voxels' attributes ([`crate::VoxelVolume::attributes`]).
    pub attributes: u32,
    /// Where the voxels changed in the last few frames: the dynamic occluders that moved (turned, deformed,
    /// appeared or went), the static ones added, changed or taken out. Temporal passes keep less history
    /// near them.
    pub moved: [GpuMovedOccluder; MAX_MOVED_OCCLUDERS],
}

impl GpuVoxelGrid {
    pub(crate) fn new(levels: &[LevelLayout], mip_levels: u32, moved: &[MovedOccluder]) -> Self {
        let mut g = GpuVoxelGrid { level_count: levels.len() as u32, mip_levels, ..default() };
        let moved = merge_moved(moved);
        g.moved_count = moved.len() as u32;
        g.moved[..moved.len()].copy_from_slice(&moved);
        for (dst, l) in g.levels.iter_mut().zip(levels) {
            *dst = GpuVoxelLevel {
                origin: l.origin,
                cell_size: l.cell_size,
                window_min: l.window_min,
                texture_z: l.texture_z,
                wrap: l.wrap(),
                dims: l.dims,
                size: l.size,
                ..default()
            };
        }
        g
    }
}

/// At most [`MAX_MOVED_OCCLUDERS`] entries covering `moved`. Past the slots, the boxes are sorted along the
/// axis their centres spread most on and merged in runs cut at the widest gaps, so that groups of occluders
/// far apart stay apart; a merged entry moved as far as the farthest of its occluders. One without bounds is
/// everywhere, moved by an unknown amount.
fn merge_moved(moved: &[MovedOccluder]) -> Vec<GpuMovedOccluder> {
    let entry = |(lo, hi): (Vec3, Vec3), motion: f32| GpuMovedOccluder {
        min: lo,
        max: hi,
        motion: if motion.is_finite() { motion.min(UNKNOWN_MOTION) } else { UNKNOWN_MOTION },
        _pad: 0.0,
    };
    if moved.iter().any(|m| m.bounds.is_none()) {
        return vec![entry((Vec3::splat(-UNKNOWN_MOTION), Vec3::splat(UNKNOWN_MOTION)), f32::INFINITY)];
    }
    let mut boxes: Vec<((Vec3, Vec3), f32)> = moved.iter().filter_map(|m| Some((m.bounds?, m.motion))).collect();
    if boxes.len() <= MAX_MOVED_OCCLUDERS {
        return boxes.into_iter().map(|(b, m)| entry(b, m)).collect();
    }
    let centers = boxes.iter().map(|((lo, hi), _)| (*lo + *hi) * 0.5);
    let (lo, hi) = centers.fold((Vec3::MAX, Vec3::MIN), |(a, b), c| (a.min(c), b.max(c)));
    let axis = (hi - lo).max_position();
    let center = |b: &((Vec3, Vec3), f32)| b.0.0[axis] + b.0.1[axis];
    boxes.sort_by(|a, b| center(a).total_cmp(&center(b)));
    // Cut at the widest gaps between neighbours.
    let mut gaps: Vec<usize> = (1..boxes.len()).collect();
    gaps.sort_by(|&i, &j| {
        (center(&boxes[j]) - center(&boxes[j - 1])).total_cmp(&(center(&boxes[i]) - center(&boxes[i - 1])))
    });
    let mut cuts: Vec<usize> = gaps.into_iter().take(MAX_MOVED_OCCLUDERS - 1).collect();
    cuts.sort_unstable();
    let mut merged = Vec::with_capacity(MAX_MOVED_OCCLUDERS);
    let mut start = 0;
    for end in cuts.into_iter().chain([boxes.len()]) {
        let run = &boxes[start..end];
        let (b, m) = run
            .iter()
            .fold(((Vec3::MAX, Vec3::MIN), 0.0f32), |((lo, hi), m), ((a, b), n)| ((lo.min(*a), hi.max(*b)), m.max(*n)));
        merged.push(entry(b, m));
        start = end;
    }
    merged
}

/// The layout of the voxel grid's bind group, for the pipelines that bind it at [`VOXEL_GRID_GROUP`].
pub fn voxel_grid_layout() -> BindGroupLayoutDescriptor {
    BindGroupLayoutDescriptor::new(
        "hao_voxel_grid_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE | ShaderStages::FRAGMENT,
            (
                texture_3d(TextureSampleType::Float { filterable: false }),
                uniform_buffer::<GpuVoxelGrid>(false),
                texture_3d(TextureSampleType::Float { filterable: false }),
                texture_3d(TextureSampleType::Float { filterable: false }),
            ),
        ),
    )
}

/// The layout of the voxel grid's bind group and a placeholder texture for frames without a grid.
#[derive(Resource)]
pub struct VoxelGridLayout {
    /// Binding 0: the 3D texture; binding 1: the [`GpuVoxelGrid`] uniform; bindings 2 and 3: the albedo and
    /// normal textures.
    pub layout: BindGroupLayoutDescriptor,
    empty_texture: TextureView,
}

impl FromWorld for VoxelGridLayout {
    fn from_world(world: &mut World) -> Self {
        let device = world.resource::<RenderDevice>();
        let queue = world.resource::<RenderQueue>();
        let empty_texture = device
            .create_texture_with_data(
                queue,
                &TextureDescriptor {
                    label: Some("hao_empty_voxels"),
                    size: Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: TextureDimension::D3,
                    format: TextureFormat::R32Float,
                    usage: TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                },
                TextureDataOrder::default(),
                &[0; 4],
            )
            .create_view(&TextureViewDescriptor::default());
        Self { layout: voxel_grid_layout(), empty_texture }
    }
}

/// This frame's voxel grid bind group (always present once the layout exists: with no levels and an empty
/// texture while there is no grid), and the levels it describes.
#[derive(Resource)]
pub struct VoxelGridBindings {
    /// Bind it at [`VOXEL_GRID_GROUP`].
    pub bind_group: BindGroup,
    /// What the uniform holds.
    pub grid: GpuVoxelGrid,
}

/// Prepares [`VoxelGridBindings`] from the levels the voxelization placed this frame.
pub fn prepare_voxel_grid_bindings(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    layout: Res<VoxelGridLayout>,
    cache: Res<PipelineCache>,
    extracted: Res<ExtractedVoxelGrid>,
    state: Res<VoxelizeState>,
    images: Res<RenderAssets<GpuImage>>,
) {
    let texture = extracted.assets.as_ref().and_then(|a| images.get(&a.texture).map(|i| (a, i)));
    let empty = &layout.empty_texture;
    let (grid, view, [albedo, normal]) = match texture {
        Some((assets, image)) if !state.levels().is_empty() => {
            let mut grid = GpuVoxelGrid::new(state.levels(), assets.mip_levels, &state.moved());
            let attributes = assets.attributes.as_ref().and_then(|[a, n]| Some([images.get(a)?, images.get(n)?]));
            grid.attributes = attributes.is_some() as u32;
            let views = attributes.map_or([empty, empty], |[a, n]| [&a.texture_view, &n.texture_view]);
            (grid, &image.texture_view, views)
        }
        _ => (GpuVoxelGrid::default(), empty, [empty, empty]),
    };
    let mut uniform = UniformBuffer::from(grid);
    uniform.set_label(Some("hao_voxel_grid"));
    uniform.write_buffer(&device, &queue);
    let Some(binding) = uniform.binding() else { return };
    let bind_group = device.create_bind_group(
        "hao_voxel_grid_bind_group",
        &cache.get_bind_group_layout(&layout.layout),
        &BindGroupEntries::sequential((view, binding, albedo, normal)),
    );
    commands.insert_resource(VoxelGridBindings { bind_group, grid });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moved_occluders_past_the_slots_are_merged_with_their_neighbours() {
        // 20 occluders in two rows far apart along x: merged into at most 8 entries, none spanning the gap,
        // each moved as far as the farthest of its own.
        let b = |x: f32, motion: f32| MovedOccluder {
            bounds: Some((Vec3::new(x, 0.0, 0.0), Vec3::new(x + 1.0, 1.0, 1.0))),
            motion,
        };
        let moved: Vec<_> =
            (0..10).map(|k| b(k as f32 * 2.0, 0.01)).chain((0..10).map(|k| b(500.0 + k as f32 * 2.0, 0.5))).collect();
        let merged = merge_moved(&moved);
        assert!(merged.len() <= MAX_MOVED_OCCLUDERS);
        assert!(merged.iter().all(|m| m.max.x - m.min.x < 100.0), "{merged:?}");
        for o in &moved {
            let (lo, hi) = o.bounds.unwrap();
            assert!(merged.iter().any(|m| m.min.cmple(lo).all() && m.max.cmpge(hi).all() && m.motion >= o.motion));
        }
        assert!(merged.iter().any(|m| m.motion == 0.01) && merged.iter().any(|m| m.motion == 0.5));
        // Few stay as they are; one without bounds is everywhere, by an unknown motion (finite for WGSL).
        assert_eq!(merge_moved(&[b(0.0, 0.1)]).len(), 1);
        let everywhere = merge_moved(&[b(0.0, 0.1), MovedOccluder { bounds: None, motion: 0.1 }]);
        assert_eq!(
            (everywhere.len(), everywhere[0].max, everywhere[0].motion),
            (1, Vec3::splat(UNKNOWN_MOTION), UNKNOWN_MOTION)
        );
        assert_eq!(merge_moved(&[b(0.0, f32::INFINITY)])[0].motion, UNKNOWN_MOTION);
    }
}
