//! Main world: gamma for `VoxelVolume::target_bias` (equation 3), measured on patches of the static
//! occluders by [`crate::cpu::calibrate`] whenever the static set, the target or the cell size changes.

use super::components::*;
use super::occluders::occluder_is_dynamic;
use super::stats::VoxelizationStats;
use crate::cpu::{self, SubdivisionPattern};
use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::prelude::*;
use std::hash::{Hash, Hasher};

/// The gamma chosen for the volume's target bias, if it has one.
#[derive(Resource, Default, Debug, Clone)]
pub(crate) struct GammaForTarget {
    /// What the gamma was measured for: the static set, the target, the cell size and the pattern.
    key: u64,
    /// The gamma to use (`None`: no target, or nothing to measure yet).
    pub(crate) gamma: Option<f32>,
}

/// The triangles of a mesh in world space, if its data is in the main world.
fn world_triangles(mesh: &Mesh, transform: &GlobalTransform, out: &mut Vec<[Vec3; 3]>) {
    let Ok(Some(VertexAttributeValues::Float32x3(positions))) = mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION)
    else {
        return;
    };
    let affine = transform.affine();
    let corner = |i: usize| positions.get(i).map(|p| affine.transform_point3(Vec3::from(*p)));
    let mut push = |a: usize, b: usize, c: usize| {
        if let (Some(a), Some(b), Some(c)) = (corner(a), corner(b), corner(c)) {
            out.push([a, b, c]);
        }
    };
    match mesh.try_indices_option() {
        Ok(Some(Indices::U16(i))) => i.chunks_exact(3).for_each(|t| push(t[0] as usize, t[1] as usize, t[2] as usize)),
        Ok(Some(Indices::U32(i))) => i.chunks_exact(3).for_each(|t| push(t[0] as usize, t[1] as usize, t[2] as usize)),
        Ok(None) => (0..positions.len() / 3).for_each(|t| push(3 * t, 3 * t + 1, 3 * t + 2)),
        Err(_) => {}
    }
}

/// Measures gamma for the target bias when what it depends on changed.
#[allow(clippy::type_complexity)]
pub(crate) fn choose_gamma_for_target(
    volumes: Query<&VoxelVolume>,
    assets: Option<Res<super::volume::VoxelGridAssets>>,
    meshes: Res<Assets<Mesh>>,
    occluders: Query<
        (
            Entity,
            &Mesh3d,
            &GlobalTransform,
            &InheritedVisibility,
            Has<StaticOccluder>,
            Has<DynamicOccluder>,
            Has<PromotedToDynamic>,
        ),
        Without<NoVoxelOcclusion>,
    >,
    mut chosen: ResMut<GammaForTarget>,
    stats: Res<VoxelizationStats>,
) {
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
    let statics: Vec<_> = occluders
        .iter()
        .filter(|(_, _, _, visible, s, d, p)| visible.get() && !occluder_is_dynamic(*s, *d, *p))
        .collect();
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    (target.to_bits(), cell.to_bits(), pattern as u8).hash(&mut hasher);
    for (entity, mesh, transform, ..) in &statics {
        (entity, mesh.id(), meshes.get(mesh.id()).is_some()).hash(&mut hasher);
        transform.affine().to_cols_array().map(f32::to_bits).hash(&mut hasher);
    }
    let key = hasher.finish();
    if key == chosen.key {
        return;
    }
    chosen.key = key;
    let mut triangles = Vec::new();
    for (_, mesh, transform, ..) in &statics {
        if let Some(m) = meshes.get(mesh.id()) {
            world_triangles(m, transform, &mut triangles);
        }
    }
    let (lo, hi) = cpu::voxelize::GAMMA_RANGE;
    chosen.gamma = cpu::calibrate(&triangles, cell, pattern).map(|c| c.gamma_for_bias(target as f64, hi).clamp(lo, hi));
    if let Some(gamma) = chosen.gamma {
        info!("bevy_hao: gamma {gamma:.2} for a target bias of {target} (measured on the static occluders)");
    }
    stats.update(|s| s.gamma_for_target = chosen.gamma.map(|g| (target, g)));
}
