// What the three voxelization passes (classify, scan, expand) share: the bind group of the pass (group 1:
// settings, the occupancy grid and point counts being written, the queue of big triangles, the statistics
// counters and the scan's offsets), the injection of one sub-triangle, and workgroup-aggregated counters. CPU twin of the injection: the two match arms of
// `bevy_hao::cpu::voxelize::voxelize_triangle`.
#define_import_path bevy_hao::voxelize_pass

#import bevy_hao::voxelize_common::{
    VoxelizeParams, BigTriangle, LatticeRange, SubTriangle, sub_triangle_centroid, sub_triangle_corners,
    lattice_point, rotate_to_apex, PnPatch, pn_patch, pn_point,
    lattice_cell, storage_index, triangle_box_overlap, MODE_CENTROID, CONSERVATIVE_PAD,
    SAMPLE_WORDS, point_sample, centroid_weights, face_normal, interpolated_normal,
    COUNTER_SUB_TRIANGLES, COUNTER_INJECTED, COUNTER_OVERLAP_TESTS, COUNTER_COUNT,
}

// In a storage buffer where the device allows (src/voxel/pipelines.rs: `params_in_storage`): lavapipe
// compiles and keeps a shader variant per set of uniform values, a leak when they change every frame.
#ifdef VOXELIZE_PARAMS_IN_STORAGE
@group(1) @binding(0) var<storage, read> params: VoxelizeParams;
#else
@group(1) @binding(0) var<uniform> params: VoxelizeParams;
#endif
@group(1) @binding(1) var<storage, read_write> occupancy: array<atomic<u32>>;
// Per-voxel records of `params.sample_words` words: the point count, then (attributes.rs) the albedo and
// normal sums.
@group(1) @binding(2) var<storage, read_write> point_counts: array<atomic<u32>>;
@group(1) @binding(3) var<storage, read_write> big_triangles: array<BigTriangle>;
@group(1) @binding(4) var<storage, read_write> counters: array<atomic<u32>>;
// Exclusive prefix sums of the big triangles' sub-triangle counts (written by the scan pass).
@group(1) @binding(5) var<storage, read_write> offsets: array<u32>;

var<workgroup> local_counters: array<atomic<u32>, 14>;

fn reset_counters(local_index: u32) {
    if local_index < COUNTER_COUNT {
        atomicStore(&local_counters[local_index], 0u);
    }
}

fn add_counter(counter: u32, value: u32) {
    atomicAdd(&local_counters[counter], value);
}

// After a workgroup barrier: one global atomic per counter and workgroup.
fn flush_counters(local_index: u32, base: u32) {
    if local_index < COUNTER_COUNT {
        let v = atomicLoad(&local_counters[local_index]);
        if v != 0u {
            atomicAdd(&counters[base + local_index], v);
        }
    }
}

// Whether the pass accumulates attributes (then each point's `point_sample` is added).
fn keeps_attributes() -> bool {
    return params.sample_words == SAMPLE_WORDS;
}

// grid.rs: VoxelOccupancy::inject_point. Sets the voxel, counts the point, and adds its sample where the
// pass keeps attributes.
fn inject_voxel(index: u32, sample: array<u32, 6>) {
    atomicOr(&occupancy[index >> 5u], 1u << (index & 31u));
    if params.sample_words != 0u {
        let base = index * params.sample_words;
        atomicAdd(&point_counts[base], 1u);
        if keeps_attributes() {
            for (var k = 0u; k < 6u; k++) {
                if sample[k] != 0u {
                    atomicAdd(&point_counts[base + 1u + k], sample[k]);
                }
            }
        }
    }
}

const NO_SAMPLE: array<u32, 6> = array<u32, 6>(0u, 0u, 0u, 0u, 0u, 0u);

// One sub-triangle of the grid-space triangle v0 v1 v2 (in its own vertex order), subdivided as `range` says
// after rotating vertex `apex` first: flat, or on the PN patch of the vertex normals n0 n1 n2 (zero for a
// flat triangle); its points sample the corner albedos `albedo` (`triangle_albedo`).
fn inject_sub_triangle(
    v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, n0: vec3<f32>, n1: vec3<f32>, n2: vec3<f32>,
    albedo: vec3<u32>, apex: u32, range: LatticeRange, sub: SubTriangle,
) {
    if any(n0 != vec3<f32>(0.0)) {
        inject_pn_sub_triangle(pn_patch(v0, v1, v2, n0, n1, n2), n0, n1, n2, albedo, apex, range, sub);
        return;
    }
    add_counter(COUNTER_SUB_TRIANGLES, 1u);
    var r0 = v0;
    var r1 = v1;
    var r2 = v2;
    rotate_to_apex(&r0, &r1, &r2, apex);
    let e1 = r1 - r0;
    let e2 = r2 - r0;
    let fine = f32(range.n * range.strips);
    let inv_3n = 1.0 / (3.0 * fine);
    var sample = NO_SAMPLE;
    if keeps_attributes() {
        sample = point_sample(albedo, centroid_weights(range, sub, apex, inv_3n), face_normal(v0, v1, v2, albedo.x));
    }
    if params.mode == MODE_CENTROID {
        let p = sub_triangle_centroid(r0, e1, e2, inv_3n, range, sub);
        var cell: vec3<i32>;
        if lattice_cell(p, params.region_min, params.region_max, params.closed_max, &cell) {
            inject_voxel(storage_index(cell, params.window_min, params.wrap, params.dims, params.voxel_base), sample);
            add_counter(COUNTER_INJECTED, 1u);
        }
        return;
    }
    // Conservative: the cells of the sub-triangle's padded bounds, each tested against the parent (in its own
    // vertex order, as the ground truth tests it).
    let inv_n = 1.0 / fine;
    let corners = sub_triangle_corners(range, sub);
    let a = lattice_point(r0, e1, e2, inv_n, corners[0].x, corners[0].y);
    let b = lattice_point(r0, e1, e2, inv_n, corners[1].x, corners[1].y);
    let c = lattice_point(r0, e1, e2, inv_n, corners[2].x, corners[2].y);
    inject_overlapped_cells(a, b, c, v0, v1, v2, sample);
}

