//! Voxel global illumination: the light of Bevy's lights in the voxels, for diffuse indirect light.
//!
//! A room beside `ao/` that reads the voxel grid through [`crate::VoxelGridBindings`], as `ao/` does. Once
//! a frame, in the `RenderGraph` schedule after the voxelization and before the cameras render:
//!
//! 1. **lighting** (`gi_lighting.wgsl`, GPU span `hao/gi_lighting`): each occupied voxel's outgoing
//!    diffuse radiance under Bevy's directional, point and spot lights, each shadowed by a march through
//!    the voxels toward it, from the multi-valued voxels' average albedo and normal, in Bevy's units before
//!    exposure (cd/m^2), into the *lighting volume*: an `R32Uint` texture of `rgb9e5` words laid out as the
//!    voxel texture's mip 0 (4 bytes a voxel). One of [`VoxelGlobalIllumination::lighting_frames`] slabs of
//!    each level a frame, in turn.
//!
//! The CPU twin: [`crate::cpu::lighting`] (`voxel_radiance`, `light_reaches`, `pack_rgb9e5`).

pub(crate) mod extract;
pub(crate) mod lighting;

use crate::voxel::VoxelGridAssets;
use crate::voxel::volume::AttributesWanted;
use bevy::asset::RenderAssetUsages;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::image::ImageSampler;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDescriptor, TextureDimension, TextureFormat, TextureUsages};
use bevy::render::renderer::{RenderDevice, RenderGraph, RenderGraphSystems};
use bevy::render::{ExtractSchedule, GpuResourceAppExt, Render, RenderApp, RenderSystems};
use bevy::shader::load_shader_library;

/// Diffuse global illumination from the voxels, on a camera with [`crate::HybridAmbientOcclusion`]
/// (required, so adding this alone brings it). Off unless a camera has it; the voxel volume's cascades
/// follow the same camera as the AO's.
///
/// **In progress**: this version builds the *lighting volume*, the light of Bevy's lights in the voxels
/// (see [`crate::HaoDebugView::LitVoxels`]); the indirect light it is for (probes written into an irradiance
/// volume Bevy's PBR applies) is not built yet, so the rendered image does not change.
///
/// It turns the voxels' attributes on ([`crate::VoxelVolume::attributes`]: each voxel's average albedo and
/// normal, 64 bytes a voxel), and the lighting volume takes 4 bytes a voxel more: with the default
/// cascades (4 of 192^3) 1.8 GB and 113 MB. Where the device cannot hold the attributes (their sums exceed
/// `Limits::max_storage_buffer_binding_size`, as the default cascades do under WebGPU's 128 MiB) it is off,
/// with a warning, and the AO goes on.
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hao::prelude::*;
/// fn setup(mut commands: Commands) {
///     commands.spawn((Camera3d::default(), VoxelGlobalIllumination::default()));
/// }
/// ```
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Default, Debug, PartialEq, Clone)]
#[require(crate::HybridAmbientOcclusion)]
pub struct VoxelGlobalIllumination {
    /// Frames over which the lighting volume is refreshed: each frame lights one slab in this many of every
    /// level's voxels, so a light that moves or changes shows in the voxels within this many frames (1 to
    /// 16; 1: all of them every frame).
    pub lighting_frames: u32,
}

impl Default for VoxelGlobalIllumination {
    fn default() -> Self {
        Self { lighting_frames: 4 }
    }
}

impl VoxelGlobalIllumination {
    /// The settings with invalid values replaced, and a message for each replacement.
    pub fn sanitized(&self) -> (VoxelGlobalIllumination, Vec<String>) {
        let mut g = self.clone();
        let mut fixes = Vec::new();
        if !(1..=MAX_LIGHTING_FRAMES).contains(&g.lighting_frames) {
            let used = g.lighting_frames.clamp(1, MAX_LIGHTING_FRAMES);
            fixes.push(format!("VoxelGlobalIllumination::lighting_frames is {}; using {used}", g.lighting_frames));
            g.lighting_frames = used;
        }
        (g, fixes)
    }
}

/// The most frames [`VoxelGlobalIllumination::lighting_frames`] spreads the lighting volume over.
pub const MAX_LIGHTING_FRAMES: u32 = 16;

/// Renders [`VoxelGlobalIllumination`] (added by [`crate::HaoPlugin`]).
#[derive(Default)]
pub struct VoxelGlobalIlluminationPlugin;

impl Plugin for VoxelGlobalIlluminationPlugin {
    fn build(&self, app: &mut App) {
        load_shader_library!(app, "gi_common.wgsl");
        bevy::asset::embedded_asset!(app, "gi_lighting.wgsl");
        app.register_type::<VoxelGlobalIllumination>();
    }

