// Hybrid ambient occlusion, pass 2: the denoiser, a bilateral filter (depth- and normal-aware) over the
// temporal history, at full resolution, in one pass (`bilateral_cross`). Without the near field it writes the
// result straight into the texture PBR reads (at target_pixel(p): the texture is the target's size); with it,
// into the plugin's result texture with the minimum of Bevy's screen-space AO, which the apply pass then
// copies (Bevy's SSAO texture cannot be read and written in one pass).
// CPU twin: `bevy_hao::cpu::denoise`.
#import bevy_hao::hao_common::{
    HaoSettings, bilateral_weight, denoise_radius, history_index, target_pixel, unpack_direction,
    unpack_history, unpack_normal,
}

// The temporal pass's output, the view's pixels row by row: ao, view depth, packed normal, frames, packed in
// 64 bits (`unpack_history`).
@group(0) @binding(0) var<storage, read> history: array<vec2<u32>>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
#ifdef NEAR_FIELD
@group(0) @binding(2) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(3) var ao_out: texture_storage_2d<r32float, write>;
#else ifdef USE_R16FLOAT
@group(0) @binding(2) var ao_out: texture_storage_2d<r16float, write>;
#else
@group(0) @binding(2) var ao_out: texture_storage_2d<r32float, write>;
#endif

// The history's texel at pixel `p` of the view, clamped to it.
fn load_history(p: vec2<i32>) -> vec4<f32> {
    let last = vec2<i32>(i32(settings.view_width), i32(settings.view_height)) - 1;
    return unpack_history(history[history_index(settings, vec2<u32>(clamp(p, vec2<i32>(0), last)))]);
}

// cpu/denoise.rs: bilateral_tap. One tap of the denoiser at `p` (clamped to the view), `offset` texels from
// the center: (weight x AO, weight); nothing from the background.
fn bilateral_tap(p: vec2<i32>, offset: f32, radius: f32, center: vec4<f32>, center_normal: vec3<f32>) -> vec2<f32> {
    let tap = load_history(p);
    if tap.y <= 0.0 {
        return vec2<f32>(0.0);
    }
    let w = bilateral_weight(offset, radius, center.y, tap.y, center_normal, unpack_direction(tap.z));
    return vec2<f32>(w * tap.x, w);
}

// cpu/denoise.rs: bilateral_cross. The AO of pixel `pixel` of the history (ao, view depth, packed normal,
// frames) filtered in one pass over a cross, the center and the texels up to `denoise_radius` away along its
// row and column, each weighed by `bilateral_weight`. The background keeps its value.
fn bilateral_cross(pixel: vec2<u32>, radius: u32) -> f32 {
    let center = load_history(vec2<i32>(pixel));
    if center.y <= 0.0 {
        return center.x;
    }
    let n0 = unpack_normal(center.z);
    let r = denoise_radius(radius, center.w);
    let c = vec2<i32>(pixel);
    var sum = vec2<f32>(center.x, 1.0);
    for (var d = 1; d <= r; d++) {
        let o = f32(d);
        sum += bilateral_tap(c + vec2<i32>(d, 0), o, f32(r), center, n0);
        sum += bilateral_tap(c - vec2<i32>(d, 0), o, f32(r), center, n0);
        sum += bilateral_tap(c + vec2<i32>(0, d), o, f32(r), center, n0);
        sum += bilateral_tap(c - vec2<i32>(0, d), o, f32(r), center, n0);
    }
    return sum.x / sum.y;
}

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn denoise(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid.xy >= vec2<u32>(settings.view_width, settings.view_height)) {
        return;
    }
    var ao = bilateral_cross(gid.xy, settings.denoise_radius);
#ifdef NEAR_FIELD
    ao = min(ao, textureLoad(screen_space_ao, gid.xy, 0).r);
    let at = gid.xy;
#else
    let at = target_pixel(settings, gid.xy);
    if any(at >= textureDimensions(ao_out)) {
        return;
    }
#endif
    textureStore(ao_out, at, vec4<f32>(clamp(ao, 0.0, 1.0), 0.0, 0.0, 1.0));
}
