// Hybrid ambient occlusion, pass 2: the denoiser, a bilateral filter (depth- and normal-aware) over the
// temporal history, at full resolution, in one pass (`bilateral_cross` in hao_common.wgsl). Without the
// near field it writes the result straight into the texture PBR reads (at target_pixel(p): the texture is
// the target's size); with it, into the plugin's result texture with the minimum of Bevy's screen-space AO,
// which the apply pass then copies (Bevy's SSAO texture cannot be read and written in one pass).
#import bevy_hao::hao_common::{HaoSettings, bilateral_cross, target_pixel}

// The temporal pass's output: ao, view depth, packed normal, frames, packed in 64 bits (`load_history`)
@group(0) @binding(0) var history: texture_2d<u32>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
#ifdef NEAR_FIELD
@group(0) @binding(2) var screen_space_ao: texture_2d<f32>;
@group(0) @binding(3) var ao_out: texture_storage_2d<r32float, write>;
#else ifdef USE_R16FLOAT
@group(0) @binding(2) var ao_out: texture_storage_2d<r16float, write>;
#else
@group(0) @binding(2) var ao_out: texture_storage_2d<r32float, write>;
#endif

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn denoise(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid.xy >= textureDimensions(history)) {
        return;
    }
    var ao = bilateral_cross(history, gid.xy, settings.denoise_radius);
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
