//! The lighting pass (`gi_lighting.wgsl`): each occupied voxel's outgoing diffuse radiance under the lights,
//! into the lighting volume, one slab of each level a frame; with a bounce feedback, plus its share of the
//! indirect light the near probes held at the end of last frame.

use super::extract::ExtractedGi;
use super::probes::{GpuProbeParams, PROBE_RECORD_BYTES};
use crate::cpu::lighting::PreparedLight;
use crate::gpu::queue_compute;
use crate::voxel::{VoxelGridBindings, voxel_grid_layout};
use bevy::asset::load_embedded_asset;
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_storage_3d, uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::storage::GpuShaderBuffer;
use bevy::render::texture::GpuImage;
use bytemuck::{Pod, Zeroable};

/// The workgroup edge of the lighting pass (4x4x4 voxels).
pub(crate) const LIGHTING_WORKGROUP: u32 = 4;

/// A light as the lighting pass takes it (WGSL `GiLight`; CPU twin [`PreparedLight`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuGiLight {
    pub(crate) position: [f32; 3],
    pub(crate) kind: u32,
    pub(crate) direction: [f32; 3],
    pub(crate) inverse_range_squared: f32,
    pub(crate) intensity: [f32; 3],
    pub(crate) spot_scale: f32,
    pub(crate) spot_offset: f32,
    pub(crate) _pad_a: f32,
    pub(crate) _pad_b: f32,
    pub(crate) _pad_c: f32,
}

impl From<&PreparedLight> for GpuGiLight {
    fn from(l: &PreparedLight) -> Self {
        Self {
            position: l.position.to_array(),
            kind: l.kind as u32,
            direction: l.direction.to_array(),
            inverse_range_squared: l.inverse_range_squared,
            intensity: l.intensity.to_array(),
            spot_scale: l.spot_scale,
            spot_offset: l.spot_offset,
            _pad_a: 0.0,
            _pad_b: 0.0,
            _pad_c: 0.0,
        }
    }
}

/// WGSL `GiLightingParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, ShaderType)]
pub(crate) struct GpuGiLightingParams {
    pub(crate) light_count: u32,
    pub(crate) phase: u32,
    pub(crate) phases: u32,
    pub(crate) blocks_z: u32,
    pub(crate) bounce_feedback: f32,
    pub(crate) _pad_a: u32,
    pub(crate) _pad_b: u32,
    pub(crate) _pad_c: u32,
}

/// The lighting pass's pipeline and layout.
#[derive(Resource)]
pub struct GiLightingPipeline {
    layout: BindGroupLayoutDescriptor,
    pub(crate) pipeline: CachedComputePipelineId,
    /// Bound as the probes' records where there are none yet (one record's bytes).
    no_records: Buffer,
}

impl FromWorld for GiLightingPipeline {
    fn from_world(world: &mut World) -> Self {
        let layout = BindGroupLayoutDescriptor::new(
            "hao_gi_lighting_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer::<GpuGiLightingParams>(false),
                    storage_buffer_read_only_sized(false, None),
                    texture_storage_3d(TextureFormat::R32Uint, StorageTextureAccess::WriteOnly),
                    uniform_buffer::<GpuProbeParams>(false),
                    storage_buffer_read_only_sized(false, None),
                ),
            ),
        );
        let shader = load_embedded_asset!(world, "gi_lighting.wgsl");
        let empty = BindGroupLayoutDescriptor::new("hao_gi_empty_layout", &[]);
        let pipeline = queue_compute(
            world.resource::<PipelineCache>(),
            "hao_gi_lighting",
            vec![layout.clone(), empty, voxel_grid_layout()],
            shader,
            "light_voxels",
            vec![],
        );
        let no_records = world.resource::<RenderDevice>().create_buffer(&BufferDescriptor {
            label: Some("hao_gi_lighting_no_records"),
            size: PROBE_RECORD_BYTES,
            usage: BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Self { layout, pipeline, no_records }
    }
}

/// This frame's lighting pass: its bind groups and workgroups.
#[derive(Resource)]
pub struct GiLightingFrame {
    pub(crate) bind_group: BindGroup,
    pub(crate) empty: BindGroup,
    pub(crate) workgroups: UVec3,
}

