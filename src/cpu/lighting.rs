//! The light that Bevy's lights put on a surface, in Bevy 0.19's units and by its PBR shader's formulas:
//! the voxels' lighting volume for diffuse global illumination (docs/design-gi.md), the CPU twin of
//! `src/gi/gi_lighting.wgsl`.
//!
//! * `DirectionalLight`: `illuminance` in lux, uploaded as `color * illuminance`.
//! * `PointLight` and `SpotLight`: `intensity` in lumens, divided by 4 pi for both (candela), attenuated
//!   by [`distance_attenuation`] within `range`; a spot also by [`spot_attenuation`] (bevy_pbr
//!   `render/light.rs`, `render/pbr_lighting.wgsl`).
//!
//! The lighting volume: each occupied voxel's outgoing diffuse radiance under the lights
//! ([`voxel_radiance`]), each shadowed by a march through the voxel levels toward it ([`light_reaches`]), from
//! the multi-valued voxels' average albedo and normal. Exposure is not here: Bevy's shader multiplies all
//! non-emissive light by the view's exposure at the end, irradiance volumes included, so the volume keeps
//! physical units. With a bounce feedback each voxel also takes back the indirect light the probes hold
//! around it ([`bounced_radiance`]), for further bounces.

use super::attributes::VoxelAttributes;
use super::march::{TraceLevel, march_cascades};
use super::probes::ProbeWindow;
use glam::{IVec3, Vec3};
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
    let (scale, offset) = spot_scale_offset(inner_angle, outer_angle);
    let a = (cos_angle * scale + offset).clamp(0.0, 1.0);
    a * a
}

impl Light {
    /// The light this one brings to the point `p`, or `None` where it brings none (behind a spot's cone,
    /// out of range, a zero or non-finite intensity, a degenerate direction): [`Light::prepare`], then
    /// [`PreparedLight::incident`], as the GPU takes it.
    pub fn incident(&self, p: Vec3) -> Option<Incident> {
        self.prepare()?.incident(p)
    }

    /// The light in the form the GPU's lighting pass takes it (WGSL `GiLight`), its constants folded as
    /// Bevy's renderer folds them when it uploads its lights, or `None` for a light that brings no light
    /// anywhere (a zero, negative or non-finite intensity, colour or range, a zero direction) or whose
    /// light would overflow `f32` near it, which is then never uploaded: the GPU sees no NaN.
    pub fn prepare(&self) -> Option<PreparedLight> {
        let bright = |v: Vec3| v.is_finite() && v.min_element() >= 0.0 && v.max_element() > 0.0;
        let (prepared, range) = match *self {
            Light::Directional { direction, color, illuminance } => (
                PreparedLight {
                    kind: LightKind::Directional,
                    position: Vec3::ZERO,
                    direction: direction.normalize_or_zero(),
                    intensity: color * illuminance,
                    inverse_range_squared: 0.0,
                    spot_scale: 0.0,
                    spot_offset: 0.0,
                },
                1.0,
            ),
            Light::Point { position, color, intensity, range } => (
                PreparedLight {
                    kind: LightKind::Point,
                    position,
                    direction: Vec3::ZERO,
                    intensity: color * (intensity / (4.0 * PI)),
                    inverse_range_squared: 1.0 / (range * range),
                    spot_scale: 0.0,
                    spot_offset: 0.0,
                },
                range,
            ),
            Light::Spot { position, direction, color, intensity, range, inner_angle, outer_angle } => {
                let (spot_scale, spot_offset) = spot_scale_offset(inner_angle, outer_angle);
                (
                    PreparedLight {
                        kind: LightKind::Spot,
                        position,
                        direction: direction.normalize_or_zero(),
                        intensity: color * (intensity / (4.0 * PI)),
                        inverse_range_squared: 1.0 / (range * range),
                        spot_scale,
                        spot_offset,
                    },
                    range,
                )
            }
        };
        let range_ok = range > 0.0 && range.is_finite();
        let direction_ok = prepared.kind == LightKind::Point || prepared.direction != Vec3::ZERO;
        let spot_ok = prepared.spot_scale.is_finite() && prepared.spot_offset.is_finite();
        // (Its light at 1 cm stays finite: no infinite illuminance, and no NaN from one times a spot's 0.)
        let bounded = (prepared.intensity * 1.0e4).is_finite();
        let ok = bright(prepared.intensity)
            && bounded
            && range_ok
            && direction_ok
            && prepared.position.is_finite()
            && spot_ok;
        ok.then_some(prepared)
    }
}

