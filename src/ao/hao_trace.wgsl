// Hybrid ambient occlusion, pass 1: per pixel (or, at half resolution, per 2x2 block from its pixel whose
// turn it is: `traced_pixel`), cosine-weighted rays from the surface (position from the depth prepass,
// normal from the normal prepass) through the voxel texture, with empty-space skipping on its max-reduced
// mips; each ray's first cells, which the voxels skip, are traced in the depth prepass (`depth_contact`),
// and its voxel hits near the surface that the depth prepass shows in empty space are passed (`near`);
// where the view hides the march's start, those first cells are marched in the voxels past the surface's
// own (`near_voxel_hit`).
// Writes the noisy AO (1 = open, 0 = occluded) with the traced pixel's view depth and octahedral normal,
// which the temporal pass weighs by, into a buffer of the trace's texels row by row (`pack_history`; in
// place of frames, 1 where occluders moved near the pixel, whose texel the passes after it filter wider).
// In the checkerboard (`Low`) it runs on half the texels, alternating (`checkerboard_texel`), and the others
// keep their last frame's.
// Where occluders moved near the pixel, `change_rays` times the rays (`hao_change.wgsl`).
// CPU twin: `bevy_hao::cpu::ao::voxel_ambient_occlusion_counted` (the contacts: `bevy_hao::cpu::contacts`;
// the first cells in the voxels: `bevy_hao::cpu::near`;
// the rays: `bevy_hao::cpu::temporal::change_rays`).
// The voxel levels are bound at group 2.
#import bevy_render::view::View
#import bevy_hao::hao_common::{
    HaoSettings, ray_rotation, hemisphere_direction, orthonormal_basis, ao_falloff, interleaved_gradient_noise,
    GOLDEN,
    octahedral_encode, traced_pixel, checkerboard_texel, trace_turn, noise_frame, target_pixel, trace_index,
    pack_history, pack_normal,
}
#import bevy_hao::voxel_grid::{
    voxel_grid, ray_start_level, march_cascades_left, level_position, voxel_normal_at, safe_inverse, ray_box,
    voxel_occupied, MIN_OCCLUDING_CHORD,
}
#import bevy_hao::hao_change::{occlusion_change, change_rays, filters_wide}

// The prepasses, the target's size: the view's pixel p is at target_pixel(p). With MSAA, sample 0.
#ifdef MULTISAMPLED
@group(0) @binding(0) var depth_texture: texture_depth_multisampled_2d;
@group(0) @binding(1) var normal_texture: texture_multisampled_2d<f32>;
#else
@group(0) @binding(0) var depth_texture: texture_depth_2d;
@group(0) @binding(1) var normal_texture: texture_2d<f32>;
#endif
@group(0) @binding(2) var<uniform> settings: HaoSettings;
@group(0) @binding(3) var<storage, read_write> noisy: array<vec2<u32>>;
@group(1) @binding(0) var<uniform> view: View;

// cpu/ao.rs: BACK_HIT_COS, MAX_BACK_HITS
const BACK_HIT_COS: f32 = 0.5;
const MAX_BACK_HITS: u32 = 4u;

// cpu/ao.rs: back_hit_exit. Where a ray that hit the cell at `hit` (world distance, level) leaves that cell,
// in the level's cells, if the cell's average normal faces along the ray (its back); else -1.
fn back_hit_exit(origin: vec3<f32>, dir: vec3<f32>, hit: vec2<f32>) -> f32 {
    let level = u32(hit.y);
    let o = level_position(level, origin);
    let t = hit.x / voxel_grid.levels[level].cell_size;
    // The cell the march found occupied (the point it stopped at).
    let cell = floor(o + dir * t);
    let n = voxel_normal_at(level, vec3<i32>(cell));
    if dot(n, dir) <= BACK_HIT_COS {
        return -1.0;
    }
    return cell_exit(origin, dir, hit);
}

