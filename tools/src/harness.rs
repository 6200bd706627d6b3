//! Headless Bevy apps for the examples and the GPU tests: an app on Vulkan (Mesa's lavapipe on a machine
//! without a GPU) with no window, run frame by frame, with buffers read back and GPU timings collected.
//! Shared by the tools (`src/bin`), the plugin's examples and its GPU tests.

use bevy::app::PluginGroupBuilder;
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::error_handler::{RenderErrorHandler, RenderErrorPolicy};
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::settings::{Backends, RenderCreation, RenderResources, WgpuFeatures, WgpuSettings};
use bevy::render::storage::ShaderBuffer;
use bevy::window::ExitCondition;
use bevy_hao::cpu::{TriangleMesh, VoxelGrid, VoxelOccupancy};
use bevy_hao::{VoxelGridAssets, VoxelizationStats, VoxelizationStatsData};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

static GPU: Mutex<()> = Mutex::new(());
static RENDER_ERRORS: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// One GPU test at a time: lavapipe runs on the CPU, and Bevy apps are heavy.
pub fn gpu_lock() -> MutexGuard<'static, ()> {
    GPU.lock().unwrap_or_else(|e| e.into_inner())
}

/// The render resources (one Vulkan instance, adapter and device) that every app of this process shares once
/// the first has made them, but for apps on a device of constrained limits (`app_on_device`), which get
/// their own. A driver may find no adapter after a few devices in one process (NVIDIA's 580.159.04 on an H100:
/// none after 15 Bevy apps, with or without this plugin), and a test run makes far more.
static SHARED_RENDER: Mutex<Option<RenderResources>> = Mutex::new(None);

/// Whether this process found a Vulkan adapter (looked for once).
static HAS_VULKAN: OnceLock<bool> = OnceLock::new();

fn vulkan_adapters() -> Vec<wgpu::Adapter> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    bevy::tasks::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN))
}

/// Fails (does not skip) when there is no Vulkan adapter.
pub fn require_vulkan() {
    assert!(
        *HAS_VULKAN.get_or_init(|| !vulkan_adapters().is_empty()),
        "no Vulkan adapter found: the GPU tests need one. Install Mesa's lavapipe (a Vulkan device on the CPU): \
         `apt-get install mesa-vulkan-drivers`"
    );
}

/// Whether the Vulkan adapter can render `samples` MSAA samples into the formats a camera with Bevy's depth
/// and normal prepasses uses (WebGPU guarantees 1 and 4): the shared apps' adapter, once there is one.
pub fn msaa_supported(samples: u32) -> bool {
    use wgpu::TextureFormat;
    let shared = SHARED_RENDER.lock().unwrap_or_else(|e| e.into_inner()).as_ref().map(|r| r.3.clone());
    let supported = |adapter: &wgpu::Adapter| {
        [TextureFormat::Rgba8UnormSrgb, TextureFormat::Depth32Float, TextureFormat::Rgb10a2Unorm]
            .iter()
            .all(|f| adapter.get_texture_format_features(*f).flags.sample_count_supported(samples))
    };
    match shared {
        Some(adapter) => supported(&adapter),
        None => vulkan_adapters().first().is_some_and(supported),
    }
}

/// wgpu errors reported to Bevy's render error handler since the last call.
pub fn take_render_errors() -> Vec<String> {
    std::mem::take(&mut *RENDER_ERRORS.lock().unwrap_or_else(|e| e.into_inner()))
}

/// The labels of the render pipelines that failed to compile, with their errors. Bevy logs a shader error and
/// goes on without the pipeline, and wgpu reports nothing: a tool must not print figures of passes that
/// never ran.
pub fn failed_pipelines(app: &App) -> Vec<String> {
    use bevy::render::render_resource::{CachedPipelineState, PipelineCache, PipelineDescriptor};
    let Some(cache) = app.get_sub_app(bevy::render::RenderApp).and_then(|r| r.world().get_resource::<PipelineCache>())
    else {
        return Vec::new();
    };
    cache
        .pipelines()
        .filter_map(|p| match &p.state {
            CachedPipelineState::Err(e) => {
                let label = match &p.descriptor {
                    PipelineDescriptor::RenderPipelineDescriptor(d) => d.label.clone(),
                    PipelineDescriptor::ComputePipelineDescriptor(d) => d.label.clone(),
                };
                Some(format!("{}: {e}", label.as_deref().unwrap_or("unlabelled")))
            }
            _ => None,
        })
        .collect()
}

static LOGGING: std::sync::Once = std::sync::Once::new();

