// Hybrid ambient occlusion, pass 2b: the vertical half of the bilateral filter, at full resolution (see
// hao_denoise.wgsl), and the near field.
#import bevy_render::view::View
#import bevy_hao::hao_common::{HaoSettings, octahedral_decode, bilateral_weight}

@group(0) @binding(0) var filtered: texture_2d<f32>;
@group(0) @binding(1) var depth_texture: texture_depth_2d;
@group(0) @binding(2) var normal_texture: texture_2d<f32>;
@group(0) @binding(3) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(4) var<uniform> settings: HaoSettings;
@group(0) @binding(5) var ao_out: texture_storage_2d<r32float, write>;
@group(1) @binding(0) var<uniform> view: View;

@compute @workgroup_size(8, 8, 1)
fn denoise_vertical(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(ao_out);
    if any(gid.xy >= size) {
        return;
    }
    let pixel = gid.xy;
    var ao = 1.0;
    let depth = textureLoad(depth_texture, pixel, 0);
    if depth > 0.0 {
        let scale = select(1u, 2u, settings.half_resolution != 0u);
        let filtered_size = vec2<i32>(textureDimensions(filtered));
        let center = vec2<i32>(pixel / scale);
        let p = view.view_from_clip * vec4<f32>(0.0, 0.0, depth, 1.0);
        let d0 = -p.z / p.w;
        let n0 = normalize(textureLoad(normal_texture, pixel, 0).xyz * 2.0 - 1.0);
        let r = i32(settings.denoise_radius);
        var sum = 0.0;
        var weights = 0.0;
        for (var dy = -r; dy <= r; dy++) {
            let y = clamp(center.y + dy, 0, filtered_size.y - 1);
            let tap = textureLoad(filtered, vec2<i32>(min(center.x, filtered_size.x - 1), y), 0);
            if tap.y <= 0.0 {
                continue;
            }
            let w = bilateral_weight(f32(dy), f32(r), d0, tap.y, n0, octahedral_decode(tap.zw));
            sum += w * tap.x;
            weights += w;
        }
        if weights > 1.0e-6 {
            ao = sum / weights;
        } else {
            ao = textureLoad(filtered, min(center, filtered_size - vec2<i32>(1)), 0).x;
        }
    }
    if settings.near_field != 0u {
        ao = min(ao, textureLoad(screen_space_ao, pixel, 0).r);
    }
    textureStore(ao_out, pixel, vec4<f32>(clamp(ao, 0.0, 1.0), 0.0, 0.0, 1.0));
}
