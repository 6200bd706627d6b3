//! How HAO's result reaches Bevy's PBR shading. Bevy 0.19's PBR reads ambient occlusion from one texture
//! only: the one Bevy's SSAO makes for a view (`ScreenSpaceAmbientOcclusionResources`), bound with the
//! view and read at each fragment's position in the render target. So a HAO camera carries Bevy's
//! `ScreenSpaceAmbientOcclusion`, and HAO's temporal pass (with the near field, its apply pass) writes into
//! that texture. Two kinds of view need more than Bevy's SSAO gives them:
//!
//! * **MSAA.** Bevy's SSAO refuses cameras with MSAA (it reads single-sampled prepasses), so the main-world
//!   camera does not carry it; [`extract_multisampled_views`] puts it on the render-world view instead,
//!   which gives the view the texture and PBR the binding. Bevy's SSAO would then make bind groups with the
//!   multisampled prepasses, a wgpu validation error, so [`hold_ao_textures`] takes the texture off the view
//!   while bind groups are made, and [`return_held_ao_textures`] gives it back and makes PBR's view bind
//!   groups again with it. Bevy's SSAO passes never run on such a view (they have no bind groups); HAO's
//!   passes read sample 0 of the prepasses.
//! * **Viewports that do not start at the target's corner** (split screen). PBR reads the texture at target
//!   coordinates, but Bevy makes it the viewport's size; [`hold_ao_textures`] puts a texture of the
//!   plugin's in its place, large enough to hold the viewport where it lies, and HAO's passes read the
//!   prepasses (the target's size) and write the result there.

use super::prepare::HaoViewResources;
use bevy::ecs::query::QueryData;
use bevy::pbr::{
    ScreenSpaceAmbientOcclusion, ScreenSpaceAmbientOcclusionQualityLevel, ScreenSpaceAmbientOcclusionResources,
    SsaoBindGroups, SsaoPipelineId, prepare_mesh_view_bind_groups,
};
use bevy::prelude::*;
use bevy::render::Extract;
use bevy::render::render_resource::TextureView;
use bevy::render::sync_world::RenderEntity;

/// Marks a render-world view with MSAA whose `ScreenSpaceAmbientOcclusion` the plugin put there (the
/// main-world camera does not have it).
#[derive(Component)]
pub struct MultisampledHaoView;

/// Bevy's SSAO resources of a view with MSAA, held off the view while bind groups are made.
#[derive(Component)]
pub struct HeldAoTexture(ScreenSpaceAmbientOcclusionResources);

/// The texture PBR reads a view's AO from, on the view or held (see the module's documentation).
#[derive(QueryData)]
pub struct PbrAoTexture {
    on_view: Option<&'static ScreenSpaceAmbientOcclusionResources>,
    held: Option<&'static HeldAoTexture>,
}

impl PbrAoTextureItem<'_, '_> {
    /// The texture's view, if the view has one this frame.
    pub fn view(&self) -> Option<&TextureView> {
        let resources = self.on_view.or(self.held.map(|h| &h.0))?;
        Some(&resources.screen_space_ambient_occlusion_texture.default_view)
    }
}

/// Gives the render-world views of active HAO cameras with MSAA Bevy's `ScreenSpaceAmbientOcclusion` (at its
/// cheapest: its passes never run there), and takes it away again when a camera no longer needs it.
pub fn extract_multisampled_views(
    mut commands: Commands,
    cameras: Extract<
        Query<(RenderEntity, &Camera, &Msaa, Has<super::HybridAmbientOcclusion>, Has<ScreenSpaceAmbientOcclusion>)>,
    >,
    marked: Query<(), With<MultisampledHaoView>>,
) {
    for (entity, camera, msaa, hao, main_has_ssao) in &cameras {
        if hao && camera.is_active && *msaa != Msaa::Off {
            commands.entity(entity).insert((
                ScreenSpaceAmbientOcclusion {
                    quality_level: ScreenSpaceAmbientOcclusionQualityLevel::Custom {
                        slice_count: 1,
                        samples_per_slice_side: 1,
                    },
                    ..default()
                },
                MultisampledHaoView,
            ));
        } else if marked.contains(entity) {
            let mut view = commands.entity(entity);
            view.remove::<MultisampledHaoView>();
            // A camera whose MSAA went off has Bevy's SSAO in the main world again, which Bevy extracts.
            if !main_has_ssao {
                view.remove::<(
                    ScreenSpaceAmbientOcclusion,
                    ScreenSpaceAmbientOcclusionResources,
                    SsaoPipelineId,
                    SsaoBindGroups,
                    HeldAoTexture,
                )>();
            }
        }
    }
}

/// After Bevy's SSAO made this frame's textures and before bind groups are made: a view whose viewport does
/// not start at the target's corner gets the plugin's target-sized texture in place of Bevy's; a view with
/// MSAA has its SSAO resources held off it (and any bind groups Bevy's SSAO made for it before dropped).
pub fn hold_ao_textures(
    world: &mut World,
    views: &mut QueryState<(&HaoViewResources, &mut ScreenSpaceAmbientOcclusionResources)>,
    multisampled: &mut QueryState<Entity, (With<MultisampledHaoView>, With<ScreenSpaceAmbientOcclusionResources>)>,
) {
    for (hao, mut ssao) in views.iter_mut(world) {
        if let Some(texture) = &hao.pbr_texture {
            ssao.screen_space_ambient_occlusion_texture = texture.clone();
        }
    }
    let multisampled: Vec<Entity> = multisampled.iter(world).collect();
    for entity in multisampled {
        let mut view = world.entity_mut(entity);
        if let Some(resources) = view.take::<ScreenSpaceAmbientOcclusionResources>() {
            view.insert(HeldAoTexture(resources));
        }
        view.remove::<SsaoBindGroups>();
    }
}

/// After bind groups are made: the held textures go back on their views, and PBR's view bind groups are
/// made again so that they bind them (Bevy's `prepare_mesh_view_bind_groups`, run here once more).
pub fn return_held_ao_textures(
    world: &mut World,
    held: &mut QueryState<Entity, With<HeldAoTexture>>,
    mut mesh_view_bind_groups: Local<Option<Box<dyn System<In = (), Out = ()>>>>,
) {
    let held: Vec<Entity> = held.iter(world).collect();
    if held.is_empty() {
        return;
    }
    for entity in held {
        let mut view = world.entity_mut(entity);
        if let Some(HeldAoTexture(resources)) = view.take::<HeldAoTexture>() {
            view.insert(resources);
        }
    }
    let system = mesh_view_bind_groups.get_or_insert_with(|| {
        let mut system = IntoSystem::into_system(prepare_mesh_view_bind_groups);
        system.initialize(world);
        Box::new(system)
    });
    if let Err(error) = system.run((), world) {
        warn_once!("bevy_hao: PBR's view bind groups could not be made again for cameras with MSAA: {error}");
    }
}
