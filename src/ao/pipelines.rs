//! The HAO pipelines.

use super::prepare::GpuHaoSettings;
use crate::gpu::queue_compute;
use crate::voxel::voxel_grid_layout;
use bevy::asset::load_embedded_asset;
use bevy::core_pipeline::prepass::PreviousViewData;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_2d_multisampled, texture_depth_2d,
    texture_depth_2d_multisampled, texture_storage_2d, uniform_buffer,
};
use bevy::render::render_resource::*;
use bevy::render::renderer::RenderAdapter;
use bevy::render::view::ViewUniform;
use bevy::shader::ShaderDefVal;

/// Bytes of a pixel of the temporal history: two `u32`, packed by `pack_history` in hao_common.wgsl (the view
/// depth and AO in one word, the packed normal and frames of weight in the other; CPU twin
/// `cpu::denoise::HistoryTexel::stored`), which the temporal pass writes at full resolution every frame. The
/// history is a storage buffer of the view's pixels row by row rather than a texture: the temporal pass
/// reads four of its texels a pixel, and a software rasterizer such as lavapipe loads from a buffer for less
/// than it fetches a texel.
pub(crate) const HISTORY_TEXEL_BYTES: u64 = 8;

/// Bytes of a pixel of the AO it showed last frame, with the frames of the history it was taken from (two
/// 16-bit unorms), which the temporal pass reads and writes in place (`stable_ao` in hao_common.wgsl), laid
/// out as the history.
pub(crate) const SHOWN_TEXEL_BYTES: u64 = 4;

/// Bytes of the window of a texel of the trace that bounds the history (lower and upper bound, two floats),
/// which the neighborhood pass writes and the temporal pass reads, in a buffer laid out as the trace's.
pub(crate) const WINDOW_TEXEL_BYTES: u64 = 8;

/// Bytes of a texel of the trace filtered by the neighborhood pass (a float), laid out as the trace's.
pub(crate) const FILTERED_TEXEL_BYTES: u64 = 4;

/// Bytes of a texel of the trace (ao, view depth, packed normal, packed as a texel of the history with no
/// frames: `pack_history` in hao_common.wgsl), in a storage buffer of its texels row by row, as the history.
pub(crate) const TRACE_TEXEL_BYTES: u64 = 8;

/// Which loops a view's trace runs after its march, and whether its trace and temporal pass look for the
/// occluders that moved, each in a pipeline of its own: on devices that run every branch and every loop
/// until all its lanes are done, such as lavapipe, a loop compiled in costs a march per ray (or a pass over
/// the moved occluders per pixel) whether taken or not.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceVariant {
    /// Through the backs of surfaces (`ignore_back_hits`, with multi-valued voxels): `BACK_HITS`.
    pub back_hits: bool,
    /// Past the voxel hits the view shows in free space (`depth_free_space`): `FREE_SPACE`.
    pub free_space: bool,
    /// Near the occluders that moved since last frame, more rays and less history (`MOVED_OCCLUDERS`, in the
    /// trace and the temporal pass): chosen on the frames the grid lists any.
    pub moved: bool,
}

impl TraceVariant {
    /// The loops `settings` ask for (`ignore_back_hits`, `depth_free_space`).
    pub fn requested(settings: &super::HybridAmbientOcclusion) -> Self {
        Self { back_hits: settings.ignore_back_hits, free_space: settings.uses_depth_free_space(), moved: false }
    }

    /// The trace these loops need on a grid that keeps the voxels' normals (`attributes`) or not: through
    /// the backs of surfaces only with them.
    pub fn on_grid(self, attributes: bool) -> Self {
        Self { back_hits: self.back_hits && attributes, ..self }
    }

    /// The same, with or without the moved occluders.
    pub fn with_moved(self, moved: bool) -> Self {
        Self { moved, ..self }
    }

    /// Its slot in [`PrepassReaders`]'s traces.
    fn index(self) -> usize {
        self.back_hits as usize + 2 * self.free_space as usize + 4 * self.moved as usize
    }

    /// The trace's shader defs.
    fn shader_defs(self) -> impl Iterator<Item = ShaderDefVal> {
        let defs = [(self.back_hits, "BACK_HITS"), (self.free_space, "FREE_SPACE"), (self.moved, "MOVED_OCCLUDERS")];
        defs.into_iter().filter(|(on, _)| *on).map(|(_, def)| def.into())
    }

