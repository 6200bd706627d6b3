// The irradiance probes (src/gi/probes.rs): a grid of probes following the camera, each gathering the
// lighting volume's light along rays through the voxels into the six faces of an ambient cube, blended into
// its history (`update_probes`, one of `phases` probes a frame in turn); then every probe of the window
// written into the irradiance volume Bevy's PBR samples, in its layout (`write_probes`). CPU twin:
// `bevy_hao::cpu::probes`.
#import bevy_hao::voxel_grid::{
    voxel_grid, MAX_MOVED_OCCLUDERS, voxel_occupied, voxel_texel, voxel_normal_at, march_cascades, level_position,
    finest_level_containing,
}
#import bevy_hao::gi_common::{unpack_rgb9e5, ProbeParams, ProbeRecord, window_slot, edge_fade, occupied_at}

@group(0) @binding(0) var<uniform> params: ProbeParams;
@group(0) @binding(1) var<storage, read_write> records: array<ProbeRecord>;
// The lighting volume (src/gi/gi_lighting.wgsl).
@group(0) @binding(2) var radiance: texture_3d<u32>;
// Bevy's irradiance volume: (counts.x, 2 counts.y, 3 counts.z) texels.
@group(0) @binding(3) var irradiance: texture_storage_3d<rgba16float, write>;
// With `params.far`: the far window and its probes' records (else unused).
@group(0) @binding(4) var<uniform> far_params: ProbeParams;
@group(0) @binding(5) var<storage, read> far_records: array<ProbeRecord>;
// The voxel levels are bound at group 2 (`bevy_hao::voxel_grid`).

// cpu/probes.rs: PROBE_STEPS, PROBE_MAX_DISTANCE, RELOCATE_MAX, FACE_REACH, FACE_STEPS, FACE_EXIT_STEPS
const PROBE_STEPS: u32 = 64u;
const PROBE_MAX_DISTANCE: f32 = 10000.0;
const RELOCATE_MAX: f32 = 0.45;
const FACE_REACH: f32 = 1.0;
const FACE_STEPS: u32 = 16u;
const FACE_EXIT_STEPS: u32 = 16u;
// cpu/lighting.rs: SHADOW_NORMAL_MIN
const SHADOW_NORMAL_MIN: f32 = 0.25;

const PI: f32 = 3.141592653589793;
const GOLDEN: f32 = 0.618034;
// The largest finite f16.
const F16_MAX: f32 = 65504.0;

// cpu/probes.rs: PROBE_FACES
const PROBE_FACES: array<vec3<f32>, 6> = array<vec3<f32>, 6>(
    vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(-1.0, 0.0, 0.0),
    vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, -1.0, 0.0),
    vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 0.0, -1.0),
);

fn probe_slot(q: vec3<i32>) -> u32 {
    return window_slot(params, q);
}

