//! Prepare: place this frame's levels (a single grid, or the cascades around the camera), resolve the
//! occluders to mesh slabs, decide what needs voxelizing (static geometry only in the regions that changed:
//! slabs a cascade scrolled into, boxes where a static occluder changed, whole levels when rebuilt; dynamic
//! geometry every frame in every level it overlaps), and build the buffers and bind groups of the passes.

use super::extract::{ExtractedOccluder, ExtractedOccluders, ExtractedVoxelGrid};
use super::pipelines::*;
use super::stats::{CascadeLevelStats, VoxelizationStats};
use super::stats::{STATIC_REGION_SLOTS, counter_base};
use super::volume::VoxelGridAssets;
use crate::cpu::{self, InjectionMode, SubdivisionPattern, VoxelGrid};
use bevy::math::{Affine3A, IVec3};
use bevy::mesh::VertexFormat;
use bevy::pbr::SkinUniforms;
#[cfg(feature = "morph")]
use bevy::pbr::{MorphIndices, MorphUniforms};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::mesh::{RenderMesh, RenderMeshBufferInfo};
use bevy::render::render_asset::{ExtractedAssets, RenderAssets};
use bevy::render::render_resource::encase::internal::WriteInto;
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::sync_world::MainEntity;
use bevy::render::texture::GpuImage;
use std::hash::{Hash, Hasher};

/// A box of lattice cells, `[min, max)`.
pub(crate) type CellBox = (IVec3, IVec3);

fn union(a: CellBox, b: CellBox) -> CellBox {
    (a.0.min(b.0), a.1.max(b.1))
}

fn intersect(a: CellBox, b: CellBox) -> Option<CellBox> {
    let r = (a.0.max(b.0), a.1.min(b.1));
    r.0.cmplt(r.1).all().then_some(r)
}

/// Workgroups of 4x4x4 covering a box.
fn groups4(b: CellBox) -> UVec3 {
    ((b.1 - b.0).max(IVec3::ZERO).as_uvec3() + UVec3::splat(3)) / 4
}

fn cells(b: CellBox) -> u64 {
    (b.1 - b.0).max(IVec3::ZERO).as_u64vec3().element_product()
}

/// One level of the volume as placed this frame: a single grid, or a cascade with its window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LevelLayout {
    /// World position of lattice cell 0.
    pub origin: Vec3,
    /// World-space cell size.
    pub cell_size: f32,
    /// Cells of the window.
    pub dims: UVec3,
    /// Texels of the level in the texture at mip 0.
    pub size: UVec3,
    /// The lattice cell at the window's min corner.
    pub window_min: IVec3,
    /// Stored toroidally (a cascade) rather than as a plain grid.
    pub toroidal: bool,
    /// The level's first voxel in the occupancy and count buffers.
    pub voxel_base: u32,
    /// The level's first texel along z in the texture.
    pub texture_z: u32,
}

impl LevelLayout {
    /// World space to the level's lattice.
    pub fn grid_from_world(&self) -> Affine3A {
        if self.toroidal {
            Affine3A::from_scale(Vec3::splat(1.0 / self.cell_size))
        } else {
            VoxelGrid { origin: self.origin, cell_size: self.cell_size, dims: self.dims }.grid_from_world()
        }
    }

    /// Where the window's min corner is stored.
    pub fn wrap(&self) -> UVec3 {
        if self.toroidal { self.window_min.rem_euclid(self.dims.as_ivec3()).as_uvec3() } else { UVec3::ZERO }
    }

    /// The window as a box of cells.
    pub fn window(&self) -> CellBox {
        (self.window_min, self.window_min + self.dims.as_ivec3())
    }

    /// The injection region of a box of the window (cpu: `InjectionRegion`).
    pub fn region(&self, b: CellBox) -> cpu::InjectionRegion {
        cpu::InjectionRegion {
            min: b.0,
            max: b.1,
            window_min: self.window_min,
            closed_max: if self.toroidal { IVec3::MAX } else { self.dims.as_ivec3() },
        }
    }

    /// The cells of the window a world-space box touches, padded by a cell.
    pub fn cells_of_box(&self, min: Vec3, max: Vec3) -> Option<CellBox> {
        let g = self.grid_from_world();
        let lo = g.transform_point3(min).floor() - Vec3::ONE;
        let hi = g.transform_point3(max).ceil() + Vec3::ONE;
        if !(lo.is_finite() && hi.is_finite()) {
            return Some(self.window());
        }
        let (w0, w1) = self.window();
        let lo = lo.clamp(w0.as_vec3(), w1.as_vec3()).as_ivec3();
        let hi = hi.clamp(w0.as_vec3(), w1.as_vec3()).as_ivec3();
        lo.cmplt(hi).all().then_some((lo, hi))
    }

    /// The world-space box of a box of cells.
    fn world_box(&self, b: CellBox) -> (Vec3, Vec3) {
        let inv = self.grid_from_world().inverse();
        (inv.transform_point3(b.0.as_vec3()), inv.transform_point3(b.1.as_vec3()))
    }
}

