//! The CPU twin of the hybrid ambient occlusion trace (`src/ao/hao_trace.wgsl`, `hao_common.wgsl`): ray
//! directions, falloff, and the march through the voxel grid with empty-space skipping, with the same names
//! and operations as the WGSL. The ray-traced reference that HAO is measured against (rays against the real
//! triangles) shares [`hemisphere_direction`] and [`ao_falloff`] with it.

use super::contacts::{
    CONTACT_LENGTH, FREE_SPACE_MARGIN, MAX_FREE_SPACE_PASSES, MAX_NEAR_FREE_SPACE_PASSES, NEAR_FREE_SPACE_CELLS,
    NEAR_FREE_SPACE_PIXELS, ViewDepth, depth_contact, ray_jitter,
};
use super::march::{March, TraceLevel, ray_box, ray_start_level, safe_inverse};
use super::near::{hides_origin, near_voxel_hit};
use glam::{Mat3, Vec2, Vec3};
use std::f32::consts::PI;

/// The golden ratio's fractional part (WGSL: `GOLDEN`).
pub(crate) const GOLDEN: f32 = 0.618_034;

/// Interleaved gradient noise (Jimenez 2014) at a pixel, varied per frame, in `[0, 1)`.
pub fn interleaved_gradient_noise(pixel: Vec2, frame: u32) -> f32 {
    let p = pixel + 5.588238 * (frame % 64) as f32;
    (52.982_918 * (0.067_110_56 * p.x + 0.005_837_15 * p.y).fract()).fract()
}

/// The rotation of a pixel's set of rays in frame `frame` (WGSL: `ray_rotation`): interleaved gradient noise
/// over the screen, a different pattern per coordinate, shifted each frame along the R2 sequence (Roberts
/// 2018), so that accumulated frames cover the two coordinates evenly (IGN's own frame offset moves both
/// together). Frame 0 is the noise of a single frame.
pub fn ray_rotation(pixel: Vec2, frame: u32) -> Vec2 {
    let spatial = Vec2::new(
        interleaved_gradient_noise(pixel, 0),
        interleaved_gradient_noise(Vec2::new(pixel.y, pixel.x) + Vec2::new(17.0, 59.0), 0),
    );
    let f = (frame % 4096) as f32;
    let shift = Vec2::new((f * 0.754_877_7).fract(), (f * 0.569_840_3).fract());
    let r = spatial + shift;
    r - r.floor()
}

/// The pixel of its 2x2 block that a half-resolution trace samples in `frame` (WGSL:
/// `half_resolution_offset`), as an offset from the block's first pixel: the four in turn, diagonals first,
/// so that every pixel traces every fourth frame and the temporal pass accumulates each pixel's own rays.
/// Frame 0 (a single frame, no accumulation) samples the first pixel.
pub fn half_resolution_offset(frame: u32) -> glam::UVec2 {
    const OFFSETS: [glam::UVec2; 4] =
        [glam::UVec2::new(0, 0), glam::UVec2::new(1, 1), glam::UVec2::new(1, 0), glam::UVec2::new(0, 1)];
    OFFSETS[(frame % 4) as usize]
}

/// The pixel that texel `texel` of the trace traces in `frame` on a view of `view_size` pixels (WGSL:
/// `traced_pixel`): at full resolution its own; at half resolution the pixel of its 2x2 block whose turn it
/// is ([`half_resolution_offset`]), clamped to the view.
pub fn traced_pixel(texel: glam::UVec2, frame: u32, view_size: glam::UVec2, half_resolution: bool) -> glam::UVec2 {
    if !half_resolution {
        return texel;
    }
    (texel * 2 + half_resolution_offset(frame)).min(view_size.saturating_sub(glam::UVec2::ONE))
}

/// The texel of the trace that invocation `id` of the trace pass traces in `frame` (WGSL:
/// `checkerboard_texel`): its own, or with the checkerboard the texel of row `id.y` at column `2 id.x` or
/// `2 id.x + 1`, whichever [`texel_traced`] picks. With the checkerboard the pass runs half the invocations.
pub fn checkerboard_texel(id: glam::UVec2, frame: u32, checkerboard: bool) -> glam::UVec2 {
    if !checkerboard {
        return id;
    }
    // (Wrapping, as WGSL's u32 arithmetic: only the parity counts.)
    glam::UVec2::new(id.x * 2 + (id.y.wrapping_add(frame) & 1), id.y)
}

