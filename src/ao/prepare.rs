//! Per-view textures, settings and bind groups of the HAO passes.

use super::HybridAmbientOcclusion;
use super::pbr_texture::PbrAoTexture;
use super::pipelines::{
    FILTERED_TEXEL_BYTES, HISTORY_TEXEL_BYTES, HaoPipelines, SHOWN_TEXEL_BYTES, TRACE_TEXEL_BYTES, TraceVariant,
    WINDOW_TEXEL_BYTES,
};
use crate::voxel::bindings::GpuVoxelGrid;
use crate::voxel::extract::ExtractedVoxelGrid;
use bevy::core_pipeline::prepass::{PreviousViewData, PreviousViewUniforms, ViewPrepassTextures};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, TemporalJitter};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy::render::texture::{CachedTexture, TextureCache};
use bevy::render::view::{Msaa, ViewUniforms};
use bytemuck::{Pod, Zeroable};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// The WGSL `HaoSettings`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub struct GpuHaoSettings {
    /// The previous frame's `clip_from_world` with the previous frame's TAA jitter (Bevy's
    /// `PreviousViewData` holds it without), so the history is read where it was traced.
    pub previous_clip_from_world: Mat4,
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
    /// The filter's width, trace texels.
    pub denoise_radius: u32,
    /// Most frames of temporal history (1: none).
    pub accumulation_frames: u32,
    /// 1 to pass through voxels whose average normal faces along the ray.
    pub back_hits: u32,
    /// 0 when the history must not be read: the view is new, was resized or was off last frame.
    pub history_valid: u32,
    /// The view's first pixel in its render target (its viewport's corner), x.
    pub origin_x: u32,
    /// And y.
    pub origin_y: u32,
    /// The view's width in pixels: the temporal history's rows.
    pub view_width: u32,
    /// The view's height in pixels.
    pub view_height: u32,
    /// The trace's width in texels: the rows of its buffers.
    pub trace_width: u32,
    /// The trace's height in texels.
    pub trace_height: u32,
    /// 1 to trace each ray's first cells in the depth prepass.
    pub depth_contacts: u32,
    /// 1 to trace half the texels a frame, in a checkerboard that alternates.
    pub checkerboard: u32,
    /// Points each ray's depth contacts sample in the depth prepass.
    pub contact_samples: u32,
    /// Most frames of temporal history where the view stands still.
    pub still_accumulation_frames: u32,
    /// Padding to the struct's alignment (its matrix's 16 bytes).
    pub _pad_c: u32,
}

/// What a view's temporal pass needs from its last frame: the TAA jitter, sizes and settings it had, when,
/// and whether its passes ran then.
#[derive(Clone)]
pub struct ViewHistory {
    jitter: Vec2,
    /// The settings it was traced with (sanitized).
    settings: HybridAmbientOcclusion,
    view_size: UVec2,
    trace_size: UVec2,
    frame: u32,
    /// Set by the render node once it has recorded the view's passes (`HaoViewResources::history_written`):
    /// a view prepared in a frame whose passes did not run (a pipeline still compiling, no voxel grid yet)
    /// wrote no history then.
    written: Arc<AtomicBool>,
}

impl ViewHistory {
    /// Whether a view traced at `trace_size` in frame `frame` may read the history this record describes:
    /// only one written the frame before, at the same size (a resize, a view that was off, or passes that
    /// did not run restart it).
    pub fn continues(&self, view_size: UVec2, trace_size: UVec2, frame: u32) -> bool {
        self.frame.wrapping_add(1) == frame
            && self.view_size == view_size
            && self.trace_size == trace_size
            && self.written.load(Ordering::Relaxed)
    }

    /// The frames a still pixel's history keeps this frame, with `settings` (sanitized): their
    /// `still_history_frames`, or in a frame whose settings differ from the last frame's
    /// `accumulation_frames`, which cuts every longer history short, so that a change of the settings
    /// (an inspector's slider) shows as fast as it would in a view that moves.
    pub fn still_history_frames(last: Option<&Self>, settings: &HybridAmbientOcclusion) -> u32 {
        match last {
            Some(last) if last.settings != *settings => settings.accumulation_frames.clamp(1, 64),
            _ => settings.still_history_frames(),
        }
    }
}

