//! GPU point-tessellated voxelization in Bevy's renderer.
//!
//! Every frame, before the cameras render (Bevy 0.19's `RenderGraph` schedule, before `camera_driver`):
//!
//! The volume is a set of *levels*: one grid ([`crate::VolumeBounds::FitStaticScene`],
//! [`crate::VolumeBounds::World`]) or the cascades that follow the camera (the default; see
//! [`crate::cpu::cascade`]). Each frame places the levels, then:
//!
//! 1. **voxelize static** (only the regions that changed: the slabs a cascade scrolled into, the boxes
//!    where a static occluder was added, moved, changed or removed, whole levels when rebuilt): `clear`, then
//!    `classify` (one invocation per triangle, read
//!    from the mesh allocator's slabs: equation 1, and small triangles injected at once), `scan` (prefix
//!    sums over the queued big triangles, and the point budget), `expand` (indirect, one invocation per
//!    sub-triangle of the big triangles) into the static occupancy bits and point counts;
//! 2. **voxelize dynamic**: the static grid copied into the frame's grid, then the same three passes for
//!    dynamic geometry on top, once per level it overlaps;
//! 3. **resolve**: the frame's bits into the 3D voxel texture over the boxes that changed, and its
//!    max-reduced mips.
//!
//! Sampling passes bind [`VoxelGridBindings`] at [`VOXEL_GRID_GROUP`] and import `bevy_hao::voxel_grid`.
//!
//! The CPU twin of passes 1 and 2 is [`mod@crate::cpu::voxelize`]; the WGSL files beside this module name their
//! functions after it. GPU time spans: `hao/voxelize_static`, `hao/voxelize_dynamic`, `hao/resolve` (add
//! Bevy's `RenderDiagnosticsPlugin` to see them).

pub(crate) mod bindings;
mod budget;
mod calibration;
mod changes;
pub mod components;
pub(crate) mod extract;
pub(crate) mod pass;
pub(crate) mod pipelines;
mod prepare;
pub(crate) mod stats;
pub(crate) mod volume;

pub use bindings::{VOXEL_GRID_GROUP, VoxelGridBindings, voxel_grid_layout};
pub use extract::RebuildStaticVoxels;
pub use stats::{CascadeLevelStats, LevelBytes, VoxelizationStats, VoxelizationStatsData};
pub use stats::{VoxelizeCounters, VoxelizeCpuTime};
pub use volume::VoxelGridAssets;

use bevy::asset::embedded_asset;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::mesh::allocator::MeshAllocatorSettings;
use bevy::render::render_resource::BufferUsages;
use bevy::render::renderer::{RenderDevice, RenderGraph, RenderGraphSystems};
use bevy::render::{ExtractSchedule, GpuResourceAppExt, Render, RenderApp, RenderSystems};
use bevy::shader::load_shader_library;

/// Storage buffers the voxelization passes bind in one stage (classify: 3 in group 0, 5 in group 1).
pub const REQUIRED_STORAGE_BUFFERS: u32 = 8;

/// Voxelizes the scene every frame (added by [`crate::HaoPlugin`]).
#[derive(Default)]
pub struct VoxelizationPlugin;

impl Plugin for VoxelizationPlugin {
    fn build(&self, app: &mut App) {
        load_shader_library!(app, "voxelize_common.wgsl");
        load_shader_library!(app, "voxelize_pass.wgsl");
        load_shader_library!(app, "voxelize_vertices.wgsl");
        load_shader_library!(app, "voxel_grid.wgsl");
        embedded_asset!(app, "voxel_clear.wgsl");
        embedded_asset!(app, "voxelize_classify.wgsl");
        embedded_asset!(app, "voxelize_scan.wgsl");
        embedded_asset!(app, "voxelize_expand.wgsl");
        embedded_asset!(app, "voxelize_solid.wgsl");
        embedded_asset!(app, "voxel_resolve.wgsl");
        embedded_asset!(app, "voxel_mip.wgsl");
        app.register_type::<crate::voxel::components::StaticOccluder>()
            .register_type::<crate::voxel::components::DynamicOccluder>()
            .register_type::<crate::voxel::components::NoVoxelOcclusion>()
            .register_type::<crate::voxel::components::PnTriangles>()
            .register_type::<crate::voxel::components::VoxelFill>()
            .register_type::<crate::voxel::components::PromotedToDynamic>()
            .register_type::<crate::voxel::components::VoxelVolume>()
            .add_message::<extract::RebuildStaticVoxels>()
            .init_resource::<extract::StaticRebuildRequests>()
            .add_systems(PostUpdate, extract::count_rebuild_requests);
    }