/// Where the app's `AssetServer` reads from (the folder of a model given by path), if not `assets/`.
static ASSET_ROOT: Mutex<Option<String>> = Mutex::new(None);

static LIMITS: Mutex<Option<bevy::render::settings::WgpuLimits>> = Mutex::new(None);

fn set_device_limits(limits: Option<bevy::render::settings::WgpuLimits>) {
    *LIMITS.lock().unwrap_or_else(|e| e.into_inner()) = limits;
}

/// The app `make` makes, on a device of its own no more capable than `limits`, to test how the plugin copes
/// with a weaker device (the apps made after it, even where `make` panics, get the adapter's own limits).
pub fn app_on_device(limits: bevy::render::settings::WgpuLimits, make: impl FnOnce() -> App) -> App {
    struct Reset;
    impl Drop for Reset {
        fn drop(&mut self) {
            set_device_limits(None);
        }
    }
    set_device_limits(Some(limits));
    let _reset = Reset;
    make()
}

/// WebGPU's default limits, but with the 8 storage buffers and 8 storage textures a shader stage that
/// Bevy's SSAO and the voxelizer need: the weakest device the plugin runs on whole.
pub fn webgpu_limits_with_storage() -> bevy::render::settings::WgpuLimits {
    bevy::render::settings::WgpuLimits {
        max_storage_buffers_per_shader_stage: 8,
        max_storage_textures_per_shader_stage: 8,
        ..default()
    }
}

/// Makes the next apps' `AssetServer` read from `dir` (for a model's textures and glTF scenes).
pub fn set_asset_root(dir: Option<String>) {
    *ASSET_ROOT.lock().unwrap() = dir;
}

fn plugins() -> PluginGroupBuilder {
    let mut plugins = DefaultPlugins.build();
    if let Some(root) = ASSET_ROOT.lock().unwrap().clone() {
        plugins =
            plugins.set(AssetPlugin { file_path: root, meta_check: bevy::asset::AssetMetaCheck::Never, ..default() });
    }
    // Logging can be set up once per process: the first app gets it, later ones do not.
    let mut first = false;
    LOGGING.call_once(|| first = true);
    if !first {
        plugins = plugins.disable::<bevy::log::LogPlugin>();
    }
    let constrained_limits = LIMITS.lock().unwrap_or_else(|e| e.into_inner()).clone();
    // A device whose limits allow no binding arrays has no binding-array features either: Bevy's bindless
    // materials look at the features (and would make layouts such a device refuses, on a GPU that has them).
    let disabled_features = constrained_limits
        .as_ref()
        .filter(|l| l.max_binding_array_elements_per_shader_stage == 0)
        .map(|_| WgpuFeatures::TEXTURE_BINDING_ARRAY | WgpuFeatures::BUFFER_BINDING_ARRAY);
    let shared = SHARED_RENDER.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let render_creation = match (constrained_limits, shared) {
        (None, Some(resources)) => RenderCreation::Manual(resources),
        (constrained_limits, _) => RenderCreation::Automatic(Box::new(WgpuSettings {
            backends: Some(Backends::VULKAN),
            constrained_limits,
            disabled_features,
            ..default()
        })),
    };
    plugins
        .disable::<bevy::winit::WinitPlugin>()
        .disable::<bevy::render::pipelined_rendering::PipelinedRenderingPlugin>()
        .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
        .set(RenderPlugin { render_creation, synchronous_pipeline_compilation: true, ..default() })
}

/// A headless app with the HAO plugin (and Bevy's render diagnostics, for GPU time spans), ready to
/// `update()`.
pub fn headless_app(setup: impl FnOnce(&mut App)) -> App {
    headless_app_with(true, setup)
}

/// A headless app as [`headless_app`], with the HAO plugin or without it (Bevy alone, for side-by-side
/// measurements).
pub fn headless_app_with(hao: bool, setup: impl FnOnce(&mut App)) -> App {
    require_vulkan();
    let mut app = App::new();
    app.add_plugins((plugins(), bevy::render::diagnostic::RenderDiagnosticsPlugin));
    if hao {
        app.add_plugins(bevy_hao::HaoPlugin);
    }
    app.insert_resource(RenderErrorHandler(|error, _, _| {
        RENDER_ERRORS.lock().unwrap_or_else(|e| e.into_inner()).push(format!("{:?}: {}", error.ty, error.description));
        RenderErrorPolicy::StopRendering
    }));
    setup(&mut app);
    app.finish();
    app.cleanup();
    share_render_resources(&app);
    app
}

