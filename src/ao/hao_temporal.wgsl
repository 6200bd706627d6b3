// Hybrid ambient occlusion, pass 3: temporal accumulation, at full resolution; it writes the AO PBR reads.
// Each pixel's surface is reprojected into the previous frame with the camera's previous matrices, the
// history is read there (bilinear, each texel kept only if it saw the same surface), clamped to the window of
// this frame's trace around the pixel's block, and blended with its own trace filtered over the block's 3x3
// texels (both from the neighborhood pass). At half resolution a pixel is traced every fourth frame (every
// eighth in the checkerboard, where the trace keeps half its texels from last frame: `texel_traced`); in the
// other frames its history stays as it is, and where it has none its traced neighbours on its surface stand
// in. Where the view stands still (the surface reprojects onto the pixel itself), the pixel's own texel is
// read, exactly, and the history keeps up to `still_accumulation_frames` (`history_limit`). Writes the new
// history (ao, view depth, packed normal, frames of weight, in 64 bits: `pack_history`; a
// buffer of the view's pixels row by row), which the next frame reprojects, and its AO into the texture PBR
// reads (at target_pixel(p): the texture is the target's size); with the near field, into the plugin's result
// texture with the minimum of Bevy's screen-space AO, which the apply pass then copies (Bevy's SSAO texture
// cannot be read and written in one pass). Near voxels that changed (moving occluders) the history is kept
// as short as the change there calls for (`change_cap`). Where the view stands still, a pixel whose long
// history stays near the AO it showed last frame shows that again (`stable_ao`; the `shown` buffer).
// CPU twin: `bevy_hao::cpu::temporal`. The voxel grid is bound at group 2.
#import bevy_render::view::View
#import bevy_hao::hao_common::{
    HaoSettings, history_accepts, history_index, history_limit, octahedral_encode, pack_history, pack_normal,
    stable_ao, target_pixel, temporal_update, trace_index, uses_stand_in, traced_pixel, texel_traced,
    trace_turn, unpack_direction, unpack_history, MAX_HISTORY_FRAMES, STILL_TOLERANCE,
}
#import bevy_hao::hao_change::{occlusion_change, change_cap}

// bevy_core_pipeline::prepass::PreviousViewData
struct PreviousViewData {
    view_from_world: mat4x4<f32>,
    clip_from_world: mat4x4<f32>,
    clip_from_view: mat4x4<f32>,
    world_from_clip: mat4x4<f32>,
    view_from_clip: mat4x4<f32>,
}

// The trace's texels (ao, view depth, packed normal: `unpack_history`) and the neighborhood pass's output for
// each (the window's lower and upper bound; the filtered AO), row by row (`trace_index`).
@group(0) @binding(0) var<storage, read> noisy: array<vec2<u32>>;
@group(0) @binding(1) var<storage, read> trace_window: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> filtered: array<f32>;
// Last frame's history (`history_index`; zero where there is none).
@group(0) @binding(3) var<storage, read> history: array<vec2<u32>>;
// The prepasses, the target's size (the view's pixel p is at target_pixel(p)); with MSAA, sample 0.
#ifdef MULTISAMPLED
@group(0) @binding(4) var depth_texture: texture_depth_multisampled_2d;
@group(0) @binding(5) var normal_texture: texture_multisampled_2d<f32>;
#else
@group(0) @binding(4) var depth_texture: texture_depth_2d;
@group(0) @binding(5) var normal_texture: texture_2d<f32>;
#endif
@group(0) @binding(6) var<uniform> settings: HaoSettings;
@group(0) @binding(7) var<storage, read_write> history_out: array<vec2<u32>>;
// The AO each pixel showed last frame and the frames of weight of the history it was taken from
// (`pack2x16unorm`: the frames over MAX_HISTORY_FRAMES), at `history_index`, read and written in place: each
// pixel reads and writes its own (`stable_ao`).
@group(0) @binding(8) var<storage, read_write> shown: array<u32>;
#ifdef NEAR_FIELD
@group(0) @binding(9) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(10) var ao_out: texture_storage_2d<r32float, write>;
#else ifdef USE_R16FLOAT
@group(0) @binding(9) var ao_out: texture_storage_2d<r16float, write>;
#else
@group(0) @binding(9) var ao_out: texture_storage_2d<r32float, write>;
#endif

@group(1) @binding(0) var<uniform> view: View;
@group(1) @binding(1) var<uniform> previous_view: PreviousViewData;