/// Bevy's spot cone as its renderer uploads it (`spot_light_scale`, `spot_light_offset`): the cosine of
/// the angle from the axis times the scale plus the offset, saturated and squared, is the cone's factor
/// ([`spot_attenuation`]). The outer angle is clamped just below pi/2 and the inner one to it.
pub fn spot_scale_offset(inner_angle: f32, outer_angle: f32) -> (f32, f32) {
    let outer = if outer_angle >= FRAC_PI_2 { FRAC_PI_2 - 1.0e-4 } else { outer_angle };
    let inner = inner_angle.min(outer);
    let cos_outer = outer.cos();
    let scale = 1.0 / (inner.cos() - cos_outer).max(1.0e-4);
    (scale, -cos_outer * scale)
}

/// What kind of light a [`PreparedLight`] is (WGSL: `GI_LIGHT_DIRECTIONAL`, `GI_LIGHT_POINT`,
/// `GI_LIGHT_SPOT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum LightKind {
    /// A `DirectionalLight`.
    Directional = 0,
    /// A `PointLight`.
    Point = 1,
    /// A `SpotLight`.
    Spot = 2,
}

/// A light in the form the lighting pass takes it (WGSL `GiLight`; made by [`Light::prepare`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedLight {
    /// Its kind.
    pub kind: LightKind,
    /// World position (point and spot lights).
    pub position: Vec3,
    /// The way its light travels, unit length (directional lights), or the way a spot points.
    pub direction: Vec3,
    /// Per colour channel: a directional light's illuminance (lux), a point or spot light's luminous
    /// intensity (candela: lumens over 4 pi).
    pub intensity: Vec3,
    /// `1 / range^2` (point and spot lights).
    pub inverse_range_squared: f32,
    /// The spot cone's scale ([`spot_scale_offset`]).
    pub spot_scale: f32,
    /// The spot cone's offset ([`spot_scale_offset`]).
    pub spot_offset: f32,
}

impl PreparedLight {
    /// The light this one brings to the point `p`, or `None` where it brings none (WGSL `light_incident`).
    pub fn incident(&self, p: Vec3) -> Option<Incident> {
        let (to_light, distance, illuminance) = match self.kind {
            LightKind::Directional => (-self.direction, f32::INFINITY, self.intensity),
            LightKind::Point | LightKind::Spot => {
                let d = self.position - p;
                let d2 = d.length_squared();
                let to_light = d.normalize_or_zero();
                let mut e = self.intensity * distance_attenuation(d2, self.inverse_range_squared);
                if self.kind == LightKind::Spot {
                    let a = (self.direction.dot(-to_light) * self.spot_scale + self.spot_offset).clamp(0.0, 1.0);
                    e *= a * a;
                }
                (to_light, d2.sqrt(), e)
            }
        };
        let lit = to_light != Vec3::ZERO && illuminance.max_element() > 0.0;
        lit.then_some(Incident { to_light, distance, illuminance })
    }
}

/// The outgoing diffuse radiance (cd/m^2 per colour channel) of a Lambertian surface of linear albedo
/// `albedo` and unit normal `normal` under `incident`, unshadowed: `albedo / pi * E * max(n . l, 0)`.
pub fn diffuse_radiance(albedo: Vec3, normal: Vec3, incident: &Incident) -> Vec3 {
    albedo / PI * incident.illuminance * normal.dot(incident.to_light).max(0.0)
}

/// How far off its voxel's centre a shadow ray starts, along the voxel's average normal, and how far along
/// the ray its march starts, in cells of the voxel's level (WGSL `SHADOW_START_CELLS`): as the AO
/// trace's rays start a cell off the surface and a cell along their way, so that the surface's own voxels
/// (the voxel itself, its neighbours along a slanted floor) do not shadow it.
pub const SHADOW_START_CELLS: f32 = 1.0;
/// The most texel visits a shadow ray's march makes (WGSL `SHADOW_STEPS`): the AO trace's `High`
/// budget. A march out of visits counts as lit: a light is more often seen than not where the march has
/// stepped that far through empty space.
pub const SHADOW_STEPS: u32 = 64;
/// Below this length a voxel's average normal has no direction to start its shadow rays along (its points'
/// normals cancel: the two faces of a thin wall), and they start at its centre.
pub const SHADOW_NORMAL_MIN: f32 = 0.25;

