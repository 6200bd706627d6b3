//! Prepare: resolve this frame's occluders to mesh slabs, decide what needs voxelizing (the static grid only
//! when the static set changed; dynamic geometry every frame), and build the buffers and bind groups of the
//! passes.

use super::assets::{VoxelGridAssets, VoxelizationStats};
use super::extract::{ExtractedOccluder, ExtractedOccluders, ExtractedVoxelGrid};
use super::pipelines::*;
use super::stats::{DYNAMIC_COUNTER_BASE, STATIC_COUNTER_BASE};
use crate::cpu::{InjectionMode, VoxelGrid};
use bevy::math::Affine3A;
use bevy::mesh::VertexFormat;
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::mesh::{RenderMesh, RenderMeshBufferInfo};
use bevy::render::render_asset::{ExtractedAssets, RenderAssets};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::texture::GpuImage;
use std::hash::{Hash, Hasher};

/// A box of cells, `[min, max)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellRegion {
    /// First cell.
    pub min: UVec3,
    /// One past the last cell.
    pub max: UVec3,
}

impl CellRegion {
    fn union(self, o: CellRegion) -> CellRegion {
        CellRegion { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    fn full(dims: UVec3) -> CellRegion {
        CellRegion { min: UVec3::ZERO, max: dims }
    }
}

/// State kept across frames.
#[derive(Resource, Default)]
pub struct VoxelizeState {
    generation: u64,
    static_fingerprint: Option<u64>,
    prev_dynamic_region: Option<CellRegion>,
    had_dynamic: bool,
    warned_meshes: HashSet<AssetId<Mesh>>,
    warned_moved: HashSet<Entity>,
    static_transforms: HashMap<Entity, Affine3A>,
    rebuild_requests: u64,
    big: Option<BigBuffers>,
    warned_capacity: bool,
}

struct BigBuffers {
    capacity: u64,
    triangles: Buffer,
    offsets: Buffer,
    dispatch: Buffer,
}

/// One classify dispatch: the instances whose meshes live in one pair of vertex and index slabs.
pub struct SlabDispatch {
    /// Group 0.
    pub bind_group: BindGroup,
    /// Workgroups (x, y).
    pub workgroups: (u32, u32),
}

/// A voxelization pass (static or dynamic).
pub struct VoxelizePass {
    /// The classify dispatches.
    pub slabs: Vec<SlabDispatch>,
    /// Group 1.
    pub bind_group: BindGroup,
    /// First word of the pass's counter block.
    pub counter_base: u32,
}

/// The resolve work of a frame.
pub struct ResolveWork {
    /// Bits to level 0.
    pub bind_group: BindGroup,
    /// Workgroups of 4x4x4.
    pub workgroups: UVec3,
    /// One per further mip level.
    pub mips: Vec<(BindGroup, UVec3)>,
}

/// Everything the voxelize system records this frame; absent on frames with nothing to do.
#[derive(Resource)]
pub struct VoxelizeFrame {
    /// Rebuild the static grid.
    pub static_pass: Option<VoxelizePass>,
    /// Inject dynamic geometry.
    pub dynamic_pass: Option<VoxelizePass>,
    /// Group 0 of scan and expand.
    pub empty_bind_group: BindGroup,
    /// Group 2 of scan.
    pub dispatch_bind_group: BindGroup,
    /// The expand pass's indirect arguments.
    pub dispatch_args: Buffer,
    /// The counters.
    pub counters: Buffer,
    /// Static and frame occupancy.
    pub static_occupancy: Buffer,
    /// This frame's occupancy.
    pub occupancy: Buffer,
    /// Static and frame point counts, if kept.
    pub counts: Option<(Buffer, Buffer)>,
    /// Bits to texture.
    pub resolve: ResolveWork,
}

/// An occluder ready for the GPU.
struct ResolvedInstance {
    slabs: (BufferId, Option<BufferId>),
    vertex_buffer: Buffer,
    index_buffer: Option<Buffer>,
    gpu: GpuOccluderInstance,
    ranges: [u32; 4],
}

enum Resolution {
    Ready(ResolvedInstance),
    /// Not uploaded yet: try again next frame.
    Pending,
    /// Cannot be voxelized (warned once per mesh).
    Skipped,
}

fn resolve_occluder(
    o: &ExtractedOccluder,
    grid: &VoxelGrid,
    meshes: &RenderAssets<RenderMesh>,
    allocator: &MeshAllocator,
    warned: &mut HashSet<AssetId<Mesh>>,
) -> Resolution {
    let Some(mesh) = meshes.get(o.mesh) else { return Resolution::Pending };
    let mut skip = |why: &str| {
        if warned.insert(o.mesh) {
            warn!("bevy_hao: mesh {:?} is not voxelized: {why}", o.mesh);
        }
        Resolution::Skipped
    };
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return skip(&format!("its topology is {:?}, not a triangle list", mesh.primitive_topology()));
    }
    let Some(vertices) = allocator.mesh_vertex_slice(&o.mesh) else { return Resolution::Pending };
    if !vertices.buffer.usage().contains(BufferUsages::STORAGE) {
        return skip(
            "it sits in a vertex slab that cannot be bound as storage (a mesh above the slab allocator's large_threshold)",
        );
    }
    let layout = mesh.layout.0.layout();
    let stride = layout.array_stride;
    let Some(position) = mesh
        .layout
        .0
        .attribute_ids()
        .iter()
        .position(|id| *id == Mesh::ATTRIBUTE_POSITION.id)
        .map(|i| layout.attributes[i])
    else {
        return skip("it has no positions");
    };
    if position.format != VertexFormat::Float32x3 || stride % 4 != 0 || position.offset % 4 != 0 {
        return skip("its positions are not 4-byte aligned Float32x3");
    }
    let (index_buffer, index_start, index_format, triangles) = match &mesh.buffer_info {
        RenderMeshBufferInfo::Indexed { count, index_format } => {
            let Some(indices) = allocator.mesh_index_slice(&o.mesh) else { return Resolution::Pending };
            if !indices.buffer.usage().contains(BufferUsages::STORAGE) || indices.buffer.size() % 4 != 0 {
                return skip("it sits in an index slab that cannot be bound as storage");
            }
            let format = match index_format {
                IndexFormat::Uint16 => 1,
                IndexFormat::Uint32 => 2,
            };
            (Some(indices.buffer.clone()), indices.range.start, format, count / 3)
        }
        RenderMeshBufferInfo::NonIndexed => (None, 0, 0, mesh.vertex_count / 3),
    };
    let m = grid.grid_from_world() * o.world_from_local;
    let col = |v: bevy::math::Vec3A| [v.x, v.y, v.z, 0.0];
    Resolution::Ready(ResolvedInstance {
        slabs: (vertices.buffer.id(), index_buffer.as_ref().map(|b| b.id())),
        vertex_buffer: vertices.buffer.clone(),
        index_buffer,
        ranges: [vertices.range.start, vertices.range.end, index_start, triangles],
        gpu: GpuOccluderInstance {
            grid_from_local: [col(m.matrix3.x_axis), col(m.matrix3.y_axis), col(m.matrix3.z_axis), col(m.translation)],
            vertex_start: vertices.range.start,
            vertex_count: mesh.vertex_count,
            vertex_stride: (stride / 4) as u32,
            position_offset: (position.offset / 4) as u32,
            index_start,
            index_format,
            triangle_count: triangles,
            first_triangle: 0,
        },
    })
}

fn resolve_list<'a>(
    list: &'a [ExtractedOccluder],
    grid: &VoxelGrid,
    meshes: &RenderAssets<RenderMesh>,
    allocator: &MeshAllocator,
    state: &mut VoxelizeState,
    skipped: &mut u64,
) -> Vec<(&'a ExtractedOccluder, ResolvedInstance)> {
    let mut ready = Vec::with_capacity(list.len());
    for o in list {
        match resolve_occluder(o, grid, meshes, allocator, &mut state.warned_meshes) {
            Resolution::Ready(r) => ready.push((o, r)),
            Resolution::Pending => {}
            Resolution::Skipped => *skipped += 1,
        }
    }
    ready
}

