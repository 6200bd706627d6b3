//! Every WGSL file of the crate, composed with naga_oil (as Bevy does) and validated with naga. No GPU
//! needed.

use bevy::render::render_resource::encase::internal::WriteInto;
use naga_oil::compose::{ComposableModuleDescriptor, Composer, NagaModuleDescriptor, ShaderDefValue, ShaderType};
use std::collections::HashMap;
use std::path::Path;

/// Import modules, in dependency order.
const MODULES: &[&str] = &[
    "src/voxel/voxelize_common.wgsl",
    "src/voxel/voxelize_pass.wgsl",
    "src/voxel/voxelize_vertices.wgsl",
    "src/voxel/voxel_grid.wgsl",
    "src/ao/hao_common.wgsl",
    "src/ao/hao_change.wgsl",
    "src/gi/gi_common.wgsl",
];

/// Bevy's modules our shaders import, relative to the `bevy_render` crate's root.
const BEVY_RENDER_MODULES: &[&str] = &["src/view/view.wgsl"];

/// The root of the `bevy_render` crate this build uses, from `cargo metadata`.
fn bevy_render_root() -> std::path::PathBuf {
    let out = std::process::Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata");
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("cargo metadata output");
    let package = meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "bevy_render")
        .expect("bevy_render in the dependency graph");
    Path::new(package["manifest_path"].as_str().unwrap()).parent().unwrap().to_path_buf()
}

/// Entry shaders and the shader-def sets they are compiled with.
fn shaders() -> Vec<(&'static str, Vec<Vec<(&'static str, ShaderDefValue)>>)> {
    let texture_variants = vec![vec![("VOXEL_TEXTURE_R8", ShaderDefValue::Bool(true))], vec![]];
    let multisampled = vec![vec![("MULTISAMPLED", ShaderDefValue::Bool(true))], vec![]];
    vec![
        ("src/voxel/voxelize_classify.wgsl", vec![vec![]]),
        ("src/voxel/voxelize_scan.wgsl", vec![vec![]]),
        ("src/voxel/voxelize_expand.wgsl", vec![vec![]]),
        (
            "src/voxel/voxelize_solid.wgsl",
            vec![
                vec![],
                vec![
                    ("VOXELIZE_PARAMS_IN_STORAGE", ShaderDefValue::Bool(true)),
                    ("VOXELIZE_SKINNING", ShaderDefValue::Bool(true)),
                    ("VOXELIZE_MORPH", ShaderDefValue::Bool(true)),
                ],
            ],
        ),
        ("src/voxel/voxel_clear.wgsl", vec![vec![]]),
        ("src/voxel/voxel_resolve.wgsl", texture_variants.clone()),
        ("src/voxel/voxel_mip.wgsl", texture_variants),
        // Every combination of the trace's defs (`TraceVariant`), and the temporal pass's with and without
        // the moved occluders.
        ("src/ao/hao_trace.wgsl", combinations(&["MULTISAMPLED", "BACK_HITS", "FREE_SPACE", "MOVED_OCCLUDERS"], &[])),
        ("src/ao/hao_neighborhood.wgsl", vec![vec![]]),
        (
            "src/ao/hao_temporal.wgsl",
            [
                vec![],
                vec!["USE_R16FLOAT"],
                vec!["NEAR_FIELD"],
                vec!["MULTISAMPLED", "USE_R16FLOAT"],
                vec!["MULTISAMPLED", "NEAR_FIELD"],
            ]
            .iter()
            .flat_map(|defs| combinations(&["MOVED_OCCLUDERS"], defs))
            .collect(),
        ),
        ("src/ao/hao_apply.wgsl", vec![vec![("USE_R16FLOAT", ShaderDefValue::Bool(true))], vec![]]),
        ("src/debug/debug_images.wgsl", multisampled),
        ("src/debug/debug_view.wgsl", vec![vec![]]),
        ("src/gi/gi_lighting.wgsl", vec![vec![]]),
        ("src/gi/gi_probes.wgsl", vec![vec![]]),
    ]
}

/// Every subset of `optional` (each def `true`), each with `always`.
fn combinations(optional: &[&'static str], always: &[&'static str]) -> Vec<Vec<(&'static str, ShaderDefValue)>> {
    (0..1u32 << optional.len())
        .map(|mask| {
            let chosen = optional.iter().enumerate().filter(|(k, _)| mask & (1 << k) != 0).map(|(_, d)| *d);
            always.iter().copied().chain(chosen).map(|d| (d, ShaderDefValue::Bool(true))).collect()
        })
        .collect()
}

