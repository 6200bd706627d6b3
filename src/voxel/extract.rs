//! Extraction: the voxel grid's assets and the occluding mesh instances, with their class and transform.
//!
//! The plugin does its own extraction of instances (as Solari does) rather than reading Bevy's
//! `RenderMeshInstances`, which hold no CPU transforms when meshes are built on the GPU, and which are culled
//! to the views: an occluder behind the camera must still be voxelized.

use super::changes::{OccluderChanges, occluder_is_dynamic, world_aabb};
use super::stats::VoxelizationStats;
use super::volume::{VoxelGridAssets, VoxelVolumeFocus};
use crate::voxel::components::*;
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::DynamicSkinnedMeshBounds;
use bevy::ecs::entity::EntityHashMap;
use bevy::math::Affine3A;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::morph::MeshMorphWeights;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::platform::collections::{HashMap, HashSet};
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
    /// Voxelized every frame (marked or promoted dynamic, skinned or morphed) rather than into the cached
    /// static grid.
    pub dynamic: bool,
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
    /// Its material's albedo, linear, packed ([`crate::cpu::attributes::pack_albedo`]): white unless the
    /// volume keeps attributes (see [`material_albedo`]).
    pub albedo: u32,
}

/// The occluders, kept across frames and extracted again only where the main world saw a change
/// ([`OccluderChanges`]).
#[derive(Resource, Default)]
pub struct ExtractedOccluders {
    /// Every visible occluder, by main-world entity.
    pub occluders: EntityHashMap<ExtractedOccluder>,
    /// The entities extracted again this frame: added, changed, or gone (then absent from `occluders`).
    pub changed: Vec<Entity>,
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

/// Extracts the occluders that changed this frame (visible in the hierarchy, not per view).
#[allow(clippy::type_complexity)]
pub fn extract_voxel_occluders(
    mut extracted: ResMut<ExtractedOccluders>,
    changes: Extract<Res<OccluderChanges>>,
    occluders: Extract<
        Query<
            (
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
                Option<&MeshMaterial3d<StandardMaterial>>,
            ),
            Without<NoVoxelOcclusion>,
        >,
    >,
    requests: Extract<Res<StaticRebuildRequests>>,
    meshes: Extract<Res<Assets<Mesh>>>,
    (grid, materials, images): (
        Extract<Option<Res<VoxelGridAssets>>>,
        Extract<Option<Res<Assets<StandardMaterial>>>>,
        Extract<Option<Res<Assets<Image>>>>,
    ),
    mut checked: Local<HashSet<(AssetId<Mesh>, Option<u32>)>>,
    mut warned_morph: Local<bool>,
    mut texture_means: Local<HashMap<AssetId<Image>, Vec3>>,
    stats: Res<VoxelizationStats>,
) {
    let _span = stats.cpu_span(|t| &mut t.extract_occluders);
    let attributes = grid.as_ref().is_some_and(|g| g.attributes.is_some());
    let extracted = &mut *extracted;
    extracted.rebuild_requests = requests.0;
    extracted.changed.clear();
    extracted.changed.extend(&changes.changed);
    if changes.all_changed {
        extracted.changed.extend(changes.occluders.keys());
    }
    for &entity in &extracted.changed {
        let Ok((mesh, transform, aabb, visible, s, d, p, skin, dynamic_bounds, morphed, pn, fill, material)) =
            occluders.get(entity)
        else {
            extracted.occluders.remove(&entity);
            continue;
        };
        if !visible.get() {
            extracted.occluders.remove(&entity);
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
            // Skinned and morphed meshes move by themselves: dynamic unless marked static (then voxelized in
            // the pose they have when the static voxels are built). The tracker's class: a mesh it promoted
            // this frame is dynamic already.
            dynamic: occluder_is_dynamic(s, d, p || skin_joints.is_some() || morphed)
                || changes.dynamics.contains(&entity),
            marked_static: s,
            skin_joints,
            morphed,
            pn,
            solid: fill == Some(&VoxelFill::Solid),
            albedo: match (material, materials.as_deref(), images.as_deref()) {
                (Some(m), Some(materials), Some(images)) if attributes => {
                    material_albedo(m, materials, images, &mut texture_means)
                }
                _ => WHITE,
            },
        };
        extracted.occluders.insert(entity, occluder);
    }
}

const WHITE: u32 = 0x00ff_ffff;

/// Pixels of a base-colour texture averaged at most (evenly spaced).
const TEXTURE_MEAN_SAMPLES: usize = 1 << 16;

/// A material's albedo for multi-valued voxels, linear, packed: `base_color`, times the mean colour of
/// `base_color_texture` where that image is 8-bit RGBA (sRGB or linear) with its data in the main world
/// (otherwise the factor alone), with [`crate::cpu::attributes::TWO_SIDED_BIT`] for a material drawn from
/// both sides. Means are computed once per image (an image changed later keeps its first mean), from at
/// most [`TEXTURE_MEAN_SAMPLES`] pixels of its first mip.
pub fn material_albedo(
    material: &MeshMaterial3d<StandardMaterial>,
    materials: &Assets<StandardMaterial>,
    images: &Assets<Image>,
    means: &mut HashMap<AssetId<Image>, Vec3>,
) -> u32 {
    let Some(m) = materials.get(material) else { return WHITE };
    let base = m.base_color.to_linear();
    let mut albedo = Vec3::new(base.red, base.green, base.blue);
    if let Some(texture) = &m.base_color_texture {
        let id = texture.id();
        let mean = match means.get(&id) {
            Some(mean) => Some(*mean),
            None => {
                let mean = images.get(id).and_then(texture_mean);
                if let Some(mean) = mean {
                    means.insert(id, mean);
                }
                mean
            }
        };
        albedo *= mean.unwrap_or(Vec3::ONE);
    }
    let two_sided = m.double_sided || m.cull_mode.is_none();
    crate::cpu::attributes::pack_albedo(albedo) | if two_sided { crate::cpu::attributes::TWO_SIDED_BIT } else { 0 }
}

/// The mean linear colour of an 8-bit RGBA image's first mip, from evenly spaced pixels.
fn texture_mean(image: &Image) -> Option<Vec3> {
    use bevy::render::render_resource::TextureFormat;
    let srgb = match image.texture_descriptor.format {
        TextureFormat::Rgba8UnormSrgb => true,
        TextureFormat::Rgba8Unorm => false,
        _ => return None,
    };
    let data = image.data.as_ref()?;
    let size = image.texture_descriptor.size;
    let pixels = (size.width as usize * size.height as usize).min(data.len() / 4);
    if pixels == 0 {
        return None;
    }
    let step = pixels.div_ceil(TEXTURE_MEAN_SAMPLES);
    let decode = |b: u8| {
        let c = b as f32 / 255.0;
        if srgb { Srgba::gamma_function(c) } else { c }
    };
    let mut sum = Vec3::ZERO;
    let mut n = 0u32;
    for p in (0..pixels).step_by(step) {
        let px = &data[p * 4..p * 4 + 3];
        sum += Vec3::new(decode(px[0]), decode(px[1]), decode(px[2]));
        n += 1;
    }
    Some(sum / n as f32)
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

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};

