// What the GI passes share: the lights as the lighting pass takes them, the light they bring to a point, and
// the lighting volume's packing. CPU twin: `bevy_hao::cpu::lighting` (`PreparedLight`, `pack_rgb9e5`).
#define_import_path bevy_hao::gi_common

// cpu/lighting.rs: LightKind
const GI_LIGHT_DIRECTIONAL: u32 = 0u;
const GI_LIGHT_POINT: u32 = 1u;
const GI_LIGHT_SPOT: u32 = 2u;

// src/gi/lighting.rs: `GpuGiLight` (cpu/lighting.rs: `PreparedLight`).
struct GiLight {
    // World position (point and spot lights).
    position: vec3<f32>,
    kind: u32,
    // The way a directional light's light travels, or the way a spot points (unit length).
    direction: vec3<f32>,
    inverse_range_squared: f32,
    // A directional light's illuminance (lux), a point or spot light's intensity (candela), per channel.
    intensity: vec3<f32>,
    spot_scale: f32,
    spot_offset: f32,
    pad_a: f32,
    pad_b: f32,
    pad_c: f32,
}

// cpu/lighting.rs: Incident (the light's illuminance 0 where it brings none).
struct Incident {
    to_light: vec3<f32>,
    distance: f32,
    illuminance: vec3<f32>,
}

// cpu/lighting.rs: range_falloff, distance_attenuation (Bevy's getRangeFalloff, getDistanceAttenuation).
fn distance_attenuation(distance_squared: f32, inverse_range_squared: f32) -> f32 {
    let factor = distance_squared * inverse_range_squared;
    let falloff = saturate(1.0 - factor * factor);
    return falloff * falloff / max(distance_squared, 1.0e-4);
}

// cpu/lighting.rs: PreparedLight::incident. A directional light's distance is 1e30 (the CPU's infinity,
// which light_reaches takes at 1e30 too).
fn light_incident(light: GiLight, p: vec3<f32>) -> Incident {
    if light.kind == GI_LIGHT_DIRECTIONAL {
        return Incident(-light.direction, 1.0e30, light.intensity);
    }
    let d = light.position - p;
    let d2 = dot(d, d);
    if d2 <= 0.0 {
        return Incident(vec3<f32>(0.0), 0.0, vec3<f32>(0.0));
    }
    let to_light = d * inverseSqrt(d2);
    var e = light.intensity * distance_attenuation(d2, light.inverse_range_squared);
    if light.kind == GI_LIGHT_SPOT {
        let a = saturate(dot(light.direction, -to_light) * light.spot_scale + light.spot_offset);
        e *= a * a;
    }
    return Incident(to_light, sqrt(d2), e);
}

// cpu/lighting.rs: RGB9E5_MAX
const RGB9E5_MAX: f32 = 65408.0;

// cpu/lighting.rs: exp2i. 2^e, exact, for e in the normal range.
fn exp2i(e: i32) -> f32 {
    return bitcast<f32>(u32(e + 127) << 23u);
}

// cpu/lighting.rs: pack_rgb9e5. Non-negative channels as a shared-exponent word (NaN and negatives: 0).
fn pack_rgb9e5(color: vec3<f32>) -> u32 {
    let c = select(vec3<f32>(0.0), min(color, vec3<f32>(RGB9E5_MAX)), color > vec3<f32>(0.0));
    let m = max(max(c.x, c.y), c.z);
    let floor_log2 = i32((bitcast<u32>(m) >> 23u) & 0xffu) - 127;
    var exponent = max(floor_log2, -16) + 16;
    var scale = exp2i(24 - exponent);
    if floor(m * scale + 0.5) >= 512.0 {
        exponent += 1;
        scale *= 0.5;
    }
    let q = min(vec3<u32>(floor(c * scale + vec3<f32>(0.5))), vec3<u32>(511u));
    return q.x | (q.y << 9u) | (q.z << 18u) | (u32(exponent) << 27u);
}

// cpu/lighting.rs: unpack_rgb9e5.
fn unpack_rgb9e5(p: u32) -> vec3<f32> {
    let q = vec3<f32>(vec3<u32>(p & 511u, (p >> 9u) & 511u, (p >> 18u) & 511u));
    return q * exp2i(i32(p >> 27u) - 24);
}
