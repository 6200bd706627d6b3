//! Prepare: place this frame's levels (a single grid, or the cascades around the camera), bring the
//! occluders' resolution to mesh slabs up to date with what changed, decide what needs voxelizing (static
//! geometry only in the regions that changed: slabs a cascade scrolled into, boxes where a static occluder
//! changed, whole levels when rebuilt; dynamic geometry every frame in every level it overlaps), and build
//! the buffers and bind groups of the passes.
//!
//! - [`levels`]: where the levels are this frame, and boxes of their cells;
//! - [`instances`]: what changed, the occluders resolved to slabs and kept across frames;
//! - [`upload`]: a pass's instances uploaded and grouped into classify dispatches;
//! - [`resolve`]: the occupancy bits resolved into the voxel texture and its mips where they changed;
//! - this file: the passes planned, and their buffers and bind groups.

mod instances;
mod levels;
mod moved;
mod resolve;
mod upload;

pub(crate) use levels::{CellBox, LevelLayout, place_levels};
pub use moved::MovedOccluder;

use super::extract::{ExtractedOccluders, ExtractedVoxelGrid};
use super::pipelines::*;
use super::stats::{CascadeLevelStats, VoxelizationStats};
use super::stats::{STATIC_REGION_SLOTS, counter_base};
use crate::cpu::{self, InjectionMode, SubdivisionPattern};
use bevy::ecs::entity::EntityHashSet;
use bevy::math::IVec3;
use bevy::pbr::SkinUniforms;
#[cfg(feature = "morph")]
use bevy::pbr::{MorphIndices, MorphUniforms};
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::mesh::RenderMesh;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::render_asset::{ExtractedAssets, RenderAssets};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::texture::GpuImage;
use instances::{ResolvedInstance, ResolvedOccluders, Skins};
use levels::{add_bricks, brick_count, cells, groups4, intersect, union};
pub use resolve::ResolveWork;
use resolve::{MAX_BRICKS, ResolveBindings, brick_and_box_texels, brick_mips};
use upload::{build_slab_dispatches, instances_in, settings_buffer};

/// State kept across frames.
#[derive(Resource, Default)]
pub struct VoxelizeState {
    generation: u64,
    /// The levels as voxelized last (empty: nothing is valid).
    levels: Vec<LevelLayout>,
    /// The occluders resolved to mesh slabs.
    occluders: ResolvedOccluders,
    prev_dynamic: Vec<Option<CellBox>>,
    /// Per level, the bricks the dynamic occluders touched last frame (`None`: too many, `prev_dynamic`).
    prev_dynamic_bricks: Vec<Option<HashSet<IVec3>>>,
    had_dynamic: bool,
    rebuild_requests: u64,
    big: Option<BigBuffers>,
    warned_capacity: bool,
    /// The solid pass's scratch (a level's cells, then one bit per column), as long as it is big enough.
    crossings: Option<Buffer>,
    warned_crossings: bool,
}

impl VoxelizeState {
    /// The levels as voxelized this frame (for the bindings consumers read).
    pub(crate) fn levels(&self) -> &[LevelLayout] {
        &self.levels
    }

    /// The occluders whose voxels changed in the last few frames (temporal passes keep less history around
    /// them).
    pub(crate) fn moved(&self) -> Vec<MovedOccluder> {
        self.occluders.moved()
    }
}

struct BigBuffers {
    capacity: u64,
    triangles: Buffer,
    offsets: Buffer,
    dispatch: Buffer,
}

/// One classify dispatch: the instances whose meshes live in one pair of vertex and index slabs.
pub struct SlabDispatch {
    pub bind_group: BindGroup,
    /// Workgroups (x, y).
    pub workgroups: (u32, u32),
}

/// A voxelization pass: one level, one region, static or dynamic geometry.
pub struct VoxelizePass {
    /// The classify dispatches.
    pub slabs: Vec<SlabDispatch>,
    pub bind_group: BindGroup,
    /// The solid fill, when an instance of the pass is [`crate::VoxelFill::Solid`].
    pub solid: Option<SolidPass>,
}

/// The solid fill of a pass (voxelize_solid.wgsl): its crossings over the pass's slabs, then its fill.
pub struct SolidPass {
    /// Group 1 of both.
    pub bind_group: BindGroup,
    /// The scratch buffer, cleared before the crossings.
    pub crossings: Buffer,
    /// Workgroups of the fill (8x8 columns each).
    pub columns: UVec2,
}

