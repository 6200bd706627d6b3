//! The probe passes (`gi_probes.wgsl`): the probes of this frame's share gather the lighting volume's light
//! into their histories (`update_probes`: [`GROUP_PROBES`] probes a workgroup, their rays shared by
//! [`crate::cpu::probes::PROBE_LANES`] lanes each), then every probe of the window is written into Bevy's
//! irradiance volume (`write_probes`).

use super::extract::ExtractedGi;
use crate::cpu::probes::ProbeWindow;
use crate::gpu::queue_compute;
use crate::voxel::{VoxelGridBindings, voxel_grid_layout};
use bevy::asset::load_embedded_asset;
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, texture_3d, texture_storage_3d, uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::texture::GpuImage;
use bytemuck::{Pod, Zeroable};

/// Bytes of a probe's record (WGSL `ProbeRecord`): six faces of four floats, its lattice point, the
/// updates it holds, the seed of the last, and where it gathered from (three floats).
pub const PROBE_RECORD_BYTES: u64 = 128;

/// `update_probes`' workgroups along x (the rest along y: WGSL `PROBE_GROUPS_X`).
pub(crate) const PROBE_GROUPS_X: u32 = 4096;
/// Probes in a workgroup of `update_probes` (WGSL `GROUP_PROBES`): 32 invocations, 4 probes of
/// [`crate::cpu::probes::PROBE_LANES`] lanes.
pub(crate) const GROUP_PROBES: u32 = 4;
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
    /// 1 for the near probes with a far window beside them (WGSL `write_probes` then fades them into it).
    pub(crate) far: u32,
}

/// The probe passes' pipelines and layout.
#[derive(Resource)]
pub struct GiProbePipelines {
    layout: BindGroupLayoutDescriptor,
    update: CachedComputePipelineId,
    write: CachedComputePipelineId,
    /// Bound as the far records where there are none (one record's bytes).
    no_far_records: Buffer,
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
                    uniform_buffer::<GpuProbeParams>(false),
                    storage_buffer_read_only_sized(false, None),
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
        let no_far_records = world.resource::<RenderDevice>().create_buffer(&BufferDescriptor {
            label: Some("hao_gi_no_far_records"),
            size: PROBE_RECORD_BYTES,
            usage: BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Self { layout, update, write, no_far_records }
    }
}

/// One window's probe passes this frame: their bind group and workgroups.
pub(crate) struct GiProbePasses {
    pub(crate) bind_group: BindGroup,
    pub(crate) update_groups: UVec3,
    pub(crate) write_groups: UVec3,
}

/// This frame's probe passes: the near probes', and the far probes' where they are on (dispatched first:
/// the near volume is written from the far probes' records).
#[derive(Resource)]
pub struct GiProbesFrame {
    pub(crate) near: GiProbePasses,
    pub(crate) far: Option<GiProbePasses>,
}

impl GiProbePipelines {
    /// The two pipelines, once compiled.
    pub(crate) fn get<'a>(&self, cache: &'a PipelineCache) -> Option<[&'a ComputePipeline; 2]> {
        Some([cache.get_compute_pipeline(self.update)?, cache.get_compute_pipeline(self.write)?])
    }
}

/// Prepares the probe passes: this frame's windows, share and seed, the history's cap, and the bindings.
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
    // The far probes, where on and ready: their window, volume and records.
    let far = assets
        .far
        .as_ref()
        .zip(extracted.far_window)
        .and_then(|(f, w)| Some((w, images.get(&f.irradiance)?, buffers.get(&f.probe_records)?)));
    let phases = settings.probe_frames.max(1);
    let params_of = |window: &ProbeWindow, far: bool| GpuProbeParams {
        window_min: window.min,
        rays: settings.rays,
        counts: window.counts,
        phase: *frame % phases,
        spacing: window.spacing,
        phases,
        max_frames: extracted.history_cap.unwrap_or(settings.accumulation_frames),
        seed: *frame,
        focus: window.focus,
        far: u32::from(far),
    };
    let uniform =
        |label, params: &GpuProbeParams| crate::gpu::uniform_buffer(&device, label, params, BufferUsages::UNIFORM);
    let near_params = uniform("hao_gi_probe_params", &params_of(&window, far.is_some()));
    let far_params = far.as_ref().map(|(w, ..)| uniform("hao_gi_far_probe_params", &params_of(w, false)));
    *frame = frame.wrapping_add(1);
    let layout = cache.get_bind_group_layout(&pipelines.layout);
    // A window's passes: its params, records and volume, and the far window's params and records (read by
    // the near probes' write, unused by the far probes' own passes).
    let passes = |label,
                  window: &ProbeWindow,
                  params: &Buffer,
                  records: &Buffer,
                  volume: &GpuImage,
                  far: Option<(&Buffer, &Buffer)>| {
        let (far_params, far_records) = far.unwrap_or((params, &pipelines.no_far_records));
        let bind_group = device.create_bind_group(
            label,
            &layout,
            &BindGroupEntries::sequential((
                params.as_entire_binding(),
                records.as_entire_binding(),
                &radiance.texture_view,
                &volume.texture_view,
                far_params.as_entire_binding(),
                far_records.as_entire_binding(),
            )),
        );
        let probes = window.counts.x * window.counts.y * window.counts.z;
        GiProbePasses {
            bind_group,
            update_groups: update_groups(probes.div_ceil(phases).div_ceil(GROUP_PROBES)),
            write_groups: (window.counts + UVec3::splat(WRITE_WORKGROUP - 1)) / WRITE_WORKGROUP,
        }
    };
    let far_passes = far.as_ref().zip(far_params.as_ref()).map(|((w, volume, records), params)| {
        passes("hao_gi_far_probes_bind_group", w, params, &records.buffer, volume, None)
    });
    let far_bindings = far.as_ref().zip(far_params.as_ref()).map(|((_, _, records), params)| (params, &records.buffer));
    let near = passes("hao_gi_probes_bind_group", &window, &near_params, &records.buffer, irradiance, far_bindings);
    commands.insert_resource(GiProbesFrame { near, far: far_passes });
}

/// `update_probes`' dispatch for `groups` workgroups: at most [`PROBE_GROUPS_X`] along x (a dispatch holds
/// at most 65,535 along each axis).
fn update_groups(groups: u32) -> UVec3 {
    UVec3::new(groups.clamp(1, PROBE_GROUPS_X), groups.div_ceil(PROBE_GROUPS_X).max(1), 1)
}
