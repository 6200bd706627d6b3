// Copies what a view's ambient occlusion was computed from and what it came to into images that can be
// read back or shown: the AO PBR reads (HAO's, or Bevy's SSAO alone), the prepass depth and world normal.

@group(0) @binding(0) var ambient_occlusion: texture_2d<f32>;
@group(0) @binding(1) var depth_texture: texture_depth_2d;
@group(0) @binding(2) var normal_texture: texture_2d<f32>;
@group(0) @binding(3) var ao_image: texture_storage_2d<r32float, write>;
@group(0) @binding(4) var depth_image: texture_storage_2d<r32float, write>;
@group(0) @binding(5) var normal_image: texture_storage_2d<rgba16float, write>;

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn debug_copy(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid.xy >= textureDimensions(ao_image)) {
        return;
    }
    let p = gid.xy;
    textureStore(ao_image, p, vec4<f32>(textureLoad(ambient_occlusion, p, 0).r, 0.0, 0.0, 1.0));
    textureStore(depth_image, p, vec4<f32>(textureLoad(depth_texture, p, 0), 0.0, 0.0, 1.0));
    let n = textureLoad(normal_texture, p, 0).xyz * 2.0 - 1.0;
    textureStore(normal_image, p, vec4<f32>(n, 1.0));
}
