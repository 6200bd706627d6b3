//! Per-view textures, settings and bind groups of the HAO passes.

use super::HybridAmbientOcclusion;
use super::pipelines::HaoPipelines;
use bevy::core_pipeline::prepass::{PreviousViewUniforms, ViewPrepassTextures};
use bevy::pbr::ScreenSpaceAmbientOcclusionResources;
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, TemporalJitter};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::texture::{CachedTexture, TextureCache};
use bevy::render::view::ViewUniforms;
use bytemuck::{Pod, Zeroable};

/// The WGSL `HaoSettings`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub struct GpuHaoSettings {
    /// Rays per pixel.
    pub rays: u32,
    /// Texel visits per ray.
    pub steps: u32,
    /// World units.
    pub max_distance: f32,
    /// Falloff exponent.
    pub falloff: f32,
    /// Occlusion scale.
    pub intensity: f32,
    /// Ray start offset, cells.
    pub start_offset: f32,
    /// Noise frame (0 unless TAA jitters the view).
    pub frame: u32,
    /// 1 to take the minimum with SSAO.
    pub near_field: u32,
    /// 1 to trace at half resolution.
    pub half_resolution: u32,
    /// Bilateral filter radius.
    pub denoise_radius: u32,
    /// Most frames of temporal history (1: none).
    pub accumulation_frames: u32,
    /// 1 to pass through voxels whose average normal faces along the ray.
    pub back_hits: u32,
}

/// A view's HAO textures and settings.
#[derive(Component)]
pub struct HaoViewResources {
    /// The traced AO with view depth and normal (half or full resolution).
    pub noisy: CachedTexture,
    /// The temporal history this frame reads (last frame's output): ao, view depth, packed normal, frames.
    /// Once the temporal pass has read it, the horizontal half of the denoiser writes into it (the next
    /// frame's temporal pass overwrites it whole).
    pub history: CachedTexture,
    /// The temporal history this frame writes, same layout.
    pub history_out: CachedTexture,
    /// At half resolution, the denoised AO at the traced resolution, in the history's layout (at full
    /// resolution the upsample pass filters vertically itself, and there is none).
    pub filtered: Option<CachedTexture>,
    /// The denoised AO at full resolution (and near-field combined).
    pub result: CachedTexture,
    /// The settings uniform.
    pub settings: Buffer,
    /// Size of the noisy texture.
    pub trace_size: UVec2,
    /// Size of the view.
    pub view_size: UVec2,
}

/// A view's HAO bind groups.
#[derive(Component)]
pub struct HaoBindGroups {
    /// The view uniform.
    pub view: BindGroup,
    /// Trace.
    pub trace: BindGroup,
    /// The view and the previous view, for the temporal pass.
    pub temporal_view: BindGroup,
    /// Temporal accumulation.
    pub temporal: BindGroup,
    /// Horizontal denoise.
    pub denoise_horizontal: BindGroup,
    /// Vertical denoise, at half resolution (at full resolution the upsample pass does it).
    pub denoise_vertical: Option<BindGroup>,
    /// Upsample and near field.
    pub upsample: BindGroup,
    /// Apply.
    pub apply: BindGroup,
}

/// Creates the per-view textures and settings.
pub fn prepare_hao_textures(
    mut commands: Commands,
    mut texture_cache: ResMut<TextureCache>,
    device: Res<RenderDevice>,
    views: Query<(Entity, &ExtractedCamera, &HybridAmbientOcclusion, Has<TemporalJitter>)>,
    mut frame: Local<u32>,
) {
    *frame = frame.wrapping_add(1);
    for (entity, camera, hao, jitter) in &views {
        let Some(view_size) = camera.physical_viewport_size else { continue };
        // Invalid values are replaced (and reported once in the main world, by `report_invalid_settings`).
        let (hao, _) = hao.sanitized();
        let hao = &hao;
        let (rays, steps, half) = hao.trace_parameters_at(view_size);
        let trace_size = if half { (view_size + UVec2::ONE) / 2 } else { view_size };
        let texture = |cache: &mut TextureCache, label: &'static str, size: UVec2, format: TextureFormat| {
            cache.get(
                &device,
                TextureDescriptor {
                    label: Some(label),
                    size: Extent3d { width: size.x.max(1), height: size.y.max(1), depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: TextureDimension::D2,
                    format,
                    usage: TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                },
            )
        };
        let noisy = texture(&mut texture_cache, "hao_noisy_texture", trace_size, TextureFormat::Rgba16Float);
        let filtered =
            half.then(|| texture(&mut texture_cache, "hao_filtered_texture", trace_size, TextureFormat::Rgba32Float));
        // Two histories, read and written in turn (the texture cache hands each label's texture back while
        // it is used every frame; a new one is zeroed, which reads as no history).
        let a = texture(&mut texture_cache, "hao_history_a_texture", trace_size, TextureFormat::Rgba32Float);
        let b = texture(&mut texture_cache, "hao_history_b_texture", trace_size, TextureFormat::Rgba32Float);
        let (history, history_out) = if (*frame).is_multiple_of(2) { (a, b) } else { (b, a) };
        let result = texture(&mut texture_cache, "hao_result_texture", view_size, TextureFormat::R32Float);
        let settings = GpuHaoSettings {
            rays,
            steps,
            max_distance: hao.max_distance,
            falloff: hao.falloff,
            intensity: hao.intensity,
            start_offset: hao.start_offset,
            // The noise turns every frame when frames are accumulated (or TAA averages them).
            frame: if jitter || hao.accumulation_frames > 1 { *frame } else { 0 },
            near_field: hao.near_field as u32,
            half_resolution: half as u32,
            denoise_radius: hao.denoise_radius,
            accumulation_frames: hao.accumulation_frames,
            back_hits: hao.ignore_back_hits as u32,
        };
        let settings = crate::gpu::uniform_buffer(&device, "hao_settings", &settings, BufferUsages::UNIFORM);
        commands.entity(entity).insert(HaoViewResources {
            noisy,
            history,
            history_out,
            filtered,
            result,
            settings,
            trace_size,
            view_size,
        });
    }
}

