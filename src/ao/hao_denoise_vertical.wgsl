// Hybrid ambient occlusion, pass 2b: the vertical half of the bilateral filter (`bilateral_line`) over the
// horizontal half's output, into the AO the apply pass writes out; with the near field on, the minimum with
// Bevy's screen-space AO. The background keeps the 1 the temporal pass stored there.
#import bevy_hao::hao_common::{HaoSettings, bilateral_line}

// ao, view depth, packed normal, frames: the history filtered horizontally
@group(0) @binding(0) var denoised: texture_2d<f32>;
@group(0) @binding(1) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(2) var<uniform> settings: HaoSettings;
@group(0) @binding(3) var ao_out: texture_storage_2d<r32float, write>;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn denoise_vertical(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(ao_out);
    if any(gid.xy >= size) {
        return;
    }
    var ao = bilateral_line(denoised, gid.xy, vec2<i32>(0, 1), settings.denoise_radius).x;
    if settings.near_field != 0u {
        ao = min(ao, textureLoad(screen_space_ao, gid.xy, 0).r);
    }
    textureStore(ao_out, gid.xy, vec4<f32>(clamp(ao, 0.0, 1.0), 0.0, 0.0, 1.0));
}
