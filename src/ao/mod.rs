//! Hybrid ambient occlusion: per pixel, rays through the voxel grid.
//!
//! Per view with a [`HybridAmbientOcclusion`], in `Core3d` after Bevy's SSAO and before the main opaque pass
//! and deferred lighting:
//!
//! 1. **trace** (`hao_trace.wgsl`, GPU span `hao/trace`): from each pixel's world position and normal (the
//!    depth and normal prepasses), cosine-weighted hemisphere rays, rotated per pixel (and per frame when
//!    frames are accumulated or TAA jitters the view), start about a voxel off the surface and march the
//!    voxel texture up to `max_distance`, skipping empty space on its mips; each hit weighs
//!    `(1 - d/max)^falloff`. At half resolution each 2x2 block traces one of its pixels a frame, in turn;
//!    `Low` traces half the blocks a frame, in a checkerboard that alternates, and the others keep their
//!    last frame's trace;
//! 2. **neighborhood** (`hao_neighborhood.wgsl`, `hao/neighborhood`), at the trace's resolution: from each
//!    texel's 3x3 neighbourhood of traced AO, the window its pixels allow their history (mean plus or minus
//!    two standard deviations), and its AO filtered over them by a depth- and normal-aware bilateral weight
//!    (the denoiser), once for the pixels that read it;
//! 3. **temporal** (`hao_temporal.wgsl`, `hao/temporal`), at full resolution: the history reprojected,
//!    checked, clamped to its window and blended with the pixel's own filtered trace (at half resolution
//!    every fourth frame, every eighth in the checkerboard; a pixel without history takes its traced neighbours
//!    on its surface meanwhile; where the view stands still, a pixel keeps showing the AO it showed while
//!    its long history stays near it). It
//!    writes the result into the texture Bevy's PBR reads AO from, so it dims indirect light only;
//! 4. with the near field only, the temporal pass writes a texture of its own with the minimum of Bevy's
//!    SSAO, and **apply** (`hao_apply.wgsl`, `hao/apply`) copies it into the texture PBR reads (which holds
//!    Bevy's SSAO until then, so the temporal pass cannot write there itself).
//!
//! The CPU twins: [`crate::cpu::ao`] (trace), [`crate::cpu::temporal`], [`crate::cpu::denoise`].

pub(crate) mod node;
pub(crate) mod pbr_texture;
mod pipelines;
pub(crate) mod prepare;

use bevy::asset::embedded_asset;
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::core_3d::main_opaque_pass_3d;
use bevy::core_pipeline::prepass::{DepthPrepass, NormalPrepass};
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::pbr::{
    ScreenSpaceAmbientOcclusion, ScreenSpaceAmbientOcclusionQualityLevel, ScreenSpaceAmbientOcclusionResources,
    SsaoBindGroups, SsaoPipelineId,
};
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, MipBias, TemporalJitter};
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_resource::PipelineCache;
use bevy::render::renderer::RenderDevice;
use bevy::render::sync_world::MainEntity;
use bevy::render::view::{ExtractedView, NoIndirectDrawing, RenderVisibleEntities, ViewUniformOffset};
use bevy::render::{ExtractSchedule, GpuResourceAppExt, Render, RenderApp, RenderSystems};
use bevy::shader::load_shader_library;

/// Renders [`HybridAmbientOcclusion`] (added by [`crate::HaoPlugin`]).
#[derive(Default)]
pub struct HybridAmbientOcclusionPlugin;

impl Plugin for HybridAmbientOcclusionPlugin {
    fn build(&self, app: &mut App) {
        load_shader_library!(app, "hao_common.wgsl");
        load_shader_library!(app, "hao_change.wgsl");
        embedded_asset!(app, "hao_trace.wgsl");
        embedded_asset!(app, "hao_neighborhood.wgsl");
        embedded_asset!(app, "hao_temporal.wgsl");
        embedded_asset!(app, "hao_apply.wgsl");
        app.register_type::<HybridAmbientOcclusion>()
            .add_plugins(ExtractComponentPlugin::<HybridAmbientOcclusion>::default())
            .add_systems(PostUpdate, (configure_hao_cameras, report_invalid_settings));
    }

