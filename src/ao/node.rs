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

/// Workgroups covering `size` invocations.
fn groups_for(size: UVec2) -> (u32, u32) {
    (size.x.div_ceil(SCREEN_WORKGROUP), size.y.div_ceil(SCREEN_WORKGROUP))
}

/// Trace, filter and bound (neighborhood), accumulate (and with the near field, apply).
pub fn hao(
    view: ViewQuery<(&HaoViewResources, &HaoBindGroups, &ViewUniformOffset, &PreviousViewUniformOffset)>,
    pipelines: Res<HaoPipelines>,
    voxel_grid: Option<Res<VoxelGridBindings>>,
    cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (res, bind_groups, view_offset, previous_view_offset) = view.into_inner();
    let Some(voxel_grid) = voxel_grid else { return };
    let Some([trace, neighborhood, temporal, temporal_near_field, apply]) =
        pipelines.view_pipelines(&cache, res.samples, res.trace_variant(&voxel_grid.grid))
    else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let encoder = ctx.command_encoder();
    encoder.push_debug_group("hao");
    // One compute pass: its label, GPU span, pipeline, bind groups (with their dynamic offsets) and size in
    // pixels (one invocation each).
    let mut pass = |label: &'static str, span: &'static str, pipeline, groups: &[(u32, &BindGroup, &[u32])], size| {
        let mut pass =
            encoder.begin_compute_pass(&ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        let span = diagnostics.pass_span(&mut pass, span);
        pass.set_pipeline(pipeline);
        for &(index, group, offsets) in groups {
            pass.set_bind_group(index, group, offsets);
        }
        let (x, y) = groups_for(size);
        pass.dispatch_workgroups(x, y, 1);
        span.end(&mut pass);
    };
    pass(
        "hao_trace",
        "hao/trace",
        trace,
        &[
            (0, &bind_groups.trace, &[]),
            (1, &bind_groups.view, &[view_offset.offset]),
            (VOXEL_GRID_GROUP, &voxel_grid.bind_group, &[]),
        ],
        res.trace_dispatch,
    );
    pass("hao_neighborhood", "hao/neighborhood", neighborhood, &[(0, &bind_groups.neighborhood, &[])], res.trace_size);
    // The temporal pass writes into the texture PBR reads; with the near field, into the result texture with
    // the minimum of Bevy's SSAO, which apply then copies there.
    pass(
        "hao_temporal",
        "hao/temporal",
        if bind_groups.apply.is_some() { temporal_near_field } else { temporal },
        &[
            (0, &bind_groups.temporal, &[]),
            (1, &bind_groups.temporal_view, &[view_offset.offset, previous_view_offset.offset]),
            (VOXEL_GRID_GROUP, &voxel_grid.bind_group, &[]),
        ],
        res.view_size,
    );
    if let Some(apply_group) = &bind_groups.apply {
        pass("hao_apply", "hao/apply", apply, &[(0, apply_group, &[])], res.view_size);
    }
    encoder.pop_debug_group();
    // The temporal pass wrote this frame's history: next frame reads it.
    res.history_written.store(true, std::sync::atomic::Ordering::Relaxed);
}
