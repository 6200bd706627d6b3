//! What changed: the occluders resolved to the mesh allocator's slabs, kept across frames and resolved again
//! only where extraction saw a change, where a mesh was uploaded again or its slab moved, where an
//! occluder waits for its mesh, and for skinned and morphed meshes (whose places in Bevy's joint matrices and
//! morph weights are looked up each frame). Changes to the static set become the world boxes whose static
//! voxels must be rebuilt.

use super::super::extract::{ExtractedOccluder, ExtractedOccluders};
use super::super::pipelines::*;
use super::moved::{MovedOccluder, Pose, moved};
use bevy::ecs::entity::{EntityHashMap, EntityHashSet};
use bevy::mesh::VertexFormat;
use bevy::pbr::SkinUniforms;
#[cfg(feature = "morph")]
use bevy::pbr::{MorphIndices, MorphUniforms};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::mesh::{RenderMesh, RenderMeshBufferInfo};
use bevy::render::render_asset::{ExtractedAssets, RenderAssets};
use bevy::render::render_resource::*;
use bevy::render::sync_world::MainEntity;

/// What a mesh was warned about (once each).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum WarnedFor {
    /// It cannot be voxelized.
    Skipped,
    /// Its morph targets cannot be applied.
    Morph,
    /// `PnTriangles` without normals: voxelized flat.
    FlatPn,
}

/// An occluder ready for the GPU.
#[derive(Clone)]
pub(super) struct ResolvedInstance {
    /// The vertex, index and morph-target slabs: instances sharing them share a classify dispatch.
    pub slabs: (BufferId, Option<BufferId>, Option<BufferId>),
    pub vertex_buffer: Buffer,
    pub index_buffer: Option<Buffer>,
    pub morph_buffer: Option<Buffer>,
    pub gpu: GpuOccluderInstance,
    /// Vertex range (start, end), first index, triangles.
    pub ranges: [u32; 4],
}

#[allow(clippy::large_enum_variant, reason = "one per instance per frame, matched at once")]
pub(super) enum Resolution {
    Ready(ResolvedInstance),
    /// Not uploaded yet: try again next frame.
    Pending,
    /// Cannot be voxelized (warned once per mesh).
    Skipped,
}

/// Where skinned and morphed meshes get their joint matrices and morph weights this frame.
pub(super) struct Skins<'a> {
    /// Bevy's joint matrices (`None` if the device cannot bind them as storage).
    pub uniforms: Option<&'a SkinUniforms>,
    /// Whether the classify pipeline skins (see `VoxelizePipelines::skinning`).
    pub supported: bool,
    /// Bevy's morph descriptors per entity, where the pipeline applies morph targets.
    #[cfg(feature = "morph")]
    pub morphs: Option<(&'a MorphIndices, &'a MorphUniforms)>,
}

/// An instance's morph data: (weights offset, weight count, targets offset, vertices per target) and the
/// morph-target slab, or `None` if it is not morphed. `Err` while Bevy has not placed its weights (a mesh not
/// visible to any view).
#[cfg(feature = "morph")]
fn resolve_morph(
    o: &ExtractedOccluder,
    allocator: &MeshAllocator,
    skins: &Skins,
    warned: &mut HashSet<(AssetId<Mesh>, WarnedFor)>,
) -> Result<Option<([u32; 4], Buffer)>, ()> {
    // Without morph weights Bevy draws the base shape, and so is it voxelized.
    if !o.morphed {
        return Ok(None);
    }
    let Some(slice) = allocator.mesh_morph_target_slice(&o.mesh) else { return Ok(None) };
    let Some((indices, uniforms)) = skins.morphs else {
        if warned.insert((o.mesh, WarnedFor::Morph)) {
            warn!(
                "bevy_hao: mesh {:?} has morph targets, and this device cannot bind them for voxelization: its base \
                 shape is voxelized",
                o.mesh
            );
        }
        return Ok(None);
    };
    if !slice.buffer.usage().contains(BufferUsages::STORAGE) {
        if warned.insert((o.mesh, WarnedFor::Morph)) {
            warn!(
                "bevy_hao: mesh {:?}'s morph targets cannot be bound as storage: its base shape is voxelized",
                o.mesh
            );
        }
        return Ok(None);
    }
    let descriptor = indices
        .morph_descriptor_index(MainEntity::from(o.entity))
        .and_then(|i| uniforms.descriptors_buffer.as_ref()?.values().get(i.0 as usize).copied())
        .ok_or(())?;
    Ok(Some((
        [
            descriptor.current_weights_offset,
            descriptor.weight_count,
            descriptor.targets_offset,
            descriptor.vertex_count,
        ],
        slice.buffer.clone(),
    )))
}