/// The previous frame's `clip_from_world` as that frame was rendered: with its TAA jitter (at its viewport
/// size), which Bevy's `PreviousViewData` leaves out.
pub fn previous_clip_from_world(previous: &PreviousViewData, jitter: Vec2, view_size: UVec2) -> Mat4 {
    let mut clip_from_view = previous.clip_from_view;
    TemporalJitter { offset: jitter }.jitter_projection(&mut clip_from_view, view_size.as_vec2());
    clip_from_view * previous.view_from_world
}

/// A view's HAO buffers, textures and settings.
#[derive(Component)]
pub struct HaoViewResources {
    /// The traced AO with the traced pixel's view depth and normal (half or full resolution), its texels row by
    /// row.
    pub noisy: Buffer,
    /// The window of each texel of the trace that bounds the history (the neighborhood pass's output), laid
    /// out as `noisy`.
    pub window: Buffer,
    /// Each texel of the trace filtered by the neighborhood pass (the denoiser), laid out as `noisy`.
    pub filtered: Buffer,
    /// The temporal history this frame reads (last frame's output): ao, view depth, packed normal, frames,
    /// 64 bits a pixel, the view's pixels row by row.
    pub history: Buffer,
    /// The temporal history this frame writes, same layout.
    pub history_out: Buffer,
    /// The AO each pixel showed last frame and the frames of the history it was taken from, which the
    /// temporal pass reads and writes in place (two 16-bit unorms a pixel, laid out as the history;
    /// `stable_ao` in hao_common.wgsl).
    pub shown: Buffer,
    /// With the near field: the AO combined with Bevy's SSAO, which apply copies into the texture PBR reads
    /// (without, the temporal pass writes there itself).
    pub result: Option<CachedTexture>,
    /// The settings uniform (the view's own buffer, written each frame).
    pub settings: Buffer,
    /// Size of the trace.
    pub trace_size: UVec2,
    /// Invocations of the trace: its size, or with the checkerboard half its width.
    pub trace_dispatch: UVec2,
    /// Size of the view.
    pub view_size: UVec2,
    /// MSAA samples of the view's prepasses (1: none).
    pub samples: u32,
    /// The trace's loops asked for (`ignore_back_hits`, `depth_free_space`): see `trace_variant`.
    pub requested_trace: TraceVariant,
    /// Whether the minimum with Bevy's SSAO is taken: the near field asked for, on a view Bevy's SSAO can run
    /// on (no MSAA, a viewport at the target's corner).
    pub near_field: bool,
    /// The texture PBR reads AO from in place of Bevy's SSAO texture, the target's size, where the viewport
    /// does not start at the target's corner (PBR reads it at target coordinates; Bevy's is the viewport's
    /// size). See `pbr_texture`.
    pub pbr_texture: Option<CachedTexture>,
    /// Set once the render node has recorded this frame's passes, which write `history_out`: next frame's
    /// history is read only then (`ViewHistory::continues`).
    pub history_written: Arc<AtomicBool>,
}

impl HaoViewResources {
    /// The view's trace on `grid`: through the backs of surfaces where asked for and the grid keeps the
    /// voxels' normals, past the voxel hits the view shows in free space where asked for (the trace
    /// pipeline with the `BACK_HITS` or `FREE_SPACE` loop; `HaoPipelines::view_pipelines`), near the
    /// occluders that moved where the grid lists any (the trace and temporal pass with `MOVED_OCCLUDERS`).
    pub fn trace_variant(&self, grid: &GpuVoxelGrid) -> TraceVariant {
        self.requested_trace.on_grid(grid.attributes != 0).with_moved(grid.moved_count > 0)
    }
}

/// A view's HAO bind groups.
#[derive(Component)]
pub struct HaoBindGroups {
    /// The view uniform.
    pub view: BindGroup,
    /// Trace.
    pub trace: BindGroup,
    /// The neighborhood pass.
    pub neighborhood: BindGroup,
    /// The view and the previous view, for the temporal pass.
    pub temporal_view: BindGroup,
    /// Temporal accumulation and the filter: into the texture PBR reads, or with the near field into the
    /// result texture.
    pub temporal: BindGroup,
    /// With the near field: apply, the result texture into the texture PBR reads.
    pub apply: Option<BindGroup>,
}

