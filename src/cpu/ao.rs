//! The CPU twin of the hybrid ambient occlusion trace (`src/ao/hao_trace.wgsl`, `hao_common.wgsl`): ray
//! directions, falloff, and the march through the voxel grid with empty-space skipping, with the same names
//! and operations as the WGSL. The ray-traced reference that HAO is measured against (rays against the real
//! triangles) shares [`hemisphere_direction`] and [`ao_falloff`] with it.

use super::contacts::{
    CONTACT_LENGTH, FREE_SPACE_MARGIN, MAX_FREE_SPACE_PASSES, MAX_NEAR_FREE_SPACE_PASSES, NEAR_FREE_SPACE_CELLS,
    NEAR_FREE_SPACE_PIXELS, ViewDepth, depth_contact, ray_jitter,
};
use super::grid::VoxelOccupancy;
use glam::{IVec3, Mat3, UVec3, Vec2, Vec3};
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

/// `1 / d` with zero components replaced by a huge value of the same sign.
pub fn safe_inverse(d: Vec3) -> Vec3 {
    Vec3::select(
        d.abs().cmplt(Vec3::splat(1.0e-30)),
        Vec3::select(d.cmpge(Vec3::ZERO), Vec3::splat(1.0e30), Vec3::splat(-1.0e30)),
        1.0 / d,
    )
}

/// The `(t_enter, t_exit)` of a ray in the box `[lo, hi]` (empty if `t_enter > t_exit`).
pub fn ray_box(origin: Vec3, inv_dir: Vec3, lo: Vec3, hi: Vec3) -> Vec2 {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let (tmin, tmax) = (t0.min(t1), t0.max(t1));
    Vec2::new(tmin.max_element(), tmax.min_element())
}

/// The occupancy as the voxel texture holds it: padded to a multiple of `2^(levels - 1)` per axis, with
/// max-reduced levels (a texel of level `l` is set if any of its `2^l`-cell block is).
pub struct VoxelMips {
    dims: UVec3,
    levels: Vec<(UVec3, Vec<bool>)>,
    /// The cells' average normals as the normal texture holds them (8-bit signed), where the occupancy has
    /// attributes.
    normals: Option<Vec<Vec3>>,
}

impl VoxelMips {
    /// Builds the pyramid with `levels` levels (as the plugin does: `VoxelGridAssets::mip_levels`), clamped
    /// to 1..=8.
    pub fn new(occ: &VoxelOccupancy, levels: u32) -> Self {
        let levels = levels.clamp(1, 8);
        let dims = occ.grid().dims;
        let align = 1u32 << (levels - 1);
        let size = (dims + UVec3::splat(align - 1)) / align * align;
        let mut base = vec![false; (size.x * size.y * size.z) as usize];
        occ.for_each_set_index(|i| {
            let c = occ.grid().cell_of_index(i);
            base[(c.x + size.x * (c.y + size.y * c.z)) as usize] = true;
        });
        let mut out = vec![(size, base)];
        for _ in 1..levels {
            let (prev_size, prev) = out.last().expect("level 0 exists");
            let s = *prev_size / 2;
            let mut cur = vec![false; (s.x * s.y * s.z) as usize];
            for z in 0..s.z {
                for y in 0..s.y {
                    for x in 0..s.x {
                        let mut any = false;
                        for k in 0..8u32 {
                            let c = UVec3::new(2 * x + (k & 1), 2 * y + ((k >> 1) & 1), 2 * z + (k >> 2));
                            any |= prev[(c.x + prev_size.x * (c.y + prev_size.y * c.z)) as usize];
                        }
                        cur[(x + s.x * (y + s.y * z)) as usize] = any;
                    }
                }
            }
            out.push((s, cur));
        }
        // The normal texture's precision: Rgba8Snorm.
        let snorm = |v: Vec3| (v.clamp(Vec3::NEG_ONE, Vec3::ONE) * 127.0).round() / 127.0;
        let normals = occ.has_attributes().then(|| {
            (0..occ.grid().voxel_count() as u32)
                .map(|i| occ.attributes(occ.grid().cell_of_index(i)).map_or(Vec3::ZERO, |a| snorm(a.normal)))
                .collect()
        });
        Self { dims, levels: out, normals }
    }

