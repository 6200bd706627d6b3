// Voxelization, pass 3 of 3, dispatched indirectly with one invocation per sub-triangle of the queued big
// triangles: a grid-spanning triangle's quarter of a million points are spread over as many invocations,
// not looped over by one. Each invocation finds its triangle by binary search in the scan's offsets, its
// sub-triangle by `sub_triangle`, and injects it. CPU twin: the loop of
// `bevy_hao::cpu::voxelize::voxelize_triangle`.
#import bevy_hao::voxelize_common::{
    LatticeRange, sub_triangle, COUNTER_BIG_TRIANGLES, COUNTER_POINTS_DISPATCHED,
}
#import bevy_hao::voxelize_pass::{
    params, big_triangles, counters, offsets, inject_sub_triangle, flush_counters, reset_counters,
}

@compute @workgroup_size(64)
fn expand(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local_index: u32,
) {
    reset_counters(local_index);
    workgroupBarrier();
    let g = (wg.x + wg.y * groups.x) * 64u + local_index;
    let base = params.counter_base;
    if g < atomicLoad(&counters[base + COUNTER_POINTS_DISPATCHED]) {
        let queued = min(atomicLoad(&counters[base + COUNTER_BIG_TRIANGLES]), arrayLength(&big_triangles));
        // The last triangle whose first sub-triangle is at or before g.
        var lo = 0u;
        var hi = queued;
        while hi - lo > 1u {
            let mid = (lo + hi) / 2u;
            if offsets[mid] <= g {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let t = big_triangles[lo];
        let range = LatticeRange(t.n, t.u_start, t.v_start, t.width, t.height, true);
        let sub = sub_triangle(range, g - offsets[lo]);
        if sub.valid {
            inject_sub_triangle(t.a, t.b, t.c, range, sub);
        }
    }
    workgroupBarrier();
    flush_counters(local_index, base);
}
