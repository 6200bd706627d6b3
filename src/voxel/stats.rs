//! The GPU's voxelization counters (the `COUNTER_*` constants of `voxelize_common.wgsl`).

/// Counters per pass.
pub const COUNTER_BLOCK: usize = 14;
/// Words in the counters buffer: a block for the static pass, one for the dynamic pass, and the points
/// used so far this frame.
pub const COUNTER_WORDS: usize = 2 * COUNTER_BLOCK + 1;
/// Index of the static pass's block.
pub const STATIC_COUNTER_BASE: u32 = 0;
/// Index of the dynamic pass's block.
pub const DYNAMIC_COUNTER_BASE: u32 = COUNTER_BLOCK as u32;
/// Index of the frame's points-used word.
pub const FRAME_POINTS_USED: u32 = 2 * COUNTER_BLOCK as u32;

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
