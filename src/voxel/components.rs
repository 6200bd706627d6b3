//! The components a user puts on entities: which meshes occlude and how they move, and the voxel volume.

use crate::cpu;
use bevy::prelude::*;

/// Marks a mesh entity as static occluding geometry: it is voxelized into the cached static grid, which is
/// rebuilt only when the static set changes (an entity added or removed, a transform or mesh changed, the
/// volume changed). A static occluder that moves is still handled correctly (the static grid is rebuilt on
/// the frames it moves) but costs a rebuild each time, and the plugin warns once per entity: mark things
/// that move with [`DynamicOccluder`].
///
/// On a skinned mesh (`SkinnedMesh`, dynamic by default) it voxelizes the mesh in the pose it has whenever
/// its part of the static grid is built, and not again while that part stands: for a character posed once
/// and left, not for one that is animated.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct StaticOccluder;

/// Marks a mesh entity as dynamic occluding geometry: it is voxelized every frame on top of a copy of the
/// static grid, so its occlusion follows it frame by frame. Skinned meshes (`SkinnedMesh`) are dynamic
/// without it, and are voxelized in the pose Bevy draws them each frame.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct DynamicOccluder;

/// Keeps a mesh entity out of the voxel grid: it casts no voxel occlusion (it still receives it).
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct NoVoxelOcclusion;

/// Voxelizes an occluding mesh as PN triangles (Fei 2012 section 3.4): each triangle is curved by the
/// mesh's vertex normals (`Mesh::ATTRIBUTE_NORMAL`, `Float32x3`) into the cubic patch of Vlachos et al.
/// 2001, subdivided finer as the patch needs, and its sub-triangles' corners put on the patch, so that a
/// coarse mesh of a curved shape voxelizes curved (a 320-triangle sphere voxelizes within a cell of the
/// true sphere at 512^3). The patch follows the normals as given: hard edges (split normals) leave the
/// patches apart there, as drawn PN triangles do.
///
/// Costs more points than the flat triangles (gamma is raised by up to
/// [`cpu::pn::MAX_PN_GAMMA_SCALE`]) and is never clipped to the grid, so a huge PN triangle crossing a
/// cascade is subdivided whole. A mesh without normals is voxelized flat, with a warning. Skinned and
/// morphed meshes curve by their skinned and morphed normals. CPU twin: [`cpu::voxelize_mesh_pn`].
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct PnTriangles;

/// Whether an occluder is voxelized as a surface (the default) or filled solid.
///
/// `Solid` fills the inside of a closed mesh (Dong et al. 2004: the parity of the crossings of the
/// vertical lines through the cell centres), so that a thick wall or a pillar is solid rather than a
/// shell and rays do not pass through its inside. Only for closed meshes: where a mesh is not closed, a
/// column it crosses an odd number of times is left as its surface (the `voxelize` tool's `--solid` warns
/// about open meshes). The solid occluders voxelized together (in one pass of a cascade level) are filled
/// together: where two overlap, the shared part is left out, so keep solids apart. With [`PnTriangles`] the
/// inside filled is the flat mesh's, under the curved surface. CPU twin: [`cpu::fill_solid`].
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[reflect(Component, Default, Debug, PartialEq, Hash)]
pub enum VoxelFill {
    /// The surface only.
    #[default]
    Surface,
    /// The surface and the inside.
    Solid,
}

/// Added by the plugin to an unmarked `Mesh3d` entity the first time its transform changes after it was
/// voxelized: from then on it is treated as a [`DynamicOccluder`].
///
/// A `Mesh3d` with none of [`StaticOccluder`], [`DynamicOccluder`] or [`NoVoxelOcclusion`] starts out
/// static (most scene geometry never moves, and static geometry is voxelized once). If it moves, the
/// static grid is rebuilt once and the entity is promoted to dynamic, so a moving object costs one
/// rebuild, not one per frame. Remove this component to demote it again.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct PromotedToDynamic;

/// How sub-triangles mark voxels (see [`cpu::InjectionMode`]).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[reflect(Default, Debug, PartialEq, Hash)]
pub enum VoxelInjection {
    /// One point per sub-triangle at its centroid (Fei et al. 2012): fast, gap-free in practice, misses
    /// some voxels the surface only clips.
    #[default]
    Centroid,
    /// Every voxel a sub-triangle overlaps, by exact tests on at most 8 candidates: nothing missed, about
    /// 2-5x the cost.
    Conservative,
}

impl From<VoxelInjection> for cpu::InjectionMode {
    fn from(m: VoxelInjection) -> Self {
        match m {
            VoxelInjection::Centroid => cpu::InjectionMode::Centroid,
            VoxelInjection::Conservative => cpu::InjectionMode::Conservative,
        }
    }
}