/// Creates the per-view textures and settings.
#[allow(clippy::too_many_arguments)]
pub fn prepare_hao_textures(
    mut commands: Commands,
    mut texture_cache: ResMut<TextureCache>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut pipelines: ResMut<HaoPipelines>,
    cache: Res<PipelineCache>,
    views: Query<(
        Entity,
        &ExtractedCamera,
        &HybridAmbientOcclusion,
        &Msaa,
        Option<&TemporalJitter>,
        Option<&PreviousViewData>,
    )>,
    mut frame: Local<u32>,
    mut histories: Local<HashMap<Entity, (ViewHistory, ViewBuffers)>>,
    voxel_grid: Option<Res<ExtractedVoxelGrid>>,
) {
    *frame = frame.wrapping_add(1);
    let grid_has_attributes = voxel_grid.is_some_and(|g| g.assets.as_ref().is_some_and(|a| a.attributes.is_some()));
    for (entity, camera, hao, msaa, jitter, previous_view) in &views {
        let Some(view_size) = camera.physical_viewport_size else { continue };
        let samples = msaa.samples();
        let origin = camera.viewport.as_ref().map_or(UVec2::ZERO, |v| v.physical_position);
        // Invalid values are replaced (and reported once in the main world, by `report_invalid_settings`).
        let (hao, _) = hao.sanitized();
        let hao = &hao;
        // The trace through the backs of surfaces is compiled only for a grid with attributes.
        let requested_trace = TraceVariant::requested(hao);
        pipelines.queue_view(&cache, samples, requested_trace.on_grid(grid_has_attributes));
        let (rays, steps, half) = hao.trace_parameters();
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
        // Last frame's record of the view and its buffers, kept while it is prepared every frame at one size:
        // the settings, the trace, its windows and filtered AO, and two histories read and written in turn
        // (new ones are zeroed, which reads as no history).
        let (last, buffers) = match histories.remove(&entity) {
            Some((last, buffers)) if (last.view_size, last.trace_size) == (view_size, trace_size) => {
                (Some(last), buffers)
            }
            kept => (kept.map(|(last, _)| last), ViewBuffers::new(&device, view_size, trace_size)),
        };
        let [a, b] = buffers.history.clone();
        let (history, history_out) = if (*frame).is_multiple_of(2) { (a, b) } else { (b, a) };
        let (noisy, window, filtered) = (buffers.noisy.clone(), buffers.window.clone(), buffers.filtered.clone());
        let (settings, shown) = (buffers.settings.clone(), buffers.shown.clone());
        let pbr_texture = (origin != UVec2::ZERO)
            .then(|| texture(&mut texture_cache, "hao_pbr_ao_texture", origin + view_size, pipelines.ao_format));
        let near_field = hao.near_field && super::near_field_can_run(samples, origin);
        let result =
            near_field.then(|| texture(&mut texture_cache, "hao_result_texture", view_size, TextureFormat::R32Float));
        let jitter_offset = jitter.map_or(Vec2::ZERO, |j| j.offset);
        let history_written = Arc::new(AtomicBool::new(false));
        let record = ViewHistory {
            jitter: jitter_offset,
            settings: hao.clone(),
            view_size,
            trace_size,
            frame: *frame,
            written: history_written.clone(),
        };
        histories.insert(entity, (record, buffers));
        let history_valid = last.as_ref().is_some_and(|l| l.continues(view_size, trace_size, *frame));
        let still_history_frames = ViewHistory::still_history_frames(last.as_ref(), hao);
        let previous_clip_from_world = match (previous_view, last) {
            (Some(previous), Some(last)) => previous_clip_from_world(previous, last.jitter, last.view_size),
            (Some(previous), None) => previous.clip_from_world,
            // No previous view (its first frame): the history is not read.
            (None, _) => Mat4::IDENTITY,
        };
        let history_read = history_valid && previous_view.is_some();
        // The checkerboard keeps half the trace's texels from last frame: a view without a last frame
        // traces them all.
        let checkerboard = hao.uses_checkerboard() && half && history_read;
        let trace_dispatch = if checkerboard { UVec2::new(trace_size.x.div_ceil(2), trace_size.y) } else { trace_size };
        let gpu_settings = GpuHaoSettings {
            previous_clip_from_world,
            rays,
            steps,
            max_distance: hao.max_distance,
            falloff: hao.falloff,
            intensity: hao.intensity,
            start_offset: hao.start_offset,
            // The noise turns every frame when frames are accumulated (or TAA averages them).
            frame: if jitter.is_some() || hao.accumulation_frames > 1 { *frame } else { 0 },
            near_field: near_field as u32,
            half_resolution: half as u32,
            denoise_radius: hao.denoise_radius,
            accumulation_frames: hao.accumulation_frames,
            back_hits: hao.ignore_back_hits as u32,
            history_valid: history_read as u32,
            origin_x: origin.x,
            origin_y: origin.y,
            view_width: view_size.x,
            view_height: view_size.y,
            trace_width: trace_size.x,
            trace_height: trace_size.y,
            depth_contacts: hao.depth_contacts as u32,
            checkerboard: checkerboard as u32,
            contact_samples: hao.contact_samples(),
            still_accumulation_frames: still_history_frames,
            _pad_c: 0,
        };
        // Written into the view's own buffer before this frame's passes run (the last frame's passes were
        // submitted before this write).
        queue.write_buffer(&settings, 0, &crate::gpu::uniform_bytes(&gpu_settings));
        commands.entity(entity).insert(HaoViewResources {
            noisy,
            window,
            filtered,
            history,
            history_out,
            shown,
            result,
            settings,
            trace_size,
            trace_dispatch,
            view_size,
            samples,
            requested_trace,
            near_field,
            pbr_texture,
            history_written,
        });
    }
    // Views not prepared this frame (off, removed, despawned) are forgotten; when they come back their
    // history starts again.
    histories.retain(|_, (h, _)| h.frame == *frame);
}

