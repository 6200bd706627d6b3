// Hybrid ambient occlusion: what the HAO passes and the CPU twin (`bevy_hao::cpu::ao`) share: the settings,
// the ray directions (cosine-weighted, stratified, rotated per pixel) and the distance falloff. The march
// through the voxel levels is `bevy_hao::voxel_grid`'s.
#define_import_path bevy_hao::hao_common

// src/ao/prepare.rs: `GpuHaoSettings`
struct HaoSettings {
    // The previous frame's clip_from_world with its TAA jitter (PreviousViewData's has none).
    previous_clip_from_world: mat4x4<f32>,
    rays: u32,
    steps: u32,
    max_distance: f32,
    falloff: f32,
    intensity: f32,
    start_offset: f32,
    frame: u32,
    // 1 with the near field (the passes take hao_denoise.wgsl's NEAR_FIELD variant then; no shader reads it).
    near_field: u32,
    half_resolution: u32,
    denoise_radius: u32,
    // Most frames of history a pixel keeps (1: none).
    accumulation_frames: u32,
    // 1: rays pass through voxels whose average normal faces along them (`ignore_back_hits`).
    back_hits: u32,
    // 0: the view is new, resized or was off last frame, and its history is not read.
    history_valid: u32,
    // The view's first pixel in its render target (its viewport's corner): where the view's pixels lie in
    // the prepass textures and in the AO texture PBR reads, which are the target's size.
    origin_x: u32,
    origin_y: u32,
    // The view's size in pixels: the temporal history's rows (`history_index`).
    view_width: u32,
    view_height: u32,
    // The trace's size: the view's, or half of it rounded up (`trace_index`).
    trace_width: u32,
    trace_height: u32,
    // 1: each ray's first cells are traced in the depth prepass (`depth_contacts`).
    depth_contacts: u32,
    // 1: the trace runs on half its texels a frame, in a checkerboard that alternates (`texel_traced`); the
    // others keep their last frame's trace.
    checkerboard: u32,
    // Points each ray's depth contacts sample in the depth prepass (`depth_contact`).
    contact_samples: u32,
    // Most frames of history a pixel keeps where the view stands still (`history_limit`).
    still_accumulation_frames: u32,
    pad_c: u32,
}

// Where the temporal history holds pixel `p` of the view: its buffers are the view's pixels row by row.
fn history_index(settings: HaoSettings, p: vec2<u32>) -> u32 {
    return p.y * settings.view_width + p.x;
}

// Where the trace's buffers (its AO, the neighborhood pass's windows) hold its texel `t`: row by row.
fn trace_index(settings: HaoSettings, t: vec2<u32>) -> u32 {
    return t.y * settings.trace_width + t.x;
}

// Where pixel `p` of the view (0 at its viewport's corner) lies in the render target.
fn target_pixel(settings: HaoSettings, p: vec2<u32>) -> vec2<u32> {
    return p + vec2<u32>(settings.origin_x, settings.origin_y);
}

const PI: f32 = 3.141592653589793;
const GOLDEN: f32 = 0.6180339887498949;

// cpu/ao.rs: interleaved_gradient_noise (Jimenez 2014), in [0, 1).
fn interleaved_gradient_noise(pixel: vec2<f32>, frame: u32) -> f32 {
    let p = pixel + 5.588238 * f32(frame % 64u);
    return fract(52.9829189 * fract(0.06711056 * p.x + 0.00583715 * p.y));
}

// cpu/ao.rs: ray_rotation. The rotation of a pixel's rays: screen-space noise, shifted each frame along the
// R2 sequence so that accumulated frames cover the hemisphere evenly.
fn ray_rotation(pixel: vec2<f32>, frame: u32) -> vec2<f32> {
    let spatial = vec2<f32>(
        interleaved_gradient_noise(pixel, 0u),
        interleaved_gradient_noise(pixel.yx + vec2<f32>(17.0, 59.0), 0u),
    );
    let f = f32(frame % 4096u);
    let shift = vec2<f32>(fract(f * 0.7548777), fract(f * 0.5698403));
    let r = spatial + shift;
    return r - floor(r);
}

