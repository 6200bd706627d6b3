// Voxelization, pass 1 of 3: one invocation per triangle. Reads the triangle where Bevy keeps it (the mesh
// allocator's vertex and index slabs), skins it if its mesh is skinned (Bevy's joint matrices), moves it to
// grid space, picks its subdivision (equation 1's factors and the pattern: `subdivision`) and, for the
// common small triangle wholly inside the grid (at most 16 sub-triangles), injects it at once. Larger or boundary-
// crossing triangles are queued for the expand pass, which spreads their sub-triangles over many
// invocations. CPU twin: `bevy_hao::cpu::voxelize::voxelize_triangle`.
#import bevy_hao::voxelize_common::{
    BigTriangle, LatticeRange, SubTriangle, sub_triangle, grid_space_position, is_finite3,
    triangle_is_degenerate, subdivision, rotate_to_apex, pack_strips, grid_placement, clipped_lattice_range, sub_triangle_count,
    PLACEMENT_INSIDE, PLACEMENT_OUTSIDE, PLACEMENT_CROSSING, MAX_SUBDIVISION, pn_patch, pn_gamma_scale,
    pn_bounds_min, pn_bounds_max, MAX_SUB_TRIANGLES_PER_TRIANGLE, INLINE_SUB_TRIANGLES,
    COUNTER_TRIANGLES, COUNTER_INVALID, COUNTER_DEGENERATE, COUNTER_OUTSIDE, COUNTER_OVERSIZE,
    COUNTER_SMALL, COUNTER_BIG_TRIANGLES, COUNTER_POINTS_REQUESTED, COUNTER_POINTS_DISPATCHED,
    COUNTER_BUDGET_EXCEEDED, FRAME_POINTS_USED,
}
#import bevy_hao::voxelize_pass::{
    params, big_triangles, counters, inject_sub_triangle, add_counter, flush_counters, reset_counters,
}

// One mesh instance (src/voxel/prepare.rs: `GpuOccluderInstance`).
struct OccluderInstance {
    grid_from_local: mat4x3<f32>,
    vertex_start: u32,
    vertex_count: u32,
    vertex_stride: u32,
    position_offset: u32,
    index_start: u32,
    index_format: u32,
    triangle_count: u32,
    first_triangle: u32,
    // Skinned instances: the first joint of the skin in `joint_matrices` (NO_SKIN: not skinned), the skin's
    // joint count, and the word offsets of the joint indices (Uint16x4) and weights (Float32x4) in a vertex.
    skin_index: u32,
    joint_count: u32,
    joint_offset: u32,
    weight_offset: u32,
    // Morphed instances: where their weights and displacements are, how many targets (0: not morphed), and
    // the vertices per target.
    morph_weights_offset: u32,
    morph_weight_count: u32,
    morph_targets_offset: u32,
    morph_vertex_count: u32,
    // PN instances: the word offset of the normals (Float32x3) in a vertex (NO_NORMALS: a flat instance).
    normal_offset: u32,
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
}

// The instances of this dispatch: those whose meshes live in the bound pair of slabs.
struct SlabGroup {
    first_instance: u32,
    instance_count: u32,
    triangle_count: u32,
    _pad: u32,
}

@group(0) @binding(0) var<storage, read> instances: array<OccluderInstance>;
@group(0) @binding(1) var<storage, read> vertices: array<u32>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
// In a storage buffer where the device allows (src/voxel/pipelines.rs: `params_in_storage`).
#ifdef VOXELIZE_PARAMS_IN_STORAGE
@group(0) @binding(3) var<storage, read> slab_group: SlabGroup;
#else
@group(0) @binding(3) var<uniform> slab_group: SlabGroup;
#endif
#ifdef VOXELIZE_SKINNING
// Bevy's joint matrices of this frame (`bevy::pbr::SkinUniforms::current_buffer`).
@group(0) @binding(4) var<storage, read> joint_matrices: array<mat4x4<f32>>;
#endif

#ifdef VOXELIZE_MORPH
// Bevy's `MorphAttributes`: one vertex's displacement by one target.
struct MorphTarget {
    position: vec3<f32>,
    pad_a: f32,
    normal: vec3<f32>,
    pad_b: f32,
    tangent: vec3<f32>,
    pad_c: f32,
}
// Bevy's morph weights of this frame (`MorphUniforms::current_buffer`) and the bound slab of morph targets.
@group(0) @binding(5) var<storage, read> morph_weights: array<f32>;
@group(0) @binding(6) var<storage, read> morph_targets: array<MorphTarget>;
#endif