    fn finish(&self, app: &mut App) {
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        // Bevy's SSAO plugin, whose texture is the only way AO reaches PBR, loads only with 5 storage textures
        // per stage (WebGPU's default is 4).
        if render_app.world().resource::<RenderDevice>().limits().max_storage_textures_per_shader_stage < 5 {
            warn!(
                "bevy_hao: hybrid ambient occlusion is disabled: Limits::max_storage_textures_per_shader_stage is below 5 (Bevy 0.19 then makes no SSAO texture, the only way ambient occlusion reaches its PBR shading)"
            );
            return;
        }
        render_app
            .init_gpu_resource::<pipelines::HaoPipelines>()
            .add_systems(ExtractSchedule, pbr_texture::extract_multisampled_views)
            .add_systems(
                Render,
                skip_unsupported_views.after(RenderSystems::ExtractCommands).before(RenderSystems::PrepareAssets),
            )
            .add_systems(
                Render,
                (
                    prepare::prepare_hao_textures.in_set(RenderSystems::PrepareResources),
                    pbr_texture::hold_ao_textures.in_set(RenderSystems::PrepareResourcesFlush),
                    pbr_texture::return_held_ao_textures
                        .in_set(RenderSystems::Prepare)
                        .after(RenderSystems::PrepareBindGroups),
                    prepare::prepare_hao_bind_groups.in_set(RenderSystems::PrepareBindGroups),
                    skip_unused_ssao
                        .in_set(RenderSystems::PrepareBindGroups)
                        .after(prepare::prepare_hao_bind_groups)
                        .after(crate::voxel::bindings::prepare_voxel_grid_bindings),
                ),
            )
            .add_systems(
                Core3d,
                node::hao
                    .in_set(Core3dSystems::MainPass)
                    .before(main_opaque_pass_3d)
                    .before(bevy::pbr::deferred::deferred_lighting),
            );
    }
}

/// The smallest viewport side, in pixels, that HAO runs on: Bevy's SSAO textures, which carry HAO's result
/// to PBR, hold a depth mip chain of 5 levels, which a viewport needs 16 pixels on its longer side for (and
/// no texture has a side of 0). Smaller viewports (a window dragged tiny, a minimized or zero-size one) get
/// no ambient occlusion for as long as they are that small, with one warning per camera.
pub const MIN_VIEWPORT_PIXELS: u32 = 16;

/// The most frames of weight a pixel's history holds (its texel keeps them to an eighth in 10 bits:
/// `bevy_hao::cpu::denoise::HistoryTexel::stored`), the most `still_accumulation_frames` can keep.
const MAX_HISTORY_FRAMES: u32 = crate::cpu::temporal::MAX_HISTORY_FRAMES as u32;

/// Whether HAO (and Bevy's SSAO textures with it) can run on a viewport of `size` pixels.
pub fn viewport_supported(size: UVec2) -> bool {
    size.min_element() >= 1 && size.max_element() >= MIN_VIEWPORT_PIXELS
}

/// Takes HAO and the SSAO it brings off this frame's render-world view where its viewport is too small for
/// Bevy's SSAO textures (see [`MIN_VIEWPORT_PIXELS`]) or so large that its temporal history exceeds the
/// device's storage buffer binding limit, with one warning per camera and reason, before the views' pipeline
/// keys are made (so PBR does not expect the texture either); a view with a side of 0 is not rendered at all
/// this frame. The main world is untouched, so AO comes back when the view allows it again.
fn skip_unsupported_views(
    mut commands: Commands,
    views: Query<(Entity, &MainEntity, &ExtractedCamera), With<HybridAmbientOcclusion>>,
    device: Res<RenderDevice>,
    mut warned: Local<bevy::platform::collections::HashSet<(MainEntity, bool)>>,
) {
    let limits = device.limits();
    let history_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    for (entity, main, camera) in &views {
        let size = camera.physical_viewport_size.unwrap_or_default();
        let too_large = prepare::history_bytes(size) > history_limit;
        if viewport_supported(size) && !too_large {
            continue;
        }
        if too_large && warned.insert((*main, true)) {
            warn!(
                "bevy_hao: camera {}'s viewport is {}x{} pixels: no ambient occlusion while its temporal history ({} bytes) exceeds the device's storage buffer binding limit ({history_limit} bytes, the smaller of Limits::max_storage_buffer_binding_size and max_buffer_size)",
                main.id(),
                size.x,
                size.y,
                prepare::history_bytes(size)
            );
        } else if !too_large && warned.insert((*main, false)) {
            warn!(
                "bevy_hao: camera {}'s viewport is {}x{} pixels: no ambient occlusion while a side is 0 or both are under {MIN_VIEWPORT_PIXELS} (Bevy's SSAO textures, which carry it to PBR, cannot be that small)",
                main.id(),
                size.x,
                size.y
            );
        }
        if size.min_element() == 0 {
            // Nothing of a zero-size viewport is seen: the view is not rendered this frame, as Bevy does for a
            // zero-size target (Bevy's clustering would make a texture of side 0 for it).
            commands.entity(entity).remove::<(
                ExtractedCamera,
                ExtractedView,
                RenderVisibleEntities,
                TemporalJitter,
                MipBias,
                RenderLayers,
                Projection,
                NoIndirectDrawing,
                ViewUniformOffset,
            )>();
        }
        commands.entity(entity).remove::<(
            HybridAmbientOcclusion,
            prepare::HaoViewResources,
            prepare::HaoBindGroups,
            ScreenSpaceAmbientOcclusion,
            ScreenSpaceAmbientOcclusionResources,
            SsaoPipelineId,
            SsaoBindGroups,
            pbr_texture::HeldAoTexture,
        )>();
    }
}

