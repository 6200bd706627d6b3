// Hybrid ambient occlusion, pass 2b: the denoised AO at full resolution, and the near field. At full
// resolution this pass is the vertical half of the bilateral filter (`bilateral_line`). A half-resolution
// trace, filtered both ways by hao_denoise.wgsl, is upsampled: a block's value stands for its middle (the
// trace samples its pixels in turn), so a pixel's centre lies a quarter of a block from the nearest, and it
// reads the 2x2 nearest blocks, weighed linearly and by their depth and normal against its own (CPU twin:
// `bevy_hao::cpu::denoise::upsample_taps`). With the near field on, the result is the minimum with Bevy's
// screen-space AO.
#import bevy_render::view::View
#import bevy_hao::hao_common::{HaoSettings, unpack_normal, bilateral_weight, bilateral_line, target_pixel}

// ao, view depth, packed normal, frames (at the traced resolution): filtered across at full resolution,
// both ways at half resolution
@group(0) @binding(0) var denoised: texture_2d<f32>;
// The prepasses, the target's size: the view's pixel p is at target_pixel(p). With MSAA, sample 0.
#ifdef MULTISAMPLED
@group(0) @binding(1) var depth_texture: texture_depth_multisampled_2d;
@group(0) @binding(2) var normal_texture: texture_multisampled_2d<f32>;
#else
@group(0) @binding(1) var depth_texture: texture_depth_2d;
@group(0) @binding(2) var normal_texture: texture_2d<f32>;
#endif
@group(0) @binding(3) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(4) var<uniform> settings: HaoSettings;
@group(0) @binding(5) var ao_out: texture_storage_2d<r32float, write>;
@group(1) @binding(0) var<uniform> view: View;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn upsample(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(ao_out);
    if any(gid.xy >= size) {
        return;
    }
    let pixel = gid.xy;
    var ao = 1.0;
    let depth = textureLoad(depth_texture, target_pixel(settings, pixel), 0);
    if depth > 0.0 {
        if settings.half_resolution == 0u {
            ao = bilateral_line(denoised, pixel, vec2<i32>(0, 1), settings.denoise_radius).x;
        } else {
            let denoised_size = vec2<i32>(textureDimensions(denoised));
            let p = view.view_from_clip * vec4<f32>(0.0, 0.0, depth, 1.0);
            let d0 = -p.z / p.w;
            let n0 = normalize(textureLoad(normal_texture, target_pixel(settings, pixel), 0).xyz * 2.0 - 1.0);
            let u = (vec2<f32>(pixel) + 0.5) * 0.5 - 0.5;
            let base = vec2<i32>(floor(u));
            let f = u - floor(u);
            var sum = 0.0;
            var weights = 0.0;
            for (var k = 0; k < 4; k++) {
                let o = vec2<i32>(k & 1, k >> 1);
                let t = clamp(base + o, vec2<i32>(0), denoised_size - 1);
                let tap = textureLoad(denoised, t, 0);
                if tap.y <= 0.0 {
                    continue;
                }
                let bilinear = select(1.0 - f.x, f.x, o.x == 1) * select(1.0 - f.y, f.y, o.y == 1);
                let w = bilinear * bilateral_weight(0.0, 1.0, d0, tap.y, n0, unpack_normal(tap.z));
                sum += w * tap.x;
                weights += w;
            }
            if weights > 1.0e-6 {
                ao = sum / weights;
            } else {
                ao = textureLoad(denoised, min(vec2<i32>(pixel / 2u), denoised_size - 1), 0).x;
            }
        }
    }
    if settings.near_field != 0u {
        ao = min(ao, textureLoad(screen_space_ao, pixel, 0).r);
    }
    textureStore(ao_out, pixel, vec4<f32>(clamp(ao, 0.0, 1.0), 0.0, 0.0, 1.0));
}
