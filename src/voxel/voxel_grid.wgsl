// The voxel grid as every sampling pass sees it: the one bind group that `voxel/` prepares
// (src/voxel/bindings.rs: `VoxelGridBindings`), with the levels of the volume (one for a single grid, one
// per cascade), their 3D texture, and the march through them. Import it and add the bind group at
// VOXEL_GRID_GROUP. CPU twin: `bevy_hao::cpu::march` (`TraceLevel`, `March`, `march_cascades`).
#define_import_path bevy_hao::voxel_grid

const MAX_VOXEL_LEVELS: u32 = 8u;

// src/voxel/bindings.rs: `GpuVoxelLevel`. Lattice cell c of a level covers [c, c + 1] * cell_size + origin
// in world space; the level holds the window [window_min, window_min + dims) of it, stored toroidally in
// the texture (texel (c - window_min + wrap) % size, at z + texture_z).
struct VoxelLevel {
    origin: vec3<f32>,
    cell_size: f32,
    window_min: vec3<i32>,
    texture_z: u32,
    wrap: vec3<u32>,
    pad_a: u32,
    // Cells of the window (the march's box).
    dims: vec3<u32>,
    pad_b: u32,
    // Texels of mip 0 per axis (dims rounded up to the coarsest mip's texel).
    size: vec3<u32>,
    pad_c: u32,
}

// src/voxel/bindings.rs: `GpuMovedOccluder` (CPU twin: `cpu::temporal::MovedVoxels`). An occluder whose
// voxels changed in the last few frames: the box around it now and last frame, and how far its points moved
// (world units; UNKNOWN_MOTION where not known).
struct MovedOccluder {
    min: vec3<f32>,
    motion: f32,
    max: vec3<f32>,
    pad: f32,
}

// src/voxel/bindings.rs: `MAX_MOVED_OCCLUDERS`, `UNKNOWN_MOTION`
const MAX_MOVED_OCCLUDERS: u32 = 8u;
const UNKNOWN_MOTION: f32 = 1.0e30;

// src/voxel/bindings.rs: `GpuVoxelGrid`.
struct VoxelGrid {
    levels: array<VoxelLevel, MAX_VOXEL_LEVELS>,
    // 0 while there is no grid.
    level_count: u32,
    mip_levels: u32,
    // How many of `moved` are valid.
    moved_count: u32,
    // 1 where `voxel_albedo` and `voxel_normal` hold the voxels' attributes (VoxelVolume::attributes).
    attributes: u32,
    // Where the voxels changed in the last few frames: the dynamic occluders that moved (turned, deformed,
    // appeared or went), the static ones added, changed or taken out.
    moved: array<MovedOccluder, MAX_MOVED_OCCLUDERS>,
}

@group(2) @binding(0) var voxel_texture: texture_3d<f32>;
@group(2) @binding(1) var<uniform> voxel_grid: VoxelGrid;
// Multi-valued voxels (src/cpu/attributes.rs), mip 0 only, in the layout of `voxel_texture`: the average
// linear albedo (a: 1 where the voxel has points) and the average normal (length 1 where its points agree,
// toward 0 where they cancel). 1x1x1 placeholders unless `voxel_grid.attributes` is 1.
@group(2) @binding(2) var voxel_albedo: texture_3d<f32>;
@group(2) @binding(3) var voxel_normal: texture_3d<f32>;

// cpu/march.rs: CASCADE_BLEND_CELLS
const CASCADE_BLEND_CELLS: f32 = 8.0;

// cpu/march.rs: safe_inverse. 1 / d with zero components replaced by a huge value of the same sign.
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    let big = vec3<f32>(1.0e30);
    let s = select(vec3<f32>(-1.0), vec3<f32>(1.0), d >= vec3<f32>(0.0));
    return select(1.0 / d, s * big, abs(d) < vec3<f32>(1.0e-30));
}

// cpu/march.rs: ray_box. The [t_enter, t_exit] of a ray in the box [lo, hi]; empty if t_enter > t_exit.
fn ray_box(origin: vec3<f32>, inv_dir: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>) -> vec2<f32> {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let tmin = min(t0, t1);
    let tmax = max(t0, t1);
    return vec2<f32>(max(max(tmin.x, tmin.y), tmin.z), min(min(tmax.x, tmax.y), tmax.z));
}

// cpu/march.rs: TraceLevel::level_position. World space to the level's window, in its cells.
fn level_position(level: u32, world: vec3<f32>) -> vec3<f32> {
    let l = voxel_grid.levels[level];
    return (world - l.origin) / l.cell_size - vec3<f32>(l.window_min);
}