/// Joint indices (`Uint16x4`) and weights (`Float32x4`) of a mesh layout, in words; `None` if either is
/// missing, misaligned or of another format.
fn joint_attributes(mesh: &RenderMesh) -> Option<(u32, u32)> {
    let layout = mesh.layout.0.layout();
    let find = |id, format| {
        let i = mesh.layout.0.attribute_ids().iter().position(|a| *a == id)?;
        let a = layout.attributes[i];
        (a.format == format && a.offset.is_multiple_of(4)).then_some((a.offset / 4) as u32)
    };
    Some((
        find(Mesh::ATTRIBUTE_JOINT_INDEX.id, VertexFormat::Uint16x4)?,
        find(Mesh::ATTRIBUTE_JOINT_WEIGHT.id, VertexFormat::Float32x4)?,
    ))
}

pub(super) fn resolve_occluder(
    o: &ExtractedOccluder,
    meshes: &RenderAssets<RenderMesh>,
    allocator: &MeshAllocator,
    skins: &Skins,
    warned: &mut HashSet<(AssetId<Mesh>, WarnedFor)>,
) -> Resolution {
    let Some(mesh) = meshes.get(o.mesh) else { return Resolution::Pending };
    let skip = |warned: &mut HashSet<(AssetId<Mesh>, WarnedFor)>, why: &str| {
        if warned.insert((o.mesh, WarnedFor::Skipped)) {
            warn!("bevy_hao: mesh {:?} is not voxelized: {why}", o.mesh);
        }
        Resolution::Skipped
    };
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return skip(warned, &format!("its topology is {:?}, not a triangle list", mesh.primitive_topology()));
    }
    let Some(vertices) = allocator.mesh_vertex_slice(&o.mesh) else { return Resolution::Pending };
    if !vertices.buffer.usage().contains(BufferUsages::STORAGE) {
        return skip(
            warned,
            "it sits in a vertex slab that cannot be bound as storage (a mesh above the slab allocator's large_threshold)",
        );
    }
    let layout = mesh.layout.0.layout();
    let stride = layout.array_stride;
    let Some(position) = mesh
        .layout
        .0
        .attribute_ids()
        .iter()
        .position(|id| *id == Mesh::ATTRIBUTE_POSITION.id)
        .map(|i| layout.attributes[i])
    else {
        return skip(warned, "it has no positions");
    };
    if position.format != VertexFormat::Float32x3 || stride % 4 != 0 || position.offset % 4 != 0 {
        return skip(warned, "its positions are not 4-byte aligned Float32x3");
    }
    // A PN occluder: its normals' place in the vertex; without usable normals it is voxelized flat.
    let mut normal_offset = NO_NORMALS;
    if o.pn {
        let normal = mesh
            .layout
            .0
            .attribute_ids()
            .iter()
            .position(|id| *id == Mesh::ATTRIBUTE_NORMAL.id)
            .map(|i| layout.attributes[i]);
        match normal {
            Some(n) if n.format == VertexFormat::Float32x3 && n.offset % 4 == 0 => {
                normal_offset = (n.offset / 4) as u32
            }
            _ => {
                if warned.insert((o.mesh, WarnedFor::FlatPn)) {
                    warn!("bevy_hao: mesh {:?} has PnTriangles but no Float32x3 normals: it is voxelized flat", o.mesh);
                }
            }
        }
    }
    // Vertex colours (multi-valued voxels' albedo): Float32x4, as Bevy keeps them.
    let color_offset = mesh
        .layout
        .0
        .attribute_ids()
        .iter()
        .position(|id| *id == Mesh::ATTRIBUTE_COLOR.id)
        .map(|i| layout.attributes[i])
        .filter(|a| a.format == VertexFormat::Float32x4 && a.offset % 4 == 0)
        .map_or(NO_COLORS, |a| (a.offset / 4) as u32);
    // A skinned mesh: its joint data in the vertex layout, and its skin's place in Bevy's joint matrices
    // (allocated only while the mesh is visible to a view). Without joint data it is voxelized unskinned
    // (extraction warned); where the device cannot skin, skipped.
    let (mut skin_index, mut joint_count, mut joint_offset, mut weight_offset) = (NO_SKIN, 0, 0, 0);
    if let (Some(joints), Some((j, w))) = (o.skin_joints, joint_attributes(mesh)) {
        let Some(uniforms) = skins.uniforms.filter(|_| skins.supported) else {
            return skip(warned, "it is skinned, and this device cannot bind the joint matrices for voxelization");
        };
        let Some(index) = uniforms.skin_index(MainEntity::from(o.entity)) else { return Resolution::Pending };
        (skin_index, joint_count, joint_offset, weight_offset) = (index, joints, j, w);
    }
    // A morphed mesh: its targets' slab and Bevy's descriptor of its weights.
    #[cfg(feature = "morph")]
    let (morph, morph_buffer) = match resolve_morph(o, allocator, skins, warned) {
        Ok(Some((m, b))) => (m, Some(b)),
        Ok(None) => ([0; 4], None),
        Err(()) => return Resolution::Pending,
    };
    #[cfg(not(feature = "morph"))]
    let (morph, morph_buffer): ([u32; 4], Option<Buffer>) = ([0; 4], None);
    let (index_buffer, index_start, index_format, triangles) = match &mesh.buffer_info {
        RenderMeshBufferInfo::Indexed { count, index_format } => {
            let Some(indices) = allocator.mesh_index_slice(&o.mesh) else { return Resolution::Pending };
            if !indices.buffer.usage().contains(BufferUsages::STORAGE) || indices.buffer.size() % 4 != 0 {
                return skip(warned, "it sits in an index slab that cannot be bound as storage");
            }
            let format = match index_format {
                IndexFormat::Uint16 => 1,
                IndexFormat::Uint32 => 2,
            };
            (Some(indices.buffer.clone()), indices.range.start, format, count / 3)
        }
        RenderMeshBufferInfo::NonIndexed => (None, 0, 0, mesh.vertex_count / 3),
    };
    Resolution::Ready(ResolvedInstance {
        slabs: (vertices.buffer.id(), index_buffer.as_ref().map(|b| b.id()), morph_buffer.as_ref().map(|b| b.id())),
        vertex_buffer: vertices.buffer.clone(),
        index_buffer,
        morph_buffer,
        ranges: [vertices.range.start, vertices.range.end, index_start, triangles],
        gpu: GpuOccluderInstance {
            grid_from_local: [[0.0; 4]; 4],
            vertex_start: vertices.range.start,
            vertex_count: mesh.vertex_count,
            vertex_stride: (stride / 4) as u32,
            position_offset: (position.offset / 4) as u32,
            index_start,
            index_format,
            triangle_count: triangles,
            first_triangle: 0,
            skin_index,
            joint_count,
            joint_offset,
            weight_offset,
            morph_weights_offset: morph[0],
            morph_weight_count: morph[1],
            morph_targets_offset: morph[2],
            morph_vertex_count: morph[3],
            normal_offset,
            solid: o.solid as u32,
            color_offset,
            albedo: o.albedo,
        },
    })
}

