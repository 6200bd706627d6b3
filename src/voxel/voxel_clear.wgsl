// Clears a box of one level's static occupancy (and point counts and attribute sums) before the box is voxelized again: the
// slabs a cascade scrolled into, or where a static occluder changed. One invocation per lattice cell of the
// box, mapped to where the level stores it (see `VoxelizeParams`). CPU twin: a fresh occupancy.
#import bevy_hao::voxelize_common::storage_index
#import bevy_hao::voxelize_pass::{params, occupancy, point_counts}

@compute @workgroup_size(4, 4, 4)
fn clear_region(@builtin(global_invocation_id) gid: vec3<u32>) {
    let cell = params.region_min + vec3<i32>(gid);
    if any(cell >= params.region_max) {
        return;
    }
    let index = storage_index(cell, params.window_min, params.wrap, params.dims, params.voxel_base);
    atomicAnd(&occupancy[index >> 5u], ~(1u << (index & 31u)));
    for (var k = 0u; k < params.sample_words; k++) {
        atomicStore(&point_counts[index * params.sample_words + k], 0u);
    }
}