// Where a texel of a level's window (clamped to it; `size`: the level's texels at this mip) is stored: its
// window texel plus the wrap, taken back once past the end (both are below `size`, which every mip divides,
// so one subtraction is the remainder, without a division).
fn wrapped_texel(l: VoxelLevel, texel: vec3<i32>, mip: u32, size: vec3<u32>) -> vec3<i32> {
    let t = vec3<u32>(clamp(texel, vec3<i32>(0), vec3<i32>(size) - vec3<i32>(1)));
    let s = t + (l.wrap >> vec3<u32>(mip));
    var physical = select(s, s - size, s >= size);
    physical.z += l.texture_z >> mip;
    return vec3<i32>(physical);
}

// Whether texel `texel` of level `l`'s window at mip `mip` (clamped to it; `size`: its texels at this mip)
// is occupied. Mesa 22's lavapipe returns wrong textureDimensions for levels >= 2 of 3D textures, so sizes
// are computed.
fn level_occupied(l: VoxelLevel, texel: vec3<i32>, mip: u32, size: vec3<u32>) -> bool {
    return textureLoad(voxel_texture, wrapped_texel(l, texel, mip, size), i32(mip)).r > 0.0;
}

// Whether texel `texel` (of the window, at mip `mip`, clamped to it) of a level is occupied.
fn voxel_occupied(level: u32, texel: vec3<i32>, mip: u32) -> bool {
    let l = voxel_grid.levels[level];
    return level_occupied(l, texel, mip, l.size >> vec3<u32>(mip));
}

// Where cell `texel` (of the window, clamped to it) of a level is stored in the textures' mip 0.
fn voxel_texel(level: u32, texel: vec3<i32>) -> vec3<i32> {
    let l = voxel_grid.levels[level];
    return wrapped_texel(l, texel, 0u, l.size);
}

// The average albedo of a cell of the window of a level (rgb), and 1 in a where it has points; zero where
// the volume keeps no attributes.
fn voxel_albedo_at(level: u32, texel: vec3<i32>) -> vec4<f32> {
    if voxel_grid.attributes == 0u {
        return vec4<f32>(0.0);
    }
    return textureLoad(voxel_albedo, voxel_texel(level, texel), 0);
}

// The average normal of a cell of the window of a level; zero where the volume keeps no attributes.
fn voxel_normal_at(level: u32, texel: vec3<i32>) -> vec3<f32> {
    if voxel_grid.attributes == 0u {
        return vec3<f32>(0.0);
    }
    return textureLoad(voxel_normal, voxel_texel(level, texel), 0).xyz;
}

// cpu/march.rs: MIN_OCCLUDING_CHORD
const MIN_OCCLUDING_CHORD: f32 = 0.5773503;

// cpu/march.rs: MarchResult (t < 0: no hit).
struct MarchResult {
    t: f32,
    steps_left: u32,
}

// cpu/march.rs: VoxelMips::march_level (one level of March::run). The distance along `dir` (the level's
// cells, from `origin` in its window) to the entry of the first run of occupied cells within [t_start, t_end]
// that the ray goes MIN_OCCLUDING_CHORD through: start at mip `start_mip`, step over empty texels whole,
// descend into occupied ones, and go up a mip after a step only where it entered another texel of the mip
// above (within the same one, that texel is the one just descended from, or one not read, which near a
// surface is most often occupied too); at most `steps` texel visits.
fn march_level(level: u32, origin: vec3<f32>, dir: vec3<f32>, t_start: f32, t_end: f32, start_mip: u32, steps: u32) -> MarchResult {
    // The level's record, read once.
    let l = voxel_grid.levels[level];
    let inv = safe_inverse(dir);
    let span = ray_box(origin, inv, vec3<f32>(0.0), vec3<f32>(l.dims));
    var t = max(t_start, span.x);
    let t_max = min(t_end, span.y);
    let top = voxel_grid.mip_levels - 1u;
    var mip = min(start_mip, top);
    var left = steps;
    // The faces a ray leaves a texel through: the upper one on each axis it goes up (or along), else the
    // lower (`ray_box`'s exit, without its entry).
    let exit_side = select(vec3<f32>(0.0), vec3<f32>(1.0), dir >= vec3<f32>(0.0));
    // The texel last stepped over (unclamped), and whether the last visit was such a step.
    var last = vec3<i32>(0);
    var stepped = false;
    // The run of occupied cells the ray is in: where it entered it, and how far it has gone through it.
    var run_start = 0.0;
    var run_length = 0.0;
    // One visit a step, without branches but its two ends (devices that run both sides of a branch, such as
    // lavapipe, pay for both anyway): an occupied texel descends a mip, an empty one is stepped over.
    while left > 0u {
        if t > t_max {
            return MarchResult(-1.0, left);
        }
        left -= 1u;
        let p = origin + dir * t;
        // The point's texel at this mip (2^-mip, exact); after a step that entered another texel of the mip
        // above, that one (its parent, by a shift: exact).
        let here = vec3<i32>(floor(p * bitcast<f32>((127u - mip) << 23u)));
        let up = stepped && mip < top && any((here >> vec3<u32>(1u)) != (last >> vec3<u32>(1u)));
        let texel = select(here, here >> vec3<u32>(1u), up);
        mip = select(mip, mip + 1u, up);
        // 2^mip, exact.
        let scale = bitcast<f32>((127u + mip) << 23u);
        let size = l.size >> vec3<u32>(mip);
        let occupied = level_occupied(l, texel, mip, size);
        let lo = vec3<f32>(clamp(texel, vec3<i32>(0), vec3<i32>(size) - vec3<i32>(1))) * scale;
        let exit_faces = (lo + exit_side * scale - origin) * inv;
        let exit = min(min(exit_faces.x, exit_faces.y), exit_faces.z);
        // A run of occupied cells stops the ray once it has gone MIN_OCCLUDING_CHORD through it, at the run's
        // entry: a cell it only clips is passed, as an empty one.
        let cell = occupied && mip == 0u;
        run_start = select(run_start, t, cell && run_length == 0.0);
        run_length = select(select(run_length, 0.0, !occupied), run_length + exit - t, cell);
        if cell && run_length >= MIN_OCCLUDING_CHORD {
            return MarchResult(run_start, left);
        }
        let descend = occupied && mip > 0u;
        t = select(max(exit, t) + 1.0e-3, t, descend);
        mip = select(mip, mip - 1u, descend);
        last = texel;
        stepped = !descend;
    }
    return MarchResult(-1.0, 0u);
}

