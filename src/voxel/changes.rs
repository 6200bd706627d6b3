//! Main world: which occluders changed this frame, from Bevy's change detection, so that every later step
//! (promotion, extraction, the point estimate, the fitted grid, the gamma calibration) works on what changed
//! rather than on every mesh entity.
//!
//! One system, [`track_occluders`], reads the change ticks of the components an occluder's voxels depend on
//! and the removals of the markers, and keeps:
//! - the entities that changed this frame (extraction reads only those, plus every occluder on the rare
//!   frames when a material changed or the volume started keeping attributes);
//! - each occluder's last transform and class, so that an unmarked mesh that really moved is promoted to
//!   dynamic ([`PromotedToDynamic`]);
//! - a version of the static set, bumped when a static occluder is added, removed, moved, re-meshed,
//!   re-marked, shown or hidden: the systems that look at the whole static set do so only when it changed.

use super::stats::VoxelizationStats;
use crate::voxel::components::*;
use bevy::camera::primitives::Aabb;
use bevy::ecs::entity::{EntityHashMap, EntityHashSet};
use bevy::mesh::morph::MeshMorphWeights;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;

/// Whether an occluder entity is dynamic, from its markers.
pub(crate) fn occluder_is_dynamic(is_static: bool, is_dynamic: bool, promoted: bool) -> bool {
    is_dynamic || (promoted && !is_static)
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

/// What the tracker remembers of an occluder.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TrackedOccluder {
    /// Its transform when last seen changing.
    pub transform: GlobalTransform,
    /// Classed dynamic (marked, promoted, skinned or morphed).
    pub dynamic: bool,
}

/// The occluders as last seen, and this frame's changes (see the module's documentation).
#[derive(Resource, Default)]
pub struct OccluderChanges {
    /// Every visible occluding mesh entity.
    pub(crate) occluders: EntityHashMap<TrackedOccluder>,
    /// The dynamic ones among them.
    pub(crate) dynamics: EntityHashSet,
    /// Entities whose occluder may have changed this frame (added, changed, removed, hidden or shown):
    /// extraction reads these again.
    pub(crate) changed: Vec<Entity>,
    /// Every occluder must be extracted again this frame (a material changed while attributes are kept,
    /// attributes turned on or off).
    pub(crate) all_changed: bool,
    /// Bumped whenever the static set changes.
    pub(crate) static_version: u64,
}

impl OccluderChanges {
    /// The visible occluders that are static.
    pub(crate) fn static_entities(&self) -> impl Iterator<Item = Entity> + '_ {
        self.occluders.iter().filter(|(_, o)| !o.dynamic).map(|(e, _)| *e)
    }
}

/// The components every mesh entity has whose changes make an occluder's voxels out of date. Each term of
/// an `Or` is checked for every entity the query matches, so the components few entities have are queried
/// apart: those queries match only the archetypes that have them.
type MeshChanged = Or<(Changed<GlobalTransform>, Changed<Mesh3d>, Changed<InheritedVisibility>, Changed<Aabb>)>;

/// The markers, added or changed.
type MarkersChanged = Or<(
    Changed<StaticOccluder>,
    Changed<DynamicOccluder>,
    Changed<PromotedToDynamic>,
    Changed<NoVoxelOcclusion>,
    Changed<VoxelFill>,
    Changed<PnTriangles>,
)>;

/// Skins and morph targets, added or changed.
type AnimationChanged = Or<(Changed<SkinnedMesh>, Added<MeshMorphWeights>)>;

/// The queries of the entities that changed, by how many entities have the components.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct OccluderChangedQueries<'w, 's> {
    mesh: Query<'w, 's, Entity, (With<Mesh3d>, MeshChanged)>,
    markers: Query<'w, 's, Entity, (With<Mesh3d>, MarkersChanged)>,
    animation: Query<'w, 's, Entity, (With<Mesh3d>, AnimationChanged)>,
    /// Read only where the volume keeps attributes (albedo comes from the material).
    material: Query<'w, 's, Entity, (With<Mesh3d>, Changed<MeshMaterial3d<StandardMaterial>>)>,
}