/// Whether texel `texel` of the trace is traced in `frame` (WGSL: `texel_traced`): every texel, or with the
/// checkerboard those whose coordinates' sum has the frame's parity. The others keep their last frame's trace.
pub fn texel_traced(texel: glam::UVec2, frame: u32, checkerboard: bool) -> bool {
    !checkerboard || texel.x.wrapping_add(texel.y).wrapping_add(frame) & 1 == 0
}

/// The frame number that picks a block's pixel ([`traced_pixel`]) and turns the noise ([`noise_frame`])
/// (WGSL: `trace_turn`): the frame, or with the checkerboard, where each texel is traced every other frame,
/// half of it, so that each block still traces its four pixels in turn.
pub fn trace_turn(frame: u32, checkerboard: bool) -> u32 {
    if checkerboard { frame / 2 } else { frame }
}

/// The frame number that turns a pixel's ray noise ([`ray_rotation`]; WGSL: in `trace`): the frame at full
/// resolution; at half resolution the number of the pixel's own trace (one every fourth frame, or with
/// `frame` from [`trace_turn`] every eighth in a checkerboard), so that a
/// pixel's successive traces step through the R2 sequence as they do at full resolution (every fourth
/// element of it would barely move its first coordinate: 4 x 0.7548777 is 0.0195 past a whole number).
pub fn noise_frame(frame: u32, half_resolution: bool) -> u32 {
    if half_resolution { frame / 4 } else { frame }
}

/// Two tangents completing the unit vector `n` to an orthonormal basis (Duff et al. 2017); columns
/// (tangent, bitangent, n).
pub fn orthonormal_basis(n: Vec3) -> Mat3 {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    Mat3::from_cols(Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x), Vec3::new(b, s + n.y * n.y * a, -n.y), n)
}

/// Ray `i` of `count` over the hemisphere around the normal (the third column of `basis`, from
/// [`orthonormal_basis`]): cosine-weighted, stratified in the polar coordinate, the whole set shifted by
/// `rotation` (two numbers in `[0, 1)`, one pair per pixel).
pub fn hemisphere_direction(basis: Mat3, i: u32, count: u32, rotation: Vec2) -> Vec3 {
    let u1 = ((i as f32 + rotation.x) / count as f32).fract();
    let u2 = (i as f32 * GOLDEN + rotation.y).fract();
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let local = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
    basis * local
}

/// The weight of an occluder at `distance`: 1 at the surface, 0 at `max_distance` and beyond,
/// `(1 - d / max)^falloff` between.
pub fn ao_falloff(distance: f32, max_distance: f32, falloff: f32) -> f32 {
    let x = (distance / max_distance).clamp(0.0, 1.0);
    (1.0 - x).powf(falloff)
}

/// The work of a trace, counted by the CPU twin: a measure of its cost that does not depend on the device
/// (the GPU does the same loads; see `bench_ao`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TraceWork {
    /// Rays traced.
    pub rays: u64,
    /// Voxel texels the marches loaded (one occupancy load per visit, at some mip).
    pub texel_visits: u64,
    /// Average normals loaded to tell the backs of surfaces ([`TraceSettings::ignore_back_hits`]).
    pub normal_loads: u64,
    /// Depth prepass samples read: the rays' first cells ([`TraceSettings::depth_contacts`]) and the voxel
    /// hits tested for free space ([`TraceSettings::depth_free_space`]).
    pub depth_loads: u64,
    /// Voxel hits passed because the view shows them in free space ([`TraceSettings::depth_free_space`]).
    pub free_space_passes: u64,
    /// Voxel hits near the surface passed because the view shows them in free space
    /// ([`TraceSettings::depth_contacts`], [`NEAR_FREE_SPACE_CELLS`]).
    pub near_free_space_passes: u64,
    /// Of `texel_visits`, those of the marches past the near hits passed as free space (all passes together).
    pub near_free_space_visits: u64,
    /// Of `texel_visits`, those of the marches past the hits passed as free space, pass by pass (a SIMD
    /// device runs each pass after every lane's march before it: see `bench_ao`'s work table).
    pub free_space_visits: [u64; MAX_FREE_SPACE_PASSES as usize],
    /// Rays that hit an occupied voxel or a contact in the depth prepass.
    pub hits: u64,
    /// Rays stopped by a contact in the depth prepass (their march is not run).
    pub contacts: u64,
    /// Rays whose first cells were marched in the voxels, the view hiding the march's start
    /// ([`super::near`]).
    pub near_voxel_marches: u64,
    /// Of those, rays stopped there (their march is not run).
    pub near_voxel_hits: u64,
    /// Marches stopped by the step budget before reaching `max_distance` or leaving the volume.
    pub out_of_steps: u64,
}

