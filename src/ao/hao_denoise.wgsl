// Hybrid ambient occlusion, pass 2: a separable bilateral filter (depth- and normal-aware) over the noisy
// AO. The horizontal half runs at the traced resolution; the vertical half runs at full resolution, so it
// also upsamples a half-resolution trace, weighing each tap against the full-resolution pixel's own depth
// and normal. With the near field on, the result is the minimum with Bevy's screen-space AO.
#import bevy_hao::hao_common::{HaoSettings, octahedral_decode, bilateral_weight}

// Horizontal half: noisy (ao, view depth, octahedral normal) -> filtered, same layout.
@group(0) @binding(0) var noisy: texture_2d<f32>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
@group(0) @binding(2) var filtered_out: texture_storage_2d<rgba16float, write>;

@compute @workgroup_size(8, 8, 1)
fn denoise_horizontal(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(noisy);
    if any(gid.xy >= size) {
        return;
    }
    let center = textureLoad(noisy, gid.xy, 0);
    if center.y <= 0.0 {
        textureStore(filtered_out, gid.xy, center);
        return;
    }
    let n0 = octahedral_decode(center.zw);
    let r = i32(settings.denoise_radius);
    var sum = 0.0;
    var weights = 0.0;
    for (var dx = -r; dx <= r; dx++) {
        let x = clamp(i32(gid.x) + dx, 0, i32(size.x) - 1);
        let tap = textureLoad(noisy, vec2<i32>(x, i32(gid.y)), 0);
        if tap.y <= 0.0 {
            continue;
        }
        let w = bilateral_weight(f32(dx), f32(r), center.y, tap.y, n0, octahedral_decode(tap.zw));
        sum += w * tap.x;
        weights += w;
    }
    textureStore(filtered_out, gid.xy, vec4<f32>(select(center.x, sum / weights, weights > 1.0e-6), center.yzw));
}
