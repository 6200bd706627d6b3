//! Extraction: the voxel grid's assets and the occluding mesh instances, with their class and transform.
//!
//! The plugin does its own extraction of instances (as Solari does) rather than reading Bevy's
//! `RenderMeshInstances`, which hold no CPU transforms when meshes are built on the GPU, and which are culled
//! to the views: an occluder behind the camera must still be voxelized.

use super::assets::{VoxelGridAssets, VoxelVolumeFocus, occluder_is_dynamic, world_aabb};
use crate::components::*;
use bevy::camera::primitives::Aabb;
use bevy::math::Affine3A;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::Extract;

/// The grid's assets (`None` while there is no valid grid) and the cascades' focus, extracted each frame.
#[derive(Resource, Default)]
pub struct ExtractedVoxelGrid {
    /// The assets.
    pub assets: Option<VoxelGridAssets>,
    /// Where the cascades are centred.
    pub focus: Option<Vec3>,
}

/// One occluding mesh instance.
#[derive(Clone, Debug)]
pub struct ExtractedOccluder {
    /// The main-world entity.
    pub entity: Entity,
    /// Its mesh.
    pub mesh: AssetId<Mesh>,
    /// Its world transform.
    pub world_from_local: Affine3A,
    /// Its world-space bounds, if Bevy computed them.
    pub world_bounds: Option<(Vec3, Vec3)>,
    /// Marked [`StaticOccluder`] (as opposed to static by default).
    pub marked_static: bool,
}

/// This frame's occluders, split into static and dynamic.
#[derive(Resource, Default)]
pub struct ExtractedOccluders {
    /// Voxelized into the cached static grid.
    pub statics: Vec<ExtractedOccluder>,
    /// Voxelized every frame.
    pub dynamics: Vec<ExtractedOccluder>,
    /// The number of [`RebuildStaticVoxels`] requests so far.
    pub rebuild_requests: u64,
}

/// Asks for the static grid to be voxelized again this frame, although nothing the plugin watches changed
/// (for instance after editing vertex data in place in a way the asset system does not report, or to
/// measure the static pass in a benchmark).
#[derive(Message, Clone, Copy, Debug, Default)]
pub struct RebuildStaticVoxels;

/// Counts [`RebuildStaticVoxels`] messages (main world).
#[derive(Resource, Default, Clone, Copy, Debug)]
pub struct StaticRebuildRequests(pub u64);

/// Main world: counts the rebuild requests of this frame.
pub fn count_rebuild_requests(
    mut messages: MessageReader<RebuildStaticVoxels>,
    mut count: ResMut<StaticRebuildRequests>,
) {
    count.0 += messages.read().count() as u64;
}

/// Extracts the grid assets.
pub fn extract_voxel_grid(
    mut commands: Commands,
    assets: Extract<Option<Res<VoxelGridAssets>>>,
    focus: Extract<Res<VoxelVolumeFocus>>,
) {
    commands.insert_resource(ExtractedVoxelGrid { assets: assets.as_deref().cloned(), focus: focus.0 });
}

/// Extracts the visible (in the hierarchy, not per view) occluding mesh instances.
#[allow(clippy::type_complexity)]
pub fn extract_voxel_occluders(
    mut extracted: ResMut<ExtractedOccluders>,
    occluders: Extract<
        Query<
            (
                Entity,
                &Mesh3d,
                &GlobalTransform,
                Option<&Aabb>,
                &InheritedVisibility,
                Has<StaticOccluder>,
                Has<DynamicOccluder>,
                Has<PromotedToDynamic>,
                Has<SkinnedMesh>,
            ),
            Without<NoVoxelOcclusion>,
        >,
    >,
    requests: Extract<Res<StaticRebuildRequests>>,
    mut warned_skinned: Local<HashSet<Entity>>,
) {
    extracted.statics.clear();
    extracted.dynamics.clear();
    extracted.rebuild_requests = requests.0;
    for (entity, mesh, transform, aabb, visible, s, d, p, skinned) in &occluders {
        if !visible.get() {
            continue;
        }
        if skinned {
            // Bevy skins meshes in the vertex shader: the slabs hold the bind pose, which would be voxelized
            // in the wrong place.
            if warned_skinned.insert(entity) {
                warn!(
                    "bevy_hao: {entity} is a skinned mesh; skinned meshes are not voxelized yet (add NoVoxelOcclusion to silence this)"
                );
            }
            continue;
        }
        let occluder = ExtractedOccluder {
            entity,
            mesh: mesh.id(),
            world_from_local: transform.affine(),
            world_bounds: aabb.map(|a| world_aabb(a, transform)),
            marked_static: s,
        };
        if occluder_is_dynamic(s, d, p) {
            extracted.dynamics.push(occluder);
        } else {
            extracted.statics.push(occluder);
        }
    }
    // A stable order, so that the static set's fingerprint does not depend on query order.
    extracted.statics.sort_by_key(|o| o.entity);
}