/// The shader defs every compute pipeline gets (`crate::gpu::shader_defs`), as naga_oil takes them.
fn shared_defs() -> HashMap<String, ShaderDefValue> {
    use bevy::shader::ShaderDefVal;
    crate::gpu::shader_defs()
        .into_iter()
        .map(|d| match d {
            ShaderDefVal::Bool(k, v) => (k, ShaderDefValue::Bool(v)),
            ShaderDefVal::Int(k, v) => (k, ShaderDefValue::Int(v)),
            ShaderDefVal::UInt(k, v) => (k, ShaderDefValue::UInt(v)),
        })
        .collect()
}

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn composer() -> Composer {
    let mut c = Composer::default();
    let root = bevy_render_root();
    for path in BEVY_RENDER_MODULES {
        let file = root.join(path);
        let source = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        c.add_composable_module(ComposableModuleDescriptor { source: &source, file_path: path, ..Default::default() })
            .unwrap_or_else(|e| panic!("{path}: {}", e.emit_to_string(&Composer::default())));
    }
    for path in MODULES {
        c.add_composable_module(ComposableModuleDescriptor {
            source: &read(path),
            file_path: path,
            ..Default::default()
        })
        .unwrap_or_else(|e| panic!("{path}: {}", e.emit_to_string(&Composer::default())));
    }
    c
}

