// Point-tessellated voxelization: the functions shared by the voxelization passes. Each is the twin of the
// Rust function of the same name in `bevy_hao::cpu` (tessellation.rs, voxelize.rs, overlap.rs, grid.rs), with
// the same operations in the same order, so that the GPU and the CPU reference produce the same grids.
#define_import_path bevy_hao::voxelize_common

// `#{NAME}`: a shader def carrying the Rust constant's value (src/gpu.rs: `shader_defs`).
// tessellation.rs: MAX_SUBDIVISION, MAX_SUB_TRIANGLES_PER_TRIANGLE
const MAX_SUBDIVISION: u32 = #{MAX_SUBDIVISION}u;
const MAX_SUB_TRIANGLES_PER_TRIANGLE: u32 = #{MAX_SUB_TRIANGLES_PER_TRIANGLE}u;
// tessellation.rs: INLINE_SUB_TRIANGLES (sub-triangles a triangle may have and still be injected by the
// invocation that reads it, rather than queued for the expand pass)
const INLINE_SUB_TRIANGLES: u32 = #{INLINE_SUB_TRIANGLES}u;
// voxelize.rs: CONSERVATIVE_PAD
const CONSERVATIVE_PAD: f32 = 0.00390625;
// tessellation.rs: CLIP_MAX_VERTICES
const CLIP_MAX_VERTICES: u32 = 9u;
// tessellation.rs: STRIPS_MAX_COARSE
const STRIPS_MAX_COARSE: u32 = #{STRIPS_MAX_COARSE}u;
// pn.rs: MAX_PN_GAMMA_SCALE
const MAX_PN_GAMMA_SCALE: f32 = 4.0;

// attributes.rs: SAMPLE_WORDS, ALBEDO_SCALE, NORMAL_SCALE, MIRRORED_BIT, TWO_SIDED_BIT
const SAMPLE_WORDS: u32 = #{SAMPLE_WORDS}u;
const ALBEDO_SCALE: f32 = 255.0;
const NORMAL_SCALE: f32 = 1023.0;
const MIRRORED_BIT: u32 = #{MIRRORED_BIT}u;
const TWO_SIDED_BIT: u32 = #{TWO_SIDED_BIT}u;

// tessellation.rs: SubdivisionPattern (VoxelizeParams::pattern)
const PATTERN_UNIFORM: u32 = 0u;
const PATTERN_STRIPS: u32 = 1u;

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
const COUNTER_COUNT: u32 = #{COUNTER_COUNT}u;
// Before the passes' counter blocks: the points spent so far this frame (every pass, both paths).
const FRAME_POINTS_USED: u32 = #{FRAME_POINTS_USED}u;

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
    // Words of a voxel's record in `point_counts`: 0 (none), 1 (the point count) or SAMPLE_WORDS (the count
    // and the attribute sums; attributes.rs).
    sample_words: u32,
    wrap: vec3<u32>,
    counter_base: u32,
    dims: vec3<u32>,
    voxel_base: u32,
    pattern: u32,
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
}

// src/voxel/pipelines.rs: `GpuLevelRegion`. A box of one level's lattice at one mip of the texture, how
// the level stores it (toroidally for a cascade), and where it sits in the texture.
struct LevelRegion {
    region_min: vec3<i32>,
    texture_z: u32,
    region_max: vec3<i32>,
    voxel_base: u32,
    window_min: vec3<i32>,
    // 1 for a pass over a list of bricks (then the region is the window at this mip, a clip), 0 for a pass
    // over the region.
    brick_pass: u32,
    wrap: vec3<u32>,
    // Words of a voxel's record in the frame's `point_counts` (see `VoxelizeParams`; the resolve pass).
    sample_words: u32,
    // Cells of the level (its bits).
    dims: vec3<u32>,
    pad_c: u32,
    // Texels of the level at this mip (dims padded to the coarsest mip's texel).
    size: vec3<u32>,
    pad_d: u32,
}

// src/voxel/prepare/levels.rs: `BRICK_CELLS`. Texels along a side of a brick at the pass's mip: one
// workgroup of 4x4x4.
const BRICK_CELLS: i32 = 4;