    /// The trace's pipeline label.
    fn label(self, multisampled: bool) -> String {
        let mut label = String::from(if multisampled { "hao_trace_multisampled" } else { "hao_trace" });
        for (on, part) in [(self.back_hits, "_back_hits"), (self.free_space, "_free_space"), (self.moved, "_moved")] {
            if on {
                label.push_str(part);
            }
        }
        label
    }
}

/// The passes that read the depth and normal prepasses (trace, temporal), for one kind of prepass
/// texture: single-sampled, or multisampled on a camera with MSAA (they read sample 0).
pub struct PrepassReaders {
    /// Group 0 of trace.
    pub trace_layout: BindGroupLayoutDescriptor,
    /// Group 0 of the temporal pass, which writes into the texture PBR reads.
    pub temporal_layout: BindGroupLayoutDescriptor,
    /// Group 0 of the temporal pass with the near field, which writes the result texture apply copies.
    pub temporal_near_field_layout: BindGroupLayoutDescriptor,
    /// Rays through the voxels, stopping in the first run of occupied ones they go far enough through: each
    /// [`TraceVariant`] (by `TraceVariant::index`), the plain one queued at once, the others when a view
    /// first needs them (with their twin near moved occluders, which a view may need on any frame).
    pub traces: [Option<CachedComputePipelineId>; 8],
    /// Temporal accumulation and the filter, into the texture PBR reads: without and with the moved
    /// occluders ([`TraceVariant::moved`]).
    pub temporal: [CachedComputePipelineId; 2],
    /// The same and the near field, into the result texture.
    pub temporal_near_field: [CachedComputePipelineId; 2],
    multisampled: bool,
}

/// The HAO pipelines and layouts.
#[derive(Resource)]
pub struct HaoPipelines {
    /// Group 1 of trace: the view uniform.
    pub view_layout: BindGroupLayoutDescriptor,
    /// Group 1 of the temporal pass: the view and the previous view.
    pub temporal_view_layout: BindGroupLayoutDescriptor,
    /// Group 0 of the neighborhood pass.
    pub neighborhood_layout: BindGroupLayoutDescriptor,
    /// Group 0 of apply.
    pub apply_layout: BindGroupLayoutDescriptor,
    /// The passes reading single-sampled prepasses.
    pub single: PrepassReaders,
    /// The passes reading multisampled prepasses, queued when the first view with MSAA needs them.
    pub multisampled: Option<PrepassReaders>,
    /// The window and the filtered AO of each texel of the trace.
    pub neighborhood: CachedComputePipelineId,
    /// With the near field: the result texture into the texture PBR reads.
    pub apply: CachedComputePipelineId,
    /// The format of Bevy's SSAO texture, which PBR reads (and of the plugin's own in its place).
    pub ao_format: TextureFormat,
    shaders: [Handle<Shader>; 2],
}

impl HaoPipelines {
    /// The prepass readers for a view with `samples` MSAA samples, once queued (see
    /// [`queue_view`](Self::queue_view)).
    pub fn readers(&self, samples: u32) -> Option<&PrepassReaders> {
        if samples > 1 { self.multisampled.as_ref() } else { Some(&self.single) }
    }

    /// Queues what a view with `samples` MSAA samples needs, once: the multisampled prepass readers where
    /// `samples` > 1, and the traces of its `variant` without and with the moved occluders.
    pub fn queue_view(&mut self, cache: &PipelineCache, samples: u32, variant: TraceVariant) {
        if samples > 1 && self.multisampled.is_none() {
            self.multisampled = Some(prepass_readers(
                cache,
                &self.shaders,
                &self.view_layout,
                &self.temporal_view_layout,
                self.ao_format,
                true,
            ));
        }
        let Some(r) = (if samples > 1 { self.multisampled.as_mut() } else { Some(&mut self.single) }) else { return };
        for variant in [variant.with_moved(false), variant.with_moved(true)] {
            if r.traces[variant.index()].is_none() {
                let (layout, multisampled) = (&r.trace_layout, r.multisampled);
                r.traces[variant.index()] =
                    Some(queue_trace(cache, &self.shaders[0], layout, &self.view_layout, multisampled, variant));
            }
        }
    }

