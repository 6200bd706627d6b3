//! The camera component and its settings.

use bevy::core_pipeline::prepass::{DepthPrepass, NormalPrepass};
use bevy::pbr::ScreenSpaceAmbientOcclusionQualityLevel;
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponent;

/// Voxel-based hybrid ambient occlusion on a 3D camera: per pixel, rays through the scene's voxel grid
/// (see [`crate::VoxelVolume`]), so occluders off screen, behind other objects or far away still darken what
/// they shadow. The result replaces the ambient occlusion Bevy's PBR shading reads: it dims indirect light
/// (ambient, environment maps, irradiance volumes) only, in forward and deferred rendering.
///
/// Adding it to a camera is enough: it requires the depth and normal prepasses, turns MSAA off (AO needs
/// `Msaa::Off`, as Bevy's SSAO does) and adds Bevy's `ScreenSpaceAmbientOcclusion`, whose texture is where
/// PBR reads AO and which provides the optional near field. Removing it removes what it added.
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
#[extract_component_sync_target((Self, super::prepare::HaoViewResources, super::prepare::HaoBindGroups))]
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
    /// closer than that are the near field's job. 1 measured best against the ray-traced reference.
    pub start_offset: f32,
    /// Combine with Bevy's screen-space AO (the minimum of both) for contact detail finer than a voxel.
    /// Off by default: against a ray-traced reference the minimum measured worse than HAO alone on the
    /// built-in cathedral, Sibenik and Sponza (Bevy's SSAO darkens open surfaces; see `ao_compare`).
    pub near_field: bool,
    /// The quality of Bevy's SSAO when it provides the near field. Without the near field the plugin keeps
    /// SSAO at its cheapest, since its result is not used.
    pub near_field_quality: ScreenSpaceAmbientOcclusionQualityLevel,
    /// Radius in pixels (of the traced resolution) of the bilateral denoiser; 0 turns it off. It narrows
    /// as a pixel's temporal history grows (half of it at 16 frames).
    pub denoise_radius: u32,
    /// Temporal accumulation: each pixel averages its AO over at most this many frames (1: none; at most
    /// 64), with the ray noise turned every frame, so few rays per frame converge to the error of many. The
    /// history follows the camera (reprojected with its previous matrices), restarts where a surface was
    /// hidden or has moved, and is clamped to the current frame's neighbourhood so that a moving occluder
    /// leaves no trail (see `bevy_hao::cpu::temporal`).
    pub accumulation_frames: u32,
}

impl HybridAmbientOcclusion {
    /// `(rays, steps, half_resolution)` traced each frame: the quality's, with fewer rays for the presets
    /// when frames are accumulated (see [`HaoQuality::parameters_accumulated`]).
    pub fn trace_parameters(&self) -> (u32, u32, bool) {
        self.quality.parameters_accumulated(self.accumulation_frames.clamp(1, 64))
    }

    /// These settings with every invalid value replaced by the one the passes use, and one message per
    /// replacement naming the field, the value given and the value used (the plugin logs each once per
    /// camera). NaN, infinite, zero or negative distances and exponents are invalid; so are more than 256
    /// rays, more than 1024 steps, a denoise radius above 8, or accumulation frames outside 1..=64.
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
            near_field: false,
            near_field_quality: ScreenSpaceAmbientOcclusionQualityLevel::Medium,
            denoise_radius: 2,
            accumulation_frames: 16,
        }
    }
}

/// Quality presets of [`HybridAmbientOcclusion`]. Each traces fewer rays a frame when frames are
/// accumulated (`accumulation_frames` of 4 or more, the default 16): the rays of 16 frames make up for them
/// (see [`HybridAmbientOcclusion::trace_parameters`]).
#[derive(Reflect, Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[reflect(Default, Debug, PartialEq, Hash, Clone)]
pub enum HaoQuality {
    /// 24 steps, traced at half resolution and upsampled with depth: 2 rays a frame accumulated, 4 without.
    /// Each 2x2 block traces from a different pixel each frame, so accumulated frames average the block.
    Low,
    /// 32 steps, 2 rays a frame accumulated (6 without): the default. Accumulated, its error against the
    /// ray-traced reference is below that of 6 rays a frame without accumulation on the scenes measured.
    #[default]
    Medium,
    /// 48 steps, 4 rays a frame accumulated (8 without).
    High,
    /// 64 steps, 8 rays a frame accumulated (16 without).
    Ultra,
    /// Your own.
    Custom {
        /// Rays per pixel.
        rays: u32,
        /// Texel visits per ray (empty space is skipped at up to 16 voxels a step).
        steps: u32,
        /// Trace at half resolution (one pixel of each 2x2 block, a different one each frame when
        /// accumulating), upsampled by depth and normal.
        half_resolution: bool,
    },
}

impl HaoQuality {
    /// `(rays, steps, half_resolution)` of a frame without temporal accumulation.
    pub fn parameters(&self) -> (u32, u32, bool) {
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

    /// `(rays, steps, half_resolution)` of a frame whose result is accumulated over `accumulation_frames`
    /// frames: the presets trace fewer rays from 4 frames on; `Custom` traces what it says.
    pub fn parameters_accumulated(&self, accumulation_frames: u32) -> (u32, u32, bool) {
        let (rays, steps, half) = self.parameters();
        if accumulation_frames < 4 {
            return (rays, steps, half);
        }
        let rays = match *self {
            Self::Low | Self::Medium => 2,
            Self::High => 4,
            Self::Ultra => 8,
            Self::Custom { .. } => rays,
        };
        (rays, steps, half)
    }
}

/// Marks a camera whose `ScreenSpaceAmbientOcclusion` was added by [`HybridAmbientOcclusion`] (and goes
/// when it goes).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct HaoAddedSsao;
