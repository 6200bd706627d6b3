//! Extraction: voxel GI's settings and assets, and Bevy's lights as the lighting pass takes them.

use super::{GiAssets, VoxelGlobalIllumination, gi_camera};
use crate::cpu::lighting::{Light, PreparedLight};
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
    mut warned: Local<bool>,
) {
    let extracted = &mut *extracted;
    extracted.gi = gi_camera(cameras.iter()).zip(assets.as_deref().cloned()).map(|((_, g), a)| (g, a));
    extracted.lights.clear();
    if extracted.gi.is_none() {
        return;
    }
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
}
