//! Voxel global illumination: the light of Bevy's lights in the voxels, for diffuse indirect light.
//!
//! A room beside `ao/` that reads the voxel grid through [`crate::VoxelGridBindings`], as `ao/` does. Once
//! a frame, in the `RenderGraph` schedule after the voxelization and before the cameras render:
//!
//! 1. **lighting** (`gi_lighting.wgsl`, GPU span `hao/gi_lighting`): each occupied voxel's outgoing
//!    diffuse radiance under Bevy's directional, point and spot lights, each shadowed by a march through
//!    the voxels toward it, from the multi-valued voxels' average albedo and normal, in Bevy's units before
//!    exposure (cd/m^2), plus [`VoxelGlobalIllumination::bounce_feedback`] times its albedo times the
//!    indirect light the probes held around it at the end of last frame (further bounces), into the
//!    *lighting volume*: an `R32Uint` texture of `rgb9e5` words laid out as the voxel texture's mip 0 (4
//!    bytes a voxel). One of [`VoxelGlobalIllumination::lighting_frames`] slabs of each level a frame, in
//!    turn;
//! 2. **probes** (`gi_probes.wgsl`, `hao/gi_probes`): a grid of probes following the camera (snapped to
//!    their spacing, stored toroidally), one of [`VoxelGlobalIllumination::probe_frames`] of them a frame,
//!    each moved out of the voxel it may lie in, gathers the lighting volume's light along
//!    [`VoxelGlobalIllumination::rays`] rays through the voxels into the six faces of an ambient cube
//!    (irradiance over pi), blended into its history;
//! 3. **write** (`gi_probes.wgsl`, `hao/gi_write`): every probe of the window into the irradiance volume
//!    behind the `LightProbe` + `IrradianceVolume` the plugin keeps around the camera, which Bevy's PBR
//!    applies to every mesh (forward and deferred), dimmed by the AO as all indirect light.
//!
//! The CPU twins: [`crate::cpu::lighting`] (`voxel_radiance`, `light_reaches`, `bounced_radiance`,
//! `pack_rgb9e5`) and [`crate::cpu::probes`].

pub(crate) mod extract;
pub(crate) mod lighting;
mod node;
pub(crate) mod probes;

use crate::cpu::probes::{ProbeWindow, probe_window};
use crate::voxel::VoxelGridAssets;
use crate::voxel::volume::AttributesWanted;
use bevy::asset::RenderAssetUsages;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::image::ImageSampler;
use bevy::light::{IrradianceVolume, LightProbe};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDescriptor, TextureDimension, TextureFormat, TextureUsages};
use bevy::render::renderer::{RenderDevice, RenderGraph, RenderGraphSystems};
use bevy::render::settings::WgpuFeatures;
use bevy::render::storage::ShaderBuffer;
use bevy::render::{ExtractSchedule, GpuResourceAppExt, Render, RenderApp, RenderSystems};
use bevy::shader::load_shader_library;