// cpu/temporal.rs: stand_in. What stands in for a pixel's own trace where its block traced another pixel:
// the mean of the trace's 3x3 texels around `block` that show its surface (`history_accepts`), else of all
// that show geometry, else 1; where occluders moved near the block's traced pixel (the trace's flag, read in
// every variant: in the checkerboard a texel keeps its flag with its trace until traced again), of their
// filtered AO, which the neighborhood pass filtered wider there. `taps`: 9, or 0 where it is not used (a
// loop rather than a branch: lavapipe runs both sides of every branch, taken or not, but leaves a loop once
// none of its invocations goes on).
fn stand_in(block: vec2<u32>, view_depth: f32, normal: vec3<f32>, taps: i32) -> f32 {
    let trace_size = vec2<i32>(i32(settings.trace_width), i32(settings.trace_height));
    var wide = false;
    if taps > 0 {
        wide = unpack_history(noisy[trace_index(settings, block)]).w > 0.5;
    }
    var sum = 0.0;
    var n = 0.0;
    var same_sum = 0.0;
    var same_n = 0.0;
    for (var k = 0; k < taps; k++) {
        let t = vec2<i32>(block) + vec2<i32>(k % 3 - 1, k / 3 - 1);
        if any(t < vec2<i32>(0)) || any(t >= trace_size) {
            continue;
        }
        let at = trace_index(settings, vec2<u32>(t));
        let v = unpack_history(noisy[at]);
        if v.y > 0.0 {
            var ao = v.x;
            if wide {
                ao = filtered[at];
            }
            sum += ao;
            n += 1.0;
            if history_accepts(view_depth, v.y, normal, unpack_direction(v.z)) {
                same_sum += ao;
                same_n += 1.0;
            }
        }
    }
    return select(select(1.0, sum / n, n > 0.0), same_sum / same_n, same_n > 0.0);
}