// cpu/ao.rs: cell_exit. Where a ray that hit the cell at `hit` (world distance, level) leaves that cell, in
// the level's cells.
fn cell_exit(origin: vec3<f32>, dir: vec3<f32>, hit: vec2<f32>) -> f32 {
    let level = u32(hit.y);
    let o = level_position(level, origin);
    let cell = floor(o + dir * (hit.x / voxel_grid.levels[level].cell_size));
    return ray_box(o, safe_inverse(dir), cell, cell + vec3<f32>(1.0)).y + 1.0e-3;
}

// cpu/contacts.rs: FREE_SPACE_MARGIN, MAX_FREE_SPACE_PASSES
const FREE_SPACE_MARGIN: f32 = 1.0;
const MAX_FREE_SPACE_PASSES: u32 = 2u;

// cpu/contacts.rs: ViewDepth::shows_free_space. Whether the view shows the world point `p` in free space:
// on the view, and in front of the nearest surface of the 3x3 pixels around the one it projects to by more
// than `margin` (world units, in view depth), or with none of them showing a surface.
fn shows_free_space(p: vec3<f32>, margin: f32) -> bool {
    let clip = view.clip_from_world * vec4<f32>(p, 1.0);
    if !(clip.w > 0.0) {
        return false;
    }
    let ndc = clip.xyz / clip.w;
    if abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0 || ndc.z <= 0.0 || ndc.z > 1.0 {
        return false;
    }
    let size = vec2<i32>(view.viewport.zw);
    let pixel = min(vec2<i32>(vec2<f32>(ndc.x + 1.0, 1.0 - ndc.y) * 0.5 * view.viewport.zw), size - 1);
    // The nearest surface around it: the largest depth (reverse Z), 0 where none shows one.
    var nearest = 0.0;
    for (var k = 0; k < 9; k++) {
        let q = pixel + vec2<i32>(k % 3 - 1, k / 3 - 1);
        if any(q < vec2<i32>(0)) || any(q >= size) {
            continue;
        }
        nearest = max(nearest, textureLoad(depth_texture, target_pixel(settings, vec2<u32>(q)), 0));
    }
    if nearest <= 0.0 {
        return true;
    }
    return -(view.view_from_world * vec4<f32>(p, 1.0)).z < surface_view_depth(nearest) - margin;
}

// cpu/contacts.rs: NEAR_FREE_SPACE_CELLS, NEAR_FREE_SPACE_PIXELS, MAX_NEAR_FREE_SPACE_PASSES
const NEAR_FREE_SPACE_CELLS: f32 = 8.0;
const NEAR_FREE_SPACE_PIXELS: f32 = 1.0;
const MAX_NEAR_FREE_SPACE_PASSES: u32 = 8u;

// The trace's passes past a voxel hit, in the order a ray takes them (cpu/ao.rs: voxel_ray_occluder's loops).
const PASS_BACK_HITS: u32 = 0u;
const PASS_NEAR_FREE_SPACE: u32 = 1u;
const PASS_FREE_SPACE: u32 = 2u;

// cpu/contacts.rs: CONTACT_LENGTH, CONTACT_THICKNESS, CONTACT_LIFT_PIXELS, CONTACT_LIFT_CELLS,
// CONTACT_DEPTH_EPSILON
const CONTACT_LENGTH: f32 = 2.0;
const CONTACT_THICKNESS: f32 = 1.0;
const CONTACT_LIFT_PIXELS: f32 = 0.5;
const CONTACT_LIFT_CELLS: f32 = 0.125;
const CONTACT_DEPTH_EPSILON: f32 = 1.0e-3;

// cpu/contacts.rs: CONTACT_GRAZING_COS
const CONTACT_GRAZING_COS: f32 = 0.25;

// cpu/contacts.rs: Behind
const BEHIND_NO: u32 = 0u;
const BEHIND_ALONG_VIEW: u32 = 1u;
const BEHIND_ALONG_NORMAL: u32 = 2u;