/// Removals that change whether or how an entity occludes.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct OccluderRemovals<'w, 's> {
    mesh: RemovedComponents<'w, 's, Mesh3d>,
    marked_static: RemovedComponents<'w, 's, StaticOccluder>,
    marked_dynamic: RemovedComponents<'w, 's, DynamicOccluder>,
    promoted: RemovedComponents<'w, 's, PromotedToDynamic>,
    excluded: RemovedComponents<'w, 's, NoVoxelOcclusion>,
    fill: RemovedComponents<'w, 's, VoxelFill>,
    pn: RemovedComponents<'w, 's, PnTriangles>,
    skin: RemovedComponents<'w, 's, SkinnedMesh>,
    morph: RemovedComponents<'w, 's, MeshMorphWeights>,
    material: RemovedComponents<'w, 's, MeshMaterial3d<StandardMaterial>>,
}

impl OccluderRemovals<'_, '_> {
    fn read(&mut self) -> impl Iterator<Item = Entity> + '_ {
        self.mesh
            .read()
            .chain(self.marked_static.read())
            .chain(self.marked_dynamic.read())
            .chain(self.promoted.read())
            .chain(self.excluded.read())
            .chain(self.fill.read())
            .chain(self.pn.read())
            .chain(self.skin.read())
            .chain(self.morph.read())
            .chain(self.material.read())
    }
}

/// An occluder as [`track_occluders`] queries it.
type OccluderQueryData = (
    &'static GlobalTransform,
    &'static InheritedVisibility,
    Has<StaticOccluder>,
    Has<DynamicOccluder>,
    Has<PromotedToDynamic>,
    Has<SkinnedMesh>,
    Has<MeshMorphWeights>,
);

