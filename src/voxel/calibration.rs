//! Main world: gamma for `VoxelVolume::target_bias` (equation 3), measured on patches of the static
//! occluders by [`crate::cpu::calibrate`] whenever the static set, the target or the cell size changes.

use super::budget::mesh_triangles;
use super::changes::OccluderChanges;
use super::components::*;
use super::stats::VoxelizationStats;
use crate::cpu::{self, SubdivisionPattern};
use bevy::platform::hash::FixedHasher;
use bevy::prelude::*;
use std::hash::BuildHasher;

/// The gamma chosen for the volume's target bias, if it has one.
#[derive(Resource, Default, Debug, Clone)]
pub(crate) struct GammaForTarget {
    /// What the gamma was measured for: the static set, the target, the cell size and the pattern.
    key: u64,
    /// The gamma to use (`None`: no target, or nothing to measure yet).
    pub(crate) gamma: Option<f32>,
}

/// Measures gamma for the target bias when what it depends on changed.
#[allow(clippy::type_complexity)]
pub(crate) fn choose_gamma_for_target(
    volumes: Query<&VoxelVolume>,
    assets: Option<Res<super::volume::VoxelGridAssets>>,
    meshes: Res<Assets<Mesh>>,
    occluders: Query<(&Mesh3d, &GlobalTransform)>,
    changes: Res<OccluderChanges>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    mut mesh_epoch: Local<u64>,
    mut chosen: ResMut<GammaForTarget>,
    stats: Res<VoxelizationStats>,
) {
    let _span = stats.cpu_span(|t| &mut t.choose_gamma);
    let volume = volumes.iter().next().copied().unwrap_or_default().sanitized().0;
    let Some(target) = volume.target_bias.filter(|_| volume.injection == VoxelInjection::Centroid) else {
        if chosen.gamma.is_some() {
            *chosen = GammaForTarget::default();
            stats.update(|s| s.gamma_for_target = None);
        }
        return;
    };
    // The finest cell size in use (cascades: the finest level's; a single grid, once it is known).
    let cell = match volume.bounds {
        VolumeBounds::FollowCamera { finest_cell_size, .. } => finest_cell_size,
        _ => match &assets {
            Some(a) => a.grid.cell_size,
            None => return,
        },
    };
    let pattern: SubdivisionPattern = volume.subdivision.into();
    for event in mesh_events.read() {
        if let AssetEvent::Added { .. } | AssetEvent::Modified { .. } | AssetEvent::LoadedWithDependencies { .. } =
            event
        {
            *mesh_epoch += 1;
        }
    }
    // Measured again only when the static set, a mesh or the settings changed.
    let key =
        FixedHasher.hash_one((target.to_bits(), cell.to_bits(), pattern as u8, changes.static_version, *mesh_epoch));
    if key == chosen.key {
        return;
    }
    chosen.key = key;
    let mut triangles = Vec::new();
    let mut statics: Vec<Entity> = changes.static_entities().collect();
    // A stable order, so that the patches measured do not depend on the map's.
    statics.sort_unstable();
    for entity in statics {
        let Ok((mesh, transform)) = occluders.get(entity) else { continue };
        if let Some((_, local)) = meshes.get(mesh.id()).and_then(mesh_triangles) {
            let affine = transform.affine();
            triangles.extend(local.into_iter().map(|t| t.map(|p| affine.transform_point3(p))));
        }
    }
    let (lo, hi) = cpu::voxelize::GAMMA_RANGE;
    chosen.gamma = cpu::calibrate(&triangles, cell, pattern).map(|c| c.gamma_for_bias(target as f64, hi).clamp(lo, hi));
    if let Some(gamma) = chosen.gamma {
        info!("bevy_hao: gamma {gamma:.2} for a target bias of {target} (measured on the static occluders)");
    }
    stats.update(|s| s.gamma_for_target = chosen.gamma.map(|g| (target, g)));
}