/// What a resolved dynamic occluder's voxels are made from this frame besides its mesh (see [`Pose`]).
fn pose(o: &ExtractedOccluder, r: &ResolvedInstance, skins: &Skins) -> Pose {
    let g = &r.gpu;
    let transforms = if g.skin_index == NO_SKIN {
        vec![Mat4::from(o.world_from_local)]
    } else {
        // The skin's joint matrices this frame (world space), as the classify pass reads them.
        let start = g.skin_index as usize;
        skins
            .uniforms
            .and_then(|u| u.current_staging_buffer.get(start..start + g.joint_count as usize))
            .map_or_else(Vec::new, <[Mat4]>::to_vec)
    };
    #[cfg(feature = "morph")]
    let weights = skins
        .morphs
        .filter(|_| g.morph_weight_count > 0)
        .and_then(|(_, u)| {
            let start = g.morph_weights_offset as usize;
            u.current_buffer.values().get(start..start + g.morph_weight_count as usize)
        })
        .map_or_else(Vec::new, <[f32]>::to_vec);
    #[cfg(not(feature = "morph"))]
    let weights = Vec::new();
    Pose { transforms, weights, mesh: (o.mesh, r.ranges), bounds: o.world_bounds }
}

/// Frames a dynamic occluder whose voxels changed stays listed as moved (`ResolvedOccluders::moved`), with
/// its last motion: where it stopped, the AO keeps the short history of its last move until every pixel
/// has traced its own rays again (every fourth frame at half resolution, every eighth in `Low`'s
/// checkerboard), rather than blend them slowly into the history from before it came.
pub(super) const MOVED_FRAMES: u32 = 8;