/// Where the voxel grid is.
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, PartialEq)]
pub enum VolumeBounds {
    /// The default: `cascades` grids of `cells^3` cells centred on the camera, each with twice the cell size
    /// of the one inside it (`finest_cell_size` for the first), so that HAO works in a world of any size at
    /// a bounded memory cost. The grids follow the camera that has [`crate::HybridAmbientOcclusion`] (the
    /// active one of lowest `Camera::order`, if several: the plugin warns once; other cameras trace into the
    /// same cascades). When the camera moves, only the slabs of cells that come into a cascade are
    /// voxelized again (the grids wrap around); a jump of a whole cascade or more rebuilds it.
    /// [`VoxelVolume::resolution`] is not used. See [`crate::cpu::cascade`].
    FollowCamera {
        /// Cascade levels, 1 to 8.
        cascades: u32,
        /// Cells per axis of every cascade: a multiple of 8, 16 to 256 (other values are rounded, with a
        /// warning).
        cells: u32,
        /// World-space cell size of the finest cascade (1e-4 to 1e4).
        finest_cell_size: f32,
    },
    /// The world-space bounds of all static occluders, grown by `margin` (world units) on every side.
    /// Refitted when the static scene changes. Dynamic occluders outside it are clipped.
    FitStaticScene {
        /// Extra space around the static scene, world units.
        margin: f32,
    },
    /// A fixed world-space box.
    World {
        /// Min corner.
        min: Vec3,
        /// Max corner.
        max: Vec3,
    },
}

/// Most cells along an axis of a single grid ([`VolumeResolution::Cells`]).
pub const MAX_CELLS: u32 = 16384;
/// Most cells per axis of a cascade.
pub const MAX_CASCADE_CELLS: u32 = 256;
/// Smallest and largest cell size of the finest cascade, world units.
pub const MIN_CELL_SIZE: f32 = 1.0e-4;
/// See [`MIN_CELL_SIZE`].
pub const MAX_CELL_SIZE: f32 = 1.0e4;

impl Default for VolumeBounds {
    fn default() -> Self {
        VolumeBounds::FollowCamera { cascades: 4, cells: 192, finest_cell_size: 0.125 }
    }
}

/// How fine a single voxel grid is ([`VolumeBounds::FitStaticScene`] and [`VolumeBounds::World`]).
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Debug, PartialEq)]
pub enum VolumeResolution {
    /// This many cells along the bounds' longest axis (cells are cubes; the other axes get what their
    /// extent needs).
    Cells(u32),
    /// Cells of this side length, world units.
    CellSize(f32),
}

/// How triangles are cut into sub-triangles before injection (see [`cpu::SubdivisionPattern`]).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[reflect(Default, Debug, PartialEq, Hash)]
pub enum VoxelSubdivision {
    /// A segment count per edge: long thin triangles are cut into strips along their length (about `2L`
    /// sub-triangles for one `L` cells long and under a cell wide), others as by `Uniform`, whichever has
    /// fewer sub-triangles.
    #[default]
    Strips,
    /// The `n x n` pattern for the longest edge (`L^2` sub-triangles for that sliver). For comparison.
    Uniform,
}

impl From<cpu::SubdivisionPattern> for VoxelSubdivision {
    fn from(p: cpu::SubdivisionPattern) -> Self {
        match p {
            cpu::SubdivisionPattern::Strips => VoxelSubdivision::Strips,
            cpu::SubdivisionPattern::Uniform => VoxelSubdivision::Uniform,
        }
    }
}

impl From<VoxelSubdivision> for cpu::SubdivisionPattern {
    fn from(p: VoxelSubdivision) -> Self {
        match p {
            VoxelSubdivision::Strips => cpu::SubdivisionPattern::Strips,
            VoxelSubdivision::Uniform => cpu::SubdivisionPattern::Uniform,
        }
    }
}