/// This frame's levels: a single grid, or the cascades placed around the focus. `None` while the cascades
/// have no focus (no camera with HAO) or it is unusable.
pub(crate) fn place_levels(assets: &VoxelGridAssets, focus: Option<Vec3>) -> Option<Vec<LevelLayout>> {
    let g = assets.grid;
    let level_voxels = g.voxel_count() as u32;
    match assets.cascades {
        None => Some(vec![LevelLayout {
            origin: g.origin,
            cell_size: g.cell_size,
            dims: g.dims,
            size: assets.texture_size,
            window_min: IVec3::ZERO,
            toroidal: false,
            voxel_base: 0,
            texture_z: 0,
        }]),
        Some(shape) => {
            let levels = shape.levels_at(focus?).ok()?;
            Some(
                levels
                    .iter()
                    .enumerate()
                    .map(|(l, c)| LevelLayout {
                        origin: Vec3::ZERO,
                        cell_size: c.cell_size,
                        dims: UVec3::splat(c.cells),
                        size: assets.texture_size,
                        window_min: c.window_min,
                        toroidal: true,
                        voxel_base: l as u32 * level_voxels,
                        texture_z: l as u32 * assets.texture_size.z,
                    })
                    .collect(),
            )
        }
    }
}

/// What prepare remembers of a static occluder.
#[derive(Clone, Copy, PartialEq)]
struct StaticEntry {
    fingerprint: u64,
    bounds: Option<(Vec3, Vec3)>,
}

/// State kept across frames.
#[derive(Resource, Default)]
pub struct VoxelizeState {
    generation: u64,
    /// The levels as voxelized last (empty: nothing is valid).
    levels: Vec<LevelLayout>,
    statics: HashMap<Entity, StaticEntry>,
    prev_dynamic: Vec<Option<CellBox>>,
    had_dynamic: bool,
    /// World boxes of the dynamic occluders this frame (`None`: one without bounds, anywhere).
    dynamic_world: Vec<Option<(Vec3, Vec3)>>,
    /// The same last frame.
    prev_dynamic_world: Vec<Option<(Vec3, Vec3)>>,
    warned_meshes: HashSet<(AssetId<Mesh>, WarnedFor)>,
    warned_moved: HashSet<Entity>,
    static_transforms: HashMap<Entity, Affine3A>,
    rebuild_requests: u64,
    big: Option<BigBuffers>,
    warned_capacity: bool,
    /// The solid pass's scratch (a level's cells, then one bit per column), as long as it is big enough.
    crossings: Option<Buffer>,
    warned_crossings: bool,
}

impl VoxelizeState {
    /// The levels as voxelized this frame (for the bindings consumers read).
    pub(crate) fn levels(&self) -> &[LevelLayout] {
        &self.levels
    }

    /// Where the voxels may have changed since last frame: the world boxes of the dynamic occluders now and
    /// last frame (`None` for one without bounds: anywhere). Temporal passes keep less history there.
    pub(crate) fn changed_world_boxes(&self) -> impl Iterator<Item = Option<(Vec3, Vec3)>> + '_ {
        self.dynamic_world.iter().chain(&self.prev_dynamic_world).copied()
    }
}

struct BigBuffers {
    capacity: u64,
    triangles: Buffer,
    offsets: Buffer,
    dispatch: Buffer,
}

/// One classify dispatch: the instances whose meshes live in one pair of vertex and index slabs.
pub struct SlabDispatch {
    pub bind_group: BindGroup,
    /// Workgroups (x, y).
    pub workgroups: (u32, u32),
}

/// A voxelization pass: one level, one region, static or dynamic geometry.
pub struct VoxelizePass {
    /// The classify dispatches.
    pub slabs: Vec<SlabDispatch>,
    pub bind_group: BindGroup,
    /// The solid fill, when an instance of the pass is [`crate::VoxelFill::Solid`].
    pub solid: Option<SolidPass>,
}

/// The solid fill of a pass (voxelize_solid.wgsl): its crossings over the pass's slabs, then its fill.
pub struct SolidPass {
    /// Group 1 of both.
    pub bind_group: BindGroup,
    /// The scratch buffer, cleared before the crossings.
    pub crossings: Buffer,
    /// Workgroups of the fill (8x8 columns each).
    pub columns: UVec2,
}

/// How a static region is cleared before it is voxelized again.
pub enum StaticClear {
    /// A whole level, by clearing its bytes.
    Level {
        /// (offset, size) in the occupancy buffer.
        occupancy: (u64, u64),
        /// (offset, size) in the point count buffer, if kept.
        counts: Option<(u64, u64)>,
    },
    /// A box of cells, by the clear pass (workgroups of 4x4x4).
    Region(UVec3),
}

/// A static region: cleared, then voxelized.
pub struct StaticPass {
    /// How it is cleared.
    pub clear: StaticClear,
    /// The voxelization (its bind group also serves the clear pass).
    pub pass: VoxelizePass,
}

/// One box of one level to resolve into the texture.
pub struct ResolveWork {
    /// Bits to mip 0.
    pub bind_group: BindGroup,
    /// Workgroups of 4x4x4.
    pub workgroups: UVec3,
    /// One per further mip level.
    pub mips: Vec<(BindGroup, UVec3)>,
}

