//! Main world: the estimate of the points each frame needs, against the point budget.
//!
//! [`crate::cpu::expected_point_count`] (equation 5 for the uniform pattern, its strip-pattern counterpart by
//! default; at least one point per triangle), per occluder from its mesh's triangle sizes (computed once per
//! mesh, from the main world's copy of the mesh; meshes kept only in the render world are not estimated)
//! scaled by its transform. The budget
//! itself is enforced exactly on the GPU (the scan pass); this estimate warns before it is hit, and the
//! inspector shows it.

use super::changes::OccluderChanges;
use super::stats::VoxelizationStats;
use super::volume::VoxelGridAssets;
use crate::cpu::{TriangleSizes, expected_point_count};
use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

/// A mesh's triangles in its local space, if its data is in the main world: the number of triangles its
/// indices name, and the corners of those whose indices are in range (finite or not).
pub(super) fn mesh_triangles(mesh: &Mesh) -> Option<(u64, Vec<[Vec3; 3]>)> {
    // A mesh kept only in the render world has no data here (the `try_` accessors say so; the others panic).
    let Ok(Some(VertexAttributeValues::Float32x3(positions))) = mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION)
    else {
        return None;
    };
    let index: Vec<usize> = match mesh.try_indices_option().ok()? {
        Some(Indices::U16(i)) => i.iter().map(|&i| i as usize).collect(),
        Some(Indices::U32(i)) => i.iter().map(|&i| i as usize).collect(),
        None => (0..positions.len()).collect(),
    };
    let triangles = index
        .chunks_exact(3)
        .filter_map(|t| match [t[0], t[1], t[2]].map(|i| positions.get(i).map(|p| Vec3::from(*p))) {
            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
            _ => None,
        })
        .collect();
    Some(((index.len() / 3) as u64, triangles))
}

/// The triangle sizes of a mesh in its local space, if its data is in the main world.
fn mesh_triangle_sizes(mesh: &Mesh) -> Option<TriangleSizes> {
    let (count, triangles) = mesh_triangles(mesh)?;
    Some(TriangleSizes::of(count, triangles.into_iter().filter(|t| t.iter().all(|p| p.is_finite()))))
}

/// Estimates the static and per-frame dynamic point counts and warns (once per episode)
/// when the dynamic estimate exceeds `VoxelVolume::point_budget`. The static estimate is summed again only
/// when the static set, the grid or a mesh changed; the dynamic one over the dynamic occluders each frame.
#[allow(clippy::type_complexity)]
pub(crate) fn estimate_point_budget(
    meshes: Res<Assets<Mesh>>,
    mut events: MessageReader<AssetEvent<Mesh>>,
    mut cache: Local<HashMap<AssetId<Mesh>, Option<TriangleSizes>>>,
    occluders: Query<(&Mesh3d, &GlobalTransform)>,
    changes: Res<OccluderChanges>,
    assets: Option<Res<VoxelGridAssets>>,
    stats: Res<VoxelizationStats>,
    mut warned: Local<bool>,
    mut statics: Local<Option<((u64, u64, u64, u64, u32, u8), f64)>>,
    mut mesh_epoch: Local<u64>,
) {
    let _span = stats.cpu_span(|t| &mut t.estimate_point_budget);
    for event in events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } | AssetEvent::Added { id } = event {
            cache.remove(id);
            *mesh_epoch += 1;
        }
    }
    let Some(assets) = assets else { return };
    let gamma = assets.settings.effective_gamma() as f64;
    let cell = assets.grid.cell_size as f64;
    let pattern = assets.settings.pattern;
    let mut points = |entity: Entity| {
        let Ok((mesh, transform)) = occluders.get(entity) else { return 0.0 };
        let id = mesh.id();
        let entry = *cache.entry(id).or_insert_with(|| meshes.get(id).and_then(mesh_triangle_sizes));
        let Some(sizes) = entry else { return 0.0 };
        let sizes = sizes.scaled(transform.compute_transform().scale.abs().max_element() as f64);
        // Every level a mesh overlaps voxelizes it (at most all of them, each with twice the cell size).
        (0..assets.levels).map(|l| expected_point_count(&sizes, cell * (1u64 << l) as f64, gamma, pattern)).sum::<f64>()
    };
    let key = (changes.static_version, *mesh_epoch, gamma.to_bits(), cell.to_bits(), assets.levels, pattern as u8);
    let static_points = match *statics {
        Some((k, p)) if k == key => p,
        _ => {
            let p = changes.static_entities().map(&mut points).sum();
            *statics = Some((key, p));
            p
        }
    };
    let dynamic_points: f64 = changes.dynamics.iter().map(|e| points(*e)).sum();
    let budget = assets.point_budget as f64;
    if dynamic_points > budget && !*warned {
        warn!(
            "bevy_hao: an estimated {dynamic_points:.0} points per frame for the dynamic occluders, over \
             VoxelVolume::point_budget ({budget}); dynamic voxels will be missing. Raise the budget, lower the \
             resolution or gamma, or mark fewer meshes dynamic"
        );
    }
    *warned = dynamic_points > budget;
    stats.update(|s| {
        s.estimated_static_points = static_points as u64;
        s.estimated_dynamic_points = dynamic_points as u64;
    });
}
