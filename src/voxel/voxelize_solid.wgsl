// Solid voxelization (Dong et al. 2004), after a pass has voxelized the surface: the inside of the
// occluders marked `VoxelFill::Solid` filled by the parity of crossings along z. CPU twin:
// `bevy_hao::cpu::solid::fill_solid_in_region`.
//
// `crossings` (one invocation per triangle of the pass's solid instances): every vertical line through a
// column centre of the region that the triangle crosses flips a bit at the first cell above the crossing
// (at the region's bottom cell for a crossing below the region; none for one above it) and the column's
// parity bit (every crossing, wherever it is). `fill` (one invocation per column of the region): a column
// with an odd parity (an occluder that is not closed) is left alone; otherwise each cell whose running
// parity from the region's bottom is odd is set. The crossings buffer holds a level's cells (as the level
// stores them) and then one bit per column; it is cleared before each pass.
#import bevy_hao::voxelize_common::{VoxelizeParams, storage_index}
#import bevy_hao::voxelize_vertices::{slab_group, triangle_indices, grid_corners}

#ifdef VOXELIZE_PARAMS_IN_STORAGE
@group(1) @binding(0) var<storage, read> solid: VoxelizeParams;
#else
@group(1) @binding(0) var<uniform> solid: VoxelizeParams;
#endif
@group(1) @binding(1) var<storage, read_write> crossings: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> occupancy: array<atomic<u32>>;

// solid.rs: edge_function. The same value from both triangles of an edge, up to sign.
fn edge_function(a: vec2<f32>, b: vec2<f32>, c: vec2<f32>) -> f32 {
    if b.x < a.x || (b.x == a.x && b.y < a.y) {
        return -((a.x - b.x) * (c.y - b.y) - (a.y - b.y) * (c.x - b.x));
    }
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

// solid.rs: owns_edge (top-left rule)
fn owns_edge(a: vec2<f32>, b: vec2<f32>) -> bool {
    let d = b - a;
    return d.y < 0.0 || (d.y == 0.0 && d.x < 0.0);
}

fn edge_accepts(w: f32, owns: bool) -> bool {
    return w > 0.0 || (w == 0.0 && owns);
}

// solid.rs: column_crossing
fn column_crossing(v0: vec3<f32>, v1_in: vec3<f32>, v2_in: vec3<f32>, c: vec2<f32>, z: ptr<function, f32>) -> bool {
    var v1 = v1_in;
    var v2 = v2_in;
    if edge_function(v0.xy, v1.xy, v2.xy) < 0.0 {
        v1 = v2_in;
        v2 = v1_in;
    }
    let p0 = v0.xy;
    let p1 = v1.xy;
    let p2 = v2.xy;
    let w0 = edge_function(p1, p2, c);
    let w1 = edge_function(p2, p0, c);
    let w2 = edge_function(p0, p1, c);
    let area = w0 + w1 + w2;
    if !(edge_accepts(w0, owns_edge(p1, p2)) && edge_accepts(w1, owns_edge(p2, p0)) && edge_accepts(w2, owns_edge(p0, p1)) && area > 0.0) {
        return false;
    }
    *z = (w0 * v0.z + w1 * v1.z + w2 * v2.z) / area;
    return true;
}

// solid.rs: crossing_cell, clamped to [lo, hi] before it becomes an integer (a huge z would overflow).
fn crossing_cell(z: f32, lo: i32, hi: i32) -> i32 {
    return i32(clamp(floor(z - 0.5) + 1.0, f32(lo), f32(hi)));
}

fn flip(index: u32) {
    atomicXor(&crossings[index >> 5u], 1u << (index & 31u));
}

fn bit(index: u32) -> bool {
    return ((atomicLoad(&crossings[index >> 5u]) >> (index & 31u)) & 1u) != 0u;
}

// The bit of column (i, j) after the level's cells.
fn column_bit(i: i32, j: i32) -> u32 {
    let cells = solid.dims.x * solid.dims.y * solid.dims.z;
    let cell = storage_index(vec3<i32>(i, j, solid.region_min.z), solid.window_min, solid.wrap, solid.dims, 0u);
    return cells + cell % (solid.dims.x * solid.dims.y);
}

@compute @workgroup_size(#{VOXELIZE_WORKGROUP})
fn crossings_pass(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = gid.x + gid.y * groups.x * #{VOXELIZE_WORKGROUP}u;
    if t >= slab_group.triangle_count {
        return;
    }
    let tri = triangle_indices(t);
    if tri.inst.solid == 0u || !tri.valid {
        return;
    }
    var v0: vec3<f32>;
    var v1: vec3<f32>;
    var v2: vec3<f32>;
    if !grid_corners(tri, &v0, &v1, &v2) {
        return;
    }
    // The region's columns whose centres lie in the triangle's box (clamped before converting).
    let lo = min(min(v0, v1), v2).xy;
    let hi = max(max(v0, v1), v2).xy;
    let first = vec2<i32>(max(ceil(lo - 0.5), vec2<f32>(solid.region_min.xy)));
    let last = vec2<i32>(min(floor(hi - 0.5), vec2<f32>(solid.region_max.xy - vec2<i32>(1))));
    for (var j = first.y; j <= last.y; j++) {
        for (var i = first.x; i <= last.x; i++) {
            var z: f32;
            if column_crossing(v0, v1, v2, vec2<f32>(f32(i) + 0.5, f32(j) + 0.5), &z) {
                flip(column_bit(i, j));
                let k = crossing_cell(z, solid.region_min.z, solid.region_max.z);
                if k < solid.region_max.z {
                    flip(storage_index(vec3<i32>(i, j, k), solid.window_min, solid.wrap, solid.dims, 0u));
                }
            }
        }
    }
}

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = solid.region_max - solid.region_min;
    if i32(gid.x) >= size.x || i32(gid.y) >= size.y {
        return;
    }
    let i = solid.region_min.x + i32(gid.x);
    let j = solid.region_min.y + i32(gid.y);
    if bit(column_bit(i, j)) {
        return;
    }
    var inside = false;
    for (var k = solid.region_min.z; k < solid.region_max.z; k++) {
        let cell = vec3<i32>(i, j, k);
        if bit(storage_index(cell, solid.window_min, solid.wrap, solid.dims, 0u)) {
            inside = !inside;
        }
        if inside {
            let index = storage_index(cell, solid.window_min, solid.wrap, solid.dims, solid.voxel_base);
            atomicOr(&occupancy[index >> 5u], 1u << (index & 31u));
        }
    }
}