// cpu/contacts.rs: ViewDepth::behind_clip. How the point at `clip` (clip space) and view depth `depth` lies
// behind the surface the view shows at the pixel it projects to: by more than CONTACT_DEPTH_EPSILON of its
// depth and less than `thickness` along the view (BEHIND_ALONG_VIEW), or with `grazing`, deeper but within
// `thickness` along that surface's normal (BEHIND_ALONG_NORMAL; `eye`: the direction the view looks along;
// the normal is read only then), or not (BEHIND_NO).
fn behind_depth(clip: vec4<f32>, depth: f32, thickness: f32, grazing: bool, eye: vec3<f32>) -> u32 {
    if !(clip.w > 0.0) {
        return BEHIND_NO;
    }
    let ndc = clip.xyz / clip.w;
    if abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0 || ndc.z <= 0.0 || ndc.z > 1.0 {
        return BEHIND_NO;
    }
    let size = view.viewport.zw;
    let pixel = min(vec2<u32>(vec2<f32>(ndc.x + 1.0, 1.0 - ndc.y) * 0.5 * size), vec2<u32>(size) - 1u);
    let d = textureLoad(depth_texture, target_pixel(settings, pixel), 0);
    if d <= 0.0 {
        return BEHIND_NO;
    }
    let surface = surface_view_depth(d);
    if !(depth > surface * (1.0 + CONTACT_DEPTH_EPSILON)) {
        return BEHIND_NO;
    }
    if depth < surface + thickness {
        return BEHIND_ALONG_VIEW;
    }
    if !grazing {
        return BEHIND_NO;
    }
    let n = normalize(textureLoad(normal_texture, target_pixel(settings, pixel), 0).xyz * 2.0 - 1.0);
    return select(BEHIND_NO, BEHIND_ALONG_NORMAL, depth < surface + thickness / max(abs(dot(n, eye)), CONTACT_GRAZING_COS));
}

// cpu/contacts.rs: ViewDepth::surface_view_depth. The view depth of the surface at prepass depth `d`: the z
// and w rows of view_from_clip times (0, 0, d, 1).
fn surface_view_depth(d: f32) -> f32 {
    let m = view.view_from_clip;
    return -(m[2].z * d + m[3].z) / (m[2].w * d + m[3].w);
}

// cpu/contacts.rs: contact_jitter.
fn contact_jitter(pixel: vec2<f32>, frame: u32) -> f32 {
    return interleaved_gradient_noise(pixel.yx + vec2<f32>(43.0, 11.0), frame);
}

// cpu/contacts.rs: ViewDepth::pixel_size. The size of one of the view's pixels, in world units, at a point
// whose clip-space w is `clip_w` (perspective or orthographic alike).
fn pixel_size(clip_w: f32) -> f32 {
    return 2.0 * clip_w * abs(view.view_from_clip[1][1]) / max(view.viewport.w, 1.0);
}

// cpu/contacts.rs: contact_lift. How far a ray's contact points are lifted off the surface: CONTACT_LIFT_PIXELS
// pixels of size `pixel` (the prepass's own error is in its pixels), at most CONTACT_LIFT_CELLS cells.
fn contact_lift(pixel: f32, cell: f32) -> f32 {
    return min(CONTACT_LIFT_PIXELS * pixel, CONTACT_LIFT_CELLS * cell);
}

// cpu/contacts.rs: depth_contact. The distance along ray `dir` from the surface point to its first contact
// in the depth prepass within `reach`, or -1: settings.contact_samples points, lifted `contact_lift` along the
// normal, the first behind the view's surface by less than CONTACT_THICKNESS cells; with `grazing`, also one
// within it along that surface's normal that lies in an occupied cell of level `level`'s finest occupancy
// (`eye`: the direction the view looks along at `world`).
fn depth_contact(world: vec3<f32>, normal: vec3<f32>, dir: vec3<f32>, cell: f32, reach: f32, jitter: f32, grazing: bool, level: u32, eye: vec3<f32>) -> f32 {
    let lift = contact_lift(pixel_size((view.clip_from_world * vec4<f32>(world, 1.0)).w), cell);
    let base = vec4<f32>(world + normal * lift, 1.0);
    // The ray's start and direction in clip space and in view depth: each point is a multiply-add away.
    let clip = view.clip_from_world * base;
    let clip_dir = view.clip_from_world * vec4<f32>(dir, 0.0);
    let depth = -(view.view_from_world * base).z;
    let depth_dir = -(view.view_from_world * vec4<f32>(dir, 0.0)).z;
    let samples = settings.contact_samples;
    for (var k = 0u; k < samples; k++) {
        let t = reach * (f32(k) + jitter) / f32(samples);
        let behind = behind_depth(clip + clip_dir * t, depth + depth_dir * t, CONTACT_THICKNESS * cell, grazing, eye);
        if behind == BEHIND_ALONG_VIEW {
            return t;
        }
        if behind == BEHIND_ALONG_NORMAL && voxel_occupied(level, vec3<i32>(floor(level_position(level, base.xyz + dir * t))), 0u) {
            return t;
        }
    }
    return -1.0;
}