/// Diffuse global illumination from the voxels, on a camera with [`crate::HybridAmbientOcclusion`]
/// (required, so adding this alone brings it). Off unless a camera has it; the voxel volume's cascades
/// follow the same camera as the AO's.
///
/// The light of Bevy's directional, point and spot lights is put in the voxels (the *lighting volume*,
/// shadows included: [`crate::HaoDebugView::LitVoxels`] shows it), gathered by a grid of probes around the
/// camera through the voxels, and written into an irradiance volume (a `LightProbe` + `IrradianceVolume`
/// the plugin keeps) that Bevy's own PBR applies to every mesh in it, in forward and deferred rendering, as
/// diffuse indirect light, dimmed by the AO; the voxels take a share of it back
/// ([`Self::bounce_feedback`]), so the light bounces on. Bevy still adds its `GlobalAmbientLight` on top
/// (the probes' rays that escape bring no light), and an environment map's diffuse light is turned off by
/// Bevy wherever an irradiance volume is in view. Emissive materials do not light the voxels.
///
/// It turns the voxels' attributes on ([`crate::VoxelVolume::attributes`]: each voxel's average albedo and
/// normal, 64 bytes a voxel), and the lighting volume takes 4 bytes a voxel more: with the default
/// cascades (4 of 192^3) 1.8 GB and 113 MB; the probes take 128 bytes each and 48 a probe of irradiance
/// volume (9.7 MB for the default 48 x 24 x 48, 2.9 MB more for far probes of 32 x 16 x 32). Far probes
/// ([`Self::far_spacing`], off by default) light what lies beyond the near window, where the device has
/// binding arrays.
/// Where the device cannot hold the attributes (their sums exceed `Limits::max_storage_buffer_binding_size`,
/// as the default cascades do under WebGPU's 128 MiB) it is off, with a warning, and the AO goes on.
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
    /// Multiplies the indirect light (the irradiance volume's `intensity`; 0 to 1000).
    pub intensity: f32,
    /// The distance between probes, world units (0.01 to 100).
    pub probe_spacing: f32,
    /// Probes along each axis (2 to 128 each, at most 262,144 in all), centred on the camera: the
    /// default covers 24 x 12 x 24 m. The indirect light fades out over the last two spacings of the way
    /// from the camera to the window's edge on each axis (from 10.25 m and 4.25 m by default, gone at 11.25
    /// and 5.25 m; not on an axis of fewer than 4 probes); outside the window a surface gets no indirect
    /// light from the probes, but the far probes' where they are on ([`Self::far_spacing`]).
    pub probe_counts: UVec3,
    /// The far probes' spacing, in `probe_spacing`s (0, the default: no far probes; else 2 to 16; 4 puts
    /// them 2 m apart). The far probes are a second, coarser window around the camera
    /// ([`Self::far_probe_counts`]), written as a second irradiance volume that Bevy's PBR blends with the
    /// near one: the surfaces beyond the near window get their light, and the near light fades into theirs
    /// instead of into nothing. Off by default: so far apart they spread the light of small sunlit patches
    /// over whole walls (on Sibenik's view the right amount of light in all, but more error than none:
    /// docs/figures.md, *Far probes*). They need binding arrays (Bevy binds one irradiance volume without
    /// them): where the device has none, they are off, with a warning. They take 176 bytes a probe.
    pub far_spacing: u32,
    /// Far probes along each axis (2 to 128 each, at most 262,144 in all; raised, with a warning, to hold
    /// the near window within them, and past the most in all the fewest that do): the default, 32 x 16 x
    /// 32, covers 64 x 32 x 64 m at a far spacing of 4 probe spacings of 0.5 m.
    pub far_probe_counts: UVec3,
    /// Rays a probe traces each time it is updated (1 to 1024), near and far.
    pub rays: u32,
    /// Frames over which every probe is updated once (1 to 64): each frame one probe in this many.
    pub probe_frames: u32,
    /// Updates a probe's history averages (1 to 256): more is smoother and slower to follow a change.
    /// Where the lights change, for a few frames the probes keep [`CHANGED_HISTORY`] updates; near occluders
    /// that move (`DynamicOccluder`s, static ones added or removed), fewer the faster they move and the more
    /// of the probe's view they cover (a jump: one; a small prop rolling past: most of these).
    pub accumulation_frames: u32,
    /// Frames over which the lighting volume is refreshed: each frame lights one slab in this many of every
    /// level's voxels, so a light that moves or changes shows in the voxels within this many frames (1 to
    /// 16; 1: all of them every frame).
    pub lighting_frames: u32,
    /// How much of the indirect light the voxels send on (0 to 1; Godot's SDFGI calls it the same): each time
    /// a voxel is lit it also takes this share of the light the probes hold around it (at the end of last
    /// frame) times its albedo, so the light bounces on, one bounce more each time the voxels and the
    /// probes have been updated (`lighting_frames` + `probe_frames` frames). 1, the default, is every
    /// bounce the surfaces' albedo gives, as the ray-traced reference with as many bounces; 0 is one bounce
    /// (the lights' light off the voxels, and no more). Only the near probes' light is sent on.
    pub bounce_feedback: f32,
}

