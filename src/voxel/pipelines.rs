//! The voxelization pipelines and the layouts of the data they read.

use super::volume::voxel_texture_format;
use bevy::asset::load_embedded_asset;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only, storage_buffer_read_only_sized, storage_buffer_sized, texture_3d, texture_storage_3d,
    uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderAdapter, RenderDevice};
use bevy::shader::ShaderDefVal;
use bytemuck::{Pod, Zeroable};

/// One occluding mesh instance as the classify pass reads it (WGSL `OccluderInstance`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GpuOccluderInstance {
    /// `grid_from_local` as four padded columns (x, y, z axes, translation).
    pub grid_from_local: [[f32; 4]; 4],
    /// First vertex of the mesh in its vertex slab, in vertices.
    pub vertex_start: u32,
    /// Vertices of the mesh (indices at or past this are invalid).
    pub vertex_count: u32,
    /// Vertex stride in `u32` words.
    pub vertex_stride: u32,
    /// Offset of the position attribute in a vertex, in words.
    pub position_offset: u32,
    /// First index of the mesh in its index slab, in indices.
    pub index_start: u32,
    /// 0: not indexed, 1: `u16` indices, 2: `u32` indices.
    pub index_format: u32,
    /// Triangles of the mesh.
    pub triangle_count: u32,
    /// Index of the instance's first triangle within its dispatch.
    pub first_triangle: u32,
    /// First joint of the instance's skin in Bevy's joint matrices ([`NO_SKIN`]: not skinned).
    pub skin_index: u32,
    /// Joints of the skin (a vertex naming another is invalid).
    pub joint_count: u32,
    /// Offset of the joint indices (`Uint16x4`) in a vertex, in words.
    pub joint_offset: u32,
    /// Offset of the joint weights (`Float32x4`) in a vertex, in words.
    pub weight_offset: u32,
    /// First of the instance's morph weights in Bevy's `MorphUniforms::current_buffer`.
    pub morph_weights_offset: u32,
    /// Morph targets of the mesh (0: not morphed).
    pub morph_weight_count: u32,
    /// First of the mesh's morph displacements in its morph-target slab (target-major).
    pub morph_targets_offset: u32,
    /// Vertices per morph target.
    pub morph_vertex_count: u32,
    /// Offset of the normals (`Float32x3`) in a vertex, in words, for a PN instance ([`NO_NORMALS`]: flat).
    pub normal_offset: u32,
    /// 1 to fill the instance's inside (`VoxelFill::Solid`; voxelize_solid.wgsl).
    pub solid: u32,
    /// Offset of the vertex colours (`Float32x4`) in a vertex, in words ([`NO_COLORS`]: none).
    pub color_offset: u32,
    /// The material's base colour, linear, packed ([`crate::cpu::attributes::pack_albedo`]).
    pub albedo: u32,
}

/// [`GpuOccluderInstance::skin_index`] of an instance that is not skinned (WGSL `NO_SKIN`).
pub const NO_SKIN: u32 = u32::MAX;
/// [`GpuOccluderInstance::normal_offset`] of a flat instance (WGSL `NO_NORMALS`).
pub const NO_NORMALS: u32 = u32::MAX;

/// [`GpuOccluderInstance::color_offset`] of an instance without vertex colours (WGSL `NO_COLORS`).
pub const NO_COLORS: u32 = u32::MAX;

/// The instances of one classify dispatch (WGSL `SlabGroup`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub struct GpuSlabGroup {
    /// First instance in the instance buffer.
    pub first_instance: u32,
    /// Instances in the dispatch.
    pub instance_count: u32,
    /// Triangles in the dispatch.
    pub triangle_count: u32,
    pub _pad: u32,
}

/// Per-pass settings (WGSL `VoxelizeParams`): the level, the region of it to inject into, and how its
/// cells are stored.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub(crate) struct GpuVoxelizeParams {
    pub region_min: IVec3,
    /// 0: centroid, 1: conservative.
    pub mode: u32,
    pub region_max: IVec3,
    /// The effective gamma.
    pub gamma: f32,
    pub window_min: IVec3,
    /// Most points per frame.
    pub point_budget: u32,
    pub closed_max: IVec3,
    /// Words of a voxel's record in the point-count buffer: 0 (none), 1 (counts) or
    /// [`crate::cpu::attributes::SAMPLE_WORDS`] (counts and attribute sums).
    pub sample_words: u32,
    pub wrap: UVec3,
    /// First counter of this pass's block.
    pub counter_base: u32,
    pub dims: UVec3,
    pub voxel_base: u32,
    /// 0: the uniform subdivision pattern, 1: strips.
    pub pattern: u32,
    pub _pad_a: u32,
    pub _pad_b: u32,
    pub _pad_c: u32,
}