/// A voxel whose average normal has at least this cosine with a ray (facing along it) is the back of a
/// surface to that ray: with [`TraceSettings::ignore_back_hits`] the ray passes through it. Only clearly
/// back-facing voxels: both faces of a thin wall in one voxel cancel to a short normal, which occludes.
/// (0.25 was also measured; see docs/figures.md.)
pub const BACK_HIT_COS: f32 = 0.5;
/// How many backs of surfaces a ray passes through at most; the next voxel it hits occludes. Each pass
/// restarts the march with the full `steps` budget, so a ray may visit up to `(MAX_BACK_HITS + 1) * steps`
/// texels (`(MAX_BACK_HITS + MAX_FREE_SPACE_PASSES + 1) * steps` with
/// [`TraceSettings::depth_free_space`]).
pub const MAX_BACK_HITS: u32 = 4;

/// Where a ray that hit the cell at `hit` (world distance, level) leaves that cell, in the level's cells, if
/// the cell is the back of a surface to it ([`BACK_HIT_COS`]); `None` otherwise (WGSL: `back_hit_exit`).
pub fn back_hit_exit(levels: &[TraceLevel], origin: Vec3, dir: Vec3, hit: (f32, usize)) -> Option<f32> {
    let (t, level) = hit;
    let lv = &levels[level];
    let o = lv.level_position(origin);
    // The cell the march found occupied (the point it stopped at).
    let cell = (o + dir * (t / lv.cell_size)).floor();
    if lv.mips.normal(cell.as_ivec3()).dot(dir) <= BACK_HIT_COS {
        return None;
    }
    Some(cell_exit(levels, origin, dir, hit))
}

/// Where a ray that hit the cell at `hit` (world distance, level) leaves that cell, in the level's cells
/// (WGSL: `cell_exit`).
pub fn cell_exit(levels: &[TraceLevel], origin: Vec3, dir: Vec3, hit: (f32, usize)) -> f32 {
    let (t, level) = hit;
    let lv = &levels[level];
    let o = lv.level_position(origin);
    let cell = (o + dir * (t / lv.cell_size)).floor();
    ray_box(o, safe_inverse(dir), cell, cell + Vec3::ONE).y + 1.0e-3
}

/// Settings of the voxel trace (WGSL `HaoSettings`, the parts the trace reads).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceSettings {
    /// Rays per pixel.
    pub rays: u32,
    /// Texel visits per ray.
    pub steps: u32,
    /// World units.
    pub max_distance: f32,
    /// Falloff exponent.
    pub falloff: f32,
    /// Scale of the occlusion.
    pub intensity: f32,
    /// Rays start this many cells off the surface along its normal, and skip as many along their path.
    pub start_offset: f32,
    /// Rays pass through the backs of surfaces ([`back_hit_exit`]), where the voxels have attributes.
    pub ignore_back_hits: bool,
    /// Each ray's first cells are traced in the depth prepass ([`super::contacts`]), and its voxel hits
    /// within [`NEAR_FREE_SPACE_CELLS`] of the surface that the view shows in free space are passed, where
    /// a view's depth is given.
    pub depth_contacts: bool,
    /// A voxel hit the view's depth shows in free space is passed
    /// ([`super::contacts::ViewDepth::shows_free_space`]), where a view's depth is given.
    pub depth_free_space: bool,
    /// Points each ray's depth contacts sample in the depth prepass ([`super::contacts::depth_contact`]).
    pub contact_samples: u32,
}

/// Voxel ambient occlusion at one world-space surface point through the levels of the volume (one for a
/// single grid), without depth contacts. 1 = open, 0 = occluded.
pub fn voxel_ambient_occlusion(
    levels: &[TraceLevel],
    world: Vec3,
    normal: Vec3,
    rotation: Vec2,
    s: &TraceSettings,
) -> f32 {
    voxel_ambient_occlusion_counted(levels, None, world, normal, rotation, s, &mut TraceWork::default())
}

/// What the depth contacts read: the view's depth prepass, and the jitter of the points they sample.
#[derive(Clone, Copy)]
pub struct DepthContacts<'a> {
    /// The view's depth prepass.
    pub view: &'a ViewDepth,
    /// A pixel's contact jitter ([`super::contacts::contact_jitter`]) for [`voxel_ambient_occlusion_counted`],
    /// which turns it for each ray; one ray's ([`super::contacts::ray_jitter`]) for [`ray_occluder`].
    pub jitter: f32,
}

