//! Hybrid ambient occlusion: per pixel, rays through the voxel grid.
//!
//! Per view with a [`HybridAmbientOcclusion`], in `Core3d` after Bevy's SSAO and before the main opaque pass
//! and deferred lighting:
//!
//! 1. **trace** (`hao_trace.wgsl`, GPU span `hao/trace`): from each pixel's world position and normal (the
//!    depth and normal prepasses), cosine-weighted hemisphere rays, rotated per pixel (and per frame when
//!    frames are accumulated or TAA jitters the view), start about a voxel off the surface and march the
//!    voxel texture up to `max_distance`, skipping empty space on its mips; each hit weighs
//!    `(1 - d/max)^falloff`. At half resolution each 2x2 block traces from one of its pixels, a different
//!    one each frame;
//! 2. **temporal** (`hao_temporal.wgsl`, `hao/temporal`): the history reprojected, checked, clamped and
//!    blended with the frame's AO;
//! 3. **denoise** (`hao_denoise.wgsl` then `hao_upsample.wgsl`, `hao/denoise`): a separable depth- and
//!    normal-aware bilateral filter at the traced resolution, then the result at full resolution (a
//!    half-resolution trace upsampled by depth and normal) and the minimum with Bevy's SSAO when the near
//!    field is on;
//! 4. **apply** (`hao_apply.wgsl`, `hao/apply`): the result into the texture Bevy's PBR reads AO from, so
//!    it dims indirect light only.
//!
//! The CPU twins: [`crate::cpu::ao`] (trace), [`crate::cpu::temporal`], [`crate::cpu::denoise`].

pub(crate) mod node;
mod pipelines;
pub(crate) mod prepare;
mod settings;

pub(crate) use settings::HaoAddedSsao;
pub use settings::{HaoQuality, HybridAmbientOcclusion};

use bevy::asset::embedded_asset;
use bevy::core_pipeline::core_3d::main_opaque_pass_3d;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::pbr::{ScreenSpaceAmbientOcclusion, ScreenSpaceAmbientOcclusionQualityLevel, SsaoPipelineId};
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponentPlugin;
use bevy::render::render_resource::PipelineCache;
use bevy::render::renderer::RenderDevice;
use bevy::render::{GpuResourceAppExt, Render, RenderApp, RenderSystems};
use bevy::shader::load_shader_library;

/// Renders [`HybridAmbientOcclusion`] (added by [`crate::HaoPlugin`]).
#[derive(Default)]
pub struct HybridAmbientOcclusionPlugin;

impl Plugin for HybridAmbientOcclusionPlugin {
    fn build(&self, app: &mut App) {
        load_shader_library!(app, "hao_common.wgsl");
        embedded_asset!(app, "hao_trace.wgsl");
        embedded_asset!(app, "hao_temporal.wgsl");
        embedded_asset!(app, "hao_denoise.wgsl");
        embedded_asset!(app, "hao_upsample.wgsl");
        embedded_asset!(app, "hao_apply.wgsl");
        app.register_type::<HybridAmbientOcclusion>()
            .add_plugins(ExtractComponentPlugin::<HybridAmbientOcclusion>::default())
            .add_systems(PostUpdate, (configure_hao_cameras, report_invalid_settings));
    }

    fn finish(&self, app: &mut App) {
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        // Bevy's SSAO plugin, whose texture PBR reads, needs 5 storage textures per stage; so do we.
        if render_app.world().resource::<RenderDevice>().limits().max_storage_textures_per_shader_stage < 5 {
            warn!(
                "bevy_hao: hybrid ambient occlusion is disabled: Limits::max_storage_textures_per_shader_stage is below 5 (Bevy's SSAO is unavailable too)"
            );
            return;
        }
        render_app
            .init_gpu_resource::<pipelines::HaoPipelines>()
            .add_systems(
                Render,
                (
                    prepare::prepare_hao_textures.in_set(RenderSystems::PrepareResources),
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

/// Keeps Bevy's SSAO passes from running on a HAO view whose near field is off: their result would be
/// overwritten by HAO's apply pass, which writes every texel of the texture PBR reads. Bevy's SSAO node
/// runs only on views with an `SsaoPipelineId`, so removing it this frame skips the passes while the texture
/// and PBR's binding of it stay. Only when HAO's passes will run this frame (their bind groups, the voxel
/// grid and the pipelines are ready); otherwise SSAO fills the texture as before.
fn skip_unused_ssao(
    mut commands: Commands,
    views: Query<(Entity, &HybridAmbientOcclusion), (With<SsaoPipelineId>, With<prepare::HaoBindGroups>)>,
    pipelines: Res<pipelines::HaoPipelines>,
    voxel_grid: Option<Res<crate::voxel::VoxelGridBindings>>,
    cache: Res<PipelineCache>,
) {
    let ready = voxel_grid.is_some()
        && [
            pipelines.trace,
            pipelines.temporal,
            pipelines.denoise_horizontal,
            pipelines.denoise_vertical,
            pipelines.upsample,
            pipelines.apply,
        ]
        .iter()
        .all(|id| cache.get_compute_pipeline(*id).is_some());
    if !ready {
        return;
    }
    for (entity, hao) in &views {
        if !hao.near_field {
            commands.entity(entity).remove::<SsaoPipelineId>();
        }
    }
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

/// Gives HAO cameras what they need: Bevy's SSAO (added and removed with HAO unless the user put it there)
/// and `Msaa::Off`.
fn configure_hao_cameras(
    mut commands: Commands,
    cameras: Query<(
        Entity,
        Ref<HybridAmbientOcclusion>,
        Option<&ScreenSpaceAmbientOcclusion>,
        Has<HaoAddedSsao>,
        &Msaa,
    )>,
    mut removed: RemovedComponents<HybridAmbientOcclusion>,
    added_ssao: Query<(), With<HaoAddedSsao>>,
) {
    for (entity, hao, ssao, we_added, msaa) in &cameras {
        if *msaa != Msaa::Off {
            warn!("bevy_hao: {entity} has HybridAmbientOcclusion, which needs Msaa::Off; turning MSAA off");
            commands.entity(entity).insert(Msaa::Off);
        }
        match ssao {
            None => {
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
