//! The march through the voxel volume (WGSL: `src/voxel/voxel_grid.wgsl`): the occupancy's pyramid of
//! mips as the voxel texture holds it ([`VoxelMips`]), the levels of the volume as the trace reads them
//! ([`TraceLevel`]: one for a single grid, one per cascade), the level each ray starts in, and the
//! empty-space-skipping [`March`] through them, one texel visit at a time.

use super::grid::VoxelOccupancy;
use glam::{IVec3, UVec3, Vec2, Vec3};

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

    /// Whether cell `cell` of the finest level is occupied, clamped to the texture (WGSL: `voxel_occupied` at
    /// mip 0).
    pub fn occupied(&self, cell: IVec3) -> bool {
        self.load(cell, 0)
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
    /// visits were left: start at mip `start_mip`, step over empty texels whole, descend into occupied ones,
    /// visiting at most `steps` texels ([`March`] through this grid alone).
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
        start_mip: usize,
        steps: u32,
    ) -> MarchResult {
        let level = [TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: self }];
        let mut march = March::new(&level, origin, dir, 0, t_start, t_end, steps).with_start_mip(start_mip, t_start);
        let hit = march.run().map(|(t, _)| t);
        MarchResult { hit, steps_left: march.left }
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
    /// World position of lattice cell 0 (for cascades half a finest cell below the world origin, the grid's
    /// min corner otherwise).
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

/// The finest level whose window holds `world` (its border included), or the coarsest (WGSL
/// `finest_level_containing`).
pub fn finest_level_containing(levels: &[TraceLevel], world: Vec3) -> usize {
    let last = levels.len() - 1;
    levels[..last]
        .iter()
        .position(|l| {
            let p = l.level_position(world);
            p.cmpge(Vec3::ZERO).all() && p.cmple(l.mips.dims().as_vec3()).all()
        })
        .unwrap_or(last)
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
    March::new(levels, origin, dir, start, t_start, t_end, steps).run()
}

/// What one visit of a [`March`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Visit {
    /// The march goes on: a texel was visited (or the ray moved to the next coarser level) and nothing
    /// stopped it yet.
    Going,
    /// A run of occupied cells stopped the ray.
    Hit,
    /// The ray left the last level, reached its end, or ran out of visits ([`March::out_of_steps`]).
    Miss,
}

/// A march through the levels of the volume, one texel visit at a time (WGSL: `march_cascades_left`, which
/// runs `march_level` in each level): start in one level at mip [`MARCH_START_MIP`], step over empty texels
/// whole, descend into occupied ones, go up a mip after a step only where it entered another texel of the mip
/// above, stop at the entry of the first run of occupied cells that the ray goes [`MIN_OCCLUDING_CHORD`]
/// through, and go on in the next coarser level where the ray leaves a level's window.
///
/// The trace passes some hits (the backs of surfaces, the near hits and others the view shows in empty
/// space) and goes on past them: [`March::resume`] from the cell's exit, as the WGSL calls
/// `march_cascades_left` again from there (one loop around one march, each pass saying where it resumes).
/// (Folding the passes into the march's own loop, one visit an iteration, cut the visits a warp pays by a
/// sixth in `bench_ao`'s model, but made lavapipe's trace more than twice as long: docs/figures.md.)
pub struct March<'a, 'm> {
    levels: &'a [TraceLevel<'m>],
    origin: Vec3,
    dir: Vec3,
    inv: Vec3,
    t_end: f32,
    start_mip: usize,
    level: usize,
    /// The ray's origin in the level's cells, where it is along the ray and where the level's part of it ends.
    o: Vec3,
    t: f32,
    t_max: f32,
    /// Where the ray leaves the level's window (not before where it entered the level), and whether its end
    /// lies inside the window (then it goes on in no coarser level).
    leave: f32,
    ends_inside: bool,
    mip: usize,
    left: u32,
    visits: u64,
    /// The texel last stepped over (unclamped), if the last visit was such a step.
    last: Option<IVec3>,
    /// The run of occupied cells the ray is in: where it entered it, and how far it has gone through it.
    run_start: f32,
    run_length: f32,
}

