// Voxelization, pass 3 of 3, dispatched indirectly with one invocation per sub-triangle of the queued big
// triangles: a grid-spanning triangle's quarter of a million points are spread over as many invocations,
// not looped over by one. Each invocation finds its triangle by binary search in the scan's offsets, its
// sub-triangle by `sub_triangle`, and injects it. CPU twin: the loop of
// `bevy_hao::cpu::voxelize::voxelize_triangle`.
#import bevy_hao::voxelize_common::{
    LatticeRange, sub_triangle, COUNTER_BIG_TRIANGLES, COUNTER_EXPAND_POINTS,
}
#import bevy_hao::voxelize_pass::{
    params, big_triangles, counters, offsets, inject_sub_triangle, flush_counters, reset_counters,
}

var<workgroup> workgroup_first: u32;

// The last queued triangle in [lo, hi) whose first sub-triangle is at or before g.
fn find_triangle(g: u32, lo_in: u32, hi_in: u32) -> u32 {
    var lo = lo_in;
    var hi = hi_in;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if offsets[mid] <= g {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

@compute @workgroup_size(#{VOXELIZE_WORKGROUP})
fn expand(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local_index: u32,
) {
    reset_counters(local_index);
    let first = (wg.x + wg.y * groups.x) * 64u;
    let g = first + local_index;
    let base = params.counter_base;
    let queued = min(atomicLoad(&counters[base + COUNTER_BIG_TRIANGLES]), arrayLength(&big_triangles));
    let dispatched = atomicLoad(&counters[base + COUNTER_EXPAND_POINTS]);
    // One invocation finds the workgroup's first triangle; every triangle has at least one sub-triangle, so
    // invocation k's triangle is at most k triangles further.
    if local_index == 0u && first < dispatched {
        workgroup_first = find_triangle(first, 0u, queued);
    }
    workgroupBarrier();
    if g < dispatched {
        let start = workgroup_first;
        let lo = find_triangle(g, start, min(start + local_index + 1u, queued));
        let t = big_triangles[lo];
        // voxelize_common.wgsl: pack_strips
        let strips = t.strips & 0x1fffffffu;
        let diagonal = (t.strips >> 29u) & 1u;
        let apex = t.strips >> 30u;
        let range = LatticeRange(t.n, strips, diagonal, t.u_start, t.v_start, t.width, t.height, true);
        let sub = sub_triangle(range, g - offsets[lo]);
        if sub.valid {
            let albedo = vec3<u32>(t.albedo_a, t.albedo_b, t.albedo_c);
            inject_sub_triangle(t.a, t.b, t.c, t.normal_a, t.normal_b, t.normal_c, albedo, apex, range, sub);
        }
    }
    workgroupBarrier();
    flush_counters(local_index, base);
}