/// The voxel volume: where the grid is, how fine, and how geometry is voxelized into it. Put it on any
/// entity (one per app: if there are several, the first found is used and the plugin warns). Without one,
/// [`VoxelVolume::default()`] is used: 4 camera-following cascades of 192^3 cells, the finest with cells of
/// 0.125 world units (24 units across), the coarsest 1 unit (192 across).
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default, Debug, PartialEq)]
pub struct VoxelVolume {
    /// Where the grid is.
    pub bounds: VolumeBounds,
    /// How fine it is.
    pub resolution: VolumeResolution,
    /// The safety factor gamma of equation 1: at 1 the sub-triangles' edges span at most one cell per
    /// axis; higher values subdivide more, miss fewer voxels and cost `gamma^2` more points. Clamped to
    /// 1/16..16 (at least 1 in conservative mode).
    pub gamma: f32,
    /// Choose gamma for this bias instead of `gamma` (equation 3): the share of the cells the static
    /// surface touches that centroid injection may miss, e.g. `Some(0.02)`. Gamma is measured for it on
    /// patches of the static occluders (at the finest cell size, by [`cpu::calibrate`], when the static set
    /// or the volume changes; the chosen gamma is in the stats and the inspector). Conservative injection
    /// misses nothing and ignores it. Replaced by `None`, with a warning, unless in (0, 1).
    pub target_bias: Option<f32>,
    /// Centroid or conservative injection.
    pub injection: VoxelInjection,
    /// How triangles are cut into sub-triangles: `Strips` (the default) or the old `Uniform` pattern.
    pub subdivision: VoxelSubdivision,
    /// Most sub-triangle points generated per frame (static rebuild and dynamic geometry together);
    /// more are dropped with a warning. The need of each mesh is estimated (equation 5, or its strip counterpart).
    pub point_budget: u32,
    /// Most triangles of newly added static occluders voxelized per frame (a level loading, a chunk
    /// streamed in): the rest wait for the following frames, the occluders nearest the camera first (the
    /// centre of the volume without a camera), so that a chunk of thousands of meshes arriving at once
    /// spreads its cost over frames and its occlusion appears region by region. An occluder is taken whole
    /// (one bigger than the budget takes a frame to itself); its triangles count once however many levels
    /// it lies in. Occluders that move or change in place, and levels rebuilt whole, are not held back.
    /// `VoxelizationStats` reports the occluders waiting (`static_queue`). The default, 16,384, keeps a
    /// frame's extra work to a fraction of a millisecond on a desktop GPU and fills a level of a million
    /// triangles in about a second at 60 frames a second; raise it (up to `u32::MAX`: everything at once)
    /// where load time matters more than an even frame rate. Changing it keeps the grid. 0 is replaced by
    /// the default.
    pub stream_budget: u32,
    /// Keep a per-voxel point count (multi-valued voxelization; 4 bytes per voxel, twice; off by default,
    /// since cascades have millions of voxels). Turned off with a warning if the count buffers would exceed
    /// the device's storage-binding limit.
    pub point_counts: bool,
    /// Multi-valued voxels: every voxel also keeps the average albedo and the average normal of the points
    /// injected into it, in two 3D textures beside occupancy ([`crate::VoxelGridBindings`], `voxel_albedo` and
    /// `voxel_normal` in `voxel_grid.wgsl`), for the static and the dynamic geometry and in every cascade.
    ///
    /// A point's albedo is its mesh's `StandardMaterial::base_color` times the vertex colour
    /// (`Mesh::ATTRIBUTE_COLOR`) where there is one; a `base_color_texture` multiplies it by the texture's
    /// mean colour (of the image's first mip, where that is 8-bit RGBA in main-world memory; computed once per
    /// image). Meshes with other materials count white. A point's normal is its triangle's face normal
    /// (counter-clockwise front faces), or for [`crate::PnTriangles`] the interpolated vertex normal; a
    /// double-sided material (`double_sided` or no `cull_mode`) adds no normal, so its voxels always occlude.
    /// Voxels filled by [`crate::VoxelFill::Solid`] have no points: no albedo and no normal.
    ///
    /// Costs 64 bytes per voxel besides occupancy (two copies, static and frame, of the point count and six
    /// `u32` sums, and two 4-byte texels; includes [`Self::point_counts`]): 134 MB for one 128^3 grid, 403 MB
    /// for 3 cascades of 128^3, 1.8 GB for the default 4 cascades of 192^3. Turned off, with a warning naming
    /// the sizes, where one copy of the sums (28 bytes per voxel) exceeds the device's storage-binding limit
    /// (128 MiB on lavapipe and WebGPU's defaults: 3 cascades of 112^3 or one 168^3 grid fit).
    pub attributes: bool,
}

impl Default for VoxelVolume {
    fn default() -> Self {
        Self {
            bounds: VolumeBounds::default(),
            resolution: VolumeResolution::Cells(128),
            gamma: 1.0,
            target_bias: None,
            injection: VoxelInjection::Centroid,
            subdivision: VoxelSubdivision::Strips,
            point_budget: 32 << 20,
            stream_budget: 1 << 14,
            point_counts: false,
            attributes: false,
        }
    }
}

impl VoxelVolume {
    /// The CPU settings equivalent to this volume's gamma, injection mode and subdivision pattern.
    pub fn voxelize_settings(&self) -> cpu::VoxelizeSettings {
        cpu::VoxelizeSettings { gamma: self.gamma, mode: self.injection.into(), pattern: self.subdivision.into() }
    }