    fn finish(&self, app: &mut App) {
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
        let limits = render_app.world().resource::<RenderDevice>().limits();
        // The voxelization's own requirements (storage buffers, workgroups) are checked by its plugin: without
        // a voxel grid there is nothing to light.
        let lacking = if cfg!(target_arch = "wasm32") {
            Some("Bevy 0.19 compiles irradiance volumes out on wasm32".to_string())
        } else if limits.max_storage_textures_per_shader_stage < 1 {
            Some("the device has no storage textures".to_string())
        } else {
            None
        };
        if let Some(why) = lacking {
            warn!("bevy_hao: voxel global illumination is disabled: {why}");
            return;
        }
        app.init_resource::<AttributesWanted>();
        let render_app = app.sub_app_mut(RenderApp);
        render_app
            .init_resource::<extract::ExtractedGi>()
            .init_gpu_resource::<lighting::GiLightingPipeline>()
            .add_systems(ExtractSchedule, extract::extract_gi)
            .add_systems(
                Render,
                lighting::prepare_gi_lighting
                    .in_set(RenderSystems::PrepareBindGroups)
                    .after(crate::voxel::bindings::prepare_voxel_grid_bindings),
            )
            .add_systems(
                RenderGraph,
                lighting::gi_lighting
                    .in_set(RenderGraphSystems::Render)
                    .after(crate::voxel::pass::voxelize)
                    .before(camera_driver),
            );
        app.add_systems(
            PostUpdate,
            (
                want_attributes.before(bevy::transform::TransformSystems::Propagate),
                update_gi_assets.after(crate::voxel::volume::update_voxel_volume),
                report_invalid_settings,
            ),
        );
    }
}

/// The GPU side of voxel GI in the main world (mirrored in the render world): the lighting volume, made
/// for the voxel grid of [`VoxelGridAssets::generation`] `generation`. Present while a camera has
/// [`VoxelGlobalIllumination`] and the grid keeps its attributes.
#[derive(Resource, Clone, Debug)]
pub struct GiAssets {
    /// The lighting volume: `R32Uint`, each texel an `rgb9e5` word ([`crate::cpu::lighting::pack_rgb9e5`])
    /// of the voxel's outgoing diffuse radiance (cd/m^2, before exposure), 0 for an empty voxel; laid out as
    /// the voxel texture's mip 0 ([`VoxelGridAssets::texture_size`], levels stacked along z). Read it back
    /// with Bevy's `Readback::texture`.
    pub radiance: Handle<Image>,
    /// The grid it was made for.
    pub generation: u64,
}

/// The camera whose [`VoxelGlobalIllumination`] is used: the active one of lowest `Camera::order` (ties:
/// lowest entity), with its settings sanitized.
fn gi_camera<'a>(
    cameras: impl Iterator<Item = (Entity, &'a Camera, &'a VoxelGlobalIllumination)>,
) -> Option<(Entity, VoxelGlobalIllumination)> {
    cameras.filter(|(_, c, _)| c.is_active).min_by_key(|(e, c, _)| (c.order, *e)).map(|(e, _, g)| (e, g.sanitized().0))
}

/// Keeps the voxel grid's attributes on while a camera has voxel GI.
fn want_attributes(cameras: Query<(Entity, &Camera, &VoxelGlobalIllumination)>, mut wanted: ResMut<AttributesWanted>) {
    let want = gi_camera(cameras.iter()).is_some();
    if wanted.0 != want {
        wanted.0 = want;
    }
}

/// Makes the lighting volume for the current voxel grid (again when the grid is replaced), or removes it
/// when no camera has voxel GI or the grid keeps no attributes (warned once).
fn update_gi_assets(
    mut commands: Commands,
    cameras: Query<(Entity, &Camera, &VoxelGlobalIllumination)>,
    grid: Option<Res<VoxelGridAssets>>,
    current: Option<Res<GiAssets>>,
    mut images: ResMut<Assets<Image>>,
    mut warned: Local<bool>,
) {
    let on = gi_camera(cameras.iter()).is_some();
    let grid = grid.filter(|g| on && g.attributes.is_some());
    let Some(grid) = grid else {
        if on && !*warned {
            warn!(
                "bevy_hao: voxel global illumination is off: the voxel grid keeps no attributes (see the warning \
                 about VoxelVolume::attributes; lower the resolution or the cascades)"
            );
            *warned = true;
        }
        if current.is_some() {
            commands.remove_resource::<GiAssets>();
        }
        return;
    };
    if current.is_some_and(|c| c.generation == grid.generation) {
        return;
    }
    let size = grid.texture_size;
    let radiance = Image {
        data: None,
        texture_descriptor: TextureDescriptor {
            label: Some("hao_gi_radiance"),
            size: Extent3d { width: size.x, height: size.y, depth_or_array_layers: size.z * grid.levels },
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D3,
            format: TextureFormat::R32Uint,
            usage: TextureUsages::TEXTURE_BINDING | TextureUsages::STORAGE_BINDING | TextureUsages::COPY_SRC,
            view_formats: &[],
        },
        sampler: ImageSampler::nearest(),
        asset_usage: RenderAssetUsages::RENDER_WORLD,
        ..default()
    };
    commands.insert_resource(GiAssets { radiance: images.add(radiance), generation: grid.generation });
}

fn report_invalid_settings(
    cameras: Query<(Entity, &VoxelGlobalIllumination), Changed<VoxelGlobalIllumination>>,
    mut warned: Local<bevy::platform::collections::HashSet<(Entity, String)>>,
) {
    for (entity, gi) in &cameras {
        for f in gi.sanitized().1 {
            if warned.insert((entity, f.clone())) {
                warn!("bevy_hao: camera {entity}: {f}");
            }
        }
    }
}