/// Everything the voxelize system records this frame; absent on frames with nothing to do.
#[derive(Resource)]
pub struct VoxelizeFrame {
    /// Counter blocks to clear before the passes: (first word, words).
    pub clear_counters: Vec<(u32, u32)>,
    /// Static regions to voxelize again.
    pub static_passes: Vec<StaticPass>,
    /// Dynamic geometry, one pass per level it overlaps.
    pub dynamic_passes: Vec<VoxelizePass>,
    /// Group 0 of scan, expand and clear.
    pub empty_bind_group: BindGroup,
    /// Group 2 of scan.
    pub dispatch_bind_group: BindGroup,
    /// The expand pass's indirect arguments.
    pub dispatch_args: Buffer,
    pub counters: Buffer,
    /// Static occupancy.
    pub static_occupancy: Buffer,
    /// This frame's occupancy.
    pub occupancy: Buffer,
    /// Static and frame point counts, if kept.
    pub counts: Option<(Buffer, Buffer)>,
    /// Bits to texture.
    pub resolve: Vec<ResolveWork>,
}

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
struct ResolvedInstance {
    /// The vertex, index and morph-target slabs: instances sharing them share a classify dispatch.
    slabs: (BufferId, Option<BufferId>, Option<BufferId>),
    vertex_buffer: Buffer,
    index_buffer: Option<Buffer>,
    morph_buffer: Option<Buffer>,
    gpu: GpuOccluderInstance,
    ranges: [u32; 4],
}

#[allow(clippy::large_enum_variant, reason = "one per instance per frame, matched at once")]
enum Resolution {
    Ready(ResolvedInstance),
    /// Not uploaded yet: try again next frame.
    Pending,
    /// Cannot be voxelized (warned once per mesh).
    Skipped,
}

/// Where skinned and morphed meshes get their joint matrices and morph weights this frame.
struct Skins<'a> {
    /// Bevy's joint matrices (`None` if the device cannot bind them as storage).
    uniforms: Option<&'a SkinUniforms>,
    /// Whether the classify pipeline skins (see `VoxelizePipelines::skinning`).
    supported: bool,
    /// Bevy's morph descriptors per entity, where the pipeline applies morph targets.
    #[cfg(feature = "morph")]
    morphs: Option<(&'a MorphIndices, &'a MorphUniforms)>,
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

fn resolve_occluder(
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

fn resolve_list<'a>(
    list: &'a [ExtractedOccluder],
    meshes: &RenderAssets<RenderMesh>,
    allocator: &MeshAllocator,
    skins: &Skins,
    state: &mut VoxelizeState,
    skipped: &mut u64,
) -> Vec<(&'a ExtractedOccluder, ResolvedInstance)> {
    let mut ready = Vec::with_capacity(list.len());
    for o in list {
        match resolve_occluder(o, meshes, allocator, skins, &mut state.warned_meshes) {
            Resolution::Ready(r) => ready.push((o, r)),
            Resolution::Pending => {}
            Resolution::Skipped => *skipped += 1,
        }
    }
    ready
}

fn uniform<T: ShaderType + WriteInto>(device: &RenderDevice, label: &'static str, value: &T) -> Buffer {
    crate::gpu::uniform_buffer(device, label, value, BufferUsages::UNIFORM)
}

/// A buffer of per-dispatch settings, bound as a uniform or a read-only storage buffer as the pipelines
/// chose (see `VoxelizePipelines::params_in_storage`).
fn settings_buffer<T: ShaderType + WriteInto>(device: &RenderDevice, label: &'static str, value: &T) -> Buffer {
    crate::gpu::uniform_buffer(device, label, value, BufferUsages::STORAGE)
}

/// Workgroups (x, y) covering `count` invocations of `size`, with x at most 65535.
pub fn workgroups_2d(count: u64, size: u32) -> (u32, u32) {
    let groups = count.div_ceil(size as u64).max(1);
    let x = groups.min(65535) as u32;
    (x, groups.div_ceil(x as u64) as u32)
}

/// Sorts instances into slab groups and builds their classify dispatches. Returns the dispatches and the
/// triangle count.
fn build_slab_dispatches(
    device: &RenderDevice,
    pipelines: &VoxelizePipelines,
    cache: &PipelineCache,
    mut instances: Vec<ResolvedInstance>,
    joints: &Buffer,
    morph_weights: &Buffer,
    label: &'static str,
) -> (Vec<SlabDispatch>, u64) {
    instances.sort_by_key(|i| i.slabs);
    let mut gpu: Vec<GpuOccluderInstance> = Vec::with_capacity(instances.len());
    let mut groups: Vec<(usize, usize, u32)> = Vec::new();
    let mut total = 0u64;
    let mut start = 0;
    while start < instances.len() {
        let key = instances[start].slabs;
        let mut end = start;
        let mut first = 0u32;
        while end < instances.len() && instances[end].slabs == key {
            let mut g = instances[end].gpu;
            g.first_triangle = first;
            first = first.saturating_add(g.triangle_count);
            gpu.push(g);
            end += 1;
        }
        groups.push((start, end, first));
        total += first as u64;
        start = end;
    }
    if gpu.is_empty() {
        return (Vec::new(), 0);
    }
    let instance_buffer = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(&gpu),
        usage: BufferUsages::STORAGE,
    });
    let layout = cache.get_bind_group_layout(&pipelines.slab_layout);
    let dispatches = groups
        .into_iter()
        .filter(|(_, _, tris)| *tris > 0)
        .map(|(s, e, tris)| {
            let params = GpuSlabGroup {
                first_instance: s as u32,
                instance_count: (e - s) as u32,
                triangle_count: tris,
                _pad: 0,
            };
            let params = settings_buffer(device, "hao_voxelize_slab_group", &params);
            let first = &instances[s];
            let index = first.index_buffer.as_ref().unwrap_or(&pipelines.dummy);
            let entries = (
                instance_buffer.as_entire_binding(),
                first.vertex_buffer.as_entire_binding(),
                index.as_entire_binding(),
                params.as_entire_binding(),
            );
            let bind_group = if pipelines.morph {
                let (a, b, c, d) = entries;
                let targets = first.morph_buffer.as_ref().unwrap_or(&pipelines.dummy);
                let entries = BindGroupEntries::sequential((
                    a,
                    b,
                    c,
                    d,
                    joints.as_entire_binding(),
                    morph_weights.as_entire_binding(),
                    targets.as_entire_binding(),
                ));
                device.create_bind_group("hao_voxelize_slab_bind_group", &layout, &entries)
            } else if pipelines.skinning {
                let (a, b, c, d) = entries;
                let entries = BindGroupEntries::sequential((a, b, c, d, joints.as_entire_binding()));
                device.create_bind_group("hao_voxelize_slab_bind_group", &layout, &entries)
            } else {
                device.create_bind_group(
                    "hao_voxelize_slab_bind_group",
                    &layout,
                    &BindGroupEntries::sequential(entries),
                )
            };
            SlabDispatch { bind_group, workgroups: workgroups_2d(tris as u64, VOXELIZE_WORKGROUP) }
        })
        .collect();
    (dispatches, total)
}

