//! The GI passes of the frame, in the `RenderGraph` schedule after the voxelization and before the cameras
//! render: the lighting volume, then the probes that gather it and the irradiance volume they fill.

use super::lighting::{GiLightingFrame, GiLightingPipeline};
use super::probes::{GiProbePipelines, GiProbesFrame};
use crate::voxel::{VOXEL_GRID_GROUP, VoxelGridBindings};
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderContext;

/// Lights one slab of the voxels, updates this frame's share of the probes and writes the irradiance
/// volume.
pub fn gi(
    lighting: Option<Res<GiLightingFrame>>,
    probes: Option<Res<GiProbesFrame>>,
    lighting_pipeline: Res<GiLightingPipeline>,
    probe_pipelines: Res<GiProbePipelines>,
    voxel_grid: Option<Res<VoxelGridBindings>>,
    cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (Some(lighting), Some(voxel_grid)) = (lighting, voxel_grid) else { return };
    let Some(light_voxels) = cache.get_compute_pipeline(lighting_pipeline.pipeline) else { return };
    let probe_passes = probes.as_ref().zip(probe_pipelines.get(&cache));
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let encoder = ctx.command_encoder();
    // One compute pass: its label, GPU span, pipeline, bind group and workgroups.
    let mut pass = |label: &'static str, span: &'static str, pipeline, group: &BindGroup, w: UVec3| {
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, span);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.set_bind_group(1, &lighting.empty, &[]);
        pass.set_bind_group(VOXEL_GRID_GROUP, &voxel_grid.bind_group, &[]);
        pass.dispatch_workgroups(w.x, w.y, w.z);
        span.end(&mut pass);
    };
    pass("hao_gi_lighting", "hao/gi_lighting", light_voxels, &lighting.bind_group, lighting.workgroups);
    if let Some((frame, [update, write])) = probe_passes {
        // The far probes first: the near volume is written from their records.
        if let Some(far) = &frame.far {
            pass("hao_gi_update_far_probes", "hao/gi_far_probes", update, &far.bind_group, far.update_groups);
            pass("hao_gi_write_far_probes", "hao/gi_far_write", write, &far.bind_group, far.write_groups);
        }
        let near = &frame.near;
        pass("hao_gi_update_probes", "hao/gi_probes", update, &near.bind_group, near.update_groups);
        pass("hao_gi_write_probes", "hao/gi_write", write, &near.bind_group, near.write_groups);
    }
}