fn uniform<T: bytemuck::Pod>(device: &RenderDevice, label: &'static str, value: &T) -> Buffer {
    device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::bytes_of(value),
        usage: BufferUsages::UNIFORM,
    })
}

/// Workgroups (x, y) covering `count` invocations of `size`, with x at most 65535.
pub fn workgroups_2d(count: u64, size: u32) -> (u32, u32) {
    let groups = count.div_ceil(size as u64).max(1);
    let x = groups.min(65535) as u32;
    (x, groups.div_ceil(x as u64) as u32)
}

/// Sorts instances into slab groups and builds their classify dispatches. Returns the dispatches and the
/// triangle count.
fn build_slab_dispatches(
    device: &RenderDevice,
    pipelines: &VoxelizePipelines,
    cache: &PipelineCache,
    mut instances: Vec<ResolvedInstance>,
    label: &'static str,
) -> (Vec<SlabDispatch>, u64) {
    instances.sort_by_key(|i| i.slabs);
    let mut gpu: Vec<GpuOccluderInstance> = Vec::with_capacity(instances.len());
    let mut groups: Vec<(usize, usize, u32)> = Vec::new();
    let mut total = 0u64;
    let mut start = 0;
    while start < instances.len() {
        let key = instances[start].slabs;
        let mut end = start;
        let mut first = 0u32;
        while end < instances.len() && instances[end].slabs == key {
            let mut g = instances[end].gpu;
            g.first_triangle = first;
            first = first.saturating_add(g.triangle_count);
            gpu.push(g);
            end += 1;
        }
        groups.push((start, end, first));
        total += first as u64;
        start = end;
    }
    if gpu.is_empty() {
        return (Vec::new(), 0);
    }
    let instance_buffer = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(&gpu),
        usage: BufferUsages::STORAGE,
    });
    let layout = cache.get_bind_group_layout(&pipelines.slab_layout);
    let dispatches = groups
        .into_iter()
        .filter(|(_, _, tris)| *tris > 0)
        .map(|(s, e, tris)| {
            let params = GpuSlabGroup {
                first_instance: s as u32,
                instance_count: (e - s) as u32,
                triangle_count: tris,
                _pad: 0,
            };
            let params = uniform(device, "hao_voxelize_slab_group", &params);
            let first = &instances[s];
            let index = first.index_buffer.as_ref().unwrap_or(&pipelines.dummy);
            let bind_group = device.create_bind_group(
                "hao_voxelize_slab_bind_group",
                &layout,
                &BindGroupEntries::sequential((
                    instance_buffer.as_entire_binding(),
                    first.vertex_buffer.as_entire_binding(),
                    index.as_entire_binding(),
                    params.as_entire_binding(),
                )),
            );
            SlabDispatch { bind_group, workgroups: workgroups_2d(tris as u64, VOXELIZE_WORKGROUP) }
        })
        .collect();
    (dispatches, total)
}