#[test]
fn every_wgsl_file_composes_and_validates() {
    let mut composer = composer();
    let mut checked = 0;
    for (path, variants) in shaders() {
        let source = read(path);
        for defs in variants {
            let mut shader_defs = shared_defs();
            shader_defs.extend(defs.iter().map(|(k, v)| (k.to_string(), *v)));
            let module = composer
                .make_naga_module(NagaModuleDescriptor {
                    source: &source,
                    file_path: path,
                    shader_type: ShaderType::Wgsl,
                    shader_defs,
                    ..Default::default()
                })
                .unwrap_or_else(|e| panic!("{path} {defs:?}: {}", e.emit_to_string(&composer)));
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
                .validate(&module)
                .unwrap_or_else(|e| panic!("{path} {defs:?}: {}", e.emit_to_string(&source)));
            checked += 1;
        }
    }
    // Every .wgsl file under src/ is either an import module or an entry shader listed above.
    let mut on_disk = Vec::new();
    let mut stack = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("src")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "wgsl") {
                on_disk.push(p.strip_prefix(env!("CARGO_MANIFEST_DIR")).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    let listed: Vec<String> =
        MODULES.iter().map(|s| s.to_string()).chain(shaders().iter().map(|s| s.0.to_string())).collect();
    for f in &on_disk {
        assert!(listed.contains(f), "{f} is not validated: add it to src/wgsl_tests.rs");
    }
    assert!(checked >= 12);
}

/// `(entry shader, WGSL struct, Rust size, Rust field offsets)` of a Rust struct uploaded as `$t`.
macro_rules! layout {
    ($shader:expr, $wgsl:expr, $t:ty, [$($f:ident),* $(,)?]) => {
        ($shader, $wgsl, std::mem::size_of::<$t>(), vec![$(std::mem::offset_of!($t, $f)),*])
    };
}

/// Every `#[repr(C)]` struct the passes upload, with its WGSL twin and a shader that declares it.
fn layouts() -> Vec<(&'static str, &'static str, usize, Vec<usize>)> {
    use crate::ao::prepare::GpuHaoSettings;
    use crate::debug::{GpuDebugCopy, GpuDebugSettings};
    use crate::gi::lighting::{GpuGiLight, GpuGiLightingParams};
    use crate::gi::probes::GpuProbeParams;
    use crate::voxel::pipelines::{GpuLevelRegion, GpuOccluderInstance, GpuSlabGroup, GpuVoxelizeParams};
    vec![
        layout!(
            "src/ao/hao_trace.wgsl",
            "HaoSettings",
            GpuHaoSettings,
            [
                previous_clip_from_world,
                rays,
                steps,
                max_distance,
                falloff,
                intensity,
                start_offset,
                frame,
                near_field,
                half_resolution,
                denoise_radius,
                accumulation_frames,
                back_hits,
                history_valid,
                origin_x,
                origin_y,
                view_width,
                view_height,
                trace_width,
                trace_height,
                depth_contacts,
                checkerboard,
                contact_samples,
                still_accumulation_frames,
                _pad_c,
            ]
        ),
        layout!("src/debug/debug_view.wgsl", "DebugSettings", GpuDebugSettings, [mode, sample_words, has_ao, _pad]),
        layout!("src/debug/debug_images.wgsl", "DebugCopy", GpuDebugCopy, [ao_origin, prepass_origin]),
        layout!(
            "src/gi/gi_lighting.wgsl",
            "GiLightingParams",
            GpuGiLightingParams,
            [light_count, phase, phases, blocks_z, bounce_feedback, _pad_a, _pad_b, _pad_c]
        ),
        layout!(
            "src/gi/gi_probes.wgsl",
            "ProbeParams",
            GpuProbeParams,
            [window_min, rays, counts, phase, spacing, phases, max_frames, seed, focus, far]
        ),
        layout!(
            "src/gi/gi_lighting.wgsl",
            "GiLight",
            GpuGiLight,
            [
                position,
                kind,
                direction,
                inverse_range_squared,
                intensity,
                spot_scale,
                spot_offset,
                _pad_a,
                _pad_b,
                _pad_c
            ]
        ),
        layout!(
            "src/voxel/voxelize_classify.wgsl",
            "OccluderInstance",
            GpuOccluderInstance,
            [
                grid_from_local,
                vertex_start,
                vertex_count,
                vertex_stride,
                position_offset,
                index_start,
                index_format,
                triangle_count,
                first_triangle,
                skin_index,
                joint_count,
                joint_offset,
                weight_offset,
                morph_weights_offset,
                morph_weight_count,
                morph_targets_offset,
                morph_vertex_count,
                normal_offset,
                solid,
                color_offset,
                albedo,
            ]
        ),
        layout!(
            "src/voxel/voxelize_classify.wgsl",
            "SlabGroup",
            GpuSlabGroup,
            [first_instance, instance_count, triangle_count, _pad,]
        ),
        layout!(
            "src/voxel/voxelize_classify.wgsl",
            "VoxelizeParams",
            GpuVoxelizeParams,
            [
                region_min,
                mode,
                region_max,
                gamma,
                window_min,
                point_budget,
                closed_max,
                sample_words,
                wrap,
                counter_base,
                dims,
                voxel_base,
                pattern,
                _pad_a,
                _pad_b,
                _pad_c,
            ]
        ),
        layout!(
            "src/voxel/voxel_resolve.wgsl",
            "LevelRegion",
            GpuLevelRegion,
            [
                region_min,
                texture_z,
                region_max,
                voxel_base,
                window_min,
                brick_pass,
                wrap,
                sample_words,
                dims,
                _pad2,
                size,
                _pad3,
            ]
        ),
    ]
}

/// The struct named `name` in `module` (its own, or an imported one under naga_oil's decorated name):
/// its members' offsets and its size.
fn wgsl_layout(module: &naga::Module, name: &str) -> Option<(Vec<usize>, usize)> {
    let decorated = format!("{name}X_naga_oil_mod_X");
    module.types.iter().find_map(|(_, t)| match (&t.name, &t.inner) {
        (Some(n), naga::TypeInner::Struct { members, span }) if n == name || n.starts_with(&decorated) => {
            Some((members.iter().map(|m| m.offset as usize).collect(), *span as usize))
        }
        _ => None,
    })
}

/// What encase writes for a uniform (`ShaderType`) is its `repr(C)` twin's memory, for a value of
/// distinct words: so the offsets [`uploaded_structs_match_their_wgsl_layouts`] checks are the GPU's.
fn encased_as_in_memory<T: bytemuck::Pod + bevy::render::render_resource::ShaderType + WriteInto>() {
    let words: Vec<u32> = (0..std::mem::size_of::<T>() / 4).map(|k| 0x0101_0101 * (k as u32 + 1)).collect();
    let value: T = bytemuck::pod_read_unaligned(bytemuck::cast_slice(&words));
    let name = std::any::type_name::<T>();
    assert_eq!(crate::gpu::uniform_bytes(&value), bytemuck::bytes_of(&value), "{name}: encase's bytes");
    assert_eq!(T::min_size().get(), std::mem::size_of::<T>() as u64, "{name}: the binding's minimum size");
}

/// The Rust structs the passes upload have their WGSL twins' layouts: the same size and the same offset
/// for every member, as naga lays the WGSL out; the uniforms, written by encase, lie as in memory. The
/// voxel grid (a `ShaderType` with arrays) is checked by size.
#[test]
fn uploaded_structs_match_their_wgsl_layouts() {
    use bevy::render::render_resource::ShaderType as _;
    let mut composer = composer();
    let mut module = |path: &str| {
        composer
            .make_naga_module(NagaModuleDescriptor {
                source: &read(path),
                file_path: path,
                shader_type: ShaderType::Wgsl,
                shader_defs: shared_defs(),
                ..Default::default()
            })
            .unwrap_or_else(|e| panic!("{path}: {e:?}"))
    };
    for (shader, name, size, offsets) in layouts() {
        let (wgsl_offsets, wgsl_size) =
            wgsl_layout(&module(shader), name).unwrap_or_else(|| panic!("no struct {name} in {shader}"));
        assert_eq!(wgsl_size, size, "{name}: WGSL size {wgsl_size}, Rust {size}");
        assert_eq!(wgsl_offsets, offsets, "{name}: member offsets (WGSL, then Rust)");
    }
    encased_as_in_memory::<crate::ao::prepare::GpuHaoSettings>();
    encased_as_in_memory::<crate::debug::GpuDebugSettings>();
    encased_as_in_memory::<crate::voxel::pipelines::GpuVoxelizeParams>();
    encased_as_in_memory::<crate::voxel::pipelines::GpuLevelRegion>();
    encased_as_in_memory::<crate::voxel::pipelines::GpuSlabGroup>();
    encased_as_in_memory::<crate::gi::lighting::GpuGiLightingParams>();
    encased_as_in_memory::<crate::gi::probes::GpuProbeParams>();
    let (_, record) = wgsl_layout(&module("src/gi/gi_probes.wgsl"), "ProbeRecord").expect("ProbeRecord");
    assert_eq!(record as u64, crate::gi::probes::PROBE_RECORD_BYTES, "ProbeRecord size");
    let (_, grid_size) = wgsl_layout(&module("src/ao/hao_trace.wgsl"), "VoxelGrid").expect("VoxelGrid");
    assert_eq!(grid_size as u64, crate::voxel::bindings::GpuVoxelGrid::min_size().get(), "VoxelGrid size");
    let (_, big) = wgsl_layout(&module("src/voxel/voxelize_expand.wgsl"), "BigTriangle").expect("BigTriangle");
    assert_eq!(big as u64, crate::voxel::pipelines::BIG_TRIANGLE_BYTES, "BigTriangle size");
}

/// The value of `const NAME: T = VALUE;` in the WGSL file `path` (integer literals with or without `u`,
/// hexadecimal, or floats).
fn wgsl_const(path: &str, name: &str) -> f64 {
    let source = read(path);
    let line = source
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("const {name}:")))
        .unwrap_or_else(|| panic!("no const {name} in {path}"));
    let value = line.split('=').nth(1).expect("a value").trim().trim_end_matches(';').trim();
    let digits = value.trim_end_matches('u');
    if let Some(hex) = digits.strip_prefix("0x") {
        u64::from_str_radix(hex, 16).expect("a hexadecimal literal") as f64
    } else {
        digits.parse::<f64>().unwrap_or_else(|e| panic!("{name} = {value}: {e}"))
    }
}