/// Keeps `app`'s render resources for the next apps of this process, if it is the first on a device of the
/// adapter's own limits.
fn share_render_resources(app: &App) {
    if LIMITS.lock().unwrap_or_else(|e| e.into_inner()).is_some() {
        return;
    }
    use bevy::render::renderer::{RenderAdapter, RenderAdapterInfo, RenderDevice, RenderInstance, RenderQueue};
    let mut shared = SHARED_RENDER.lock().unwrap_or_else(|e| e.into_inner());
    if shared.is_some() {
        return;
    }
    let Some(world) = app.get_sub_app(bevy::render::RenderApp).map(|r| r.world()) else { return };
    *shared = (|| {
        Some(RenderResources(
            world.get_resource::<RenderDevice>()?.clone(),
            world.get_resource::<RenderQueue>()?.clone(),
            world.get_resource::<RenderAdapterInfo>()?.clone(),
            world.get_resource::<RenderAdapter>()?.clone(),
            world.get_resource::<RenderInstance>()?.clone(),
        ))
    })();
}

/// Runs `n` frames.
pub fn run(app: &mut App, n: usize) {
    for _ in 0..n {
        app.update();
    }
}

/// Waits until the device has run all the work submitted so far. A frame followed by this wait takes, in
/// wall-clock time, its CPU work plus every GPU pass it submitted: the cost of a pass is the difference
/// between frames with it and without, whatever the device's timestamps say (lavapipe's are taken when its
/// rasterizer runs, so they can miss compute passes between render passes).
pub fn wait_for_gpu(app: &App) {
    let device = app
        .get_sub_app(bevy::render::RenderApp)
        .and_then(|r| r.world().get_resource::<bevy::render::renderer::RenderDevice>());
    if let Some(device) = device {
        let _ = device.poll(bevy::render::render_resource::PollType::Wait { submission_index: None, timeout: None });
    }
}

/// The plugin's statistics.
pub fn stats(app: &App) -> VoxelizationStatsData {
    app.world().resource::<VoxelizationStats>().get()
}

/// The current grid assets.
pub fn grid_assets(app: &App) -> Option<VoxelGridAssets> {
    app.world().get_resource::<VoxelGridAssets>().cloned()
}

/// Reads something back: spawns `readback`, runs frames until data from at least `settle` frames after the
/// call arrives, despawns it.
fn read_back(app: &mut App, readback: Readback, settle: usize) -> Vec<u8> {
    let slot: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
    let writer = slot.clone();
    let entity = app
        .world_mut()
        .spawn(readback)
        .observe(move |ev: On<ReadbackComplete>| {
            // The first to arrive: two frames' data can arrive at once, and the earlier is the one asked for.
            writer.lock().unwrap().get_or_insert_with(|| ev.data.clone());
        })
        .id();
    run(app, settle);
    *slot.lock().unwrap() = None;
    let mut data = None;
    for _ in 0..20 {
        app.update();
        if let Some(d) = slot.lock().unwrap().take() {
            data = Some(d);
            break;
        }
        // The copy arrives once the device has run it, and nothing holds a headless app's frames back to the
        // device's pace: on an H100, `ao_compare` at 1920x1080 (`High`, `Low`) got no copy within twenty
        // frames until it waited here.
        wait_for_gpu(app);
    }
    app.world_mut().despawn(entity);
    data.expect("no readback arrived within 20 frames")
}

/// Reads a buffer back (see `read_back`).
pub fn read_buffer(app: &mut App, buffer: Handle<ShaderBuffer>, settle: usize) -> Vec<u8> {
    read_back(app, Readback::buffer(buffer), settle)
}

/// The frame's occupancy grid as the GPU has it.
pub fn read_occupancy(app: &mut App) -> VoxelOccupancy {
    let assets = grid_assets(app).expect("no voxel grid");
    let bytes = read_buffer(app, assets.occupancy.clone(), 3);
    let words: Vec<u32> = bytemuck::cast_slice(&bytes).to_vec();
    VoxelOccupancy::from_words(assets.grid, &words, None).expect("occupancy buffer too short")
}

/// The frame's occupancy with its per-voxel records (point counts, and with `VoxelVolume::attributes` the
/// albedo and normal sums) as the GPU has them.
pub fn read_records(app: &mut App) -> VoxelOccupancy {
    let assets = grid_assets(app).expect("no voxel grid");
    let bytes = read_buffer(app, assets.occupancy.clone(), 3);
    let words: Vec<u32> = bytemuck::cast_slice(&bytes).to_vec();
    let records = read_buffer(app, assets.point_counts.clone().expect("no point counts"), 3);
    VoxelOccupancy::from_records(assets.grid, &words, bytemuck::cast_slice(&records), assets.sample_words)
        .expect("record buffer too short")
}