/// Creates the per-view bind groups.
#[allow(clippy::too_many_arguments)]
pub fn prepare_hao_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    pipelines: Res<HaoPipelines>,
    cache: Res<PipelineCache>,
    view_uniforms: Res<ViewUniforms>,
    previous_view_uniforms: Res<PreviousViewUniforms>,
    views: Query<(Entity, &HaoViewResources, &ViewPrepassTextures, &ScreenSpaceAmbientOcclusionResources)>,
) {
    let Some(view_binding) = view_uniforms.uniforms.binding() else { return };
    let Some(previous_view_binding) = previous_view_uniforms.uniforms.binding() else { return };
    for (entity, res, prepass, ssao) in &views {
        let (Some(depth), Some(normal)) = (prepass.depth_view(), prepass.normal_view()) else { continue };
        let ssao_view = &ssao.screen_space_ambient_occlusion_texture.default_view;
        let view = device.create_bind_group(
            "hao_view_bind_group",
            &cache.get_bind_group_layout(&pipelines.view_layout),
            &BindGroupEntries::single(view_binding.clone()),
        );
        let trace = device.create_bind_group(
            "hao_trace_bind_group",
            &cache.get_bind_group_layout(&pipelines.trace_layout),
            &BindGroupEntries::sequential((depth, normal, res.settings.as_entire_binding(), &res.noisy.default_view)),
        );
        let temporal_view = device.create_bind_group(
            "hao_temporal_view_bind_group",
            &cache.get_bind_group_layout(&pipelines.temporal_view_layout),
            &BindGroupEntries::sequential((view_binding.clone(), previous_view_binding.clone())),
        );
        let temporal = device.create_bind_group(
            "hao_temporal_bind_group",
            &cache.get_bind_group_layout(&pipelines.temporal_layout),
            &BindGroupEntries::sequential((
                &res.noisy.default_view,
                &res.history.default_view,
                depth,
                res.settings.as_entire_binding(),
                &res.history_out.default_view,
            )),
        );
        let denoise = |label, input: &CachedTexture, output: &CachedTexture| {
            device.create_bind_group(
                label,
                &cache.get_bind_group_layout(&pipelines.denoise_layout),
                &BindGroupEntries::sequential((
                    &input.default_view,
                    res.settings.as_entire_binding(),
                    &output.default_view,
                )),
            )
        };
        let denoise_horizontal = denoise("hao_denoise_horizontal_bind_group", &res.history_out, &res.history);
        let denoise_vertical =
            res.filtered.as_ref().map(|f| denoise("hao_denoise_vertical_bind_group", &res.history, f));
        // At full resolution the upsample pass filters the horizontal half's output itself.
        let upsample_input = res.filtered.as_ref().unwrap_or(&res.history);
        let upsample = device.create_bind_group(
            "hao_upsample_bind_group",
            &cache.get_bind_group_layout(&pipelines.upsample_layout),
            &BindGroupEntries::sequential((
                &upsample_input.default_view,
                depth,
                normal,
                ssao_view,
                res.settings.as_entire_binding(),
                &res.result.default_view,
            )),
        );
        let apply = device.create_bind_group(
            "hao_apply_bind_group",
            &cache.get_bind_group_layout(&pipelines.apply_layout),
            &BindGroupEntries::sequential((&res.result.default_view, ssao_view)),
        );
        commands.entity(entity).insert(HaoBindGroups {
            view,
            trace,
            temporal_view,
            temporal,
            denoise_horizontal,
            denoise_vertical,
            upsample,
            apply,
        });
    }
}