/// The centre of cell `cell` (of the level's window) in world space.
pub fn cell_center(level: &TraceLevel, cell: IVec3) -> Vec3 {
    level.origin + ((cell + level.window_min).as_vec3() + Vec3::splat(0.5)) * level.cell_size
}

/// Whether the light `incident` brings reaches the voxel at `center` (level `level` of `levels`, average
/// normal `normal`) through the voxels (WGSL `light_reaches`): a march toward the light from
/// [`SHADOW_START_CELLS`] off the centre along the normal and as many along the ray, to the light's distance,
/// that no run of occupied cells stops within [`SHADOW_STEPS`] visits.
pub fn light_reaches(levels: &[TraceLevel], level: usize, center: Vec3, normal: Vec3, incident: &Incident) -> bool {
    let cell = levels[level].cell_size;
    let lift = if normal.length() >= SHADOW_NORMAL_MIN { normal.normalize() } else { Vec3::ZERO };
    let origin = center + lift * (SHADOW_START_CELLS * cell);
    // The light's distance from the march's origin along the ray (a directional light's, as the debug view's
    // rays, finite); a light nearer than the march's start lights the voxel.
    let distance = incident.distance.min(1.0e30) - lift.dot(incident.to_light) * SHADOW_START_CELLS * cell;
    if distance <= SHADOW_START_CELLS * cell {
        return true;
    }
    march_cascades(levels, origin, incident.to_light, level, SHADOW_START_CELLS, distance, SHADOW_STEPS).is_none()
}

/// The outgoing diffuse radiance (cd/m^2 per colour channel, before exposure) of cell `cell` of level `level`
/// (of its window) with average albedo and normal `attributes`, under `lights`, each shadowed by
/// [`light_reaches`] (WGSL `voxel_radiance`): `albedo / pi * sum(E * max(n . l, 0))` with the
/// average normal as it is. Where its points' normals disagree the average is shorter and so is the light
/// (a voxel holding both faces of a thin wall, one of them lit, gets about none: the known cost of one normal
/// a voxel).
pub fn voxel_radiance(
    levels: &[TraceLevel],
    level: usize,
    cell: IVec3,
    attributes: &VoxelAttributes,
    lights: &[Light],
) -> Vec3 {
    let center = cell_center(&levels[level], cell);
    let normal = attributes.normal;
    lights
        .iter()
        .filter_map(|light| light.incident(center))
        .filter(|incident| normal.dot(incident.to_light) > 0.0)
        .filter(|incident| light_reaches(levels, level, center, normal, incident))
        .map(|incident| diffuse_radiance(attributes.albedo, normal, &incident))
        .sum()
}

/// How far off its voxel's centre a voxel reads the probes' indirect light for further bounces, along its
/// average normal, in cells of its level (WGSL `BOUNCE_LIFT_CELLS`): as its shadow rays start, out of its own
/// voxel, in the space its surface looks out into.
pub const BOUNCE_LIFT_CELLS: f32 = 1.0;
/// The most texel visits of the march that tells whether a probe sees the point a voxel reads it from (WGSL
/// `BOUNCE_VISIBILITY_STEPS`): the probes are at most a spacing and a half away.
pub const BOUNCE_VISIBILITY_STEPS: u32 = 16;