/// The static grid's occupancy as the GPU has it.
pub fn read_static_occupancy(app: &mut App) -> VoxelOccupancy {
    let assets = grid_assets(app).expect("no voxel grid");
    let bytes = read_buffer(app, assets.static_occupancy.clone(), 3);
    let words: Vec<u32> = bytemuck::cast_slice(&bytes).to_vec();
    VoxelOccupancy::from_words(assets.grid, &words, None).expect("occupancy buffer too short")
}

/// One cascade level as the GPU has it: its window, and its occupancy (the frame's, or the static grid's)
/// unwrapped from the level's toroidal storage into window order (cell `(0, 0, 0)` = the window's min).
pub struct CascadeReadback {
    /// The level's window and counters.
    pub level: bevy_hao::CascadeLevelStats,
    /// The window as a grid (origin at its min corner).
    pub grid: VoxelGrid,
    /// Its occupancy in window order.
    pub occupancy: VoxelOccupancy,
}

/// Every cascade level of the frame's occupancy (`static_only`: of the static grid), unwrapped.
pub fn read_cascades(app: &mut App, static_only: bool) -> Vec<CascadeReadback> {
    let assets = grid_assets(app).expect("no voxel grid");
    let buffer = if static_only { assets.static_occupancy.clone() } else { assets.occupancy.clone() };
    let bytes = read_buffer(app, buffer, 3);
    let words: Vec<u32> = bytemuck::cast_slice(&bytes).to_vec();
    let d = assets.grid.dims;
    let level_voxels = assets.grid.voxel_count() as u32;
    stats(app)
        .cascades
        .iter()
        .enumerate()
        .map(|(l, level)| {
            let grid = VoxelGrid::new(level.origin + level.window_min.as_vec3() * level.cell_size, level.cell_size, d)
                .unwrap();
            let occupancy = VoxelOccupancy::new(grid, false);
            let wrap = level.window_min.rem_euclid(d.as_ivec3()).as_uvec3();
            for z in 0..d.z {
                for y in 0..d.y {
                    for x in 0..d.x {
                        let p = (UVec3::new(x, y, z) + wrap) % d;
                        let i = l as u32 * level_voxels + p.x + d.x * (p.y + d.y * p.z);
                        if words[(i >> 5) as usize] >> (i & 31) & 1 == 1 {
                            occupancy.set(UVec3::new(x, y, z));
                        }
                    }
                }
            }
            CascadeReadback { level: *level, grid, occupancy }
        })
        .collect()
}

/// The frame's voxels as the trace reads them, one entry per level (one for a single grid): the level's
/// origin, cell size and window, and its occupancy pyramid. Borrow them as
/// [`bevy_hao::cpu::march::TraceLevel`]s with [`trace_levels`].
pub fn read_trace_voxels(app: &mut App) -> Vec<(Vec3, f32, IVec3, bevy_hao::cpu::march::VoxelMips)> {
    let assets = grid_assets(app).expect("no voxel grid");
    if assets.cascades.is_none() {
        let occupancy = read_occupancy(app);
        let mips = bevy_hao::cpu::march::VoxelMips::new(&occupancy, assets.mip_levels);
        return vec![(assets.grid.origin, assets.grid.cell_size, IVec3::ZERO, mips)];
    }
    read_cascades(app, false)
        .into_iter()
        .map(|c| {
            let mips = bevy_hao::cpu::march::VoxelMips::new(&c.occupancy, assets.mip_levels);
            (c.level.origin, c.level.cell_size, c.level.window_min, mips)
        })
        .collect()
}

/// The levels of [`read_trace_voxels`] as the CPU twin of the trace takes them.
pub fn trace_levels(
    voxels: &[(Vec3, f32, IVec3, bevy_hao::cpu::march::VoxelMips)],
) -> Vec<bevy_hao::cpu::march::TraceLevel<'_>> {
    voxels
        .iter()
        .map(|(origin, cell_size, window_min, mips)| bevy_hao::cpu::march::TraceLevel {
            origin: *origin,
            cell_size: *cell_size,
            window_min: *window_min,
            mips,
        })
        .collect()
}

/// The settings the CPU twin of the trace takes for `settings`, with the rays and steps it traces a frame.
pub fn cpu_trace_settings(settings: &bevy_hao::HybridAmbientOcclusion) -> bevy_hao::cpu::ao::TraceSettings {
    let (rays, steps, _) = settings.trace_parameters();
    bevy_hao::cpu::ao::TraceSettings {
        rays,
        steps,
        max_distance: settings.max_distance,
        falloff: settings.falloff,
        intensity: settings.intensity,
        start_offset: settings.start_offset,
        ignore_back_hits: settings.ignore_back_hits,
        depth_contacts: settings.depth_contacts,
        depth_free_space: settings.uses_depth_free_space(),
        contact_samples: settings.contact_samples(),
    }
}