// The pixel's AO into the texture PBR reads; with the near field, with the minimum of Bevy's SSAO into the
// result texture apply copies.
fn store_ao(pixel: vec2<u32>, ao: f32) {
#ifdef NEAR_FIELD
    let value = min(clamp(ao, 0.0, 1.0), textureLoad(screen_space_ao, pixel, 0).r);
    textureStore(ao_out, pixel, vec4<f32>(value, 0.0, 0.0, 1.0));
#else
    let at = target_pixel(settings, pixel);
    if all(at < textureDimensions(ao_out)) {
        textureStore(ao_out, at, vec4<f32>(clamp(ao, 0.0, 1.0), 0.0, 0.0, 1.0));
    }
#endif
}

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn temporal(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = vec2<u32>(settings.view_width, settings.view_height);
    if any(gid.xy >= size) {
        return;
    }
    let pixel = gid.xy;
    let depth = textureLoad(depth_texture, target_pixel(settings, pixel), 0);
    if depth <= 0.0 {
        // Background: no history.
        history_out[history_index(settings, pixel)] = pack_history(vec4<f32>(1.0, 0.0, 0.0, 0.0));
        shown[history_index(settings, pixel)] = pack2x16unorm(vec2<f32>(1.0, 0.0));
        store_ao(pixel, 1.0);
        return;
    }
    let uv = (vec2<f32>(pixel) + 0.5) / view.viewport.zw;
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let w = view.world_from_clip * vec4<f32>(ndc, depth, 1.0);
    let world = w.xyz / w.w;
    let view_depth = -(view.view_from_world * vec4<f32>(world, 1.0)).z;
    let normal = normalize(textureLoad(normal_texture, target_pixel(settings, pixel), 0).xyz * 2.0 - 1.0);

    // This frame's trace: at full resolution every pixel's; at half resolution one pixel of each 2x2 block,
    // each pixel's own every fourth frame (`traced_pixel`), or in the checkerboard every eighth (the block's
    // texel is traced every other frame: `texel_traced`).
    let half = settings.half_resolution != 0u;
    let block = pixel / select(1u, 2u, half);
    let checkerboard = settings.checkerboard != 0u;
    let turn = trace_turn(settings.frame, checkerboard);
    let traced = texel_traced(block, settings.frame, checkerboard)
        && all(traced_pixel(block, turn, vec2<u32>(view.viewport.zw), half) == pixel);
    // The window of the trace around its block bounds the history.
    let window = trace_window[trace_index(settings, block)];

    // Where this surface was: its world position in the previous view, as that frame was rendered (with its
    // own TAA jitter, as this frame's world_from_clip has this frame's).
    let clip = settings.previous_clip_from_world * vec4<f32>(world, 1.0);
    let expected_depth = -(previous_view.view_from_world * vec4<f32>(world, 1.0)).z;
    var history_ao = 0.0;
    var history_count = 0.0;
    // Whether the view stands still here: the surface reprojects onto the pixel itself (no camera motion,
    // no TAA jitter), whose history is then read exactly and may keep more frames (`history_limit`).
    var still = false;
    if clip.w > 0.0 {
        let prev_ndc = clip.xy / clip.w;
        let prev_uv = vec2<f32>(prev_ndc.x * 0.5 + 0.5, 0.5 - prev_ndc.y * 0.5);
        // The history's texel coordinates, bilinear; the pixel's own texel where the view stands still.
        var hp = prev_uv * view.viewport.zw - 0.5;
        still = all(abs(hp - vec2<f32>(pixel)) <= vec2<f32>(STILL_TOLERANCE));
        if still {
            hp = vec2<f32>(pixel);
        }
        let base = vec2<i32>(floor(hp));
        let f = hp - floor(hp);
        var weight = 0.0;
        var ao = 0.0;
        var count = 0.0;
        for (var k = 0; k < 4; k++) {
            let o = vec2<i32>(k & 1, k >> 1);
            let t = base + o;
            if any(t < vec2<i32>(0)) || any(t >= vec2<i32>(size)) {
                continue;
            }
            let h = unpack_history(history[history_index(settings, vec2<u32>(t))]);
            if h.w <= 0.0 || !history_accepts(expected_depth, h.y, normal, unpack_direction(h.z)) {
                continue;
            }
            let bw = select(1.0 - f.x, f.x, o.x == 1) * select(1.0 - f.y, f.y, o.y == 1);
            weight += bw;
            ao += bw * h.x;
            count += bw * h.w;
        }
        if weight > 0.01 {
            history_ao = ao / weight;
            // No history where the view is new, resized or was off: the texels may be another frame's
            // (multiplied, not branched on: lavapipe compiles a variant per value of a uniform in a branch).
            history_count = count / weight * f32(min(settings.history_valid, 1u));
        }
    }
    // Near voxels that changed, as much history as the change there allows.
    // (A variant of its own, `MOVED_OCCLUDERS`, chosen while any moved: on devices that run every loop until
    // all its lanes are done, such as lavapipe, the loop over them would cost every pixel every frame.)
    var cap = 1.0e30;
#ifdef MOVED_OCCLUDERS
    if history_count > 0.0 {
        cap = change_cap(occlusion_change(world, normal, settings.max_distance, settings.falloff), window);
    }
#endif
    // Its own trace, filtered; or where its block traced another pixel, the traced neighbours on its surface
    // (the stand-in), read only where it is used: where the pixel has little history or must follow a change.
    let max_count = f32(settings.accumulation_frames);
    let limit = history_limit(max_count, f32(settings.still_accumulation_frames), still);
    let stand_in_used = !traced && uses_stand_in(history_count, max_count, cap);
    var current = stand_in(block, view_depth, normal, select(0, 9, stand_in_used));
    if traced {
        current = filtered[trace_index(settings, block)];
    }
    // Frames between a pixel's own traces.
    let frames_per_trace = select(1.0, select(4.0, 8.0, checkerboard), half);
    let blended = temporal_update(history_ao, history_count, window, traced, current, max_count, limit, cap, frames_per_trace);
    history_out[history_index(settings, pixel)] =
        pack_history(vec4<f32>(blended.x, view_depth, pack_normal(octahedral_encode(normal)), blended.y));
    // Where the view stands still and the pixel has a history (of its own texel, on its surface), what it
    // showed last frame may stay.
    let at = history_index(settings, pixel);
    let last = unpack2x16unorm(shown[at]) * vec2<f32>(1.0, MAX_HISTORY_FRAMES);
    let ao = stable_ao(last, still && history_count > 0.0, blended.x, blended.y, max_count, cap, window);
    let kept = pack2x16unorm(ao / vec2<f32>(1.0, MAX_HISTORY_FRAMES));
    shown[at] = kept;
    // As kept, so that the frames that show it again show exactly the same.
    store_ao(pixel, unpack2x16unorm(kept).x);
}
