//! The voxelize system: records the passes of the frame, in the `RenderGraph` schedule before the cameras
//! render, so that every view's sampling pass sees this frame's grid.

use super::pipelines::VoxelizePipelines;
use super::prepare::{VoxelizeFrame, VoxelizePass};
use super::stats::{COUNTER_BLOCK, FRAME_POINTS_USED};
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderContext;

fn record_pass(
    encoder: &mut CommandEncoder,
    pass: &VoxelizePass,
    frame: &VoxelizeFrame,
    pipelines: [&ComputePipeline; 3],
    label: &'static str,
) {
    let [classify, scan, expand] = pipelines;
    encoder.clear_buffer(&frame.counters, pass.counter_base as u64 * 4, Some(COUNTER_BLOCK as u64 * 4));
    {
        let mut cpass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        cpass.set_pipeline(classify);
        cpass.set_bind_group(1, &pass.bind_group, &[]);
        for slab in &pass.slabs {
            cpass.set_bind_group(0, &slab.bind_group, &[]);
            cpass.dispatch_workgroups(slab.workgroups.0, slab.workgroups.1, 1);
        }
    }
    {
        let mut cpass = encoder
            .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_voxelize_scan"), timestamp_writes: None });
        cpass.set_pipeline(scan);
        cpass.set_bind_group(0, &frame.empty_bind_group, &[]);
        cpass.set_bind_group(1, &pass.bind_group, &[]);
        cpass.set_bind_group(2, &frame.dispatch_bind_group, &[]);
        cpass.dispatch_workgroups(1, 1, 1);
    }
    {
        let mut cpass = encoder
            .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_voxelize_expand"), timestamp_writes: None });
        cpass.set_pipeline(expand);
        cpass.set_bind_group(0, &frame.empty_bind_group, &[]);
        cpass.set_bind_group(1, &pass.bind_group, &[]);
        cpass.dispatch_workgroups_indirect(&frame.dispatch_args, 0);
    }
}

/// Voxelizes: the static grid when it must be rebuilt, then this frame's copy of it with the dynamic
/// geometry on top, then the voxel texture over the region that changed.
pub fn voxelize(
    frame: Option<Res<VoxelizeFrame>>,
    pipelines: Res<VoxelizePipelines>,
    cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let Some(frame) = frame else { return };
    let (Some(classify), Some(scan), Some(expand), Some(resolve), Some(mip)) = (
        cache.get_compute_pipeline(pipelines.classify),
        cache.get_compute_pipeline(pipelines.scan),
        cache.get_compute_pipeline(pipelines.expand),
        cache.get_compute_pipeline(pipelines.resolve),
        cache.get_compute_pipeline(pipelines.mip),
    ) else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let encoder = ctx.command_encoder();
    encoder.clear_buffer(&frame.counters, FRAME_POINTS_USED as u64 * 4, Some(4));

    if let Some(pass) = &frame.static_pass {
        let span = diagnostics.time_span(ctx.command_encoder(), "hao/voxelize_static");
        let encoder = ctx.command_encoder();
        encoder.clear_buffer(&frame.static_occupancy, 0, None);
        if let Some((static_counts, _)) = &frame.counts {
            encoder.clear_buffer(static_counts, 0, None);
        }
        record_pass(encoder, pass, &frame, [classify, scan, expand], "hao_voxelize_static");
        span.end(ctx.command_encoder());
    }

    let span = diagnostics.time_span(ctx.command_encoder(), "hao/voxelize_dynamic");
    let encoder = ctx.command_encoder();
    encoder.copy_buffer_to_buffer(&frame.static_occupancy, 0, &frame.occupancy, 0, frame.occupancy.size());
    if let Some((static_counts, counts)) = &frame.counts {
        encoder.copy_buffer_to_buffer(static_counts, 0, counts, 0, counts.size());
    }
    if let Some(pass) = &frame.dynamic_pass {
        record_pass(encoder, pass, &frame, [classify, scan, expand], "hao_voxelize_dynamic");
    }
    span.end(ctx.command_encoder());

    let span = diagnostics.time_span(ctx.command_encoder(), "hao/resolve");
    {
        let encoder = ctx.command_encoder();
        let mut cpass = encoder
            .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_voxel_resolve"), timestamp_writes: None });
        cpass.set_pipeline(resolve);
        cpass.set_bind_group(0, &frame.resolve.bind_group, &[]);
        let w = frame.resolve.workgroups;
        cpass.dispatch_workgroups(w.x, w.y, w.z);
    }
    // One pass per level: each reads the level the previous one wrote.
    for (bind_group, w) in &frame.resolve.mips {
        let encoder = ctx.command_encoder();
        let mut cpass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some("hao_voxel_mip"), timestamp_writes: None });
        cpass.set_pipeline(mip);
        cpass.set_bind_group(0, bind_group, &[]);
        cpass.dispatch_workgroups(w.x.max(1), w.y.max(1), w.z.max(1));
    }
    span.end(ctx.command_encoder());
}