/// The surface each pixel of `camera` shows (world position and normal; `None` for the background), from
/// the depth and normal its [`bevy_hao::HaoDebugImages`] copied: the trace's inputs. Returns the width, the
/// height and the samples in rows.
pub fn view_samples(
    app: &mut App,
    camera: Entity,
    debug: &bevy_hao::HaoDebugImages,
) -> (u32, u32, Vec<Option<(Vec3, Vec3)>>) {
    let (w, h, depth) = read_image_f32(app, debug.depth.clone(), 0);
    let (_, _, _, normal_bytes) = read_image(app, debug.normal.clone(), 0);
    let world = app.world();
    let (cam, transform) =
        (world.get::<Camera>(camera).expect("a camera"), world.get::<GlobalTransform>(camera).expect("a transform"));
    let world_from_clip = transform.to_matrix() * cam.clip_from_view().inverse();
    let mut samples = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if depth[i] <= 0.0 {
                samples.push(None);
                continue;
            }
            let ndc =
                Vec3::new((x as f32 + 0.5) / w as f32 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / h as f32 * 2.0, depth[i]);
            let n = &normal_bytes[i * 8..i * 8 + 6];
            let normal = Vec3::new(f16_at(n, 0), f16_at(n, 2), f16_at(n, 4)).normalize();
            samples.push(Some((world_from_clip.project_point3(ndc), normal)));
        }
    }
    (w, h, samples)
}

/// The depth and normal prepasses of `camera` as the trace reads them (from the depth and normal its
/// [`bevy_hao::HaoDebugImages`] copied, and the camera's matrices, without TAA jitter), for the CPU twin's
/// depth contacts.
pub fn view_depth(
    app: &mut App,
    camera: Entity,
    debug: &bevy_hao::HaoDebugImages,
) -> bevy_hao::cpu::contacts::ViewDepth {
    let (w, h, depth) = read_image_f32(app, debug.depth.clone(), 0);
    let (_, _, _, normal_bytes) = read_image(app, debug.normal.clone(), 0);
    let normals = normal_bytes
        .chunks_exact(8)
        .map(|n| Vec3::new(f16_at(n, 0), f16_at(n, 2), f16_at(n, 4)).normalize_or_zero())
        .collect();
    let world = app.world();
    let (cam, transform) =
        (world.get::<Camera>(camera).expect("a camera"), world.get::<GlobalTransform>(camera).expect("a transform"));
    let clip_from_view = cam.clip_from_view();
    let view_from_world = transform.to_matrix().inverse();
    bevy_hao::cpu::contacts::ViewDepth {
        size: UVec2::new(w, h),
        depth,
        clip_from_world: clip_from_view * view_from_world,
        view_from_world,
        view_from_clip: clip_from_view.inverse(),
        normals,
    }
}

/// How a test mesh stores its data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// Positions only (stride 12), `u32` indices.
    U32,
    /// Positions, normals and UVs (stride 32), `u16` indices.
    U16WithAttributes,
    /// Positions and normals (stride 24), no indices (three vertices per triangle).
    NonIndexed,
}

/// A Bevy mesh from a [`TriangleMesh`], in one of the layouts.
pub fn bevy_mesh(mesh: &TriangleMesh, layout: Layout) -> Mesh {
    let mut m = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default());
    match layout {
        Layout::NonIndexed => {
            let positions: Vec<[f32; 3]> =
                mesh.triangles.iter().flat_map(|t| t.map(|i| mesh.positions[i as usize].to_array())).collect();
            let normals = vec![[0.0, 1.0, 0.0]; positions.len()];
            m.insert_attribute(Mesh::ATTRIBUTE_POSITION, positions);
            m.insert_attribute(Mesh::ATTRIBUTE_NORMAL, normals);
        }
        Layout::U32 | Layout::U16WithAttributes => {
            let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
            let n = positions.len();
            m.insert_attribute(Mesh::ATTRIBUTE_POSITION, positions);
            let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
            if layout == Layout::U16WithAttributes {
                assert!(n <= 65536, "too many vertices for u16 indices");
                m.insert_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n]);
                m.insert_attribute(Mesh::ATTRIBUTE_UV_0, vec![[0.5f32, 0.5]; n]);
                m.insert_indices(Indices::U16(indices.iter().map(|&i| i as u16).collect()));
            } else {
                m.insert_indices(Indices::U32(indices));
            }
        }
    }
    m
}

