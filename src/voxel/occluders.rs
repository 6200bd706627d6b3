//! Main world: which meshes are occluders, static or dynamic (the markers of `crate::voxel::components`, and
//! meshes that move without one promoted to dynamic).

use crate::voxel::components::*;
use bevy::camera::primitives::Aabb;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

/// Whether an occluder entity is dynamic, from its markers (`None`: not an occluder).
pub(crate) fn occluder_is_dynamic(is_static: bool, is_dynamic: bool, promoted: bool) -> bool {
    is_dynamic || (promoted && !is_static)
}

/// The markers that class a mesh entity as a static or dynamic occluder, as queried by the main-world
/// systems that look at the static set.
pub(crate) type OccluderMarkers = (Has<StaticOccluder>, Has<DynamicOccluder>, Has<PromotedToDynamic>);

/// [`occluder_is_dynamic`] of queried [`OccluderMarkers`].
pub(crate) fn markers_are_dynamic((is_static, is_dynamic, promoted): (bool, bool, bool)) -> bool {
    occluder_is_dynamic(is_static, is_dynamic, promoted)
}

/// The world-space bounds of an entity's mesh.
pub(crate) fn world_aabb(aabb: &Aabb, transform: &GlobalTransform) -> (Vec3, Vec3) {
    let m = transform.affine();
    let center = m.transform_point3a(aabb.center);
    let m3 = m.matrix3;
    let half = m3.x_axis.abs() * aabb.half_extents.x
        + m3.y_axis.abs() * aabb.half_extents.y
        + m3.z_axis.abs() * aabb.half_extents.z;
    (Vec3::from(center - half), Vec3::from(center + half))
}

/// Promotes unmarked mesh entities that move to dynamic occluders (see [`PromotedToDynamic`]).
pub(crate) fn promote_moved_occluders(
    mut commands: Commands,
    candidates: Query<
        (Entity, &GlobalTransform),
        (
            With<Mesh3d>,
            Without<StaticOccluder>,
            Without<DynamicOccluder>,
            Without<NoVoxelOcclusion>,
            Without<PromotedToDynamic>,
        ),
    >,
    mut last: Local<HashMap<Entity, GlobalTransform>>,
) {
    let mut seen = HashMap::with_capacity(last.len());
    for (entity, transform) in &candidates {
        if let Some(previous) = last.get(&entity)
            && previous != transform
        {
            debug!("bevy_hao: {entity} moved; treating it as a dynamic occluder from now on");
            commands.entity(entity).insert(PromotedToDynamic);
            continue;
        }
        seen.insert(entity, *transform);
    }
    *last = seen;
}