/// Workgroups of the lighting pass over `levels` levels of `dims` cells, one of `phases` slabs of each:
/// `(x, y, z)` with `z = levels * ceil(ceil(dims.z / 4) / phases)`, and the rows of 4 cells along z.
pub(crate) fn lighting_workgroups(dims: UVec3, levels: u32, phases: u32) -> (UVec3, u32) {
    let blocks = (dims + UVec3::splat(LIGHTING_WORKGROUP - 1)) / LIGHTING_WORKGROUP;
    (UVec3::new(blocks.x, blocks.y, levels * blocks.z.div_ceil(phases)), blocks.z)
}

/// Prepares the lighting pass: the lights, this frame's slab, the lighting volume as a storage texture, and
/// the near probes' window and records for the bounce feedback (none while they are not ready).
#[allow(clippy::too_many_arguments)]
pub fn prepare_gi_lighting(
    mut commands: Commands,
    device: Res<RenderDevice>,
    cache: Res<PipelineCache>,
    pipeline: Res<GiLightingPipeline>,
    extracted: Res<ExtractedGi>,
    voxel_grid: Option<Res<VoxelGridBindings>>,
    images: Res<RenderAssets<GpuImage>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    mut frame: Local<u32>,
) {
    commands.remove_resource::<GiLightingFrame>();
    let (Some((settings, assets)), Some(voxel_grid)) = (&extracted.gi, voxel_grid) else { return };
    let grid = &voxel_grid.grid;
    let Some(radiance) = images.get(&assets.radiance) else { return };
    if grid.level_count == 0 || grid.attributes == 0 {
        return;
    }
    let phases = settings.lighting_frames.max(1);
    let (workgroups, blocks_z) = lighting_workgroups(grid.levels[0].dims, grid.level_count, phases);
    // The near probes as last frame left them (the probe passes run after this one), where they are.
    let probes = extracted.window.zip(buffers.get(&assets.probe_records));
    let window = probes.map_or(GpuProbeParams::zeroed(), |(w, _)| GpuProbeParams {
        window_min: w.min,
        counts: w.counts,
        spacing: w.spacing,
        focus: w.focus,
        ..GpuProbeParams::zeroed()
    });
    let records = probes.map_or(&pipeline.no_records, |(_, r)| &r.buffer);
    let params = GpuGiLightingParams {
        light_count: extracted.lights.len() as u32,
        phase: *frame % phases,
        phases,
        blocks_z,
        bounce_feedback: if probes.is_some() { settings.bounce_feedback } else { 0.0 },
        ..GpuGiLightingParams::zeroed()
    };
    *frame = frame.wrapping_add(1);
    let params = crate::gpu::uniform_buffer(&device, "hao_gi_lighting_params", &params, BufferUsages::UNIFORM);
    let window = crate::gpu::uniform_buffer(&device, "hao_gi_lighting_probe_window", &window, BufferUsages::UNIFORM);
    // At least one light's worth: a storage binding is never empty.
    let mut lights: Vec<GpuGiLight> = extracted.lights.iter().map(GpuGiLight::from).collect();
    if lights.is_empty() {
        lights.push(GpuGiLight::zeroed());
    }
    let lights = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some("hao_gi_lights"),
        contents: bytemuck::cast_slice(&lights),
        usage: BufferUsages::STORAGE,
    });
    let bind_group = device.create_bind_group(
        "hao_gi_lighting_bind_group",
        &cache.get_bind_group_layout(&pipeline.layout),
        &BindGroupEntries::sequential((
            params.as_entire_binding(),
            lights.as_entire_binding(),
            &radiance.texture_view,
            window.as_entire_binding(),
            records.as_entire_binding(),
        )),
    );
    let empty = device.create_bind_group(
        "hao_gi_empty_bind_group",
        &cache.get_bind_group_layout(&BindGroupLayoutDescriptor::new("hao_gi_empty_layout", &[])),
        &[],
    );
    commands.insert_resource(GiLightingFrame { bind_group, empty, workgroups });
}