/// The latest value of a diagnostic (e.g. `render/hao/voxelize_static/elapsed_gpu`, in ms).
pub fn diagnostic(app: &App, path: &str) -> Option<f64> {
    let store = app.world().resource::<bevy::diagnostic::DiagnosticsStore>();
    store.get(&bevy::diagnostic::DiagnosticPath::new(path.to_string())).and_then(|d| d.value())
}

/// The latest measurement of a diagnostic and when it was taken (to tell new measurements from old).
pub fn diagnostic_measurement(app: &App, path: &str) -> Option<(std::time::Instant, f64)> {
    let store = app.world().resource::<bevy::diagnostic::DiagnosticsStore>();
    store
        .get(&bevy::diagnostic::DiagnosticPath::new(path.to_string()))
        .and_then(|d| d.measurement())
        .map(|m| (m.time, m.value))
}

/// The recorded history of a diagnostic (oldest first; Bevy keeps the latest 120 or so).
pub fn diagnostic_history(app: &App, path: &str) -> Vec<f64> {
    let store = app.world().resource::<bevy::diagnostic::DiagnosticsStore>();
    store
        .get(&bevy::diagnostic::DiagnosticPath::new(path.to_string()))
        .map(|d| d.values().copied().collect())
        .unwrap_or_default()
}

/// Median of a list of timings.
pub fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// Reads an image back (the first arrival at least `settle` frames after the call), without the 256-byte
/// row padding. Returns `(width, height, bytes per texel, bytes)`; a 3D image's slices follow each other.
pub fn read_image(app: &mut App, image: Handle<Image>, settle: usize) -> (u32, u32, u32, Vec<u8>) {
    let (w, h, depth, texel) = {
        let images = app.world().resource::<Assets<Image>>();
        let img = images.get(&image).expect("image asset");
        let size = img.texture_descriptor.size;
        let texel = img.texture_descriptor.format.block_copy_size(None).expect("uncompressed format");
        (size.width, size.height, size.depth_or_array_layers, texel)
    };
    let data = read_back(app, Readback::texture(image), settle);
    let row = (w * texel) as usize;
    let padded = row.div_ceil(256) * 256;
    let rows = (h * depth) as usize;
    let mut out = Vec::with_capacity(row * rows);
    for y in 0..rows {
        out.extend_from_slice(&data[y * padded..y * padded + row]);
    }
    (w, h, texel, out)
}

/// Reads `images` back in each of the next `frames` frames, consecutive ones, calling `after_frame` after
/// each (its index): per image, each frame's bytes without the row padding. The last frames' copies arrive in
/// the frames after them (`after_frame` can stop whatever moves the scene at the last). Fails if they do not
/// arrive within 20 frames.
pub fn read_frames(
    app: &mut App,
    images: &[Handle<Image>],
    frames: usize,
    mut after_frame: impl FnMut(&mut App, usize),
) -> Vec<Vec<Vec<u8>>> {
    let sinks: Vec<Arc<Mutex<Vec<Vec<u8>>>>> = images.iter().map(|_| Arc::default()).collect();
    let entities: Vec<Entity> = images
        .iter()
        .zip(&sinks)
        .map(|(image, sink)| {
            let sink = sink.clone();
            app.world_mut()
                .spawn(Readback::texture(image.clone()))
                .observe(move |ev: On<ReadbackComplete>| sink.lock().unwrap().push(ev.data.clone()))
                .id()
        })
        .collect();
    let arrived = |sinks: &[Arc<Mutex<Vec<Vec<u8>>>>]| sinks.iter().map(|s| s.lock().unwrap().len()).min().unwrap_or(0);
    for k in 0..frames {
        app.update();
        // Each frame's copy arrives in the next once the device has run it (see `read_back`).
        wait_for_gpu(app);
        after_frame(app, k);
    }
    for _ in 0..20 {
        if arrived(&sinks) >= frames {
            break;
        }
        app.update();
        wait_for_gpu(app);
    }
    for e in entities {
        app.world_mut().despawn(e);
    }
    assert!(arrived(&sinks) >= frames, "the readbacks of {frames} frames did not arrive within 20 frames");
    images
        .iter()
        .zip(sinks)
        .map(|(image, sink)| {
            // Rows of every layer of a 3D image, as `read_image` reads them.
            let (w, h, texel) = {
                let img = app.world().resource::<Assets<Image>>().get(image).expect("image asset");
                let size = img.texture_descriptor.size;
                let texel = img.texture_descriptor.format.block_copy_size(None).expect("uncompressed");
                (size.width, size.height * size.depth_or_array_layers, texel)
            };
            let row = (w * texel) as usize;
            let padded = row.div_ceil(256) * 256;
            let data = std::mem::take(&mut *sink.lock().unwrap());
            data.into_iter()
                .take(frames)
                .map(|d| (0..h as usize).flat_map(|y| d[y * padded..y * padded + row].iter().copied()).collect())
                .collect()
        })
        .collect()
}

