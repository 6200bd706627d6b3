// Voxelization, pass 1 of 3: one invocation per triangle. Reads the triangle where Bevy keeps it (the mesh
// allocator's vertex and index slabs), skins it if its mesh is skinned (Bevy's joint matrices), moves it to
// grid space, picks its subdivision (equation 1's factors and the pattern: `subdivision`) and, for the
// common small triangle wholly inside the grid (at most 16 sub-triangles), injects it at once. Larger or boundary-
// crossing triangles are queued for the expand pass, which spreads their sub-triangles over many
// invocations. CPU twin: `bevy_hao::cpu::voxelize::voxelize_triangle`.
#import bevy_hao::voxelize_common::{
    BigTriangle, LatticeRange, SubTriangle, sub_triangle,
    triangle_is_degenerate, subdivision, rotate_to_apex, pack_strips, grid_placement, clipped_lattice_range, sub_triangle_count,
    PLACEMENT_INSIDE, PLACEMENT_OUTSIDE, PLACEMENT_CROSSING, MAX_SUBDIVISION, pn_patch, pn_gamma_scale,
    pn_bounds_min, pn_bounds_max, MAX_SUB_TRIANGLES_PER_TRIANGLE, INLINE_SUB_TRIANGLES,
    COUNTER_TRIANGLES, COUNTER_INVALID, COUNTER_DEGENERATE, COUNTER_OUTSIDE, COUNTER_OVERSIZE,
    COUNTER_SMALL, COUNTER_BIG_TRIANGLES, COUNTER_POINTS_REQUESTED, COUNTER_POINTS_DISPATCHED,
    COUNTER_BUDGET_EXCEEDED, FRAME_POINTS_USED,
}
#import bevy_hao::voxelize_vertices::{
    slab_group, triangle_indices, grid_corners, vertex_normal, triangle_albedo, NO_NORMALS,
}
#import bevy_hao::voxelize_pass::{
    params, big_triangles, counters, inject_sub_triangle, add_counter, flush_counters, reset_counters,
    keeps_attributes,
}

// A triangle small enough to inject here, kept across the workgroup's budget reservation.
struct InlineJob {
    v0: vec3<f32>,
    v1: vec3<f32>,
    v2: vec3<f32>,
    n0: vec3<f32>,
    n1: vec3<f32>,
    n2: vec3<f32>,
    albedo: vec3<u32>,
    apex: u32,
    range: LatticeRange,
    count: u32,
}

var<workgroup> inline_total: atomic<u32>;
var<workgroup> inline_accepted: atomic<u32>;
var<workgroup> inline_base: u32;