/// Ambient occlusion at one world-space surface point (WGSL: the body of `trace`), through the levels of
/// the volume and, with `contacts` and [`TraceSettings::depth_contacts`], the depth prepass for each ray's
/// first cells, adding the work it did to `work`. 1 = open, 0 = occluded.
pub fn voxel_ambient_occlusion_counted(
    levels: &[TraceLevel],
    contacts: Option<DepthContacts>,
    world: Vec3,
    normal: Vec3,
    rotation: Vec2,
    s: &TraceSettings,
    work: &mut TraceWork,
) -> f32 {
    let mut occlusion = 0.0;
    let basis = orthonormal_basis(normal);
    work.rays += u64::from(s.rays);
    for i in 0..s.rays {
        let dir = hemisphere_direction(basis, i, s.rays, rotation);
        let start = ray_start_level(levels, world, i, rotation);
        let contact = contacts.map(|c| DepthContacts { jitter: ray_jitter(c.jitter, i), ..c });
        if let Some(d) = ray_occluder(levels, contact, world, normal, dir, start, s, work) {
            work.hits += 1;
            occlusion += ao_falloff(d, s.max_distance, s.falloff);
        }
    }
    (1.0 - s.intensity * occlusion / s.rays as f32).clamp(0.0, 1.0)
}

/// The distance from the surface point `world` (normal `normal`) to the occluder that ray `dir`, starting in
/// level `start`, finds within `s.max_distance`, or `None` (WGSL: the body of the ray loop in `trace`): with
/// `contact` (the view's depth and this ray's jitter) and [`TraceSettings::depth_contacts`], first a contact
/// in the depth prepass along its first [`CONTACT_LENGTH`] cells per cell of start offset, which stops it;
/// where the view hides the march's start, a hit in those cells' voxels past the surface's own
/// ([`super::near`]), which stops it too; then the voxels ([`voxel_ray_occluder`]).
#[allow(clippy::too_many_arguments)]
pub fn ray_occluder(
    levels: &[TraceLevel],
    contact: Option<DepthContacts>,
    world: Vec3,
    normal: Vec3,
    dir: Vec3,
    start: usize,
    s: &TraceSettings,
    work: &mut TraceWork,
) -> Option<f32> {
    // Without a start offset the march starts at the surface, and there is nothing for the contacts to do.
    if let Some(DepthContacts { view, jitter }) = contact.filter(|_| s.depth_contacts && s.start_offset > 0.0) {
        let cell = levels[start].cell_size;
        let length = CONTACT_LENGTH * s.start_offset * cell;
        let samples = s.contact_samples;
        // Where the view hides the march's start, it may lie inside an occluder: the contacts' thickness is
        // measured along the normal of the surface the view shows (deeper than a cell along the view, only
        // inside the voxels), and the first cells are also marched in the voxels, past the surface's own.
        let hidden = hides_origin(view, world + normal * (s.start_offset * cell), &mut work.depth_loads);
        let loads = &mut work.depth_loads;
        let grazing = hidden.then_some(&levels[start]);
        if let Some(t) = depth_contact(view, world, normal, dir, cell, length, samples, jitter, grazing, loads) {
            work.contacts += 1;
            return Some(t);
        }
        if hidden {
            let reach = CONTACT_LENGTH * s.start_offset;
            let near = near_voxel_hit(&levels[start], Some(view), world, normal, dir, reach, &mut work.depth_loads);
            work.near_voxel_marches += 1;
            work.texel_visits += u64::from(near.visits);
            if let Some(d) = near.distance {
                work.near_voxel_hits += 1;
                return Some(d);
            }
        }
    }
    voxel_ray_occluder(levels, contact.map(|c| c.view), world, normal, dir, start, s, work).map(|o| o.distance)
}

/// The occluder one ray of [`voxel_ambient_occlusion`] finds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelOccluder {
    /// World distance from the surface point to the occluder, as the falloff takes it: half a cell past the
    /// entry into the first occupied cell.
    pub distance: f32,
    /// The level whose cell stopped the ray.
    pub level: usize,
}