    /// This volume with every invalid value replaced by a usable one, and one message per replacement naming
    /// the field, the value given and the value used (the plugin logs each once). Values that cannot be
    /// replaced sensibly (a `World` box that is not finite, a grid too large for the device) are left for
    /// the grid to refuse with an error.
    pub fn sanitized(&self) -> (VoxelVolume, Vec<String>) {
        let mut v = *self;
        let mut fixes = Vec::new();
        let mut fix = |field: &str, given: String, used: String| {
            fixes.push(format!("VoxelVolume::{field} is {given}; using {used}"));
        };
        let (lo, hi) = cpu::voxelize::GAMMA_RANGE;
        if !v.gamma.is_finite() {
            fix("gamma", format!("{}", v.gamma), "1".into());
            v.gamma = 1.0;
        } else if !(lo..=hi).contains(&v.gamma) {
            let g = v.gamma.clamp(lo, hi);
            fix("gamma", format!("{}", v.gamma), format!("{g}"));
            v.gamma = g;
        }
        if let Some(p) = v.target_bias
            && !(p > 0.0 && p < 1.0)
        {
            fix("target_bias", format!("Some({p})"), "None".into());
            v.target_bias = None;
        }
        if v.stream_budget == 0 {
            let d = VoxelVolume::default().stream_budget;
            fix("stream_budget", "0".into(), format!("{d}"));
            v.stream_budget = d;
        }
        if v.point_budget == 0 {
            let d = VoxelVolume::default().point_budget;
            fix("point_budget", "0".into(), format!("{d}"));
            v.point_budget = d;
        }
        match v.resolution {
            VolumeResolution::Cells(n) if !(1..=MAX_CELLS).contains(&n) => {
                let c = n.clamp(1, MAX_CELLS);
                fix("resolution", format!("Cells({n})"), format!("Cells({c})"));
                v.resolution = VolumeResolution::Cells(c);
            }
            VolumeResolution::CellSize(s) if !(s.is_finite() && s > 0.0) => {
                fix("resolution", format!("CellSize({s})"), "Cells(128)".into());
                v.resolution = VolumeResolution::Cells(128);
            }
            _ => {}
        }
        match &mut v.bounds {
            VolumeBounds::FitStaticScene { margin } if !(margin.is_finite() && *margin >= 0.0) => {
                fix("bounds margin", format!("{margin}"), "0".into());
                *margin = 0.0;
            }
            VolumeBounds::FollowCamera { cascades, cells, finest_cell_size } => {
                let max = cpu::cascade::MAX_CASCADES;
                if !(1..=max).contains(cascades) {
                    let c = (*cascades).clamp(1, max);
                    fix("bounds cascades", format!("{cascades}"), format!("{c}"));
                    *cascades = c;
                }
                let step = cpu::cascade::SCROLL_STEP;
                let c = (*cells).clamp(cpu::cascade::MIN_CASCADE_CELLS, MAX_CASCADE_CELLS).div_ceil(step) * step;
                if c != *cells {
                    fix(
                        "bounds cells",
                        format!("{cells}"),
                        format!(
                            "{c} (a multiple of {step}, {} to {MAX_CASCADE_CELLS})",
                            cpu::cascade::MIN_CASCADE_CELLS
                        ),
                    );
                    *cells = c;
                }
                if !(finest_cell_size.is_finite()
                    && *finest_cell_size >= MIN_CELL_SIZE
                    && *finest_cell_size <= MAX_CELL_SIZE)
                {
                    let f = if finest_cell_size.is_finite() && *finest_cell_size > 0.0 {
                        finest_cell_size.clamp(MIN_CELL_SIZE, MAX_CELL_SIZE)
                    } else {
                        0.125
                    };
                    fix("bounds finest_cell_size", format!("{finest_cell_size}"), format!("{f}"));
                    *finest_cell_size = f;
                }
            }
            _ => {}
        }
        (v, fixes)
    }

    /// The cascades' shape, for [`VolumeBounds::FollowCamera`].
    pub fn cascade_shape(&self) -> Option<cpu::CascadeShape> {
        match self.bounds {
            VolumeBounds::FollowCamera { cascades, cells, finest_cell_size } => {
                Some(cpu::CascadeShape { levels: cascades, cells, finest_cell_size })
            }
            _ => None,
        }
    }

    /// The grid for given world bounds (the static scene's, for [`VolumeBounds::FitStaticScene`]).
    pub fn grid_for_bounds(&self, min: Vec3, max: Vec3) -> Result<cpu::VoxelGrid, cpu::GridError> {
        match self.resolution {
            VolumeResolution::Cells(n) => cpu::VoxelGrid::fit_to_bounds(min, max, n),
            VolumeResolution::CellSize(s) => cpu::VoxelGrid::from_bounds_and_cell_size(min, max, s),
        }
    }
}
