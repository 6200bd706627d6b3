//! The HAO pipelines.

use super::prepare::GpuHaoSettings;
use crate::gpu::queue_compute;
use crate::voxel::voxel_grid_layout;
use bevy::asset::load_embedded_asset;
use bevy::core_pipeline::prepass::PreviousViewData;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{texture_2d, texture_depth_2d, texture_storage_2d, uniform_buffer};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderAdapter;
use bevy::render::view::ViewUniform;

/// The HAO pipelines and layouts.
#[derive(Resource)]
pub struct HaoPipelines {
    /// Group 1 of trace and upsample: the view uniform.
    pub view_layout: BindGroupLayoutDescriptor,
    /// Group 0 of trace.
    pub trace_layout: BindGroupLayoutDescriptor,
    /// Group 0 of the temporal pass.
    pub temporal_layout: BindGroupLayoutDescriptor,
    /// Group 1 of the temporal pass: the view and the previous view.
    pub temporal_view_layout: BindGroupLayoutDescriptor,
    /// Group 0 of both halves of the denoiser.
    pub denoise_layout: BindGroupLayoutDescriptor,
    /// Group 0 of the upsample.
    pub upsample_layout: BindGroupLayoutDescriptor,
    /// Group 0 of apply.
    pub apply_layout: BindGroupLayoutDescriptor,
    /// Rays through the voxels.
    pub trace: CachedComputePipelineId,
    /// Temporal accumulation.
    pub temporal: CachedComputePipelineId,
    /// Bilateral filter, horizontal half.
    pub denoise_horizontal: CachedComputePipelineId,
    /// Bilateral filter, vertical half.
    pub denoise_vertical: CachedComputePipelineId,
    /// To full resolution, and the near field.
    pub upsample: CachedComputePipelineId,
    /// Into the texture PBR reads.
    pub apply: CachedComputePipelineId,
}

impl FromWorld for HaoPipelines {
    fn from_world(world: &mut World) -> Self {
        let adapter = world.resource::<RenderAdapter>();
        // The same rule as bevy_pbr's SsaoPipelines.
        let ssao_format = if adapter
            .get_texture_format_features(TextureFormat::R16Float)
            .allowed_usages
            .contains(TextureUsages::STORAGE_BINDING)
        {
            TextureFormat::R16Float
        } else {
            TextureFormat::R32Float
        };
        let unfilterable = TextureSampleType::Float { filterable: false };
        let view_layout = BindGroupLayoutDescriptor::new(
            "hao_view_layout",
            &BindGroupLayoutEntries::single(ShaderStages::COMPUTE, uniform_buffer::<ViewUniform>(true)),
        );
        let trace_layout = BindGroupLayoutDescriptor::new(
            "hao_trace_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_depth_2d(),
                    texture_2d(unfilterable),
                    uniform_buffer::<GpuHaoSettings>(false),
                    texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let temporal_layout = BindGroupLayoutDescriptor::new(
            "hao_temporal_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_2d(unfilterable),
                    texture_2d(unfilterable),
                    texture_depth_2d(),
                    uniform_buffer::<GpuHaoSettings>(false),
                    texture_storage_2d(TextureFormat::Rgba32Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let temporal_view_layout = BindGroupLayoutDescriptor::new(
            "hao_temporal_view_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (uniform_buffer::<ViewUniform>(true), uniform_buffer::<PreviousViewData>(true)),
            ),
        );
        let denoise_layout = BindGroupLayoutDescriptor::new(
            "hao_denoise_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_2d(unfilterable),
                    uniform_buffer::<GpuHaoSettings>(false),
                    texture_storage_2d(TextureFormat::Rgba32Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let upsample_layout = BindGroupLayoutDescriptor::new(
            "hao_upsample_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_2d(unfilterable),
                    texture_depth_2d(),
                    texture_2d(unfilterable),
                    texture_2d(unfilterable),
                    uniform_buffer::<GpuHaoSettings>(false),
                    texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let apply_layout = BindGroupLayoutDescriptor::new(
            "hao_apply_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (texture_2d(unfilterable), texture_storage_2d(ssao_format, StorageTextureAccess::WriteOnly)),
            ),
        );
        let cache = world.resource::<PipelineCache>();
        let queue_pipeline =
            |label, layout, shader, entry, defs| queue_compute(cache, label, layout, shader, entry, defs);
        let trace = queue_pipeline(
            "hao_trace",
            vec![trace_layout.clone(), view_layout.clone(), voxel_grid_layout()],
            load_embedded_asset!(world, "hao_trace.wgsl"),
            "trace",
            vec![],
        );
        let temporal = queue_pipeline(
            "hao_temporal",
            vec![temporal_layout.clone(), temporal_view_layout.clone(), voxel_grid_layout()],
            load_embedded_asset!(world, "hao_temporal.wgsl"),
            "temporal",
            vec![],
        );
        let denoise_horizontal = queue_pipeline(
            "hao_denoise_horizontal",
            vec![denoise_layout.clone()],
            load_embedded_asset!(world, "hao_denoise.wgsl"),
            "denoise_horizontal",
            vec![],
        );
        let denoise_vertical = queue_pipeline(
            "hao_denoise_vertical",
            vec![denoise_layout.clone()],
            load_embedded_asset!(world, "hao_denoise.wgsl"),
            "denoise_vertical",
            vec![],
        );
        let upsample = queue_pipeline(
            "hao_upsample",
            vec![upsample_layout.clone(), view_layout.clone()],
            load_embedded_asset!(world, "hao_upsample.wgsl"),
            "upsample",
            vec![],
        );
        let apply_defs = if ssao_format == TextureFormat::R16Float { vec!["USE_R16FLOAT".into()] } else { vec![] };
        let apply = queue_pipeline(
            "hao_apply",
            vec![apply_layout.clone()],
            load_embedded_asset!(world, "hao_apply.wgsl"),
            "apply",
            apply_defs,
        );
        Self {
            view_layout,
            trace_layout,
            temporal_layout,
            temporal_view_layout,
            denoise_layout,
            upsample_layout,
            apply_layout,
            trace,
            temporal,
            denoise_horizontal,
            denoise_vertical,
            upsample,
            apply,
        }
    }
}
