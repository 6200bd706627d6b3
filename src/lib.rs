#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod ao;
pub mod components;
pub mod cpu;
pub mod debug;
#[cfg(feature = "inspector")]
pub mod inspector;
pub mod meshes;
pub mod voxel;

#[cfg(test)]
mod wgsl_tests;

pub use ao::{HaoDebugImages, HaoQuality, HybridAmbientOcclusion};
pub use components::*;
pub use debug::HaoDebugView;

use bevy::prelude::*;

/// Voxel-based hybrid ambient occlusion: add this plugin, put a `HybridAmbientOcclusion` on a camera.
#[derive(Default)]
pub struct HaoPlugin;

impl Plugin for HaoPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins((voxel::VoxelizationPlugin, ao::HybridAmbientOcclusionPlugin, debug::HaoDebugViewPlugin));
    }
}

/// The components and plugin most apps need.
pub mod prelude {
    pub use crate::HaoPlugin;
    pub use crate::ao::{HaoDebugImages, HaoQuality, HybridAmbientOcclusion};
    pub use crate::components::*;
    pub use crate::debug::HaoDebugView;
}
