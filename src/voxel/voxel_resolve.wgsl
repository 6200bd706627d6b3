// Resolve: the frame's occupancy bits (static geometry plus this frame's dynamic geometry) become the 3D
// voxel texture that sampling passes read (1 = occupied, 0 = empty), over a box or a list of bricks of one
// level that changed.
// The box is in the level's lattice; each cell goes where the level stores it (toroidally for a cascade),
// and the level sits at its own z in the texture (see `voxel_grid.wgsl`). Where the volume keeps attributes,
// the voxels' records become their average albedo and normal in two more textures of the same layout.

#import bevy_hao::voxelize_common::{LevelRegion, SAMPLE_WORDS, ALBEDO_SCALE, NORMAL_SCALE, region_texel, stored_texel}

@group(0) @binding(0) var<uniform> resolve: LevelRegion;
@group(0) @binding(1) var<storage, read> occupancy: array<u32>;
#ifdef VOXEL_TEXTURE_R8
@group(0) @binding(2) var level0: texture_storage_3d<r8unorm, write>;
#else
@group(0) @binding(2) var level0: texture_storage_3d<r32float, write>;
#endif
// The frame's per-voxel records (`VoxelizeParams::sample_words` words each) and the attribute textures
// (1x1x1 placeholders where attributes are not kept).
@group(0) @binding(3) var<storage, read> records: array<u32>;
@group(0) @binding(4) var albedo_texture: texture_storage_3d<rgba8unorm, write>;
@group(0) @binding(5) var normal_texture: texture_storage_3d<rgba8snorm, write>;
// The bricks of a brick pass (at the pass's mip, in units of BRICK_CELLS texels, in xyz; a placeholder for a box pass).
@group(0) @binding(6) var<storage, read> bricks: array<vec4<i32>>;

// attributes.rs: resolve_sample. The average albedo (rgb; a = 1 where the voxel has points) and normal of
// the record at `base`.
struct Resolved {
    albedo: vec4<f32>,
    normal: vec4<f32>,
}

fn resolve_sample(base: u32) -> Resolved {
    let count = records[base];
    if count == 0u {
        return Resolved(vec4<f32>(0.0), vec4<f32>(0.0));
    }
    let n = f32(count);
    let albedo = vec3<f32>(f32(records[base + 1u]), f32(records[base + 2u]), f32(records[base + 3u])) / (n * ALBEDO_SCALE);
    let sums = vec3<i32>(bitcast<i32>(records[base + 4u]), bitcast<i32>(records[base + 5u]), bitcast<i32>(records[base + 6u]));
    let normal = vec3<f32>(sums) / (n * NORMAL_SCALE);
    return Resolved(vec4<f32>(min(albedo, vec3<f32>(1.0)), 1.0), vec4<f32>(clamp(normal, vec3<f32>(-1.0), vec3<f32>(1.0)), 0.0));
}

@compute @workgroup_size(4, 4, 4)
fn resolve_occupancy(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    // Read whatever the pass (no branch on the uniform: lavapipe would compile a variant of the shader
    // for each value of a uniform that a branch tests, every frame).
    let brick = bricks[min(wid.z, arrayLength(&bricks) - 1u)].xyz;
    let t = region_texel(resolve, gid, local, brick);
    if t.w == 0 {
        return;
    }
    let cell = t.xyz;
    let physical = stored_texel(resolve, cell);
    // A single grid's texture is padded past its cells: empty there.
    var bit = 0u;
    var sample = Resolved(vec4<f32>(0.0), vec4<f32>(0.0));
    let attributes = resolve.sample_words == SAMPLE_WORDS;
    if all(physical < resolve.dims) {
        let index = resolve.voxel_base + physical.x + resolve.dims.x * (physical.y + resolve.dims.y * physical.z);
        bit = (occupancy[index >> 5u] >> (index & 31u)) & 1u;
        if attributes {
            sample = resolve_sample(index * SAMPLE_WORDS);
        }
    }
    let texel = vec3<i32>(physical + vec3<u32>(0u, 0u, resolve.texture_z));
    textureStore(level0, texel, vec4<f32>(f32(bit), 0.0, 0.0, 1.0));
    if attributes {
        textureStore(albedo_texture, texel, sample.albedo);
        textureStore(normal_texture, texel, sample.normal);
    }
}
