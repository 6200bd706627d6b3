// Hybrid ambient occlusion, pass 2: a bilateral filter (depth- and normal-aware) over the noisy AO, which
// also upsamples it from half resolution, and, with the near field on, the minimum with Bevy's own
// screen-space AO for contact detail finer than a voxel.
#import bevy_render::view::View
#import bevy_hao::hao_common::HaoSettings

@group(0) @binding(0) var noisy: texture_2d<f32>;
@group(0) @binding(1) var depth_texture: texture_depth_2d;
@group(0) @binding(2) var normal_texture: texture_2d<f32>;
@group(0) @binding(3) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(4) var<uniform> settings: HaoSettings;
@group(0) @binding(5) var ao_out: texture_storage_2d<r32float, write>;
@group(1) @binding(0) var<uniform> view: View;

fn view_depth(pixel: vec2<u32>) -> f32 {
    let d = textureLoad(depth_texture, pixel, 0);
    let p = view.view_from_clip * vec4<f32>(0.0, 0.0, d, 1.0);
    return -p.z / p.w;
}

fn world_normal(pixel: vec2<u32>) -> vec3<f32> {
    return normalize(textureLoad(normal_texture, pixel, 0).xyz * 2.0 - 1.0);
}

@compute @workgroup_size(8, 8, 1)
fn denoise(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(ao_out);
    if any(gid.xy >= size) {
        return;
    }
    let pixel = gid.xy;
    var ao = 1.0;
    if textureLoad(depth_texture, pixel, 0) > 0.0 {
        let scale = select(1u, 2u, settings.half_resolution != 0u);
        let noisy_size = vec2<i32>(textureDimensions(noisy));
        let center = vec2<i32>(pixel / scale);
        let d0 = view_depth(pixel);
        let n0 = world_normal(pixel);
        let r = i32(settings.denoise_radius);
        var sum = 0.0;
        var weights = 0.0;
        for (var dy = -r; dy <= r; dy++) {
            for (var dx = -r; dx <= r; dx++) {
                let q = clamp(center + vec2<i32>(dx, dy), vec2<i32>(0), noisy_size - vec2<i32>(1));
                let full = min(vec2<u32>(q) * scale, size - vec2<u32>(1u));
                if textureLoad(depth_texture, full, 0) <= 0.0 {
                    continue;
                }
                let dq = view_depth(full);
                let nq = world_normal(full);
                let spatial = exp(-f32(dx * dx + dy * dy) / (2.0 * max(f32(r * r), 1.0)));
                let depth_w = exp(-abs(dq - d0) / (0.02 * abs(d0) + 1.0e-4));
                let normal_w = pow(max(dot(n0, nq), 0.0), 16.0);
                let w = spatial * depth_w * normal_w;
                sum += w * textureLoad(noisy, q, 0).r;
                weights += w;
            }
        }
        if weights > 1.0e-6 {
            ao = sum / weights;
        } else {
            ao = textureLoad(noisy, center, 0).r;
        }
    }
    if settings.near_field != 0u {
        ao = min(ao, textureLoad(screen_space_ao, pixel, 0).r);
    }
    textureStore(ao_out, pixel, vec4<f32>(clamp(ao, 0.0, 1.0), 0.0, 0.0, 1.0));
}
