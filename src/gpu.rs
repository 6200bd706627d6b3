//! What every pass of bevy_hao does the same way: queue a compute pipeline, and upload a uniform in the
//! layout WGSL gives its struct.

use bevy::prelude::*;
use bevy::render::render_resource::encase::{UniformBuffer, internal::WriteInto};
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, Buffer, BufferInitDescriptor, BufferUsages, CachedComputePipelineId,
    ComputePipelineDescriptor, PipelineCache, ShaderType,
};
use bevy::render::renderer::RenderDevice;
use bevy::shader::ShaderDefVal;

/// Workgroup edge of the 2D compute passes (8x8 invocations), `#{SCREEN_WORKGROUP}` in their WGSL.
pub(crate) const SCREEN_WORKGROUP: u32 = 8;

/// The integer constants the WGSL shares with Rust, as shader defs: every compute pipeline gets them, and
/// the WGSL reads `#{NAME}`, so that each has one value, here. (Floats, and the constants of
/// `voxel_grid.wgsl`, which other crates' shaders import without our defs, stay WGSL `const`s checked by
/// `wgsl_tests::shared_constants_agree`.)
pub(crate) fn shader_defs() -> Vec<ShaderDefVal> {
    use crate::cpu::tessellation;
    use crate::voxel::{pipelines, stats};
    let u = |name: &str, value: u32| ShaderDefVal::UInt(name.into(), value);
    vec![
        u("MAX_SUBDIVISION", tessellation::MAX_SUBDIVISION),
        u("MAX_SUB_TRIANGLES_PER_TRIANGLE", tessellation::MAX_SUB_TRIANGLES_PER_TRIANGLE as u32),
        u("INLINE_SUB_TRIANGLES", tessellation::INLINE_SUB_TRIANGLES as u32),
        u("STRIPS_MAX_COARSE", tessellation::STRIPS_MAX_COARSE),
        u("COUNTER_COUNT", stats::COUNTER_BLOCK as u32),
        u("FRAME_POINTS_USED", stats::FRAME_POINTS_USED),
        u("NO_SKIN", pipelines::NO_SKIN),
        u("NO_NORMALS", pipelines::NO_NORMALS),
        u("NO_COLORS", pipelines::NO_COLORS),
        u("SAMPLE_WORDS", crate::cpu::attributes::SAMPLE_WORDS),
        u("MIRRORED_BIT", crate::cpu::attributes::MIRRORED_BIT),
        u("TWO_SIDED_BIT", crate::cpu::attributes::TWO_SIDED_BIT),
        u("VOXELIZE_WORKGROUP", pipelines::VOXELIZE_WORKGROUP),
        u("SCREEN_WORKGROUP", SCREEN_WORKGROUP),
    ]
}

/// Queues one compute pipeline: every pass has a label, its layouts, one shader, one entry point and its
/// shader defs (to which [`shader_defs`] are added).
pub(crate) fn queue_compute(
    cache: &PipelineCache,
    label: impl Into<std::borrow::Cow<'static, str>>,
    layout: Vec<BindGroupLayoutDescriptor>,
    shader: Handle<Shader>,
    entry: &'static str,
    mut shader_defs: Vec<ShaderDefVal>,
) -> CachedComputePipelineId {
    shader_defs.extend(self::shader_defs());
    cache.queue_compute_pipeline(ComputePipelineDescriptor {
        label: Some(label.into()),
        layout,
        shader,
        shader_defs,
        entry_point: Some(entry.into()),
        ..default()
    })
}

/// `value` as its WGSL struct lays it out in a uniform buffer (encase's layout, which `ShaderType` derives).
pub(crate) fn uniform_bytes<T: ShaderType + WriteInto>(value: &T) -> Vec<u8> {
    let mut buffer = UniformBuffer::new(Vec::<u8>::new());
    buffer.write(value).expect("a uniform struct is written into a growable buffer");
    buffer.into_inner()
}

/// A buffer holding `value` (see [`uniform_bytes`]) for a uniform binding, and for a read-only storage
/// binding too when `usage` has `STORAGE` (a struct of scalars and `vec3`s lays out the same in both).
pub(crate) fn uniform_buffer<T: ShaderType + WriteInto>(
    device: &RenderDevice,
    label: &'static str,
    value: &T,
    usage: BufferUsages,
) -> Buffer {
    device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some(label),
        contents: &uniform_bytes(value),
        usage: usage | BufferUsages::UNIFORM,
    })
}