// Conservative injection: the cells of the piece a b c's padded bounds (voxelize.rs:
// conservative_candidate_cells) that the triangle t0 t1 t2 overlaps (the parent, for a flat triangle; the
// piece itself, for a PN one).
fn inject_overlapped_cells(
    a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, t0: vec3<f32>, t1: vec3<f32>, t2: vec3<f32>, sample: array<u32, 6>,
) {
    let lo = max(vec3<i32>(floor(min(min(a, b), c) - vec3<f32>(CONSERVATIVE_PAD))), params.region_min);
    let hi = min(vec3<i32>(floor(max(max(a, b), c) + vec3<f32>(CONSERVATIVE_PAD))), params.region_max - vec3<i32>(1));
    var tests = 0u;
    var hits = 0u;
    for (var z = lo.z; z <= hi.z; z++) {
        for (var y = lo.y; y <= hi.y; y++) {
            for (var x = lo.x; x <= hi.x; x++) {
                let cell = vec3<i32>(x, y, z);
                tests += 1u;
                if triangle_box_overlap(t0, t1, t2, cell) {
                    inject_voxel(storage_index(cell, params.window_min, params.wrap, params.dims, params.voxel_base), sample);
                    hits += 1u;
                }
            }
        }
    }
    add_counter(COUNTER_OVERLAP_TESTS, tests);
    add_counter(COUNTER_INJECTED, hits);
}

// pn.rs: the corner of a sub-triangle on the patch: lattice point (a, b) of `range.n * range.strips`
// segments, along the edges from corner `apex`, as weights of corners 0, 1, 2.
fn pn_corner(pn: PnPatch, apex: u32, c: vec2<u32>, inv_n: f32) -> vec3<f32> {
    let a = f32(c.x) * inv_n;
    let b = f32(c.y) * inv_n;
    var w = array<f32, 3>(0.0, 0.0, 0.0);
    w[apex % 3u] = 1.0 - a - b;
    w[(apex + 1u) % 3u] = a;
    w[(apex + 2u) % 3u] = b;
    return pn_point(pn, vec3<f32>(w[0], w[1], w[2]));
}

// pn.rs: the loop of voxelize_pn_triangle_in_region. The sub-triangle's corners moved onto the patch; its
// centroid injected, or (conservative) the cells its curved piece overlaps; its points sample the albedo and
// the vertex normals n0 n1 n2 at the centroid's weights.
fn inject_pn_sub_triangle(
    pn: PnPatch, n0: vec3<f32>, n1: vec3<f32>, n2: vec3<f32>, albedo: vec3<u32>, apex: u32, range: LatticeRange,
    sub: SubTriangle,
) {
    add_counter(COUNTER_SUB_TRIANGLES, 1u);
    let inv_n = 1.0 / f32(range.n * range.strips);
    var sample = NO_SAMPLE;
    if keeps_attributes() {
        let w = centroid_weights(range, sub, apex, 1.0 / (3.0 * f32(range.n * range.strips)));
        sample = point_sample(albedo, w, interpolated_normal(n0, n1, n2, w));
    }
    let corners = sub_triangle_corners(range, sub);
    let a = pn_corner(pn, apex, corners[0], inv_n);
    let b = pn_corner(pn, apex, corners[1], inv_n);
    let c = pn_corner(pn, apex, corners[2], inv_n);
    if params.mode == MODE_CENTROID {
        var cell: vec3<i32>;
        if lattice_cell((a + b + c) / 3.0, params.region_min, params.region_max, params.closed_max, &cell) {
            inject_voxel(storage_index(cell, params.window_min, params.wrap, params.dims, params.voxel_base), sample);
            add_counter(COUNTER_INJECTED, 1u);
        }
        return;
    }
    inject_overlapped_cells(a, b, c, a, b, c, sample);
}
