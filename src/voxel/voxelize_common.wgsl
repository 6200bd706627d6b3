// Point-tessellated voxelization: the functions shared by the voxelization passes. Each is the twin of the
// Rust function of the same name in `bevy_hao::cpu` (tessellation.rs, voxelize.rs, overlap.rs, grid.rs), with
// the same operations in the same order, so that the GPU and the CPU reference produce the same grids.
#define_import_path bevy_hao::voxelize_common

// tessellation.rs: MAX_SUBDIVISION, MAX_SUB_TRIANGLES_PER_TRIANGLE
const MAX_SUBDIVISION: u32 = 1048576u;
const MAX_SUB_TRIANGLES_PER_TRIANGLE: u32 = 268435456u;
// tessellation.rs: INLINE_SUB_TRIANGLES (sub-triangles a triangle may have and still be injected by the
// invocation that reads it, rather than queued for the expand pass)
const INLINE_SUB_TRIANGLES: u32 = 16u;
// voxelize.rs: CONSERVATIVE_PAD
const CONSERVATIVE_PAD: f32 = 0.00390625;
// tessellation.rs: CLIP_MAX_VERTICES
const CLIP_MAX_VERTICES: u32 = 9u;

const PLACEMENT_INSIDE: u32 = 0u;
const PLACEMENT_OUTSIDE: u32 = 1u;
const PLACEMENT_CROSSING: u32 = 2u;

const MODE_CENTROID: u32 = 0u;
const MODE_CONSERVATIVE: u32 = 1u;

// Counters, in the order of `VoxelizeCounters` (src/voxel/stats.rs).
const COUNTER_TRIANGLES: u32 = 0u;
const COUNTER_INVALID: u32 = 1u;
const COUNTER_DEGENERATE: u32 = 2u;
const COUNTER_OUTSIDE: u32 = 3u;
const COUNTER_OVERSIZE: u32 = 4u;
const COUNTER_SMALL: u32 = 5u;
const COUNTER_SUB_TRIANGLES: u32 = 6u;
const COUNTER_INJECTED: u32 = 7u;
const COUNTER_OVERLAP_TESTS: u32 = 8u;
const COUNTER_BIG_TRIANGLES: u32 = 9u;
const COUNTER_POINTS_REQUESTED: u32 = 10u;
const COUNTER_POINTS_DISPATCHED: u32 = 11u;
const COUNTER_BUDGET_EXCEEDED: u32 = 12u;
const COUNTER_EXPAND_POINTS: u32 = 13u;
const COUNTER_COUNT: u32 = 14u;
// Before the passes' counter blocks: the points spent so far this frame (every pass, both paths).
const FRAME_POINTS_USED: u32 = 0u;

// Per-pass settings (src/voxel/pipelines.rs: `GpuVoxelizeParams`). The pass injects into the box
// [region_min, region_max) of its level's lattice (cpu/voxelize.rs: `InjectionRegion`); lattice cell c is
// stored at voxel_base + linear_index((c - window_min + wrap) % dims): toroidally for a cascade level (wrap =
// window_min mod dims), as a plain grid otherwise (window_min = wrap = 0).
struct VoxelizeParams {
    region_min: vec3<i32>,
    mode: u32,
    region_max: vec3<i32>,
    gamma: f32,
    window_min: vec3<i32>,
    point_budget: u32,
    closed_max: vec3<i32>,
    store_counts: u32,
    wrap: vec3<u32>,
    counter_base: u32,
    dims: vec3<u32>,
    voxel_base: u32,
}

// src/voxel/pipelines.rs: `GpuLevelRegion`. A box of one level's lattice at one mip of the texture, how
// the level stores it (toroidally for a cascade), and where it sits in the texture.
struct LevelRegion {
    region_min: vec3<i32>,
    texture_z: u32,
    region_max: vec3<i32>,
    voxel_base: u32,
    window_min: vec3<i32>,
    pad_a: u32,
    wrap: vec3<u32>,
    pad_b: u32,
    // Cells of the level (its bits).
    dims: vec3<u32>,
    pad_c: u32,
    // Texels of the level at this mip (dims padded to the coarsest mip's texel).
    size: vec3<u32>,
    pad_d: u32,
}

// A triangle that needs more than one point or crosses the grid boundary, queued by the classify pass for
// the expand pass (src/voxel/pipelines.rs: `BigTriangle`).
struct BigTriangle {
    a: vec3<f32>,
    n: u32,
    b: vec3<f32>,
    u_start: u32,
    c: vec3<f32>,
    v_start: u32,
    width: u32,
    height: u32,
    sub_triangle_count: u32,
    _pad: u32,
}

// voxelize.rs: grid_space_position
fn grid_space_position(m: mat4x3<f32>, p: vec3<f32>) -> vec3<f32> {
    return m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3];
}