// cpu/march.rs: level_weight. How many of a surface point's rays may start in a level: 1 when it lies at
// least CASCADE_BLEND_CELLS cells inside the window, 0 at its border.
fn level_weight(level: u32, world: vec3<f32>) -> f32 {
    let p = level_position(level, world);
    let q = min(p, vec3<f32>(voxel_grid.levels[level].dims) - p);
    let margin = min(min(q.x, q.y), q.z);
    return clamp(margin / CASCADE_BLEND_CELLS, 0.0, 1.0);
}

// cpu/march.rs: ray_start_level. The finest level whose weight exceeds ray i's own number; the coarsest
// takes what no finer one does.
fn ray_start_level(world: vec3<f32>, i: u32, rotation: vec2<f32>) -> u32 {
    let u = fract(f32(i) * 0.7548777 + rotation.x + rotation.y);
    let last = voxel_grid.level_count - 1u;
    for (var l = 0u; l < last; l++) {
        if level_weight(l, world) > u {
            return l;
        }
    }
    return last;
}

// The finest level whose window holds `world`, or the coarsest.
fn finest_level_containing(world: vec3<f32>) -> u32 {
    let last = voxel_grid.level_count - 1u;
    for (var l = 0u; l < last; l++) {
        let p = level_position(l, world);
        if all(p >= vec3<f32>(0.0)) && all(p <= vec3<f32>(voxel_grid.levels[l].dims)) {
            return l;
        }
    }
    return last;
}

// cpu/march.rs: MARCH_START_MIP
const MARCH_START_MIP: u32 = 1u;

// cpu/march.rs: march_cascades. The world distance along `dir` from `origin` to the first run of occupied voxels
// that stops it within `t_end` (world), starting in level `start` at `t_start` of its cells, and the level
// hit: (t, level), t < 0 for no hit. A ray that leaves a level goes on in the next coarser one from where it
// left.
fn march_cascades(origin: vec3<f32>, dir: vec3<f32>, start: u32, t_start: f32, t_end: f32, steps: u32) -> vec2<f32> {
    return march_cascades_left(origin, dir, start, t_start, t_end, steps).xy;
}

// cpu/march.rs: March::run, March::steps_left. `march_cascades`, with the steps it has left as the third
// component (a march past a hit the caller passes: March::resume).
fn march_cascades_left(origin: vec3<f32>, dir: vec3<f32>, start: u32, t_start: f32, t_end: f32, steps: u32) -> vec3<f32> {
    let inv = safe_inverse(dir);
    var level = start;
    var t0 = t_start;
    var left = steps;
    loop {
        let cell = voxel_grid.levels[level].cell_size;
        let o = level_position(level, origin);
        let t1 = t_end / cell;
        let r = march_level(level, o, dir, t0, t1, MARCH_START_MIP, left);
        if r.t >= 0.0 {
            return vec3<f32>(r.t * cell, f32(level), f32(r.steps_left));
        }
        left = r.steps_left;
        if left == 0u || level + 1u >= voxel_grid.level_count {
            return vec3<f32>(-1.0, 0.0, f32(left));
        }
        let exit = ray_box(o, inv, vec3<f32>(0.0), vec3<f32>(voxel_grid.levels[level].dims)).y;
        if exit >= t1 {
            return vec3<f32>(-1.0, 0.0, f32(left));
        }
        t0 = max(exit, t0) * cell / voxel_grid.levels[level + 1u].cell_size;
        level += 1u;
    }
    return vec3<f32>(-1.0, 0.0, 0.0);
}