impl<'a, 'm> March<'a, 'm> {
    /// A march along `dir` from the world point `origin`, starting in level `start` at `t_start` of its cells,
    /// to `t_end` (world units), of at most `steps` texel visits.
    pub fn new(
        levels: &'a [TraceLevel<'m>],
        origin: Vec3,
        dir: Vec3,
        start: usize,
        t_start: f32,
        t_end: f32,
        steps: u32,
    ) -> Self {
        let mut march = Self {
            levels,
            origin,
            dir,
            inv: safe_inverse(dir),
            t_end,
            start_mip: MARCH_START_MIP,
            level: start,
            o: Vec3::ZERO,
            t: 0.0,
            t_max: 0.0,
            leave: 0.0,
            ends_inside: false,
            mip: 0,
            left: steps,
            visits: 0,
            last: None,
            run_start: 0.0,
            run_length: 0.0,
        };
        march.enter(start, t_start);
        march
    }

    /// The march, starting each level at mip `start_mip` rather than [`MARCH_START_MIP`] (from `t_start` of
    /// the start level's cells again).
    fn with_start_mip(mut self, start_mip: usize, t_start: f32) -> Self {
        self.start_mip = start_mip;
        self.enter(self.level, t_start);
        self
    }

    /// Starts level `level` at `t0` of its cells (WGSL: the start of `march_level`).
    fn enter(&mut self, level: usize, t0: f32) {
        let lv = &self.levels[level];
        self.level = level;
        self.o = lv.level_position(self.origin);
        let t1 = self.t_end / lv.cell_size;
        let span = ray_box(self.o, self.inv, Vec3::ZERO, lv.mips.dims().as_vec3());
        self.t = t0.max(span.x);
        self.t_max = t1.min(span.y);
        self.leave = span.y.max(t0);
        self.ends_inside = span.y >= t1;
        self.mip = self.start_mip.min(lv.mips.levels.len() - 1);
        self.last = None;
        self.run_start = 0.0;
        self.run_length = 0.0;
    }

    /// One texel visit (WGSL: an iteration of `march_level`'s loop), or the move to the next coarser level
    /// where the ray left this one's part, which costs no visit (WGSL: `march_cascades_left`'s loop).
    fn visit(&mut self) -> Visit {
        if self.left == 0 {
            return Visit::Miss;
        }
        if self.t > self.t_max {
            let next = self.level + 1;
            if next >= self.levels.len() || self.ends_inside {
                return Visit::Miss;
            }
            let t0 = self.leave * self.levels[self.level].cell_size / self.levels[next].cell_size;
            self.enter(next, t0);
            return Visit::Going;
        }
        self.left -= 1;
        self.visits += 1;
        let mips = self.levels[self.level].mips;
        let top = mips.levels.len() - 1;
        let p = self.o + self.dir * self.t;
        let mut texel = (p * (1.0 / (1u32 << self.mip) as f32)).floor().as_ivec3();
        // After a step that entered another texel of the mip above, that one.
        if self.last.is_some_and(|last| self.mip < top && texel >> 1 != last >> 1) {
            self.mip += 1;
            texel >>= 1;
        }
        let scale = (1u32 << self.mip) as f32;
        let size = mips.levels[self.mip].0.as_ivec3();
        let clamped = texel.clamp(IVec3::ZERO, size - IVec3::ONE);
        let lo = clamped.as_vec3() * scale;
        let exit = ray_box(self.o, self.inv, lo, lo + Vec3::splat(scale)).y;
        let occupied = mips.load(clamped, self.mip);
        // A run of occupied cells stops the ray once it has gone MIN_OCCLUDING_CHORD through it; a cell it
        // only clips is passed, as an empty one.
        if occupied && self.mip == 0 {
            if self.run_length == 0.0 {
                self.run_start = self.t;
            }
            self.run_length += exit - self.t;
            if self.run_length >= MIN_OCCLUDING_CHORD {
                return Visit::Hit;
            }
        } else if !occupied {
            self.run_length = 0.0;
        }
        if occupied && self.mip > 0 {
            self.mip -= 1;
            self.last = None;
        } else {
            self.t = exit.max(self.t) + 1.0e-3;
            self.last = Some(texel);
        }
        Visit::Going
    }

    /// Visits until a hit or a miss: the world distance along the ray to the entry of the run of occupied
    /// cells that stopped it and the level it is in, if any.
    pub fn run(&mut self) -> Option<(f32, usize)> {
        loop {
            match self.visit() {
                Visit::Going => {}
                Visit::Hit => return Some(self.hit()),
                Visit::Miss => return None,
            }
        }
    }

    /// After a hit: the world distance along the ray to the entry of the run of occupied cells that stopped
    /// it, and the level it is in.
    fn hit(&self) -> (f32, usize) {
        (self.run_start * self.levels[self.level].cell_size, self.level)
    }

    /// Goes on from `t0` of the current level's cells (past a hit the caller passes), with `steps` texel visits
    /// left (WGSL: `march_cascades_left` from the hit's level).
    pub fn resume(&mut self, t0: f32, steps: u32) {
        self.left = steps;
        self.enter(self.level, t0);
    }

    /// Texel visits left.
    pub fn steps_left(&self) -> u32 {
        self.left
    }

    /// Texel visits made so far (each one occupancy load, at some mip).
    pub fn visits(&self) -> u64 {
        self.visits
    }

    /// Whether a march that found nothing ([`March::run`] returned `None`) stopped for want of steps.
    pub fn out_of_steps(&self) -> bool {
        self.left == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::VoxelGrid;
    use crate::cpu::ao::{hemisphere_direction, orthonormal_basis};

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
    fn a_march_resumed_past_a_hit_goes_on_as_a_new_march_from_there_with_the_steps_left() {
        // Two walls, at x = 12 and x = 20, in two levels (level 0 holds the first; the second lies across
        // its border, in level 1).
        let g0 = VoxelGrid::new(Vec3::ZERO, 1.0, UVec3::splat(16)).unwrap();
        let g1 = VoxelGrid::new(Vec3::splat(-8.0), 2.0, UVec3::splat(16)).unwrap();
        let (o0, o1) = (VoxelOccupancy::new(g0, false), VoxelOccupancy::new(g1, false));
        for y in 0..16 {
            for z in 0..16 {
                o0.set(UVec3::new(12, y, z));
                o1.set(UVec3::new(10, y, z));
                o1.set(UVec3::new(14, y, z));
            }
        }
        let (m0, m1) = (VoxelMips::new(&o0, 4), VoxelMips::new(&o1, 4));
        let levels = [
            TraceLevel { origin: Vec3::ZERO, cell_size: 1.0, window_min: IVec3::ZERO, mips: &m0 },
            TraceLevel { origin: Vec3::ZERO, cell_size: 2.0, window_min: IVec3::splat(-4), mips: &m1 },
        ];
        let (origin, dir) = (Vec3::new(2.5, 8.3, 8.6), Vec3::new(1.0, 0.05, -0.03).normalize());
        let mut march = March::new(&levels, origin, dir, 0, 0.5, 40.0, 64);
        let first = march.run().unwrap();
        assert_eq!(first.1, 0);
        assert!(((origin + dir * first.0).x - 12.0).abs() < 0.01, "{first:?}");
        // Past the first wall's cell, the march goes on into level 1 and finds the second wall.
        let exit = first.0 + 1.0;
        let left = march.steps_left();
        march.resume(exit, left);
        let second = march.run().unwrap();
        assert_eq!(second.1, 1);
        assert!(((origin + dir * second.0).x - 20.0).abs() < 0.01, "{second:?}");
        // The same as a march started there with the same steps, visit for visit.
        let mut fresh = March::new(&levels, origin, dir, 0, exit, 40.0, left);
        assert_eq!(fresh.run(), Some(second));
        assert_eq!(fresh.steps_left(), march.steps_left());
        assert_eq!(march.visits(), u64::from(64 - march.steps_left()));
        // With too few steps left to reach it: a miss, out of steps.
        let mut starved = March::new(&levels, origin, dir, 0, exit, 40.0, 2);
        assert_eq!(starved.run(), None);
        assert!(starved.out_of_steps());
    }
}