/// Keeps Bevy's SSAO passes from running on a HAO view whose near field is off: their result would be
/// overwritten by HAO's temporal pass, which writes every texel of the texture PBR reads. Bevy's SSAO node
/// runs only on views with an `SsaoPipelineId`, so removing it this frame skips the passes while the texture
/// and PBR's binding of it stay. Only when HAO's passes will run this frame (their bind groups, the voxel
/// grid and the pipelines are ready); otherwise SSAO fills the texture as before.
fn skip_unused_ssao(
    mut commands: Commands,
    views: Query<(Entity, &prepare::HaoViewResources), (With<SsaoPipelineId>, With<prepare::HaoBindGroups>)>,
    pipelines: Res<pipelines::HaoPipelines>,
    voxel_grid: Option<Res<crate::voxel::VoxelGridBindings>>,
    cache: Res<PipelineCache>,
) {
    let Some(voxel_grid) = voxel_grid else { return };
    for (entity, res) in &views {
        if pipelines.view_pipelines(&cache, res.samples, res.trace_variant(&voxel_grid.grid)).is_some()
            && !res.near_field
        {
            commands.entity(entity).remove::<SsaoPipelineId>();
        }
    }
}

/// Whether the near field (Bevy's SSAO) can run on a view with `samples` MSAA samples whose viewport starts
/// at pixel `origin` of its target: Bevy's SSAO reads single-sampled prepasses at viewport coordinates.
pub(crate) fn near_field_can_run(samples: u32, origin: UVec2) -> bool {
    samples == 1 && origin == UVec2::ZERO
}

/// The SSAO quality a HAO camera asks for: its near-field quality, or the cheapest when the near field is
/// off (PBR reads AO from SSAO's texture, so the component must be there; its passes are skipped while HAO's
/// run, see `skip_unused_ssao`, and fill the texture in the frames before HAO is ready).
fn ssao_for(hao: &HybridAmbientOcclusion) -> ScreenSpaceAmbientOcclusion {
    ScreenSpaceAmbientOcclusion {
        quality_level: if hao.near_field {
            hao.near_field_quality
        } else {
            ScreenSpaceAmbientOcclusionQualityLevel::Custom { slice_count: 1, samples_per_slice_side: 1 }
        },
        ..default()
    }
}

