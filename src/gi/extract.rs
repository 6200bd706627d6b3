//! Extraction: voxel GI's settings and assets, and Bevy's lights as the lighting pass takes them.

use super::{CHANGED_HISTORY, GiAssets, GiFarProbeWindow, GiProbeWindow, VoxelGlobalIllumination, gi_camera};
use crate::cpu::lighting::{Light, PreparedLight};
use crate::cpu::probes::ProbeWindow;
use bevy::light::{DirectionalLight, PointLight, SpotLight};
use bevy::prelude::*;
use bevy::render::Extract;

/// The most lights the lighting volume takes; past them, the brightest at the cascades' focus are kept
/// (warned once).
pub const MAX_GI_LIGHTS: usize = 64;

/// This frame's voxel GI: the settings of the camera that has it and the assets, or `None` while off; and
/// the lights.
#[derive(Resource, Default)]
pub struct ExtractedGi {
    /// The settings (sanitized) and the lighting volume, while on.
    pub gi: Option<(VoxelGlobalIllumination, GiAssets)>,
    /// Every visible directional, point and spot light that brings light, prepared
    /// ([`Light::prepare`]), at most [`MAX_GI_LIGHTS`].
    pub lights: Vec<PreparedLight>,
    /// This frame's probes.
    pub window: Option<ProbeWindow>,
    /// This frame's far probes, where on.
    pub far_window: Option<ProbeWindow>,
    /// The updates a probe's history holds this frame where the lights changed lately
    /// ([`CHANGED_HISTORY`]), or `None` (the settings' `accumulation_frames`).
    pub history_cap: Option<u32>,
    /// Frames left with `history_cap` since the lights last changed.
    changed_frames_left: u32,
    /// Last frame's lights.
    last_lights: Vec<PreparedLight>,
}

/// A light's colour as Bevy's renderer uploads it: linear RGB.
fn linear(color: Color) -> Vec3 {
    let c = color.to_linear();
    Vec3::new(c.red, c.green, c.blue)
}

/// Extracts the GI camera's settings, the assets, and the lights (Bevy's own components, as its renderer
/// reads them: a light's forward is the way its light travels).
#[allow(clippy::type_complexity)]
pub fn extract_gi(
    mut extracted: ResMut<ExtractedGi>,
    cameras: Extract<Query<(Entity, &Camera, &VoxelGlobalIllumination)>>,
    assets: Extract<Option<Res<GiAssets>>>,
    directional: Extract<Query<(&DirectionalLight, &GlobalTransform, &InheritedVisibility)>>,
    point: Extract<Query<(&PointLight, &GlobalTransform, &InheritedVisibility)>>,
    spot: Extract<Query<(&SpotLight, &GlobalTransform, &InheritedVisibility)>>,
    focus: Extract<Res<crate::voxel::volume::VoxelVolumeFocus>>,
    window: Extract<Res<GiProbeWindow>>,
    far_window: Extract<Res<GiFarProbeWindow>>,
    mut warned: Local<bool>,
) {
    let extracted = &mut *extracted;
    extracted.gi = gi_camera(cameras.iter()).zip(assets.as_deref().cloned()).map(|((_, g), a)| (g, a));
    extracted.window = window.0;
    extracted.far_window = far_window.0;
    std::mem::swap(&mut extracted.lights, &mut extracted.last_lights);
    extracted.lights.clear();
    let Some((settings, _)) = &extracted.gi else { return };
    // Until every voxel has been lit again and every probe has gathered twice since.
    let changed_frames = settings.lighting_frames + 2 * settings.probe_frames;
    let lights = directional
        .iter()
        .filter(|(_, _, v)| v.get())
        .map(|(l, t, _)| Light::Directional {
            direction: t.forward().as_vec3(),
            color: linear(l.color),
            illuminance: l.illuminance,
        })
        .chain(point.iter().filter(|(_, _, v)| v.get()).map(|(l, t, _)| Light::Point {
            position: t.translation(),
            color: linear(l.color),
            intensity: l.intensity,
            range: l.range,
        }))
        .chain(spot.iter().filter(|(_, _, v)| v.get()).map(|(l, t, _)| Light::Spot {
            position: t.translation(),
            direction: t.forward().as_vec3(),
            color: linear(l.color),
            intensity: l.intensity,
            range: l.range,
            inner_angle: l.inner_angle,
            outer_angle: l.outer_angle,
        }));
    extracted.lights.extend(lights.filter_map(|l| l.prepare()));
    if extracted.lights.len() > MAX_GI_LIGHTS {
        if !*warned {
            warn!(
                "bevy_hao: {} lights; voxel global illumination takes the {MAX_GI_LIGHTS} brightest at the camera",
                extracted.lights.len()
            );
            *warned = true;
        }
        let at = focus.0.unwrap_or(Vec3::ZERO);
        let brightness = |l: &PreparedLight| l.incident(at).map_or(0.0, |i| i.illuminance.max_element());
        extracted.lights.sort_by(|a, b| brightness(b).total_cmp(&brightness(a)));
        extracted.lights.truncate(MAX_GI_LIGHTS);
    }
    if extracted.lights != extracted.last_lights {
        extracted.changed_frames_left = changed_frames;
    }
    extracted.history_cap = (extracted.changed_frames_left > 0).then_some(CHANGED_HISTORY);
    extracted.changed_frames_left = extracted.changed_frames_left.saturating_sub(1);
}