// cpu/probes.rs: pcg_hash
fn pcg_hash(x: u32) -> u32 {
    let state = x * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// cpu/probes.rs: probe_rotation
fn probe_rotation(slot: u32, seed: u32) -> vec2<f32> {
    let a = pcg_hash(slot ^ pcg_hash(seed));
    let b = pcg_hash(a);
    return vec2<f32>(f32(a >> 8u), f32(b >> 8u)) / 16777216.0;
}

// cpu/probes.rs: sphere_direction. Ray k of count over the sphere, turned by `rotation`.
fn sphere_direction(k: u32, count: u32, rotation: vec2<f32>) -> vec3<f32> {
    let u1 = fract((f32(k) + rotation.x) / f32(count));
    let z = 1.0 - 2.0 * u1;
    let r = sqrt(max(0.0, 1.0 - z * z));
    let phi = 2.0 * PI * fract(f32(k) * GOLDEN + rotation.y);
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

// cpu/probes.rs: hit_cell. The cell of a level's window a ray from `origin` enters `t` (world) along it.
fn hit_cell(level: u32, origin: vec3<f32>, dir: vec3<f32>, t: f32) -> vec3<i32> {
    let l = voxel_grid.levels[level];
    let p = level_position(level, origin) + dir * (t / l.cell_size + 1.0e-3);
    return clamp(vec3<i32>(floor(p)), vec3<i32>(0), vec3<i32>(l.dims) - vec3<i32>(1));
}

// cpu/probes.rs: neighbourhood_normal. The mean of the average normals of the occupied cells among a cell
// and its 26 neighbours.
fn neighbourhood_normal(level: u32, cell: vec3<i32>) -> vec3<f32> {
    let dims = vec3<i32>(voxel_grid.levels[level].dims);
    var sum = vec3<f32>(0.0);
    var count = 0u;
    for (var z = -1; z <= 1; z++) {
        for (var y = -1; y <= 1; y++) {
            for (var x = -1; x <= 1; x++) {
                let c = cell + vec3<i32>(x, y, z);
                if all(c >= vec3<i32>(0)) && all(c < dims) && voxel_occupied(level, c, 0u) {
                    sum += voxel_normal_at(level, c);
                    count += 1u;
                }
            }
        }
    }
    return sum / f32(max(count, 1u));
}

// cpu/probes.rs: relocate_probe. Where a probe at `p` gathers from: out of an occupied voxel along the
// average normal of the voxels around it, a cell at a time, at most RELOCATE_MAX spacings.
fn relocate_probe(p: vec3<f32>, spacing: f32) -> vec3<f32> {
    let level = finest_level_containing(p);
    if !occupied_at(level, p) {
        return p;
    }
    let normal = neighbourhood_normal(level, vec3<i32>(floor(level_position(level, p))));
    if length(normal) < SHADOW_NORMAL_MIN {
        return p;
    }
    let n = normalize(normal);
    let reach = RELOCATE_MAX * spacing;
    let steps = u32(max(floor(reach / voxel_grid.levels[level].cell_size), 1.0));
    let step = reach / f32(steps);
    for (var k = 1u; k <= steps; k++) {
        let q = p + n * (step * f32(k));
        if !occupied_at(level, q) {
            return q;
        }
    }
    return p + n * reach;
}

// cpu/probes.rs: face_origin. Where the face along `axis` gathers from, where the surfaces that read it are:
// half a cell in front of a voxel facing along `axis` that a march against it meets within FACE_REACH
// spacings; else past a run of occupied voxels a march along it meets within FACE_REACH spacings (half a
// cell at a time); where both stop, the nearer; else `p`.
fn face_origin(p: vec3<f32>, axis: vec3<f32>, spacing: f32) -> vec3<f32> {
    let start = finest_level_containing(p);
    let reach = FACE_REACH * spacing;
    let ahead = march_cascades(p, axis, start, 0.0, reach, FACE_STEPS);
    let behind = march_cascades(p, -axis, start, 0.0, reach, FACE_STEPS);
    if behind.x >= 0.0 && (ahead.x < 0.0 || behind.x < ahead.x) {
        let level = u32(behind.y);
        let normal = voxel_normal_at(level, hit_cell(level, p, -axis, behind.x));
        if length(normal) >= SHADOW_NORMAL_MIN && dot(normal, axis) > 0.0 {
            return p - axis * (behind.x - 0.5 * voxel_grid.levels[level].cell_size);
        }
    }
    if ahead.x < 0.0 {
        return p;
    }
    let level = u32(ahead.y);
    let step = 0.5 * voxel_grid.levels[level].cell_size;
    for (var k = 1u; k <= FACE_EXIT_STEPS; k++) {
        let q = p + axis * (ahead.x + step * f32(k));
        if !occupied_at(level, q) {
            return q;
        }
    }
    return p;
}

// cpu/probes.rs: probe_ray_radiance. The lit voxel a ray stops in, where its average normal faces the ray.
fn probe_ray_radiance(p: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let start = finest_level_containing(p);
    let hit = march_cascades(p, dir, start, 0.0, PROBE_MAX_DISTANCE, PROBE_STEPS);
    if hit.x < 0.0 {
        return vec3<f32>(0.0);
    }
    let level = u32(hit.y);
    let cell = hit_cell(level, p, dir, hit.x);
    if !(dot(voxel_normal_at(level, cell), dir) < 0.0) {
        return vec3<f32>(0.0);
    }
    return unpack_rgb9e5(textureLoad(radiance, voxel_texel(level, cell), 0).r);
}

// cpu/probes.rs: PROBE_LANES. The lanes that share a probe's rays: lane j of a probe traces its rays k = j,
// j + PROBE_LANES, ... (4 each at the default 32), so that a lane marches a few rays, not all of them.
const PROBE_LANES: u32 = 8u;
// src/gi/probes.rs: GROUP_PROBES. Probes a workgroup, of GROUP_SIZE invocations.
const GROUP_PROBES: u32 = 4u;
const GROUP_SIZE: u32 = GROUP_PROBES * PROBE_LANES;
// src/gi/probes.rs: PROBE_GROUPS_X. Workgroups along x of the dispatch (the rest along y).
const PROBE_GROUPS_X: u32 = 4096u;

// Each probe's face origins, and each lane's sums of its rays on the six faces.
var<workgroup> face_origins: array<array<vec3<f32>, 6>, GROUP_PROBES>;
var<workgroup> lane_faces: array<array<vec3<f32>, 6>, GROUP_SIZE>;

// cpu/probes.rs: MOVED_REACH_RADII
const MOVED_REACH_RADII: f32 = 2.0;

// cpu/probes.rs: moved_cap. The updates the probe at `p` holds at most this frame: `max_frames`, or near an
// occluder that moved (the voxel grid's list) `1 + (u - 1) / c`, with `u` the updates it takes it to move as
// far as it is from the probe (at least a spacing) and `c` the share of the probe's view it covers; 1 where
// it jumped (`u` at most 1).
fn moved_cap(p: vec3<f32>) -> u32 {
    var cap = max(params.max_frames, 1u);
    for (var i = 0u; i < min(voxel_grid.moved_count, MAX_MOVED_OCCLUDERS); i++) {
        let m = voxel_grid.moved[i];
        let center = (m.min + m.max) * 0.5;
        let half = (m.max - m.min) * 0.5;
        let r = max((half.x + half.y + half.z) / 3.0, 1.0e-4);
        let d = length(max(abs(p - center) - half, vec3<f32>(0.0)));
        if !(d <= MOVED_REACH_RADII * r + params.spacing) {
            continue;
        }
        let u = max(d, params.spacing) / (max(m.motion, 1.0e-6) * f32(max(params.phases, 1u)));
        let s = r / max(distance(p, center), r);
        let updates = select(1.0 + (u - 1.0) / (s * s), 1.0, u <= 1.0);
        cap = min(cap, u32(clamp(updates, 1.0, f32(cap))));
    }
    return cap;
}

// GROUP_PROBES probes a workgroup (this frame's share of them: one of `phases`), PROBE_LANES lanes each.
@compute @workgroup_size(GROUP_SIZE)
fn update_probes(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) index: u32) {
    let c = params.counts;
    let member = index / PROBE_LANES;
    let lane = index % PROBE_LANES;
    let i = ((group.y * PROBE_GROUPS_X + group.x) * GROUP_PROBES + member) * params.phases + params.phase;
    // A lane past the window's last probe does no work, but reaches the barriers as the others do.
    let live = i < c.x * c.y * c.z;
    let q = params.window_min + vec3<i32>(vec3<u32>(i % c.x, (i / c.x) % c.y, i / (c.x * c.y)));
    let slot = probe_slot(q);
    // Read by every lane before the barriers, written after them by lanes 0-5 of the probe.
    var record = ProbeRecord();
    if live {
        record = records[slot];
    }
    // A slot another lattice point held starts again.
    let frames = select(0u, record.frames, all(record.lattice == q));
    let n = min(frames + 1u, moved_cap(vec3<f32>(q) * params.spacing));
    // cpu/probes.rs: gather_probe, each face's rays from its origin (traced once from `p` for the faces that
    // gather there); lanes 0-5 find one face origin each.
    var p = vec3<f32>(0.0);
    if live {
        p = relocate_probe(vec3<f32>(q) * params.spacing, params.spacing);
        if lane < 6u {
            face_origins[member][lane] = face_origin(p, PROBE_FACES[lane], params.spacing);
        }
    }
    workgroupBarrier();
    // (Orders the record's reads above before the writes below in every lane: a workgroup barrier orders
    // only workgroup memory.)
    storageBarrier();
    let origins = face_origins[member];
    let rotation = probe_rotation(slot, params.seed);
    var faces = array<vec3<f32>, 6>();
    let rays = select(0u, params.rays, live);
    for (var k = lane; k < rays; k += PROBE_LANES) {
        let d = sphere_direction(k, params.rays, rotation);
        var here = vec3<f32>(0.0);
        var traced = false;
        for (var f = 0u; f < 6u; f++) {
            let w = dot(d, PROBE_FACES[f]);
            if w <= 0.0 {
                continue;
            }
            var l: vec3<f32>;
            if all(origins[f] == p) {
                if !traced {
                    here = probe_ray_radiance(p, d);
                    traced = true;
                }
                l = here;
            } else {
                l = probe_ray_radiance(origins[f], d);
            }
            faces[f] += l * w;
        }
    }
    lane_faces[index] = faces;
    workgroupBarrier();
    // The faces' sums over the probe's lanes in their order (lanes 0-5, one face each), then
    // cpu/probes.rs: blend_probe (a history of one update is that update, exactly).
    if live && lane < 6u {
        var sum = vec3<f32>(0.0);
        for (var j = 0u; j < PROBE_LANES; j++) {
            sum += lane_faces[member * PROBE_LANES + j][lane];
        }
        let update = sum * (4.0 / f32(params.rays));
        let old = record.faces[lane].xyz;
        records[slot].faces[lane] = vec4<f32>(select(old + (update - old) * (1.0 / f32(n)), update, n == 1u), 0.0);
    }
    if live && lane == 0u {
        records[slot].lattice = q;
        records[slot].frames = n;
        records[slot].seed = params.seed;
        records[slot].at_x = p.x;
        records[slot].at_y = p.y;
        records[slot].at_z = p.z;
    }
}

// cpu/far_probes.rs: far_texel. The far probe `w` (its index in the far window)'s face `f` as its texel
// holds it: its history within f16's range, faded toward the far window's edges (0 for a probe not yet
// gathered), as `write_probes` writes it.
fn far_texel(w: vec3<u32>, f: u32) -> vec3<f32> {
    let q = far_params.window_min + vec3<i32>(w);
    let record = far_records[window_slot(far_params, q)];
    let valid = all(record.lattice == q) && record.frames > 0u;
    return min(select(vec3<f32>(0.0), record.faces[f].xyz, valid), vec3<f32>(F16_MAX)) * edge_fade(far_params, q);
}

// cpu/probes.rs: sample_faces. The far volume's face `f` at the world point `p`, as Bevy's PBR samples it:
// trilinear between the eight far probes around `p`, clamped half a probe inside the far window.
fn far_face_at(p: vec3<f32>, f: u32) -> vec3<f32> {
    let r = vec3<f32>(far_params.counts);
    let stp = clamp(p / far_params.spacing - vec3<f32>(far_params.window_min) + 0.5, vec3<f32>(0.5), r - 0.5) - 0.5;
    let base = min(vec3<u32>(floor(stp)), far_params.counts - vec3<u32>(1u));
    let t = stp - vec3<f32>(base);
    var e = vec3<f32>(0.0);
    for (var corner = 0u; corner < 8u; corner++) {
        let o = vec3<u32>(corner & 1u, (corner >> 1u) & 1u, corner >> 2u);
        let weights = select(vec3<f32>(1.0) - t, t, o == vec3<u32>(1u));
        let w = weights.x * weights.y * weights.z;
        if w > 0.0 {
            e += w * far_texel(min(base + o, far_params.counts - vec3<u32>(1u)), f);
        }
    }
    return e;
}

@compute @workgroup_size(4, 4, 4)
fn write_probes(@builtin(global_invocation_id) w: vec3<u32>) {
    let c = params.counts;
    if any(w >= c) {
        return;
    }
    let q = params.window_min + vec3<i32>(w);
    let record = records[probe_slot(q)];
    let valid = all(record.lattice == q) && record.frames > 0u;
    let fade = edge_fade(params, q);
    // Bevy's layout: the + faces in the first counts.y rows, the - faces in the next; the x, y and z faces
    // in the three slabs along z.
    for (var f = 0u; f < 6u; f++) {
        let texel = vec3<u32>(w.x, w.y + (f & 1u) * c.y, w.z + (f >> 1u) * c.z);
        // Within f16's range: a light of absurd intensity saturates rather than turning the surfaces infinite.
        let own = min(select(vec3<f32>(0.0), record.faces[f].xyz, valid), vec3<f32>(F16_MAX));
        // cpu/far_probes.rs: near_texel. With a far window, what makes Bevy's mean of the two volumes the
        // near light faded into the far one.
        var face = own * fade;
        if params.far != 0u {
            face = own * (2.0 * fade) + far_face_at(vec3<f32>(q) * params.spacing, f) * (1.0 - 2.0 * fade);
        }
        textureStore(irradiance, texel, vec4<f32>(clamp(face, vec3<f32>(-F16_MAX), vec3<f32>(F16_MAX)), 1.0));
    }
}
