// Copies what a view's ambient occlusion was computed from and what it came to into images that can be
// read back or shown: the AO PBR reads (HAO's, or Bevy's SSAO alone), the prepass depth and world normal
// (sample 0 with MSAA). The view's pixel p lies at p + ao_origin in the AO texture and at p + prepass_origin
// in the prepasses (the target's size); the images hold it at p.

// src/debug/images.rs: `GpuDebugCopy`
struct DebugCopy {
    ao_origin: vec2<u32>,
    prepass_origin: vec2<u32>,
}

@group(0) @binding(0) var ambient_occlusion: texture_2d<f32>;
#ifdef MULTISAMPLED
@group(0) @binding(1) var depth_texture: texture_depth_multisampled_2d;
@group(0) @binding(2) var normal_texture: texture_multisampled_2d<f32>;
#else
@group(0) @binding(1) var depth_texture: texture_depth_2d;
@group(0) @binding(2) var normal_texture: texture_2d<f32>;
#endif
@group(0) @binding(3) var<uniform> copy: DebugCopy;
@group(0) @binding(4) var ao_image: texture_storage_2d<r32float, write>;
@group(0) @binding(5) var depth_image: texture_storage_2d<r32float, write>;
@group(0) @binding(6) var normal_image: texture_storage_2d<rgba16float, write>;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn debug_copy(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.xy;
    let a = p + copy.ao_origin;
    let q = p + copy.prepass_origin;
    if any(p >= textureDimensions(ao_image)) || any(a >= textureDimensions(ambient_occlusion))
        || any(q >= textureDimensions(depth_texture)) {
        return;
    }
    textureStore(ao_image, p, vec4<f32>(textureLoad(ambient_occlusion, a, 0).r, 0.0, 0.0, 1.0));
    textureStore(depth_image, p, vec4<f32>(textureLoad(depth_texture, q, 0), 0.0, 0.0, 1.0));
    let n = textureLoad(normal_texture, q, 0).xyz * 2.0 - 1.0;
    textureStore(normal_image, p, vec4<f32>(n, 1.0));
}