/// Whether the probe that gathered from `at` ([`crate::cpu::probes::relocate_probe`]'s point) sees the point
/// `p` that a voxel of level `level` with unit normal `n` reads it from, [`BOUNCE_LIFT_CELLS`] off its centre
/// (WGSL `probe_visible`): in front of the plane through the voxel's centre along `n`, outside the voxels,
/// and a march from `p` toward it, from half a cell of that level along, that no run of occupied cells stops
/// before it (a probe within half a cell: yes). Bevy's PBR weighs the probes around a point by distance alone, so a surface
/// beside a wall takes the light of the probes beyond it (behind a thin wall, the lit room's) and of those
/// behind itself: what the voxels send on is kept to what they see.
pub fn probe_visible(levels: &[TraceLevel], level: usize, p: Vec3, n: Vec3, at: Vec3) -> bool {
    let cell = levels[level].cell_size;
    if (at - p).dot(n) < -BOUNCE_LIFT_CELLS * cell {
        return false;
    }
    // A probe that gathered from inside a voxel (one that could not move out: a thin wall's, whose normals
    // cancel) sees both of its sides.
    if super::probes::occupied_at(&levels[super::march::finest_level_containing(levels, at)], at) {
        return false;
    }
    let d = p.distance(at);
    if d <= 0.5 * cell {
        return true;
    }
    let start = super::march::finest_level_containing(levels, p);
    let start_cells = 0.5 * cell / levels[start].cell_size;
    march_cascades(levels, p, (at - p) / d, start, start_cells, d, BOUNCE_VISIBILITY_STEPS).is_none()
}

/// The faces the probes of `window` that see `p` (read for a voxel of level `level` and unit normal `n`)
/// hold there (WGSL `window_faces`): Bevy's sampling of the
/// volume ([`crate::cpu::probes::sample_faces`]: trilinear between the eight probes around `p`, the point
/// clamped half a probe inside the window, each probe's faces faded toward the window's edges), over the
/// probes [`probe_visible`] from `p` alone, their weights renormalised over them (all zero where none is).
/// `probe(q)` is lattice point `q`'s record: its faces and where it gathered from, or `None` where its slot
/// holds another lattice point or it has not gathered yet (a probe of no light, as Bevy reads it). Zero
/// outside the window's bounds.
pub fn window_faces(
    levels: &[TraceLevel],
    level: usize,
    window: &ProbeWindow,
    probe: impl Fn(IVec3) -> Option<([Vec3; 6], Vec3)>,
    p: Vec3,
    n: Vec3,
) -> [Vec3; 6] {
    let mut e = [Vec3::ZERO; 6];
    let Some(corners) = super::probes::trilinear_probes(window, p) else { return e };
    let mut total = 0.0;
    for (c, w) in corners {
        let q = window.min + c.as_ivec3();
        if let Some((faces, at)) = probe(q) {
            if !probe_visible(levels, level, p, n, at) {
                continue;
            }
            let k = w * window.edge_fade(q);
            for (sum, face) in e.iter_mut().zip(faces) {
                *sum += k * face;
            }
        }
        total += w;
    }
    if total > 0.0 {
        for sum in &mut e {
            *sum *= 1.0 / total;
        }
    }
    e
}

/// The light a voxel sends on of the indirect light around it (WGSL `bounced_radiance`): `feedback` times
/// its albedo times the irradiance over pi that the probes of `window` that see the point
/// [`BOUNCE_LIFT_CELLS`] off cell `cell`'s centre along its average normal hold there ([`window_faces`];
/// `probe` as there), read along that normal ([`crate::cpu::probes::ambient_cube`]), times the normal's
/// length (as [`voxel_radiance`], less where the points' normals disagree). Nothing for a normal shorter
/// than [`SHADOW_NORMAL_MIN`] or a `feedback` of 0. Added to [`voxel_radiance`] each time a voxel is lit, it
/// brings one bounce more each time the voxels and then the probes have been updated: a `feedback` of 1 is
/// every bounce a surface of that albedo gives.
#[allow(clippy::too_many_arguments)]
pub fn bounced_radiance(
    levels: &[TraceLevel],
    level: usize,
    cell: IVec3,
    attributes: &VoxelAttributes,
    feedback: f32,
    window: &ProbeWindow,
    probe: impl Fn(IVec3) -> Option<([Vec3; 6], Vec3)>,
) -> Vec3 {
    let length = attributes.normal.length();
    if !(feedback > 0.0) || length < SHADOW_NORMAL_MIN {
        return Vec3::ZERO;
    }
    let n = attributes.normal / length;
    let l = &levels[level];
    let p = cell_center(l, cell) + n * (BOUNCE_LIFT_CELLS * l.cell_size);
    let faces = window_faces(levels, level, window, probe, p, n);
    attributes.albedo * (super::probes::ambient_cube(&faces, n) * (length.min(1.0) * feedback))
}