    /// The average normal of cell `cell` as the normal texture holds it (WGSL: `voxel_normal_at`): clamped
    /// to the padded texture, zero in its padding and without attributes.
    pub fn normal(&self, cell: IVec3) -> Vec3 {
        let Some(n) = &self.normals else { return Vec3::ZERO };
        let c = cell.clamp(IVec3::ZERO, self.levels[0].0.as_ivec3() - IVec3::ONE).as_uvec3();
        if c.cmpge(self.dims).any() {
            return Vec3::ZERO;
        }
        n[(c.x + self.dims.x * (c.y + self.dims.y * c.z)) as usize]
    }

    fn load(&self, texel: IVec3, level: usize) -> bool {
        let (s, v) = &self.levels[level];
        let c = texel.clamp(IVec3::ZERO, s.as_ivec3() - IVec3::ONE).as_uvec3();
        v[(c.x + s.x * (c.y + s.y * c.z)) as usize]
    }

    /// The cells per axis of level 0 (the occupancy's dimensions).
    pub fn dims(&self) -> UVec3 {
        self.dims
    }

    /// The distance along `dir` (grid units, from `origin`) to the entry of the first run of occupied cells
    /// within `[t_start, t_end]` that the ray goes [`MIN_OCCLUDING_CHORD`] through, if any, and how many texel
    /// visits were left: start at mip `start_level`, step over empty texels whole, descend into occupied ones,
    /// visiting at most `steps` texels (WGSL: `march_level`).
    /// After a step it goes up a mip only where the step entered another texel of the mip above: within the
    /// same one, that texel is the one it descended from (occupied: reading it again would be a wasted visit)
    /// or one it has not read, which near a surface, where rays start, is most often occupied too (going up
    /// into those as well measured more visits). With [`MARCH_START_MIP`], this costs 17-21 % fewer visits a
    /// ray than going up after every step from mip 2 on the cathedral, Sibenik and Sponza (`bench_ao`'s work
    /// table; docs/figures.md).
    pub fn march_level(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_start: f32,
        t_end: f32,
        start_level: usize,
        steps: u32,
    ) -> MarchResult {
        let inv = safe_inverse(dir);
        let span = ray_box(origin, inv, Vec3::ZERO, self.dims.as_vec3());
        let mut t = t_start.max(span.x);
        let t_max = t_end.min(span.y);
        let top = self.levels.len() - 1;
        let mut level = start_level.min(top);
        let mut left = steps;
        // The texel last stepped over (unclamped), if the last visit was such a step.
        let mut last: Option<IVec3> = None;
        // The run of occupied cells the ray is in: where it entered it, and how far it has gone through it.
        let mut run_start = 0.0f32;
        let mut run_length = 0.0f32;
        while left > 0 {
            if t > t_max {
                return MarchResult { hit: None, steps_left: left };
            }
            left -= 1;
            let p = origin + dir * t;
            let mut texel = (p * (1.0 / (1u32 << level) as f32)).floor().as_ivec3();
            // After a step that entered another texel of the mip above, that one.
            if last.is_some_and(|last| level < top && texel >> 1 != last >> 1) {
                level += 1;
                texel >>= 1;
            }
            let scale = (1u32 << level) as f32;
            let size = self.levels[level].0.as_ivec3();
            let clamped = texel.clamp(IVec3::ZERO, size - IVec3::ONE);
            let lo = clamped.as_vec3() * scale;
            let exit = ray_box(origin, inv, lo, lo + Vec3::splat(scale)).y;
            let occupied = self.load(clamped, level);
            // A run of occupied cells stops the ray once it has gone MIN_OCCLUDING_CHORD through it; a cell it
            // only clips is passed, as an empty one.
            if occupied && level == 0 {
                if run_length == 0.0 {
                    run_start = t;
                }
                run_length += exit - t;
                if run_length >= MIN_OCCLUDING_CHORD {
                    return MarchResult { hit: Some(run_start), steps_left: left };
                }
            } else if !occupied {
                run_length = 0.0;
            }
            if occupied && level > 0 {
                level -= 1;
                last = None;
            } else {
                t = exit.max(t) + 1.0e-3;
                last = Some(texel);
            }
        }
        MarchResult { hit: None, steps_left: 0 }
    }
}