// Where texel `texel` of the region's level (in its window, at the pass's mip) is stored: toroidally, the
// window texel plus the wrap taken back once past the size (both below it: one subtraction, no division).
// voxel_grid.wgsl: `wrapped_texel`.
fn stored_texel(region: LevelRegion, texel: vec3<i32>) -> vec3<u32> {
    let s = vec3<u32>(texel - region.window_min) + region.wrap;
    return select(s, s - region.size, s >= region.size);
}

// The texel (xyz) that invocation `gid` of a pass over `region` handles, and whether it handles one (w): a
// box pass covers the region from its min corner; a brick pass runs one workgroup per brick (`brick`, in
// units of BRICK_CELLS texels at the pass's mip), clipped to the region.
fn region_texel(region: LevelRegion, gid: vec3<u32>, local: vec3<u32>, brick: vec3<i32>) -> vec4<i32> {
    let texel = select(region.region_min + vec3<i32>(gid), brick * BRICK_CELLS + vec3<i32>(local), region.brick_pass != 0u);
    let inside = all(texel >= region.region_min) && all(texel < region.region_max);
    return vec4<i32>(texel, select(0, 1, inside));
}

// A triangle that needs more than one point or crosses the grid boundary, queued by the classify pass for
// the expand pass (src/voxel/pipelines.rs: `BIG_TRIANGLE_BYTES`): its vertices in their own order, its
// coarse lattice range, `strips` packed with the diagonal (bit 29) and the apex (bits 30-31), its
// grid-space vertex normals for a PN triangle (zero for a flat one), and its corner albedos
// (`triangle_albedo`).
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
    strips: u32,
    normal_a: vec3<f32>,
    albedo_a: u32,
    normal_b: vec3<f32>,
    albedo_b: u32,
    normal_c: vec3<f32>,
    albedo_c: u32,
}

// pn.rs: PnPatch. The ten control points of a PN triangle: b300, b030, b003, b210, b120, b021, b012, b102,
// b201, b111.
struct PnPatch {
    b: array<vec3<f32>, 10>,
}

// pn.rs: PnPatch::new (corners p, unit normals n)
fn pn_edge(pi: vec3<f32>, pj: vec3<f32>, ni: vec3<f32>) -> vec3<f32> {
    return (2.0 * pi + pj - dot(pj - pi, ni) * ni) / 3.0;
}

fn pn_patch(p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, n0: vec3<f32>, n1: vec3<f32>, n2: vec3<f32>) -> PnPatch {
    let b210 = pn_edge(p0, p1, n0);
    let b120 = pn_edge(p1, p0, n1);
    let b021 = pn_edge(p1, p2, n1);
    let b012 = pn_edge(p2, p1, n2);
    let b102 = pn_edge(p2, p0, n2);
    let b201 = pn_edge(p0, p2, n0);
    let e = (b210 + b120 + b021 + b012 + b102 + b201) / 6.0;
    let v = (p0 + p1 + p2) / 3.0;
    let b111 = e + (e - v) / 2.0;
    return PnPatch(array<vec3<f32>, 10>(p0, p1, p2, b210, b120, b021, b012, b102, b201, b111));
}

// pn.rs: PnPatch::point (barycentric weights w of corners 0, 1, 2)
fn pn_point(pn: PnPatch, w: vec3<f32>) -> vec3<f32> {
    let b = pn.b;
    let w0 = w.x;
    let w1 = w.y;
    let w2 = w.z;
    return b[0] * (w0 * w0 * w0)
        + b[1] * (w1 * w1 * w1)
        + b[2] * (w2 * w2 * w2)
        + b[3] * (3.0 * w0 * w0 * w1)
        + b[4] * (3.0 * w0 * w1 * w1)
        + b[8] * (3.0 * w0 * w0 * w2)
        + b[5] * (3.0 * w1 * w1 * w2)
        + b[7] * (3.0 * w0 * w2 * w2)
        + b[6] * (3.0 * w1 * w2 * w2)
        + b[9] * (6.0 * w0 * w1 * w2);
}

