//! Debug views of a camera: its ambient occlusion alone, or the voxel grid ray-marched from it.
//!
//! Put a [`HaoDebugView`] on a camera (the inspector does it from its panel; the examples take `--view`).
//! The view is drawn after tonemapping over the camera's final image by `debug_view.wgsl`, which marches the
//! voxel texture with the same empty-space skipping as the HAO trace and reads the occupancy bits, the
//! static grid's bits and the point counts for the colors.

mod images;

#[cfg(test)]
pub(crate) use images::GpuDebugCopy;
pub use images::HaoDebugImages;

use crate::voxel::extract::ExtractedVoxelGrid;
use crate::voxel::{VOXEL_GRID_GROUP, VoxelGridBindings, voxel_grid_layout};
use bevy::asset::{embedded_asset, load_embedded_asset};
use bevy::core_pipeline::FullscreenShader;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::core_pipeline::tonemapping::tonemapping;
use bevy::pbr::ScreenSpaceAmbientOcclusionResources;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_2d, texture_3d, uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::view::{ViewTarget, ViewUniform, ViewUniformOffset, ViewUniforms};
use bevy::render::{GpuResourceAppExt, Render, RenderApp, RenderSystems};
use bytemuck::{Pod, Zeroable};

/// What a camera shows.
#[derive(Component, ExtractComponent, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[reflect(Component, Default, Debug, PartialEq, Hash, Clone)]
pub enum HaoDebugView {
    /// The rendered image (no debug view).
    #[default]
    Final,
    /// The ambient occlusion PBR reads (HAO's, or Bevy's SSAO alone), white = open.
    AmbientOcclusion,
    /// The voxel grid as shaded boxes.
    Voxels,
    /// The voxel grid colored by each voxel's point count (log scale, blue = 1, red = 255 and more): the
    /// paper's Figure 5c. Needs `VoxelVolume::point_counts`.
    PointCounts,
    /// Static voxels blue, voxels set by dynamic geometry alone orange.
    StaticDynamic,
    /// Voxels tinted by the cascade level that holds them (finest violet, then cyan, green, yellow).
    Cascades,
    /// Voxels colored by their average albedo (multi-valued voxels; grey without
    /// `VoxelVolume::attributes`, magenta for a voxel without points, as inside a solid).
    Albedo,
    /// Voxels colored by their average normal (`n * 0.5 + 0.5`, unshaded; toward grey where the points'
    /// normals cancel; black for a voxel without points). Needs `VoxelVolume::attributes`.
    Normals,
    /// Voxels colored by the light of Bevy's lights in them, the lighting volume of
    /// [`crate::VoxelGlobalIllumination`] (their outgoing diffuse radiance times the view's exposure,
    /// `x / (1 + x)`, unshaded; near black where unlit; grey without voxel GI).
    LitVoxels,
}

impl HaoDebugView {
    /// All views, in the inspector's order.
    pub const ALL: [HaoDebugView; 9] = [
        Self::Final,
        Self::AmbientOcclusion,
        Self::Voxels,
        Self::PointCounts,
        Self::StaticDynamic,
        Self::Cascades,
        Self::Albedo,
        Self::Normals,
        Self::LitVoxels,
    ];

    fn mode(self) -> u32 {
        match self {
            Self::Final => 0,
            Self::AmbientOcclusion => 1,
            Self::Voxels => 2,
            Self::PointCounts => 3,
            Self::StaticDynamic => 4,
            Self::Cascades => 5,
            Self::Albedo => 6,
            Self::Normals => 7,
            Self::LitVoxels => 8,
        }
    }
}

/// Draws [`HaoDebugView`]s (added by [`crate::HaoPlugin`]).
#[derive(Default)]
pub struct HaoDebugViewPlugin;

impl Plugin for HaoDebugViewPlugin {
    fn build(&self, app: &mut App) {
        embedded_asset!(app, "debug_view.wgsl");
        app.register_type::<HaoDebugView>().add_plugins(ExtractComponentPlugin::<HaoDebugView>::default());
        images::build(app);
    }