    fn finish(&self, app: &mut App) {
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        let limits = render_app.world().resource::<RenderDevice>().limits();
        let lacking = if limits.max_storage_buffers_per_shader_stage < REQUIRED_STORAGE_BUFFERS {
            Some(format!(
                "Limits::max_storage_buffers_per_shader_stage is {} (needs {REQUIRED_STORAGE_BUFFERS})",
                limits.max_storage_buffers_per_shader_stage
            ))
        } else if limits.max_storage_textures_per_shader_stage < 1 {
            Some("the device has no storage textures".to_string())
        } else if limits.max_compute_invocations_per_workgroup < 256 {
            Some(format!(
                "Limits::max_compute_invocations_per_workgroup is {} (needs 256)",
                limits.max_compute_invocations_per_workgroup
            ))
        } else {
            None
        };
        if let Some(why) = lacking {
            warn!("bevy_hao: voxelization is disabled: {why}. Voxel ambient occlusion will not be rendered");
            return;
        }
        // Read mesh data where Bevy keeps it: the allocator's slabs must be bindable as storage, and no slab
        // may exceed what one binding can address.
        let max_binding = limits.max_storage_buffer_binding_size;
        {
            let mut settings = render_app.world_mut().resource_mut::<MeshAllocatorSettings>();
            settings.extra_buffer_usages |= BufferUsages::STORAGE;
            let s = &mut settings.slab_allocator_settings;
            s.min_slab_size = s.min_slab_size.min(max_binding);
            s.max_slab_size = s.max_slab_size.min(max_binding);
            s.large_threshold = s.large_threshold.min(max_binding);
        }
        let stats = stats::VoxelizationStats::default();
        app.insert_resource(stats.clone())
            .init_resource::<volume::VoxelVolumeFocus>()
            .init_resource::<volume::AttributesWanted>()
            .init_resource::<calibration::GammaForTarget>()
            .init_resource::<changes::OccluderChanges>()
            .add_systems(
                PostUpdate,
                (
                    changes::track_occluders,
                    volume::update_voxel_focus,
                    calibration::choose_gamma_for_target,
                    volume::update_voxel_volume,
                    budget::estimate_point_budget,
                )
                    .chain()
                    .after(bevy::transform::TransformSystems::Propagate)
                    .after(bevy::camera::visibility::VisibilitySystems::CalculateBounds),
            );
        let render_app = app.sub_app_mut(RenderApp);
        render_app
            .insert_resource(stats)
            .init_resource::<extract::ExtractedOccluders>()
            .init_resource::<extract::ExtractedVoxelGrid>()
            .init_resource::<prepare::VoxelizeState>()
            .init_gpu_resource::<pipelines::VoxelizePipelines>()
            .init_gpu_resource::<bindings::VoxelGridLayout>()
            .add_systems(ExtractSchedule, (extract::extract_voxel_grid, extract::extract_voxel_occluders))
            .add_systems(
                Render,
                (prepare::prepare_voxelize, bindings::prepare_voxel_grid_bindings)
                    .chain()
                    .in_set(RenderSystems::PrepareBindGroups),
            )
            .add_systems(RenderGraph, pass::voxelize.in_set(RenderGraphSystems::Render).before(camera_driver));
    }
}