/// How a static region is cleared before it is voxelized again.
pub enum StaticClear {
    /// A whole level, by clearing its bytes.
    Level {
        /// (offset, size) in the occupancy buffer.
        occupancy: (u64, u64),
        /// (offset, size) in the point count buffer, if kept.
        counts: Option<(u64, u64)>,
    },
    /// A box of cells, by the clear pass (workgroups of 4x4x4).
    Region(UVec3),
    /// Nothing: occluders added to the static grid as it is.
    Keep,
}

/// A static region: cleared, then voxelized.
pub struct StaticPass {
    /// How it is cleared.
    pub clear: StaticClear,
    /// The voxelization (its bind group also serves the clear pass).
    pub pass: VoxelizePass,
}

/// Everything the voxelize system records this frame; absent on frames with nothing to do.
#[derive(Resource)]
pub struct VoxelizeFrame {
    /// Counter blocks to clear before the passes: (first word, words).
    pub clear_counters: Vec<(u32, u32)>,
    /// Static regions to voxelize again.
    pub static_passes: Vec<StaticPass>,
    /// Dynamic geometry, one pass per level it overlaps.
    pub dynamic_passes: Vec<VoxelizePass>,
    /// Group 0 of scan, expand and clear.
    pub empty_bind_group: BindGroup,
    /// Group 2 of scan.
    pub dispatch_bind_group: BindGroup,
    /// The expand pass's indirect arguments.
    pub dispatch_args: Buffer,
    pub counters: Buffer,
    /// Static occupancy.
    pub static_occupancy: Buffer,
    /// This frame's occupancy.
    pub occupancy: Buffer,
    /// Static and frame point counts, if kept.
    pub counts: Option<(Buffer, Buffer)>,
    /// Bits to texture.
    pub resolve: Vec<ResolveWork>,
}