/// What a march through one level found (WGSL: `MarchResult`, with `t < 0` for no hit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarchResult {
    /// The distance to the entry of the run of occupied cells that stopped the ray, in the level's cells.
    pub hit: Option<f32>,
    /// Texel visits left.
    pub steps_left: u32,
}

/// One level of the voxel volume as the trace reads it (WGSL: `VoxelLevel` of `voxel_grid.wgsl`): a single
/// grid, or one cascade level with its occupancy stored relative to its window.
#[derive(Clone, Copy)]
pub struct TraceLevel<'a> {
    /// World position of lattice cell 0 (the world origin for cascades, the grid's min corner otherwise).
    pub origin: Vec3,
    /// World-space cell size.
    pub cell_size: f32,
    /// The lattice cell at the window's min corner (0 for a single grid).
    pub window_min: IVec3,
    /// The window's occupancy pyramid.
    pub mips: &'a VoxelMips,
}

impl TraceLevel<'_> {
    /// World space to the window's cells (WGSL: `level_position`).
    pub fn level_position(&self, world: Vec3) -> Vec3 {
        (world - self.origin) / self.cell_size - self.window_min.as_vec3()
    }
}

/// The width, in the level's cells, of the band over which rays move from one level to the next.
pub const CASCADE_BLEND_CELLS: f32 = 8.0;

/// How many of a surface point's rays may start in a level (WGSL: `level_weight`): 1 when the point lies
/// at least [`CASCADE_BLEND_CELLS`] cells inside the window, falling to 0 at its border. `p` in the window's
/// cells. Rays that leave the window go on in coarser levels; starting them in the finest level that holds
/// the surface (rather than one that holds their whole reach) measured better against the ray-traced
/// reference on the cathedral, Sibenik and Sponza.
pub fn level_weight(p: Vec3, dims: UVec3) -> f32 {
    let margin = p.min(dims.as_vec3() - p).min_element();
    (margin / CASCADE_BLEND_CELLS).clamp(0.0, 1.0)
}

/// The level ray `i` starts in (WGSL: `ray_start_level`): the finest whose [`level_weight`] exceeds the
/// ray's own number in `[0, 1)`, so that across the blend band rays move to the coarser level in proportion
/// and no seam shows; the coarsest level takes what no finer one does.
pub fn ray_start_level(levels: &[TraceLevel], world: Vec3, i: u32, rotation: Vec2) -> usize {
    let u = (i as f32 * 0.754_877_7 + rotation.x + rotation.y).fract();
    let last = levels.len() - 1;
    for (l, level) in levels[..last].iter().enumerate() {
        let w = level_weight(level.level_position(world), level.mips.dims());
        if w > u {
            return l;
        }
    }
    last
}

/// How far a ray must go through a run of occupied cells (consecutive along it, in the level's cells) before
/// they stop it, at the run's entry (WGSL: `MIN_OCCLUDING_CHORD`): `1 / sqrt(3)`, half a cell's diagonal. A
/// cell holds some surface, not a solid cube, and a ray that only clips a corner or an edge of a lone cell most
/// often passes that surface by: stopping at every cell a ray touches made occluders up to a cell thicker and
/// darkened every scene measured (docs/figures.md). Through a wall or a floor one cell thick the run is at
/// least a cell long at any angle, so it is not passed through. 0.5 measured about the same.
pub const MIN_OCCLUDING_CHORD: f32 = 0.577_350_3;

/// The mip a march starts at in each level (WGSL: `MARCH_START_MIP`). A ray starts about a cell from the
/// surface, whose coarse texels are occupied: starting at mip 1 spares most of the descent to mip 0.
pub const MARCH_START_MIP: usize = 1;