    fn finish(&self, app: &mut App) {
        images::finish(app);
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        render_app
            .init_gpu_resource::<DebugViewPipelines>()
            .add_systems(Render, prepare_debug_views.in_set(RenderSystems::PrepareResources))
            .add_systems(Core3d, debug_view.in_set(Core3dSystems::PostProcess).after(tonemapping));
    }
}

/// WGSL `DebugSettings`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub(crate) struct GpuDebugSettings {
    pub(crate) mode: u32,
    pub(crate) sample_words: u32,
    pub(crate) has_ao: u32,
    pub(crate) _pad: u32,
}

/// The debug view pipelines (one per target format) and placeholders for missing inputs.
#[derive(Resource)]
pub struct DebugViewPipelines {
    layout: BindGroupLayoutDescriptor,
    shader: Handle<Shader>,
    vertex: VertexState,
    empty_layout: BindGroupLayoutDescriptor,
    pipelines: HashMap<TextureFormat, CachedRenderPipelineId>,
    empty_2d: TextureView,
    empty_radiance: TextureView,
    empty_buffer: Buffer,
}

impl FromWorld for DebugViewPipelines {
    fn from_world(world: &mut World) -> Self {
        let device = world.resource::<RenderDevice>();
        let queue = world.resource::<RenderQueue>();
        let texture = |dimension: TextureDimension, format: TextureFormat| {
            device
                .create_texture_with_data(
                    queue,
                    &TextureDescriptor {
                        label: Some("hao_debug_placeholder"),
                        size: Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension,
                        format,
                        usage: TextureUsages::TEXTURE_BINDING,
                        view_formats: &[],
                    },
                    TextureDataOrder::default(),
                    &[0; 4],
                )
                .create_view(&TextureViewDescriptor::default())
        };
        let unfilterable = TextureSampleType::Float { filterable: false };
        let layout = BindGroupLayoutDescriptor::new(
            "hao_debug_view_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::FRAGMENT,
                (
                    uniform_buffer::<ViewUniform>(true),
                    storage_buffer_read_only_sized(false, None),
                    storage_buffer_read_only_sized(false, None),
                    storage_buffer_read_only_sized(false, None),
                    texture_2d(unfilterable),
                    uniform_buffer::<GpuDebugSettings>(false),
                    texture_2d(unfilterable),
                    texture_3d(TextureSampleType::Uint),
                ),
            ),
        );
        let empty_buffer = device.create_buffer(&BufferDescriptor {
            label: Some("hao_debug_placeholder_buffer"),
            size: 16,
            usage: BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Self {
            layout,
            shader: load_embedded_asset!(world, "debug_view.wgsl"),
            vertex: world.resource::<FullscreenShader>().to_vertex_state(),
            empty_layout: BindGroupLayoutDescriptor::new("hao_debug_view_empty_layout", &[]),
            pipelines: HashMap::default(),
            empty_2d: texture(TextureDimension::D2, TextureFormat::R32Float),
            empty_radiance: texture(TextureDimension::D3, TextureFormat::R32Uint),
            empty_buffer,
        }
    }
}

/// A view's debug-view pipeline and settings.
#[derive(Component)]
pub struct DebugViewResources {
    pipeline: CachedRenderPipelineId,
    settings: Buffer,
}

fn prepare_debug_views(
    mut commands: Commands,
    device: Res<RenderDevice>,
    cache: Res<PipelineCache>,
    mut pipelines: ResMut<DebugViewPipelines>,
    grid: Option<Res<ExtractedVoxelGrid>>,
    views: Query<(Entity, &HaoDebugView, &ViewTarget, Has<ScreenSpaceAmbientOcclusionResources>)>,
) {
    for (entity, view, target, has_ao) in &views {
        if *view == HaoDebugView::Final {
            commands.entity(entity).remove::<DebugViewResources>();
            continue;
        }
        let format = target.main_texture_format();
        let p = &mut *pipelines;
        let pipeline = *p.pipelines.entry(format).or_insert_with(|| {
            cache.queue_render_pipeline(RenderPipelineDescriptor {
                label: Some("hao_debug_view".into()),
                layout: vec![p.layout.clone(), p.empty_layout.clone(), voxel_grid_layout()],
                vertex: p.vertex.clone(),
                fragment: Some(FragmentState {
                    shader: p.shader.clone(),
                    targets: vec![Some(ColorTargetState { format, blend: None, write_mask: ColorWrites::ALL })],
                    ..default()
                }),
                ..default()
            })
        });
        let g = grid.as_ref().and_then(|g| g.assets.as_ref());
        let settings = GpuDebugSettings {
            mode: view.mode(),
            sample_words: g.filter(|g| g.point_counts.is_some()).map_or(0, |g| g.sample_words),
            has_ao: has_ao as u32,
            _pad: 0,
        };
        let settings = crate::gpu::uniform_buffer(&device, "hao_debug_view_settings", &settings, BufferUsages::UNIFORM);
        commands.entity(entity).insert(DebugViewResources { pipeline, settings });
    }
}

#[allow(clippy::too_many_arguments)]
fn debug_view(
    view: ViewQuery<(
        &ViewTarget,
        &DebugViewResources,
        &ViewUniformOffset,
        Option<&ScreenSpaceAmbientOcclusionResources>,
    )>,
    pipelines: Res<DebugViewPipelines>,
    cache: Res<PipelineCache>,
    grid: Option<Res<ExtractedVoxelGrid>>,
    voxel_grid: Option<Res<VoxelGridBindings>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    images: Res<RenderAssets<bevy::render::texture::GpuImage>>,
    gi: Option<Res<crate::gi::extract::ExtractedGi>>,
    view_uniforms: Res<ViewUniforms>,
    mut ctx: RenderContext,
) {
    let (target, res, view_offset, ssao) = view.into_inner();
    let (Some(pipeline), Some(view_binding)) =
        (cache.get_render_pipeline(res.pipeline), view_uniforms.uniforms.binding())
    else {
        return;
    };
    let Some(voxel_grid) = voxel_grid else { return };
    let g = grid.as_ref().and_then(|g| g.assets.as_ref());
    let buffer = |h: Option<&Handle<bevy::render::storage::ShaderBuffer>>| {
        h.and_then(|h| buffers.get(h)).map(|b| b.buffer.clone())
    };
    let occupancy = buffer(g.map(|g| &g.occupancy)).unwrap_or_else(|| pipelines.empty_buffer.clone());
    let static_occupancy = buffer(g.map(|g| &g.static_occupancy)).unwrap_or_else(|| pipelines.empty_buffer.clone());
    let counts = buffer(g.and_then(|g| g.point_counts.as_ref())).unwrap_or_else(|| pipelines.empty_buffer.clone());
    let ao = ssao.map(|s| &s.screen_space_ambient_occlusion_texture.default_view).unwrap_or(&pipelines.empty_2d);
    let radiance = gi
        .as_ref()
        .and_then(|g| g.gi.as_ref())
        .and_then(|(_, a)| images.get(&a.radiance))
        .map_or(&pipelines.empty_radiance, |i| &i.texture_view);
    let post = target.post_process_write();
    let bind_group = ctx.render_device().create_bind_group(
        "hao_debug_view_bind_group",
        &cache.get_bind_group_layout(&pipelines.layout),
        &BindGroupEntries::sequential((
            view_binding,
            occupancy.as_entire_binding(),
            static_occupancy.as_entire_binding(),
            counts.as_entire_binding(),
            ao,
            res.settings.as_entire_binding(),
            post.source,
            radiance,
        )),
    );
    let empty = ctx.render_device().create_bind_group(
        "hao_debug_view_empty_bind_group",
        &cache.get_bind_group_layout(&pipelines.empty_layout),
        &[],
    );
    let mut pass = ctx.command_encoder().begin_render_pass(&RenderPassDescriptor {
        label: Some("hao_debug_view"),
        color_attachments: &[Some(RenderPassColorAttachment {
            view: post.destination,
            depth_slice: None,
            resolve_target: None,
            ops: Operations::default(),
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &bind_group, &[view_offset.offset]);
    pass.set_bind_group(1, &empty, &[]);
    pass.set_bind_group(VOXEL_GRID_GROUP, &voxel_grid.bind_group, &[]);
    pass.draw(0..3, 0..1);
}