/// The bytes of one of a view's temporal histories (a storage buffer, bound whole; a view whose history
/// exceeds the device's binding limit gets no AO: `skip_unsupported_views`). The history is the largest of a
/// view's buffers: the others hold at most as many bytes a texel, for at most as many texels (the trace's).
pub(crate) fn history_bytes(view_size: UVec2) -> u64 {
    buffer_bytes(view_size, HISTORY_TEXEL_BYTES)
}

/// The bytes of a buffer of `size` texels of `texel_bytes` each, row by row (at least one texel, so that it
/// can be bound; saturating, so that an absurd size reads as too large rather than wrapping).
fn buffer_bytes(size: UVec2, texel_bytes: u64) -> u64 {
    u64::from(size.x.max(1)).saturating_mul(u64::from(size.y.max(1))).saturating_mul(texel_bytes)
}

// The binding-limit check on the history covers every buffer of a view (see `history_bytes`).
const _: () = assert!(
    TRACE_TEXEL_BYTES <= HISTORY_TEXEL_BYTES
        && WINDOW_TEXEL_BYTES <= HISTORY_TEXEL_BYTES
        && FILTERED_TEXEL_BYTES <= HISTORY_TEXEL_BYTES
        && SHOWN_TEXEL_BYTES <= HISTORY_TEXEL_BYTES
);

/// A view's buffers (see `HaoViewResources`), for the view size and trace size of its `ViewHistory`.
pub struct ViewBuffers {
    settings: Buffer,
    noisy: Buffer,
    window: Buffer,
    filtered: Buffer,
    history: [Buffer; 2],
    shown: Buffer,
}