/// Finds the occluders that changed this frame, promotes unmarked meshes that moved, and bumps the static
/// set's version when it changed.
#[allow(clippy::type_complexity)]
pub(crate) fn track_occluders(
    mut commands: Commands,
    mut changes: ResMut<OccluderChanges>,
    changed: OccluderChangedQueries,
    occluders: Query<OccluderQueryData, (With<Mesh3d>, Without<NoVoxelOcclusion>)>,
    mut removals: OccluderRemovals,
    mut material_events: MessageReader<AssetEvent<StandardMaterial>>,
    mut image_events: MessageReader<AssetEvent<Image>>,
    volumes: Query<&VoxelVolume>,
    wanted: Res<super::volume::AttributesWanted>,
    mut had_attributes: Local<bool>,
    stats: Res<VoxelizationStats>,
) {
    let _span = stats.cpu_span(|t| &mut t.track_occluders);
    let changes = &mut *changes;
    changes.changed.clear();
    // Albedo comes from materials only where the volume keeps attributes.
    let attributes = volumes.iter().next().is_some_and(|v| v.attributes) || wanted.0;
    changes.changed.extend(changed.mesh.iter());
    changes.changed.extend(changed.markers.iter());
    changes.changed.extend(changed.animation.iter());
    if attributes {
        changes.changed.extend(changed.material.iter());
    }
    changes.changed.extend(removals.read());
    // An entity met twice is looked at once.
    if changes.changed.len() > 1 {
        changes.changed.sort_unstable();
        changes.changed.dedup();
    }
    // (A material or texture that loads or changes: the albedo of every occluder may change.)
    let material_changed =
        material_events.read().any(|e| !matches!(e, AssetEvent::Removed { .. } | AssetEvent::Unused { .. }))
            | image_events
                .read()
                .any(|e| matches!(e, AssetEvent::Added { .. } | AssetEvent::LoadedWithDependencies { .. }));
    changes.all_changed =
        (attributes && material_changed) || attributes != std::mem::replace(&mut *had_attributes, attributes);
    let mut static_changed = false;
    for &entity in &changes.changed {
        let now = occluders.get(entity).ok().filter(|o| o.1.get());
        let old = changes.occluders.get(&entity).copied();
        let Some((transform, _, s, d, p, skinned, morphed)) = now else {
            if let Some(old) = old {
                changes.occluders.remove(&entity);
                changes.dynamics.remove(&entity);
                static_changed |= !old.dynamic;
            }
            continue;
        };
        let marked = s || d;
        // An unmarked static mesh that moved (not merely touched) from now on is dynamic.
        let moved = old.is_some_and(|o| !o.dynamic && o.transform != *transform);
        let promote = moved && !marked && !p && !skinned && !morphed;
        if promote {
            debug!("bevy_hao: {entity} moved; treating it as a dynamic occluder from now on");
            commands.entity(entity).insert(PromotedToDynamic);
        }
        let dynamic = promote || occluder_is_dynamic(s, d, p || skinned || morphed);
        changes.occluders.insert(entity, TrackedOccluder { transform: *transform, dynamic });
        if dynamic {
            changes.dynamics.insert(entity);
        } else {
            changes.dynamics.remove(&entity);
        }
        // A static occluder added, changed or gone, or one that changed class.
        static_changed |= !dynamic || old.is_some_and(|o| !o.dynamic);
    }
    if static_changed || changes.all_changed {
        changes.static_version += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn app() -> App {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default()))
            .init_asset::<StandardMaterial>()
            .init_asset::<Mesh>()
            .init_asset::<Image>()
            .init_resource::<OccluderChanges>()
            .init_resource::<crate::voxel::volume::AttributesWanted>()
            .init_resource::<VoxelizationStats>()
            .add_systems(PostUpdate, track_occluders.after(bevy::transform::TransformSystems::Propagate));
        app
    }

    fn spawn_cube(app: &mut App, at: Vec3) -> Entity {
        let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(Cuboid::default());
        app.world_mut().spawn((Mesh3d(mesh), Transform::from_translation(at), InheritedVisibility::VISIBLE)).id()
    }

    #[test]
    fn only_what_changed_is_tracked_again() {
        let mut app = app();
        let cubes: Vec<Entity> = (0..50).map(|i| spawn_cube(&mut app, Vec3::X * i as f32)).collect();
        app.update();
        let c = app.world().resource::<OccluderChanges>();
        assert_eq!(c.changed.len(), 50, "every new mesh is a change");
        assert_eq!(c.occluders.len(), 50);
        let version = c.static_version;
        app.update();
        let c = app.world().resource::<OccluderChanges>();
        assert!(c.changed.is_empty(), "nothing changed: {:?}", c.changed);
        assert_eq!(c.static_version, version, "the static set did not change");

        // A transform written with its own value: looked at again, not promoted.
        app.world_mut().get_mut::<Transform>(cubes[3]).unwrap().set_changed();
        app.update();
        assert_eq!(app.world().resource::<OccluderChanges>().changed, vec![cubes[3]]);
        assert!(app.world().get::<PromotedToDynamic>(cubes[3]).is_none());

        // A real move promotes an unmarked mesh, once.
        app.world_mut().get_mut::<Transform>(cubes[7]).unwrap().translation.y += 1.0;
        app.update();
        let c = app.world().resource::<OccluderChanges>();
        assert_eq!(c.changed, vec![cubes[7]]);
        assert!(c.static_version > version, "a static occluder left the static set");
        assert!(c.dynamics.contains(&cubes[7]));
        assert!(app.world().get::<PromotedToDynamic>(cubes[7]).is_some());

        // A despawned occluder is forgotten.
        app.world_mut().despawn(cubes[9]);
        app.update();
        let c = app.world().resource::<OccluderChanges>();
        assert!(!c.occluders.contains_key(&cubes[9]));
        assert_eq!(c.occluders.len(), 49);

        // NoVoxelOcclusion takes it out; removing it brings it back.
        app.world_mut().entity_mut(cubes[11]).insert(NoVoxelOcclusion);
        app.update();
        assert!(!app.world().resource::<OccluderChanges>().occluders.contains_key(&cubes[11]));
        app.world_mut().entity_mut(cubes[11]).remove::<NoVoxelOcclusion>();
        app.update();
        assert!(app.world().resource::<OccluderChanges>().occluders.contains_key(&cubes[11]));
    }
}