// pn.rs: PnPatch::gamma_scale. One edge direction: three times the largest net step along it over the
// chord, on the largest axis.
fn pn_direction(chord: vec3<f32>, s0: vec3<f32>, s1: vec3<f32>, s2: vec3<f32>, s3: vec3<f32>, s4: vec3<f32>, s5: vec3<f32>) -> f32 {
    let step = max(max(max(abs(s0), abs(s1)), max(abs(s2), abs(s3))), max(abs(s4), abs(s5)));
    let c = max3(abs(chord));
    if c > 0.0 {
        return 3.0 * max3(step) / c;
    }
    return 1.0;
}

fn pn_gamma_scale(pn: PnPatch) -> f32 {
    let b = pn.b;
    // b300 b030 b003 b210 b120 b021 b012 b102 b201 b111 = b[0..10]
    let r01 = pn_direction(b[1] - b[0], b[3] - b[0], b[4] - b[3], b[1] - b[4], b[9] - b[8], b[5] - b[9], b[6] - b[7]);
    let r02 = pn_direction(b[2] - b[0], b[8] - b[0], b[7] - b[8], b[2] - b[7], b[9] - b[3], b[6] - b[9], b[5] - b[4]);
    let r12 = pn_direction(b[2] - b[1], b[5] - b[1], b[6] - b[5], b[2] - b[6], b[9] - b[4], b[7] - b[9], b[8] - b[3]);
    let r = max(max(r01, r02), r12);
    // NaN or infinite: the most.
    if !(r <= MAX_PN_GAMMA_SCALE) {
        return MAX_PN_GAMMA_SCALE;
    }
    return max(r, 1.0);
}

// pn.rs: PnPatch::bounds
fn pn_bounds_min(pn: PnPatch) -> vec3<f32> {
    var lo = pn.b[0];
    for (var k = 1u; k < 10u; k++) {
        lo = min(lo, pn.b[k]);
    }
    return lo;
}

fn pn_bounds_max(pn: PnPatch) -> vec3<f32> {
    var hi = pn.b[0];
    for (var k = 1u; k < 10u; k++) {
        hi = max(hi, pn.b[k]);
    }
    return hi;
}

fn pack_strips(sub: Subdivision) -> u32 {
    return sub.strips | (sub.diagonal << 29u) | (sub.apex << 30u);
}

// voxelize.rs: grid_space_position
fn grid_space_position(m: mat4x3<f32>, p: vec3<f32>) -> vec3<f32> {
    return m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3];
}

// attributes.rs: unit_byte. x in [0, 1] to a byte, rounded to nearest; NaN gives 0.
fn unit_byte(x: f32) -> u32 {
    if !(x > 0.0) {
        return 0u;
    }
    if x >= 1.0 {
        return 255u;
    }
    // Capped: a driver may assume no NaN and let one through the tests above.
    return min(u32(floor(0.5 + ALBEDO_SCALE * x)), 255u);
}

// attributes.rs: pack_albedo
fn pack_albedo(c: vec3<f32>) -> u32 {
    return unit_byte(c.x) | (unit_byte(c.y) << 8u) | (unit_byte(c.z) << 16u);
}

// attributes.rs: unpack_albedo
fn unpack_albedo(p: u32) -> vec3<f32> {
    return vec3<f32>(f32(p & 255u), f32((p >> 8u) & 255u), f32((p >> 16u) & 255u)) / ALBEDO_SCALE;
}

// attributes.rs: corner_albedo
fn corner_albedo(base: u32, vertex_color: vec4<f32>) -> u32 {
    return pack_albedo(unpack_albedo(base) * vertex_color.xyz) & 0xffffffu;
}

// attributes.rs: apex_weights. The weights of corners 0, 1, 2 of lattice point (a, b) along the edges from
// corner `apex`.
fn apex_weights(apex: u32, a: f32, b: f32) -> vec3<f32> {
    var w = array<f32, 3>(0.0, 0.0, 0.0);
    w[apex % 3u] = 1.0 - a - b;
    w[(apex + 1u) % 3u] = a;
    w[(apex + 2u) % 3u] = b;
    return vec3<f32>(w[0], w[1], w[2]);
}

