//! What the plugin knows about voxelization, shared by the main and render worlds: the GPU's counters (the
//! `COUNTER_*` constants of `voxelize_common.wgsl`), read back a few frames late, and the CPU's figures.

use crate::cpu::VoxelGrid;
use bevy::prelude::*;
use bevy::render::gpu_readback::ReadbackComplete;
use std::sync::{Arc, Mutex};

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

/// One cascade level as it stands (see [`VoxelizationStatsData::cascades`]).
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub struct CascadeLevelStats {
    /// World position of the lattice's cell 0 (min corner): the cell of lattice coordinates `c` covers
    /// `origin + [c, c + 1] * cell_size`.
    pub origin: Vec3,
    /// World-space cell size.
    pub cell_size: f32,
    /// The lattice cell at the window's min corner.
    pub window_min: IVec3,
    /// Cells voxelized again for static geometry in the last frame (entered slabs, changed regions).
    pub static_cells_last_frame: u64,
    /// Static cells voxelized again since the start.
    pub static_cells_total: u64,
    /// Times the level was rebuilt whole (a new volume, a teleport, a forced rebuild).
    pub rebuilds: u64,
    /// Times the level scrolled (moved by less than its size).
    pub scrolls: u64,
    /// GPU memory of the level, bytes: occupancy bits (static and frame), texture with mips, point counts, attributes.
    pub bytes: LevelBytes,
}

/// GPU memory of one level, bytes.
#[derive(Clone, Copy, Default, Debug, PartialEq, Eq)]
pub struct LevelBytes {
    /// Occupancy bits, static and frame copies.
    pub occupancy: u64,
    /// The 3D texture's share, all mips.
    pub texture: u64,
    /// Point counts, with attributes their sums, static and frame copies (0 when off).
    pub point_counts: u64,
    /// The albedo and normal textures (0 without attributes).
    pub attributes: u64,
}

impl LevelBytes {
    /// All of it.
    pub fn total(&self) -> u64 {
        self.occupancy + self.texture + self.point_counts + self.attributes
    }
}

/// What the plugin knows about voxelization, shared by the main and render worlds: counters of CPU-side
/// work (static rebuilds, instances) and the GPU's own counters, read back a few frames late.
#[derive(Resource, Clone, Default, Debug)]
pub struct VoxelizationStats(pub(crate) Arc<Mutex<VoxelizationStatsData>>);

/// The figures behind [`VoxelizationStats`].
#[derive(Clone, Default, Debug, PartialEq)]
pub struct VoxelizationStatsData {
    /// The grid in use, if any (for cascades, one cascade's storage: see [`crate::VoxelGridAssets::grid`]).
    pub grid: Option<VoxelGrid>,
    /// The cascade levels and what they did (one entry for a single grid).
    pub cascades: Vec<CascadeLevelStats>,
    /// Frames in which static geometry was voxelized (a new grid, a change to the static set, a cascade
    /// that scrolled or was rebuilt; see [`Self::cascades`] for which cells).
    pub static_rebuilds: u64,
    /// Frames in which the voxelization passes ran (static, dynamic or resolve).
    pub frames_voxelized: u64,
    /// Static instances read in the last frame with static work (summed over its regions and levels).
    pub static_instances: u64,
    /// Triangles of those.
    pub static_triangles: u64,
    /// Dynamic instances voxelized in the last frame.
    pub dynamic_instances: u64,
    /// Triangles of those.
    pub dynamic_triangles: u64,
    /// Occluders skipped because their mesh cannot be voxelized (not a triangle list, not bindable).
    pub skipped_instances: u64,
    /// Occluders the render world knows (visible mesh entities that are not `NoVoxelOcclusion`): resolved to
    /// mesh slabs, waiting for their mesh, or skipped.
    pub occluders_tracked: u64,
    /// Occluders resolved to mesh slabs again in the last frame: those that changed (added, moved, re-marked,
    /// re-meshed, shown or hidden), those waiting for their mesh, and skinned or morphed ones. A frame in
    /// which nothing changed resolves none.
    pub occluders_resolved: u64,
    /// Static occluders added and waiting to be voxelized (`VoxelVolume::stream_budget`).
    pub static_queue: u64,
    /// The GPU counters of the last static build.
    pub static_counters: VoxelizeCounters,
    /// The GPU counters of the last frame's dynamic pass.
    pub dynamic_counters: VoxelizeCounters,
    /// Readbacks of the counters received so far.
    pub counter_readbacks: u64,
    /// The estimate of the static occluders' points (equation 5 or its strip counterpart: [`crate::cpu::expected_point_count`]).
    pub estimated_static_points: u64,
    /// The estimate of the dynamic occluders' points per frame.
    pub estimated_dynamic_points: u64,
    /// `VoxelVolume::target_bias` and the gamma chosen for it, once measured.
    pub gamma_for_target: Option<(f32, f32)>,
    /// The CPU time of the plugin's voxelization systems in the last frame, main and render world.
    pub cpu_time: VoxelizeCpuTime,
}