/// The occluder that ray `dir` from the surface point `world` (normal `normal`), starting in level `start`,
/// finds within `s.max_distance`, or `None` (WGSL: the body of the ray loop in `trace`). With `view`, the
/// hits near the surface that it shows in free space are passed ([`TraceSettings::depth_contacts`]), and
/// with [`TraceSettings::depth_free_space`] the others too, by a wider margin.
#[allow(clippy::too_many_arguments)]
pub fn voxel_ray_occluder(
    levels: &[TraceLevel],
    view: Option<&ViewDepth>,
    world: Vec3,
    normal: Vec3,
    dir: Vec3,
    start: usize,
    s: &TraceSettings,
    work: &mut TraceWork,
) -> Option<VoxelOccluder> {
    let origin = world + normal * (s.start_offset * levels[start].cell_size);
    let mut march = March::new(levels, origin, dir, start, s.start_offset, s.max_distance, s.steps);
    let mut hit = march.run();
    // Through the backs of surfaces, a few times at most, each with the whole step budget.
    for _ in 0..MAX_BACK_HITS {
        let Some(h) = hit.filter(|_| s.ignore_back_hits) else { break };
        work.normal_loads += 1;
        let Some(exit) = back_hit_exit(levels, origin, dir, h) else { break };
        march.resume(exit, s.steps);
        hit = march.run();
    }
    // Past the cells near the surface that the view shows empty, by a pixel, where the trace takes their
    // surface to be; the march goes on with the steps it has left.
    let first = march.visits();
    if let Some(view) = view.filter(|_| s.depth_contacts) {
        let near = NEAR_FREE_SPACE_CELLS * levels[start].cell_size;
        for _ in 0..MAX_NEAR_FREE_SPACE_PASSES {
            let Some((t, level)) = hit.filter(|_| march.steps_left() > 0) else { break };
            // The point at the hit's distance on the ray from the surface itself, which the lift moved the
            // march's off: near an occluder overhead the lifted ray crosses cells the ray misses.
            let distance = (origin + dir * (t + 0.5 * levels[level].cell_size) - world).length();
            if distance > near {
                break;
            }
            let surface = world + dir * distance;
            let margin = NEAR_FREE_SPACE_PIXELS * view.pixel_size((view.clip_from_world * surface.extend(1.0)).w);
            if !view.shows_free_space(surface, margin, &mut work.depth_loads) {
                break;
            }
            work.near_free_space_passes += 1;
            march.resume(cell_exit(levels, origin, dir, (t, level)), march.steps_left());
            hit = march.run();
        }
    }
    work.near_free_space_visits += march.visits() - first;
    // Past the cells the view shows empty where the trace takes their surface to be, a few times at most,
    // each with the whole step budget.
    if let Some(view) = view.filter(|_| s.depth_free_space) {
        for pass in 0..MAX_FREE_SPACE_PASSES as usize {
            let Some((t, level)) = hit else { break };
            let cell = levels[level].cell_size;
            let surface = origin + dir * (t + 0.5 * cell);
            if !view.shows_free_space(surface, FREE_SPACE_MARGIN * cell, &mut work.depth_loads) {
                break;
            }
            work.free_space_passes += 1;
            let before = march.visits();
            march.resume(cell_exit(levels, origin, dir, (t, level)), s.steps);
            hit = march.run();
            work.free_space_visits[pass] += march.visits() - before;
        }
    }
    work.texel_visits += march.visits();
    if hit.is_none() && march.out_of_steps() {
        work.out_of_steps += 1;
    }
    // The surface lies somewhere in the first occupied cell, on average half a cell past its entry.
    hit.map(|(t, level)| VoxelOccluder {
        distance: (origin + dir * (t + 0.5 * levels[level].cell_size) - world).length(),
        level,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::VoxelGrid;
    use crate::cpu::grid::VoxelOccupancy;
    use crate::cpu::march::{VoxelMips, march_cascades, ray_start_level};
    use glam::{IVec3, UVec3};

    #[test]
    fn a_checkerboard_traces_half_the_blocks_a_frame_and_every_pixel_every_eighth() {
        use glam::UVec2;
        let (view, trace) = (UVec2::new(10, 6), UVec2::new(5, 3));
        let mut traced = vec![0; 60];
        for frame in 40..48 {
            // The trace pass's invocations (half the width, rounded up) cover exactly the texels traced.
            let mut from_invocations: Vec<UVec2> = (0..trace.y)
                .flat_map(|y| (0..trace.x.div_ceil(2)).map(move |x| UVec2::new(x, y)))
                .map(|id| checkerboard_texel(id, frame, true))
                .filter(|t| t.x < trace.x)
                .collect();
            from_invocations.sort_by_key(|t| (t.y, t.x));
            let texels: Vec<UVec2> = (0..trace.y)
                .flat_map(|y| (0..trace.x).map(move |x| UVec2::new(x, y)))
                .filter(|&t| texel_traced(t, frame, true))
                .collect();
            assert_eq!(from_invocations, texels, "frame {frame}");
            // A checkerboard: no two traced texels side by side.
            assert!(texels.iter().all(|t| !texel_traced(*t + UVec2::X, frame, true)));
            for t in texels {
                let p = traced_pixel(t, trace_turn(frame, true), view, true);
                traced[(p.y * view.x + p.x) as usize] += 1;
            }
        }
        assert!(traced.iter().all(|&n| n == 1), "{traced:?}");
        // Without the checkerboard every texel, every frame, and the frame turns the pixel.
        assert!(texel_traced(UVec2::new(3, 0), 0, false) && checkerboard_texel(UVec2::new(3, 0), 0, false).x == 3);
        assert_eq!(trace_turn(7, false), 7);
        assert_eq!(noise_frame(trace_turn(47, true), true), 47 / 8, "each of a pixel's traces turns the noise");
    }

    /// 64 rays of 64 steps reaching 8 cells, starting a cell off.
    fn trace_settings(falloff: f32, ignore_back_hits: bool) -> TraceSettings {
        TraceSettings {
            rays: 64,
            steps: 64,
            max_distance: 8.0,
            falloff,
            intensity: 1.0,
            start_offset: 1.0,
            ignore_back_hits,
            depth_contacts: false,
            depth_free_space: false,
            contact_samples: crate::cpu::contacts::CONTACT_SAMPLES,
        }
    }

    #[test]
    fn hemisphere_directions_are_unit_cosine_weighted_and_above_the_surface() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let count = 4096;
        let mut mean_cos = 0.0;
        for i in 0..count {
            let d = hemisphere_direction(orthonormal_basis(n), i, count, Vec2::new(0.37, 0.81));
            assert!((d.length() - 1.0).abs() < 1e-4);
            assert!(d.dot(n) >= -1e-6);
            mean_cos += d.dot(n);
        }
        // E[cos] under a cosine-weighted distribution is 2/3.
        assert!((mean_cos / count as f32 - 2.0 / 3.0).abs() < 0.01);
        let b = orthonormal_basis(n);
        assert!(b.x_axis.dot(n).abs() < 1e-5 && b.y_axis.dot(n).abs() < 1e-5 && b.x_axis.dot(b.y_axis).abs() < 1e-5);
    }

    #[test]
    fn falloff_runs_from_one_to_zero() {
        assert_eq!(ao_falloff(0.0, 2.0, 1.0), 1.0);
        assert_eq!(ao_falloff(1.0, 2.0, 1.0), 0.5);
        assert_eq!(ao_falloff(3.0, 2.0, 1.0), 0.0);
        assert_eq!(ao_falloff(1.0, 2.0, 2.0), 0.25);
    }

    #[test]
    fn the_work_counted_is_the_marches_loads() {
        // A 32^3 grid with a floor at z = 0: rays from above it, looking down, hit but for the most grazing
        // (past max_distance); looking up, none do.
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(32)).unwrap();
        let occ = VoxelOccupancy::new(grid, false);
        for y in 0..32 {
            for x in 0..32 {
                occ.set(UVec3::new(x, y, 0));
            }
        }
        let mips = VoxelMips::new(&occ, 4);
        let level = [TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: &mips }];
        let s = trace_settings(1.0, false);
        let p = Vec3::new(16.2, 16.3, 4.5);
        let mut down = TraceWork::default();
        let ao = voxel_ambient_occlusion_counted(&level, None, p, Vec3::NEG_Z, Vec2::new(0.3, 0.7), &s, &mut down);
        assert_eq!(ao, voxel_ambient_occlusion(&level, p, Vec3::NEG_Z, Vec2::new(0.3, 0.7), &s));
        assert_eq!((down.rays, down.out_of_steps, down.normal_loads), (64, 0, 0));
        assert!(down.hits >= 48, "{down:?}");
        // Each ray's visits: at least the descent to the hit, at most the budget.
        assert!(down.texel_visits >= 64 * 3 && down.texel_visits <= 64 * 64, "{down:?}");
        let mut up = TraceWork::default();
        voxel_ambient_occlusion_counted(&level, None, p, Vec3::Z, Vec2::new(0.3, 0.7), &s, &mut up);
        assert_eq!((up.rays, up.hits), (64, 0));
        // Empty space is stepped over on the mips: fewer visits than the 8 cells each ray crosses.
        assert!(up.texel_visits < 64 * 8, "{up:?}");
        // One step a ray: every march runs out of steps.
        let mut starved = TraceWork::default();
        voxel_ambient_occlusion_counted(
            &level,
            None,
            p,
            Vec3::NEG_Z,
            Vec2::ZERO,
            &TraceSettings { steps: 1, ..s },
            &mut starved,
        );
        assert_eq!((starved.texel_visits, starved.out_of_steps, starved.hits), (64, 64, 0));
    }

    #[test]
    fn the_march_finds_the_first_occupied_cell_and_skips_empty_space() {
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::new(40, 20, 20)).unwrap();
        let occ = VoxelOccupancy::new(grid, false);
        // A wall at x = 30.
        for y in 0..20 {
            for z in 0..20 {
                occ.set(UVec3::new(30, y, z));
            }
        }
        let mips = VoxelMips::new(&occ, 4);
        let t = mips.march_level(Vec3::new(2.5, 10.5, 10.5), Vec3::X, 0.0, 100.0, 2, 64).hit.unwrap();
        assert!((t - 27.5).abs() < 0.01, "{t}");
        // Empty space is crossed in few steps: 27 cells with 12 texel visits at most.
        assert!(mips.march_level(Vec3::new(2.5, 10.5, 10.5), Vec3::X, 0.0, 100.0, 2, 12).hit.is_some());
        // Away from the wall, nothing; beyond t_end, nothing.
        assert!(mips.march_level(Vec3::new(2.5, 10.5, 10.5), -Vec3::X, 0.0, 100.0, 2, 64).hit.is_none());
        assert!(mips.march_level(Vec3::new(2.5, 10.5, 10.5), Vec3::X, 0.0, 20.0, 2, 64).hit.is_none());
        // A diagonal ray hits too.
        let d = Vec3::new(1.0, 0.3, -0.2).normalize();
        let t = mips.march_level(Vec3::new(2.5, 5.5, 12.5), d, 0.0, 100.0, 2, 64).hit.unwrap();
        assert!(((Vec3::new(2.5, 5.5, 12.5) + d * t).x - 30.0).abs() < 0.01);
        // An open floor sees no occlusion; facing the wall from close by does.
        let s = trace_settings(1.0, true);
        let level = [TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: &mips }];
        let open = voxel_ambient_occlusion(&level, Vec3::new(10.5, 10.5, 10.5), -Vec3::X, Vec2::ZERO, &s);
        let near = voxel_ambient_occlusion(&level, Vec3::new(28.0, 10.5, 10.5), Vec3::X, Vec2::ZERO, &s);
        assert_eq!(open, 1.0);
        assert!(near < 0.6, "{near}");
        // One ray straight at the wall from x = 24.5: it starts a cell off along the normal, skips a cell
        // along its way and finds the wall's cell (entered at x = 30) at half a cell past its entry.
        let mut work = TraceWork::default();
        let hit =
            voxel_ray_occluder(&level, None, Vec3::new(24.5, 10.5, 10.5), Vec3::X, Vec3::X, 0, &s, &mut work).unwrap();
        assert_eq!(hit.level, 0);
        assert!((hit.distance - 6.0).abs() < 0.01, "{hit:?}");
        assert!(work.texel_visits > 0);
        // Away from the wall, none.
        assert!(
            voxel_ray_occluder(&level, None, Vec3::new(24.5, 10.5, 10.5), -Vec3::X, -Vec3::X, 0, &s, &mut work)
                .is_none()
        );
    }

    #[test]
    fn rays_go_on_in_the_coarser_cascade_and_an_occluder_across_the_border_occludes() {
        // Level 0: 32 cells of 1 over [0, 32]^3; level 1: 32 cells of 2 over [-16, 48]^3.
        let g0 = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(32)).unwrap();
        let g1 = VoxelGrid::new(Vec3::splat(-16.0), 2.0, UVec3::splat(32)).unwrap();
        let (o0, o1) = (VoxelOccupancy::new(g0, false), VoxelOccupancy::new(g1, false));
        // A wall at x = 40 (outside level 0) and one at x = 33 (just across its border).
        for y in 0..32 {
            for z in 0..32 {
                o1.set(UVec3::new(28, y, z));
                o1.set(UVec3::new(24, y, z));
            }
        }
        let (m0, m1) = (VoxelMips::new(&o0, 4), VoxelMips::new(&o1, 4));
        let levels = [
            TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: &m0 },
            TraceLevel { origin: Vec3::ZERO, cell_size: 2.0, window_min: IVec3::splat(-8), mips: &m1 },
        ];
        // From x = 20 along +x: no hit in level 0, then the wall at x = 32..34 in level 1, about 12 away.
        let (t, level) = march_cascades(&levels, Vec3::new(20.0, 16.5, 16.5), Vec3::X, 0, 0.0, 30.0, 64).unwrap();
        assert_eq!(level, 1);
        assert!((t - 12.0).abs() <= 2.0, "{t}");
        // Within the max distance only.
        assert!(march_cascades(&levels, Vec3::new(20.0, 16.5, 16.5), Vec3::X, 0, 0.0, 8.0, 64).is_none());
        // A floor point just inside level 0's border, facing the wall across it, is occluded; deep inside the
        // level, facing away, it is open.
        let s = trace_settings(1.0, true);
        let near = voxel_ambient_occlusion(&levels, Vec3::new(29.0, 16.5, 16.5), Vec3::X, Vec2::new(0.3, 0.7), &s);
        let open = voxel_ambient_occlusion(&levels, Vec3::new(16.0, 16.5, 16.5), -Vec3::X, Vec2::new(0.3, 0.7), &s);
        assert!(near < 0.85, "{near}");
        assert_eq!(open, 1.0);
        // The start level moves from 0 to 1 across the blend band near level 0's border.
        let starts: Vec<usize> = (0..64)
            .map(|i| ray_start_level(&levels, Vec3::new(16.0 * (i % 2) as f32, 16.0, 16.0), i, Vec2::ZERO))
            .collect();
        assert!(starts.iter().step_by(2).all(|&l| l == 1) && starts.iter().skip(1).step_by(2).all(|&l| l == 0));
    }

    #[test]
    fn rays_pass_through_the_back_of_a_single_sided_surface_and_stop_at_its_front() {
        use crate::cpu::attributes::MeshAlbedo;
        use crate::cpu::{InjectionRegion, TriangleMesh, VoxelizeSettings, voxelize_sampled_mesh_in_region};
        // A quad at y = 10.5 facing up (counter-clockwise seen from above), and a closed box beside it.
        let quad = TriangleMesh::new(
            vec![
                Vec3::new(2.0, 10.5, 2.0),
                Vec3::new(2.0, 10.5, 18.0),
                Vec3::new(18.0, 10.5, 18.0),
                Vec3::new(18.0, 10.5, 2.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(20)).unwrap();
        let occ = VoxelOccupancy::with_attributes(grid);
        let region = InjectionRegion::whole(grid.dims);
        let settings = VoxelizeSettings::default();
        voxelize_sampled_mesh_in_region(&quad, &MeshAlbedo::WHITE, grid.grid_from_world(), &settings, &region, &occ);
        let mips = VoxelMips::new(&occ, 3);
        assert!(mips.normal(IVec3::new(10, 10, 10)).distance(Vec3::Y) < 0.01);
        let level = [TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: &mips }];
        let trace = |ignore_back_hits: bool, world: Vec3, normal: Vec3| {
            let s = trace_settings(0.0, ignore_back_hits);
            voxel_ambient_occlusion(&level, world, normal, Vec2::ZERO, &s)
        };
        // From below, looking up at the quad's back: occluded, unless back hits are ignored; then the rays
        // within 60 degrees of its normal pass (a quarter of cosine-weighted rays are further off: they
        // still stop).
        let below = Vec3::new(10.0, 8.0, 10.0);
        let (stopped, passed) = (trace(false, below, Vec3::Y), trace(true, below, Vec3::Y));
        assert!(stopped < 0.1 && (0.65..0.85).contains(&passed), "{stopped} {passed}");
        // From above, looking down at its front: occluded either way.
        let above = Vec3::new(10.0, 13.0, 10.0);
        assert!(trace(true, above, -Vec3::Y) < 0.2);
        // Without attributes there are no normals: the setting changes nothing.
        let plain = VoxelMips::new(&VoxelOccupancy::from_words(grid, &occ.words(), None).unwrap(), 3);
        let level = [TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: &plain }];
        let s = trace_settings(0.0, true);
        assert!(voxel_ambient_occlusion(&level, below, Vec3::Y, Vec2::ZERO, &s) < 0.2);
    }
}