/// An `R32Float` image read back as floats, with its width and height.
pub fn read_image_f32(app: &mut App, image: Handle<Image>, settle: usize) -> (u32, u32, Vec<f32>) {
    let (w, h, texel, bytes) = read_image(app, image, settle);
    assert_eq!(texel, 4, "not a 32-bit single-channel image");
    (w, h, bytemuck::cast_slice(&bytes).to_vec())
}

/// Saves `target` (a render-target image) to the PNG file `out` with Bevy's screenshot and runs frames
/// until the file exists. Fails if wgpu reported errors or the file was not written within 20 frames.
pub fn save_screenshot(app: &mut App, target: Handle<Image>, out: &str) -> Result<(), String> {
    use bevy::render::view::screenshot::{Screenshot, save_to_disk};
    let _ = std::fs::remove_file(out);
    let path = out.to_string();
    app.world_mut().spawn(Screenshot::image(target)).observe(save_to_disk(path));
    for _ in 0..20 {
        app.update();
        if std::path::Path::new(out).exists() {
            break;
        }
        // As in `read_back`: the frames may run ahead of the device.
        wait_for_gpu(app);
    }
    let errors = take_render_errors();
    if !errors.is_empty() {
        return Err(format!("wgpu errors: {errors:?}"));
    }
    if !std::path::Path::new(out).exists() {
        return Err("the screenshot was not written".into());
    }
    Ok(())
}

/// A render target image that can be read back.
pub fn target_image(images: &mut Assets<Image>, size: UVec2) -> Handle<Image> {
    let mut image =
        Image::new_target_texture(size.x, size.y, bevy::render::render_resource::TextureFormat::Rgba8UnormSrgb, None);
    image.texture_descriptor.usage |= bevy::render::render_resource::TextureUsages::COPY_SRC;
    images.add(image)
}

/// A progress bar on standard error for `len` steps of `what` (drawn only on a terminal).
pub fn progress_bar(len: u64, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta} left)")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// The `f16` at `bytes[at..at + 2]` (little-endian, as a half-float texture reads back) as `f32`.
pub fn f16_at(bytes: &[u8], at: usize) -> f32 {
    half::f16::from_le_bytes([bytes[at], bytes[at + 1]]).to_f32()
}

/// Command-line values shared by the tools and the examples (as clap value parsers).
pub mod args {
    use bevy::math::{UVec2, UVec3, Vec3};
    use bevy_hao::HaoDebugView;

    /// A HAO quality preset (`--quality`): [`bevy_hao::HaoQuality`]'s presets by their command-line names.
    #[derive(Clone, Copy, Debug, PartialEq, clap::ValueEnum)]
    pub enum Quality {
        /// `HaoQuality::Low`.
        Low,
        /// `HaoQuality::Medium`.
        Medium,
        /// `HaoQuality::High`.
        High,
        /// `HaoQuality::Ultra`.
        Ultra,
    }

    impl From<Quality> for bevy_hao::HaoQuality {
        fn from(q: Quality) -> Self {
            match q {
                Quality::Low => Self::Low,
                Quality::Medium => Self::Medium,
                Quality::High => Self::High,
                Quality::Ultra => Self::Ultra,
            }
        }
    }

    /// What a view shows (`--view`): [`HaoDebugView`]'s choices by their command-line names.
    #[derive(Clone, Copy, Debug, clap::ValueEnum)]
    pub enum View {
        /// The lit image.
        Final,
        /// The ambient occlusion.
        Ao,
        /// The voxel grid.
        Voxels,
        /// Points per voxel as a heat map.
        Counts,
        /// Static and dynamic voxels.
        StaticDynamic,
        /// Voxels tinted by cascade.
        Cascades,
        /// Voxels colored by their average albedo (needs `VoxelVolume::attributes`).
        Albedo,
        /// Voxels colored by their average normal (needs `VoxelVolume::attributes`).
        Normals,
        /// Voxels colored by the light in them (voxel GI's lighting volume).
        Lit,
    }