/// Builds this frame's [`VoxelizeFrame`], or removes it when there is nothing to do.
#[allow(clippy::too_many_arguments)]
pub fn prepare_voxelize(
    mut commands: Commands,
    device: Res<RenderDevice>,
    grid_assets: Res<ExtractedVoxelGrid>,
    occluders: Res<ExtractedOccluders>,
    meshes: Res<RenderAssets<RenderMesh>>,
    allocator: Res<MeshAllocator>,
    mesh_changes: Res<ExtractedAssets<RenderMesh>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    images: Res<RenderAssets<GpuImage>>,
    pipelines: Res<VoxelizePipelines>,
    cache: Res<PipelineCache>,
    mut state: ResMut<VoxelizeState>,
    stats: Res<VoxelizationStats>,
    skin_uniforms: Option<Res<SkinUniforms>>,
    #[cfg(feature = "morph")] morph_indices: Option<Res<MorphIndices>>,
    #[cfg(feature = "morph")] morph_uniforms: Option<Res<MorphUniforms>>,
) {
    let stats = stats.into_inner();
    let _span = stats.cpu_span(|t| &mut t.prepare_voxelize);
    commands.remove_resource::<VoxelizeFrame>();
    // Forget the voxels (not the occluders' resolution): the next valid frame rebuilds every level.
    let invalidate = |state: &mut VoxelizeState| {
        state.levels.clear();
        state.prev_dynamic.clear();
        state.prev_dynamic_bricks.clear();
    };
    // Resolve the occluders that changed to slabs: every frame, whatever follows, since a change is
    // extracted once.
    // Bevy's joint matrices, if they can be bound as storage (they are a uniform buffer on devices without
    // storage buffers, where the voxelizer is off anyway).
    let skin_uniforms = skin_uniforms.as_deref().filter(|u| u.current_buffer.usage().contains(BufferUsages::STORAGE));
    // Bevy's morph weights and descriptors (storage buffers only; `None` where the pipeline does not morph).
    #[cfg(feature = "morph")]
    let morphs = match (morph_indices.as_deref(), morph_uniforms.as_deref()) {
        (Some(i), Some(u)) if pipelines.morph && u.descriptors_buffer.is_some() => Some((i, u)),
        _ => None,
    };
    #[cfg(feature = "morph")]
    let morph_weights = morphs.and_then(|(_, u)| u.current_buffer.buffer()).unwrap_or(&pipelines.dummy);
    #[cfg(not(feature = "morph"))]
    let morph_weights = &pipelines.dummy;
    let skins = Skins {
        uniforms: skin_uniforms,
        supported: pipelines.skinning,
        #[cfg(feature = "morph")]
        morphs,
    };
    let changes = state.occluders.update(&occluders, &mesh_changes, &meshes, &allocator, &skins);
    let skipped = state.occluders.skipped() as u64;
    let (tracked, resolved) = (state.occluders.len() as u64, state.occluders.resolved_last_frame);
    stats.update(|s| {
        s.occluders_tracked = tracked;
        s.occluders_resolved = resolved;
    });
    let Some(assets) = grid_assets.assets.as_ref() else {
        invalidate(&mut state);
        return;
    };
    let (Some(static_occupancy), Some(occupancy), Some(counters), Some(texture)) = (
        buffers.get(&assets.static_occupancy),
        buffers.get(&assets.occupancy),
        buffers.get(&assets.counters),
        images.get(&assets.texture),
    ) else {
        invalidate(&mut state);
        return;
    };
    let counts = match (&assets.static_point_counts, &assets.point_counts) {
        (Some(s), Some(f)) => match (buffers.get(s), buffers.get(f)) {
            (Some(s), Some(f)) => Some((s.buffer.clone(), f.buffer.clone())),
            _ => return invalidate(&mut state),
        },
        _ => None,
    };
    // The solid pipelines too once a solid occluder exists: a static level built without its fill would stay
    // hollow until it is rebuilt.
    let solid_wanted = state.occluders.any_solid();
    let solid_ids = [pipelines.solid_crossings, pipelines.solid_fill];
    if [pipelines.classify, pipelines.scan, pipelines.expand, pipelines.clear, pipelines.resolve, pipelines.mip]
        .iter()
        .chain(if solid_wanted { &solid_ids[..] } else { &[] })
        .any(|id| cache.get_compute_pipeline(*id).is_none())
    {
        return invalidate(&mut state);
    }
    let Some(levels) = place_levels(assets, grid_assets.focus) else {
        return invalidate(&mut state);
    };
    let settings = &assets.settings;
    let mut full_rebuild = state.generation != assets.generation || state.levels.len() != levels.len();
    state.generation = assets.generation;

    // Bound to every classify dispatch where the pipeline skins (a placeholder when Bevy has none).
    let joints = skin_uniforms.map(|u| &u.current_buffer).unwrap_or(&pipelines.dummy);

    let dirty = changes.dirty;
    if changes.everywhere {
        full_rebuild = true;
    }
    if occluders.rebuild_requests != state.rebuild_requests {
        full_rebuild = true;
    }
    state.rebuild_requests = occluders.rebuild_requests;

    // Static occluders added this frame, within the streaming budget, nearest the focus first.
    let focus = grid_assets.focus.unwrap_or_else(|| {
        let (lo, hi) = levels[0].world_box(levels[0].window());
        (lo + hi) * 0.5
    });
    let added = state.occluders.take_queued(focus, assets.stream_budget as u64);
    let no_entities = EntityHashSet::default();
    let queued = state.occluders.queued() as u64;
    stats.update(|s| s.static_queue = queued);

    // Per level: the static regions to voxelize again.
    let mut level_regions: Vec<(Vec<CellBox>, bool, bool)> = Vec::with_capacity(levels.len()); // (boxes, whole, scrolled)
    for (l, level) in levels.iter().enumerate() {
        let old = state.levels.get(l).copied();
        let moved = old.and_then(|o| {
            (o.cell_size == level.cell_size && o.dims == level.dims)
                .then(|| cpu::entered_regions(o.window_min, level.window_min, level.dims.x))
                .flatten()
        });
        let Some(entered) = moved.filter(|_| !full_rebuild) else {
            level_regions.push((vec![level.window()], true, false));
            continue;
        };
        let scrolled = !entered.is_empty();
        let mut boxes = entered;
        let mut changed: Option<CellBox> = None;
        let mut changed_boxes = Vec::new();
        for (lo, hi) in &dirty {
            if let Some(b) = level.cells_of_box(*lo, *hi) {
                changed_boxes.push(b);
                changed = Some(changed.map_or(b, |c| union(c, b)));
            }
        }
        // One slot stays free for the occluders added (voxelized last, without a clear).
        let slots = STATIC_REGION_SLOTS as usize - 1;
        if boxes.len() + changed_boxes.len() <= slots {
            boxes.extend(changed_boxes);
        } else if let Some(c) = changed {
            boxes.push(c);
        }
        if boxes.len() > slots {
            level_regions.push((vec![level.window()], true, false));
        } else {
            level_regions.push((boxes, false, scrolled));
        }
    }

    // Per level: where dynamic geometry is now (the box around it, and its bricks: `None` where it touches too
    // many), and where it was last frame.
    let (dynamic_boxes, dynamic_bricks): (Vec<Option<CellBox>>, Vec<Option<HashSet<IVec3>>>) =
        levels.iter().map(|level| touched(state.occluders.dynamics().map(|(o, _)| o.world_bounds), level)).unzip();
    let prev_dynamic_bricks = std::mem::replace(&mut state.prev_dynamic_bricks, dynamic_bricks.clone());

    // Per level not rebuilt whole: the box and the bricks the added occluders cover (they are voxelized into
    // it, the rest of the static grid kept).
    let (added_boxes, added_bricks): (Vec<Option<CellBox>>, Vec<Option<HashSet<IVec3>>>) = levels
        .iter()
        .zip(&level_regions)
        .map(|(level, (_, whole, _))| {
            if *whole {
                return (None, None);
            }
            touched(state.occluders.some(&added).map(|(o, _)| o.world_bounds), level)
        })
        .unzip();

    let any_static = level_regions.iter().any(|(b, _, _)| !b.is_empty()) || added_boxes.iter().any(Option::is_some);
    let has_dynamic = dynamic_boxes.iter().any(|b| b.is_some());
    let prev_dynamic = std::mem::take(&mut state.prev_dynamic);
    state.levels = levels.clone();
    state.prev_dynamic = dynamic_boxes.clone();
    let had_dynamic = std::mem::replace(&mut state.had_dynamic, has_dynamic);
    let level_stats = |s: &mut Vec<CascadeLevelStats>, regions: &[(Vec<CellBox>, bool, bool)]| {
        for (l, level) in levels.iter().enumerate() {
            if let Some(ls) = s.get_mut(l) {
                ls.origin = level.origin;
                ls.cell_size = level.cell_size;
                ls.window_min = level.window_min;
                let (boxes, whole, scrolled) = &regions[l];
                let n: u64 = boxes.iter().chain(&added_boxes[l]).map(|b| cells(*b)).sum();
                ls.static_cells_last_frame = n;
                ls.static_cells_total += n;
                ls.rebuilds += *whole as u64;
                ls.scrolls += *scrolled as u64;
            }
        }
    };
    if !any_static && !has_dynamic && !had_dynamic {
        stats.update(|s| {
            s.dynamic_instances = 0;
            s.dynamic_triangles = 0;
            s.skipped_instances = skipped;
            level_stats(&mut s.cascades, &level_regions);
        });
        return;
    }

    // Static passes and their triangle counts.
    struct PendingPass {
        level: usize,
        region: CellBox,
        instances: Vec<ResolvedInstance>,
        counter_base: u32,
        clear: Option<StaticClear>,
    }
    let mut pending: Vec<PendingPass> = Vec::new();
    let mut clear_counters = Vec::new();
    let mut static_instances = 0u64;
    let mut static_triangles = 0u64;
    let level_voxels = assets.grid.voxel_count();
    for (l, (boxes, whole, _)) in level_regions.iter().enumerate() {
        if boxes.is_empty() && added_boxes[l].is_none() {
            continue;
        }
        let level = &levels[l];
        clear_counters
            .push((counter_base(l as u32, 0), counter_base(l as u32, STATIC_REGION_SLOTS) - counter_base(l as u32, 0)));
        // A level rebuilt whole takes the added occluders with the rest; otherwise they have a pass of their own.
        let except = if *whole { &no_entities } else { &added };
        for (slot, b) in boxes.iter().enumerate() {
            let instances = instances_in(state.occluders.statics(except), level, level.world_box(*b));
            static_instances += instances.len() as u64;
            static_triangles += instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>();
            let clear = if *whole {
                // Levels hold a multiple of 32 voxels when there are several (cascades).
                let words = level_voxels.div_ceil(32);
                let record = level_voxels * 4 * assets.sample_words as u64;
                Some(StaticClear::Level {
                    occupancy: (l as u64 * words * 4, words * 4),
                    counts: counts.as_ref().map(|_| (l as u64 * record, record)),
                })
            } else {
                Some(StaticClear::Region(groups4(*b)))
            };
            pending.push(PendingPass {
                level: l,
                region: *b,
                instances,
                counter_base: counter_base(l as u32, slot as u32),
                clear,
            });
        }
        if let Some(b) = added_boxes[l] {
            let instances = instances_in(state.occluders.some(&added), level, level.world_box(b));
            static_instances += instances.len() as u64;
            static_triangles += instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>();
            pending.push(PendingPass {
                level: l,
                region: b,
                instances,
                counter_base: counter_base(l as u32, boxes.len() as u32),
                clear: Some(StaticClear::Keep),
            });
        }
    }
    let mut dynamic_instances = 0u64;
    let mut dynamic_triangles = 0u64;
    for (l, b) in dynamic_boxes.iter().enumerate() {
        let base = counter_base(l as u32, STATIC_REGION_SLOTS);
        clear_counters.push((base, super::stats::COUNTER_BLOCK as u32));
        if b.is_none() {
            continue;
        }
        let level = &levels[l];
        let instances = instances_in(state.occluders.dynamics(), level, level.world_box(level.window()));
        dynamic_instances = dynamic_instances.max(instances.len() as u64);
        dynamic_triangles += instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>();
        pending.push(PendingPass { level: l, region: level.window(), instances, counter_base: base, clear: None });
    }

    // The queue of big triangles, shared by the passes (which run one after the other): room for every
    // triangle of the largest pass.
    let largest = pending.iter().map(|p| p.instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>()).max();
    let largest = largest.unwrap_or(0);
    let limit = (device.limits().max_storage_buffer_binding_size / BIG_TRIANGLE_BYTES).max(1);
    let need = largest.clamp(1, limit);
    if largest > limit && !state.warned_capacity {
        warn!(
            "bevy_hao: {largest} triangles exceed the big-triangle queue the device allows ({limit}); some large triangles \
             are not voxelized"
        );
        state.warned_capacity = true;
    }
    if state.big.as_ref().is_none_or(|b| b.capacity < need) {
        let capacity = (need + need / 2).min(limit);
        let storage = |label, bytes: u64, extra: BufferUsages| {
            device.create_buffer(&BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: BufferUsages::STORAGE | extra,
                mapped_at_creation: false,
            })
        };
        state.big = Some(BigBuffers {
            capacity,
            triangles: storage("hao_big_triangles", capacity * BIG_TRIANGLE_BYTES, BufferUsages::empty()),
            offsets: storage("hao_big_triangle_offsets", capacity * 4, BufferUsages::empty()),
            dispatch: storage("hao_expand_dispatch", 16, BufferUsages::INDIRECT),
        });
    }
    // The solid passes' scratch: a level's cells and a bit per column, in words (levels share their dims).
    if pending.iter().any(|p| p.instances.iter().any(|r| r.gpu.solid != 0)) {
        let most = levels.iter().map(|l| level_voxels + (l.dims.x * l.dims.y) as u64).max().unwrap_or(0);
        let bytes = most.div_ceil(32).max(1) * 4;
        if bytes > device.limits().max_storage_buffer_binding_size {
            if !state.warned_crossings {
                warn!(
                    "bevy_hao: filling solid occluders needs a {bytes}-byte scratch buffer, over the device's \
                     Limits::max_storage_buffer_binding_size; VoxelFill::Solid occluders are voxelized as surfaces"
                );
                state.warned_crossings = true;
            }
            state.crossings = None;
        } else if state.crossings.as_ref().is_none_or(|b| b.size() < bytes) {
            state.crossings = Some(device.create_buffer(&BufferDescriptor {
                label: Some("hao_voxelize_crossings"),
                size: bytes,
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
    }
    let crossings = state.crossings.clone();
    let big = state.big.as_ref().expect("allocated above");

    let pass_layout = cache.get_bind_group_layout(&pipelines.pass_layout);
    let mode = match settings.mode {
        InjectionMode::Centroid => 0,
        InjectionMode::Conservative => 1,
    };
    let mut static_passes = Vec::new();
    let mut dynamic_passes = Vec::new();
    for p in pending {
        let level = &levels[p.level];
        let is_static = p.clear.is_some();
        let label = if is_static { "hao_static_instances" } else { "hao_dynamic_instances" };
        let any_solid = p.instances.iter().any(|r| r.gpu.solid != 0);
        let (slabs, _) = build_slab_dispatches(&device, &pipelines, &cache, p.instances, joints, morph_weights, label);
        let region = level.region(p.region);
        let params = GpuVoxelizeParams {
            region_min: region.min,
            mode,
            region_max: region.max,
            gamma: settings.effective_gamma(),
            window_min: region.window_min,
            point_budget: assets.point_budget,
            closed_max: region.closed_max,
            sample_words: if counts.is_some() { assets.sample_words } else { 0 },
            wrap: level.wrap(),
            counter_base: p.counter_base,
            dims: level.dims,
            voxel_base: level.voxel_base,
            pattern: (settings.pattern == SubdivisionPattern::Strips) as u32,
            _pad_a: 0,
            _pad_b: 0,
            _pad_c: 0,
        };
        let params = settings_buffer(&device, "hao_voxelize_params", &params);
        let (occ, cnt) = if is_static {
            (&static_occupancy.buffer, counts.as_ref().map(|c| &c.0))
        } else {
            (&occupancy.buffer, counts.as_ref().map(|c| &c.1))
        };
        let bind_group = device.create_bind_group(
            "hao_voxelize_pass_bind_group",
            &pass_layout,
            &BindGroupEntries::sequential((
                params.as_entire_binding(),
                occ.as_entire_binding(),
                cnt.unwrap_or(&pipelines.dummy_counts).as_entire_binding(),
                big.triangles.as_entire_binding(),
                counters.buffer.as_entire_binding(),
                big.offsets.as_entire_binding(),
            )),
        );
        let solid = (any_solid && crossings.is_some()).then(|| {
            let crossings = crossings.clone().expect("allocated when a pass has solid instances");
            let bind_group = device.create_bind_group(
                "hao_voxelize_solid_bind_group",
                &cache.get_bind_group_layout(&pipelines.solid_layout),
                &BindGroupEntries::sequential((
                    params.as_entire_binding(),
                    crossings.as_entire_binding(),
                    occ.as_entire_binding(),
                )),
            );
            let size = (region.max - region.min).max(IVec3::ZERO).as_uvec3();
            let w = crate::gpu::SCREEN_WORKGROUP;
            SolidPass { bind_group, crossings, columns: UVec2::new(size.x.div_ceil(w), size.y.div_ceil(w)) }
        });
        let pass = VoxelizePass { slabs, bind_group, solid };
        match p.clear {
            Some(clear) => static_passes.push(StaticPass { clear, pass }),
            None => dynamic_passes.push(pass),
        }
    }

    // Resolve: per level, the boxes that changed (static regions, and dynamic geometry now and last frame)
    // into the texture's level 0, then the mips over their footprint.
    let level_view = |mip: u32| {
        texture.texture.create_view(&TextureViewDescriptor {
            label: Some("hao_voxel_texture_level"),
            dimension: Some(TextureViewDimension::D3),
            base_mip_level: mip,
            mip_level_count: Some(1),
            ..default()
        })
    };
    let views: Vec<TextureView> = (0..assets.mip_levels).map(level_view).collect();
    // The attribute textures, where kept and the records are bound.
    let attribute_views = match (&assets.attributes, &counts) {
        (Some([a, n]), Some(_)) => match (images.get(a), images.get(n)) {
            (Some(a), Some(n)) => Some([a.texture_view.clone(), n.texture_view.clone()]),
            _ => return invalidate(&mut state),
        },
        _ => None,
    };
    let [albedo_view, normal_view] = attribute_views.as_ref().unwrap_or(&pipelines.dummy_attributes);
    let records = counts.as_ref().map_or(&pipelines.dummy, |c| &c.1);
    let bindings = ResolveBindings {
        device: &device,
        resolve_layout: &cache.get_bind_group_layout(&pipelines.resolve_layout),
        mip_layout: &cache.get_bind_group_layout(&pipelines.mip_layout),
        views: &views,
        occupancy: &occupancy.buffer,
        records,
        albedo: albedo_view,
        normal: normal_view,
        sample_words: if counts.is_some() { assets.sample_words } else { 0 },
        dummy: &pipelines.dummy,
    };
    let mut resolve = Vec::new();
    for (l, level) in levels.iter().enumerate() {
        let (boxes, whole, _) = &level_regions[l];
        if *whole {
            // The padding past the grid too, so that it reads as empty.
            resolve.push(bindings.resolve_box(level, (level.window_min, level.window_min + level.size.as_ivec3())));
            continue;
        }
        for b in boxes {
            resolve.push(bindings.resolve_box(level, *b));
        }
        // Scattered changes: the occluders added, and dynamic geometry now and last frame, as bricks or as
        // the box around them, whichever writes fewer texels.
        let Some(around) = [added_boxes[l], dynamic_boxes[l], prev_dynamic.get(l).copied().flatten()]
            .into_iter()
            .flatten()
            .filter_map(|b| intersect(b, level.window()))
            .reduce(union)
        else {
            continue;
        };
        // All three brick sets, or `None` where any of them had too many bricks to list.
        let no_bricks = Some(HashSet::default());
        let scattered = [&added_bricks[l], &dynamic_bricks[l], prev_dynamic_bricks.get(l).unwrap_or(&no_bricks)];
        let bricks = scattered.into_iter().try_fold(HashSet::default(), |mut all: HashSet<IVec3>, set| {
            all.extend(set.as_ref()?.iter().copied());
            Some(all)
        });
        let lists = bricks
            .filter(|b| !b.is_empty() && b.len() <= MAX_BRICKS)
            .map(|b| brick_mips(&b, assets.mip_levels))
            .filter(|lists| {
                let (bricks, boxes) = brick_and_box_texels(lists, around);
                bricks < boxes
            });
        resolve.push(match lists {
            Some(lists) => bindings.resolve_bricks(level, &lists),
            None => bindings.resolve_box(level, around),
        });
    }
    let empty_bind_group = device.create_bind_group(
        "hao_voxelize_empty_bind_group",
        &cache.get_bind_group_layout(&pipelines.empty_layout),
        &[],
    );
    let dispatch_bind_group = device.create_bind_group(
        "hao_voxelize_dispatch_bind_group",
        &cache.get_bind_group_layout(&pipelines.dispatch_layout),
        &BindGroupEntries::single(BufferBinding { buffer: &big.dispatch, offset: 0, size: BufferSize::new(12) }),
    );

    stats.update(|s| {
        if any_static {
            s.static_rebuilds += 1;
            s.static_instances = static_instances;
            s.static_triangles = static_triangles;
        }
        s.frames_voxelized += 1;
        s.dynamic_instances = dynamic_instances;
        s.dynamic_triangles = dynamic_triangles;
        s.skipped_instances = skipped;
        level_stats(&mut s.cascades, &level_regions);
    });
    commands.insert_resource(VoxelizeFrame {
        clear_counters,
        static_passes,
        dynamic_passes,
        empty_bind_group,
        dispatch_bind_group,
        dispatch_args: big.dispatch.clone(),
        counters: counters.buffer.clone(),
        static_occupancy: static_occupancy.buffer.clone(),
        occupancy: occupancy.buffer.clone(),
        counts,
        resolve,
    });
}

/// The cells of `level` that boxes of occluders (`None`: one without bounds, anywhere) touch: the box around
/// them, and their bricks (`None` where they are more than a brick pass takes).
fn touched(
    bounds: impl Iterator<Item = Option<(Vec3, Vec3)>>,
    level: &LevelLayout,
) -> (Option<CellBox>, Option<HashSet<IVec3>>) {
    let (mut around, mut bricks) = (None, Some(HashSet::default()));
    let mut count = 0u64;
    for b in bounds {
        let Some(cells) = b.map_or(Some(level.window()), |(lo, hi)| level.cells_of_box(lo, hi)) else { continue };
        around = Some(around.map_or(cells, |a| union(a, cells)));
        count += brick_count(cells);
        if count > MAX_BRICKS as u64 {
            bricks = None;
        }
        if let Some(set) = &mut bricks {
            add_bricks(cells, set);
        }
    }
    (around, bricks)
}