@compute @workgroup_size(#{VOXELIZE_WORKGROUP})
fn classify(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local_index: u32,
) {
    reset_counters(local_index);
    if local_index == 0u {
        atomicStore(&inline_total, 0u);
        atomicStore(&inline_accepted, 0u);
    }
    workgroupBarrier();
    let t = gid.x + gid.y * groups.x * 64u;
    let zero = vec3<f32>(0.0);
    var job = InlineJob(zero, zero, zero, zero, zero, zero, vec3<u32>(0u), 0u, LatticeRange(1u, 1u, 0u, 0u, 0u, 0u, 0u, false), 0u);
    if t < slab_group.triangle_count {
        job = classify_triangle(t);
    }
    // The points of the inline triangles count against the frame's budget like the expand pass's: the
    // workgroup reserves its total at once, and a triangle past the budget is dropped whole.
    var offset = 0u;
    if job.count > 0u {
        offset = atomicAdd(&inline_total, job.count);
    }
    workgroupBarrier();
    if local_index == 0u {
        let total = atomicLoad(&inline_total);
        inline_base = atomicAdd(&counters[FRAME_POINTS_USED], total);
        atomicAdd(&counters[params.counter_base + COUNTER_POINTS_REQUESTED], total);
    }
    workgroupBarrier();
    if job.count > 0u {
        let start = inline_base + offset;
        if start <= params.point_budget && job.count <= params.point_budget - start {
            atomicAdd(&inline_accepted, job.count);
            for (var s = 0u; s < job.count; s++) {
                inject_sub_triangle(job.v0, job.v1, job.v2, job.n0, job.n1, job.n2, job.albedo, job.apex, job.range, sub_triangle(job.range, s));
            }
        } else {
            atomicStore(&counters[params.counter_base + COUNTER_BUDGET_EXCEEDED], 1u);
        }
    }
    workgroupBarrier();
    if local_index == 0u {
        atomicAdd(&counters[params.counter_base + COUNTER_POINTS_DISPATCHED], atomicLoad(&inline_accepted));
    }
    flush_counters(local_index, params.counter_base);
}

fn classify_triangle(t: u32) -> InlineJob {
    let zero = vec3<f32>(0.0);
    var none = InlineJob(zero, zero, zero, zero, zero, zero, vec3<u32>(0u), 0u, LatticeRange(1u, 1u, 0u, 0u, 0u, 0u, 0u, false), 0u);
    add_counter(COUNTER_TRIANGLES, 1u);
    let tri = triangle_indices(t);
    let inst = tri.inst;
    let i0 = tri.index_a;
    let i1 = tri.index_b;
    let i2 = tri.index_c;
    var v0: vec3<f32>;
    var v1: vec3<f32>;
    var v2: vec3<f32>;
    if !(tri.valid && grid_corners(tri, &v0, &v1, &v2)) {
        add_counter(COUNTER_INVALID, 1u);
        return none;
    }
    if triangle_is_degenerate(v0, v1, v2) {
        add_counter(COUNTER_DEGENERATE, 1u);
        return none;
    }
    let box_min = vec3<f32>(params.region_min);
    let box_max = vec3<f32>(params.region_max);
    // A PN triangle (pn.rs: voxelize_pn_triangle_in_region): its patch's control box is placed against the
    // region, gamma is raised by the patch, and its lattice is never clipped (the patch may bulge out of the
    // flat triangle's clip). Normals that cannot be had make it flat.
    var n0 = zero;
    var n1 = zero;
    var n2 = zero;
    if inst.normal_offset != NO_NORMALS {
        n0 = vertex_normal(inst, i0);
        n1 = vertex_normal(inst, i1);
        n2 = vertex_normal(inst, i2);
        if dot(n0, n0) < 0.5 || dot(n1, n1) < 0.5 || dot(n2, n2) < 0.5 {
            n0 = zero;
            n1 = zero;
            n2 = zero;
        }
    }
    let pn = any(n0 != zero);
    var gamma = params.gamma;
    var placement: u32;
    if pn {
        let curved = pn_patch(v0, v1, v2, n0, n1, n2);
        let lo = pn_bounds_min(curved);
        let hi = pn_bounds_max(curved);
        if any(lo > box_max) || any(hi < box_min) {
            placement = PLACEMENT_OUTSIDE;
        } else if all(lo >= box_min) && all(hi <= box_max) {
            placement = PLACEMENT_INSIDE;
        } else {
            placement = PLACEMENT_CROSSING;
        }
        gamma = gamma * pn_gamma_scale(curved);
    } else {
        placement = grid_placement(v0, v1, v2, box_min, box_max);
    }
    if placement == PLACEMENT_OUTSIDE {
        add_counter(COUNTER_OUTSIDE, 1u);
        return none;
    }
    let sub = subdivision(v0, v1, v2, gamma, params.pattern);
    let n = sub.n;
    if n > MAX_SUBDIVISION {
        add_counter(COUNTER_OVERSIZE, 1u);
        return none;
    }
    var r0 = v0;
    var r1 = v1;
    var r2 = v2;
    rotate_to_apex(&r0, &r1, &r2, sub.apex);
    var range = LatticeRange(n, sub.strips, sub.diagonal, 0u, 0u, 0u, 0u, true);
    if placement != PLACEMENT_INSIDE && !pn {
        range = clipped_lattice_range(r0, r1 - r0, r2 - r0, n, box_min, box_max);
        if !range.valid {
            add_counter(COUNTER_OUTSIDE, 1u);
            return none;
        }
        range.strips = sub.strips;
        range.diagonal = sub.diagonal;
    }
    let count = sub_triangle_count(range);
    if count > MAX_SUB_TRIANGLES_PER_TRIANGLE {
        add_counter(COUNTER_OVERSIZE, 1u);
        return none;
    }
    var albedo = vec3<u32>(0u);
    if keeps_attributes() {
        albedo = triangle_albedo(tri);
    }
    if placement == PLACEMENT_INSIDE && count <= INLINE_SUB_TRIANGLES {
        // The common case: a triangle near a voxel in size (n <= 4); inject its few sub-triangles here.
        add_counter(COUNTER_SMALL, 1u);
        return InlineJob(v0, v1, v2, n0, n1, n2, albedo, sub.apex, range, count);
    }
    let slot = atomicAdd(&counters[params.counter_base + COUNTER_BIG_TRIANGLES], 1u);
    if slot < arrayLength(&big_triangles) {
        big_triangles[slot] = BigTriangle(
            v0, n, v1, range.u_start, v2, range.v_start, range.width, range.height, count, pack_strips(sub),
            n0, albedo.x, n1, albedo.y, n2, albedo.z,
        );
    }
    return none;
}