    impl From<View> for HaoDebugView {
        fn from(v: View) -> Self {
            match v {
                View::Final => HaoDebugView::Final,
                View::Ao => HaoDebugView::AmbientOcclusion,
                View::Voxels => HaoDebugView::Voxels,
                View::Counts => HaoDebugView::PointCounts,
                View::StaticDynamic => HaoDebugView::StaticDynamic,
                View::Cascades => HaoDebugView::Cascades,
                View::Albedo => HaoDebugView::Albedo,
                View::Normals => HaoDebugView::Normals,
                View::Lit => HaoDebugView::LitVoxels,
            }
        }
    }

    /// `X,Y,Z`.
    pub fn vec3(s: &str) -> Result<Vec3, String> {
        triple::<f32>(s, "number").map(Vec3::from_array)
    }

    /// `X,Y,Z`, whole numbers.
    pub fn uvec3(s: &str) -> Result<UVec3, String> {
        triple::<u32>(s, "count").map(UVec3::from_array)
    }

    /// Three comma-separated values of `T` (`what` names one in the error).
    fn triple<T: std::str::FromStr>(s: &str, what: &str) -> Result<[T; 3], String>
    where
        T::Err: std::fmt::Display,
    {
        let v: Vec<T> = s
            .split(',')
            .map(|x| x.trim().parse::<T>().map_err(|e| format!("bad {what} {x:?}: {e}")))
            .collect::<Result<_, _>>()?;
        <[T; 3]>::try_from(v).map_err(|_| format!("expected X,Y,Z, got {s}"))
    }

    /// `WIDTHxHEIGHT`, each from 1 to [`MAX_SIZE`] (wgpu's default limit on a texture's side): a render
    /// target of zero pixels, or past what the device takes, is refused here rather than by the device.
    pub fn size(s: &str) -> Result<UVec2, String> {
        let (w, h) = s.split_once('x').ok_or("a size is WIDTHxHEIGHT")?;
        let size = UVec2::new(
            w.parse().map_err(|_| format!("bad width {w:?}"))?,
            h.parse().map_err(|_| format!("bad height {h:?}"))?,
        );
        if size.min_element() == 0 || size.max_element() > MAX_SIZE {
            return Err(format!("{s}: width and height from 1 to {MAX_SIZE}"));
        }
        Ok(size)
    }

    /// The largest width or height [`size`] takes.
    pub const MAX_SIZE: u32 = 8192;

    /// `X,Y,W,H`: a crop of an image, in pixels (`--zoom`), of at least one pixel each way.
    pub fn crop(v: &str) -> Result<[u32; 4], String> {
        let p: Vec<u32> =
            v.split(',').map(|x| x.trim().parse::<u32>()).collect::<Result<_, _>>().map_err(|e| e.to_string())?;
        let c = <[u32; 4]>::try_from(p).map_err(|_| format!("expected X,Y,W,H, got {v}"))?;
        if c[2] == 0 || c[3] == 0 {
            return Err(format!("{v}: an empty crop"));
        }
        Ok(c)
    }

    /// `LEVELS,CELLS,FINEST_CELL_SIZE`: the shape of camera-following cascades (`--cascades`), as
    /// `VolumeBounds::FollowCamera` takes it (the plugin sanitizes the values).
    pub fn cascades(v: &str) -> Result<(u32, u32, f32), String> {
        let bad = || format!("expected LEVELS,CELLS,FINEST_CELL_SIZE, got {v}");
        let p: Vec<&str> = v.split(',').map(str::trim).collect();
        let [levels, cells, size] = p[..] else { return Err(bad()) };
        Ok((levels.parse().map_err(|_| bad())?, cells.parse().map_err(|_| bad())?, size.parse().map_err(|_| bad())?))
    }

    #[cfg(test)]
    mod tests {
        #[test]
        fn cascades_take_three_values() {
            assert_eq!(super::cascades("5, 192,0.0625"), Ok((5, 192, 0.0625)));
            for bad in ["5,192", "5,192,0.1,2", "a,192,0.1", "5,x,0.1", "5,192,y"] {
                assert!(super::cascades(bad).is_err(), "{bad}");
            }
        }

        #[test]
        fn sizes_and_crops_of_zero_or_past_the_limit_are_refused() {
            assert_eq!(super::size("320x180"), Ok(super::UVec2::new(320, 180)));
            for bad in ["0x180", "320x0", "9000x10", "320", "axb", "-1x5"] {
                assert!(super::size(bad).is_err(), "{bad}");
            }
            assert_eq!(super::crop("1, 2,3,4"), Ok([1, 2, 3, 4]));
            for bad in ["1,2,0,4", "1,2,3", "1,2,3,4,5", "a,b,c,d"] {
                assert!(super::crop(bad).is_err(), "{bad}");
            }
        }
    }
}