/// An occluder as extracted, and as resolved to the mesh slabs (`None`: waiting, or skipped).
struct TrackedInstance {
    occluder: ExtractedOccluder,
    resolved: Option<ResolvedInstance>,
    /// Its mesh cannot be voxelized (warned once per mesh).
    skipped: bool,
}

impl TrackedInstance {
    /// Whether it is in the static grid.
    fn is_static(&self) -> bool {
        !self.occluder.dynamic && self.resolved.is_some()
    }

    /// Whether it voxelizes into the static grid exactly as `other` does.
    fn same_static_voxels(&self, other: &TrackedInstance) -> bool {
        let (a, b) = (&self.occluder, &other.occluder);
        let same_resolution = match (&self.resolved, &other.resolved) {
            (Some(r), Some(s)) => r.slabs == s.slabs && r.ranges == s.ranges,
            (None, None) => true,
            _ => false,
        };
        same_resolution
            && a.mesh == b.mesh
            && a.pn == b.pn
            && a.solid == b.solid
            && a.albedo == b.albedo
            && a.world_bounds == b.world_bounds
            && a.world_from_local.to_cols_array().map(f32::to_bits)
                == b.world_from_local.to_cols_array().map(f32::to_bits)
    }
}

/// What this frame's changes mean for the static grid.
#[derive(Default)]
pub(super) struct StaticChanges {
    /// World boxes whose static voxels must be rebuilt.
    pub dirty: Vec<(Vec3, Vec3)>,
    /// A static occluder without bounds changed: everything must be rebuilt.
    pub everywhere: bool,
}

impl StaticChanges {
    fn touch(&mut self, bounds: Option<(Vec3, Vec3)>) {
        match bounds {
            Some(b) => self.dirty.push(b),
            None => self.everywhere = true,
        }
    }
}

/// The occluders resolved to mesh slabs, kept across frames (see the module's documentation).
#[derive(Default)]
pub(crate) struct ResolvedOccluders {
    instances: EntityHashMap<TrackedInstance>,
    /// Waiting for their mesh, its slabs, or their skin to be uploaded: tried again every frame.
    pending: EntityHashSet,
    /// Skinned or morphed: resolved every frame.
    per_frame: EntityHashSet,
    /// The dynamic ones that are resolved.
    dynamics: EntityHashSet,
    /// The occluders of each mesh.
    by_mesh: HashMap<AssetId<Mesh>, EntityHashSet>,
    /// Skipped (their mesh cannot be voxelized).
    skipped: EntityHashSet,
    /// Static occluders added and not yet voxelized: added to the static grid within the streaming budget,
    /// nearest the focus first.
    queued: EntityHashSet,
    /// Occluders filled solid (`VoxelFill::Solid`), resolved or not.
    solid: EntityHashSet,
    /// Occluders resolved in the last frame.
    pub resolved_last_frame: u64,
    /// The poses of the resolved dynamic occluders, as voxelized last.
    poses: EntityHashMap<Pose>,
    /// The occluders whose voxels changed in the last [`MOVED_FRAMES`] frames, with the frames they stay
    /// listed: dynamic ones that moved, static ones added to the static grid, changed or taken out of it.
    recent: EntityHashMap<(MovedOccluder, u32)>,
    warned_meshes: HashSet<(AssetId<Mesh>, WarnedFor)>,
    warned_moved: EntityHashSet,
}

impl ResolvedOccluders {
    /// Occluders known (resolved, waiting or skipped).
    pub fn len(&self) -> usize {
        self.instances.len()
    }

    /// Occluders skipped because their mesh cannot be voxelized.
    pub fn skipped(&self) -> usize {
        self.skipped.len()
    }

