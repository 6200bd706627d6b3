//! [`HaoDebugImages`]: what a view's ambient occlusion was computed from and what it came to, copied into
//! images after the HAO passes (`debug_images.wgsl`).

use crate::gpu::{SCREEN_WORKGROUP, queue_compute};
use bevy::asset::{embedded_asset, load_embedded_asset};
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::pbr::ScreenSpaceAmbientOcclusionResources;
use bevy::prelude::*;
use bevy::render::camera::ExtractedCamera;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{texture_2d, texture_depth_2d, texture_storage_2d};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
use bevy::render::texture::GpuImage;
use bevy::render::{GpuResourceAppExt, Render, RenderApp, RenderSystems};

/// Put on a camera to get what its ambient occlusion was computed from and what it came to, in images that
/// can be shown or read back (`Readback::texture`): the AO PBR reads (HAO's, or Bevy's SSAO alone on a camera
/// without [`crate::HybridAmbientOcclusion`]) as `R32Float`, the prepass depth as `R32Float` (Bevy's reverse-Z
/// NDC depth, 0 = far), and the world normal as `Rgba16Float`. Sized like the camera's target.
#[derive(Component, ExtractComponent, Clone, Debug, PartialEq)]
pub struct HaoDebugImages {
    /// Ambient occlusion, 1 = open.
    pub ao: Handle<Image>,
    /// Depth.
    pub depth: Handle<Image>,
    /// World-space normal (xyz).
    pub normal: Handle<Image>,
}

impl HaoDebugImages {
    /// Creates the three images for a target of `size` pixels.
    pub fn new(images: &mut Assets<Image>, size: UVec2) -> Self {
        use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages};
        let mut image = |format: TextureFormat| {
            let mut image = Image::new_uninit(
                Extent3d { width: size.x, height: size.y, depth_or_array_layers: 1 },
                TextureDimension::D2,
                format,
                bevy::asset::RenderAssetUsages::RENDER_WORLD,
            );
            image.texture_descriptor.usage =
                TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_SRC;
            images.add(image)
        };
        Self {
            ao: image(TextureFormat::R32Float),
            depth: image(TextureFormat::R32Float),
            normal: image(TextureFormat::Rgba16Float),
        }
    }
}

/// Copies the views' AO, depth and normal into their [`HaoDebugImages`] (added by
/// [`super::HaoDebugViewPlugin`]).
pub(crate) fn build(app: &mut App) {
    embedded_asset!(app, "debug_images.wgsl");
    app.add_plugins(ExtractComponentPlugin::<HaoDebugImages>::default());
}

pub(crate) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_gpu_resource::<DebugImagesPipeline>()
        .add_systems(Render, prepare_debug_images.in_set(RenderSystems::PrepareBindGroups))
        .add_systems(
            Core3d,
            copy_debug_images
                .in_set(Core3dSystems::MainPass)
                .after(crate::ao::node::hao)
                .before(bevy::core_pipeline::core_3d::main_opaque_pass_3d),
        );
}

/// The copy's layout and pipeline.
#[derive(Resource)]
struct DebugImagesPipeline {
    layout: BindGroupLayoutDescriptor,
    pipeline: CachedComputePipelineId,
}

impl FromWorld for DebugImagesPipeline {
    fn from_world(world: &mut World) -> Self {
        let unfilterable = TextureSampleType::Float { filterable: false };
        let layout = BindGroupLayoutDescriptor::new(
            "hao_debug_images_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_2d(unfilterable),
                    texture_depth_2d(),
                    texture_2d(unfilterable),
                    texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                    texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                    texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let shader = load_embedded_asset!(world, "debug_images.wgsl");
        let pipeline = queue_compute(
            world.resource::<PipelineCache>(),
            "hao_debug_images",
            vec![layout.clone()],
            shader,
            "debug_copy",
            vec![],
        );
        Self { layout, pipeline }
    }
}

/// A view's bind group of the copy.
#[derive(Component)]
struct DebugImagesBindGroup(BindGroup);

fn prepare_debug_images(
    mut commands: Commands,
    device: Res<RenderDevice>,
    pipeline: Res<DebugImagesPipeline>,
    cache: Res<PipelineCache>,
    images: Res<RenderAssets<GpuImage>>,
    views: Query<(Entity, &HaoDebugImages, &ViewPrepassTextures, &ScreenSpaceAmbientOcclusionResources)>,
    stale: Query<Entity, (With<DebugImagesBindGroup>, Without<ScreenSpaceAmbientOcclusionResources>)>,
) {
    // A view whose AO texture is gone this frame (HAO skipped on a viewport too small) copies nothing.
    for entity in &stale {
        commands.entity(entity).remove::<DebugImagesBindGroup>();
    }
    for (entity, debug, prepass, ssao) in &views {
        let (Some(depth), Some(normal)) = (prepass.depth_view(), prepass.normal_view()) else { continue };
        let (Some(ao), Some(d), Some(n)) = (images.get(&debug.ao), images.get(&debug.depth), images.get(&debug.normal))
        else {
            continue;
        };
        let bind_group = device.create_bind_group(
            "hao_debug_images_bind_group",
            &cache.get_bind_group_layout(&pipeline.layout),
            &BindGroupEntries::sequential((
                &ssao.screen_space_ambient_occlusion_texture.default_view,
                depth,
                normal,
                &ao.texture_view,
                &d.texture_view,
                &n.texture_view,
            )),
        );
        commands.entity(entity).insert(DebugImagesBindGroup(bind_group));
    }
}

/// Copies the view's AO, depth and normal into its [`HaoDebugImages`].
fn copy_debug_images(
    view: ViewQuery<(&DebugImagesBindGroup, &ExtractedCamera)>,
    pipeline: Res<DebugImagesPipeline>,
    cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (bind_group, camera) = view.into_inner();
    let Some(size) = camera.physical_viewport_size else { return };
    let Some(pipeline) = cache.get_compute_pipeline(pipeline.pipeline) else { return };
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_debug_images"), timestamp_writes: None });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &bind_group.0, &[]);
    pass.dispatch_workgroups(size.x.div_ceil(SCREEN_WORKGROUP), size.y.div_ceil(SCREEN_WORKGROUP), 1);
}