/// The constants Rust and WGSL share that are WGSL `const`s rather than shader defs (floats, and those of
/// `voxel_grid.wgsl`, which other crates' shaders import) have one value: each against the Rust constant it
/// mirrors. And the voxelizer's entry points, sized by a shader def, run `VOXELIZE_WORKGROUP` invocations.
#[test]
fn shared_constants_agree() {
    use crate::cpu::{cascade, contacts, temporal, voxelize};
    use crate::voxel::{bindings, pipelines};
    let common = "src/voxel/voxelize_common.wgsl";
    let hao = "src/ao/hao_common.wgsl";
    let gi = "src/gi/gi_common.wgsl";
    let lighting = "src/gi/gi_lighting.wgsl";
    let probes = "src/gi/gi_probes.wgsl";
    let pairs: [(&str, &str, f64); 63] = [
        (probes, "MOVED_REACH_RADII", crate::cpu::probes::MOVED_REACH_RADII as f64),
        (probes, "FACE_REACH", crate::cpu::probes::FACE_REACH as f64),
        (probes, "PROBE_LANES", crate::cpu::probes::PROBE_LANES as f64),
        (probes, "PROBE_GROUPS_X", crate::gi::probes::PROBE_GROUPS_X as f64),
        (probes, "GROUP_PROBES", crate::gi::probes::GROUP_PROBES as f64),
        (probes, "FACE_STEPS", crate::cpu::probes::FACE_STEPS as f64),
        (probes, "FACE_EXIT_STEPS", crate::cpu::probes::FACE_EXIT_STEPS as f64),
        (probes, "PROBE_STEPS", crate::cpu::probes::PROBE_STEPS as f64),
        (probes, "PROBE_MAX_DISTANCE", crate::cpu::probes::PROBE_MAX_DISTANCE as f64),
        (probes, "RELOCATE_MAX", crate::cpu::probes::RELOCATE_MAX as f64),
        (probes, "SHADOW_NORMAL_MIN", crate::cpu::lighting::SHADOW_NORMAL_MIN as f64),
        (gi, "GI_LIGHT_DIRECTIONAL", crate::cpu::lighting::LightKind::Directional as u32 as f64),
        (gi, "GI_LIGHT_POINT", crate::cpu::lighting::LightKind::Point as u32 as f64),
        (gi, "GI_LIGHT_SPOT", crate::cpu::lighting::LightKind::Spot as u32 as f64),
        (gi, "RGB9E5_MAX", crate::cpu::lighting::RGB9E5_MAX as f64),
        (gi, "EDGE_FADE_SPACINGS", crate::cpu::probes::EDGE_FADE_SPACINGS as f64),
        (lighting, "SHADOW_START_CELLS", crate::cpu::lighting::SHADOW_START_CELLS as f64),
        (lighting, "SHADOW_STEPS", crate::cpu::lighting::SHADOW_STEPS as f64),
        (lighting, "SHADOW_NORMAL_MIN", crate::cpu::lighting::SHADOW_NORMAL_MIN as f64),
        (lighting, "BOUNCE_LIFT_CELLS", crate::cpu::lighting::BOUNCE_LIFT_CELLS as f64),
        (lighting, "BOUNCE_VISIBILITY_STEPS", crate::cpu::lighting::BOUNCE_VISIBILITY_STEPS as f64),
        (common, "CONSERVATIVE_PAD", voxelize::CONSERVATIVE_PAD as f64),
        ("src/voxel/voxel_grid.wgsl", "MAX_VOXEL_LEVELS", bindings::MAX_VOXEL_LEVELS as f64),
        ("src/voxel/voxel_grid.wgsl", "MAX_VOXEL_LEVELS", cascade::MAX_CASCADES as f64),
        ("src/voxel/voxel_grid.wgsl", "MAX_MOVED_OCCLUDERS", bindings::MAX_MOVED_OCCLUDERS as f64),
        ("src/voxel/voxel_grid.wgsl", "UNKNOWN_MOTION", bindings::UNKNOWN_MOTION as f64),
        ("src/voxel/voxel_grid.wgsl", "MIN_OCCLUDING_CHORD", crate::cpu::march::MIN_OCCLUDING_CHORD as f64),
        ("src/voxel/voxel_grid.wgsl", "MARCH_START_MIP", crate::cpu::march::MARCH_START_MIP as f64),
        ("src/voxel/voxel_grid.wgsl", "CASCADE_BLEND_CELLS", crate::cpu::march::CASCADE_BLEND_CELLS as f64),
        (hao, "DEPTH_TOLERANCE", temporal::DEPTH_TOLERANCE as f64),
        (hao, "NORMAL_TOLERANCE", temporal::NORMAL_TOLERANCE as f64),
        (hao, "CLAMP_MARGIN", temporal::CLAMP_MARGIN as f64),
        (hao, "CLAMPED_COUNT", temporal::CLAMPED_COUNT as f64),
        (hao, "CHANGED_COUNT", temporal::CHANGED_COUNT as f64),
        (hao, "STAND_IN_COUNT", temporal::STAND_IN_COUNT as f64),
        (hao, "MAX_HISTORY_FRAMES", temporal::MAX_HISTORY_FRAMES as f64),
        (hao, "STILL_TOLERANCE", temporal::STILL_TOLERANCE as f64),
        (hao, "CHANGE_NOISE_FLOOR", temporal::CHANGE_NOISE_FLOOR as f64),
        (hao, "CHANGE_NOISE_SAMPLES", temporal::CHANGE_NOISE_SAMPLES as f64),
        (hao, "WINDOW_Z", temporal::WINDOW_Z as f64),
        (hao, "STABLE_Z", temporal::STABLE_Z as f64),
        ("src/ao/hao_change.wgsl", "CHANGE_RAYS_SCALE", temporal::CHANGE_RAYS_SCALE as f64),
        ("src/ao/hao_change.wgsl", "CHANGE_RAYS_FROM", temporal::CHANGE_RAYS_FROM as f64),
        ("src/ao/hao_neighborhood.wgsl", "CHANGED_FILTER_REACH", temporal::CHANGED_FILTER_REACH as f64),
        ("src/ao/hao_change.wgsl", "CHANGED_FILTER_FROM", temporal::CHANGED_FILTER_FROM as f64),
        (common, "MAX_PN_GAMMA_SCALE", crate::cpu::pn::MAX_PN_GAMMA_SCALE as f64),
        (common, "ALBEDO_SCALE", crate::cpu::attributes::ALBEDO_SCALE as f64),
        (common, "NORMAL_SCALE", crate::cpu::attributes::NORMAL_SCALE as f64),
        ("src/ao/hao_trace.wgsl", "BACK_HIT_COS", crate::cpu::ao::BACK_HIT_COS as f64),
        ("src/ao/hao_trace.wgsl", "MAX_BACK_HITS", crate::cpu::ao::MAX_BACK_HITS as f64),
        ("src/ao/hao_trace.wgsl", "CONTACT_LENGTH", contacts::CONTACT_LENGTH as f64),
        ("src/ao/hao_trace.wgsl", "CONTACT_THICKNESS", contacts::CONTACT_THICKNESS as f64),
        ("src/ao/hao_trace.wgsl", "CONTACT_GRAZING_COS", contacts::CONTACT_GRAZING_COS as f64),
        ("src/ao/hao_trace.wgsl", "CONTACT_LIFT_PIXELS", contacts::CONTACT_LIFT_PIXELS as f64),
        ("src/ao/hao_trace.wgsl", "CONTACT_LIFT_CELLS", contacts::CONTACT_LIFT_CELLS as f64),
        ("src/ao/hao_trace.wgsl", "CONTACT_DEPTH_EPSILON", contacts::CONTACT_DEPTH_EPSILON as f64),
        ("src/ao/hao_trace.wgsl", "FREE_SPACE_MARGIN", contacts::FREE_SPACE_MARGIN as f64),
        ("src/ao/hao_trace.wgsl", "MAX_FREE_SPACE_PASSES", contacts::MAX_FREE_SPACE_PASSES as f64),
        ("src/ao/hao_trace.wgsl", "NEAR_FREE_SPACE_CELLS", contacts::NEAR_FREE_SPACE_CELLS as f64),
        ("src/ao/hao_trace.wgsl", "NEAR_FREE_SPACE_PIXELS", contacts::NEAR_FREE_SPACE_PIXELS as f64),
        ("src/ao/hao_trace.wgsl", "MAX_NEAR_FREE_SPACE_PASSES", contacts::MAX_NEAR_FREE_SPACE_PASSES as f64),
        ("src/ao/hao_trace.wgsl", "OWN_CELL_MARGIN", crate::cpu::near::OWN_CELL_MARGIN as f64),
        ("src/ao/hao_trace.wgsl", "NEAR_VOXEL_STEPS", crate::cpu::near::NEAR_VOXEL_STEPS as f64),
    ];
    for (path, name, rust) in pairs {
        let wgsl = wgsl_const(path, name);
        // f32 constants compared at f32 precision.
        assert!((wgsl - rust).abs() <= rust.abs() * 1.0e-7, "{path}: {name} is {wgsl} in WGSL, {rust} in Rust");
    }
    // The classify and expand entry points run VOXELIZE_WORKGROUP invocations a workgroup (the dispatches
    // are sized by it).
    let mut composer = composer();
    for path in ["src/voxel/voxelize_classify.wgsl", "src/voxel/voxelize_expand.wgsl"] {
        let module = composer
            .make_naga_module(NagaModuleDescriptor {
                source: &read(path),
                file_path: path,
                shader_type: ShaderType::Wgsl,
                shader_defs: shared_defs(),
                ..Default::default()
            })
            .unwrap_or_else(|e| panic!("{path}: {e:?}"));
        for entry in &module.entry_points {
            let size = entry.workgroup_size;
            assert_eq!(size, [pipelines::VOXELIZE_WORKGROUP, 1, 1], "{path}: {}", entry.name);
        }
    }
}