    #[test]
    fn a_material_albedo_is_its_base_colour_times_its_texture_mean() {
        let size = Extent3d { width: 2, height: 1, depth_or_array_layers: 1 };
        // sRGB 188 is linear 0.5 (to a byte), 0 is 0: the mean of red (188, 0, 0) and grey (188, 188, 188).
        let pixels = vec![188, 0, 0, 255, 188, 188, 188, 255];
        let image =
            Image::new(size, TextureDimension::D2, pixels, TextureFormat::Rgba8UnormSrgb, RenderAssetUsages::default());
        let mut images = Assets::<Image>::default();
        let texture = images.add(image);
        let mut materials = Assets::<StandardMaterial>::default();
        let plain = materials.add(StandardMaterial { base_color: Color::linear_rgb(0.2, 0.4, 1.0), ..default() });
        let textured = materials.add(StandardMaterial {
            base_color: Color::WHITE,
            base_color_texture: Some(texture.clone()),
            ..default()
        });
        // An image in another format: the factor alone.
        let float = Image::new(
            size,
            TextureDimension::D2,
            vec![0; 32],
            TextureFormat::Rgba32Float,
            RenderAssetUsages::default(),
        );
        let missing = materials.add(StandardMaterial { base_color_texture: Some(images.add(float)), ..default() });
        let mut means = HashMap::new();
        let albedo = |m: &Handle<StandardMaterial>, means: &mut HashMap<_, _>| {
            crate::cpu::attributes::unpack_albedo(material_albedo(
                &MeshMaterial3d(m.clone()),
                &materials,
                &images,
                means,
            ))
        };
        assert!(albedo(&plain, &mut means).distance(Vec3::new(0.2, 0.4, 1.0)) < 0.5 / 255.0);
        let mean = albedo(&textured, &mut means);
        assert!(mean.distance(Vec3::new(0.5, 0.25, 0.25)) < 1.5 / 255.0, "{mean}");
        assert_eq!(means.len(), 1, "the mean is kept");
        assert_eq!(albedo(&missing, &mut means), Vec3::ONE);
    }
}