    /// Every pipeline a view with `samples` MSAA samples may run, in pass order (trace, neighborhood,
    /// temporal, and with the near field temporal_near_field and apply instead of temporal), once all are
    /// compiled. The trace is `variant`'s once that is compiled (until then, or if it failed to compile,
    /// which the pipeline cache logs, the same without the moved occluders, or else the plain trace: its
    /// rays stop at the first voxels they hit); the temporal passes are those with the moved occluders where
    /// `variant` has them and they are compiled.
    pub fn view_pipelines<'a>(
        &self,
        cache: &'a PipelineCache,
        samples: u32,
        variant: TraceVariant,
    ) -> Option<[&'a ComputePipeline; 5]> {
        let r = self.readers(samples)?;
        let get = |id: Option<CachedComputePipelineId>| id.and_then(|id| cache.get_compute_pipeline(id));
        let trace = [variant, variant.with_moved(false), TraceVariant::default()]
            .into_iter()
            .find_map(|v| get(r.traces[v.index()]))?;
        // The temporal passes of `variant`, or the ones without the moved occluders until those compile.
        let temporal = |ids: [CachedComputePipelineId; 2]| get(Some(ids[variant.moved as usize])).or(get(Some(ids[0])));
        Some([
            trace,
            get(Some(self.neighborhood))?,
            temporal(r.temporal)?,
            temporal(r.temporal_near_field)?,
            get(Some(self.apply))?,
        ])
    }
}

/// Queues the trace (group 0: `trace_layout`), for multisampled prepasses or not, with the loops of
/// `variant`.
fn queue_trace(
    cache: &PipelineCache,
    shader: &Handle<Shader>,
    trace_layout: &BindGroupLayoutDescriptor,
    view_layout: &BindGroupLayoutDescriptor,
    multisampled: bool,
    variant: TraceVariant,
) -> CachedComputePipelineId {
    let mut defs: Vec<ShaderDefVal> = Vec::new();
    if multisampled {
        defs.push("MULTISAMPLED".into());
    }
    defs.extend(variant.shader_defs());
    queue_compute(
        cache,
        variant.label(multisampled),
        vec![trace_layout.clone(), view_layout.clone(), voxel_grid_layout()],
        shader.clone(),
        "trace",
        defs,
    )
}

/// The layouts and pipelines of the passes that read the prepasses, `multisampled` or not; the temporal
/// pass writes `ao_format`, the format of the texture PBR reads.
fn prepass_readers(
    cache: &PipelineCache,
    [trace_shader, temporal_shader]: &[Handle<Shader>; 2],
    view_layout: &BindGroupLayoutDescriptor,
    temporal_view_layout: &BindGroupLayoutDescriptor,
    ao_format: TextureFormat,
    multisampled: bool,
) -> PrepassReaders {
    let unfilterable = TextureSampleType::Float { filterable: false };
    let (depth, normal) = if multisampled {
        (texture_depth_2d_multisampled(), texture_2d_multisampled(unfilterable))
    } else {
        (texture_depth_2d(), texture_2d(unfilterable))
    };
    let defs: Vec<ShaderDefVal> = if multisampled { vec!["MULTISAMPLED".into()] } else { vec![] };
    let label = |single: &'static str, multi: &'static str| if multisampled { multi } else { single };
    let trace_layout = BindGroupLayoutDescriptor::new(
        label("hao_trace_layout", "hao_trace_multisampled_layout"),
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (depth, normal, uniform_buffer::<GpuHaoSettings>(false), storage_buffer_sized(false, None)),
        ),
    );
    // The trace, its windows and filtered AO, the history read and written, the prepasses, the settings and
    // the AO shown last frame; then the texture PBR reads, or with the near field Bevy's SSAO and the result
    // texture.
    let common = BindGroupLayoutEntries::sequential(
        ShaderStages::COMPUTE,
        (
            storage_buffer_read_only_sized(false, None),
            storage_buffer_read_only_sized(false, None),
            storage_buffer_read_only_sized(false, None),
            storage_buffer_read_only_sized(false, None),
            depth,
            normal,
            uniform_buffer::<GpuHaoSettings>(false),
            storage_buffer_sized(false, None),
            storage_buffer_sized(false, None),
        ),
    );
    let with = |outputs: &[BindGroupLayoutEntryBuilder]| {
        let mut entries = common.to_vec();
        let first = entries.len() as u32;
        entries.extend((first..).zip(outputs).map(|(binding, o)| o.build(binding, ShaderStages::COMPUTE)));
        entries
    };
    let temporal_layout = BindGroupLayoutDescriptor::new(
        label("hao_temporal_layout", "hao_temporal_multisampled_layout"),
        &with(&[texture_storage_2d(ao_format, StorageTextureAccess::WriteOnly)]),
    );
    let temporal_near_field_layout = BindGroupLayoutDescriptor::new(
        label("hao_temporal_near_field_layout", "hao_temporal_multisampled_near_field_layout"),
        &with(&[
            texture_2d(unfilterable),
            texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
        ]),
    );
    // The temporal pass writing the texture PBR reads (in its format), or with the near field the result;
    // without and with the moved occluders.
    let queue_temporal = |name: &'static str, layout: &BindGroupLayoutDescriptor, def: Option<&str>| {
        [false, true].map(|moved| {
            let mut defs = defs.clone();
            defs.extend(def.map(Into::into));
            let mut name = name.to_string();
            if moved {
                defs.push("MOVED_OCCLUDERS".into());
                name.push_str("_moved");
            }
            let layouts = vec![layout.clone(), temporal_view_layout.clone(), voxel_grid_layout()];
            queue_compute(cache, name, layouts, temporal_shader.clone(), "temporal", defs)
        })
    };
    let temporal = queue_temporal(
        label("hao_temporal", "hao_temporal_multisampled"),
        &temporal_layout,
        (ao_format == TextureFormat::R16Float).then_some("USE_R16FLOAT"),
    );
    let temporal_near_field = queue_temporal(
        label("hao_temporal_near_field", "hao_temporal_multisampled_near_field"),
        &temporal_near_field_layout,
        Some("NEAR_FIELD"),
    );
    let trace = queue_trace(cache, trace_shader, &trace_layout, view_layout, multisampled, TraceVariant::default());
    let mut traces = [None; 8];
    traces[0] = Some(trace);
    PrepassReaders {
        trace_layout,
        temporal_layout,
        temporal_near_field_layout,
        traces,
        temporal,
        temporal_near_field,
        multisampled,
    }
}