// cpu/ao.rs: half_resolution_offset. The pixel of its 2x2 block a half-resolution trace samples in `frame`.
fn half_resolution_offset(frame: u32) -> vec2<u32> {
    let k = frame % 4u;
    return vec2<u32>(select(0u, 1u, k == 1u || k == 2u), select(0u, 1u, k == 1u || k == 3u));
}

// cpu/ao.rs: traced_pixel. The pixel texel `texel` of the trace traces in `frame` on a view of `view_size`:
// its own at full resolution, at half resolution the pixel of its 2x2 block whose turn it is.
fn traced_pixel(texel: vec2<u32>, frame: u32, view_size: vec2<u32>, half_resolution: bool) -> vec2<u32> {
    let p = min(texel * 2u + half_resolution_offset(frame), view_size - vec2<u32>(1u));
    return select(texel, p, half_resolution);
}

// cpu/ao.rs: checkerboard_texel. The texel of the trace invocation `id` traces: its own, or with the
// checkerboard the one of row id.y at column 2 id.x or 2 id.x + 1 that `texel_traced` picks (the pass then
// runs half the invocations).
fn checkerboard_texel(id: vec2<u32>, frame: u32, checkerboard: bool) -> vec2<u32> {
    return select(id, vec2<u32>(id.x * 2u + ((id.y + frame) & 1u), id.y), checkerboard);
}

// cpu/ao.rs: texel_traced. Whether texel `t` of the trace is traced in `frame`: every texel, or with the
// checkerboard those whose coordinates' sum has the frame's parity (the others keep their last trace).
fn texel_traced(t: vec2<u32>, frame: u32, checkerboard: bool) -> bool {
    return !checkerboard || ((t.x + t.y + frame) & 1u) == 0u;
}

// cpu/ao.rs: trace_turn. The frame number that picks a block's pixel and turns the noise: with the
// checkerboard, where each texel is traced every other frame, half the frame.
fn trace_turn(frame: u32, checkerboard: bool) -> u32 {
    return select(frame, frame / 2u, checkerboard);
}

// cpu/ao.rs: noise_frame. The frame number that turns a pixel's ray noise: at half resolution the number of
// the pixel's own trace (one every fourth frame; pass it `trace_turn`, and one every eighth in the
// checkerboard).
fn noise_frame(frame: u32, half_resolution: bool) -> u32 {
    return select(frame, frame / 4u, half_resolution);
}

// cpu/ao.rs: orthonormal_basis (Duff et al. 2017): two tangents completing `n`.
fn orthonormal_basis(n: vec3<f32>) -> mat3x3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t = vec3<f32>(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let bt = vec3<f32>(b, s + n.y * n.y * a, -n.y);
    return mat3x3<f32>(t, bt, n);
}

// cpu/ao.rs: hemisphere_direction. Ray `i` of `count`, cosine-weighted around the normal (the third column
// of `basis`, from `orthonormal_basis`) and stratified in the polar coordinate; `rotation` (two numbers in
// [0, 1)) shifts the whole set per pixel.
fn hemisphere_direction(basis: mat3x3<f32>, i: u32, count: u32, rotation: vec2<f32>) -> vec3<f32> {
    let u1 = fract((f32(i) + rotation.x) / f32(count));
    let u2 = fract(f32(i) * GOLDEN + rotation.y);
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    let local = vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u1)));
    return basis * local;
}

// cpu/ao.rs: ao_falloff. The weight of an occluder at `distance`: 1 near the surface, 0 at `max_distance`
// and beyond, `(1 - d / max)^falloff` between.
fn ao_falloff(distance: f32, max_distance: f32, falloff: f32) -> f32 {
    let x = clamp(distance / max_distance, 0.0, 1.0);
    return pow(1.0 - x, falloff);
}

