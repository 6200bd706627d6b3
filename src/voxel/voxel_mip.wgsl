// One mip level of the voxel texture: the maximum of the eight children one level down (the texture's size
// is a multiple of the coarsest texel, so every texel has exactly eight).

struct MipParams {
    region_min: vec3<u32>,
    _pad0: u32,
    region_max: vec3<u32>,
    _pad1: u32,
    // Size of the level read from.
    source_size: vec3<u32>,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> mip: MipParams;
@group(0) @binding(1) var source: texture_3d<f32>;
#ifdef VOXEL_TEXTURE_R8
@group(0) @binding(2) var destination: texture_storage_3d<r8unorm, write>;
#else
@group(0) @binding(2) var destination: texture_storage_3d<r32float, write>;
#endif

@compute @workgroup_size(4, 4, 4)
fn downsample_max(@builtin(global_invocation_id) gid: vec3<u32>) {
    let texel = mip.region_min + gid;
    if any(texel >= mip.region_max) {
        return;
    }
    var m = 0.0;
    for (var k = 0u; k < 8u; k++) {
        let child = min(texel * 2u + vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u), mip.source_size - vec3<u32>(1u));
        m = max(m, textureLoad(source, vec3<i32>(child), 0).r);
    }
    textureStore(destination, vec3<i32>(texel), vec4<f32>(m, 0.0, 0.0, 1.0));
}
