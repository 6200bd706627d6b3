//! The lab of [`bevy_hao`]: what the plugin is built, measured and tested with, and what a game does not
//! need.
//!
//! * [`meshes`]: the built-in shapes and procedural cathedral, OBJ and glTF files read into
//!   [`bevy_hao::cpu::TriangleMesh`]es.
//! * [`ground_truth`]: the exact conservative voxelization the voxelizer is measured against;
//!   [`metrics`]: bias, excess voxels and the six-direction watertight test; [`binvox`]: export and import;
//!   [`ply`]: the albedo and normal sidecar of multi-valued voxels.
//! * [`mod@reference`]: the ray-traced AO reference (rays against the real triangles through a BVH).
//! * [`harness`]: headless Bevy apps on Vulkan for the tools and the GPU tests (readback, GPU timings);
//!   [`scene`]: scenes spawned from the meshes; [`motion`]: scripted scenes of contacts and moving props.
//!
//! The tools (`src/bin`): `voxelize`, `ao_compare`, `ao_motion`, `bench_voxelize`, `bench_level`, `bench_ao`; see
//! docs/tools.md.

pub mod binvox;
pub mod ground_truth;
pub mod harness;
pub mod meshes;
pub mod metrics;
pub mod motion;
pub mod ply;
pub mod reference;
pub mod scene;

pub use binvox::{Binvox, read_binvox, write_binvox};
pub use ground_truth::{GroundTruthStats, ground_truth_mesh, ground_truth_mesh_with_cuts, ground_truth_triangle};
pub use metrics::{Comparison, GrazeSplit, WatertightReport, compare, enclosed_voxels, graze_split, watertight};
pub use ply::write_attribute_ply;