impl ViewBuffers {
    fn new(device: &RenderDevice, view_size: UVec2, trace_size: UVec2) -> Self {
        let buffer = |label, size: UVec2, texel_bytes: u64| {
            device.create_buffer(&BufferDescriptor {
                label: Some(label),
                size: buffer_bytes(size, texel_bytes),
                usage: BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        Self {
            settings: device.create_buffer(&BufferDescriptor {
                label: Some("hao_settings"),
                size: GpuHaoSettings::min_size().get(),
                usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            noisy: buffer("hao_noisy_buffer", trace_size, TRACE_TEXEL_BYTES),
            window: buffer("hao_window_buffer", trace_size, WINDOW_TEXEL_BYTES),
            filtered: buffer("hao_filtered_buffer", trace_size, FILTERED_TEXEL_BYTES),
            history: [
                buffer("hao_history_a_buffer", view_size, HISTORY_TEXEL_BYTES),
                buffer("hao_history_b_buffer", view_size, HISTORY_TEXEL_BYTES),
            ],
            shown: buffer("hao_shown_buffer", view_size, SHOWN_TEXEL_BYTES),
        }
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
    views: Query<(Entity, &HaoViewResources, &ViewPrepassTextures, PbrAoTexture)>,
) {
    let Some(view_binding) = view_uniforms.uniforms.binding() else { return };
    let Some(previous_view_binding) = previous_view_uniforms.uniforms.binding() else { return };
    for (entity, res, prepass, pbr_ao) in &views {
        let (Some(depth), Some(normal)) = (prepass.depth_view(), prepass.normal_view()) else { continue };
        let Some(ssao_view) = pbr_ao.view() else { continue };
        let Some(readers) = pipelines.readers(res.samples) else { continue };
        let view = device.create_bind_group(
            "hao_view_bind_group",
            &cache.get_bind_group_layout(&pipelines.view_layout),
            &BindGroupEntries::single(view_binding.clone()),
        );
        let trace = device.create_bind_group(
            "hao_trace_bind_group",
            &cache.get_bind_group_layout(&readers.trace_layout),
            &BindGroupEntries::sequential((
                depth,
                normal,
                res.settings.as_entire_binding(),
                res.noisy.as_entire_binding(),
            )),
        );
        let neighborhood = device.create_bind_group(
            "hao_neighborhood_bind_group",
            &cache.get_bind_group_layout(&pipelines.neighborhood_layout),
            &BindGroupEntries::sequential((
                res.noisy.as_entire_binding(),
                res.settings.as_entire_binding(),
                res.window.as_entire_binding(),
                res.filtered.as_entire_binding(),
            )),
        );
        let temporal_view = device.create_bind_group(
            "hao_temporal_view_bind_group",
            &cache.get_bind_group_layout(&pipelines.temporal_view_layout),
            &BindGroupEntries::sequential((view_binding.clone(), previous_view_binding.clone())),
        );
        // The temporal pass writes the AO into the texture PBR reads; with the near field, with the minimum of
        // Bevy's SSAO (read from that texture) into the result texture, which apply copies there. The two
        // layouts share their first entries (`prepass_readers`), and so do the bind groups.
        let common = BindGroupEntries::sequential((
            res.noisy.as_entire_binding(),
            res.window.as_entire_binding(),
            res.filtered.as_entire_binding(),
            res.history.as_entire_binding(),
            depth,
            normal,
            res.settings.as_entire_binding(),
            res.history_out.as_entire_binding(),
            res.shown.as_entire_binding(),
            ssao_view,
        ));
        let (temporal, apply) = match &res.result {
            None => {
                let temporal = device.create_bind_group(
                    "hao_temporal_bind_group",
                    &cache.get_bind_group_layout(&readers.temporal_layout),
                    &common,
                );
                (temporal, None)
            }
            Some(result) => {
                let mut entries = common.to_vec();
                entries.push(BindGroupEntry {
                    binding: entries.len() as u32,
                    resource: BindingResource::TextureView(&result.default_view),
                });
                let temporal = device.create_bind_group(
                    "hao_temporal_near_field_bind_group",
                    &cache.get_bind_group_layout(&readers.temporal_near_field_layout),
                    &entries,
                );
                let apply = device.create_bind_group(
                    "hao_apply_bind_group",
                    &cache.get_bind_group_layout(&pipelines.apply_layout),
                    &BindGroupEntries::sequential((&result.default_view, res.settings.as_entire_binding(), ssao_view)),
                );
                (temporal, Some(apply))
            }
        };
        commands.entity(entity).insert(HaoBindGroups { view, trace, neighborhood, temporal_view, temporal, apply });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_continues_only_from_the_frame_before_at_the_same_size() {
        let h = ViewHistory {
            jitter: Vec2::ZERO,
            settings: HybridAmbientOcclusion::default(),
            view_size: UVec2::new(64, 48),
            trace_size: UVec2::new(32, 24),
            frame: 7,
            written: Arc::new(AtomicBool::new(true)),
        };
        assert!(h.continues(UVec2::new(64, 48), UVec2::new(32, 24), 8));
        // A resize of the view or of the traced resolution, a frame missed (off, skipped), the same frame.
        assert!(!h.continues(UVec2::new(65, 48), UVec2::new(33, 24), 8));
        assert!(!h.continues(UVec2::new(64, 48), UVec2::new(64, 48), 8));
        assert!(!h.continues(UVec2::new(64, 48), UVec2::new(32, 24), 9));
        assert!(!h.continues(UVec2::new(64, 48), UVec2::new(32, 24), 7));
        let wrapping = ViewHistory { frame: u32::MAX, ..h.clone() };
        assert!(wrapping.continues(UVec2::new(64, 48), UVec2::new(32, 24), 0));
        // Prepared the frame before, but its passes did not run (the node left early): no history written.
        let not_run = ViewHistory { written: Arc::new(AtomicBool::new(false)), ..h };
        assert!(!not_run.continues(UVec2::new(64, 48), UVec2::new(32, 24), 8));
    }

    #[test]
    fn a_change_of_settings_cuts_a_still_history_short_for_a_frame() {
        let settings = HybridAmbientOcclusion::default();
        let last = ViewHistory {
            jitter: Vec2::ZERO,
            settings: settings.clone(),
            view_size: UVec2::new(64, 48),
            trace_size: UVec2::new(32, 24),
            frame: 7,
            written: Arc::new(AtomicBool::new(true)),
        };
        assert_eq!(ViewHistory::still_history_frames(Some(&last), &settings), 127);
        assert_eq!(ViewHistory::still_history_frames(None, &settings), 127);
        let brighter = HybridAmbientOcclusion { intensity: 0.5, ..settings.clone() };
        assert_eq!(ViewHistory::still_history_frames(Some(&last), &brighter), 16);
        // Never under accumulation_frames, at most what the texel holds; none without accumulation.
        let short = HybridAmbientOcclusion { still_accumulation_frames: 4, ..settings.clone() };
        assert_eq!(short.still_history_frames(), 16);
        let none = HybridAmbientOcclusion { accumulation_frames: 1, ..settings.clone() };
        assert_eq!(none.still_history_frames(), 1);
        let (fixed, fixes) = HybridAmbientOcclusion { still_accumulation_frames: 1000, ..settings }.sanitized();
        assert_eq!((fixed.still_accumulation_frames, fixes.len()), (127, 1), "{fixes:?}");
    }

    #[test]
    fn a_history_fits_webgpus_default_binding_limit_up_to_about_16_million_pixels() {
        let limit = bevy::render::settings::WgpuLimits::default().max_storage_buffer_binding_size;
        assert!(history_bytes(UVec2::new(5120, 2880)) <= limit);
        assert!(history_bytes(UVec2::new(4096, 4096)) <= limit);
        assert!(history_bytes(UVec2::new(4097, 4096)) > limit);
        assert!(history_bytes(UVec2::new(7680, 4320)) > limit);
        // A side of 0 still gets a buffer that can be bound (the view is not drawn then).
        assert_eq!(history_bytes(UVec2::new(0, 720)), 720 * HISTORY_TEXEL_BYTES);
        // An absurd size is too large, not wrapped round to a small one.
        assert!(history_bytes(UVec2::MAX) > limit);
    }

    #[test]
    fn the_previous_view_gets_its_own_jitter() {
        let projection = Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1);
        let view_from_world = Mat4::from_translation(Vec3::new(0.0, 0.0, -5.0));
        let previous = PreviousViewData {
            view_from_world,
            clip_from_world: projection * view_from_world,
            clip_from_view: projection,
            world_from_clip: (projection * view_from_world).inverse(),
            view_from_clip: projection.inverse(),
        };
        let size = UVec2::new(100, 50);
        let at = |m: Mat4| {
            let c = m * Vec4::new(0.3, 0.2, 0.0, 1.0);
            (c.truncate().truncate() / c.w) * Vec2::new(0.5, -0.5) * size.as_vec2()
        };
        assert_eq!(previous_clip_from_world(&previous, Vec2::ZERO, size), previous.clip_from_world);
        // A jitter of (0.25, -0.5) pixels moves every point by that much in pixels (y down).
        let moved = at(previous_clip_from_world(&previous, Vec2::new(0.25, -0.5), size)) - at(previous.clip_from_world);
        // (Bevy's jitter moves the image against the offset in x and with it in y.)
        assert!((moved - Vec2::new(-0.25, 0.5)).length() < 1e-3, "{moved}");
    }
}
