// One mip level of one level of the voxel texture, over a box of its texels (in the level's lattice, at
// this mip) or a list of bricks of them: the maximum of the eight children one mip down. A level's window
// starts on a multiple of the coarsest mip's texel, so the children of a stored texel are the stored
// children of its lattice texel.

#import bevy_hao::voxelize_common::{LevelRegion, region_texel, stored_texel}

@group(0) @binding(0) var<uniform> mip: LevelRegion;
@group(0) @binding(1) var source: texture_3d<f32>;
#ifdef VOXEL_TEXTURE_R8
@group(0) @binding(2) var destination: texture_storage_3d<r8unorm, write>;
#else
@group(0) @binding(2) var destination: texture_storage_3d<r32float, write>;
#endif
// The bricks of a brick pass (at the pass's mip, in units of BRICK_CELLS texels, in xyz; a placeholder for
// a box pass).
@group(0) @binding(3) var<storage, read> bricks: array<vec4<i32>>;

@compute @workgroup_size(4, 4, 4)
fn downsample_max(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    // Read whatever the pass (no branch on the uniform: lavapipe would compile a variant of the shader
    // for each value of a uniform that a branch tests, every frame).
    let brick = bricks[min(wid.z, arrayLength(&bricks) - 1u)].xyz;
    let t = region_texel(mip, gid, local, brick);
    if t.w == 0 {
        return;
    }
    let texel = t.xyz;
    let physical = stored_texel(mip, texel);
    let source_size = mip.size * 2u;
    var m = 0.0;
    for (var k = 0u; k < 8u; k++) {
        var child = min(physical * 2u + vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u), source_size - vec3<u32>(1u));
        child.z += mip.texture_z * 2u;
        m = max(m, textureLoad(source, vec3<i32>(child), 0).r);
    }
    let out = vec3<i32>(physical + vec3<u32>(0u, 0u, mip.texture_z));
    textureStore(destination, out, vec4<f32>(m, 0.0, 0.0, 1.0));
}