/// The largest value [`pack_rgb9e5`] holds: `(511 / 512) * 2^16`. Brighter radiance is clamped to it.
pub const RGB9E5_MAX: f32 = 65_408.0;

/// `2^e` for an integer `e` in the normal range of `f32`, exact.
fn exp2i(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// A colour of non-negative channels as a shared-exponent `rgb9e5` word (WGSL `pack_rgb9e5`; the encoding of
/// `TextureFormat::Rgb9e5Ufloat`, which is no storage format, so the lighting volume holds it in an
/// `R32Uint` texture): three 9-bit mantissas, red in the low bits, and a 5-bit exponent on top, each
/// channel rounded to nearest. A 4-byte radiance a voxel with a relative precision of 1/512 of its largest
/// channel; NaN and negative channels give 0, channels past [`RGB9E5_MAX`] are clamped to it.
pub fn pack_rgb9e5(c: Vec3) -> u32 {
    let c = Vec3::from_array(c.to_array().map(|x| if x > 0.0 { x.min(RGB9E5_MAX) } else { 0.0 }));
    let m = c.max_element();
    // floor(log2(m)) from the float's exponent bits (exact; 0 and denormals read as -127).
    let floor_log2 = ((m.to_bits() >> 23) & 0xff) as i32 - 127;
    let mut exponent = floor_log2.max(-16) + 16;
    let mut scale = exp2i(24 - exponent);
    if (m * scale + 0.5).floor() >= 512.0 {
        exponent += 1;
        scale *= 0.5;
    }
    let q = (c * scale + Vec3::splat(0.5)).floor().as_uvec3().min(glam::UVec3::splat(511));
    q.x | (q.y << 9) | (q.z << 18) | ((exponent as u32) << 27)
}

/// The colour of an `rgb9e5` word (WGSL `unpack_rgb9e5`).
pub fn unpack_rgb9e5(p: u32) -> Vec3 {
    let q = glam::UVec3::new(p & 511, (p >> 9) & 511, (p >> 18) & 511).as_vec3();
    q * exp2i((p >> 27) as i32 - 24)
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

    /// A floor of one layer of cells (y = 2 of a 32x16x32 grid of 0.25 m cells from the origin) under a roof
    /// (y = 10) over x < 16, and the levels that trace it.
    fn floor_under_a_roof() -> (crate::cpu::march::VoxelMips, Vec3) {
        use crate::cpu::grid::{VoxelGrid, VoxelOccupancy};
        use glam::UVec3;
        let grid = VoxelGrid::new(Vec3::ZERO, 0.25, UVec3::new(32, 16, 32)).unwrap();
        let occupancy = VoxelOccupancy::new(grid, false);
        for x in 0..32 {
            for z in 0..32 {
                occupancy.set(UVec3::new(x, 2, z));
                if x < 16 {
                    occupancy.set(UVec3::new(x, 10, z));
                }
            }
        }
        (crate::cpu::march::VoxelMips::new(&occupancy, 4), grid.origin)
    }

    #[test]
    fn a_voxel_in_the_open_takes_its_lambertian_radiance_and_one_under_a_roof_none() {
        let (mips, origin) = floor_under_a_roof();
        let levels = [TraceLevel { origin, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        let floor = VoxelAttributes { albedo: Vec3::new(0.8, 0.5, 0.2), normal: Vec3::Y };
        let sun = Light::Directional { direction: Vec3::NEG_Y, color: Vec3::ONE, illuminance: 10_000.0 };
        let lit = voxel_radiance(&levels, 0, IVec3::new(24, 2, 16), &floor, &[sun]);
        let expected = floor.albedo / PI * 10_000.0;
        assert!(lit.distance(expected) < 1.0e-3 * expected.length(), "{lit} {expected}");
        assert_eq!(voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &floor, &[sun]), Vec3::ZERO);
        // A sun at 45 degrees from -x (the roof's side) casts the roof's shadow past its edge (x = 4 m): the
        // floor a cell and a half past it (cell 17's centre, x = 4.375), which the sun overhead lights, is in
        // shadow; 2 m past it, lit.
        let low = Light::Directional {
            direction: Vec3::new(1.0, -1.0, 0.0).normalize(),
            color: Vec3::ONE,
            illuminance: 10_000.0,
        };
        let under = |x: i32| voxel_radiance(&levels, 0, IVec3::new(x, 2, 16), &floor, &[low]).x;
        assert!(voxel_radiance(&levels, 0, IVec3::new(17, 2, 16), &floor, &[sun]).x > 0.0);
        assert_eq!((under(12), under(17)), (0.0, 0.0));
        assert!(close(under(24), 0.8 / PI * 10_000.0 / 2f32.sqrt()), "{}", under(24));
        // The light of several adds up; from below the floor, none.
        let twice = voxel_radiance(&levels, 0, IVec3::new(24, 2, 16), &floor, &[sun, sun]);
        assert!(twice.distance(2.0 * expected) < 1.0e-3 * expected.length());
        let below = Light::Directional { direction: Vec3::Y, color: Vec3::ONE, illuminance: 10_000.0 };
        assert_eq!(voxel_radiance(&levels, 0, IVec3::new(24, 2, 16), &floor, &[below]), Vec3::ZERO);
    }

    #[test]
    fn a_voxel_sends_on_its_share_of_the_light_of_the_probes_that_see_it() {
        let (mips, origin) = floor_under_a_roof();
        let levels = [TraceLevel { origin, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        let floor = VoxelAttributes { albedo: Vec3::new(0.8, 0.5, 0.2), normal: Vec3::Y };
        // A floor voxel in the open (x = 6.125 m, z = 4.125 m; its top at y = 0.75 m); probes 1 m apart, the
        // window wide enough that its edges fade nothing there.
        let cell = IVec3::new(24, 2, 16);
        let window = crate::cpu::probes::probe_window(Vec3::new(6.0, 1.0, 4.0), 1.0, glam::UVec3::splat(16)).unwrap();
        // Every probe's +y face 3 (irradiance over pi), every other face 100; each gathered from its lattice
        // point, or from under the floor (y = 0) where `below`.
        let mut faces = [Vec3::splat(100.0); 6];
        faces[2] = Vec3::splat(3.0);
        let probes = |below: bool| {
            move |q: IVec3| {
                let at = window.position(q);
                Some((faces, if below { Vec3::new(at.x, 0.0, at.z) } else { at }))
            }
        };
        let bounced = bounced_radiance(&levels, 0, cell, &floor, 1.0, &window, probes(false));
        assert!(bounced.distance(floor.albedo * 3.0) < 1.0e-4, "{bounced}");
        // Half the feedback, half the light; a normal half cancelled, half again; none for a cancelled normal,
        // a feedback of 0 or NaN, or probes that have not gathered.
        let half = bounced_radiance(&levels, 0, cell, &floor, 0.5, &window, probes(false));
        assert!(half.distance(floor.albedo * 1.5) < 1.0e-4, "{half}");
        let worn = VoxelAttributes { normal: Vec3::Y * 0.5, ..floor };
        let worn = bounced_radiance(&levels, 0, cell, &worn, 1.0, &window, probes(false));
        assert!(worn.distance(floor.albedo * 1.5) < 1.0e-4, "{worn}");
        let cancelled = VoxelAttributes { normal: Vec3::Y * 0.1, ..floor };
        assert_eq!(bounced_radiance(&levels, 0, cell, &cancelled, 1.0, &window, probes(false)), Vec3::ZERO);
        for feedback in [0.0, f32::NAN] {
            assert_eq!(bounced_radiance(&levels, 0, cell, &floor, feedback, &window, probes(false)), Vec3::ZERO);
        }
        assert_eq!(bounced_radiance(&levels, 0, cell, &floor, 1.0, &window, |_| None), Vec3::ZERO);
        // Probes that gathered under the floor do not see the point over it: their light is not sent on.
        assert_eq!(bounced_radiance(&levels, 0, cell, &floor, 1.0, &window, probes(true)), Vec3::ZERO);
        // Nor is the light of the probes under the roof for a voxel of the roof's top beside its edge
        // (x = 3.875 m): the one above the roof sees it, and takes all of the weight.
        let roof = IVec3::new(15, 10, 16);
        let over = |q: IVec3| {
            let at = window.position(q);
            Some((if at.y > 2.5 { faces } else { [Vec3::splat(50.0); 6] }, at))
        };
        let top = bounced_radiance(&levels, 0, roof, &floor, 1.0, &window, over);
        assert!(top.distance(floor.albedo * 3.0) < 1.0e-4, "{top}");
        // Seen: a probe over the floor; not: one under it, one behind a surface facing away from it (the
        // floor's underside), and one beyond the roof's edge for a point under the roof (a run of it between).
        let over_floor = Vec3::new(6.1, 1.0, 4.1);
        assert!(probe_visible(&levels, 0, over_floor, Vec3::Y, Vec3::new(6.0, 2.0, 4.0)));
        assert!(!probe_visible(&levels, 0, over_floor, Vec3::Y, Vec3::new(6.0, 0.0, 4.0)));
        assert!(!probe_visible(&levels, 0, Vec3::new(6.1, 0.2, 4.1), Vec3::NEG_Y, Vec3::new(6.0, 1.0, 4.0)));
        assert!(!probe_visible(&levels, 0, Vec3::new(3.5, 2.0, 4.1), Vec3::Y, Vec3::new(3.5, 3.0, 4.0)));
        // Nor one that gathered from inside the roof's voxels, in front of the point's plane and a march too
        // short into the roof to stop.
        assert!(!probe_visible(&levels, 0, Vec3::new(3.5, 2.0, 4.1), Vec3::X, Vec3::new(3.9, 2.6, 4.1)));
    }

    #[test]
    fn a_point_light_under_the_roof_lights_the_floor_below_it_and_a_bad_one_nothing() {
        let (mips, origin) = floor_under_a_roof();
        let levels = [TraceLevel { origin, cell_size: 0.25, window_min: IVec3::ZERO, mips: &mips }];
        let floor = VoxelAttributes { albedo: Vec3::ONE, normal: Vec3::Y };
        // 1.5 m over the floor voxel's centre (y = 0.625), under the roof (y = 2.5): 1 candela.
        let center = cell_center(&levels[0], IVec3::new(8, 2, 16));
        let bulb = Light::Point {
            position: center + Vec3::new(0.0, 1.5, 0.0),
            color: Vec3::ONE,
            intensity: 4.0 * PI,
            range: 20.0,
        };
        let lit = voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &floor, &[bulb]);
        let expected = bulb.incident(center).unwrap().illuminance.x / PI;
        assert!(close(lit.x, expected), "{lit} {expected}");
        // Just under the roof (7.5 cm): the shadow march ends at the light, measured from the march's origin a
        // cell above the voxel; a cell further on it would have gone into the roof.
        let high = Light::Point {
            position: center + Vec3::new(0.0, 1.8, 0.0),
            color: Vec3::ONE,
            intensity: 4.0 * PI,
            range: 20.0,
        };
        assert!(voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &floor, &[high]).x > 0.0);
        // Above the roof, the same bulb does not reach the floor.
        let above = Light::Point {
            position: center + Vec3::new(0.0, 3.0, 0.0),
            color: Vec3::ONE,
            intensity: 4.0 * PI,
            range: 20.0,
        };
        assert_eq!(voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &floor, &[above]), Vec3::ZERO);
        // Bad lights: no light, no NaN.
        let bad = Light::Point { position: center + Vec3::Y, color: Vec3::ONE, intensity: f32::NAN, range: 20.0 };
        assert_eq!(voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &floor, &[bad]), Vec3::ZERO);
        // A voxel whose normals nearly cancel (an average a tenth long, under SHADOW_NORMAL_MIN): a tenth of the
        // light, its shadow ray from its centre; one whose normals cancel: none.
        let mostly_cancelled = VoxelAttributes { albedo: Vec3::ONE, normal: Vec3::Y * 0.1 };
        let short = voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &mostly_cancelled, &[bulb]);
        assert!(close(short.x, 0.1 * expected), "{short} {expected}");
        let both_faces = VoxelAttributes { albedo: Vec3::ONE, normal: Vec3::ZERO };
        assert_eq!(voxel_radiance(&levels, 0, IVec3::new(8, 2, 16), &both_faces, &[bulb]), Vec3::ZERO);
    }

    #[test]
    fn rgb9e5_round_trips_within_its_precision_and_takes_bad_values_as_zero() {
        for c in [
            Vec3::new(1.0, 0.5, 0.25),
            Vec3::new(3183.1, 1591.5, 636.6),
            Vec3::new(0.0, 1.0e-3, 7.0),
            Vec3::splat(RGB9E5_MAX),
            Vec3::new(511.9, 0.0, 0.0),
            Vec3::new(1.0e-6, 2.0e-6, 0.0),
        ] {
            let back = unpack_rgb9e5(pack_rgb9e5(c));
            // Each channel within a step of the largest channel's exponent (1/512 of it, rounded), and no finer
            // than the smallest exponent's step (2^-24).
            let step = (c.max_element() / 256.0).max(1.0 / 16_777_216.0);
            assert!((back - c).abs().max_element() <= step, "{c} -> {back}");
        }
        // Exact values stay exact; the encoding's own examples.
        assert_eq!(unpack_rgb9e5(pack_rgb9e5(Vec3::new(1.0, 0.5, 0.0))), Vec3::new(1.0, 0.5, 0.0));
        assert_eq!(pack_rgb9e5(Vec3::ZERO), 0);
        assert_eq!(unpack_rgb9e5(pack_rgb9e5(Vec3::splat(1.0e9))), Vec3::splat(RGB9E5_MAX));
        assert_eq!(pack_rgb9e5(Vec3::new(f32::NAN, -1.0, f32::NEG_INFINITY)), 0);
        assert_eq!(unpack_rgb9e5(pack_rgb9e5(Vec3::new(f32::INFINITY, 0.0, 0.0))).x, RGB9E5_MAX);
        // A value whose mantissa rounds up to 512 moves to the next exponent.
        let back = unpack_rgb9e5(pack_rgb9e5(Vec3::splat(511.9)));
        assert_eq!(back, Vec3::splat(512.0));
    }

    #[test]
    fn prepared_lights_bring_the_same_light_and_bad_ones_are_not_prepared() {
        let spot = Light::Spot {
            position: Vec3::new(1.0, 3.0, -2.0),
            direction: Vec3::new(0.2, -1.0, 0.1),
            color: Vec3::new(1.0, 0.8, 0.6),
            intensity: 8000.0,
            range: 12.0,
            inner_angle: 0.3,
            outer_angle: 0.7,
        };
        let p = Vec3::new(2.6, 0.0, -2.0);
        let i = spot.incident(p).unwrap();
        let cone = spot_attenuation(Vec3::new(0.2, -1.0, 0.1).normalize().dot(-i.to_light), 0.3, 0.7);
        assert!(cone > 0.0 && cone < 1.0, "{cone}: between the cones");
        let d2 = (Vec3::new(1.0, 3.0, -2.0) - p).length_squared();
        let e = 8000.0 / (4.0 * PI) * distance_attenuation(d2, 1.0 / 144.0) * cone;
        assert!(close(i.illuminance.x, e) && close(i.illuminance.z, 0.6 * e), "{} {e}", i.illuminance);
        let bad = [
            Light::Directional { direction: Vec3::ZERO, color: Vec3::ONE, illuminance: 1.0 },
            Light::Directional { direction: Vec3::Y, color: Vec3::new(1.0, f32::NAN, 0.0), illuminance: 1.0 },
            Light::Directional { direction: Vec3::Y, color: Vec3::ONE, illuminance: f32::INFINITY },
            Light::Point { position: Vec3::NAN, color: Vec3::ONE, intensity: 1.0, range: 1.0 },
            Light::Point { position: Vec3::ZERO, color: Vec3::ONE, intensity: 1.0, range: f32::INFINITY },
            Light::Point { position: Vec3::ZERO, color: Vec3::ZERO, intensity: 1.0, range: 1.0 },
            Light::Spot {
                position: Vec3::ZERO,
                direction: Vec3::ZERO,
                color: Vec3::ONE,
                intensity: 1.0,
                range: 1.0,
                inner_angle: 0.1,
                outer_angle: 0.2,
            },
        ];
        for light in bad {
            assert_eq!(light.prepare(), None, "{light:?}");
        }
    }
}