// cpu/near.rs: hides_origin. Whether the view hides the point `origin` (where a ray's march starts): behind
// the surface the view shows at its pixel by more than CONTACT_DEPTH_EPSILON of its depth, however far.
fn hides_origin(origin: vec3<f32>) -> bool {
    let p = vec4<f32>(origin, 1.0);
    return behind_depth(view.clip_from_world * p, -(view.view_from_world * p).z, 1.0e30, false, vec3<f32>(0.0)) != BEHIND_NO;
}

// cpu/near.rs: OWN_CELL_MARGIN, NEAR_VOXEL_STEPS
const OWN_CELL_MARGIN: f32 = 0.125;
const NEAR_VOXEL_STEPS: u32 = 8u;

// cpu/near.rs: own_cell. Whether cell `cell` (a level's cells) is the surface's own: the plane through
// `surface` (the same cells) with normal `normal` crosses it, or passes within OWN_CELL_MARGIN of it.
fn own_cell(cell: vec3<f32>, surface: vec3<f32>, normal: vec3<f32>) -> bool {
    let extent = 0.5 * (abs(normal.x) + abs(normal.y) + abs(normal.z)) + OWN_CELL_MARGIN;
    return abs(dot(normal, cell + vec3<f32>(0.5) - surface)) <= extent;
}

// cpu/near.rs: near_voxel_hit. The world distance (half a cell past the entry) from the surface point `world`
// (normal `normal`) along ray `dir` to the first occupied cell of level `level`'s finest occupancy within
// `reach` cells that is not the surface's own, entered by a run of such cells the ray goes
// MIN_OCCLUDING_CHORD through, or -1; a hit whose surface the view shows in free space by a pixel is passed.
fn near_voxel_hit(level: u32, world: vec3<f32>, normal: vec3<f32>, dir: vec3<f32>, reach: f32) -> f32 {
    let o = level_position(level, world);
    let inv = safe_inverse(dir);
    let cell_size = voxel_grid.levels[level].cell_size;
    var t = 0.0;
    var run_start = 0.0;
    var run_length = 0.0;
    var visits = 0u;
    while visits < NEAR_VOXEL_STEPS && t < reach {
        visits += 1u;
        let cell = floor(o + dir * t);
        let exit = ray_box(o, inv, cell, cell + vec3<f32>(1.0)).y;
        let other = voxel_occupied(level, vec3<i32>(cell), 0u) && !own_cell(cell, o, normal);
        run_start = select(run_start, t, other && run_length == 0.0);
        run_length = select(0.0, run_length + exit - t, other);
        if run_length >= MIN_OCCLUDING_CHORD {
            let distance = (run_start + 0.5) * cell_size;
            let surface = world + dir * distance;
            let margin = NEAR_FREE_SPACE_PIXELS * pixel_size((view.clip_from_world * vec4<f32>(surface, 1.0)).w);
            if !shows_free_space(surface, margin) {
                return distance;
            }
            run_length = 0.0;
        }
        t = max(exit, t) + 1.0e-3;
    }
    return -1.0;
}

fn world_position(pixel: vec2<u32>, depth: f32) -> vec3<f32> {
    let uv = (vec2<f32>(pixel) + 0.5) / view.viewport.zw;
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let p = view.world_from_clip * vec4<f32>(ndc, depth, 1.0);
    return p.xyz / p.w;
}