/// A box (or a list of bricks) of one level to resolve into the texture, at one mip (WGSL `LevelRegion`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub(crate) struct GpuLevelRegion {
    pub region_min: IVec3,
    pub texture_z: u32,
    pub region_max: IVec3,
    pub voxel_base: u32,
    pub window_min: IVec3,
    /// 1 in a pass over a list of bricks (the region then clips), 0 in a pass over the region.
    pub brick_pass: u32,
    pub wrap: UVec3,
    /// Words of a voxel's record in the frame's point-count buffer (resolve: attributes where it is
    /// `SAMPLE_WORDS`).
    pub sample_words: u32,
    pub dims: UVec3,
    pub _pad2: u32,
    pub size: UVec3,
    pub _pad3: u32,
}

/// Size of WGSL `BigTriangle` in bytes.
pub const BIG_TRIANGLE_BYTES: u64 = 112;
/// Invocations per classify and expand workgroup.
pub const VOXELIZE_WORKGROUP: u32 = 64;

/// Storage buffers per shader stage the classify pass needs to read its settings from storage buffers rather
/// than uniforms (WGSL `VOXELIZE_PARAMS_IN_STORAGE`).
pub const PARAMS_IN_STORAGE_BUFFERS: u32 = 10;
/// Storage buffers per shader stage the classify pass needs to skin meshes (its settings in storage, and
/// Bevy's joint matrices); see [`VoxelizePipelines::skinning`].
pub const SKINNING_STORAGE_BUFFERS: u32 = 11;
/// Storage buffers per shader stage the classify pass needs to apply morph targets as well (Bevy's morph
/// weights and a morph-target slab); see [`VoxelizePipelines::morph`].
pub const MORPH_STORAGE_BUFFERS: u32 = 13;

/// The voxelization pipelines, layouts and the small buffers they share.
#[derive(Resource)]
pub struct VoxelizePipelines {
    /// Group 0 of classify: instances, vertex slab, index slab, slab group.
    pub slab_layout: BindGroupLayoutDescriptor,
    /// Group 1 of classify, scan and expand.
    pub pass_layout: BindGroupLayoutDescriptor,
    /// Group 0 of scan and expand, which read no slabs: empty.
    pub empty_layout: BindGroupLayoutDescriptor,
    /// Group 2 of scan: the expand pass's indirect arguments.
    pub dispatch_layout: BindGroupLayoutDescriptor,
    /// The resolve pass's group.
    pub resolve_layout: BindGroupLayoutDescriptor,
    /// The mip pass's group.
    pub mip_layout: BindGroupLayoutDescriptor,
    /// The solid pass's group 1: settings, the crossings scratch and the occupancy.
    pub solid_layout: BindGroupLayoutDescriptor,
    /// Pass 1.
    pub classify: CachedComputePipelineId,
    /// Pass 2.
    pub scan: CachedComputePipelineId,
    /// Pass 3.
    pub expand: CachedComputePipelineId,
    /// Clears a box of a level before it is voxelized again.
    pub clear: CachedComputePipelineId,
    /// Bits to texture.
    pub resolve: CachedComputePipelineId,
    /// Texture mips.
    pub mip: CachedComputePipelineId,
    /// The solid pass's crossings (one invocation per triangle).
    pub solid_crossings: CachedComputePipelineId,
    /// The solid pass's fill (one invocation per column).
    pub solid_fill: CachedComputePipelineId,
    /// Whether classify skins skinned meshes (WGSL `VOXELIZE_SKINNING`, group 0 binding 4: Bevy's joint
    /// matrices): wherever the device has [`SKINNING_STORAGE_BUFFERS`]. Elsewhere skinned meshes are skipped
    /// with a warning.
    pub skinning: bool,
    /// Whether classify applies morph targets (WGSL `VOXELIZE_MORPH`, group 0 bindings 5 and 6: Bevy's morph
    /// weights and a morph-target slab): with this crate's `morph` feature, wherever the device has
    /// [`MORPH_STORAGE_BUFFERS`]. Elsewhere morphed meshes are voxelized in their base shape, with a warning.
    pub morph: bool,
    /// A 64-byte storage buffer bound (read only) where a mesh has no index slab, and as the joint matrices
    /// (one matrix) where Bevy has none.
    pub dummy: Buffer,
    /// A 16-byte storage buffer bound (read-write) where point counts are off: not `dummy`, since one
    /// buffer may not be bound both ways in one dispatch.
    pub dummy_counts: Buffer,
    /// 1x1x1 albedo and normal textures the resolve pass binds where the volume keeps no attributes.
    pub dummy_attributes: [TextureView; 2],
}