const INDEX_NONE: u32 = 0u;
const NO_SKIN: u32 = #{NO_SKIN}u;
const INDEX_U16: u32 = 1u;
const NO_NORMALS: u32 = #{NO_NORMALS}u;

fn read_index(format: u32, element: u32) -> u32 {
    if format == INDEX_U16 {
        let word = indices[element >> 1u];
        if (element & 1u) == 0u {
            return word & 0xffffu;
        }
        return word >> 16u;
    }
    return indices[element];
}

fn read_position(inst: OccluderInstance, vertex: u32) -> vec3<f32> {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride + inst.position_offset;
    return vec3<f32>(bitcast<f32>(vertices[base]), bitcast<f32>(vertices[base + 1u]), bitcast<f32>(vertices[base + 2u]));
}

#ifdef VOXELIZE_SKINNING
// skinning.rs: skin_matrix (Bevy's `skin_model`, same order of operations). False if a joint is outside
// the skin or the buffer.
fn skin_matrix(inst: OccluderInstance, vertex: u32, m: ptr<function, mat4x4<f32>>) -> bool {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride;
    let packed_a = vertices[base + inst.joint_offset];
    let packed_b = vertices[base + inst.joint_offset + 1u];
    let joints = vec4<u32>(packed_a & 0xffffu, packed_a >> 16u, packed_b & 0xffffu, packed_b >> 16u);
    let w = base + inst.weight_offset;
    let weights = vec4<f32>(
        bitcast<f32>(vertices[w]), bitcast<f32>(vertices[w + 1u]), bitcast<f32>(vertices[w + 2u]), bitcast<f32>(vertices[w + 3u])
    );
    let limit = min(inst.joint_count, arrayLength(&joint_matrices) - min(inst.skin_index, arrayLength(&joint_matrices)));
    if any(joints >= vec4<u32>(limit)) {
        return false;
    }
    let s = inst.skin_index;
    *m = joint_matrices[s + joints.x] * weights.x + joint_matrices[s + joints.y] * weights.y
        + joint_matrices[s + joints.z] * weights.z + joint_matrices[s + joints.w] * weights.w;
    return true;
}
#endif

// skinning.rs: morph_position then skin_position, as Bevy draws the vertex: morphed, then for a skinned
// instance skinned from bind pose to world space. False if a joint or target is out of range (the triangle
// is then invalid).
fn vertex_position(inst: OccluderInstance, vertex: u32, p: ptr<function, vec3<f32>>) -> bool {
    var local = read_position(inst, vertex);
#ifdef VOXELIZE_MORPH
    // skinning.rs: morph_position (Bevy's `morph_vertex`, before skinning): each target's displacement
    // times its weight, added in target order, zero weights skipped.
    for (var i = 0u; i < inst.morph_weight_count; i++) {
        let w = inst.morph_weights_offset + i;
        let t = inst.morph_targets_offset + i * inst.morph_vertex_count + vertex;
        if w >= arrayLength(&morph_weights) || t >= arrayLength(&morph_targets) {
            return false;
        }
        let weight = morph_weights[w];
        if weight == 0.0 {
            continue;
        }
        local += weight * morph_targets[t].position;
    }
#endif
    *p = local;
#ifdef VOXELIZE_SKINNING
    if inst.skin_index != NO_SKIN {
        var m: mat4x4<f32>;
        if !skin_matrix(inst, vertex, &m) {
            return false;
        }
        *p = (m[0] * local.x + m[1] * local.y + m[2] * local.z + m[3]).xyz;
    }
#endif
    return true;
}

fn read_normal(inst: OccluderInstance, vertex: u32) -> vec3<f32> {
    let base = (inst.vertex_start + vertex) * inst.vertex_stride + inst.normal_offset;
    return vec3<f32>(bitcast<f32>(vertices[base]), bitcast<f32>(vertices[base + 1u]), bitcast<f32>(vertices[base + 2u]));
}

// The inverse transpose of m times n, up to a positive factor: m's cofactors, signed by its determinant
// (pn.rs normalizes `m.inverse().transpose() * n`).
fn normal_transform(m0: vec3<f32>, m1: vec3<f32>, m2: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let c0 = cross(m1, m2);
    let c1 = cross(m2, m0);
    let c2 = cross(m0, m1);
    let det = dot(m0, c0);
    return (c0 * n.x + c1 * n.y + c2 * n.z) * sign(det);
}

// n / |n|, or zero where that is not finite (glam's normalize_or_zero).
fn normalize_or_zero(n: vec3<f32>) -> vec3<f32> {
    let l = length(n);
    let u = n / l;
    if l > 0.0 && is_finite3(u) {
        return u;
    }
    return vec3<f32>(0.0);
}

