// Hybrid ambient occlusion, pass 2: a separable bilateral filter (depth- and normal-aware) over the
// accumulated AO. The horizontal half runs at the traced resolution; the vertical half runs at full
// resolution, so it also upsamples a half-resolution trace, weighing each tap against the full-resolution
// pixel's own depth and normal. With the near field on, the result is the minimum with Bevy's screen-space
// AO. The more frames a pixel's history holds, the less noise is left and the narrower the horizontal
// half: the full radius up to 4 frames, half of it at 16.
#import bevy_hao::hao_common::{HaoSettings, unpack_normal, unpack_octahedral, bilateral_weight}

// Horizontal half: the temporal history (ao, view depth, packed normal, frames) -> filtered (ao, view
// depth, octahedral normal).
@group(0) @binding(0) var accumulated: texture_2d<f32>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
@group(0) @binding(2) var filtered_out: texture_storage_2d<rgba16float, write>;

@compute @workgroup_size(8, 8, 1)
fn denoise_horizontal(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(accumulated);
    if any(gid.xy >= size) {
        return;
    }
    let center = textureLoad(accumulated, gid.xy, 0);
    if center.y <= 0.0 {
        textureStore(filtered_out, gid.xy, vec4<f32>(center.x, 0.0, 0.0, 0.0));
        return;
    }
    let e0 = unpack_octahedral(center.z);
    let n0 = unpack_normal(center.z);
    let r = i32(ceil(f32(settings.denoise_radius) * min(1.0, 2.0 / sqrt(max(center.w, 1.0)))));
    var sum = 0.0;
    var weights = 0.0;
    for (var dx = -r; dx <= r; dx++) {
        let x = clamp(i32(gid.x) + dx, 0, i32(size.x) - 1);
        let tap = textureLoad(accumulated, vec2<i32>(x, i32(gid.y)), 0);
        if tap.y <= 0.0 {
            continue;
        }
        let w = bilateral_weight(f32(dx), f32(r), center.y, tap.y, n0, unpack_normal(tap.z));
        sum += w * tap.x;
        weights += w;
    }
    textureStore(filtered_out, gid.xy, vec4<f32>(select(center.x, sum / weights, weights > 1.0e-6), center.y, e0));
}