/// Formats of the albedo and normal textures (multi-valued voxels).
pub const ATTRIBUTE_FORMATS: [TextureFormat; 2] = [TextureFormat::Rgba8Unorm, TextureFormat::Rgba8Snorm];

impl FromWorld for VoxelizePipelines {
    fn from_world(world: &mut World) -> Self {
        let texture_format = voxel_texture_format(world.resource::<RenderAdapter>());
        let device = world.resource::<RenderDevice>();
        let dummy = device.create_buffer(&BufferDescriptor {
            label: Some("hao_dummy_storage"),
            size: 64,
            usage: BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let dummy_counts = device.create_buffer(&BufferDescriptor {
            label: Some("hao_dummy_counts"),
            size: 16,
            usage: BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let dummy_attributes = ATTRIBUTE_FORMATS.map(|format| {
            device
                .create_texture(&TextureDescriptor {
                    label: Some("hao_dummy_voxel_attributes"),
                    size: Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: TextureDimension::D3,
                    format,
                    usage: TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                })
                .create_view(&TextureViewDescriptor::default())
        });
        // The per-dispatch settings (`SlabGroup`, `VoxelizeParams`) are read from storage buffers where the
        // device has the bindings to spare, else from uniform buffers. Mesa's lavapipe (seen with 22.3.6)
        // compiles a new variant of a compute shader for each new set of uniform values that steer its
        // control flow, and keeps every variant: with uniforms, a moving occluder cost it about 2 MB of
        // process memory per frame (and a shader compile per dispatch). Storage buffers are not inlined.
        let storage_buffers = world.resource::<RenderDevice>().limits().max_storage_buffers_per_shader_stage;
        let params_in_storage = storage_buffers >= PARAMS_IN_STORAGE_BUFFERS;
        let skinning = storage_buffers >= SKINNING_STORAGE_BUFFERS;
        let morph = cfg!(feature = "morph") && storage_buffers >= MORPH_STORAGE_BUFFERS;
        // The per-dispatch settings, bound with their size.
        fn params_binding<T: ShaderType>(params_in_storage: bool) -> BindGroupLayoutEntryBuilder {
            if params_in_storage { storage_buffer_read_only::<T>(false) } else { uniform_buffer::<T>(false) }
        }
        let slab_entries = (
            storage_buffer_read_only_sized(false, None),
            storage_buffer_read_only_sized(false, None),
            storage_buffer_read_only_sized(false, None),
            params_binding::<GpuSlabGroup>(params_in_storage),
        );
        let read_only = || storage_buffer_read_only_sized(false, None);
        let slab_layout = if morph {
            let (a, b, c, d) = slab_entries;
            BindGroupLayoutDescriptor::new(
                "hao_voxelize_slab_layout",
                &BindGroupLayoutEntries::sequential(
                    ShaderStages::COMPUTE,
                    (a, b, c, d, read_only(), read_only(), read_only()),
                ),
            )
        } else if skinning {
            let (a, b, c, d) = slab_entries;
            BindGroupLayoutDescriptor::new(
                "hao_voxelize_slab_layout",
                &BindGroupLayoutEntries::sequential(ShaderStages::COMPUTE, (a, b, c, d, read_only())),
            )
        } else {
            BindGroupLayoutDescriptor::new(
                "hao_voxelize_slab_layout",
                &BindGroupLayoutEntries::sequential(ShaderStages::COMPUTE, slab_entries),
            )
        };
        let pass_layout = BindGroupLayoutDescriptor::new(
            "hao_voxelize_pass_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    params_binding::<GpuVoxelizeParams>(params_in_storage),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                ),
            ),
        );
        let solid_layout = BindGroupLayoutDescriptor::new(
            "hao_voxelize_solid_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    params_binding::<GpuVoxelizeParams>(params_in_storage),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                ),
            ),
        );
        let dispatch_layout = BindGroupLayoutDescriptor::new(
            "hao_voxelize_dispatch_layout",
            &BindGroupLayoutEntries::single(ShaderStages::COMPUTE, storage_buffer_sized(false, None)),
        );
        let empty_layout = BindGroupLayoutDescriptor::new("hao_voxelize_empty_layout", &[]);
        let resolve_layout = BindGroupLayoutDescriptor::new(
            "hao_voxel_resolve_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer::<GpuLevelRegion>(false),
                    storage_buffer_read_only_sized(false, None),
                    texture_storage_3d(texture_format, StorageTextureAccess::WriteOnly),
                    storage_buffer_read_only_sized(false, None),
                    texture_storage_3d(ATTRIBUTE_FORMATS[0], StorageTextureAccess::WriteOnly),
                    texture_storage_3d(ATTRIBUTE_FORMATS[1], StorageTextureAccess::WriteOnly),
                    storage_buffer_read_only_sized(false, None),
                ),
            ),
        );
        let mip_layout = BindGroupLayoutDescriptor::new(
            "hao_voxel_mip_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer::<GpuLevelRegion>(false),
                    texture_3d(TextureSampleType::Float { filterable: false }),
                    texture_storage_3d(texture_format, StorageTextureAccess::WriteOnly),
                    storage_buffer_read_only_sized(false, None),
                ),
            ),
        );
        let pass_defs: Vec<ShaderDefVal> =
            if params_in_storage { vec!["VOXELIZE_PARAMS_IN_STORAGE".into()] } else { vec![] };
        let mut classify_defs = pass_defs.clone();
        if skinning {
            classify_defs.push("VOXELIZE_SKINNING".into());
        }
        if morph {
            classify_defs.push("VOXELIZE_MORPH".into());
        }
        let texture_defs: Vec<ShaderDefVal> =
            if texture_format == TextureFormat::R8Unorm { vec!["VOXEL_TEXTURE_R8".into()] } else { vec![] };
        let pipeline_cache = world.resource::<PipelineCache>();
        let queue = |label, layout, shader, entry, defs| {
            crate::gpu::queue_compute(pipeline_cache, label, layout, shader, entry, defs)
        };
        let classify = queue(
            "hao_voxelize_classify",
            vec![slab_layout.clone(), pass_layout.clone()],
            load_embedded_asset!(world, "voxelize_classify.wgsl"),
            "classify",
            classify_defs.clone(),
        );
        let scan = queue(
            "hao_voxelize_scan",
            vec![empty_layout.clone(), pass_layout.clone(), dispatch_layout.clone()],
            load_embedded_asset!(world, "voxelize_scan.wgsl"),
            "scan",
            pass_defs.clone(),
        );
        let expand = queue(
            "hao_voxelize_expand",
            vec![empty_layout.clone(), pass_layout.clone()],
            load_embedded_asset!(world, "voxelize_expand.wgsl"),
            "expand",
            pass_defs.clone(),
        );
        let solid_crossings = queue(
            "hao_voxelize_solid_crossings",
            vec![slab_layout.clone(), solid_layout.clone()],
            load_embedded_asset!(world, "voxelize_solid.wgsl"),
            "crossings_pass",
            classify_defs.clone(),
        );
        let solid_fill = queue(
            "hao_voxelize_solid_fill",
            vec![empty_layout.clone(), solid_layout.clone()],
            load_embedded_asset!(world, "voxelize_solid.wgsl"),
            "fill",
            pass_defs.clone(),
        );
        let clear = queue(
            "hao_voxel_clear",
            vec![empty_layout.clone(), pass_layout.clone()],
            load_embedded_asset!(world, "voxel_clear.wgsl"),
            "clear_region",
            pass_defs.clone(),
        );
        let resolve = queue(
            "hao_voxel_resolve",
            vec![resolve_layout.clone()],
            load_embedded_asset!(world, "voxel_resolve.wgsl"),
            "resolve_occupancy",
            texture_defs.clone(),
        );
        let mip = queue(
            "hao_voxel_mip",
            vec![mip_layout.clone()],
            load_embedded_asset!(world, "voxel_mip.wgsl"),
            "downsample_max",
            texture_defs,
        );
        Self {
            slab_layout,
            pass_layout,
            empty_layout,
            dispatch_layout,
            resolve_layout,
            mip_layout,
            solid_layout,
            classify,
            scan,
            expand,
            clear,
            resolve,
            mip,
            solid_crossings,
            solid_fill,
            skinning,
            morph,
            dummy,
            dummy_counts,
            dummy_attributes,
        }
    }
}