@compute @workgroup_size(#{SCREEN_WORKGROUP}, #{SCREEN_WORKGROUP}, 1)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    // With the checkerboard, half the texels a frame (`texel_traced`); the others keep their last trace.
    let checkerboard = settings.checkerboard != 0u;
    let texel = checkerboard_texel(gid.xy, settings.frame, checkerboard);
    if any(texel >= vec2<u32>(settings.trace_width, settings.trace_height)) {
        return;
    }
    let at = trace_index(settings, texel);
    // At half resolution, the pixel of the 2x2 block whose turn it is: each pixel traces every fourth frame
    // (every eighth in the checkerboard),
    // and the temporal pass accumulates each pixel's own rays at full resolution.
    let half = settings.half_resolution != 0u;
    let turn = trace_turn(settings.frame, checkerboard);
    let pixel = traced_pixel(texel, turn, vec2<u32>(view.viewport.zw), half);
    let depth = textureLoad(depth_texture, target_pixel(settings, pixel), 0);
    if depth <= 0.0 {
        // Background: depth 0 tells the passes after this one to skip it.
        noisy[at] = pack_history(vec4<f32>(1.0, 0.0, 0.0, 0.0));
        return;
    }
    let world = world_position(pixel, depth);
    let normal = normalize(textureLoad(normal_texture, target_pixel(settings, pixel), 0).xyz * 2.0 - 1.0);
    let view_depth = -(view.view_from_world * vec4<f32>(world, 1.0)).z;
    // cpu/contacts.rs: ViewDepth::eye_direction. From the near plane's point at the pixel to the surface.
    let eye = normalize(world - world_position(pixel, 1.0));
    let packed_normal = pack_normal(octahedral_encode(normal));
    if voxel_grid.level_count == 0u {
        noisy[at] = pack_history(vec4<f32>(1.0, view_depth, packed_normal, 0.0));
        return;
    }
    let pf = vec2<f32>(pixel);
    // The noise turns with each of the pixel's own traces (every frame, or every fourth or eighth at half
    // resolution).
    let rotation = ray_rotation(pf, noise_frame(turn, half));
    let jitter = contact_jitter(pf, noise_frame(turn, half));
    var occlusion = 0.0;
    let basis = orthonormal_basis(normal);
    // More rays where occluders moved near the pixel: its history is short there (a variant of its own,
    // `MOVED_OCCLUDERS`, chosen while any moved).
#ifdef MOVED_OCCLUDERS
    let change = occlusion_change(world, normal, settings.max_distance, settings.falloff);
    let rays = change_rays(settings.rays, change);
    let changed = filters_wide(change);
#else
    let rays = settings.rays;
    let changed = false;
#endif
    for (var i = 0u; i < rays; i++) {
        let dir = hemisphere_direction(basis, i, rays, rotation);
        // The finest level that holds the surface (blended across its border), then coarser ones.
        let start = ray_start_level(world, i, rotation);
        let cell = voxel_grid.levels[start].cell_size;
        // The ray's first cells in the depth prepass: a contact there stops it, and the march is not run.
        if settings.depth_contacts != 0u && settings.start_offset > 0.0 {
            let reach = CONTACT_LENGTH * settings.start_offset * cell;
            // Where the view hides the march's start, it may lie inside an occluder: the contacts' thickness is
            // measured along the normal of the surface the view shows (deeper than a cell along the view, only
            // inside the voxels), and the first cells are also marched in the voxels, past the surface's own.
            let hidden = hides_origin(world + normal * (settings.start_offset * cell));
            let t = depth_contact(world, normal, dir, cell, reach, fract(jitter + f32(i) * GOLDEN), hidden, start, eye);
            if t >= 0.0 {
                occlusion += ao_falloff(t, settings.max_distance, settings.falloff);
                continue;
            }
            if hidden {
                let d = near_voxel_hit(start, world, normal, dir, CONTACT_LENGTH * settings.start_offset);
                if d >= 0.0 {
                    occlusion += ao_falloff(d, settings.max_distance, settings.falloff);
                    continue;
                }
            }
        }
        let origin = world + normal * (settings.start_offset * cell);
        // The march, and the hits it passes (cpu/ao.rs: voxel_ray_occluder's three loops, in turn), in one
        // loop around one march: devices that run every branch, taken or not (lavapipe), pay for each march
        // written out, and a GPU warp runs as many marches as its busiest lane rather than each loop's
        // busiest lane's in turn. Where the march resumes past the hit (the hit's level's cells), or -1 where
        // the hit stops the ray; the steps it resumes with.
        var from_level = start;
        var from_t = settings.start_offset;
        var budget = settings.steps;
        var phase = PASS_BACK_HITS;
        // The passes made in this phase.
        var passes = 0u;
        var marched = vec3<f32>(-1.0, 0.0, 0.0);
        // A ray marches at most once, then once a pass (MAX_BACK_HITS, MAX_NEAR_FREE_SPACE_PASSES and
        // MAX_FREE_SPACE_PASSES at most).
        loop {
            marched = march_cascades_left(origin, dir, from_level, from_t, settings.max_distance, budget);
            if marched.x < 0.0 {
                break;
            }
            var next = -1.0;
#ifdef BACK_HITS
            // Through the backs of surfaces, a few times at most, each with the whole step budget (a variant
            // of its own: without attributes or with `ignore_back_hits` off no ray takes it).
            if phase == PASS_BACK_HITS && settings.back_hits != 0u && voxel_grid.attributes != 0u && passes < MAX_BACK_HITS {
                next = back_hit_exit(origin, dir, marched.xy);
                budget = settings.steps;
            }
#endif
            if phase == PASS_BACK_HITS && next < 0.0 {
                phase = PASS_NEAR_FREE_SPACE;
                passes = 0u;
            }
            // Past the cells near the surface that the view shows empty, by a pixel, where the trace takes
            // their surface to be (`depth_contacts`); the march goes on with the steps it has left.
            if phase == PASS_NEAR_FREE_SPACE {
                // The point at the hit's distance on the ray from the surface itself, which the lift moved
                // the march's off: near an occluder overhead the lifted ray crosses cells the ray misses.
                let distance = length(origin + dir * (marched.x + 0.5 * voxel_grid.levels[u32(marched.y)].cell_size) - world);
                let near = settings.depth_contacts != 0u && passes < MAX_NEAR_FREE_SPACE_PASSES && marched.z > 0.0
                    && distance <= NEAR_FREE_SPACE_CELLS * cell;
                let surface = world + dir * distance;
                if near && shows_free_space(surface, NEAR_FREE_SPACE_PIXELS * pixel_size((view.clip_from_world * vec4<f32>(surface, 1.0)).w)) {
                    next = cell_exit(origin, dir, marched.xy);
                    budget = u32(marched.z);
                } else {
                    phase = PASS_FREE_SPACE;
                    passes = 0u;
                }
            }
#ifdef FREE_SPACE
            // Past the cells the view shows empty where the trace takes their surface to be, a few times at
            // most, each with the whole step budget (a variant of its own, as BACK_HITS).
            if phase == PASS_FREE_SPACE && passes < MAX_FREE_SPACE_PASSES {
                let hit_cell = voxel_grid.levels[u32(marched.y)].cell_size;
                if shows_free_space(origin + dir * (marched.x + 0.5 * hit_cell), FREE_SPACE_MARGIN * hit_cell) {
                    next = cell_exit(origin, dir, marched.xy);
                    budget = settings.steps;
                }
            }
#endif
            if next < 0.0 {
                break;
            }
            passes += 1u;
            from_level = u32(marched.y);
            from_t = next;
        }
        let hit = marched.xy;
        if hit.x >= 0.0 {
            // The surface lies somewhere in the first occupied cell, on average half a cell past its entry.
            let hit_cell = voxel_grid.levels[u32(hit.y)].cell_size;
            let d = length(origin + dir * (hit.x + 0.5 * hit_cell) - world);
            occlusion += ao_falloff(d, settings.max_distance, settings.falloff);
        }
    }
    let ao = clamp(1.0 - settings.intensity * occlusion / f32(rays), 0.0, 1.0);
    // The fourth field: 1 where occluders moved near the pixel, which the passes after this one filter wider
    // (cpu/temporal.rs: TracedTexel::changed).
    noisy[at] = pack_history(vec4<f32>(ao, view_depth, packed_normal, select(0.0, 1.0, changed)));
}