// attributes.rs: normalize_or_zero (glam's normalize_or_zero)
fn normalize_or_zero(n: vec3<f32>) -> vec3<f32> {
    let l = length(n);
    let u = n / l;
    if l > 0.0 && is_finite3(u) {
        return u;
    }
    return vec3<f32>(0.0);
}

// attributes.rs: face_normal. `albedo_a`: the first corner albedo, with MIRRORED_BIT.
fn face_normal(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, albedo_a: u32) -> vec3<f32> {
    let n = normalize_or_zero(cross(v1 - v0, v2 - v0));
    if (albedo_a & MIRRORED_BIT) != 0u {
        return -n;
    }
    return n;
}

// attributes.rs: interpolated_normal
fn interpolated_normal(n0: vec3<f32>, n1: vec3<f32>, n2: vec3<f32>, w: vec3<f32>) -> vec3<f32> {
    return normalize_or_zero(n0 * w.x + n1 * w.y + n2 * w.z);
}

// attributes.rs: normal_fixed. A component in [-1, 1] in fixed point, as the bits of an i32; NaN gives 0.
fn normal_fixed(x: f32) -> u32 {
    if !(x == x) {
        return 0u;
    }
    return bitcast<u32>(i32(floor(0.5 + NORMAL_SCALE * clamp(x, -1.0, 1.0))));
}

