//! [`HaoDebugImages`]: what a view's ambient occlusion was computed from and what it came to, copied into
//! images after the HAO passes (`debug_images.wgsl`).

use crate::ao::pbr_texture::PbrAoTexture;
use crate::ao::prepare::HaoViewResources;
use crate::gpu::{SCREEN_WORKGROUP, queue_compute};
use bevy::asset::{embedded_asset, load_embedded_asset};
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::prelude::*;
use bevy::render::camera::ExtractedCamera;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    texture_2d, texture_2d_multisampled, texture_depth_2d, texture_depth_2d_multisampled, texture_storage_2d,
    uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
use bevy::render::texture::GpuImage;
use bevy::render::view::Msaa;
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

/// The copy's layouts and pipelines: for single-sampled prepasses, and multisampled ones (queued when the
/// first camera with MSAA asks for debug images).
#[derive(Resource)]
struct DebugImagesPipeline {
    single: (BindGroupLayoutDescriptor, CachedComputePipelineId),
    multisampled: Option<(BindGroupLayoutDescriptor, CachedComputePipelineId)>,
    shader: Handle<Shader>,
}

impl DebugImagesPipeline {
    fn queue(
        cache: &PipelineCache,
        shader: &Handle<Shader>,
        multisampled: bool,
    ) -> (BindGroupLayoutDescriptor, CachedComputePipelineId) {
        let unfilterable = TextureSampleType::Float { filterable: false };
        let (depth, normal) = if multisampled {
            (texture_depth_2d_multisampled(), texture_2d_multisampled(unfilterable))
        } else {
            (texture_depth_2d(), texture_2d(unfilterable))
        };
        let layout = BindGroupLayoutDescriptor::new(
            if multisampled { "hao_debug_images_multisampled_layout" } else { "hao_debug_images_layout" },
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_2d(unfilterable),
                    depth,
                    normal,
                    uniform_buffer::<GpuDebugCopy>(false),
                    texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                    texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                    texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let pipeline = queue_compute(
            cache,
            if multisampled { "hao_debug_images_multisampled" } else { "hao_debug_images" },
            vec![layout.clone()],
            shader.clone(),
            "debug_copy",
            if multisampled { vec!["MULTISAMPLED".into()] } else { vec![] },
        );
        (layout, pipeline)
    }
}

impl FromWorld for DebugImagesPipeline {
    fn from_world(world: &mut World) -> Self {
        let shader = load_embedded_asset!(world, "debug_images.wgsl");
        let single = Self::queue(world.resource::<PipelineCache>(), &shader, false);
        Self { single, multisampled: None, shader }
    }
}

/// The WGSL `DebugCopy`: where the view's pixels lie in the AO texture and in the prepasses.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable, ShaderType)]
pub(crate) struct GpuDebugCopy {
    /// The view's first pixel in the AO texture (its viewport's corner where HAO wrote it, else 0).
    pub ao_origin: UVec2,
    /// The view's first pixel in the prepasses (its viewport's corner).
    pub prepass_origin: UVec2,
}

/// A view's bind group of the copy, and whether its prepasses are multisampled.
#[derive(Component)]
struct DebugImagesBindGroup(BindGroup, bool);

fn prepare_debug_images(
    mut commands: Commands,
    device: Res<RenderDevice>,
    mut pipeline: ResMut<DebugImagesPipeline>,
    cache: Res<PipelineCache>,
    images: Res<RenderAssets<GpuImage>>,
    views: Query<(
        Entity,
        &HaoDebugImages,
        &ExtractedCamera,
        &Msaa,
        &ViewPrepassTextures,
        PbrAoTexture,
        Option<&HaoViewResources>,
    )>,
    stale: Query<Entity, With<DebugImagesBindGroup>>,
) {
    // A view whose AO texture is gone this frame (HAO skipped on a viewport too small) copies nothing.
    for entity in &stale {
        if views.get(entity).is_err() {
            commands.entity(entity).remove::<DebugImagesBindGroup>();
        }
    }
    for (entity, debug, camera, msaa, prepass, pbr_ao, hao) in &views {
        let Some(ao_texture) = pbr_ao.view() else {
            commands.entity(entity).remove::<DebugImagesBindGroup>();
            continue;
        };
        let (Some(depth), Some(normal)) = (prepass.depth_view(), prepass.normal_view()) else { continue };
        let (Some(ao), Some(d), Some(n)) = (images.get(&debug.ao), images.get(&debug.depth), images.get(&debug.normal))
        else {
            continue;
        };
        let multisampled = msaa.samples() > 1;
        if multisampled && pipeline.multisampled.is_none() {
            pipeline.multisampled = Some(DebugImagesPipeline::queue(&cache, &pipeline.shader, true));
        }
        let layout = if multisampled { &pipeline.multisampled.as_ref().unwrap().0 } else { &pipeline.single.0 };
        let prepass_origin = camera.viewport.as_ref().map_or(UVec2::ZERO, |v| v.physical_position);
        let ao_origin = if hao.is_some_and(|h| h.pbr_texture.is_some()) { prepass_origin } else { UVec2::ZERO };
        let settings = crate::gpu::uniform_buffer(
            &device,
            "hao_debug_images_settings",
            &GpuDebugCopy { ao_origin, prepass_origin },
            BufferUsages::UNIFORM,
        );
        let bind_group = device.create_bind_group(
            "hao_debug_images_bind_group",
            &cache.get_bind_group_layout(layout),
            &BindGroupEntries::sequential((
                ao_texture,
                depth,
                normal,
                settings.as_entire_binding(),
                &ao.texture_view,
                &d.texture_view,
                &n.texture_view,
            )),
        );
        commands.entity(entity).insert(DebugImagesBindGroup(bind_group, multisampled));
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
    let id = if bind_group.1 { pipeline.multisampled.as_ref().map(|m| m.1) } else { Some(pipeline.single.1) };
    let Some(pipeline) = id.and_then(|id| cache.get_compute_pipeline(id)) else { return };
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor { label: Some("hao_debug_images"), timestamp_writes: None });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &bind_group.0, &[]);
    pass.dispatch_workgroups(size.x.div_ceil(SCREEN_WORKGROUP), size.y.div_ceil(SCREEN_WORKGROUP), 1);
}