/// The instances of `list` whose world bounds meet `world` (those without bounds always), with their
/// `grid_from_local` for a level.
fn instances_in(
    list: &[(&ExtractedOccluder, ResolvedInstance)],
    level: &LevelLayout,
    world: (Vec3, Vec3),
) -> Vec<ResolvedInstance> {
    let grid_from_world = level.grid_from_world();
    let col = |v: bevy::math::Vec3A| [v.x, v.y, v.z, 0.0];
    list.iter()
        .filter(|(o, _)| o.world_bounds.is_none_or(|(lo, hi)| lo.cmple(world.1).all() && hi.cmpge(world.0).all()))
        .map(|(o, r)| {
            // A skinned vertex is in world space once skinned.
            let m = if r.gpu.skin_index == NO_SKIN { grid_from_world * o.world_from_local } else { grid_from_world };
            let mut r = r.clone();
            r.gpu.grid_from_local =
                [col(m.matrix3.x_axis), col(m.matrix3.y_axis), col(m.matrix3.z_axis), col(m.translation)];
            r
        })
        .collect()
}

/// A hash of what voxelizing an occluder depends on.
fn fingerprint(o: &ExtractedOccluder, r: &ResolvedInstance) -> u64 {
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    o.mesh.hash(&mut hasher);
    o.pn.hash(&mut hasher);
    o.solid.hash(&mut hasher);
    o.albedo.hash(&mut hasher);
    r.ranges.hash(&mut hasher);
    r.slabs.hash(&mut hasher);
    for v in o.world_from_local.to_cols_array() {
        v.to_bits().hash(&mut hasher);
    }
    hasher.finish()
}

