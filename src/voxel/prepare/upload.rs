//! Instance upload: the occluders of a pass, placed in a level's lattice and grouped by the mesh slabs they
//! read, as one instance buffer and one classify dispatch per slab group.

use super::super::extract::ExtractedOccluder;
use super::super::pipelines::*;
use super::SlabDispatch;
use super::instances::ResolvedInstance;
use super::levels::LevelLayout;
use bevy::prelude::*;
use bevy::render::render_resource::encase::internal::WriteInto;
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;

pub(super) fn uniform<T: ShaderType + WriteInto>(device: &RenderDevice, label: &'static str, value: &T) -> Buffer {
    crate::gpu::uniform_buffer(device, label, value, BufferUsages::UNIFORM)
}

/// A buffer of per-dispatch settings, bound as a uniform or a read-only storage buffer as the pipelines
/// chose (see `VoxelizePipelines::params_in_storage`).
pub(super) fn settings_buffer<T: ShaderType + WriteInto>(
    device: &RenderDevice,
    label: &'static str,
    value: &T,
) -> Buffer {
    crate::gpu::uniform_buffer(device, label, value, BufferUsages::STORAGE)
}

/// Workgroups (x, y) covering `count` invocations of `size`, with x at most 65535.
pub fn workgroups_2d(count: u64, size: u32) -> (u32, u32) {
    let groups = count.div_ceil(size as u64).max(1);
    let x = groups.min(65535) as u32;
    (x, groups.div_ceil(x as u64) as u32)
}

/// Sorts instances into slab groups and builds their classify dispatches. Returns the dispatches and the
/// triangle count.
pub(super) fn build_slab_dispatches(
    device: &RenderDevice,
    pipelines: &VoxelizePipelines,
    cache: &PipelineCache,
    mut instances: Vec<ResolvedInstance>,
    joints: &Buffer,
    morph_weights: &Buffer,
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
            let params = settings_buffer(device, "hao_voxelize_slab_group", &params);
            let first = &instances[s];
            let index = first.index_buffer.as_ref().unwrap_or(&pipelines.dummy);
            let entries = (
                instance_buffer.as_entire_binding(),
                first.vertex_buffer.as_entire_binding(),
                index.as_entire_binding(),
                params.as_entire_binding(),
            );
            let bind_group = if pipelines.morph {
                let (a, b, c, d) = entries;
                let targets = first.morph_buffer.as_ref().unwrap_or(&pipelines.dummy);
                let entries = BindGroupEntries::sequential((
                    a,
                    b,
                    c,
                    d,
                    joints.as_entire_binding(),
                    morph_weights.as_entire_binding(),
                    targets.as_entire_binding(),
                ));
                device.create_bind_group("hao_voxelize_slab_bind_group", &layout, &entries)
            } else if pipelines.skinning {
                let (a, b, c, d) = entries;
                let entries = BindGroupEntries::sequential((a, b, c, d, joints.as_entire_binding()));
                device.create_bind_group("hao_voxelize_slab_bind_group", &layout, &entries)
            } else {
                device.create_bind_group(
                    "hao_voxelize_slab_bind_group",
                    &layout,
                    &BindGroupEntries::sequential(entries),
                )
            };
            SlabDispatch { bind_group, workgroups: workgroups_2d(tris as u64, VOXELIZE_WORKGROUP) }
        })
        .collect();
    (dispatches, total)
}

/// The instances of `list` whose world bounds meet `world` (those without bounds always), with their
/// `grid_from_local` for a level.
pub(super) fn instances_in<'a>(
    list: impl Iterator<Item = (&'a ExtractedOccluder, &'a ResolvedInstance)>,
    level: &LevelLayout,
    world: (Vec3, Vec3),
) -> Vec<ResolvedInstance> {
    let grid_from_world = level.grid_from_world();
    let col = |v: bevy::math::Vec3A| [v.x, v.y, v.z, 0.0];
    list.filter(|(o, _)| o.world_bounds.is_none_or(|(lo, hi)| lo.cmple(world.1).all() && hi.cmpge(world.0).all()))
        .map(|(o, r)| {
            // A skinned vertex is in world space once skinned.
            let m = if r.gpu.skin_index == NO_SKIN { grid_from_world * o.world_from_local } else { grid_from_world };
            let mut r = r.clone();
            r.gpu.grid_from_local =
                [col(m.matrix3.x_axis), col(m.matrix3.y_axis), col(m.matrix3.z_axis), col(m.translation)];
            r
        })
        .collect()
}
