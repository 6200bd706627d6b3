//! The HAO passes of a view, in `Core3d` after Bevy's SSAO and before anything lights with ambient
//! occlusion (the main opaque pass, deferred lighting).

use super::pipelines::HaoPipelines;
use super::prepare::{HaoBindGroups, HaoViewResources};
use crate::gpu::SCREEN_WORKGROUP;
use crate::voxel::{VOXEL_GRID_GROUP, VoxelGridBindings};
use bevy::core_pipeline::prepass::PreviousViewUniformOffset;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderContext, ViewQuery};
use bevy::render::view::ViewUniformOffset;

fn groups(size: UVec2) -> (u32, u32) {
    (size.x.div_ceil(SCREEN_WORKGROUP), size.y.div_ceil(SCREEN_WORKGROUP))
}

/// Trace, bound the history (neighborhood, when accumulating), accumulate, denoise (and with the near field,
/// apply).
pub fn hao(
    view: ViewQuery<(&HaoViewResources, &HaoBindGroups, &ViewUniformOffset, &PreviousViewUniformOffset)>,
    pipelines: Res<HaoPipelines>,
    voxel_grid: Option<Res<VoxelGridBindings>>,
    cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (res, bind_groups, view_offset, previous_view_offset) = view.into_inner();
    let Some(voxel_grid) = voxel_grid else { return };
    let back_hits = res.traces_back_hits(&voxel_grid.grid);
    let Some([trace, neighborhood, temporal, denoise, denoise_near_field, apply]) =
        pipelines.view_pipelines(&cache, res.samples, back_hits)
    else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let encoder = ctx.command_encoder();
    encoder.push_debug_group("hao");
    {
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some("hao_trace"), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, "hao/trace");
        pass.set_pipeline(trace);
        pass.set_bind_group(0, &bind_groups.trace, &[]);
        pass.set_bind_group(1, &bind_groups.view, &[view_offset.offset]);
        pass.set_bind_group(VOXEL_GRID_GROUP, &voxel_grid.bind_group, &[]);
        let (x, y) = groups(res.trace_size);
        pass.dispatch_workgroups(x, y, 1);
        span.end(&mut pass);
    }
    // Without accumulation the temporal pass keeps no history and reads no window.
    if res.accumulates {
        let mut pass = encoder
            .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_neighborhood"), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, "hao/neighborhood");
        pass.set_pipeline(neighborhood);
        pass.set_bind_group(0, &bind_groups.neighborhood, &[]);
        let (x, y) = groups(res.trace_size);
        pass.dispatch_workgroups(x, y, 1);
        span.end(&mut pass);
    }
    {
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some("hao_temporal"), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, "hao/temporal");
        pass.set_pipeline(temporal);
        pass.set_bind_group(0, &bind_groups.temporal, &[]);
        pass.set_bind_group(1, &bind_groups.temporal_view, &[view_offset.offset, previous_view_offset.offset]);
        pass.set_bind_group(VOXEL_GRID_GROUP, &voxel_grid.bind_group, &[]);
        let (x, y) = groups(res.view_size);
        pass.dispatch_workgroups(x, y, 1);
        span.end(&mut pass);
    }
    // The denoiser writes into the texture PBR reads; with the near field, into the result texture with
    // the minimum of Bevy's SSAO, which apply then copies there.
    let denoise_pipeline = if bind_groups.apply.is_some() { denoise_near_field } else { denoise };
    {
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some("hao_denoise"), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, "hao/denoise");
        pass.set_pipeline(denoise_pipeline);
        pass.set_bind_group(0, &bind_groups.denoise, &[]);
        let (x, y) = groups(res.view_size);
        pass.dispatch_workgroups(x, y, 1);
        span.end(&mut pass);
    }
    if let Some(apply_group) = &bind_groups.apply {
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some("hao_apply"), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, "hao/apply");
        pass.set_pipeline(apply);
        pass.set_bind_group(0, apply_group, &[]);
        let (x, y) = groups(res.view_size);
        pass.dispatch_workgroups(x, y, 1);
        span.end(&mut pass);
    }
    encoder.pop_debug_group();
}