/// The cells a world-space box touches, padded by one cell and clamped to the grid.
fn cell_region(grid: &VoxelGrid, min: Vec3, max: Vec3) -> Option<CellRegion> {
    let lo = grid.world_to_grid(min).floor() - Vec3::ONE;
    let hi = grid.world_to_grid(max).ceil() + Vec3::ONE;
    let d = grid.dims.as_vec3();
    if !(lo.is_finite() && hi.is_finite()) {
        return Some(CellRegion::full(grid.dims));
    }
    let lo = lo.clamp(Vec3::ZERO, d).as_uvec3();
    let hi = hi.clamp(Vec3::ZERO, d).as_uvec3();
    (lo.cmplt(hi).all()).then_some(CellRegion { min: lo, max: hi })
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
) {
    commands.remove_resource::<VoxelizeFrame>();
    let Some(assets) = grid_assets.0.as_ref() else {
        state.static_fingerprint = None;
        state.prev_dynamic_region = None;
        return;
    };
    let VoxelGridAssets { grid, settings, .. } = assets;
    let (Some(static_occupancy), Some(occupancy), Some(counters), Some(texture)) = (
        buffers.get(&assets.static_occupancy),
        buffers.get(&assets.occupancy),
        buffers.get(&assets.counters),
        images.get(&assets.texture),
    ) else {
        return;
    };
    let counts = match (&assets.static_point_counts, &assets.point_counts) {
        (Some(s), Some(f)) => match (buffers.get(s), buffers.get(f)) {
            (Some(s), Some(f)) => Some((s.buffer.clone(), f.buffer.clone())),
            _ => return,
        },
        _ => None,
    };
    if [pipelines.classify, pipelines.scan, pipelines.expand, pipelines.resolve, pipelines.mip]
        .iter()
        .any(|id| cache.get_compute_pipeline(*id).is_none())
    {
        return;
    }
    if state.generation != assets.generation {
        state.generation = assets.generation;
        state.static_fingerprint = None;
        state.prev_dynamic_region = None;
    }

    // Resolve the occluders to slabs.
    let mut skipped = 0u64;
    let statics = resolve_list(&occluders.statics, grid, &meshes, &allocator, &mut state, &mut skipped);
    let dynamics = resolve_list(&occluders.dynamics, grid, &meshes, &allocator, &mut state, &mut skipped);

    // The static set's fingerprint: what was voxelized and where, and how.
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    assets.generation.hash(&mut hasher);
    let mut transforms = HashMap::with_capacity(statics.len());
    let mut force = false;
    for (o, r) in &statics {
        o.entity.hash(&mut hasher);
        o.mesh.hash(&mut hasher);
        r.ranges.hash(&mut hasher);
        for v in o.world_from_local.to_cols_array() {
            v.to_bits().hash(&mut hasher);
        }
        force |= mesh_changes.modified.contains(&o.mesh) || mesh_changes.added.contains(&o.mesh);
        if o.marked_static
            && state.static_transforms.get(&o.entity).is_some_and(|t| *t != o.world_from_local)
            && state.warned_moved.insert(o.entity)
        {
            warn!(
                "bevy_hao: StaticOccluder {} moved; the static voxel grid is rebuilt each time it does. Mark it \
                 DynamicOccluder if it moves often",
                o.entity
            );
        }
        transforms.insert(o.entity, o.world_from_local);
    }
    state.static_transforms = transforms;
    let fingerprint = hasher.finish();
    force |= occluders.rebuild_requests != state.rebuild_requests;
    state.rebuild_requests = occluders.rebuild_requests;
    let rebuild_static = force || state.static_fingerprint != Some(fingerprint);
    let has_dynamic = !dynamics.is_empty();
    if !rebuild_static && !has_dynamic && !state.had_dynamic {
        stats.update(|s| {
            s.dynamic_instances = 0;
            s.dynamic_triangles = 0;
            s.skipped_instances = skipped;
        });
        return;
    }

    // The dynamic region to resolve: where dynamic geometry is now and where it was last frame.
    let mut dynamic_region: Option<CellRegion> = None;
    for (o, _) in &dynamics {
        let r = match o.world_bounds {
            Some((lo, hi)) => cell_region(grid, lo, hi),
            None => Some(CellRegion::full(grid.dims)),
        };
        if let Some(r) = r {
            dynamic_region = Some(dynamic_region.map_or(r, |d| d.union(r)));
        }
    }
    let region = if rebuild_static {
        Some(CellRegion::full(assets.texture_size))
    } else {
        match (dynamic_region, state.prev_dynamic_region) {
            (Some(a), Some(b)) => Some(a.union(b)),
            (a, b) => a.or(b),
        }
    };
    state.prev_dynamic_region = dynamic_region;
    state.had_dynamic = has_dynamic;
    if rebuild_static {
        state.static_fingerprint = Some(fingerprint);
    }

    let static_triangles: u64 =
        if rebuild_static { statics.iter().map(|(_, r)| r.gpu.triangle_count as u64).sum() } else { 0 };
    let dynamic_triangles: u64 = dynamics.iter().map(|(_, r)| r.gpu.triangle_count as u64).sum();

    // The queue of big triangles, shared by both passes: room for every triangle of the larger pass.
    let limit = (device.limits().max_storage_buffer_binding_size as u64 / BIG_TRIANGLE_BYTES).max(1);
    let need = static_triangles.max(dynamic_triangles).clamp(1, limit);
    if static_triangles.max(dynamic_triangles) > limit && !state.warned_capacity {
        warn!(
            "bevy_hao: {} triangles exceed the big-triangle queue the device allows ({limit}); some large triangles \
             are not voxelized",
            static_triangles.max(dynamic_triangles)
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
    let big = state.big.as_ref().expect("allocated above");

    let pass_layout = cache.get_bind_group_layout(&pipelines.pass_layout);
    let mode = match settings.mode {
        InjectionMode::Centroid => 0,
        InjectionMode::Conservative => 1,
    };
    let make_pass = |instances: Vec<(&ExtractedOccluder, ResolvedInstance)>, counter_base: u32, is_static: bool| {
        let label = if is_static { "hao_static_instances" } else { "hao_dynamic_instances" };
        let (slabs, _) =
            build_slab_dispatches(&device, &pipelines, &cache, instances.into_iter().map(|(_, r)| r).collect(), label);
        let params = GpuVoxelizeParams {
            dims: grid.dims.to_array(),
            mode,
            gamma: settings.effective_gamma(),
            point_budget: assets.point_budget,
            store_counts: counts.is_some() as u32,
            counter_base,
        };
        let params = uniform(&device, "hao_voxelize_params", &params);
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
                cnt.unwrap_or(&pipelines.dummy).as_entire_binding(),
                big.triangles.as_entire_binding(),
                counters.buffer.as_entire_binding(),
                big.offsets.as_entire_binding(),
            )),
        );
        VoxelizePass { slabs, bind_group, counter_base }
    };
    let static_instances = statics.len() as u64;
    let dynamic_instances = dynamics.len() as u64;
    let static_pass = rebuild_static.then(|| make_pass(statics, STATIC_COUNTER_BASE, true));
    let dynamic_pass = has_dynamic.then(|| make_pass(dynamics, DYNAMIC_COUNTER_BASE, false));

    // Resolve: bits to level 0 over the region, then the mips over the region's footprint.
    let region = region.unwrap_or(CellRegion { min: UVec3::ZERO, max: UVec3::ONE });
    let level_view = |level: u32| {
        texture.texture.create_view(&TextureViewDescriptor {
            label: Some("hao_voxel_texture_level"),
            dimension: Some(TextureViewDimension::D3),
            base_mip_level: level,
            mip_level_count: Some(1),
            ..default()
        })
    };
    let region_params = |min: UVec3, max: UVec3, size: UVec3| GpuRegionParams {
        region_min: min.to_array(),
        _pad0: 0,
        region_max: max.to_array(),
        _pad1: 0,
        size: size.to_array(),
        _pad2: 0,
    };
    let resolve_params =
        uniform(&device, "hao_voxel_resolve_params", &region_params(region.min, region.max, grid.dims));
    let resolve_bind_group = device.create_bind_group(
        "hao_voxel_resolve_bind_group",
        &cache.get_bind_group_layout(&pipelines.resolve_layout),
        &BindGroupEntries::sequential((
            resolve_params.as_entire_binding(),
            occupancy.buffer.as_entire_binding(),
            &level_view(0),
        )),
    );
    let mip_layout = cache.get_bind_group_layout(&pipelines.mip_layout);
    let mut mips = Vec::new();
    let mut level_size = assets.texture_size;
    for level in 1..assets.mip_levels {
        let source_size = level_size;
        level_size = level_size / 2;
        let min = region.min >> level;
        let max = ((region.max + UVec3::splat((1 << level) - 1)) >> level).min(level_size);
        let params = uniform(&device, "hao_voxel_mip_params", &region_params(min, max, source_size));
        let bind_group = device.create_bind_group(
            "hao_voxel_mip_bind_group",
            &mip_layout,
            &BindGroupEntries::sequential((params.as_entire_binding(), &level_view(level - 1), &level_view(level))),
        );
        mips.push((bind_group, (max - min + UVec3::splat(3)) / 4));
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
        if rebuild_static {
            s.static_rebuilds += 1;
            s.static_instances = static_instances;
            s.static_triangles = static_triangles;
        }
        s.frames_voxelized += 1;
        s.dynamic_instances = dynamic_instances;
        s.dynamic_triangles = dynamic_triangles;
        s.skipped_instances = skipped;
    });
    commands.insert_resource(VoxelizeFrame {
        static_pass,
        dynamic_pass,
        empty_bind_group,
        dispatch_bind_group,
        dispatch_args: big.dispatch.clone(),
        counters: counters.buffer.clone(),
        static_occupancy: static_occupancy.buffer.clone(),
        occupancy: occupancy.buffer.clone(),
        counts,
        resolve: ResolveWork {
            bind_group: resolve_bind_group,
            workgroups: (region.max - region.min + UVec3::splat(3)) / 4,
            mips,
        },
    });
}
