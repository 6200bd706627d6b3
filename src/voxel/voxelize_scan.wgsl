// Voxelization, pass 2 of 3: one workgroup. Exclusive prefix sums of the queued big triangles' sub-triangle
// counts, so that the expand pass can map one invocation to one sub-triangle; then the expand pass's
// dispatch size, clamped to what is left of the frame's point budget (equation 5's estimate sizes the budget
// on the CPU; this is where it is enforced exactly).
#import bevy_hao::voxelize_common::{
    COUNTER_BIG_TRIANGLES, COUNTER_POINTS_REQUESTED, COUNTER_POINTS_DISPATCHED, COUNTER_BUDGET_EXCEEDED,
    COUNTER_EXPAND_POINTS, FRAME_POINTS_USED,
}
#import bevy_hao::voxelize_pass::{params, big_triangles, counters, offsets}

// The expand pass's dispatch size (x, y, z). In a group of its own: the expand pass reads the same buffer
// as indirect arguments, which excludes binding it there as storage.
@group(2) @binding(0) var<storage, read_write> expand_dispatch: array<u32, 3>;

const SCAN_WIDTH: u32 = 256u;
// Invocations per expand workgroup (voxelize_expand.wgsl).
const EXPAND_WORKGROUP: u32 = #{VOXELIZE_WORKGROUP}u;

var<workgroup> partial: array<u32, 256>;

fn saturating_add(a: u32, b: u32) -> u32 {
    if a > 0xffffffffu - b {
        return 0xffffffffu;
    }
    return a + b;
}

@compute @workgroup_size(256)
fn scan(@builtin(local_invocation_index) local: u32) {
    let base = params.counter_base;
    let queued = min(atomicLoad(&counters[base + COUNTER_BIG_TRIANGLES]), arrayLength(&big_triangles));
    var carry = 0u;
    for (var start = 0u; start < queued; start += SCAN_WIDTH) {
        let i = start + local;
        var value = 0u;
        if i < queued {
            value = big_triangles[i].sub_triangle_count;
        }
        partial[local] = value;
        workgroupBarrier();
        // Hillis-Steele inclusive scan, saturating.
        for (var step = 1u; step < SCAN_WIDTH; step <<= 1u) {
            var add = 0u;
            if local >= step {
                add = partial[local - step];
            }
            workgroupBarrier();
            partial[local] = saturating_add(partial[local], add);
            workgroupBarrier();
        }
        if i < queued {
            offsets[i] = saturating_add(carry, partial[local] - value);
        }
        carry = saturating_add(carry, partial[SCAN_WIDTH - 1u]);
        workgroupBarrier();
    }
    if local == 0u {
        let used = atomicLoad(&counters[FRAME_POINTS_USED]);
        let left = params.point_budget - min(used, params.point_budget);
        let dispatched = min(carry, left);
        // Requested and dispatched count both paths: the classify pass added its inline points.
        atomicStore(&counters[base + COUNTER_POINTS_REQUESTED], saturating_add(atomicLoad(&counters[base + COUNTER_POINTS_REQUESTED]), carry));
        atomicStore(&counters[base + COUNTER_POINTS_DISPATCHED], saturating_add(atomicLoad(&counters[base + COUNTER_POINTS_DISPATCHED]), dispatched));
        atomicStore(&counters[base + COUNTER_EXPAND_POINTS], dispatched);
        atomicStore(&counters[FRAME_POINTS_USED], saturating_add(used, dispatched));
        if dispatched < carry {
            atomicStore(&counters[base + COUNTER_BUDGET_EXCEEDED], 1u);
        }
        let groups = (dispatched + EXPAND_WORKGROUP - 1u) / EXPAND_WORKGROUP;
        expand_dispatch[0] = min(groups, 65535u);
        expand_dispatch[1] = (groups + 65534u) / 65535u;
        expand_dispatch[2] = 1u;
    }
}
