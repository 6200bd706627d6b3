#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod ao;
pub mod cpu;
mod debug;
mod gi;
mod gpu;
#[cfg(feature = "inspector")]
pub mod inspector;
mod voxel;

#[cfg(test)]
mod wgsl_tests;

pub use ao::{HaoQuality, HybridAmbientOcclusion, HybridAmbientOcclusionPlugin, MIN_VIEWPORT_PIXELS};
pub use debug::{HaoDebugImages, HaoDebugView, HaoDebugViewPlugin};
pub use gi::{
    CHANGED_HISTORY, GiAssets, GiFarIrradianceVolume, GiFarProbeWindow, GiFarProbes, GiFarProbesSupport,
    GiIrradianceVolume, GiProbeWindow, MAX_LIGHTING_FRAMES, MAX_PROBE_RAYS_PER_FRAME, MAX_PROBES,
    VoxelGlobalIllumination, VoxelGlobalIlluminationPlugin,
};
pub use voxel::components::*;
pub use voxel::{
    CascadeLevelStats, LevelBytes, RebuildStaticVoxels, VOXEL_GRID_GROUP, VoxelGridAssets, VoxelGridBindings,
    VoxelizationPlugin, VoxelizationStats, VoxelizationStatsData, VoxelizeCounters, VoxelizeCpuTime, voxel_grid_layout,
};

use bevy::prelude::*;

/// Voxel-based hybrid ambient occlusion: add this plugin, put a `HybridAmbientOcclusion` on a camera.
#[derive(Default)]
pub struct HaoPlugin;

impl Plugin for HaoPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins((
            voxel::VoxelizationPlugin,
            ao::HybridAmbientOcclusionPlugin,
            gi::VoxelGlobalIlluminationPlugin,
            debug::HaoDebugViewPlugin,
        ));
    }
}

/// The components and plugin most apps need.
pub mod prelude {
    pub use crate::HaoPlugin;
    pub use crate::voxel::components::*;
    pub use crate::{HaoDebugImages, HaoDebugView, HaoQuality, HybridAmbientOcclusion, VoxelGlobalIllumination};
}