/// Builds this frame's [`VoxelizeFrame`], or removes it when there is nothing to do.
#[allow(clippy::too_many_arguments)]
pub fn prepare_voxelize(
    mut commands: Commands,
    device: Res<RenderDevice>,
    grid_assets: Res<ExtractedVoxelGrid>,
    occluders: Res<ExtractedOccluders>,
    meshes: Res<RenderAssets<RenderMesh>>,
    allocator: Res<MeshAllocator>,
    mesh_changes: Res<ExtractedAssets<RenderMesh>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    images: Res<RenderAssets<GpuImage>>,
    pipelines: Res<VoxelizePipelines>,
    cache: Res<PipelineCache>,
    mut state: ResMut<VoxelizeState>,
    stats: Res<VoxelizationStats>,
    skin_uniforms: Option<Res<SkinUniforms>>,
    #[cfg(feature = "morph")] morph_indices: Option<Res<MorphIndices>>,
    #[cfg(feature = "morph")] morph_uniforms: Option<Res<MorphUniforms>>,
) {
    commands.remove_resource::<VoxelizeFrame>();
    let invalidate = |state: &mut VoxelizeState| {
        state.levels.clear();
        state.statics.clear();
        state.prev_dynamic.clear();
        state.dynamic_world.clear();
        state.prev_dynamic_world.clear();
    };
    let Some(assets) = grid_assets.assets.as_ref() else {
        invalidate(&mut state);
        return;
    };
    let (Some(static_occupancy), Some(occupancy), Some(counters), Some(texture)) = (
        buffers.get(&assets.static_occupancy),
        buffers.get(&assets.occupancy),
        buffers.get(&assets.counters),
        images.get(&assets.texture),
    ) else {
        invalidate(&mut state);
        return;
    };
    let counts = match (&assets.static_point_counts, &assets.point_counts) {
        (Some(s), Some(f)) => match (buffers.get(s), buffers.get(f)) {
            (Some(s), Some(f)) => Some((s.buffer.clone(), f.buffer.clone())),
            _ => return invalidate(&mut state),
        },
        _ => None,
    };
    // The solid pipelines too once a solid occluder exists: a static level built without its fill would stay
    // hollow until it is rebuilt.
    let solid_wanted = occluders.statics.iter().chain(&occluders.dynamics).any(|o| o.solid);
    let solid_ids = [pipelines.solid_crossings, pipelines.solid_fill];
    if [pipelines.classify, pipelines.scan, pipelines.expand, pipelines.clear, pipelines.resolve, pipelines.mip]
        .iter()
        .chain(if solid_wanted { &solid_ids[..] } else { &[] })
        .any(|id| cache.get_compute_pipeline(*id).is_none())
    {
        return invalidate(&mut state);
    }
    let Some(levels) = place_levels(assets, grid_assets.focus) else {
        return invalidate(&mut state);
    };
    let settings = &assets.settings;
    let mut full_rebuild = state.generation != assets.generation || state.levels.len() != levels.len();
    if state.generation != assets.generation {
        state.generation = assets.generation;
        state.statics.clear();
    }

    // Resolve the occluders to slabs.
    let mut skipped = 0u64;
    // Bevy's joint matrices, if they can be bound as storage (they are a uniform buffer on devices without
    // storage buffers, where the voxelizer is off anyway).
    let skin_uniforms = skin_uniforms.as_deref().filter(|u| u.current_buffer.usage().contains(BufferUsages::STORAGE));
    // Bevy's morph weights and descriptors (storage buffers only; `None` where the pipeline does not morph).
    #[cfg(feature = "morph")]
    let morphs = match (morph_indices.as_deref(), morph_uniforms.as_deref()) {
        (Some(i), Some(u)) if pipelines.morph && u.descriptors_buffer.is_some() => Some((i, u)),
        _ => None,
    };
    #[cfg(feature = "morph")]
    let morph_weights = morphs.and_then(|(_, u)| u.current_buffer.buffer()).unwrap_or(&pipelines.dummy);
    #[cfg(not(feature = "morph"))]
    let morph_weights = &pipelines.dummy;
    let skins = Skins {
        uniforms: skin_uniforms,
        supported: pipelines.skinning,
        #[cfg(feature = "morph")]
        morphs,
    };
    let statics = resolve_list(&occluders.statics, &meshes, &allocator, &skins, &mut state, &mut skipped);
    let dynamics = resolve_list(&occluders.dynamics, &meshes, &allocator, &skins, &mut state, &mut skipped);
    // Bound to every classify dispatch where the pipeline skins (a placeholder when Bevy has none).
    let joints = skin_uniforms.map(|u| &u.current_buffer).unwrap_or(&pipelines.dummy);

    // What changed in the static set since last frame: world boxes to voxelize again.
    let mut dirty: Vec<(Vec3, Vec3)> = Vec::new();
    let mut dirty_everywhere = false;
    let mut entries = HashMap::with_capacity(statics.len());
    let mut transforms = HashMap::with_capacity(statics.len());
    for (o, r) in &statics {
        let entry = StaticEntry { fingerprint: fingerprint(o, r), bounds: o.world_bounds };
        let mesh_changed = mesh_changes.modified.contains(&o.mesh) || mesh_changes.added.contains(&o.mesh);
        let old = state.statics.get(&o.entity).copied();
        if old != Some(entry) || mesh_changed {
            for b in [old.and_then(|e| e.bounds), entry.bounds] {
                match b {
                    Some(b) => dirty.push(b),
                    None => dirty_everywhere |= old.is_some() || entry.bounds.is_none(),
                }
            }
        }
        if o.marked_static
            && state.static_transforms.get(&o.entity).is_some_and(|t| *t != o.world_from_local)
            && state.warned_moved.insert(o.entity)
        {
            warn!(
                "bevy_hao: StaticOccluder {} moved; the static voxels around it are rebuilt each time it does. Mark it \
                 DynamicOccluder if it moves often",
                o.entity
            );
        }
        transforms.insert(o.entity, o.world_from_local);
        entries.insert(o.entity, entry);
    }
    for (entity, old) in &state.statics {
        if !entries.contains_key(entity) {
            match old.bounds {
                Some(b) => dirty.push(b),
                None => dirty_everywhere = true,
            }
        }
    }
    state.statics = entries;
    state.static_transforms = transforms;
    if occluders.rebuild_requests != state.rebuild_requests {
        full_rebuild = true;
    }
    state.rebuild_requests = occluders.rebuild_requests;
    if dirty_everywhere {
        full_rebuild = true;
    }

    // Per level: the static regions to voxelize again.
    let mut level_regions: Vec<(Vec<CellBox>, bool, bool)> = Vec::with_capacity(levels.len()); // (boxes, whole, scrolled)
    for (l, level) in levels.iter().enumerate() {
        let old = state.levels.get(l).copied();
        let moved = old.and_then(|o| {
            (o.cell_size == level.cell_size && o.dims == level.dims)
                .then(|| cpu::entered_regions(o.window_min, level.window_min, level.dims.x))
                .flatten()
        });
        let Some(entered) = moved.filter(|_| !full_rebuild) else {
            level_regions.push((vec![level.window()], true, false));
            continue;
        };
        let scrolled = !entered.is_empty();
        let mut boxes = entered;
        let mut changed: Option<CellBox> = None;
        let mut changed_boxes = Vec::new();
        for (lo, hi) in &dirty {
            if let Some(b) = level.cells_of_box(*lo, *hi) {
                changed_boxes.push(b);
                changed = Some(changed.map_or(b, |c| union(c, b)));
            }
        }
        if boxes.len() + changed_boxes.len() <= STATIC_REGION_SLOTS as usize {
            boxes.extend(changed_boxes);
        } else if let Some(c) = changed {
            boxes.push(c);
        }
        if boxes.len() > STATIC_REGION_SLOTS as usize {
            level_regions.push((vec![level.window()], true, false));
        } else {
            level_regions.push((boxes, false, scrolled));
        }
    }

    state.prev_dynamic_world = std::mem::take(&mut state.dynamic_world);
    state.dynamic_world = dynamics.iter().map(|(o, _)| o.world_bounds).collect();
    // Per level: where dynamic geometry is now and where it was last frame.
    let mut dynamic_boxes: Vec<Option<CellBox>> = Vec::with_capacity(levels.len());
    for level in &levels {
        let mut b: Option<CellBox> = None;
        for (o, _) in &dynamics {
            let r = match o.world_bounds {
                Some((lo, hi)) => level.cells_of_box(lo, hi),
                None => Some(level.window()),
            };
            if let Some(r) = r {
                b = Some(b.map_or(r, |x| union(x, r)));
            }
        }
        dynamic_boxes.push(b);
    }

    let any_static = level_regions.iter().any(|(b, _, _)| !b.is_empty());
    let has_dynamic = dynamic_boxes.iter().any(|b| b.is_some());
    let prev_dynamic = std::mem::take(&mut state.prev_dynamic);
    state.levels = levels.clone();
    state.prev_dynamic = dynamic_boxes.clone();
    let had_dynamic = std::mem::replace(&mut state.had_dynamic, has_dynamic);
    let level_stats = |s: &mut Vec<CascadeLevelStats>, regions: &[(Vec<CellBox>, bool, bool)]| {
        for (l, level) in levels.iter().enumerate() {
            if let Some(ls) = s.get_mut(l) {
                ls.cell_size = level.cell_size;
                ls.window_min = level.window_min;
                let (boxes, whole, scrolled) = &regions[l];
                let n: u64 = boxes.iter().map(|b| cells(*b)).sum();
                ls.static_cells_last_frame = n;
                ls.static_cells_total += n;
                ls.rebuilds += *whole as u64;
                ls.scrolls += *scrolled as u64;
            }
        }
    };
    if !any_static && !has_dynamic && !had_dynamic {
        stats.update(|s| {
            s.dynamic_instances = 0;
            s.dynamic_triangles = 0;
            s.skipped_instances = skipped;
            level_stats(&mut s.cascades, &level_regions);
        });
        return;
    }

    // Static passes and their triangle counts.
    struct PendingPass {
        level: usize,
        region: CellBox,
        instances: Vec<ResolvedInstance>,
        counter_base: u32,
        clear: Option<StaticClear>,
    }
    let mut pending: Vec<PendingPass> = Vec::new();
    let mut clear_counters = Vec::new();
    let mut static_instances = 0u64;
    let mut static_triangles = 0u64;
    let level_voxels = assets.grid.voxel_count();
    for (l, (boxes, whole, _)) in level_regions.iter().enumerate() {
        if boxes.is_empty() {
            continue;
        }
        let level = &levels[l];
        clear_counters
            .push((counter_base(l as u32, 0), counter_base(l as u32, STATIC_REGION_SLOTS) - counter_base(l as u32, 0)));
        for (slot, b) in boxes.iter().enumerate() {
            let instances = instances_in(&statics, level, level.world_box(*b));
            static_instances += instances.len() as u64;
            static_triangles += instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>();
            let clear = if *whole {
                // Levels hold a multiple of 32 voxels when there are several (cascades).
                let words = level_voxels.div_ceil(32);
                let record = level_voxels * 4 * assets.sample_words as u64;
                Some(StaticClear::Level {
                    occupancy: (l as u64 * words * 4, words * 4),
                    counts: counts.as_ref().map(|_| (l as u64 * record, record)),
                })
            } else {
                Some(StaticClear::Region(groups4(*b)))
            };
            pending.push(PendingPass {
                level: l,
                region: *b,
                instances,
                counter_base: counter_base(l as u32, slot as u32),
                clear,
            });
        }
    }
    let mut dynamic_instances = 0u64;
    let mut dynamic_triangles = 0u64;
    for (l, b) in dynamic_boxes.iter().enumerate() {
        let base = counter_base(l as u32, STATIC_REGION_SLOTS);
        clear_counters.push((base, super::stats::COUNTER_BLOCK as u32));
        if b.is_none() {
            continue;
        }
        let level = &levels[l];
        let instances = instances_in(&dynamics, level, level.world_box(level.window()));
        dynamic_instances = dynamic_instances.max(instances.len() as u64);
        dynamic_triangles += instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>();
        pending.push(PendingPass { level: l, region: level.window(), instances, counter_base: base, clear: None });
    }

    // The queue of big triangles, shared by the passes (which run one after the other): room for every
    // triangle of the largest pass.
    let largest = pending.iter().map(|p| p.instances.iter().map(|r| r.gpu.triangle_count as u64).sum::<u64>()).max();
    let largest = largest.unwrap_or(0);
    let limit = (device.limits().max_storage_buffer_binding_size / BIG_TRIANGLE_BYTES).max(1);
    let need = largest.clamp(1, limit);
    if largest > limit && !state.warned_capacity {
        warn!(
            "bevy_hao: {largest} triangles exceed the big-triangle queue the device allows ({limit}); some large triangles \
             are not voxelized"
        );
        state.warned_capacity = true;
    }
    if state.big.as_ref().is_none_or(|b| b.capacity < need) {
        let capacity = (need + need / 2).min(limit);
        let storage = |label, bytes: u64, extra: BufferUsages| {
            device.create_buffer(&BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: BufferUsages::STORAGE | extra,
                mapped_at_creation: false,
            })
        };
        state.big = Some(BigBuffers {
            capacity,
            triangles: storage("hao_big_triangles", capacity * BIG_TRIANGLE_BYTES, BufferUsages::empty()),
            offsets: storage("hao_big_triangle_offsets", capacity * 4, BufferUsages::empty()),
            dispatch: storage("hao_expand_dispatch", 16, BufferUsages::INDIRECT),
        });
    }
    // The solid passes' scratch: a level's cells and a bit per column, in words (levels share their dims).
    if pending.iter().any(|p| p.instances.iter().any(|r| r.gpu.solid != 0)) {
        let most = levels.iter().map(|l| level_voxels + (l.dims.x * l.dims.y) as u64).max().unwrap_or(0);
        let bytes = most.div_ceil(32).max(1) * 4;
        if bytes > device.limits().max_storage_buffer_binding_size {
            if !state.warned_crossings {
                warn!(
                    "bevy_hao: filling solid occluders needs a {bytes}-byte scratch buffer, over the device's \
                     Limits::max_storage_buffer_binding_size; VoxelFill::Solid occluders are voxelized as surfaces"
                );
                state.warned_crossings = true;
            }
            state.crossings = None;
        } else if state.crossings.as_ref().is_none_or(|b| b.size() < bytes) {
            state.crossings = Some(device.create_buffer(&BufferDescriptor {
                label: Some("hao_voxelize_crossings"),
                size: bytes,
                usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
    }
    let crossings = state.crossings.clone();
    let big = state.big.as_ref().expect("allocated above");

    let pass_layout = cache.get_bind_group_layout(&pipelines.pass_layout);
    let mode = match settings.mode {
        InjectionMode::Centroid => 0,
        InjectionMode::Conservative => 1,
    };
    let mut static_passes = Vec::new();
    let mut dynamic_passes = Vec::new();
    for p in pending {
        let level = &levels[p.level];
        let is_static = p.clear.is_some();
        let label = if is_static { "hao_static_instances" } else { "hao_dynamic_instances" };
        let any_solid = p.instances.iter().any(|r| r.gpu.solid != 0);
        let (slabs, _) = build_slab_dispatches(&device, &pipelines, &cache, p.instances, joints, morph_weights, label);
        let region = level.region(p.region);
        let params = GpuVoxelizeParams {
            region_min: region.min,
            mode,
            region_max: region.max,
            gamma: settings.effective_gamma(),
            window_min: region.window_min,
            point_budget: assets.point_budget,
            closed_max: region.closed_max,
            sample_words: if counts.is_some() { assets.sample_words } else { 0 },
            wrap: level.wrap(),
            counter_base: p.counter_base,
            dims: level.dims,
            voxel_base: level.voxel_base,
            pattern: (settings.pattern == SubdivisionPattern::Strips) as u32,
            _pad_a: 0,
            _pad_b: 0,
            _pad_c: 0,
        };
        let params = settings_buffer(&device, "hao_voxelize_params", &params);
        let (occ, cnt) = if is_static {
            (&static_occupancy.buffer, counts.as_ref().map(|c| &c.0))
        } else {
            (&occupancy.buffer, counts.as_ref().map(|c| &c.1))
        };
        let bind_group = device.create_bind_group(
            "hao_voxelize_pass_bind_group",
            &pass_layout,
            &BindGroupEntries::sequential((
                params.as_entire_binding(),
                occ.as_entire_binding(),
                cnt.unwrap_or(&pipelines.dummy_counts).as_entire_binding(),
                big.triangles.as_entire_binding(),
                counters.buffer.as_entire_binding(),
                big.offsets.as_entire_binding(),
            )),
        );
        let solid = (any_solid && crossings.is_some()).then(|| {
            let crossings = crossings.clone().expect("allocated when a pass has solid instances");
            let bind_group = device.create_bind_group(
                "hao_voxelize_solid_bind_group",
                &cache.get_bind_group_layout(&pipelines.solid_layout),
                &BindGroupEntries::sequential((
                    params.as_entire_binding(),
                    crossings.as_entire_binding(),
                    occ.as_entire_binding(),
                )),
            );
            let size = (region.max - region.min).max(IVec3::ZERO).as_uvec3();
            let w = crate::gpu::SCREEN_WORKGROUP;
            SolidPass { bind_group, crossings, columns: UVec2::new(size.x.div_ceil(w), size.y.div_ceil(w)) }
        });
        let pass = VoxelizePass { slabs, bind_group, solid };
        match p.clear {
            Some(clear) => static_passes.push(StaticPass { clear, pass }),
            None => dynamic_passes.push(pass),
        }
    }

    // Resolve: per level, the boxes that changed (static regions, and dynamic geometry now and last frame)
    // into the texture's level 0, then the mips over their footprint.
    let level_view = |mip: u32| {
        texture.texture.create_view(&TextureViewDescriptor {
            label: Some("hao_voxel_texture_level"),
            dimension: Some(TextureViewDimension::D3),
            base_mip_level: mip,
            mip_level_count: Some(1),
            ..default()
        })
    };
    let views: Vec<TextureView> = (0..assets.mip_levels).map(level_view).collect();
    // The attribute textures, where kept and the records are bound.
    let attribute_views = match (&assets.attributes, &counts) {
        (Some([a, n]), Some(_)) => match (images.get(a), images.get(n)) {
            (Some(a), Some(n)) => Some([a.texture_view.clone(), n.texture_view.clone()]),
            _ => return invalidate(&mut state),
        },
        _ => None,
    };
    let [albedo_view, normal_view] = attribute_views.as_ref().unwrap_or(&pipelines.dummy_attributes);
    let records = counts.as_ref().map_or(&pipelines.dummy, |c| &c.1);
    let resolve_layout = cache.get_bind_group_layout(&pipelines.resolve_layout);
    let mip_layout = cache.get_bind_group_layout(&pipelines.mip_layout);
    let mut resolve = Vec::new();
    for (l, level) in levels.iter().enumerate() {
        let (boxes, whole, _) = &level_regions[l];
        let mut list: Vec<CellBox> = Vec::new();
        if *whole {
            // The padding past the grid too, so that it reads as empty.
            list.push((level.window_min, level.window_min + level.size.as_ivec3()));
        } else {
            list.extend(boxes.iter().copied());
            for b in [dynamic_boxes[l], prev_dynamic.get(l).copied().flatten()].into_iter().flatten() {
                if let Some(b) = intersect(b, level.window()) {
                    list.push(b);
                }
            }
            if list.len() > STATIC_REGION_SLOTS as usize + 2 {
                let u = list.iter().copied().reduce(union).expect("not empty");
                list = vec![u];
            }
        }
        for b in list {
            let params = |mip: u32, b: CellBox| GpuLevelRegion {
                region_min: b.0,
                texture_z: level.texture_z >> mip,
                region_max: b.1,
                voxel_base: level.voxel_base,
                window_min: level.window_min >> mip as i32,
                _pad0: 0,
                wrap: level.wrap() >> mip,
                sample_words: if counts.is_some() { assets.sample_words } else { 0 },
                dims: level.dims,
                _pad2: 0,
                size: level.size >> mip,
                _pad3: 0,
            };
            let p0 = uniform(&device, "hao_voxel_resolve_params", &params(0, b));
            let bind_group = device.create_bind_group(
                "hao_voxel_resolve_bind_group",
                &resolve_layout,
                &BindGroupEntries::sequential((
                    p0.as_entire_binding(),
                    occupancy.buffer.as_entire_binding(),
                    &views[0],
                    records.as_entire_binding(),
                    albedo_view,
                    normal_view,
                )),
            );
            let mut mips = Vec::new();
            for mip in 1..assets.mip_levels {
                let s = 1i32 << mip;
                let mb = (b.0.div_euclid(IVec3::splat(s)), (b.1 + IVec3::splat(s - 1)).div_euclid(IVec3::splat(s)));
                let pm = uniform(&device, "hao_voxel_mip_params", &params(mip, mb));
                let bind_group = device.create_bind_group(
                    "hao_voxel_mip_bind_group",
                    &mip_layout,
                    &BindGroupEntries::sequential((
                        pm.as_entire_binding(),
                        &views[mip as usize - 1],
                        &views[mip as usize],
                    )),
                );
                mips.push((bind_group, groups4(mb)));
            }
            resolve.push(ResolveWork { bind_group, workgroups: groups4(b), mips });
        }
    }
    let empty_bind_group = device.create_bind_group(
        "hao_voxelize_empty_bind_group",
        &cache.get_bind_group_layout(&pipelines.empty_layout),
        &[],
    );
    let dispatch_bind_group = device.create_bind_group(
        "hao_voxelize_dispatch_bind_group",
        &cache.get_bind_group_layout(&pipelines.dispatch_layout),
        &BindGroupEntries::single(BufferBinding { buffer: &big.dispatch, offset: 0, size: BufferSize::new(12) }),
    );

    stats.update(|s| {
        if any_static {
            s.static_rebuilds += 1;
            s.static_instances = static_instances;
            s.static_triangles = static_triangles;
        }
        s.frames_voxelized += 1;
        s.dynamic_instances = dynamic_instances;
        s.dynamic_triangles = dynamic_triangles;
        s.skipped_instances = skipped;
        level_stats(&mut s.cascades, &level_regions);
    });
    commands.insert_resource(VoxelizeFrame {
        clear_counters,
        static_passes,
        dynamic_passes,
        empty_bind_group,
        dispatch_bind_group,
        dispatch_args: big.dispatch.clone(),
        counters: counters.buffer.clone(),
        static_occupancy: static_occupancy.buffer.clone(),
        occupancy: occupancy.buffer.clone(),
        counts,
        resolve,
    });
}