fn is_finite3(v: vec3<f32>) -> bool {
    // A NaN fails the comparison; an infinity exceeds the largest finite float.
    let a = abs(v);
    return a.x <= 3.4028235e38 && a.y <= 3.4028235e38 && a.z <= 3.4028235e38;
}

// voxelize.rs: triangle_is_degenerate (f32 here, f64 on the CPU)
fn triangle_is_degenerate(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>) -> bool {
    let c = cross(v1 - v0, v2 - v0);
    return all(c == vec3<f32>(0.0));
}

fn max3(v: vec3<f32>) -> f32 {
    return max(max(v.x, v.y), v.z);
}

// tessellation.rs: tessellation_factors + subdivision_count (T_1, T_2, T_3 of equation 1, then n)
fn subdivision_count(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, gamma: f32) -> u32 {
    let t1 = gamma * max3(abs(v0 - v1));
    let t2 = gamma * max3(abs(v1 - v2));
    let t3 = gamma * max3(abs(v0 - v2));
    let t = ceil(max(max(t1, t2), t3));
    if !(t >= 1.0) {
        return 1u;
    }
    if t > f32(MAX_SUBDIVISION) {
        return MAX_SUBDIVISION + 1u;
    }
    return u32(t);
}

// tessellation.rs: grid_placement, against the closed box [box_min, box_max]
fn grid_placement(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, box_min: vec3<f32>, box_max: vec3<f32>) -> u32 {
    let lo = min(min(v0, v1), v2);
    let hi = max(max(v0, v1), v2);
    if any(hi < box_min) || any(lo > box_max) {
        return PLACEMENT_OUTSIDE;
    }
    if all(lo >= box_min) && all(hi <= box_max) {
        return PLACEMENT_INSIDE;
    }
    return PLACEMENT_CROSSING;
}

// tessellation.rs: LatticeRange (width == 0 means the full triangle); `valid` is false when clipping left
// nothing (the Rust function returns None)
struct LatticeRange {
    n: u32,
    u_start: u32,
    v_start: u32,
    width: u32,
    height: u32,
    valid: bool,
}

// tessellation.rs: clipped_lattice_range
fn clipped_lattice_range(v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, n: u32, box_min: vec3<f32>, box_max: vec3<f32>) -> LatticeRange {
    var range = LatticeRange(n, 0u, 0u, 0u, 0u, false);
    let nf = f32(n);
    let inv_n = 1.0 / nf;
    var poly: array<vec2<f32>, 10>;
    var next: array<vec2<f32>, 10>;
    poly[0] = vec2<f32>(0.0, 0.0);
    poly[1] = vec2<f32>(nf, 0.0);
    poly[2] = vec2<f32>(0.0, nf);
    var count = 3u;
    for (var plane = 0u; plane < 6u; plane++) {
        let axis = plane >> 1u;
        let upper = (plane & 1u) == 1u;
        var c0: f32;
        var c1: f32;
        var c2: f32;
        if upper {
            c0 = box_max[axis] - v0[axis];
            c1 = -e1[axis] * inv_n;
            c2 = -e2[axis] * inv_n;
        } else {
            c0 = v0[axis] - box_min[axis];
            c1 = e1[axis] * inv_n;
            c2 = e2[axis] * inv_n;
        }
        var out = 0u;
        for (var k = 0u; k < count; k++) {
            let p = poly[k];
            let q = poly[(k + 1u) % count];
            let fp = c0 + c1 * p.x + c2 * p.y;
            let fq = c0 + c1 * q.x + c2 * q.y;
            if fp >= 0.0 {
                next[out] = p;
                out += 1u;
            }
            if (fp >= 0.0) != (fq >= 0.0) {
                let t = fp / (fp - fq);
                next[out] = p + (q - p) * t;
                out += 1u;
            }
        }
        count = min(out, CLIP_MAX_VERTICES);
        if count == 0u {
            return range;
        }
        for (var k = 0u; k < count; k++) {
            poly[k] = next[k];
        }
    }
    var lo = poly[0];
    var hi = poly[0];
    for (var k = 1u; k < count; k++) {
        lo = min(lo, poly[k]);
        hi = max(hi, poly[k]);
    }
    let u0 = u32(clamp(floor(lo.x) - 1.0, 0.0, nf));
    let u1 = u32(clamp(ceil(hi.x) + 1.0, 0.0, nf));
    let w0 = u32(clamp(floor(lo.y) - 1.0, 0.0, nf));
    let w1 = u32(clamp(ceil(hi.y) + 1.0, 0.0, nf));
    if u1 <= u0 || w1 <= w0 {
        return range;
    }
    range.u_start = u0;
    range.v_start = w0;
    range.width = u1 - u0;
    range.height = w1 - w0;
    range.valid = true;
    return range;
}