/// Gives HAO cameras Bevy's SSAO, whose texture carries HAO's result to PBR (added and removed with HAO
/// unless the user put it there). Not on a camera with MSAA, which Bevy's SSAO refuses: there the render world
/// gets it (see `pbr_texture`). Warns once per camera where the near field cannot run.
fn configure_hao_cameras(
    mut commands: Commands,
    cameras: Query<(
        Entity,
        &Camera,
        Ref<HybridAmbientOcclusion>,
        Option<&ScreenSpaceAmbientOcclusion>,
        Has<HaoAddedSsao>,
        Ref<Msaa>,
    )>,
    mut removed: RemovedComponents<HybridAmbientOcclusion>,
    added_ssao: Query<(), With<HaoAddedSsao>>,
    mut warned: Local<bevy::platform::collections::HashSet<(Entity, &'static str)>>,
) {
    for (entity, camera, hao, ssao, we_added, msaa) in &cameras {
        let multisampled = *msaa != Msaa::Off;
        let origin = camera.viewport.as_ref().map_or(UVec2::ZERO, |v| v.physical_position);
        if hao.near_field && !near_field_can_run(msaa.samples(), origin) {
            let why = if multisampled { "MSAA" } else { "a viewport that does not start at the target's corner" };
            if warned.insert((entity, why)) {
                warn!(
                    "bevy_hao: camera {entity}: HybridAmbientOcclusion::near_field needs Bevy's SSAO, which cannot run with {why}; HAO runs without the near field"
                );
            }
        }
        match ssao {
            Some(_) if multisampled && we_added => {
                commands.entity(entity).remove::<(ScreenSpaceAmbientOcclusion, HaoAddedSsao)>();
            }
            Some(_) if multisampled && msaa.is_changed() => {
                warn!(
                    "bevy_hao: camera {entity} has MSAA and Bevy's ScreenSpaceAmbientOcclusion, which needs Msaa::Off; HAO runs with MSAA without it (remove it, or use the near field with Msaa::Off)"
                );
            }
            None if !multisampled => {
                commands.entity(entity).insert((ssao_for(&hao), HaoAddedSsao));
            }
            Some(current) if we_added && hao.is_changed() => {
                let wanted = ssao_for(&hao);
                if *current != wanted {
                    commands.entity(entity).insert(wanted);
                }
            }
            _ => {}
        }
    }
    for entity in removed.read() {
        if added_ssao.contains(entity) && !cameras.contains(entity) {
            commands.entity(entity).remove::<(ScreenSpaceAmbientOcclusion, HaoAddedSsao)>();
        }
    }
}

/// Warns once per camera and message about invalid [`HybridAmbientOcclusion`] values (the render world
/// replaces them the same way, see [`HybridAmbientOcclusion::sanitized`]).
fn report_invalid_settings(
    cameras: Query<(Entity, &HybridAmbientOcclusion), Changed<HybridAmbientOcclusion>>,
    mut warned: Local<bevy::platform::collections::HashSet<(Entity, String)>>,
) {
    for (entity, hao) in &cameras {
        for f in hao.sanitized().1 {
            if warned.insert((entity, f.clone())) {
                warn!("bevy_hao: camera {entity}: {f}");
            }
        }
    }
}

/// Voxel-based hybrid ambient occlusion on a 3D camera: per pixel, rays through the scene's voxel grid
/// (see [`crate::VoxelVolume`]), so occluders off screen, behind other objects or far away still darken what
/// they shadow. The result replaces the ambient occlusion Bevy's PBR shading reads: it dims indirect light
/// (ambient, environment maps, irradiance volumes) only, in forward and deferred rendering.
///
/// Adding it to a camera is enough: it requires the depth and normal prepasses and adds Bevy's
/// `ScreenSpaceAmbientOcclusion`, whose texture is where PBR reads AO and which provides the optional near
/// field (on a camera with MSAA, which Bevy's SSAO refuses, the plugin gives the texture to the render world's
/// view itself, and there is no near field). The camera keeps its MSAA, TAA, viewport and HDR. Removing it
/// removes what it added.
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hao::prelude::*;
/// fn setup(mut commands: Commands) {
///     commands.spawn((Camera3d::default(), HybridAmbientOcclusion::default()));
/// }
/// ```
#[derive(Component, ExtractComponent, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Default, Debug, PartialEq, Clone)]
#[require(DepthPrepass, NormalPrepass)]
#[extract_component_sync_target((Self, prepare::HaoViewResources, prepare::HaoBindGroups))]
pub struct HybridAmbientOcclusion {
    /// Rays, steps and resolution.
    pub quality: HaoQuality,
    /// How far rays look for occluders, world units.
    pub max_distance: f32,
    /// How fast an occluder's weight falls with distance: `(1 - d / max_distance)^falloff` (0: not at all,
    /// 1: linearly, higher: only close occluders count).
    pub falloff: f32,
    /// Scale of the occlusion (1: physically motivated, higher: darker).
    pub intensity: f32,
    /// Rays start this many voxels off the surface along its normal and skip as many voxels along their
    /// path, so that a surface does not occlude itself through the staircase of its own voxels. Occluders
    /// closer than that are found in the depth prepass (`depth_contacts`). 1 measured best against the
    /// ray-traced reference.
    pub start_offset: f32,
    /// Trace each ray's first cells, which the voxels skip (`start_offset`), in the depth prepass: four points
    /// along its first two voxels (per voxel of `start_offset`), the first that lies behind the surface the
    /// view shows, by less than a voxel, stops it there. It finds the contacts no voxel can tell from the
    /// surface itself (mouldings, a floor meeting a wall, layers lying on a surface) without screen-space
    /// AO's halos: the rays reach two voxels only, and what the view cannot see is the voxels' job. On by
    /// default: against the ray-traced reference it lowered HAO's error on every scene measured, most on
    /// Sponza and Sibenik (docs/figures.md), for at most four depth loads a ray.
    ///
    /// With it, the voxel hits within 8 voxels of the surface that the view shows in empty space (a pixel
    /// in front of every surface drawn around them) are passed too, and the march goes on with the steps it
    /// has left: an occupied voxel blocks every ray that crosses it though its surface may lie up to a voxel
    /// away, which beside a crease or a contact (a floor along a wall, under a resting ball) darkened the
    /// AO as if the other surface were a voxel nearer. That halved HAO's error on a room of contacts and
    /// lowered it on the interiors of boxes (docs/figures.md, *Contacts: the near hits the view shows
    /// empty*). Surfaces the view does not draw (a single-sided plane seen from behind) count as empty.
    pub depth_contacts: bool,
    /// Pass the voxel hits that the depth prepass shows in empty space. An occupied voxel blocks every ray
    /// that crosses it, though the surface in it may cover only part of it (most of all in the coarse
    /// cascades, whose voxels are up to 1 m at the defaults), which darkens. Where a ray's hit lies on
    /// screen in front of every surface the view shows around it, by more than a voxel, the ray goes on past
    /// that voxel, at most twice; what the view cannot see stays the voxels' job. `None` (the default):
    /// the preset's choice, on for `High` and `Ultra`, off for `Low`, `Medium` and `Custom`
    /// ([`HybridAmbientOcclusion::uses_depth_free_space`]); `Some` overrides it.
    /// Against the ray-traced reference (docs/figures.md) it lowered `High`'s error by 13 % on the
    /// built-in cathedral and by 27-30 % on two furnished interiors of boxes, and raised it by under 3 % on
    /// Sibenik and Sponza, where the missed contacts' lightening outweighs the voxels' darkening. It costs
    /// nine depth loads for each ray that hits a voxel and another march for each hit it passes, which a
    /// GPU warp runs after every lane's march before it: 20-37 % more texel visits a ray as a warp pays
    /// them (`bench_ao`'s work table); on lavapipe `High`'s trace took half as long again.
    pub depth_free_space: Option<bool>,
    /// Combine with Bevy's screen-space AO (the minimum of both) for contact detail finer than a voxel.
    /// Needs what Bevy's SSAO needs: `Msaa::Off` and a viewport at the target's corner (elsewhere HAO runs
    /// without it, with a warning). Off by default: against a ray-traced reference the minimum measured worse than HAO alone on the
    /// built-in cathedral, Sibenik and Sponza (Bevy's SSAO darkens open surfaces; see `ao_compare`).
    pub near_field: bool,
    /// The quality of Bevy's SSAO when it provides the near field. Without the near field the plugin keeps
    /// SSAO at its cheapest, since its result is not used.
    pub near_field_quality: ScreenSpaceAmbientOcclusionQualityLevel,
    /// Width of the denoiser, in texels of the trace: each frame, before it is accumulated, a pixel's trace
    /// is averaged with the trace's 3x3 texels around it, weighed by a Gaussian of this width and by how
    /// close their depth and normal are to the pixel's (a bilateral filter); 0 turns it off. Near occluders
    /// that move, where the history is short, over 5x5 texels at twice the width.
    pub denoise_radius: u32,
    /// Temporal accumulation: each pixel averages its AO over at most this many frames (1: none; at most
    /// 64), with the ray noise turned every frame, so few rays per frame converge to the error of many. The
    /// history follows the camera (reprojected with its previous matrices), restarts where a surface was
    /// hidden or has moved, and is clamped to the current frame's neighbourhood so that a moving occluder
    /// leaves no trail (see `bevy_hao::cpu::temporal`). At half resolution it counts a pixel's own traces,
    /// one every fourth frame (every eighth in `Low`'s checkerboard), so the history spans
    /// four (eight) times as many frames.
    pub accumulation_frames: u32,
    /// The frames a pixel's history keeps where the view stands still: where its surface reprojects onto
    /// the pixel itself (a still camera, a still surface, no TAA jitter), the history is read exactly, with
    /// no resampling to blur it, and the voxel grid's list of moved occluders shortens it near every occluder
    /// that moves (see `bevy_hao::cpu::temporal`), so it may keep more than `accumulation_frames` and the AO of a
    /// still view settles further. There a pixel whose history is longer than `accumulation_frames` shows
    /// the AO it showed last frame while its history stays within a standard error of it, so a still view
    /// does not shimmer (a history of up to half the frames shown; near occluders that move, the history
    /// itself). Counted as
    /// `accumulation_frames` is (a pixel's own traces); at least `accumulation_frames` (a lower value acts
    /// as it), at most 127 (what the history's texel holds). Lower it for geometry HAO does not see move
    /// (a vertex shader's animation, a `NoVoxelOcclusion` mesh), whose AO a long history would follow more
    /// slowly.
    pub still_accumulation_frames: u32,
    /// With multi-valued voxels ([`crate::VoxelVolume::attributes`]): a ray passes through a voxel whose
    /// average normal clearly faces along it (the back of a surface, which a ray reaches only from inside a
    /// solid, grazing the voxels of its own surface, or behind single-sided geometry) instead of stopping
    /// there (see `bevy_hao::cpu::ao::back_hit_exit`). Voxels of double-sided materials have no normal and
    /// always stop rays; single-sided geometry seen from behind does not. On by default: against the
    /// ray-traced reference it lowered HAO's error on the cathedral, Sibenik and Sponza in a fitted grid and
    /// in cascades (docs/figures.md). No effect without attributes.
    pub ignore_back_hits: bool,
}

impl HybridAmbientOcclusion {
    /// `(rays, steps, half_resolution)` traced each frame: the quality's (see [`HaoQuality`]), with fewer
    /// rays (and `Medium` at half resolution) for the presets when 4 or more frames are accumulated.
    pub fn trace_parameters(&self) -> (u32, u32, bool) {
        self.quality.parameters_accumulated(self.accumulation_frames.clamp(1, 64))
    }

    /// Whether the trace runs in a checkerboard: half the blocks of its half-resolution trace a frame,
    /// alternating, so that each pixel traces its own rays every eighth frame. `Low` does when
    /// 4 or more frames are accumulated.
    pub fn uses_checkerboard(&self) -> bool {
        self.accumulation_frames.clamp(1, 64) >= 4 && self.quality.traces_checkerboard()
    }

    /// Frames between a pixel's own traces: 1 at full resolution, 4 at half resolution (each 2x2 block
    /// traces one of its pixels a frame, in turn), 8 in a checkerboard. A pixel's history of
    /// `accumulation_frames` traces spans that many times the frames.
    pub fn frames_per_trace(&self) -> u32 {
        match (self.trace_parameters().2, self.uses_checkerboard()) {
            (false, _) => 1,
            (true, false) => 4,
            (true, true) => 8,
        }
    }

    /// The frames a still pixel's history keeps (`still_accumulation_frames`, at least
    /// `accumulation_frames`; with 1 accumulation frame, 1: no accumulation).
    pub fn still_history_frames(&self) -> u32 {
        let frames = self.accumulation_frames.clamp(1, 64);
        if frames <= 1 { 1 } else { self.still_accumulation_frames.clamp(frames, MAX_HISTORY_FRAMES) }
    }

    /// Points each ray samples in the depth prepass for its contacts (the occluders within its first two
    /// cells, which the voxels cannot resolve; `depth_contacts`): the quality's, 8 for `High` and `Ultra`
    /// and 4 for the others. At 1920x1080 the 8 lowered `High`'s error against the reference by up to a
    /// tenth on the interiors with mouldings and railings, for a few percent more trace time
    /// (docs/figures.md).
    pub fn contact_samples(&self) -> u32 {
        self.quality.contact_samples()
    }

    /// Whether the trace passes the voxel hits the depth prepass shows in free space: `depth_free_space`
    /// where it is given, else the quality's choice (`High` and `Ultra`).
    pub fn uses_depth_free_space(&self) -> bool {
        self.depth_free_space.unwrap_or(self.quality.passes_free_space())
    }

    /// These settings with every invalid value replaced by the one the passes use, and one message per
    /// replacement naming the field, the value given and the value used (the plugin logs each once per
    /// camera). NaN, infinite, zero or negative distances and exponents are invalid; so are more than 256
    /// rays, more than 1024 steps, a denoise radius above 8, accumulation frames outside 1..=64, or still
    /// accumulation frames above 127.
    pub fn sanitized(&self) -> (HybridAmbientOcclusion, Vec<String>) {
        let mut h = self.clone();
        let mut fixes = Vec::new();
        let mut check = |field: &str, value: &mut f32, ok: fn(f32) -> bool, used: f32| {
            if !ok(*value) {
                fixes.push(format!("HybridAmbientOcclusion::{field} is {value}; using {used}"));
                *value = used;
            }
        };
        let used = if self.max_distance.is_finite() && self.max_distance > 0.0 {
            self.max_distance.clamp(1.0e-3, 1.0e4)
        } else {
            3.0
        };
        check("max_distance", &mut h.max_distance, |v| v.is_finite() && (1.0e-3..=1.0e4).contains(&v), used);
        check(
            "falloff",
            &mut h.falloff,
            |v| v.is_finite() && (0.0..=64.0).contains(&v),
            self.falloff.clamp(0.0, 64.0).max(0.0),
        );
        check(
            "intensity",
            &mut h.intensity,
            |v| v.is_finite() && (0.0..=64.0).contains(&v),
            self.intensity.clamp(0.0, 64.0).max(0.0),
        );
        check(
            "start_offset",
            &mut h.start_offset,
            |v| v.is_finite() && (0.0..=16.0).contains(&v),
            self.start_offset.clamp(0.0, 16.0).max(0.0),
        );
        if !(1..=64).contains(&h.accumulation_frames) {
            let used = h.accumulation_frames.clamp(1, 64);
            fixes.push(format!(
                "HybridAmbientOcclusion::accumulation_frames is {}; using {used}",
                h.accumulation_frames
            ));
            h.accumulation_frames = used;
        }
        if h.still_accumulation_frames > MAX_HISTORY_FRAMES {
            let used = MAX_HISTORY_FRAMES;
            fixes.push(format!(
                "HybridAmbientOcclusion::still_accumulation_frames is {}; using {used}",
                h.still_accumulation_frames
            ));
            h.still_accumulation_frames = used;
        }
        if h.denoise_radius > 8 {
            fixes.push(format!("HybridAmbientOcclusion::denoise_radius is {}; using 8", h.denoise_radius));
            h.denoise_radius = 8;
        }
        if let HaoQuality::Custom { rays, steps, half_resolution } = h.quality {
            let (r, st, _) = h.quality.parameters();
            if (r, st) != (rays, steps) {
                fixes.push(format!(
                    "HybridAmbientOcclusion::quality is Custom {{ rays: {rays}, steps: {steps} }}; using {r} rays and {st} steps"
                ));
                h.quality = HaoQuality::Custom { rays: r, steps: st, half_resolution };
            }
        }
        (h, fixes)
    }
}

impl Default for HybridAmbientOcclusion {
    fn default() -> Self {
        Self {
            quality: HaoQuality::Medium,
            max_distance: 3.0,
            falloff: 1.0,
            intensity: 1.0,
            start_offset: 1.0,
            depth_contacts: true,
            depth_free_space: None,
            near_field: false,
            near_field_quality: ScreenSpaceAmbientOcclusionQualityLevel::Medium,
            denoise_radius: 1,
            accumulation_frames: 16,
            still_accumulation_frames: MAX_HISTORY_FRAMES,
            ignore_back_hits: true,
        }
    }
}

/// Quality presets of [`HybridAmbientOcclusion`]. Each traces fewer rays a frame when frames are
/// accumulated (`accumulation_frames` of 4 or more, the default 16): the rays of 16 frames make up for them
/// (see [`HybridAmbientOcclusion::trace_parameters`]).
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[reflect(Default, Debug, PartialEq, Hash, Clone)]
pub enum HaoQuality {
    /// 24 steps at half resolution: 1 ray a frame accumulated, 4 without. Accumulated, in a checkerboard:
    /// half the 2x2 blocks trace a frame, alternating, and the others keep their last trace, so each pixel
    /// traces its own ray every eighth frame ([`HybridAmbientOcclusion::uses_checkerboard`]). That halves
    /// the trace's work for a few percent more error than `Medium` on a still view and about a tenth more in
    /// motion (docs/figures.md). Without accumulation, under a third of `Medium`'s cost.
    Low,
    /// 32 steps, the default. Accumulated: 1 ray a frame at half resolution, where each 2x2 block traces
    /// one of its pixels a frame, in turn, and every pixel accumulates its own rays (so the AO keeps full
    /// resolution; a pixel's history spans four times the frames): under Bevy's SSAO `High`'s GPU time at
    /// 1920x1080 on the scenes measured, for 3-14 % more error against the ray-traced reference than 2
    /// rays a frame on the interiors measured (docs/figures.md). Without accumulation: 6 rays a frame at
    /// full resolution.
    #[default]
    Medium,
    /// 48 steps. Accumulated: 2 rays a frame at half resolution, as `Medium` (each pixel accumulates its
    /// own rays; 3 measured within 0.0004 of 2 against the reference at 1920x1080 and within 0.0008 at
    /// 320x180, for two fifths more trace time on an NVIDIA H100); without accumulation: 8 rays a frame at
    /// full resolution. Passes the voxel hits the depth prepass shows in free space
    /// ([`HybridAmbientOcclusion::depth_free_space`]) and samples 8 points a ray for its depth contacts
    /// instead of 4 ([`HybridAmbientOcclusion::contact_samples`]): the error left once noise is averaged
    /// away is the voxels' bias, which more rays do not lower, and those two act on it.
    High,
    /// 64 steps. Accumulated: 16 rays a frame at half resolution, as `Medium`; without accumulation: 16
    /// rays a frame at full resolution. Passes free space and samples 8 contact points, as `High`.
    Ultra,
    /// Your own.
    Custom {
        /// Rays per pixel.
        rays: u32,
        /// Texel visits per ray (empty space is skipped at up to 16 voxels a step).
        steps: u32,
        /// Trace at half resolution: one pixel of each 2x2 block a frame, in turn when accumulating (each
        /// pixel accumulates its own rays; where it has no history, its traced neighbours on its surface
        /// stand in).
        half_resolution: bool,
    },
}

impl HaoQuality {
    /// `(rays, steps, half_resolution)` of a frame without temporal accumulation.
    pub(crate) fn parameters(&self) -> (u32, u32, bool) {
        match *self {
            Self::Low => (4, 24, true),
            Self::Medium => (6, 32, false),
            Self::High => (8, 48, false),
            Self::Ultra => (16, 64, false),
            Self::Custom { rays, steps, half_resolution } => {
                (rays.clamp(1, 256), steps.clamp(1, 1024), half_resolution)
            }
        }
    }

    /// Whether the preset passes the voxel hits the depth prepass shows in free space where
    /// `HybridAmbientOcclusion::depth_free_space` leaves it to the preset: `High` and `Ultra`.
    pub(crate) fn passes_free_space(&self) -> bool {
        matches!(self, Self::High | Self::Ultra)
    }

    /// Points each ray's depth contacts sample (`HybridAmbientOcclusion::contact_samples`): 8 for `High`
    /// and `Ultra`, [`crate::cpu::contacts::CONTACT_SAMPLES`] (4) for the others.
    pub(crate) fn contact_samples(&self) -> u32 {
        match self {
            Self::High | Self::Ultra => 8,
            _ => crate::cpu::contacts::CONTACT_SAMPLES,
        }
    }

    /// Whether the preset, accumulated, traces in a checkerboard (`HybridAmbientOcclusion::uses_checkerboard`):
    /// `Low`.
    pub(crate) fn traces_checkerboard(&self) -> bool {
        matches!(self, Self::Low)
    }

    /// `(rays, steps, half_resolution)` of a frame whose result is accumulated over `accumulation_frames`
    /// frames: the presets trace fewer rays from 4 frames on; `Custom` traces what it says.
    pub(crate) fn parameters_accumulated(&self, accumulation_frames: u32) -> (u32, u32, bool) {
        if accumulation_frames < 4 {
            return self.parameters();
        }
        match *self {
            Self::Low => (1, 24, true),
            Self::Medium => (1, 32, true),
            Self::High => (2, 48, true),
            Self::Ultra => (16, 64, true),
            Self::Custom { .. } => self.parameters(),
        }
    }
}

/// Marks a camera whose `ScreenSpaceAmbientOcclusion` was added by [`HybridAmbientOcclusion`] (and goes
/// when it goes).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct HaoAddedSsao;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_presets_trace_as_they_say() {
        let at = |quality, accumulation_frames| {
            HybridAmbientOcclusion { quality, accumulation_frames, ..default() }.trace_parameters()
        };
        assert_eq!(at(HaoQuality::Low, 16), (1, 24, true));
        assert_eq!(at(HaoQuality::Medium, 16), (1, 32, true));
        assert_eq!(at(HaoQuality::High, 16), (2, 48, true));
        assert_eq!(at(HaoQuality::Ultra, 4), (16, 64, true));
        // Without accumulation the presets trace more rays, `Medium` at full resolution.
        assert_eq!(at(HaoQuality::Low, 1), (4, 24, true));
        assert_eq!(at(HaoQuality::Medium, 3), (6, 32, false));
        assert_eq!(at(HaoQuality::High, 1), (8, 48, false));
        let custom = HaoQuality::Custom { rays: 3, steps: 20, half_resolution: false };
        assert_eq!(at(custom, 16), (3, 20, false));
        assert_eq!(at(custom, 1), (3, 20, false));
    }

    #[test]
    fn low_traces_a_checkerboard_when_it_accumulates() {
        let uses = |quality, accumulation_frames| {
            HybridAmbientOcclusion { quality, accumulation_frames, ..default() }.uses_checkerboard()
        };
        let custom = HaoQuality::Custom { rays: 1, steps: 24, half_resolution: true };
        let presets = [HaoQuality::Low, HaoQuality::Medium, HaoQuality::High, HaoQuality::Ultra, custom];
        assert_eq!(presets.map(|q| uses(q, 16)), [true, false, false, false, false]);
        assert!(uses(HaoQuality::Low, 4) && !uses(HaoQuality::Low, 3) && !uses(HaoQuality::Low, 1));
    }

    #[test]
    fn a_pixel_traces_every_frame_every_fourth_or_every_eighth() {
        let frames = |quality, accumulation_frames| {
            HybridAmbientOcclusion { quality, accumulation_frames, ..default() }.frames_per_trace()
        };
        let custom = HaoQuality::Custom { rays: 1, steps: 24, half_resolution: true };
        let presets = [HaoQuality::Low, HaoQuality::Medium, HaoQuality::High, HaoQuality::Ultra, custom];
        assert_eq!(presets.map(|q| frames(q, 16)), [8, 4, 4, 4, 4]);
        // Without accumulation `Low` traces at half resolution without a checkerboard, the others at full.
        assert_eq!(presets.map(|q| frames(q, 1)), [4, 1, 1, 1, 4]);
    }

    #[test]
    fn high_and_ultra_pass_free_space_unless_told_otherwise() {
        let uses = |quality, depth_free_space| {
            HybridAmbientOcclusion { quality, depth_free_space, ..default() }.uses_depth_free_space()
        };
        let custom = HaoQuality::Custom { rays: 3, steps: 20, half_resolution: true };
        let presets = [HaoQuality::Low, HaoQuality::Medium, HaoQuality::High, HaoQuality::Ultra, custom];
        assert_eq!(presets.map(|q| uses(q, None)), [false, false, true, true, false]);
        assert!(presets.iter().all(|&q| uses(q, Some(true)) && !uses(q, Some(false))));
    }
}
