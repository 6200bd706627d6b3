//! The light that Bevy's lights put on a surface, in Bevy 0.19's units and by its PBR shader's formulas:
//! the first piece of the voxels' lighting volume for diffuse global illumination (docs/design-gi.md; the
//! GPU pass is not built yet, and this is its CPU twin to be).
//!
//! * `DirectionalLight`: `illuminance` in lux, uploaded as `color * illuminance`.
//! * `PointLight` and `SpotLight`: `intensity` in lumens, divided by 4 pi for both (candela), attenuated
//!   by [`distance_attenuation`] within `range`; a spot also by [`spot_attenuation`] (bevy_pbr
//!   `render/light.rs`, `render/pbr_lighting.wgsl`).
//!
//! Shadows are not here: the lighting volume will march the voxels toward each light. Exposure is not here
//! either: Bevy's shader multiplies all non-emissive light by the view's exposure at the end, irradiance
//! volumes included.

use glam::Vec3;
use std::f32::consts::{FRAC_PI_2, PI};

/// A light, as Bevy's PBR shader sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// A `DirectionalLight`.
    Directional {
        /// The way its light travels (the light's forward), unit length.
        direction: Vec3,
        /// Linear colour.
        color: Vec3,
        /// Lux.
        illuminance: f32,
    },
    /// A `PointLight`.
    Point {
        /// World position.
        position: Vec3,
        /// Linear colour.
        color: Vec3,
        /// Lumens.
        intensity: f32,
        /// How far it reaches (world units).
        range: f32,
    },
    /// A `SpotLight`.
    Spot {
        /// World position.
        position: Vec3,
        /// The way it points (the light's forward), unit length.
        direction: Vec3,
        /// Linear colour.
        color: Vec3,
        /// Lumens (divided by 4 pi as a point light's, as Bevy does).
        intensity: f32,
        /// How far it reaches (world units).
        range: f32,
        /// The angle from `direction` within which it is at full strength (radians).
        inner_angle: f32,
        /// The angle from `direction` beyond which it gives no light (radians; Bevy clamps it below pi/2).
        outer_angle: f32,
    },
}

/// The light one [`Light`] brings to a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit direction from the point toward the light.
    pub to_light: Vec3,
    /// Distance to the light (infinite for a directional light): how far a shadow ray goes.
    pub distance: f32,
    /// Illuminance on a surface facing the light, before shadows (lux, per colour channel).
    pub illuminance: Vec3,
}

/// Bevy's smooth cut-off at a light's range (WGSL `getRangeFalloff`): `saturate(1 - (d^2 / r^2)^2)^2`.
pub fn range_falloff(distance_squared: f32, inverse_range_squared: f32) -> f32 {
    let factor = distance_squared * inverse_range_squared;
    let smooth = (1.0 - factor * factor).clamp(0.0, 1.0);
    smooth * smooth
}

/// Bevy's distance attenuation of point and spot lights (WGSL `getDistanceAttenuation`): the inverse square
/// law, cut off smoothly at the range.
pub fn distance_attenuation(distance_squared: f32, inverse_range_squared: f32) -> f32 {
    range_falloff(distance_squared, inverse_range_squared) / distance_squared.max(1.0e-4)
}

/// Bevy's spot cone (its `spot_scale` and `spot_offset`, and the shader's square): 1 within `inner_angle`
/// of the spot's axis, 0 beyond `outer_angle`, `cos_angle` the cosine of the angle from the axis. Bevy
/// clamps `outer_angle` just below pi/2 and `inner_angle` to at most `outer_angle`; so does this.
pub fn spot_attenuation(cos_angle: f32, inner_angle: f32, outer_angle: f32) -> f32 {
    let outer = if outer_angle >= FRAC_PI_2 { FRAC_PI_2 - 1.0e-4 } else { outer_angle };
    let inner = inner_angle.min(outer);
    let cos_outer = outer.cos();
    let scale = 1.0 / (inner.cos() - cos_outer).max(1.0e-4);
    let a = (cos_angle * scale - cos_outer * scale).clamp(0.0, 1.0);
    a * a
}

impl Light {
    /// The light this one brings to the point `p`, or `None` where it brings none (behind a spot's cone,
    /// out of range, a zero or non-finite intensity, a degenerate direction).
    pub fn incident(&self, p: Vec3) -> Option<Incident> {
        let (to_light, distance, illuminance) = match *self {
            Light::Directional { direction, color, illuminance } => {
                (-direction.normalize_or_zero(), f32::INFINITY, color * illuminance)
            }
            Light::Point { position, color, intensity, range } => {
                let (to_light, d2) = toward(p, position);
                (to_light, d2.sqrt(), color * point_illuminance(intensity, range, d2))
            }
            Light::Spot { position, direction, color, intensity, range, inner_angle, outer_angle } => {
                let (to_light, d2) = toward(p, position);
                let cone = spot_attenuation(direction.normalize_or_zero().dot(-to_light), inner_angle, outer_angle);
                (to_light, d2.sqrt(), color * point_illuminance(intensity, range, d2) * cone)
            }
        };
        let lit = to_light != Vec3::ZERO && illuminance.is_finite() && illuminance.max_element() > 0.0;
        lit.then_some(Incident { to_light, distance, illuminance })
    }
}

/// The unit direction from `p` to `position` and the squared distance.
fn toward(p: Vec3, position: Vec3) -> (Vec3, f32) {
    let d = position - p;
    (d.normalize_or_zero(), d.length_squared())
}