    /// The resolved static occluders in the static grid (not queued), less `except`.
    pub fn statics<'a>(
        &'a self,
        except: &'a EntityHashSet,
    ) -> impl Iterator<Item = (&'a ExtractedOccluder, &'a ResolvedInstance)> {
        self.instances
            .iter()
            .filter(|(e, t)| !t.occluder.dynamic && !self.queued.contains(*e) && !except.contains(*e))
            .filter_map(|(_, t)| Some((&t.occluder, t.resolved.as_ref()?)))
    }

    /// These occluders, where resolved.
    pub fn some<'a>(
        &'a self,
        entities: &'a EntityHashSet,
    ) -> impl Iterator<Item = (&'a ExtractedOccluder, &'a ResolvedInstance)> {
        entities.iter().filter_map(|e| {
            let t = self.instances.get(e)?;
            Some((&t.occluder, t.resolved.as_ref()?))
        })
    }

    /// Static occluders waiting to be added to the static grid.
    pub fn queued(&self) -> usize {
        self.queued.len()
    }

    /// Takes the queued static occluders nearest `focus` (by their bounds' centres; those without bounds
    /// first) until their triangles reach `budget` (at least one occluder).
    pub fn take_queued(&mut self, focus: Vec3, budget: u64) -> EntityHashSet {
        let mut queued: Vec<(f32, Entity, u64)> = self
            .queued
            .iter()
            .filter_map(|e| {
                let t = self.instances.get(e)?;
                let distance =
                    t.occluder.world_bounds.map_or(0.0, |(lo, hi)| ((lo + hi) * 0.5).distance_squared(focus));
                Some((distance, *e, t.resolved.as_ref().map_or(0, |r| r.gpu.triangle_count as u64)))
            })
            .collect();
        queued.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut taken = EntityHashSet::default();
        let mut triangles = 0u64;
        for (_, e, n) in queued {
            if !taken.is_empty() && triangles + n > budget {
                break;
            }
            triangles += n;
            taken.insert(e);
            self.queued.remove(&e);
            // Its voxels appear in the static grid now.
            let bounds = self.instances.get(&e).and_then(|t| t.occluder.world_bounds);
            self.recent.insert(e, (MovedOccluder { bounds, motion: f32::INFINITY }, MOVED_FRAMES));
        }
        taken
    }

    /// The resolved dynamic occluders.
    pub fn dynamics(&self) -> impl Iterator<Item = (&ExtractedOccluder, &ResolvedInstance)> {
        self.dynamics.iter().filter_map(|e| {
            let t = self.instances.get(e)?;
            Some((&t.occluder, t.resolved.as_ref()?))
        })
    }

    /// The occluders whose voxels changed in the last [`MOVED_FRAMES`] frames: dynamic ones that moved,
    /// turned, deformed, appeared or went; static ones added to the static grid, changed or taken out of it.
    pub fn moved(&self) -> Vec<MovedOccluder> {
        self.recent.values().map(|(m, _)| *m).collect()
    }

    /// Whether any occluder is filled solid.
    pub fn any_solid(&self) -> bool {
        !self.solid.is_empty()
    }

    /// Brings the resolution up to date with this frame's extraction and mesh uploads, and says which static
    /// voxels changed.
    pub fn update(
        &mut self,
        extracted: &ExtractedOccluders,
        mesh_changes: &ExtractedAssets<RenderMesh>,
        meshes: &RenderAssets<RenderMesh>,
        allocator: &MeshAllocator,
        skins: &Skins,
    ) -> StaticChanges {
        let mut changes = StaticChanges::default();
        // Meshes uploaded again: their occluders' voxels change.
        let mut remeshed: EntityHashSet = EntityHashSet::default();
        for id in mesh_changes.added.iter().chain(&mesh_changes.modified).chain(&mesh_changes.removed) {
            if let Some(entities) = self.by_mesh.get(id) {
                remeshed.extend(entities.iter().copied());
            }
        }
        // Uploads move other meshes too when a slab grows: look at each mesh's slabs (once per mesh, only on
        // frames with uploads).
        let mut work: EntityHashSet = remeshed.clone();
        if !(mesh_changes.added.is_empty() && mesh_changes.modified.is_empty() && mesh_changes.removed.is_empty()) {
            for (mesh, entities) in &self.by_mesh {
                let Some(r) = entities.iter().find_map(|e| self.instances.get(e)?.resolved.as_ref()) else { continue };
                let vertices = allocator.mesh_vertex_slice(mesh).map(|s| (s.buffer.id(), s.range.start));
                let indices = allocator.mesh_index_slice(mesh).map(|s| (s.buffer.id(), s.range.start));
                if vertices != Some((r.slabs.0, r.ranges[0])) || indices.map(|i| i.0) != r.slabs.1 {
                    work.extend(entities.iter().copied());
                }
            }
        }
        work.extend(extracted.changed.iter().copied());
        work.extend(self.pending.iter().copied());
        work.extend(self.per_frame.iter().copied());
        self.resolved_last_frame = 0;
        // The occluders listed as moved stay listed a few frames after they stop.
        self.recent.retain(|_, (_, frames)| {
            *frames -= 1;
            *frames > 0
        });
        for entity in work {
            let now = extracted.occluders.get(&entity).map(|o| {
                self.resolved_last_frame += 1;
                let (resolved, skipped) = match resolve_occluder(o, meshes, allocator, skins, &mut self.warned_meshes) {
                    Resolution::Ready(r) => (Some(r), false),
                    Resolution::Pending => (None, false),
                    Resolution::Skipped => (None, true),
                };
                TrackedInstance { occluder: o.clone(), resolved, skipped }
            });
            let static_change = self.replace(entity, now, remeshed.contains(&entity), &mut changes);
            // Only the entities looked at this frame can have moved: the others were not extracted.
            let now = self.instances.get(&entity).filter(|t| t.occluder.dynamic).and_then(|t| {
                let r = t.resolved.as_ref()?;
                Some(pose(&t.occluder, r, skins))
            });
            let prev = match &now {
                Some(p) => self.poses.insert(entity, p.clone()),
                None => self.poses.remove(&entity),
            };
            let dynamic_change = moved(prev.as_ref(), now.as_ref());
            if let Some(m) = MovedOccluder::either(static_change, dynamic_change) {
                self.recent.insert(entity, (m, MOVED_FRAMES));
            }
        }
        changes
    }

    /// Puts an occluder's new state in place of its old one, noting what that does to the static voxels;
    /// returns where they changed at once (a static occluder in the static grid changed or taken out of it;
    /// one new to it changes them when it is taken from the queue).
    fn replace(
        &mut self,
        entity: Entity,
        now: Option<TrackedInstance>,
        remeshed: bool,
        changes: &mut StaticChanges,
    ) -> Option<MovedOccluder> {
        let old = self.instances.remove(&entity);
        if let Some(old) = &old
            && let Some(set) = self.by_mesh.get_mut(&old.occluder.mesh)
        {
            set.remove(&entity);
            if set.is_empty() {
                self.by_mesh.remove(&old.occluder.mesh);
            }
        }
        self.pending.remove(&entity);
        self.per_frame.remove(&entity);
        self.dynamics.remove(&entity);
        self.skipped.remove(&entity);
        self.solid.remove(&entity);
        // In the static grid already (not waiting in the queue).
        let queued = self.queued.remove(&entity);
        let was_static = old.as_ref().is_some_and(|o| o.is_static()) && !queued;
        let is_static = now.as_ref().is_some_and(|n| n.is_static());
        let same = match (&old, &now) {
            (Some(o), Some(n)) => was_static && is_static && !remeshed && n.same_static_voxels(o),
            _ => false,
        };
        let mut changed = None;
        if !same {
            // Where it was is rebuilt; an occluder new to the static grid (or one still waiting) is queued and
            // added without a rebuild.
            if was_static {
                let before = old.as_ref().and_then(|o| o.occluder.world_bounds);
                changes.touch(before);
                changed = Some(MovedOccluder { bounds: before, motion: f32::INFINITY });
            }
            if is_static {
                if was_static {
                    let after = now.as_ref().and_then(|n| n.occluder.world_bounds);
                    changes.touch(after);
                    changed =
                        MovedOccluder::either(changed, Some(MovedOccluder { bounds: after, motion: f32::INFINITY }));
                } else {
                    self.queued.insert(entity);
                }
            }
        }
        let Some(now) = now else { return changed };
        let o = &now.occluder;
        if o.marked_static
            && old.as_ref().is_some_and(|p| p.occluder.world_from_local != o.world_from_local)
            && self.warned_moved.insert(entity)
        {
            warn!(
                "bevy_hao: StaticOccluder {entity} moved; the static voxels around it are rebuilt each time it does. Mark \
                 it DynamicOccluder if it moves often"
            );
        }
        match &now.resolved {
            None if now.skipped => {
                self.skipped.insert(entity);
            }
            None => {
                self.pending.insert(entity);
            }
            Some(_) if o.dynamic => {
                self.dynamics.insert(entity);
            }
            Some(_) => {}
        }
        if o.skin_joints.is_some() || o.morphed {
            self.per_frame.insert(entity);
        }
        if o.solid {
            self.solid.insert(entity);
        }
        self.by_mesh.entry(o.mesh).or_default().insert(entity);
        self.instances.insert(entity, now);
        changed
    }
}
