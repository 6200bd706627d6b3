// The lighting volume (src/gi/lighting.rs): each occupied voxel's outgoing diffuse radiance under Bevy's
// lights, each shadowed by a march through the voxels toward it, from the multi-valued voxels' average
// albedo and normal; written as rgb9e5 into an R32Uint texture laid out as the voxel texture's mip 0. Every
// frame one of `phases` slabs of 4-cell rows of each level, in turn. CPU twin: `bevy_hao::cpu::lighting`
// (`voxel_radiance`, `light_reaches`, `bounced_radiance`). With `bounce_feedback`, each voxel also takes the
// indirect light the probes held at the end of last frame (Bevy's volume as it shows it at the voxel), so
// that the light bounces on, one bounce more each time the voxels and the probes have been updated.
#import bevy_hao::voxel_grid::{
    voxel_grid, voxel_occupied, voxel_texel, voxel_albedo_at, voxel_normal_at, march_cascades, finest_level_containing,
}
#import bevy_hao::gi_common::{
    GiLight, light_incident, pack_rgb9e5, ProbeParams, ProbeRecord, window_slot, edge_fade, occupied_at,
}

// src/gi/lighting.rs: `GpuGiLightingParams`.
struct GiLightingParams {
    light_count: u32,
    // This frame's slab, of `phases`.
    phase: u32,
    phases: u32,
    // Rows of 4 cells along z of a level's window.
    blocks_z: u32,
    // The share of the probes' indirect light a voxel takes back (0: none, one bounce).
    bounce_feedback: f32,
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
}

@group(0) @binding(0) var<uniform> params: GiLightingParams;
@group(0) @binding(1) var<storage, read> lights: array<GiLight>;
@group(0) @binding(2) var radiance_out: texture_storage_3d<r32uint, write>;
// The near probes' window and records, as last frame left them (unread without `bounce_feedback`).
@group(0) @binding(3) var<uniform> probe_window: ProbeParams;
@group(0) @binding(4) var<storage, read> records: array<ProbeRecord>;
// The voxel levels are bound at group 2 (`bevy_hao::voxel_grid`).

// cpu/lighting.rs: SHADOW_START_CELLS, SHADOW_STEPS, SHADOW_NORMAL_MIN
const SHADOW_START_CELLS: f32 = 1.0;
const SHADOW_STEPS: u32 = 64u;
const SHADOW_NORMAL_MIN: f32 = 0.25;

const PI: f32 = 3.141592653589793;

// cpu/lighting.rs: cell_center. The centre of cell `cell` of a level's window, in world space.
fn cell_center(level: u32, cell: vec3<i32>) -> vec3<f32> {
    let l = voxel_grid.levels[level];
    return l.origin + (vec3<f32>(cell + l.window_min) + vec3<f32>(0.5)) * l.cell_size;
}

// cpu/lighting.rs: light_reaches. Whether the light from `to_light`, `distance` away, reaches the voxel at
// `center` of level `level` with average normal `normal`: a march from a cell off the centre along the normal
// and a cell along the ray that no run of occupied cells stops (out of visits counts as lit).
fn light_reaches(level: u32, center: vec3<f32>, normal: vec3<f32>, to_light: vec3<f32>, distance: f32) -> bool {
    let cell = voxel_grid.levels[level].cell_size;
    let lift = select(vec3<f32>(0.0), normalize(normal), length(normal) >= SHADOW_NORMAL_MIN);
    let origin = center + lift * (SHADOW_START_CELLS * cell);
    let d = min(distance, 1.0e30) - dot(lift, to_light) * SHADOW_START_CELLS * cell;
    if d <= SHADOW_START_CELLS * cell {
        return true;
    }
    return march_cascades(origin, to_light, level, SHADOW_START_CELLS, d, SHADOW_STEPS).x < 0.0;
}

// cpu/lighting.rs: voxel_radiance. albedo / pi * sum(E * max(n . l, 0)) over the lights that reach the voxel,
// with the average normal as it is.
fn voxel_radiance(level: u32, cell: vec3<i32>, albedo: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let center = cell_center(level, cell);
    var sum = vec3<f32>(0.0);
    for (var i = 0u; i < params.light_count; i++) {
        let incident = light_incident(lights[i], center);
        let facing = dot(normal, incident.to_light);
        let strongest = max(max(incident.illuminance.x, incident.illuminance.y), incident.illuminance.z);
        if !(facing > 0.0) || !(strongest > 0.0) {
            continue;
        }
        if light_reaches(level, center, normal, incident.to_light, incident.distance) {
            sum += albedo / PI * incident.illuminance * facing;
        }
    }
    return sum;
}

// cpu/lighting.rs: BOUNCE_LIFT_CELLS, BOUNCE_VISIBILITY_STEPS
const BOUNCE_LIFT_CELLS: f32 = 1.0;
const BOUNCE_VISIBILITY_STEPS: u32 = 16u;

