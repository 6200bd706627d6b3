//! The voxelize system: records the passes of the frame, in the `RenderGraph` schedule before the cameras
//! render, so that every view's sampling pass sees this frame's grid.

use super::pipelines::VoxelizePipelines;
use super::prepare::{StaticClear, VoxelizeFrame, VoxelizePass};
use super::stats::FRAME_POINTS_USED;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderContext;

fn record_pass(
    encoder: &mut CommandEncoder,
    pass: &VoxelizePass,
    frame: &VoxelizeFrame,
    pipelines: [&ComputePipeline; 3],
    solid: Option<[&ComputePipeline; 2]>,
    label: &'static str,
) {
    let [classify, scan, expand] = pipelines;
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
    // The inside of the solid occluders, once their surface is in.
    if let (Some(fill), Some([crossings, solid_fill])) = (&pass.solid, solid) {
        encoder.clear_buffer(&fill.crossings, 0, None);
        {
            let mut cpass = encoder.begin_compute_pass(&ComputePassDescriptor {
                label: Some("hao_voxelize_solid_crossings"),
                timestamp_writes: None,
            });
            cpass.set_pipeline(crossings);
            cpass.set_bind_group(1, &fill.bind_group, &[]);
            for slab in &pass.slabs {
                cpass.set_bind_group(0, &slab.bind_group, &[]);
                cpass.dispatch_workgroups(slab.workgroups.0, slab.workgroups.1, 1);
            }
        }
        let mut cpass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: Some("hao_voxelize_solid_fill"),
            timestamp_writes: None,
        });
        cpass.set_pipeline(solid_fill);
        cpass.set_bind_group(0, &frame.empty_bind_group, &[]);
        cpass.set_bind_group(1, &fill.bind_group, &[]);
        cpass.dispatch_workgroups(fill.columns.x.max(1), fill.columns.y.max(1), 1);
    }
}

/// Voxelizes: the static regions that changed (cleared, then voxelized again), then this frame's copy of
/// the static grid with the dynamic geometry on top, then the voxel texture over the boxes that changed.
pub fn voxelize(
    frame: Option<Res<VoxelizeFrame>>,
    pipelines: Res<VoxelizePipelines>,
    cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let Some(frame) = frame else { return };
    let (Some(classify), Some(scan), Some(expand), Some(clear), Some(resolve), Some(mip)) = (
        cache.get_compute_pipeline(pipelines.classify),
        cache.get_compute_pipeline(pipelines.scan),
        cache.get_compute_pipeline(pipelines.expand),
        cache.get_compute_pipeline(pipelines.clear),
        cache.get_compute_pipeline(pipelines.resolve),
        cache.get_compute_pipeline(pipelines.mip),
    ) else {
        return;
    };
    // The solid fill waits for its own pipelines; the surface does not.
    let solid = cache
        .get_compute_pipeline(pipelines.solid_crossings)
        .zip(cache.get_compute_pipeline(pipelines.solid_fill))
        .map(|(a, b)| [a, b]);
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let encoder = ctx.command_encoder();
    encoder.clear_buffer(&frame.counters, FRAME_POINTS_USED as u64 * 4, Some(4));
    for (base, words) in &frame.clear_counters {
        encoder.clear_buffer(&frame.counters, *base as u64 * 4, Some(*words as u64 * 4));
    }

    if !frame.static_passes.is_empty() {
        let span = diagnostics.time_span(ctx.command_encoder(), "hao/voxelize_static");
        let encoder = ctx.command_encoder();
        for s in &frame.static_passes {
            match &s.clear {
                StaticClear::Level { occupancy, counts } => {
                    encoder.clear_buffer(&frame.static_occupancy, occupancy.0, Some(occupancy.1));
                    if let (Some((static_counts, _)), Some(c)) = (&frame.counts, counts) {
                        encoder.clear_buffer(static_counts, c.0, Some(c.1));
                    }
                }
                StaticClear::Keep => {}
                StaticClear::Region(w) => {
                    let mut cpass = encoder.begin_compute_pass(&ComputePassDescriptor {
                        label: Some("hao_voxel_clear"),
                        timestamp_writes: None,
                    });
                    cpass.set_pipeline(clear);
                    cpass.set_bind_group(0, &frame.empty_bind_group, &[]);
                    cpass.set_bind_group(1, &s.pass.bind_group, &[]);
                    cpass.dispatch_workgroups(w.x.max(1), w.y.max(1), w.z.max(1));
                }
            }
            record_pass(encoder, &s.pass, &frame, [classify, scan, expand], solid, "hao_voxelize_static");
        }
        span.end(ctx.command_encoder());
    }

    let span = diagnostics.time_span(ctx.command_encoder(), "hao/voxelize_dynamic");
    let encoder = ctx.command_encoder();
    encoder.copy_buffer_to_buffer(&frame.static_occupancy, 0, &frame.occupancy, 0, frame.occupancy.size());
    if let Some((static_counts, counts)) = &frame.counts {
        encoder.copy_buffer_to_buffer(static_counts, 0, counts, 0, counts.size());
    }
    for pass in &frame.dynamic_passes {
        record_pass(encoder, pass, &frame, [classify, scan, expand], solid, "hao_voxelize_dynamic");
    }
    span.end(ctx.command_encoder());

    let span = diagnostics.time_span(ctx.command_encoder(), "hao/resolve");
    for work in &frame.resolve {
        {
            let encoder = ctx.command_encoder();
            let mut cpass = encoder.begin_compute_pass(&ComputePassDescriptor {
                label: Some("hao_voxel_resolve"),
                timestamp_writes: None,
            });
            cpass.set_pipeline(resolve);
            cpass.set_bind_group(0, &work.bind_group, &[]);
            let w = work.workgroups;
            cpass.dispatch_workgroups(w.x.max(1), w.y.max(1), w.z.max(1));
        }
        // One pass per level: each reads the level the previous one wrote.
        for (bind_group, w) in &work.mips {
            let encoder = ctx.command_encoder();
            let mut cpass = encoder
                .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_voxel_mip"), timestamp_writes: None });
            cpass.set_pipeline(mip);
            cpass.set_bind_group(0, bind_group, &[]);
            cpass.dispatch_workgroups(w.x.max(1), w.y.max(1), w.z.max(1));
        }
    }
    span.end(ctx.command_encoder());
}