// Octahedral encoding of a unit vector into [-1, 1]^2 (for the denoiser's packed normals).
fn octahedral_encode(n: vec3<f32>) -> vec2<f32> {
    let p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if n.z >= 0.0 {
        return p;
    }
    return (1.0 - abs(p.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
}

// The direction an octahedral code stands for, not normalized (its length lies between 1/sqrt(3) and 1):
// `history_accepts` and `bilateral_weight` take it as it is, which spares a square root per texel.
fn octahedral_direction(e: vec2<f32>) -> vec3<f32> {
    var n = vec3<f32>(e, 1.0 - abs(e.x) - abs(e.y));
    let t = max(-n.z, 0.0);
    n.x += select(t, -t, n.x >= 0.0);
    n.y += select(t, -t, n.y >= 0.0);
    return n;
}

fn octahedral_decode(e: vec2<f32>) -> vec3<f32> {
    return normalize(octahedral_direction(e));
}

// cpu/denoise.rs: bilateral_weight. The denoiser's weight of a tap `offset` texels away with view depth
// `depth` and normal along `direction` (any length), against the center's (`center_normal`, unit): a
// Gaussian in distance, falling with the relative depth difference and the normals' angle (its cosine to
// the 16th power, from the squared cosine without a square root).
fn bilateral_weight(offset: f32, radius: f32, center_depth: f32, depth: f32, center_normal: vec3<f32>, direction: vec3<f32>) -> f32 {
    // The Gaussian in distance times the fall with depth, as one exponential.
    let spatial = offset * offset / (2.0 * max(radius * radius, 1.0));
    let relative_depth = abs(depth - center_depth) / (0.02 * abs(center_depth) + 1.0e-4);
    let c = max(dot(center_normal, direction), 0.0);
    // (A zero direction, which no octahedral code decodes to, weighs nothing.)
    let c2 = c * c / max(dot(direction, direction), 1.0e-30);
    let c4 = c2 * c2;
    let c8 = c4 * c4;
    return exp(-spatial - relative_depth) * c8 * c8;
}

// Packs an octahedral normal into one float exactly (11 bits per coordinate: an integer below 2^22), for the
// temporal history.
fn pack_normal(e: vec2<f32>) -> f32 {
    let q = vec2<u32>(round(clamp(e * 0.5 + 0.5, vec2<f32>(0.0), vec2<f32>(1.0)) * 2047.0));
    return f32(q.x * 2048u + q.y);
}

fn unpack_octahedral(p: f32) -> vec2<f32> {
    // In floats: exact for integers below 2^24, and cheaper than an integer division where that is
    // emulated per lane (CPU rasterizers).
    let x = floor(p / 2048.0);
    return vec2<f32>(x, p - x * 2048.0) / 2047.0 * 2.0 - 1.0;
}

// A packed normal's direction, not normalized (`octahedral_direction`).
fn unpack_direction(p: f32) -> vec3<f32> {
    return octahedral_direction(unpack_octahedral(p));
}

fn unpack_normal(p: f32) -> vec3<f32> {
    return octahedral_decode(unpack_octahedral(p));
}

// cpu/temporal.rs: DEPTH_TOLERANCE, NORMAL_TOLERANCE, CLAMP_MARGIN, CLAMPED_COUNT, CHANGED_COUNT,
// STAND_IN_COUNT, MAX_HISTORY_FRAMES, STILL_TOLERANCE, CHANGE_NOISE_FLOOR, CHANGE_NOISE_SAMPLES, WINDOW_Z
const DEPTH_TOLERANCE: f32 = 0.02;
const NORMAL_TOLERANCE: f32 = 0.9;
const CLAMP_MARGIN: f32 = 0.1;
const CLAMPED_COUNT: f32 = 2.0;
const CHANGED_COUNT: f32 = 2.0;
const STAND_IN_COUNT: f32 = 3.0;
const MAX_HISTORY_FRAMES: f32 = 127.0;
const STILL_TOLERANCE: f32 = 0.01;
const CHANGE_NOISE_FLOOR: f32 = 0.1;
const CHANGE_NOISE_SAMPLES: f32 = 4.0;
const WINDOW_Z: f32 = 2.0;

// cpu/temporal.rs: current_variance. The variance of a pixel's blended current AO from its neighbourhood's
// window: the deviation (a quarter of the window's width, less the margin), at least CHANGE_NOISE_FLOOR,
// squared over CHANGE_NOISE_SAMPLES.
fn current_variance(window: vec2<f32>) -> f32 {
    let sigma = max((window.y - window.x) * 0.25 - CLAMP_MARGIN * 0.5, CHANGE_NOISE_FLOOR);
    return sigma * sigma / CHANGE_NOISE_SAMPLES;
}

// cpu/temporal.rs: clamped_count. The most frames a history keeps after the window moved it by `shift`: as
// many as leave its noise no smaller than the shift, s^2 / shift^2, at least CLAMPED_COUNT.
fn clamped_count(shift: f32, window: vec2<f32>) -> f32 {
    return max(current_variance(window) / (shift * shift), CLAMPED_COUNT);
}

// cpu/temporal.rs: STABLE_Z. How many standard errors of a still pixel's history the AO it shows may stray.
const STABLE_Z: f32 = 1.0;

// cpu/temporal.rs: stable_ao. The AO a pixel shows and the frames of the history it was taken from, from
// what it showed last frame (`last`: ao, frames; `has_last`: the view stands still there and the pixel has
// a history) and its new history (ao, frames of weight): where the history is longer than `max_count`, the
// change near it caps no history (`cap`, `change_cap`, at least MAX_HISTORY_FRAMES), it holds under twice
// the frames of the one shown, and lies within STABLE_Z standard errors (the current AO's variance over
// 2 count - 1) of what it showed, the same AO again; else the history's.
fn stable_ao(last: vec2<f32>, has_last: bool, ao: f32, count: f32, max_count: f32, cap: f32, window: vec2<f32>) -> vec2<f32> {
    let reach = STABLE_Z * sqrt(current_variance(window) / max(2.0 * count - 1.0, 1.0));
    if has_last && count > max_count && cap >= MAX_HISTORY_FRAMES && count < 2.0 * last.y && abs(ao - last.x) <= reach {
        return last;
    }
    return vec2<f32>(ao, count);
}

// cpu/temporal.rs: history_limit. The most frames a pixel's history keeps: max_count (accumulation_frames),
// or where the view stands still there (`still`: its surface reprojects onto the pixel itself) still_count,
// within [max_count, MAX_HISTORY_FRAMES]; without accumulation none either way.
fn history_limit(max_count: f32, still_count: f32, still: bool) -> f32 {
    if still && max_count > 1.0 {
        return max(min(still_count, MAX_HISTORY_FRAMES), max_count);
    }
    return max_count;
}

// cpu/temporal.rs: uses_stand_in. Whether a pixel without its own trace this frame blends its stand-in: where
// its history holds fewer than STAND_IN_COUNT frames (or max_count, if lower), the voxels near it changed
// enough to cap its history (`change_cap`) under max_count, or nothing is accumulated.
fn uses_stand_in(history_count: f32, max_count: f32, cap: f32) -> bool {
    return history_count < min(STAND_IN_COUNT, max_count) || cap < max_count || max_count <= 1.0;
}

// cpu/temporal.rs: waiting_cap. The cap of a pixel that blends only its own trace, one every
// `frames_per_trace` frames: the balance of lag and noise for blends that far apart, n^3 = 2 s^2 / (T^2 c^2).
fn waiting_cap(cap: f32, frames_per_trace: f32) -> f32 {
    return cap / pow(max(frames_per_trace, 1.0), 2.0 / 3.0);
}

// cpu/temporal.rs: history_accepts. Whether a texel of view depth `history_depth` and normal along `direction`
// (any length) saw the surface of depth `expected_depth` and unit normal `normal`: the cosine test squared,
// without a square root.
fn history_accepts(expected_depth: f32, history_depth: f32, normal: vec3<f32>, direction: vec3<f32>) -> bool {
    let c = dot(normal, direction);
    return history_depth > 0.0 && abs(history_depth - expected_depth) <= DEPTH_TOLERANCE * expected_depth + 0.01
        && c > 0.0 && c * c >= NORMAL_TOLERANCE * NORMAL_TOLERANCE * dot(direction, direction);
}

// cpu/temporal.rs: neighborhood_window. The mean of the texels plus or minus two deviations and CLAMP_MARGIN;
// with `samples` rays (0: none), at least the interval they tell the mean to lie in (`sample_interval`).
fn neighborhood_window(sum: f32, sum_squares: f32, count: f32, samples: f32) -> vec2<f32> {
    let mean = sum / count;
    let sigma = sqrt(max(sum_squares / count - mean * mean, 0.0));
    let window = vec2<f32>(mean - 2.0 * sigma - CLAMP_MARGIN, mean + 2.0 * sigma + CLAMP_MARGIN);
    // (A sample count of 0 leaves the window as it is, without a branch.)
    let interval = sample_interval(mean, max(samples, 1.0));
    return select(window, vec2<f32>(min(window.x, interval.x), max(window.y, interval.y)), samples > 0.0);
}

// cpu/temporal.rs: sample_interval. Where the mean AO of `samples` rays whose mean is `mean` says the
// neighbourhood's lies: Wilson's score interval at WINDOW_Z standard errors.
fn sample_interval(mean: f32, samples: f32) -> vec2<f32> {
    let m = clamp(mean, 0.0, 1.0);
    let z2n = WINDOW_Z * WINDOW_Z / samples;
    let centre = (m + 0.5 * z2n) / (1.0 + z2n);
    let half = WINDOW_Z / (1.0 + z2n) * sqrt((m * (1.0 - m) + 0.25 * z2n) / samples);
    return vec2<f32>(centre - half, centre + half);
}

// cpu/temporal.rs: temporal_blend; returns (ao, frames of weight). `cap`: the frames the history keeps near
// voxels that changed (`change_cap`).
fn temporal_blend(history: f32, history_count: f32, window: vec2<f32>, current: f32, max_count: f32, cap: f32) -> vec2<f32> {
    var h = history;
    var c = min(history_count, cap);
    if h < window.x || h > window.y {
        let clamped = clamp(h, window.x, window.y);
        c = min(c, clamped_count(clamped - h, window));
        h = clamped;
    }
    let count = min(c + 1.0, max(max_count, 1.0));
    if count <= 1.0 {
        return vec2<f32>(current, count);
    }
    return vec2<f32>(h + (current - h) / count, count);
}

// cpu/temporal.rs: temporal_update; returns (ao, frames of weight). `own`: the pixel was traced this frame
// and `current` is its AO; else `current` is its stand-in, blended only where `uses_stand_in` (else the
// history stays as it is). Where it blends only its own trace, one every `frames_per_trace` frames, the cap
// is `waiting_cap`'s. Either way it keeps at most `limit` frames (`history_limit`): a frame that cuts the
// limit cuts every pixel's history, traced or not.
fn temporal_update(history: f32, history_count: f32, window: vec2<f32>, own: bool, current: f32, max_count: f32, limit: f32, cap: f32, frames_per_trace: f32) -> vec2<f32> {
    if uses_stand_in(history_count, max_count, cap) {
        return temporal_blend(history, history_count, window, current, limit, cap);
    }
    if own {
        return temporal_blend(history, history_count, window, current, limit, waiting_cap(cap, frames_per_trace));
    }
    return vec2<f32>(history, min(history_count, limit));
}

// cpu/denoise.rs: HistoryTexel::stored. The temporal history's texel (ao, view depth, packed normal, frames
// of weight) in 64 bits, one element of the history buffer (and of the trace's, with no frames): x holds the
// view depth rounded to 11 bits of mantissa (its top 19 bits: a positive float's exponent and mantissa) above
// the AO to 1/8191 (13 bits); y the packed normal's 22 bits above the frames to an eighth (10 bits, at most
// 127).
fn pack_history(v: vec4<f32>) -> vec2<u32> {
    let depth = (bitcast<u32>(max(v.y, 0.0)) + 0x800u) >> 12u;
    let ao = u32(round(clamp(v.x, 0.0, 1.0) * 8191.0));
    let frames = u32(round(clamp(v.w, 0.0, MAX_HISTORY_FRAMES) * 8.0));
    return vec2<u32>((depth << 13u) | ao, (u32(v.z) << 10u) | frames);
}

// A texel of the history, unpacked (`pack_history`): (ao, view depth, packed normal, frames); all zero (no
// history) where never written.
fn unpack_history(h: vec2<u32>) -> vec4<f32> {
    return vec4<f32>(f32(h.x & 8191u) / 8191.0, bitcast<f32>((h.x >> 13u) << 12u), f32(h.y >> 10u), f32(h.y & 1023u) * 0.125);
}
