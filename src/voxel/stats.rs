//! The GPU's voxelization counters (the `COUNTER_*` constants of `voxelize_common.wgsl`).

/// Counters per pass.
pub const COUNTER_BLOCK: usize = 14;
/// Index of the frame's points-used word (WGSL `FRAME_POINTS_USED`), before the passes' blocks.
pub const FRAME_POINTS_USED: u32 = 0;
/// Static passes (regions) a level may run in one frame, each with its own block of counters; more
/// regions are merged.
pub const STATIC_REGION_SLOTS: u32 = 4;

/// The first word of the counter block of a level's static region `slot` (`slot == STATIC_REGION_SLOTS`:
/// its dynamic pass). Every pass has its own block, since the scan reads its pass's queue length there.
pub fn counter_base(level: u32, slot: u32) -> u32 {
    1 + (level * (STATIC_REGION_SLOTS + 1) + slot) * COUNTER_BLOCK as u32
}

/// Words of the counters buffer for `levels` levels.
pub fn counter_words(levels: u32) -> usize {
    counter_base(levels, 0) as usize
}

/// The static and dynamic counters of a read-back buffer: every level's static blocks (each the level's
/// last update) summed, and its dynamic blocks summed. `None` if the buffer is too short.
pub fn decode_counters(words: &[u32]) -> Option<(VoxelizeCounters, VoxelizeCounters)> {
    let mut stat = VoxelizeCounters::default();
    let mut dynamic = VoxelizeCounters::default();
    let mut level = 0;
    while counter_base(level + 1, 0) as usize <= words.len() {
        for slot in 0..=STATIC_REGION_SLOTS {
            let base = counter_base(level, slot) as usize;
            let c = VoxelizeCounters::from_words(&words[base..base + COUNTER_BLOCK]);
            if slot == STATIC_REGION_SLOTS { dynamic.add(&c) } else { stat.add(&c) }
        }
        level += 1;
    }
    (level > 0).then_some((stat, dynamic))
}

/// What one voxelization pass did on the GPU; the same figures as [`crate::cpu::VoxelizeStats`].
#[derive(Clone, Copy, Default, Debug, PartialEq, Eq)]
pub struct VoxelizeCounters {
    /// Triangles read.
    pub triangles: u32,
    /// Skipped for a non-finite vertex or an index out of range.
    pub invalid: u32,
    /// Skipped for zero area.
    pub degenerate: u32,
    /// Wholly outside the grid.
    pub outside: u32,
    /// Skipped for needing too many sub-triangles.
    pub oversize: u32,
    /// Small triangles injected at once by the classify pass.
    pub small: u32,
    /// Sub-triangles generated.
    pub sub_triangles: u32,
    /// Points (centroid mode) or sub-triangle/cell overlaps (conservative mode) that landed in the grid.
    pub injected: u32,
    /// Exact overlap tests run (conservative mode).
    pub overlap_tests: u32,
    /// Triangles queued for the expand pass.
    pub big_triangles: u32,
    /// Sub-triangles the pass needed, inline and queued (saturating at `u32::MAX`).
    pub points_requested: u32,
    /// Sub-triangles the budget let through, inline and queued.
    pub points_dispatched: u32,
    /// The point budget cut this pass short.
    pub budget_exceeded: bool,
    /// Sub-triangles of the queued triangles the expand pass was dispatched for.
    pub expanded_points: u32,
}

impl VoxelizeCounters {
    /// Adds another pass's counters (saturating).
    pub fn add(&mut self, o: &VoxelizeCounters) {
        for (a, b) in [
            (&mut self.triangles, o.triangles),
            (&mut self.invalid, o.invalid),
            (&mut self.degenerate, o.degenerate),
            (&mut self.outside, o.outside),
            (&mut self.oversize, o.oversize),
            (&mut self.small, o.small),
            (&mut self.sub_triangles, o.sub_triangles),
            (&mut self.injected, o.injected),
            (&mut self.overlap_tests, o.overlap_tests),
            (&mut self.big_triangles, o.big_triangles),
            (&mut self.points_requested, o.points_requested),
            (&mut self.points_dispatched, o.points_dispatched),
            (&mut self.expanded_points, o.expanded_points),
        ] {
            *a = a.saturating_add(b);
        }
        self.budget_exceeded |= o.budget_exceeded;
    }

    /// Decodes one block of words.
    pub fn from_words(w: &[u32]) -> Self {
        Self {
            triangles: w[0],
            invalid: w[1],
            degenerate: w[2],
            outside: w[3],
            oversize: w[4],
            small: w[5],
            sub_triangles: w[6],
            injected: w[7],
            overlap_tests: w[8],
            big_triangles: w[9],
            points_requested: w[10],
            points_dispatched: w[11],
            budget_exceeded: w[12] != 0,
            expanded_points: w[13],
        }
    }
}
