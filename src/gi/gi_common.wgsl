// What the GI passes share: the lights as the lighting pass takes them, the light they bring to a point, the
// lighting volume's packing, and the probes' window and records (which the lighting pass reads back for the
// further bounces). CPU twins: `bevy_hao::cpu::lighting` (`PreparedLight`, `pack_rgb9e5`) and
// `bevy_hao::cpu::probes` (`ProbeWindow`).
#define_import_path bevy_hao::gi_common
#import bevy_hao::voxel_grid::{voxel_grid, voxel_occupied, level_position}

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

// src/gi/probes.rs: `GpuProbeParams`.
struct ProbeParams {
    // The lattice point of the window's first probe.
    window_min: vec3<i32>,
    // Rays a probe traces on an update.
    rays: u32,
    // Probes along each axis.
    counts: vec3<u32>,
    // This frame's share of the probes, of `phases`.
    phase: u32,
    spacing: f32,
    phases: u32,
    // The updates a probe's history holds at most this frame.
    max_frames: u32,
    // This frame's number, which turns the probes' rays.
    seed: u32,
    // The world point the window follows, which its probes fade out away from (`edge_fade`).
    focus: vec3<f32>,
    // 1 where these are the near probes and a far window is written beside them (`far_params`), which
    // `write_probes` fades them into (cpu/far_probes.rs); else 0.
    far: u32,
}

// src/gi/probes.rs: `PROBE_RECORD_BYTES`. A probe's history: its six faces (irradiance over pi, rgb), the
// lattice point it holds (a slot is shared by the lattice points the window's counts apart), the updates it
// holds, the seed of the last, and where it gathered from (`relocate_probe`'s point, world space).
struct ProbeRecord {
    faces: array<vec4<f32>, 6>,
    lattice: vec3<i32>,
    frames: u32,
    seed: u32,
    at_x: f32,
    at_y: f32,
    at_z: f32,
}

// cpu/probes.rs: ProbeWindow::slot. Lattice point q's record in window `window`: q modulo the counts, x
// fastest.
fn window_slot(window: ProbeParams, q: vec3<i32>) -> u32 {
    let c = vec3<i32>(window.counts);
    let s = vec3<u32>(((q % c) + c) % c);
    return s.x + window.counts.x * (s.y + window.counts.y * s.z);
}

// cpu/probes.rs: EDGE_FADE_SPACINGS
const EDGE_FADE_SPACINGS: f32 = 2.0;

// cpu/probes.rs: ProbeWindow::edge_fade. The weight of lattice point `q`'s faces in the irradiance volume: 1
// near the focus, falling linearly to 0 over the last EDGE_FADE_SPACINGS spacings (at most half) of the
// window's reach (ceil(c / 2) - 1.5 spacings) on each axis of at least 4 probes, the product over the axes.
fn edge_fade(window: ProbeParams, q: vec3<i32>) -> f32 {
    let d = abs(vec3<f32>(q) - window.focus / window.spacing);
    var weight = 1.0;
    for (var a = 0u; a < 3u; a++) {
        let c = window.counts[a];
        if c >= 4u {
            let reach = f32((c + 1u) / 2u) - 1.5;
            weight *= clamp((reach - d[a]) / min(EDGE_FADE_SPACINGS, 0.5 * reach), 0.0, 1.0);
        }
    }
    return weight;
}

// cpu/probes.rs: occupied_at. Whether the world point `q` lies in an occupied cell of level `level`'s window
// (outside it, no).
fn occupied_at(level: u32, q: vec3<f32>) -> bool {
    let c = floor(level_position(level, q));
    if any(c < vec3<f32>(0.0)) || any(c >= vec3<f32>(voxel_grid.levels[level].dims)) {
        return false;
    }
    return voxel_occupied(level, vec3<i32>(c), 0u);
}
