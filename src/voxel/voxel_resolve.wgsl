// Resolve: the frame's occupancy bits (static grid plus this frame's dynamic geometry) become the 3D voxel
// texture that sampling passes read (1 = occupied, 0 = empty), over the region that changed; then each mip
// level takes the maximum of its eight children, so that a zero texel at level l means 2^l cells per axis of
// empty space, for empty-space skipping.

struct ResolveParams {
    // Texels of the destination level to write: [region_min, region_max).
    region_min: vec3<u32>,
    _pad0: u32,
    region_max: vec3<u32>,
    _pad1: u32,
    // Cells of the grid (level 0).
    dims: vec3<u32>,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> resolve: ResolveParams;
@group(0) @binding(1) var<storage, read> occupancy: array<u32>;
#ifdef VOXEL_TEXTURE_R8
@group(0) @binding(2) var level0: texture_storage_3d<r8unorm, write>;
#else
@group(0) @binding(2) var level0: texture_storage_3d<r32float, write>;
#endif

@compute @workgroup_size(4, 4, 4)
fn resolve_occupancy(@builtin(global_invocation_id) gid: vec3<u32>) {
    let cell = resolve.region_min + gid;
    if any(cell >= resolve.region_max) {
        return;
    }
    // The texture is padded past the grid to a multiple of the coarsest mip's texel: empty there.
    var bit = 0u;
    if all(cell < resolve.dims) {
        let index = cell.x + resolve.dims.x * (cell.y + resolve.dims.y * cell.z);
        bit = (occupancy[index >> 5u] >> (index & 31u)) & 1u;
    }
    textureStore(level0, vec3<i32>(cell), vec4<f32>(f32(bit), 0.0, 0.0, 1.0));
}