// tessellation.rs: LatticeRange::sub_triangle_count, saturated at 0xffffffff (the caller rejects counts
// above MAX_SUB_TRIANGLES_PER_TRIANGLE).
fn sub_triangle_count(range: LatticeRange) -> u32 {
    if range.width == 0u {
        if range.n > 65535u {
            return 0xffffffffu;
        }
        return range.n * range.n;
    }
    if range.width > 65535u || range.height > 32767u {
        return 0xffffffffu;
    }
    let wh = range.width * range.height;
    if wh > 0x7fffffffu {
        return 0xffffffffu;
    }
    return 2u * wh;
}

struct SubTriangle {
    i: u32,
    j: u32,
    up: bool,
    valid: bool,
}

// tessellation.rs: sub_triangle
fn sub_triangle(range: LatticeRange, s: u32) -> SubTriangle {
    let n = range.n;
    if range.width == 0u {
        let a = s / n;
        let b = s % n;
        if a + b < n {
            return SubTriangle(b, a, true, true);
        }
        return SubTriangle(n - 1u - b, n - 1u - a, false, true);
    }
    let cell = s >> 1u;
    let up = (s & 1u) == 0u;
    let i = range.u_start + cell % range.width;
    let j = range.v_start + cell / range.width;
    var inside: bool;
    if up {
        inside = i + j < n;
    } else {
        inside = i + j + 1u < n;
    }
    return SubTriangle(i, j, up, inside);
}

// tessellation.rs: sub_triangle_centroid (equation 2)
fn sub_triangle_centroid(v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, inv_3n: f32, sub: SubTriangle) -> vec3<f32> {
    var c = 1u;
    if !sub.up {
        c = 2u;
    }
    let a = f32(3u * sub.i + c) * inv_3n;
    let b = f32(3u * sub.j + c) * inv_3n;
    return v0 + e1 * a + e2 * b;
}

// tessellation.rs: lattice_point
fn lattice_point(v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, inv_n: f32, a: u32, b: u32) -> vec3<f32> {
    return v0 + e1 * (f32(a) * inv_n) + e2 * (f32(b) * inv_n);
}

// voxelize.rs: lattice_cell. The cell floor(p), or the one below on a closed face; false outside the
// region [region_min, region_max) or for NaN.
fn lattice_cell(p: vec3<f32>, region_min: vec3<i32>, region_max: vec3<i32>, closed_max: vec3<i32>, cell: ptr<function, vec3<i32>>) -> bool {
    let lo = vec3<f32>(region_min);
    let hi = vec3<f32>(region_max);
    if !(p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z) {
        return false;
    }
    let f = vec3<i32>(floor(p));
    let c = select(f, f - vec3<i32>(1), p == vec3<f32>(closed_max));
    *cell = c;
    return all(c >= region_min) && all(c < region_max);
}

fn linear_index(c: vec3<u32>, dims: vec3<u32>) -> u32 {
    return c.x + dims.x * (c.y + dims.y * c.z);
}

// Where lattice cell `c` (inside the level's window) is stored (see `VoxelizeParams`).
fn storage_index(c: vec3<i32>, window_min: vec3<i32>, wrap: vec3<u32>, dims: vec3<u32>, voxel_base: u32) -> u32 {
    let physical = (vec3<u32>(c - window_min) + wrap) % dims;
    return voxel_base + linear_index(physical, dims);
}

// overlap.rs: triangle_box_overlap, for the closed cell [cell, cell + 1]^3, in f32.
fn triangle_box_overlap(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, cell: vec3<i32>) -> bool {
    let half = 0.5;
    let center = vec3<f32>(cell) + vec3<f32>(0.5);
    let a = v0 - center;
    let b = v1 - center;
    let c = v2 - center;
    let lo = min(min(a, b), c);
    let hi = max(max(a, b), c);
    if any(lo > vec3<f32>(half)) || any(hi < vec3<f32>(-half)) {
        return false;
    }
    let e0 = v1 - v0;
    let e1 = v2 - v1;
    let e2 = v0 - v2;
    let normal = cross(e0, e1);
    let d = dot(normal, a);
    let r = half * (abs(normal.x) + abs(normal.y) + abs(normal.z));
    if d > r || d < -r {
        return false;
    }
    for (var k = 0u; k < 3u; k++) {
        var e: vec3<f32>;
        if k == 0u {
            e = e0;
        } else if k == 1u {
            e = e1;
        } else {
            e = e2;
        }
        for (var m = 0u; m < 3u; m++) {
            var axis: vec3<f32>;
            if m == 0u {
                axis = vec3<f32>(0.0, -e.z, e.y);
            } else if m == 1u {
                axis = vec3<f32>(e.z, 0.0, -e.x);
            } else {
                axis = vec3<f32>(-e.y, e.x, 0.0);
            }
            let pa = dot(axis, a);
            let pb = dot(axis, b);
            let pc = dot(axis, c);
            let rr = half * (abs(axis.x) + abs(axis.y) + abs(axis.z));
            if min(min(pa, pb), pc) > rr || max(max(pa, pb), pc) < -rr {
                return false;
            }
        }
    }
    return true;
}