// A PN instance's vertex normal in grid space: morphed by the targets' normal displacements, skinned by the
// vertex's skin matrix, then through the instance's grid_from_local. Zero if it cannot be had.
fn vertex_normal(inst: OccluderInstance, vertex: u32) -> vec3<f32> {
    var n = read_normal(inst, vertex);
#ifdef VOXELIZE_MORPH
    for (var i = 0u; i < inst.morph_weight_count; i++) {
        let w = inst.morph_weights_offset + i;
        let t = inst.morph_targets_offset + i * inst.morph_vertex_count + vertex;
        if w >= arrayLength(&morph_weights) || t >= arrayLength(&morph_targets) {
            return vec3<f32>(0.0);
        }
        let weight = morph_weights[w];
        if weight == 0.0 {
            continue;
        }
        n += weight * morph_targets[t].normal;
    }
#endif
#ifdef VOXELIZE_SKINNING
    if inst.skin_index != NO_SKIN {
        var m: mat4x4<f32>;
        if !skin_matrix(inst, vertex, &m) {
            return vec3<f32>(0.0);
        }
        n = normal_transform(m[0].xyz, m[1].xyz, m[2].xyz, n);
    }
#endif
    let g = inst.grid_from_local;
    return normalize_or_zero(normal_transform(g[0], g[1], g[2], n));
}

// The instance holding triangle `t` of this dispatch: the last whose first_triangle <= t.
fn find_instance(t: u32) -> u32 {
    var lo = slab_group.first_instance;
    var hi = slab_group.first_instance + slab_group.instance_count;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if instances[mid].first_triangle <= t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// A triangle small enough to inject here, kept across the workgroup's budget reservation.
struct InlineJob {
    v0: vec3<f32>,
    v1: vec3<f32>,
    v2: vec3<f32>,
    n0: vec3<f32>,
    n1: vec3<f32>,
    n2: vec3<f32>,
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
    var job = InlineJob(zero, zero, zero, zero, zero, zero, 0u, LatticeRange(1u, 1u, 0u, 0u, 0u, 0u, 0u, false), 0u);
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
                inject_sub_triangle(job.v0, job.v1, job.v2, job.n0, job.n1, job.n2, job.apex, job.range, sub_triangle(job.range, s));
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
    var none = InlineJob(zero, zero, zero, zero, zero, zero, 0u, LatticeRange(1u, 1u, 0u, 0u, 0u, 0u, 0u, false), 0u);
    add_counter(COUNTER_TRIANGLES, 1u);
    let inst = instances[find_instance(t)];
    let local = t - inst.first_triangle;
    var i0 = 3u * local;
    var i1 = i0 + 1u;
    var i2 = i0 + 2u;
    if inst.index_format != INDEX_NONE {
        let e = inst.index_start + 3u * local;
        i0 = read_index(inst.index_format, e);
        i1 = read_index(inst.index_format, e + 1u);
        i2 = read_index(inst.index_format, e + 2u);
    }
    if i0 >= inst.vertex_count || i1 >= inst.vertex_count || i2 >= inst.vertex_count {
        add_counter(COUNTER_INVALID, 1u);
        return none;
    }
    var p0: vec3<f32>;
    var p1: vec3<f32>;
    var p2: vec3<f32>;
    let skinned = vertex_position(inst, i0, &p0) && vertex_position(inst, i1, &p1) && vertex_position(inst, i2, &p2);
    let v0 = grid_space_position(inst.grid_from_local, p0);
    let v1 = grid_space_position(inst.grid_from_local, p1);
    let v2 = grid_space_position(inst.grid_from_local, p2);
    if !(skinned && is_finite3(v0) && is_finite3(v1) && is_finite3(v2)) {
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
    if placement == PLACEMENT_INSIDE && count <= INLINE_SUB_TRIANGLES {
        // The common case: a triangle near a voxel in size (n <= 4); inject its few sub-triangles here.
        add_counter(COUNTER_SMALL, 1u);
        return InlineJob(v0, v1, v2, n0, n1, n2, sub.apex, range, count);
    }
    let slot = atomicAdd(&counters[params.counter_base + COUNTER_BIG_TRIANGLES], 1u);
    if slot < arrayLength(&big_triangles) {
        big_triangles[slot] = BigTriangle(
            v0, n, v1, range.u_start, v2, range.v_start, range.width, range.height, count, pack_strips(sub),
            n0, 0u, n1, 0u, n2, 0u,
        );
    }
    return none;
}