impl FromWorld for HaoPipelines {
    fn from_world(world: &mut World) -> Self {
        let adapter = world.resource::<RenderAdapter>();
        // The same rule as bevy_pbr's SsaoPipelines.
        let ao_format = if adapter
            .get_texture_format_features(TextureFormat::R16Float)
            .allowed_usages
            .contains(TextureUsages::STORAGE_BINDING)
        {
            TextureFormat::R16Float
        } else {
            TextureFormat::R32Float
        };
        let unfilterable = TextureSampleType::Float { filterable: false };
        let view_layout = BindGroupLayoutDescriptor::new(
            "hao_view_layout",
            &BindGroupLayoutEntries::single(ShaderStages::COMPUTE, uniform_buffer::<ViewUniform>(true)),
        );
        let temporal_view_layout = BindGroupLayoutDescriptor::new(
            "hao_temporal_view_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (uniform_buffer::<ViewUniform>(true), uniform_buffer::<PreviousViewData>(true)),
            ),
        );
        let neighborhood_layout = BindGroupLayoutDescriptor::new(
            "hao_neighborhood_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    storage_buffer_read_only_sized(false, None),
                    uniform_buffer::<GpuHaoSettings>(false),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                ),
            ),
        );
        let apply_layout = BindGroupLayoutDescriptor::new(
            "hao_apply_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    texture_2d(unfilterable),
                    uniform_buffer::<GpuHaoSettings>(false),
                    texture_storage_2d(ao_format, StorageTextureAccess::WriteOnly),
                ),
            ),
        );
        let shaders = [load_embedded_asset!(world, "hao_trace.wgsl"), load_embedded_asset!(world, "hao_temporal.wgsl")];
        let neighborhood_shader = load_embedded_asset!(world, "hao_neighborhood.wgsl");
        let apply_shader = load_embedded_asset!(world, "hao_apply.wgsl");
        let cache = world.resource::<PipelineCache>();
        let single = prepass_readers(cache, &shaders, &view_layout, &temporal_view_layout, ao_format, false);
        let ao_format_defs: Vec<ShaderDefVal> =
            if ao_format == TextureFormat::R16Float { vec!["USE_R16FLOAT".into()] } else { vec![] };
        let neighborhood = queue_compute(
            cache,
            "hao_neighborhood",
            vec![neighborhood_layout.clone()],
            neighborhood_shader,
            "neighborhood",
            vec![],
        );
        let apply =
            queue_compute(cache, "hao_apply", vec![apply_layout.clone()], apply_shader, "apply", ao_format_defs);
        Self {
            view_layout,
            temporal_view_layout,
            neighborhood_layout,
            apply_layout,
            single,
            multisampled: None,
            neighborhood,
            apply,
            ao_format,
            shaders,
        }
    }
}
