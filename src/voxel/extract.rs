//! Extraction: the voxel grid's assets and the occluding mesh instances, with their class and transform.
//!
//! The plugin does its own extraction of instances (as Solari does) rather than reading Bevy's
//! `RenderMeshInstances`, which hold no CPU transforms when meshes are built on the GPU, and which are culled
//! to the views: an occluder behind the camera must still be voxelized.

use super::occluders::{occluder_is_dynamic, world_aabb};
use super::volume::{VoxelGridAssets, VoxelVolumeFocus};
use crate::voxel::components::*;
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::DynamicSkinnedMeshBounds;
use bevy::math::Affine3A;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::morph::MeshMorphWeights;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::Extract;

/// The grid's assets (`None` while there is no valid grid) and the cascades' focus, extracted each frame.
#[derive(Resource, Default)]
pub struct ExtractedVoxelGrid {
    pub assets: Option<VoxelGridAssets>,
    /// Where the cascades are centred.
    pub focus: Option<Vec3>,
}

/// One occluding mesh instance.
#[derive(Clone, Debug)]
pub struct ExtractedOccluder {
    /// The main-world entity.
    pub entity: Entity,
    pub mesh: AssetId<Mesh>,
    /// Its world transform.
    pub world_from_local: Affine3A,
    /// Its world-space bounds, if Bevy computed them.
    pub world_bounds: Option<(Vec3, Vec3)>,
    /// Marked [`StaticOccluder`] (as opposed to static by default).
    pub marked_static: bool,
    /// For a skinned mesh ([`SkinnedMesh`]), the number of joints of its skin. Its vertices are skinned to
    /// world space by Bevy's joint matrices, so `world_from_local` is not applied to them.
    pub skin_joints: Option<u32>,
    /// Whether it has morph weights ([`MeshMorphWeights`]): its mesh's morph targets are applied with them.
    pub morphed: bool,
    /// Marked [`PnTriangles`]: voxelized as PN triangles from its normals.
    pub pn: bool,
    /// [`VoxelFill::Solid`]: its inside is filled.
    pub solid: bool,
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
                Option<&SkinnedMesh>,
                Has<DynamicSkinnedMeshBounds>,
                Has<MeshMorphWeights>,
                Has<PnTriangles>,
                Option<&VoxelFill>,
            ),
            Without<NoVoxelOcclusion>,
        >,
    >,
    requests: Extract<Res<StaticRebuildRequests>>,
    meshes: Extract<Res<Assets<Mesh>>>,
    mut checked: Local<HashSet<(AssetId<Mesh>, Option<u32>)>>,
    mut warned_morph: Local<bool>,
) {
    extracted.statics.clear();
    extracted.dynamics.clear();
    extracted.rebuild_requests = requests.0;
    for (entity, mesh, transform, aabb, visible, s, d, p, skin, dynamic_bounds, morphed, pn, fill) in &occluders {
        if !visible.get() {
            continue;
        }
        if morphed && !cfg!(feature = "morph") && !std::mem::replace(&mut *warned_morph, true) {
            warn!(
                "bevy_hao: {entity} has morph targets, and bevy_hao was built without its `morph` feature: its base \
                 shape is voxelized (skinned if it is skinned)"
            );
        }
        let skin_joints = skin.map(|k| k.joints.len() as u32);
        // Checked once per mesh and skin, once the mesh has loaded.
        if !checked.contains(&(mesh.id(), skin_joints))
            && let Some(m) = meshes.get(mesh)
        {
            checked.insert((mesh.id(), skin_joints));
            check_skin_data(entity, m, skin_joints);
        }
        // A skinned mesh's `Aabb` follows its pose only with `DynamicSkinnedMeshBounds` (which Bevy's glTF
        // loader adds), and a morphed mesh's never does; otherwise the whole cascade is treated as touched.
        let bounds_valid = (skin_joints.is_none() || dynamic_bounds) && !morphed;
        let occluder = ExtractedOccluder {
            entity,
            mesh: mesh.id(),
            world_from_local: transform.affine(),
            world_bounds: aabb.filter(|_| bounds_valid).map(|a| world_aabb(a, transform)),
            marked_static: s,
            skin_joints,
            morphed,
            pn,
            solid: fill == Some(&VoxelFill::Solid),
        };
        // Skinned and morphed meshes move by themselves: dynamic unless marked static (then voxelized in the
        // pose they have when the static voxels are built).
        if occluder_is_dynamic(s, d, p || skin_joints.is_some() || morphed) {
            extracted.dynamics.push(occluder);
        } else {
            extracted.statics.push(occluder);
        }
    }
    // A stable order, so that the static set's fingerprint does not depend on query order.
    extracted.statics.sort_by_key(|o| o.entity);
}

/// Warns (once per mesh and skin) about skin data that will not voxelize as the user may expect: joints
/// without a [`SkinnedMesh`] (voxelized unskinned), a skin on a mesh without joint data (drawn and
/// voxelized in the bind pose), joint indices past the skin (those triangles are skipped), and weights
/// that do not sum to one (used as given, as Bevy's shader does).
fn check_skin_data(entity: Entity, mesh: &Mesh, skin_joints: Option<u32>) {
    // A mesh kept only in the render world has no data left here: nothing to check.
    let (Ok(joints), Ok(weights)) = (
        mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_INDEX),
        mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_WEIGHT),
    ) else {
        return;
    };
    let Some(joint_count) = skin_joints else {
        if joints.is_some() {
            warn!(
                "bevy_hao: {entity} has joint indices but no SkinnedMesh: it is voxelized unskinned, in its bind pose \
                 (and Bevy 0.19 cannot draw it with a material)"
            );
        }
        return;
    };
    let (Some(VertexAttributeValues::Uint16x4(joints)), Some(VertexAttributeValues::Float32x4(weights))) =
        (joints, weights)
    else {
        warn!(
            "bevy_hao: {entity} has a SkinnedMesh but its mesh lacks Uint16x4 joint indices or Float32x4 joint \
             weights: it is voxelized unskinned, in its bind pose"
        );
        return;
    };
    let skin = crate::cpu::VertexSkin { joints: joints.clone(), weights: weights.clone() };
    if let Some(max) = crate::cpu::skinning::max_joint_index(&skin).filter(|m| *m as u32 >= joint_count) {
        warn!(
            "bevy_hao: {entity}'s mesh names joint {max} but its skin has {joint_count} joints; the triangles of \
             those vertices are not voxelized"
        );
    }
    if !crate::cpu::skinning::weights_are_normalized(&skin, 1e-3) {
        warn!(
            "bevy_hao: {entity}'s joint weights do not all sum to 1; they are used as given, as Bevy draws them \
             (the glTF loader normalizes them)"
        );
    }
}