/// A point light's illuminance at squared distance `d2`, facing it: its luminous intensity (lumens over
/// 4 pi) times [`distance_attenuation`]. A range that is zero, negative or NaN gives none, as Bevy's
/// `1 / range^2` does.
fn point_illuminance(intensity: f32, range: f32, d2: f32) -> f32 {
    if !(range > 0.0) {
        return 0.0;
    }
    intensity / (4.0 * PI) * distance_attenuation(d2, 1.0 / (range * range))
}

/// The outgoing diffuse radiance (cd/m^2 per colour channel) of a Lambertian surface of linear albedo
/// `albedo` and unit normal `normal` under `incident`, unshadowed: `albedo / pi * E * max(n . l, 0)`.
pub fn diffuse_radiance(albedo: Vec3, normal: Vec3, incident: &Incident) -> Vec3 {
    albedo / PI * incident.illuminance * normal.dot(incident.to_light).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1.0e-5 * b.abs().max(1.0)
    }

    #[test]
    fn a_directional_light_gives_its_illuminance_and_a_white_floor_its_lambertian_radiance() {
        let sun = Light::Directional { direction: Vec3::NEG_Y, color: Vec3::ONE, illuminance: 10_000.0 };
        let i = sun.incident(Vec3::new(3.0, 0.0, -7.0)).unwrap();
        assert_eq!((i.to_light, i.distance, i.illuminance), (Vec3::Y, f32::INFINITY, Vec3::splat(10_000.0)));
        let floor = diffuse_radiance(Vec3::ONE, Vec3::Y, &i);
        assert!(close(floor.x, 10_000.0 / PI), "{floor}");
        // At 60 degrees, half; from below, none.
        let tilted = Vec3::new(3f32.sqrt() / 2.0, 0.5, 0.0);
        assert!(close(diffuse_radiance(Vec3::ONE, tilted, &i).x, 5_000.0 / PI));
        assert_eq!(diffuse_radiance(Vec3::ONE, Vec3::NEG_Y, &i), Vec3::ZERO);
    }

    #[test]
    fn a_point_light_falls_off_with_the_square_of_the_distance_and_ends_at_its_range() {
        // 4 pi lumens: 1 candela, 1 lux at 1 m.
        let bulb = Light::Point { position: Vec3::ZERO, color: Vec3::ONE, intensity: 4.0 * PI, range: 100.0 };
        let at = |d: f32| bulb.incident(Vec3::new(d, 0.0, 0.0)).map_or(0.0, |i| i.illuminance.x);
        assert!(close(at(1.0), 1.0), "{}", at(1.0));
        assert!((at(2.0) / at(1.0) - 0.25).abs() < 1.0e-4);
        assert!(at(99.0) > 0.0 && at(100.0) == 0.0 && at(150.0) == 0.0);
        let i = bulb.incident(Vec3::new(0.0, 0.0, 5.0)).unwrap();
        assert_eq!((i.to_light, i.distance), (Vec3::NEG_Z, 5.0));
        // Bad values bring no light and no NaN.
        for (intensity, range) in [(0.0, 10.0), (f32::NAN, 10.0), (100.0, 0.0), (100.0, -1.0), (100.0, f32::NAN)] {
            let bad = Light::Point { position: Vec3::ZERO, color: Vec3::ONE, intensity, range };
            assert_eq!(bad.incident(Vec3::X), None, "{intensity} {range}");
        }
        // At the light itself: no direction, no light.
        assert_eq!(bulb.incident(Vec3::ZERO), None);
    }

    #[test]
    fn a_spot_light_is_full_within_its_inner_cone_and_dark_past_its_outer_cone() {
        let spot = |inner: f32, outer: f32| Light::Spot {
            position: Vec3::ZERO,
            direction: Vec3::NEG_Y,
            color: Vec3::ONE,
            intensity: 4.0 * PI,
            range: 100.0,
            inner_angle: inner,
            outer_angle: outer,
        };
        let bulb = Light::Point { position: Vec3::ZERO, color: Vec3::ONE, intensity: 4.0 * PI, range: 100.0 };
        let (inner, outer) = (0.3f32, 0.6f32);
        let at = |angle: f32| Vec3::new(angle.sin(), -angle.cos(), 0.0) * 2.0;
        let e = |light: Light, p: Vec3| light.incident(p).map_or(0.0, |i| i.illuminance.x);
        // On the axis and within the inner cone, a point light's light; past the outer cone, none.
        assert!(close(e(spot(inner, outer), at(0.0)), e(bulb, at(0.0))));
        assert!(close(e(spot(inner, outer), at(0.29)), e(bulb, at(0.29))));
        assert_eq!(e(spot(inner, outer), at(0.61)), 0.0);
        assert_eq!(e(spot(inner, outer), -at(0.0)), 0.0);
        // Between them, Bevy's square of the linear ramp in the cosine.
        let mid = 0.45f32;
        let ramp = (mid.cos() - outer.cos()) / (inner.cos() - outer.cos());
        assert!(close(e(spot(inner, outer), at(mid)), e(bulb, at(mid)) * ramp * ramp));
        // An outer angle of pi/2 or more is clamped just below it; an inner one past it, to it.
        assert!(e(spot(2.0, 3.0), at(1.5)) > 0.0 && e(spot(2.0, 3.0), at(1.58)) == 0.0);
        assert!(spot_attenuation(1.0, 2.0, 3.0) == 1.0);
    }
}