/// The world-space distance along `dir` from `origin` to the first run of occupied voxels that stops it
/// ([`MIN_OCCLUDING_CHORD`]) within `t_end` (world units), and the level it is in, starting in level `start`
/// at `t_start` of its cells, or `None` (WGSL: `march_cascades`). A ray that leaves a level's window goes on
/// in the next coarser level from where it left (so an occluder just across the border occludes).
pub fn march_cascades(
    levels: &[TraceLevel],
    origin: Vec3,
    dir: Vec3,
    start: usize,
    t_start: f32,
    t_end: f32,
    steps: u32,
) -> Option<(f32, usize)> {
    march_cascades_left(levels, origin, dir, start, t_start, t_end, steps, &mut TraceWork::default()).0
}

/// [`march_cascades`], adding the texel visits it made to `work` (and whether it ran out of steps), and
/// returning the steps it has left too (WGSL: `march_cascades_left`, which returns them as the hit's third
/// component).
#[allow(clippy::too_many_arguments)]
fn march_cascades_left(
    levels: &[TraceLevel],
    origin: Vec3,
    dir: Vec3,
    start: usize,
    t_start: f32,
    t_end: f32,
    steps: u32,
    work: &mut TraceWork,
) -> (Option<(f32, usize)>, u32) {
    let inv = safe_inverse(dir);
    let mut level = start;
    let mut t0 = t_start;
    let mut left = steps;
    loop {
        let lv = &levels[level];
        let o = lv.level_position(origin);
        let t1 = t_end / lv.cell_size;
        let r = lv.mips.march_level(o, dir, t0, t1, MARCH_START_MIP, left);
        work.texel_visits += u64::from(left - r.steps_left);
        if let Some(t) = r.hit {
            return (Some((t * lv.cell_size, level)), r.steps_left);
        }
        left = r.steps_left;
        if left == 0 {
            work.out_of_steps += 1;
            return (None, 0);
        }
        if level + 1 >= levels.len() {
            return (None, left);
        }
        let exit = ray_box(o, inv, Vec3::ZERO, lv.mips.dims().as_vec3()).y;
        if exit >= t1 {
            return (None, left);
        }
        let next = &levels[level + 1];
        t0 = exit.max(t0) * lv.cell_size / next.cell_size;
        level += 1;
    }
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
/// then the voxels ([`voxel_ray_occluder`]).
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
        if let Some(t) = depth_contact(view, world, normal, dir, cell, length, samples, jitter, &mut work.depth_loads) {
            work.contacts += 1;
            return Some(t);
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
    let (mut hit, mut left) =
        march_cascades_left(levels, origin, dir, start, s.start_offset, s.max_distance, s.steps, work);
    // Through the backs of surfaces, a few times at most.
    for _ in 0..MAX_BACK_HITS {
        let Some(h) = hit.filter(|_| s.ignore_back_hits) else { break };
        work.normal_loads += 1;
        let Some(exit) = back_hit_exit(levels, origin, dir, h) else { break };
        (hit, left) = march_cascades_left(levels, origin, dir, h.1, exit, s.max_distance, s.steps, work);
    }
    // Past the cells near the surface that the view shows empty, by a pixel, where the trace takes their
    // surface to be; the march goes on with the steps it has left.
    if let Some(view) = view.filter(|_| s.depth_contacts) {
        let near = NEAR_FREE_SPACE_CELLS * levels[start].cell_size;
        for _ in 0..MAX_NEAR_FREE_SPACE_PASSES {
            let Some((t, level)) = hit.filter(|_| left > 0) else { break };
            let surface = origin + dir * (t + 0.5 * levels[level].cell_size);
            if (surface - world).length() > near {
                break;
            }
            let margin = NEAR_FREE_SPACE_PIXELS * view.pixel_size((view.clip_from_world * surface.extend(1.0)).w);
            if !view.shows_free_space(surface, margin, &mut work.depth_loads) {
                break;
            }
            work.near_free_space_passes += 1;
            let exit = cell_exit(levels, origin, dir, (t, level));
            let before = work.texel_visits;
            (hit, left) = march_cascades_left(levels, origin, dir, level, exit, s.max_distance, left, work);
            work.near_free_space_visits += work.texel_visits - before;
        }
    }
    // Past the cells the view shows empty where the trace takes their surface to be, a few times at most.
    if let Some(view) = view.filter(|_| s.depth_free_space) {
        for pass in 0..MAX_FREE_SPACE_PASSES as usize {
            let Some((t, level)) = hit else { break };
            let cell = levels[level].cell_size;
            let surface = origin + dir * (t + 0.5 * cell);
            if !view.shows_free_space(surface, FREE_SPACE_MARGIN * cell, &mut work.depth_loads) {
                break;
            }
            work.free_space_passes += 1;
            let exit = cell_exit(levels, origin, dir, (t, level));
            let before = work.texel_visits;
            hit = march_cascades_left(levels, origin, dir, level, exit, s.max_distance, s.steps, work).0;
            work.free_space_visits[pass] += work.texel_visits - before;
        }
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
    fn a_ray_that_clips_a_cell_passes_it_and_a_ray_through_a_wall_of_cells_does_not() {
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(32)).unwrap();
        let lone = VoxelOccupancy::new(grid, false);
        lone.set(UVec3::splat(16));
        let mips = VoxelMips::new(&lone, 4);
        // Through the middle of the lone cell (a chord of 1): stopped at its entry.
        let through = mips.march_level(Vec3::new(2.5, 16.5, 16.5), Vec3::X, 0.0, 30.0, MARCH_START_MIP, 64);
        assert!(through.hit.is_some_and(|t| (t - 13.5).abs() < 0.01), "{through:?}");
        // Across its corner, a chord of about 0.28: passed.
        let d = Vec3::new(1.0, 1.0, 0.0).normalize();
        let corner = mips.march_level(Vec3::new(2.3, 2.3 + 14.0 - 0.2, 16.5), d, 0.0, 40.0, MARCH_START_MIP, 64);
        assert_eq!(corner.hit, None, "{corner:?}");
        // A wall one cell thick (x = 16) stops every ray that crosses it, at any angle, though each of the cells
        // it goes through may hold only a short piece of it.
        let wall = VoxelOccupancy::new(grid, false);
        for y in 0..32 {
            for z in 0..32 {
                wall.set(UVec3::new(16, y, z));
            }
        }
        let mips = VoxelMips::new(&wall, 4);
        let basis = orthonormal_basis(Vec3::X);
        let mut crossed = 0;
        for i in 0..256 {
            let d = hemisphere_direction(basis, i, 256, Vec2::new(0.37, 0.61));
            let origin = Vec3::new(12.3, 16.1, 15.7);
            // Only rays that cross the whole wall inside the grid (the others leave it through the wall's edge).
            let inside = |x: f32| {
                let p = origin + d * ((x - origin.x) / d.x);
                p.y >= 0.0 && p.y <= 32.0 && p.z >= 0.0 && p.z <= 32.0
            };
            if !(inside(16.0) && inside(17.0)) {
                continue;
            }
            let t = mips.march_level(origin, d, 0.0, 60.0, MARCH_START_MIP, 256).hit;
            assert!(t.is_some_and(|t| ((origin + d * t).x - 16.0).abs() < 0.01), "{d} {t:?}");
            crossed += 1;
        }
        assert!(crossed > 200, "{crossed}");
    }

    #[test]
    fn a_march_along_a_surface_does_not_read_a_texel_it_has_just_left_again() {
        // A floor (z = 0) and a ray along it one cell above (z in [1, 2]): every mip-1 texel it crosses holds
        // floor. Going up after every step would read each mip-1 texel again after each of its two cells (2
        // visits a cell: 58 here); going up only into a new mip-1 texel, 1.5 a cell (44).
        let grid = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::new(32, 32, 32)).unwrap();
        let occ = VoxelOccupancy::new(grid, false);
        for x in 0..32 {
            for y in 0..32 {
                occ.set(UVec3::new(x, y, 0));
            }
        }
        let mips = VoxelMips::new(&occ, 4);
        let r = mips.march_level(Vec3::new(0.5, 10.5, 1.5), Vec3::X, 0.0, 28.0, MARCH_START_MIP, 1000);
        assert_eq!(r.hit, None);
        let visits = 1000 - r.steps_left;
        assert!((40..=46).contains(&visits), "{visits}");
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
