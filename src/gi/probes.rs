//! The probe passes (`gi_probes.wgsl`): the probes of this frame's share gather the lighting volume's light
//! into their histories (`update_probes`), then every probe of the window is written into Bevy's irradiance
//! volume (`write_probes`).

use super::extract::ExtractedGi;
use crate::gpu::queue_compute;
use crate::voxel::{VoxelGridBindings, voxel_grid_layout};
use bevy::asset::load_embedded_asset;
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_sized, texture_3d, texture_storage_3d, uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::texture::GpuImage;
use bytemuck::{Pod, Zeroable};

/// Bytes of a probe's record (WGSL `ProbeRecord`): six faces of four floats, its lattice point, the
/// updates it holds, the seed of the last, padding.
pub const PROBE_RECORD_BYTES: u64 = 128;

/// The workgroup size of `update_probes` (one probe an invocation).
const UPDATE_WORKGROUP: u32 = 64;
/// The workgroup edge of `write_probes` (4x4x4 probes).
const WRITE_WORKGROUP: u32 = 4;

/// WGSL `ProbeParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub(crate) struct GpuProbeParams {
    pub(crate) window_min: IVec3,
    pub(crate) rays: u32,
    pub(crate) counts: UVec3,
    pub(crate) phase: u32,
    pub(crate) spacing: f32,
    pub(crate) phases: u32,
    pub(crate) max_frames: u32,
    pub(crate) seed: u32,
    pub(crate) focus: Vec3,
    pub(crate) pad: f32,
}

/// The probe passes' pipelines and layout.
#[derive(Resource)]
pub struct GiProbePipelines {
    layout: BindGroupLayoutDescriptor,
    update: CachedComputePipelineId,
    write: CachedComputePipelineId,
}

impl FromWorld for GiProbePipelines {
    fn from_world(world: &mut World) -> Self {
        let layout = BindGroupLayoutDescriptor::new(
            "hao_gi_probes_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer::<GpuProbeParams>(false),
                    storage_buffer_sized(false, None),
                    texture_3d(TextureSampleType::Uint),
                    texture_storage_3d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let shader: Handle<Shader> = load_embedded_asset!(world, "gi_probes.wgsl");
        let empty = BindGroupLayoutDescriptor::new("hao_gi_empty_layout", &[]);
        let layouts = vec![layout.clone(), empty, voxel_grid_layout()];
        let cache = world.resource::<PipelineCache>();
        let update =
            queue_compute(cache, "hao_gi_update_probes", layouts.clone(), shader.clone(), "update_probes", vec![]);
        let write = queue_compute(cache, "hao_gi_write_probes", layouts, shader, "write_probes", vec![]);
        Self { layout, update, write }
    }
}

/// This frame's probe passes: their bind group, workgroups and pipelines.
#[derive(Resource)]
pub struct GiProbesFrame {
    pub(crate) bind_group: BindGroup,
    pub(crate) update_groups: u32,
    pub(crate) write_groups: UVec3,
}

impl GiProbePipelines {
    /// The two pipelines, once compiled.
    pub(crate) fn get<'a>(&self, cache: &'a PipelineCache) -> Option<[&'a ComputePipeline; 2]> {
        Some([cache.get_compute_pipeline(self.update)?, cache.get_compute_pipeline(self.write)?])
    }
}

/// Prepares the probe passes: this frame's window, share and seed, the history's cap, and the bindings.
#[allow(clippy::too_many_arguments)]
pub fn prepare_gi_probes(
    mut commands: Commands,
    device: Res<RenderDevice>,
    cache: Res<PipelineCache>,
    pipelines: Res<GiProbePipelines>,
    extracted: Res<ExtractedGi>,
    voxel_grid: Option<Res<VoxelGridBindings>>,
    images: Res<RenderAssets<GpuImage>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    mut frame: Local<u32>,
) {
    commands.remove_resource::<GiProbesFrame>();
    let (Some((settings, assets)), Some(voxel_grid), Some(window)) = (&extracted.gi, voxel_grid, extracted.window)
    else {
        return;
    };
    if voxel_grid.grid.level_count == 0 || voxel_grid.grid.attributes == 0 {
        return;
    }
    let (Some(radiance), Some(irradiance), Some(records)) =
        (images.get(&assets.radiance), images.get(&assets.irradiance), buffers.get(&assets.probe_records))
    else {
        return;
    };
    let phases = settings.probe_frames.max(1);
    let params = GpuProbeParams {
        window_min: window.min,
        rays: settings.rays,
        counts: window.counts,
        phase: *frame % phases,
        spacing: window.spacing,
        phases,
        max_frames: extracted.history_cap.unwrap_or(settings.accumulation_frames),
        seed: *frame,
        focus: window.focus,
        pad: 0.0,
    };
    *frame = frame.wrapping_add(1);
    let params = crate::gpu::uniform_buffer(&device, "hao_gi_probe_params", &params, BufferUsages::UNIFORM);
    let bind_group = device.create_bind_group(
        "hao_gi_probes_bind_group",
        &cache.get_bind_group_layout(&pipelines.layout),
        &BindGroupEntries::sequential((
            params.as_entire_binding(),
            records.buffer.as_entire_binding(),
            &radiance.texture_view,
            &irradiance.texture_view,
        )),
    );
    let probes = window.counts.x * window.counts.y * window.counts.z;
    let update_groups = probes.div_ceil(phases).div_ceil(UPDATE_WORKGROUP);
    let write_groups = (window.counts + UVec3::splat(WRITE_WORKGROUP - 1)) / WRITE_WORKGROUP;
    commands.insert_resource(GiProbesFrame { bind_group, update_groups, write_groups });
}
