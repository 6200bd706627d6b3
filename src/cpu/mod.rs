//! The GPU-free core: point-tessellated voxelization (Fei et al. 2012, section 3) and the CPU twins of the
//! GPU passes, in plain Rust on [`glam`] with no Bevy types, usable and testable on its own.
//!
//! * [`grid`]: the voxel grid ([`VoxelGrid`]: world bounds to cubic cells, per-axis dimensions, world/grid
//!   transforms) and its bit-packed occupancy with per-voxel point counts ([`VoxelOccupancy`]).
//! * [`attributes`]: multi-valued voxels, the per-voxel albedo and normal accumulated from the points.
//! * [`tessellation`]: equation 1 ([`tessellation_factors`]), the subdivision patterns ([`subdivision`])
//!   and their indexing ([`sub_triangle`]), the centroids of equation 2 ([`sub_triangle_centroid`]),
//!   equation 5 ([`expected_point_count`]) and the clipping of triangles that cross the grid boundary.
//! * [`mod@voxelize`]: the voxelizer itself, in [`InjectionMode::Centroid`] (the paper's) and
//!   [`InjectionMode::Conservative`] (every overlapped cell, by exact tests on at most 8 candidates per
//!   sub-triangle, with [`overlap`]'s exact triangle/box test).
//! * [`bias_model`]: equation 3.
//! * [`skinning`]: morph targets and linear blend skinning as Bevy renders them, applied before voxelizing.
//! * [`cascade`]: the camera-following cascades (windows of an unbounded lattice, snapped and scrolled).
//! * [`march`]: the march through the voxel volume's levels with empty-space skipping ([`march::March`],
//!   on the occupancy's mips, [`march::VoxelMips`]).
//! * [`ao`]: the CPU twin of the hybrid ambient occlusion trace (ray directions, falloff, the hits a ray
//!   passes on its way, and the occlusion they add up to); [`contacts`]: of the rays' first cells, traced in
//!   the depth prepass; [`near`]: of those first cells in the voxels where the march would start inside an
//!   occluder; [`temporal`]: of its temporal accumulation and
//!   filter; [`denoise`]: the filter's weights and the history's texel.
//! * [`lighting`]: the light Bevy's lights put on a surface, in Bevy's units and by its PBR shader's
//!   formulas, and the lighting volume: each voxel's outgoing diffuse radiance under them, shadowed by a
//!   march through the voxels (the CPU twin of `gi_lighting.wgsl`, for diffuse global illumination:
//!   docs/design-gi.md); [`probes`]: the irradiance probes that gather the lit voxels' light into ambient
//!   cubes for Bevy's irradiance volume; [`far_probes`]: a second, coarser window of them for the surfaces
//!   beyond.
//!
//! The GPU passes (`src/voxel/*.wgsl`, `src/ao/*.wgsl`) implement the same algorithm with the same function
//! names; the render tests hold the GPU against these. What the voxelizer is measured against (the exact
//! conservative ground truth, bias and watertightness, binvox files, mesh readers) is in the
//! `bevy_hao_tools` crate of this repository.
//!
//! ```
//! use bevy_hao::cpu::*;
//! use glam::Vec3;
//!
//! // One triangle spanning a 16-cell grid.
//! let mesh = TriangleMesh::new(vec![Vec3::ZERO, Vec3::new(16.0, 0.0, 3.0), Vec3::new(2.0, 16.0, 9.0)], vec![[0, 1, 2]]);
//! let grid = VoxelGrid::fit_to_bounds(Vec3::ZERO, Vec3::splat(16.0), 16).unwrap();
//! let (voxels, stats) = voxelize(&mesh, &grid, &VoxelizeSettings::default());
//! assert!(voxels.set_voxel_count() >= 16 && stats.sub_triangles >= 256);
//! ```

pub mod ao;
pub mod attributes;
pub mod bias_model;
pub mod cascade;
pub mod contacts;
pub mod denoise;
pub mod far_probes;
pub mod grid;
pub mod lighting;
pub mod march;
pub mod mesh;
pub mod near;
pub mod overlap;
pub mod pn;
pub mod probes;
pub mod skinning;
pub mod solid;
pub mod temporal;
pub mod tessellation;
pub mod voxelize;

pub use attributes::{MeshAlbedo, TriangleAttributes, VoxelAttributes};
pub use bias_model::{BiasModel, Calibration, calibrate};
pub use cascade::{CascadeError, CascadeLevel, CascadeShape, cascade_window, entered_regions};
pub use grid::{GridError, VoxelGrid, VoxelOccupancy, cell_of_point};
pub use mesh::{MeshStats, TriangleMesh};
pub use overlap::{OverlapKind, OverlapTriangle, triangle_box_overlap};
pub use pn::{
    PnPatch, smooth_vertex_normals, voxelize_mesh_pn, voxelize_pn_triangle_in_region,
    voxelize_sampled_mesh_pn_in_region, voxelize_sampled_pn_triangle_in_region,
};
pub use skinning::{VertexSkin, morph_position, morphed_mesh, skin_matrix, skin_position, skinned_mesh};
pub use solid::{SolidFill, fill_solid, fill_solid_in_region, open_edge_count};
pub use tessellation::{
    LatticeRange, SubTriangle, Subdivision, SubdivisionPattern, TessellationFactors, TriangleSizes,
    expected_point_count, rotate_to_apex, sub_triangle, sub_triangle_centroid, sub_triangle_corners, subdivision,
    subdivision_count, tessellation_factors,
};
pub use voxelize::{
    InjectionMode, InjectionRegion, VoxelizeSettings, VoxelizeStats, for_each_grid_triangle, grid_space_position,
    lattice_cell, triangle_is_degenerate, voxelize, voxelize_mesh, voxelize_mesh_in_region,
    voxelize_sampled_mesh_in_region, voxelize_sampled_triangle_in_region, voxelize_triangle,
    voxelize_triangle_in_region,
};