/// The CPU time of the voxelization systems in the last frame they ran, each measured around its body
/// (wall-clock `Instant`s; the systems that look at occluders, where a level's size could show).
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub struct VoxelizeCpuTime {
    /// Main world: finding the occluders that changed, promoting moved meshes.
    pub track_occluders: std::time::Duration,
    /// Main world: the point estimate.
    pub estimate_point_budget: std::time::Duration,
    /// Main world: gamma for the target bias.
    pub choose_gamma: std::time::Duration,
    /// Main world: the grid (and the fitted bounds).
    pub update_volume: std::time::Duration,
    /// Extraction of the occluders that changed.
    pub extract_occluders: std::time::Duration,
    /// Render world: resolving what changed, planning the passes, their buffers and bind groups.
    pub prepare_voxelize: std::time::Duration,
}

impl VoxelizeCpuTime {
    /// The main world's share.
    pub fn main_world(&self) -> std::time::Duration {
        self.track_occluders + self.estimate_point_budget + self.choose_gamma + self.update_volume
    }

    /// The render world's share (extraction included).
    pub fn render_world(&self) -> std::time::Duration {
        self.extract_occluders + self.prepare_voxelize
    }
}

/// Measures a system's body and stores it in [`VoxelizeCpuTime`] when dropped.
pub(crate) struct CpuSpan<'a> {
    stats: &'a VoxelizationStats,
    start: std::time::Instant,
    field: fn(&mut VoxelizeCpuTime) -> &mut std::time::Duration,
}

impl VoxelizationStats {
    /// Starts measuring a system (see [`CpuSpan`]).
    pub(crate) fn cpu_span(&self, field: fn(&mut VoxelizeCpuTime) -> &mut std::time::Duration) -> CpuSpan<'_> {
        CpuSpan { stats: self, start: std::time::Instant::now(), field }
    }
}

impl Drop for CpuSpan<'_> {
    fn drop(&mut self) {
        let elapsed = self.start.elapsed();
        self.stats.update(|s| *(self.field)(&mut s.cpu_time) = elapsed);
    }
}

impl VoxelizationStats {
    /// A copy of the current figures.
    pub fn get(&self) -> VoxelizationStatsData {
        self.0.lock().map(|d| d.clone()).unwrap_or_default()
    }

    pub(crate) fn update(&self, f: impl FnOnce(&mut VoxelizationStatsData)) {
        if let Ok(mut d) = self.0.lock() {
            f(&mut d);
        }
    }
}

/// Decodes the counters read back from the GPU and warns (once per episode) when the point budget was
/// exceeded or triangles were too large to voxelize.
pub(crate) fn read_voxelize_counters(event: On<ReadbackComplete>, stats: Res<VoxelizationStats>) {
    let words: Vec<u32> = event.data.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let Some((static_counters, dynamic_counters)) = decode_counters(&words) else { return };
    stats.update(|s| {
        for (name, new, old) in [("static", &static_counters, &s.static_counters), ("dynamic", &dynamic_counters, &s.dynamic_counters)] {
            if new.budget_exceeded && !old.budget_exceeded {
                warn!(
                    "bevy_hao: {name} voxelization needs {} points, over VoxelVolume::point_budget; {} were injected and \
                     voxels are missing. Raise the budget or lower the resolution or gamma",
                    new.points_requested, new.points_dispatched
                );
            }
            if new.oversize > old.oversize {
                warn!("bevy_hao: {} {name} triangles need more than 2^28 sub-triangles and were skipped", new.oversize);
            }
        }
        s.static_counters = static_counters;
        s.dynamic_counters = dynamic_counters;
        s.counter_readbacks += 1;
    });
}