impl Default for VoxelGlobalIllumination {
    fn default() -> Self {
        Self {
            intensity: 1.0,
            probe_spacing: 0.5,
            probe_counts: UVec3::new(48, 24, 48),
            far_spacing: 0,
            far_probe_counts: UVec3::new(32, 16, 32),
            rays: 32,
            probe_frames: 4,
            accumulation_frames: 32,
            lighting_frames: 4,
            bounce_feedback: 1.0,
        }
    }
}

/// The updates a probe's history keeps while the lights change and for a few frames after (until every voxel
/// has been lit again and every probe has gathered twice since; see
/// [`VoxelGlobalIllumination::accumulation_frames`]): its last alone, so that it holds the new light at once,
/// and accumulates again from there.
pub const CHANGED_HISTORY: u32 = 1;

/// The most probes [`VoxelGlobalIllumination::probe_counts`] may hold in all.
pub const MAX_PROBES: u32 = 1 << 18;

/// The most probe rays a frame (probes times rays over `probe_frames`): past it, `probe_frames` is raised
/// and then `rays` lowered, with a warning, so that a frame's dispatch stays well within what a device runs
/// before it gives up (the default is 442,368).
pub const MAX_PROBE_RAYS_PER_FRAME: u64 = 1 << 22;

impl VoxelGlobalIllumination {
    /// The settings with invalid values replaced, and a message for each replacement.
    pub fn sanitized(&self) -> (VoxelGlobalIllumination, Vec<String>) {
        let mut g = self.clone();
        let mut fixes = Vec::new();
        let mut check_u32 = |field: &str, value: &mut u32, lo: u32, hi: u32| {
            if !(lo..=hi).contains(value) {
                let used = (*value).clamp(lo, hi);
                fixes.push(format!("VoxelGlobalIllumination::{field} is {value}; using {used}"));
                *value = used;
            }
        };
        check_u32("lighting_frames", &mut g.lighting_frames, 1, MAX_LIGHTING_FRAMES);
        check_u32("rays", &mut g.rays, 1, 1024);
        check_u32("probe_frames", &mut g.probe_frames, 1, 64);
        check_u32("accumulation_frames", &mut g.accumulation_frames, 1, 256);
        let mut check_f32 = |field: &str, value: &mut f32, lo: f32, hi: f32, default: f32| {
            if !(value.is_finite() && (lo..=hi).contains(value)) {
                let used = if value.is_finite() { value.clamp(lo, hi) } else { default };
                fixes.push(format!("VoxelGlobalIllumination::{field} is {value}; using {used}"));
                *value = used;
            }
        };
        check_f32("intensity", &mut g.intensity, 0.0, 1000.0, 1.0);
        check_f32("probe_spacing", &mut g.probe_spacing, 0.01, 100.0, 0.5);
        check_f32("bounce_feedback", &mut g.bounce_feedback, 0.0, 1.0, 1.0);
        let window = |counts: UVec3| {
            let counts = counts.clamp(UVec3::splat(2), UVec3::splat(128));
            if counts.element_product() > MAX_PROBES { UVec3::new(64, 32, 64) } else { counts }
        };
        let counts = window(g.probe_counts);
        if counts != g.probe_counts {
            fixes.push(format!("VoxelGlobalIllumination::probe_counts is {}; using {counts}", g.probe_counts));
            g.probe_counts = counts;
        }
        if g.far_spacing == 1 || g.far_spacing > 16 {
            let used = g.far_spacing.clamp(2, 16);
            fixes.push(format!("VoxelGlobalIllumination::far_spacing is {}; using {used}", g.far_spacing));
            g.far_spacing = used;
        }
        if g.far_spacing > 0 {
            let needed = crate::cpu::far_probes::far_counts_needed(g.probe_counts, g.far_spacing);
            // Past the most probes in all, the fewest that hold the near window (within it for any sanitized
            // near window).
            let counts = g.far_probe_counts.max(needed).clamp(UVec3::splat(2), UVec3::splat(128));
            let counts = if counts.element_product() > MAX_PROBES { needed.max(UVec3::splat(2)) } else { counts };
            if counts != g.far_probe_counts {
                fixes.push(format!(
                    "VoxelGlobalIllumination::far_probe_counts is {}; using {counts} (the far probes must hold the \
                     near window of {} within them at a far_spacing of {}, and at most {MAX_PROBES} in all)",
                    g.far_probe_counts, g.probe_counts, g.far_spacing
                ));
                g.far_probe_counts = counts;
            }
        }
        // Within the budget of probe rays a frame: more frames to update the probes, then fewer rays.
        let far_probes = if g.far_spacing > 0 { g.far_probe_counts.element_product() } else { 0 };
        let probes = u64::from(g.probe_counts.element_product()) + u64::from(far_probes);
        let per_frame = |g: &VoxelGlobalIllumination| probes * u64::from(g.rays) / u64::from(g.probe_frames);
        if per_frame(&g) > MAX_PROBE_RAYS_PER_FRAME {
            let before = per_frame(&g);
            g.probe_frames = (probes * u64::from(g.rays)).div_ceil(MAX_PROBE_RAYS_PER_FRAME).min(64) as u32;
            g.rays = g.rays.min((MAX_PROBE_RAYS_PER_FRAME * u64::from(g.probe_frames) / probes).max(1) as u32);
            fixes.push(format!(
                "VoxelGlobalIllumination: {before} probe rays a frame are over the budget of \
                 {MAX_PROBE_RAYS_PER_FRAME}; using probe_frames {} and rays {}",
                g.probe_frames, g.rays
            ));
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
        bevy::asset::embedded_asset!(app, "gi_probes.wgsl");
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
        // Bevy 0.19's `binding_arrays_are_usable` (bevy_pbr's light_probe/mod.rs), which decides whether its
        // PBR applies more than one irradiance volume: the far probes need it (all but its GLSL-shaders
        // condition, a Bevy feature this crate does not turn on).
        let info = render_app.world().resource::<bevy::render::renderer::RenderAdapterInfo>();
        let features = render_app.world().resource::<RenderDevice>().features();
        let elements = (16 + bevy::pbr::MAX_VIEW_LIGHT_PROBES) as u32;
        let arrays = WgpuFeatures::TEXTURE_BINDING_ARRAY
            | WgpuFeatures::SAMPLED_TEXTURE_AND_STORAGE_BUFFER_ARRAY_NON_UNIFORM_INDEXING;
        let support = if bevy::render::get_adreno_model(info).is_some_and(|model| model <= 610) {
            Err("Bevy does not use binding arrays on Adreno 610 and older".to_string())
        } else if !features.contains(arrays) {
            let lacking: Vec<&str> = arrays.difference(features).iter_names().map(|(name, _)| name).collect();
            Err(format!("the device lacks {}", lacking.join(" and ")))
        } else if limits.max_binding_array_elements_per_shader_stage < elements
            || limits.max_binding_array_sampler_elements_per_shader_stage < elements
        {
            Err(format!(
                "the device's binding arrays take {} textures and {} samplers a stage, under Bevy's {elements}",
                limits.max_binding_array_elements_per_shader_stage,
                limits.max_binding_array_sampler_elements_per_shader_stage
            ))
        } else {
            Ok(())
        };
        app.init_resource::<AttributesWanted>().insert_resource(GiFarProbesSupport(support));
        let render_app = app.sub_app_mut(RenderApp);
        render_app
            .init_resource::<extract::ExtractedGi>()
            .init_gpu_resource::<lighting::GiLightingPipeline>()
            .init_gpu_resource::<probes::GiProbePipelines>()
            .add_systems(ExtractSchedule, extract::extract_gi)
            .add_systems(
                Render,
                (lighting::prepare_gi_lighting, probes::prepare_gi_probes)
                    .in_set(RenderSystems::PrepareBindGroups)
                    .after(crate::voxel::bindings::prepare_voxel_grid_bindings),
            )
            .add_systems(
                RenderGraph,
                node::gi.in_set(RenderGraphSystems::Render).after(crate::voxel::pass::voxelize).before(camera_driver),
            );
        app.init_resource::<GiProbeWindow>().init_resource::<GiFarProbeWindow>().add_systems(
            PostUpdate,
            (
                want_attributes.before(bevy::transform::TransformSystems::Propagate),
                (update_gi_assets, update_gi_volume)
                    .chain()
                    .after(crate::voxel::volume::update_voxel_volume)
                    .before(bevy::camera::visibility::VisibilitySystems::CheckVisibility),
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
    /// Bevy's irradiance volume (`Rgba16Float`, `(x, 2 y, 3 z)` texels for the probe counts, the layout of
    /// `bevy::light::IrradianceVolume`): each probe's six faces, irradiance over pi (cd/m^2).
    pub irradiance: Handle<Image>,
    /// The probes' records, a storage buffer of 128 bytes each, by slot
    /// ([`crate::cpu::probes::ProbeWindow::slot`]): six faces of four `f32` (rgb, unused), the lattice point
    /// (three `i32`), the updates it holds, the seed of the last update (`u32`s), padding.
    pub probe_records: Handle<ShaderBuffer>,
    /// The probe counts the irradiance volume and records were made for.
    pub probe_counts: UVec3,
    /// The probe spacing the records were made for (a record holds a lattice point's history, which another
    /// spacing puts elsewhere).
    pub probe_spacing: f32,
    /// The far probes' volume and records, where they are on
    /// ([`VoxelGlobalIllumination::far_spacing`] above 0 and the device has binding arrays).
    pub far: Option<GiFarProbes>,
}

/// The far probes' GPU side (see [`VoxelGlobalIllumination::far_spacing`]): laid out as the near probes'
/// ([`GiAssets`]).
#[derive(Clone, Debug)]
pub struct GiFarProbes {
    /// Their irradiance volume, as [`GiAssets::irradiance`].
    pub irradiance: Handle<Image>,
    /// Their records, as [`GiAssets::probe_records`].
    pub probe_records: Handle<ShaderBuffer>,
    /// The probe counts they were made for.
    pub probe_counts: UVec3,
    /// Their spacing in near spacings, which they were made for.
    pub factor: u32,
}

/// Whether Bevy's PBR blends two irradiance volumes on this device (it needs binding arrays, as Bevy 0.19's
/// `binding_arrays_are_usable` asks), or why not: without them the far probes are off.
#[derive(Resource, Clone, Debug)]
pub struct GiFarProbesSupport(pub Result<(), String>);

/// This frame's probe window (main world, extracted): the camera's, snapped to the probe spacing.
#[derive(Resource, Clone, Copy, Default, Debug, PartialEq)]
pub struct GiProbeWindow(pub Option<ProbeWindow>);

/// This frame's far probe window (main world, extracted), where the far probes are on: the camera's,
/// snapped to the far spacing ([`crate::cpu::far_probes::far_window`]).
#[derive(Resource, Clone, Copy, Default, Debug, PartialEq)]
pub struct GiFarProbeWindow(pub Option<ProbeWindow>);

/// The entity holding the plugin's `LightProbe` and `IrradianceVolume` of the near probes.
#[derive(Component)]
pub struct GiIrradianceVolume;

/// The entity holding the plugin's `LightProbe` and `IrradianceVolume` of the far probes.
#[derive(Component)]
pub struct GiFarIrradianceVolume;

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
    mut buffers: ResMut<Assets<ShaderBuffer>>,
    support: Res<GiFarProbesSupport>,
    mut warned: Local<bool>,
    mut warned_far: Local<bool>,
) {
    let camera = gi_camera(cameras.iter());
    let on = camera.is_some();
    // (While there is no grid yet, there is nothing to warn about.)
    let without_attributes = grid.as_ref().is_some_and(|g| g.attributes.is_none());
    let grid = grid.filter(|g| on && g.attributes.is_some());
    let Some(grid) = grid else {
        if on && without_attributes && !*warned {
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
    let (counts, spacing) = camera.as_ref().map_or((UVec3::ONE, 1.0), |(_, g)| (g.probe_counts, g.probe_spacing));
    let far = camera.as_ref().filter(|(_, g)| g.far_spacing > 0).map(|(_, g)| (g.far_probe_counts, g.far_spacing));
    if let (Some(_), Err(why)) = (far, &support.0)
        && !*warned_far
    {
        warn!(
            "bevy_hao: the far probes of voxel global illumination are off: {why}, and without binding arrays \
             Bevy 0.19 applies one irradiance volume (the near probes' light fades out at their window's edges \
             instead; set VoxelGlobalIllumination::far_spacing to 0 to silence this)"
        );
        *warned_far = true;
    }
    let far = far.filter(|_| support.0.is_ok());
    let far_of = |c: &GiAssets| c.far.as_ref().map(|f| (f.probe_counts, f.factor));
    if current.as_ref().is_some_and(|c| {
        c.generation == grid.generation && c.probe_counts == counts && c.probe_spacing == spacing && far_of(c) == far
    }) {
        return;
    }
    // Where only the probes changed, the lighting volume stays.
    let radiance = match current.as_ref().filter(|c| c.generation == grid.generation) {
        Some(c) => c.radiance.clone(),
        None => radiance_image(&mut images, grid.texture_size, grid.levels),
    };
    let records = |counts: UVec3, buffers: &mut Assets<ShaderBuffer>| {
        let bytes = counts.element_product() as usize * probes::PROBE_RECORD_BYTES as usize;
        buffers.add(ShaderBuffer::with_size(bytes, RenderAssetUsages::RENDER_WORLD))
    };
    let far = far.map(|(counts, factor)| GiFarProbes {
        irradiance: images.add(irradiance_image(counts)),
        probe_records: records(counts, &mut buffers),
        probe_counts: counts,
        factor,
    });
    commands.insert_resource(GiAssets {
        radiance,
        generation: grid.generation,
        irradiance: images.add(irradiance_image(counts)),
        probe_records: records(counts, &mut buffers),
        probe_counts: counts,
        probe_spacing: spacing,
        far,
    });
}

/// The lighting volume for a grid of `levels` levels of `size` texels (see [`GiAssets::radiance`]).
fn radiance_image(images: &mut Assets<Image>, size: UVec3, levels: u32) -> Handle<Image> {
    let radiance = Image {
        data: None,
        texture_descriptor: TextureDescriptor {
            label: Some("hao_gi_radiance"),
            size: Extent3d { width: size.x, height: size.y, depth_or_array_layers: size.z * levels },
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
    images.add(radiance)
}

/// Bevy's irradiance volume for `counts` probes (see [`GiAssets::irradiance`]), written by the GPU alone.
fn irradiance_image(counts: UVec3) -> Image {
    Image {
        data: None,
        texture_descriptor: TextureDescriptor {
            label: Some("hao_gi_irradiance"),
            size: Extent3d { width: counts.x, height: 2 * counts.y, depth_or_array_layers: 3 * counts.z },
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D3,
            format: TextureFormat::Rgba16Float,
            usage: TextureUsages::TEXTURE_BINDING | TextureUsages::STORAGE_BINDING | TextureUsages::COPY_SRC,
            view_formats: &[],
        },
        sampler: ImageSampler::linear(),
        asset_usage: RenderAssetUsages::RENDER_WORLD,
        ..default()
    }
}

/// The plugin's irradiance volume entities of one kind (near or far): their volume and transforms.
type VolumeQuery<'w, 's, M, N> = Query<
    'w,
    's,
    (Entity, &'static mut IrradianceVolume, &'static mut Transform, &'static mut GlobalTransform),
    (With<M>, Without<N>),
>;

/// Places the probe windows (near and, where on, far) around the GI camera and keeps a `LightProbe` +
/// `IrradianceVolume` entity on each (its transform set whole, so that this frame's visibility and
/// extraction see it), or takes them away.
#[allow(clippy::too_many_arguments)]
fn update_gi_volume(
    mut commands: Commands,
    cameras: Query<(Entity, &Camera, &VoxelGlobalIllumination)>,
    transforms: Query<&GlobalTransform, (Without<GiIrradianceVolume>, Without<GiFarIrradianceVolume>)>,
    assets: Option<Res<GiAssets>>,
    mut window: ResMut<GiProbeWindow>,
    mut far_window: ResMut<GiFarProbeWindow>,
    mut near_volumes: VolumeQuery<GiIrradianceVolume, GiFarIrradianceVolume>,
    mut far_volumes: VolumeQuery<GiFarIrradianceVolume, GiIrradianceVolume>,
) {
    let camera = gi_camera(cameras.iter());
    let placed = camera.as_ref().zip(assets.as_deref()).and_then(|((e, g), a)| {
        let focus = transforms.get(*e).ok()?.translation();
        let near = probe_window(focus, g.probe_spacing, a.probe_counts)?;
        let far = a.far.as_ref().and_then(|f| {
            let window = crate::cpu::far_probes::far_window(focus, g.probe_spacing, f.factor, f.probe_counts)?;
            Some((window, f.irradiance.clone()))
        });
        Some(((near, a.irradiance.clone()), far, g.intensity))
    });
    let (near, far, intensity) = match placed {
        Some((near, far, intensity)) => (Some(near), far, intensity),
        None => (None, None, 1.0),
    };
    let near_window = near.as_ref().map(|n| n.0);
    if window.0 != near_window {
        window.0 = near_window;
    }
    let far_placed = far.as_ref().map(|f| f.0);
    if far_window.0 != far_placed {
        far_window.0 = far_placed;
    }
    keep_volume(
        &mut commands,
        &mut near_volumes,
        near,
        intensity,
        GiIrradianceVolume,
        "hao voxel GI irradiance volume",
    );
    keep_volume(
        &mut commands,
        &mut far_volumes,
        far,
        intensity,
        GiFarIrradianceVolume,
        "hao voxel GI far irradiance volume",
    );
}

/// Keeps one `LightProbe` + `IrradianceVolume` entity (marked `marker`) on `placed`'s window with its image,
/// or despawns them where there is none.
fn keep_volume<M: Component, N: Component>(
    commands: &mut Commands,
    volumes: &mut VolumeQuery<M, N>,
    placed: Option<(ProbeWindow, Handle<Image>)>,
    intensity: f32,
    marker: M,
    name: &'static str,
) {
    let Some((placed, image)) = placed else {
        for (e, ..) in volumes.iter() {
            commands.entity(e).despawn();
        }
        return;
    };
    let (lo, hi) = placed.bounds();
    let transform = Transform::from_translation((lo + hi) * 0.5).with_scale(hi - lo);
    let volume = IrradianceVolume { voxels: image, intensity, affects_lightmapped_meshes: true };
    match volumes.single_mut() {
        Ok((_, mut v, mut t, mut g)) => {
            if v.voxels != volume.voxels || v.intensity != volume.intensity {
                *v = volume;
            }
            if *t != transform {
                *t = transform;
                *g = GlobalTransform::from(transform);
            }
        }
        Err(_) => {
            for (e, ..) in volumes.iter() {
                commands.entity(e).despawn();
            }
            commands.spawn((
                LightProbe::default(),
                volume,
                transform,
                GlobalTransform::from(transform),
                marker,
                Name::new(name),
            ));
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_settings_are_replaced_with_a_message_each() {
        let (g, fixes) = VoxelGlobalIllumination::default().sanitized();
        assert_eq!((g, fixes.len()), (VoxelGlobalIllumination::default(), 0));
        let bad = VoxelGlobalIllumination {
            intensity: f32::NAN,
            probe_spacing: -1.0,
            probe_counts: UVec3::new(0, 1000, 8),
            far_spacing: 1,
            far_probe_counts: UVec3::ZERO,
            rays: 0,
            probe_frames: 0,
            accumulation_frames: 100_000,
            lighting_frames: 0,
            bounce_feedback: 7.0,
        };
        let (g, fixes) = bad.sanitized();
        assert_eq!(fixes.len(), 10, "{fixes:?}");
        assert_eq!(g.bounce_feedback, 1.0, "a feedback over 1 would add light with each bounce");
        let nan = VoxelGlobalIllumination { bounce_feedback: f32::NAN, ..default() }.sanitized().0;
        assert_eq!(nan.bounce_feedback, 1.0);
        assert_eq!((g.intensity, g.probe_spacing, g.probe_counts), (1.0, 0.01, UVec3::new(2, 128, 8)));
        // The far probes at least twice as far apart, and enough of them to hold the near window.
        let needed = crate::cpu::far_probes::far_counts_needed(g.probe_counts, 2);
        assert_eq!((g.far_spacing, g.far_probe_counts), (2, needed.max(UVec3::splat(2))));
        assert_eq!((g.rays, g.probe_frames, g.accumulation_frames, g.lighting_frames), (1, 1, 256, 1));
        let (g, fixes) =
            VoxelGlobalIllumination { far_spacing: 0, far_probe_counts: UVec3::ZERO, ..default() }.sanitized();
        assert!(fixes.is_empty() && g.far_probe_counts == UVec3::ZERO, "no far probes: their counts unused");
        // Too many probes in all: a window that fits.
        let (g, _) = VoxelGlobalIllumination { probe_counts: UVec3::splat(128), ..default() }.sanitized();
        assert!(g.probe_counts.element_product() <= MAX_PROBES);
        assert_eq!(g.sanitized().1.len(), 0);
        // Over the ray budget: more frames, then fewer rays, within it.
        let heavy = VoxelGlobalIllumination {
            probe_counts: UVec3::new(64, 32, 64),
            far_spacing: 0,
            rays: 1024,
            probe_frames: 1,
            ..default()
        };
        let (g, fixes) = heavy.sanitized();
        assert_eq!(fixes.len(), 1, "{fixes:?}");
        let per_frame = u64::from(g.probe_counts.element_product()) * u64::from(g.rays) / u64::from(g.probe_frames);
        assert!(per_frame <= MAX_PROBE_RAYS_PER_FRAME && g.probe_frames == 32 && g.rays == 1024, "{g:?}");
        assert_eq!(g.sanitized().1.len(), 0);
        // The far probes count in the budget.
        let (g, _) = VoxelGlobalIllumination { far_spacing: 4, ..heavy }.sanitized();
        let probes = g.probe_counts.element_product() + g.far_probe_counts.element_product();
        assert_eq!(g.probe_frames, (u64::from(probes) * 1024).div_ceil(MAX_PROBE_RAYS_PER_FRAME) as u32);
        // Far counts past the most probes in all: the fewest that hold the near window, and the same again.
        let big = VoxelGlobalIllumination {
            probe_counts: UVec3::new(128, 16, 128),
            far_spacing: 2,
            far_probe_counts: UVec3::splat(128),
            ..default()
        };
        let (g, _) = big.sanitized();
        let needed = crate::cpu::far_probes::far_counts_needed(g.probe_counts, 2);
        assert_eq!(g.far_probe_counts, needed);
        assert!(g.far_probe_counts.element_product() <= MAX_PROBES && g.sanitized().1.is_empty());
        // The default far counts hold the default near window at a far spacing of 4.
        let g = VoxelGlobalIllumination { far_spacing: 4, ..default() };
        assert!(g.far_probe_counts.cmpge(crate::cpu::far_probes::far_counts_needed(g.probe_counts, 4)).all());
        assert!(g.sanitized().1.is_empty());
    }
}
