// Resolve: the frame's occupancy bits (static geometry plus this frame's dynamic geometry) become the 3D
// voxel texture that sampling passes read (1 = occupied, 0 = empty), over a box of one level that changed.
// The box is in the level's lattice; each cell goes where the level stores it (toroidally for a cascade),
// and the level sits at its own z in the texture (see `voxel_grid.wgsl`).

#import bevy_hao::voxelize_common::LevelRegion

@group(0) @binding(0) var<uniform> resolve: LevelRegion;
@group(0) @binding(1) var<storage, read> occupancy: array<u32>;
#ifdef VOXEL_TEXTURE_R8
@group(0) @binding(2) var level0: texture_storage_3d<r8unorm, write>;
#else
@group(0) @binding(2) var level0: texture_storage_3d<r32float, write>;
#endif

@compute @workgroup_size(4, 4, 4)
fn resolve_occupancy(@builtin(global_invocation_id) gid: vec3<u32>) {
    let cell = resolve.region_min + vec3<i32>(gid);
    if any(cell >= resolve.region_max) {
        return;
    }
    let physical = (vec3<u32>(cell - resolve.window_min) + resolve.wrap) % resolve.size;
    // A single grid's texture is padded past its cells: empty there.
    var bit = 0u;
    if all(physical < resolve.dims) {
        let index = resolve.voxel_base + physical.x + resolve.dims.x * (physical.y + resolve.dims.y * physical.z);
        bit = (occupancy[index >> 5u] >> (index & 31u)) & 1u;
    }
    let texel = vec3<i32>(physical + vec3<u32>(0u, 0u, resolve.texture_z));
    textureStore(level0, texel, vec4<f32>(f32(bit), 0.0, 0.0, 1.0));
}