// cpu/lighting.rs: probe_visible. Whether the probe that gathered from `at` sees the point `p` a voxel of
// level `level` and unit normal `n` reads it from: in front of the plane through the voxel's centre, outside
// the voxels, and a march from `p` toward it, from half a cell along, that no run of occupied cells stops
// before it.
fn probe_visible(level: u32, p: vec3<f32>, n: vec3<f32>, at: vec3<f32>) -> bool {
    let cell = voxel_grid.levels[level].cell_size;
    if dot(at - p, n) < -BOUNCE_LIFT_CELLS * cell {
        return false;
    }
    // A probe that gathered from inside a voxel sees both of its sides.
    if occupied_at(finest_level_containing(at), at) {
        return false;
    }
    let d = distance(p, at);
    if d <= 0.5 * cell {
        return true;
    }
    let start = finest_level_containing(p);
    let start_cells = 0.5 * cell / voxel_grid.levels[start].cell_size;
    return march_cascades(p, (at - p) / d, start, start_cells, d, BOUNCE_VISIBILITY_STEPS).x < 0.0;
}

// cpu/lighting.rs: window_faces. The faces of the eight probes around `p` (the point clamped half a probe
// inside the window, as Bevy's PBR samples it), each faded toward the window's edges (nothing for a slot
// another lattice point holds or one not yet gathered), weighted as Bevy's trilinear weights over the
// probes that see `p` (`probe_visible`; the weights renormalised over them, nothing where none does);
// nothing outside the window's bounds.
fn window_faces(level: u32, p: vec3<f32>, n: vec3<f32>) -> array<vec3<f32>, 6> {
    var e = array<vec3<f32>, 6>();
    let r = vec3<f32>(probe_window.counts);
    let lo = (vec3<f32>(probe_window.window_min) - vec3<f32>(0.5)) * probe_window.spacing;
    let hi = lo + r * probe_window.spacing;
    if any(p < lo) || any(p > hi) {
        return e;
    }
    let stp = clamp((p - lo) / (hi - lo) * r, vec3<f32>(0.5), r - vec3<f32>(0.5)) - vec3<f32>(0.5);
    let base = min(vec3<u32>(floor(stp)), probe_window.counts - vec3<u32>(1u));
    let t = stp - vec3<f32>(base);
    var total = 0.0;
    for (var corner = 0u; corner < 8u; corner++) {
        let o = vec3<u32>(corner & 1u, (corner >> 1u) & 1u, corner >> 2u);
        let weights = select(vec3<f32>(1.0) - t, t, o == vec3<u32>(1u));
        let w = weights.x * weights.y * weights.z;
        if w > 0.0 {
            let q = probe_window.window_min + vec3<i32>(min(base + o, probe_window.counts - vec3<u32>(1u)));
            let record = records[window_slot(probe_window, q)];
            if all(record.lattice == q) && record.frames > 0u {
                if !probe_visible(level, p, n, vec3<f32>(record.at_x, record.at_y, record.at_z)) {
                    continue;
                }
                let k = w * edge_fade(probe_window, q);
                for (var f = 0u; f < 6u; f++) {
                    e[f] += k * record.faces[f].xyz;
                }
            }
            total += w;
        }
    }
    if total > 0.0 {
        for (var f = 0u; f < 6u; f++) {
            e[f] *= 1.0 / total;
        }
    }
    return e;
}

// cpu/probes.rs: ambient_cube. sum(n_i^2 * face(sign n_i)) for the unit normal n.
fn ambient_cube(faces: array<vec3<f32>, 6>, n: vec3<f32>) -> vec3<f32> {
    let nn = n * n;
    let x = select(faces[1], faces[0], n.x >= 0.0);
    let y = select(faces[3], faces[2], n.y >= 0.0);
    let z = select(faces[5], faces[4], n.z >= 0.0);
    return nn.x * x + nn.y * y + nn.z * z;
}

// cpu/lighting.rs: bounced_radiance. `bounce_feedback` times the albedo times the irradiance over pi of the
// probes that see the point a cell off the voxel's centre along its normal (`window_faces`), read along the
// normal, times the normal's length (as the direct light, less where the points' normals disagree); nothing
// for a normal shorter than SHADOW_NORMAL_MIN.
fn bounced_radiance(level: u32, cell: vec3<i32>, albedo: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let length_n = length(normal);
    if !(params.bounce_feedback > 0.0) || length_n < SHADOW_NORMAL_MIN {
        return vec3<f32>(0.0);
    }
    let n = normal / length_n;
    let p = cell_center(level, cell) + n * (BOUNCE_LIFT_CELLS * voxel_grid.levels[level].cell_size);
    return albedo * (ambient_cube(window_faces(level, p, n), n) * (min(length_n, 1.0) * params.bounce_feedback));
}

@compute @workgroup_size(4, 4, 4)
fn light_voxels(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let per_level = (params.blocks_z + params.phases - 1u) / params.phases;
    let level = group.z / per_level;
    let row = (group.z % per_level) * params.phases + params.phase;
    if level >= voxel_grid.level_count || row >= params.blocks_z {
        return;
    }
    let c = vec3<u32>(group.x, group.y, row) * 4u + local;
    if any(c >= voxel_grid.levels[level].dims) {
        return;
    }
    let cell = vec3<i32>(c);
    var packed = 0u;
    if voxel_occupied(level, cell, 0u) {
        let albedo = voxel_albedo_at(level, cell);
        let normal = voxel_normal_at(level, cell);
        packed = pack_rgb9e5(
            voxel_radiance(level, cell, albedo.rgb, normal) + bounced_radiance(level, cell, albedo.rgb, normal)
        );
    }
    textureStore(radiance_out, voxel_texel(level, cell), vec4<u32>(packed, 0u, 0u, 0u));
}
