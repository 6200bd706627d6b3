// Hybrid ambient occlusion, pass 4, with the near field only: the result into the texture Bevy's PBR shading
// reads ambient occlusion from (the screen-space AO texture), so it dims indirect light only, in forward and
// deferred rendering. Without the near field the temporal pass writes there itself; with it, that pass reads
// Bevy's SSAO from that texture, so it cannot write there in the same pass.
// PBR reads it at each fragment's position in the render target, so the view's pixel p goes to
// target_pixel(p) (the texture is the target's size where the viewport does not start at its corner).
#import bevy_hao::hao_common::{HaoSettings, target_pixel}

@group(0) @binding(0) var result: texture_2d<f32>;
@group(0) @binding(1) var<uniform> settings: HaoSettings;
#ifdef USE_R16FLOAT
@group(0) @binding(2) var pbr_ambient_occlusion: texture_storage_2d<r16float, write>;
#else
@group(0) @binding(2) var pbr_ambient_occlusion: texture_storage_2d<r32float, write>;
#endif

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn apply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let at = target_pixel(settings, gid.xy);
    if any(gid.xy >= textureDimensions(result)) || any(at >= textureDimensions(pbr_ambient_occlusion)) {
        return;
    }
    textureStore(pbr_ambient_occlusion, at, vec4<f32>(textureLoad(result, gid.xy, 0).r, 0.0, 0.0, 1.0));
}
