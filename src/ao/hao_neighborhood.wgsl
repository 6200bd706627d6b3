// Hybrid ambient occlusion, pass 2: once per texel of the trace, what the pixels of the temporal pass read
// of its 3x3 texels: the window that bounds their history (the mean of the traced AO over the texels that
// show geometry, plus and minus two standard deviations and a margin, and away from occluders that moved at
// least the interval the texels' rays tell their mean to lie in: `neighborhood_window`; (-1, 2), no bound,
// where none does), and the texel's AO filtered over them (`bilateral_weight`: their distance in
// texels over `denoise_radius`, their depth and normal against the traced pixel's; where occluders moved
// near it, over 5x5 texels at twice the width), which the pixel it traced blends into its history. At half
// resolution the four pixels of a 2x2 block share their block's window, so it is computed here once, at the
// trace's resolution, instead of read from nine texels by every pixel of the temporal pass.
// CPU twin: `bevy_hao::cpu::temporal::trace_window`, `prefilter`.
#import bevy_hao::hao_common::{
    HaoSettings, bilateral_weight, neighborhood_window, trace_index, unpack_direction, unpack_history, unpack_normal,
}

// cpu/temporal.rs: CHANGED_FILTER_REACH
const CHANGED_FILTER_REACH: i32 = 2;

// The trace's texels, and what this pass makes of them: the window (lower and upper bound) and the filtered
// AO, row by row (`trace_index`).
@group(0) @binding(0) var<storage, read> noisy: array<vec2<u32>>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
@group(0) @binding(2) var<storage, read_write> window_out: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read_write> filtered_out: array<f32>;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn neighborhood(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<i32>(i32(settings.trace_width), i32(settings.trace_height));
    let texel = vec2<i32>(gid.xy);
    if any(texel >= size) {
        return;
    }
    // (ao, view depth, packed normal): depth 0 is the background.
    let center = unpack_history(noisy[trace_index(settings, gid.xy)]);
    let center_normal = unpack_normal(center.z);
    // Where occluders moved near the traced pixel (the trace's flag in the fourth field), whose history is
    // short, the filter reaches CHANGED_FILTER_REACH texels at as many times the width; the window stays 3x3.
    let reach = select(1, CHANGED_FILTER_REACH, center.w > 0.5);
    let radius = f32(settings.denoise_radius) * f32(reach);
    var sum = 0.0;
    var squares = 0.0;
    var n = 0.0;
    var filtered = vec2<f32>(0.0);
    for (var y = -reach; y <= reach; y++) {
        for (var x = -reach; x <= reach; x++) {
            let d = vec2<i32>(x, y);
            let t = texel + d;
            if any(t < vec2<i32>(0)) || any(t >= size) {
                continue;
            }
            let v = unpack_history(noisy[trace_index(settings, vec2<u32>(t))]);
            if v.y > 0.0 {
                if max(abs(x), abs(y)) <= 1 {
                    sum += v.x;
                    squares += v.x * v.x;
                    n += 1.0;
                }
                let w = bilateral_weight(length(vec2<f32>(d)), radius, center.y, v.y, center_normal, unpack_direction(v.z));
                filtered += vec2<f32>(w * v.x, w);
            }
        }
    }
    // Away from occluders that moved, the window is at least as wide as the rays can tell: a neighbourhood
    // whose few rays all escaped by chance must not lift a pixel's history into a light speck.
    let samples = select(n * f32(settings.rays), 0.0, center.w > 0.5 || center.y <= 0.0);
    var window = vec2<f32>(-1.0, 2.0);
    if n > 0.0 {
        window = neighborhood_window(sum, squares, n, samples);
    }
    // Radius 0, or a texel that shows no geometry (no pixel blends it): the texel as traced.
    let ao = select(center.x, filtered.x / filtered.y, settings.denoise_radius > 0u && center.y > 0.0 && filtered.y > 0.0);
    window_out[trace_index(settings, gid.xy)] = window;
    filtered_out[trace_index(settings, gid.xy)] = ao;
}