// attributes.rs: point_sample. What a point adds to its voxel's record after the count (no normal for a
// double-sided material).
fn point_sample(albedo: vec3<u32>, w: vec3<f32>, normal_in: vec3<f32>) -> array<u32, 6> {
    let c = unpack_albedo(albedo.x) * w.x + unpack_albedo(albedo.y) * w.y + unpack_albedo(albedo.z) * w.z;
    var normal = normal_in;
    if (albedo.x & TWO_SIDED_BIT) != 0u {
        normal = vec3<f32>(0.0);
    }
    return array<u32, 6>(
        unit_byte(c.x), unit_byte(c.y), unit_byte(c.z), normal_fixed(normal.x), normal_fixed(normal.y), normal_fixed(normal.z),
    );
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

// tessellation.rs: Subdivision
struct Subdivision {
    n: u32,
    strips: u32,
    diagonal: u32,
    apex: u32,
}

// tessellation.rs: rotate_to_apex, in place
fn rotate_to_apex(v0: ptr<function, vec3<f32>>, v1: ptr<function, vec3<f32>>, v2: ptr<function, vec3<f32>>, apex: u32) {
    let a = *v0;
    let b = *v1;
    let c = *v2;
    if apex == 1u {
        *v0 = b;
        *v1 = c;
        *v2 = a;
    } else if apex == 2u {
        *v0 = c;
        *v1 = a;
        *v2 = b;
    }
}

fn l_inf(v: vec3<f32>) -> f32 {
    return max3(abs(v));
}

// tessellation.rs: strips_fit
fn strips_fit(e1: vec3<f32>, e2: vec3<f32>, s: vec3<f32>, nc: u32, q: u32, diagonal: u32) -> bool {
    let d = f32(nc * q);
    if !(max(l_inf(e1), l_inf(e2)) <= d && l_inf(s) <= f32(nc)) {
        return false;
    }
    let far = f32(q - 1u);
    if diagonal == 0u {
        return l_inf(e2 + s) <= d && l_inf(e2 + s * far) <= d;
    }
    return l_inf(e1 - s) <= d && l_inf(e1 - s * far) <= d;
}

// tessellation.rs: strip_count (0 for None)
fn strip_count(e1: vec3<f32>, e2: vec3<f32>, s: vec3<f32>, nc: u32, diagonal: u32) -> u32 {
    let ncf = f32(nc);
    var w = e1;
    var t = s;
    var near = e2 + s;
    if diagonal != 0u {
        w = e2;
        t = -s;
        near = e1 - s;
    }
    var estimate = max(max(l_inf(e1), l_inf(e2)), l_inf(near)) / ncf;
    for (var axis = 0u; axis < 3u; axis++) {
        if w[axis] > 0.0 {
            let den = ncf - t[axis];
            if !(den > 0.0) {
                return 0u;
            }
            estimate = max(estimate, w[axis] / den);
        } else if w[axis] < 0.0 {
            let den = ncf + t[axis];
            if !(den > 0.0) {
                return 0u;
            }
            estimate = max(estimate, -w[axis] / den);
        }
    }
    let most = MAX_SUBDIVISION / nc;
    if !(estimate <= f32(most)) {
        return 0u;
    }
    var q = clamp(u32(ceil(estimate)), 2u, max(most, 2u));
    for (var k = 0u; k < 4u; k++) {
        if q > 2u && strips_fit(e1, e2, s, nc, q - 1u, diagonal) {
            q -= 1u;
        }
    }
    for (var k = 0u; k < 4u; k++) {
        if nc * q > MAX_SUBDIVISION {
            return 0u;
        }
        if strips_fit(e1, e2, s, nc, q, diagonal) {
            return q;
        }
        q += 1u;
    }
    return 0u;
}

// tessellation.rs: subdivision. Sub-triangle counts saturate at 0xffffffff here (u64 on the CPU); every strip
// count is below 2^31, so the choices are the same.
fn subdivision(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, gamma: f32, pattern: u32) -> Subdivision {
    let n = subdivision_count(v0, v1, v2, gamma);
    var best = Subdivision(n, 1u, 0u, 0u);
    if pattern == PATTERN_UNIFORM || n <= 1u || n > MAX_SUBDIVISION {
        return best;
    }
    let t1 = gamma * max3(abs(v0 - v1));
    let t2 = gamma * max3(abs(v1 - v2));
    let t3 = gamma * max3(abs(v0 - v2));
    var apex = 2u;
    if t2 <= t1 && t2 <= t3 {
        apex = 0u;
    } else if t3 <= t1 {
        apex = 1u;
    }
    var a = v0;
    var b = v1;
    var c = v2;
    rotate_to_apex(&a, &b, &c, apex);
    let e1 = (b - a) * gamma;
    let e2 = (c - a) * gamma;
    let s = (c - b) * gamma;
    let short = u32(max(ceil(l_inf(s)), 1.0));
    var best_count = 0xffffffffu;
    if n <= 65535u {
        best_count = n * n;
    }
    for (var k = 0u; k < 3u; k++) {
        var nc = short;
        if k == 1u {
            nc = short + 1u;
        } else if k == 2u {
            nc = 2u * short;
        }
        if nc > STRIPS_MAX_COARSE {
            continue;
        }
        // tessellation.rs: the lower bound that skips a candidate which cannot win. Where nc^2 (2 least - 1)
        // would overflow u32 it is skipped here and searched in vain on the CPU (no strip count reaches 2^31).
        let least = max(u32(floor(max(l_inf(e1), l_inf(e2)) / f32(nc))), 2u);
        let room = 0xffffffffu / (nc * nc);
        if least > room / 2u + (room & 1u) || nc * nc * (2u * least - 1u) >= best_count {
            continue;
        }
        for (var diagonal = 0u; diagonal < 2u; diagonal++) {
            let q = strip_count(e1, e2, s, nc, diagonal);
            if q == 0u {
                continue;
            }
            let count = nc * nc * (2u * q - 1u);
            if count < best_count {
                best_count = count;
                best = Subdivision(nc, q, diagonal, apex);
            }
        }
    }
    return best;
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
    strips: u32,
    diagonal: u32,
    u_start: u32,
    v_start: u32,
    width: u32,
    height: u32,
    valid: bool,
}

// tessellation.rs: clipped_lattice_range
fn clipped_lattice_range(v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, n: u32, box_min: vec3<f32>, box_max: vec3<f32>) -> LatticeRange {
    var range = LatticeRange(n, 1u, 0u, 0u, 0u, 0u, 0u, false);
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
    var coarse: u32;
    if range.width == 0u {
        if range.n > 65535u {
            return 0xffffffffu;
        }
        coarse = range.n * range.n;
    } else {
        if range.width > 65535u || range.height > 32767u {
            return 0xffffffffu;
        }
        let wh = range.width * range.height;
        if wh > 0x7fffffffu {
            return 0xffffffffu;
        }
        coarse = 2u * wh;
    }
    let pieces = 2u * range.strips - 1u;
    if coarse > 0xffffffffu / pieces {
        return 0xffffffffu;
    }
    return coarse * pieces;
}

struct SubTriangle {
    i: u32,
    j: u32,
    up: bool,
    piece: u32,
    valid: bool,
}

// tessellation.rs: sub_triangle
fn sub_triangle(range: LatticeRange, s_in: u32) -> SubTriangle {
    let n = range.n;
    let pieces = 2u * range.strips - 1u;
    let piece = s_in % pieces;
    let s = s_in / pieces;
    if range.width == 0u {
        let a = s / n;
        let b = s % n;
        if a + b < n {
            return SubTriangle(b, a, true, piece, true);
        }
        return SubTriangle(n - 1u - b, n - 1u - a, false, piece, true);
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
    return SubTriangle(i, j, up, piece, inside);
}

// The fine-lattice point k steps from a coarse triangle's apex along e1 (L) or e2 (R).
fn strip_l(apex: vec2<u32>, up: bool, k: u32) -> vec2<u32> {
    if up {
        return vec2<u32>(apex.x + k, apex.y);
    }
    return vec2<u32>(apex.x - k, apex.y);
}

fn strip_r(apex: vec2<u32>, up: bool, k: u32) -> vec2<u32> {
    if up {
        return vec2<u32>(apex.x, apex.y + k);
    }
    return vec2<u32>(apex.x, apex.y - k);
}

// tessellation.rs: sub_triangle_corners
fn sub_triangle_corners(range: LatticeRange, sub: SubTriangle) -> array<vec2<u32>, 3> {
    let q = range.strips;
    var apex = vec2<u32>((sub.i + 1u) * q, (sub.j + 1u) * q);
    if sub.up {
        apex = vec2<u32>(sub.i * q, sub.j * q);
    }
    let up = sub.up;
    if sub.piece == 0u {
        return array<vec2<u32>, 3>(apex, strip_l(apex, up, 1u), strip_r(apex, up, 1u));
    }
    let k = (sub.piece + 1u) / 2u;
    let odd = (sub.piece & 1u) == 1u;
    if range.diagonal == 0u {
        if odd {
            return array<vec2<u32>, 3>(strip_l(apex, up, k), strip_r(apex, up, k), strip_r(apex, up, k + 1u));
        }
        return array<vec2<u32>, 3>(strip_l(apex, up, k), strip_r(apex, up, k + 1u), strip_l(apex, up, k + 1u));
    }
    if odd {
        return array<vec2<u32>, 3>(strip_l(apex, up, k), strip_r(apex, up, k), strip_l(apex, up, k + 1u));
    }
    return array<vec2<u32>, 3>(strip_r(apex, up, k), strip_r(apex, up, k + 1u), strip_l(apex, up, k + 1u));
}

// tessellation.rs: sub_triangle_centroid (equation 2); inv_3n = 1 / (3 n q)
fn sub_triangle_centroid(v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, inv_3n: f32, range: LatticeRange, sub: SubTriangle) -> vec3<f32> {
    let c = sub_triangle_corners(range, sub);
    let sum = c[0] + c[1] + c[2];
    let a = f32(sum.x) * inv_3n;
    let b = f32(sum.y) * inv_3n;
    return v0 + e1 * a + e2 * b;
}

// attributes.rs: centroid_weights. The weights of corners 0, 1, 2 at a sub-triangle's centroid.
fn centroid_weights(range: LatticeRange, sub: SubTriangle, apex: u32, inv_3n: f32) -> vec3<f32> {
    let c = sub_triangle_corners(range, sub);
    let sum = c[0] + c[1] + c[2];
    return apex_weights(apex, f32(sum.x) * inv_3n, f32(sum.y) * inv_3n);
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
