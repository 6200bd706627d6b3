// Hybrid ambient occlusion, pass 3: the result into the texture Bevy's PBR shading reads ambient occlusion
// from (the screen-space AO texture), so it dims indirect light only, in forward and deferred rendering.

@group(0) @binding(0) var result: texture_2d<f32>;
#ifdef USE_R16FLOAT
@group(0) @binding(1) var pbr_ambient_occlusion: texture_storage_2d<r16float, write>;
#else
@group(0) @binding(1) var pbr_ambient_occlusion: texture_storage_2d<r32float, write>;
#endif

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn apply(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid.xy >= textureDimensions(pbr_ambient_occlusion)) {
        return;
    }
    textureStore(pbr_ambient_occlusion, gid.xy, vec4<f32>(textureLoad(result, gid.xy, 0).r, 0.0, 0.0, 1.0));
}
