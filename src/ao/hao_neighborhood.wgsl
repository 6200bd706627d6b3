// Hybrid ambient occlusion, pass 1a: the window the temporal pass clamps each history to, once per texel of
// the trace: the mean of the traced AO over its 3x3 texels that show geometry, plus and minus two standard
// deviations and a margin (`neighborhood_window`; (-1, 2), no bound, where none does). At half resolution
// the four pixels of a 2x2 block share their block's window, so it is computed here once, at the trace's
// resolution, instead of read from nine texels by every pixel of the temporal pass.
// CPU twin: `bevy_hao::cpu::temporal::trace_window`.
#import bevy_hao::hao_common::{HaoSettings, neighborhood_window, trace_index, unpack_history}

// The trace's texels and their windows, row by row (`trace_index`).
@group(0) @binding(0) var<storage, read> noisy: array<vec2<u32>>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
@group(0) @binding(2) var<storage, read_write> window_out: array<vec2<f32>>;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn neighborhood(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<i32>(i32(settings.trace_width), i32(settings.trace_height));
    let texel = vec2<i32>(gid.xy);
    if any(texel >= size) {
        return;
    }
    var sum = 0.0;
    var squares = 0.0;
    var n = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let t = texel + vec2<i32>(dx, dy);
            if any(t < vec2<i32>(0)) || any(t >= size) {
                continue;
            }
            // (ao, view depth, ...): depth 0 is the background.
            let v = unpack_history(noisy[trace_index(settings, vec2<u32>(t))]).xy;
            if v.y > 0.0 {
                sum += v.x;
                squares += v.x * v.x;
                n += 1.0;
            }
        }
    }
    var window = vec2<f32>(-1.0, 2.0);
    if n > 0.0 {
        window = neighborhood_window(sum, squares, n);
    }
    window_out[trace_index(settings, gid.xy)] = window;
}
