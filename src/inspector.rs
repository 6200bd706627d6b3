//! An egui inspector for bevy_hao (cargo feature `inspector`): every [`HybridAmbientOcclusion`],
//! [`VoxelVolume`] and [`VoxelGlobalIllumination`] setting live, AO off / HAO / Bevy's SSAO / both, the debug views ([`HaoDebugView`]),
//! per-pass GPU times from Bevy's render diagnostics, and voxel and point counts.
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy_hao::prelude::*;
//! App::new()
//!     .add_plugins((DefaultPlugins, HaoPlugin, bevy_hao::inspector::HaoInspectorPlugin))
//!     .run();
//! ```
//!
//! It inspects the first camera with a [`HybridAmbientOcclusion`], Bevy's `ScreenSpaceAmbientOcclusion` or
//! an [`HaoInspected`] marker.

use crate::ao::{HaoQuality, HybridAmbientOcclusion};
use crate::debug::HaoDebugView;
use crate::gi::VoxelGlobalIllumination;
use crate::voxel::components::{VolumeResolution, VoxelInjection, VoxelSubdivision, VoxelVolume};
use crate::voxel::{VoxelGridAssets, VoxelizationStats};
use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
use bevy::pbr::{ScreenSpaceAmbientOcclusion, ScreenSpaceAmbientOcclusionQualityLevel};
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};

/// Adds the inspector window (and `EguiPlugin` and Bevy's `RenderDiagnosticsPlugin` if they are missing).
#[derive(Default)]
pub struct HaoInspectorPlugin;

impl Plugin for HaoInspectorPlugin {
    fn build(&self, app: &mut App) {
        if !app.is_plugin_added::<EguiPlugin>() {
            app.add_plugins(EguiPlugin::default());
        }
        if !app.is_plugin_added::<bevy::render::diagnostic::RenderDiagnosticsPlugin>() {
            app.add_plugins(bevy::render::diagnostic::RenderDiagnosticsPlugin);
        }
        app.init_resource::<VoxelCount>()
            .add_systems(Update, count_voxels)
            .add_systems(EguiPrimaryContextPass, inspector_window);
    }
}

/// Marks the camera the inspector edits (otherwise the first camera with HAO or SSAO).
#[derive(Component, Default, Clone, Copy, Debug)]
pub struct HaoInspected;

/// The voxels set in the frame's grid, counted from a readback every second.
#[derive(Resource, Default, Clone, Copy, Debug)]
pub struct VoxelCount {
    /// Set voxels, once counted.
    pub voxels: Option<u64>,
    timer: f32,
}

#[derive(Component)]
struct VoxelCountReadback;

fn count_voxels(
    mut commands: Commands,
    time: Res<Time>,
    mut count: ResMut<VoxelCount>,
    assets: Option<Res<VoxelGridAssets>>,
    pending: Query<Entity, With<VoxelCountReadback>>,
) {
    count.timer -= time.delta_secs();
    let Some(assets) = assets else {
        count.voxels = None;
        return;
    };
    if count.timer > 0.0 || !pending.is_empty() {
        return;
    }
    count.timer = 1.0;
    commands.spawn((Readback::buffer(assets.occupancy.clone()), VoxelCountReadback)).observe(
        |event: On<ReadbackComplete>, mut count: ResMut<VoxelCount>, mut commands: Commands| {
            count.voxels = Some(
                event
                    .data
                    .chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]).count_ones() as u64)
                    .sum(),
            );
            commands.entity(event.entity).despawn();
        },
    );
}

/// Which ambient occlusion the inspected camera renders.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum AoMode {
    Off,
    Hao,
    Ssao,
    Both,
}

/// A pass's smoothed GPU time, or `None` if it has not run in the last second (a diagnostic keeps its last
/// value when its pass stops: the static voxelization between rebuilds, Bevy's SSAO where HAO replaces it).
fn gpu_ms(store: &DiagnosticsStore, span: &str) -> Option<f64> {
    let d = store.get(&DiagnosticPath::new(format!("render/{span}/elapsed_gpu")))?;
    (d.measurement()?.time.elapsed() < std::time::Duration::from_secs(1)).then(|| d.smoothed()).flatten()
}

#[allow(clippy::too_many_arguments)]
fn inspector_window(
    mut contexts: EguiContexts,
    mut commands: Commands,
    mut cameras: Query<
        (
            Entity,
            Option<&mut HybridAmbientOcclusion>,
            Option<&ScreenSpaceAmbientOcclusion>,
            Option<&HaoDebugView>,
            Has<HaoInspected>,
            Option<&mut VoxelGlobalIllumination>,
        ),
        With<Camera3d>,
    >,
    mut volumes: Query<(Entity, &mut VoxelVolume)>,
    assets: Option<Res<VoxelGridAssets>>,
    stats: Res<VoxelizationStats>,
    count: Res<VoxelCount>,
    store: Res<DiagnosticsStore>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let mut chosen = None;
    for (entity, hao, ssao, _, marked, _) in &cameras {
        if marked || (chosen.is_none() && (hao.is_some() || ssao.is_some())) {
            chosen = Some(entity);
        }
    }
    egui::Window::new("Hybrid ambient occlusion").default_width(300.0).show(ctx, |ui| {
        let Some(camera) = chosen.or_else(|| cameras.iter().next().map(|c| c.0)) else {
            ui.label("no 3D camera");
            return;
        };
        let Ok((_, mut hao, ssao, view, _, mut gi)) = cameras.get_mut(camera) else { return };
        let mode = match (&hao, ssao) {
            (Some(h), _) if h.near_field => AoMode::Both,
            (Some(_), _) => AoMode::Hao,
            (None, Some(_)) => AoMode::Ssao,
            (None, None) => AoMode::Off,
        };
        let mut new_mode = mode;
        ui.horizontal(|ui| {
            ui.label("AO");
            ui.selectable_value(&mut new_mode, AoMode::Off, "off");
            ui.selectable_value(&mut new_mode, AoMode::Hao, "HAO");
            ui.selectable_value(&mut new_mode, AoMode::Ssao, "SSAO");
            ui.selectable_value(&mut new_mode, AoMode::Both, "both");
        });
        if new_mode != mode {
            let mut e = commands.entity(camera);
            let settings = hao.as_deref().cloned().unwrap_or_default();
            match new_mode {
                AoMode::Off => {
                    e.remove::<(HybridAmbientOcclusion, ScreenSpaceAmbientOcclusion)>();
                }
                AoMode::Hao => {
                    e.insert(HybridAmbientOcclusion { near_field: false, ..settings });
                }
                // Bevy's SSAO, alone or as HAO's near field, needs MSAA off; the SSAO of this mode is the
                // user's, not HAO's (which would take it away with HAO).
                AoMode::Ssao => {
                    e.remove::<(HybridAmbientOcclusion, crate::ao::HaoAddedSsao)>()
                        .insert((ScreenSpaceAmbientOcclusion::default(), Msaa::Off));
                }
                AoMode::Both => {
                    e.insert((HybridAmbientOcclusion { near_field: true, ..settings }, Msaa::Off));
                }
            }
        }
        let current_view = view.copied().unwrap_or_default();
        let mut new_view = current_view;
        egui::ComboBox::from_label("view").selected_text(format!("{current_view:?}")).show_ui(ui, |ui| {
            for v in HaoDebugView::ALL {
                ui.selectable_value(&mut new_view, v, format!("{v:?}"));
            }
        });
        if new_view != current_view {
            commands.entity(camera).insert(new_view);
        }

        if let Some(hao) = hao.as_deref_mut() {
            ui.separator();
            ui.heading("HAO");
            let (rays, steps, half) = hao.trace_parameters();
            egui::ComboBox::from_label("quality")
                .selected_text(format!(
                    "{:?} ({rays} rays x {steps} steps{})",
                    hao.quality,
                    match (half, hao.uses_checkerboard()) {
                        (true, true) => ", half res, checkerboard",
                        (true, false) => ", half res",
                        _ => "",
                    }
                ))
                .show_ui(ui, |ui| {
                    for q in [HaoQuality::Low, HaoQuality::Medium, HaoQuality::High, HaoQuality::Ultra] {
                        ui.selectable_value(&mut hao.quality, q, format!("{q:?}"));
                    }
                });
            ui.add(egui::Slider::new(&mut hao.max_distance, 0.1..=20.0).text("max distance"));
            ui.add(egui::Slider::new(&mut hao.falloff, 0.0..=4.0).text("falloff"));
            ui.add(egui::Slider::new(&mut hao.intensity, 0.0..=3.0).text("intensity"));
            ui.add(egui::Slider::new(&mut hao.start_offset, 0.0..=3.0).text("start offset (voxels)"));
            ui.checkbox(&mut hao.depth_contacts, "contacts from the depth prepass");
            let preset = if hao.quality.passes_free_space() { "the preset's: on" } else { "the preset's: off" };
            let label = |v: Option<bool>| match v {
                None => preset,
                Some(true) => "on",
                Some(false) => "off",
            };
            egui::ComboBox::from_label("free space from the depth prepass")
                .selected_text(label(hao.depth_free_space))
                .show_ui(ui, |ui| {
                    for v in [None, Some(true), Some(false)] {
                        ui.selectable_value(&mut hao.depth_free_space, v, label(v));
                    }
                });
            ui.add(egui::Slider::new(&mut hao.denoise_radius, 0..=6).text("denoise width"));
            if hao.near_field {
                egui::ComboBox::from_label("near field (SSAO)")
                    .selected_text(format!("{:?}", hao.near_field_quality))
                    .show_ui(ui, |ui| {
                        use ScreenSpaceAmbientOcclusionQualityLevel as Q;
                        for q in [Q::Low, Q::Medium, Q::High, Q::Ultra] {
                            ui.selectable_value(&mut hao.near_field_quality, q, format!("{q:?}"));
                        }
                    });
            }
        }

        ui.separator();
        ui.heading("Voxel global illumination");
        let mut on = gi.is_some();
        if ui.checkbox(&mut on, "indirect light from the voxels").changed() {
            if on {
                commands.entity(camera).insert(VoxelGlobalIllumination::default());
            } else {
                commands.entity(camera).remove::<VoxelGlobalIllumination>();
            }
        }
        if let Some(gi) = gi.as_deref_mut() {
            ui.add(egui::Slider::new(&mut gi.intensity, 0.0..=4.0).text("intensity"));
            ui.add(egui::Slider::new(&mut gi.probe_spacing, 0.1..=4.0).logarithmic(true).text("probe spacing"));
            ui.add(egui::Slider::new(&mut gi.rays, 1..=256).logarithmic(true).text("rays a probe"));
            ui.add(egui::Slider::new(&mut gi.probe_frames, 1..=16).text("frames to update every probe"));
            ui.add(egui::Slider::new(&mut gi.accumulation_frames, 1..=64).text("updates a probe averages"));
            ui.add(egui::Slider::new(&mut gi.lighting_frames, 1..=16).text("frames to light every voxel"));
            ui.add(egui::Slider::new(&mut gi.bounce_feedback, 0.0..=1.0).text("bounce feedback (0: one bounce)"));
            let c = gi.probe_counts;
            ui.label(format!(
                "{}x{}x{} probes, {:.1} x {:.1} x {:.1} m around the camera",
                c.x,
                c.y,
                c.z,
                c.x as f32 * gi.probe_spacing,
                c.y as f32 * gi.probe_spacing,
                c.z as f32 * gi.probe_spacing
            ));
            ui.add(egui::Slider::new(&mut gi.far_spacing, 0..=16).text("far probes' spacing (in spacings; 0: off)"));
            if gi.far_spacing > 0 {
                let (c, s) = (gi.far_probe_counts, gi.probe_spacing * gi.far_spacing.max(2) as f32);
                ui.label(format!(
                    "{}x{}x{} far probes, {:.1} x {:.1} x {:.1} m",
                    c.x,
                    c.y,
                    c.z,
                    c.x as f32 * s,
                    c.y as f32 * s,
                    c.z as f32 * s
                ));
            }
        }

        ui.separator();
        ui.heading("Voxel volume");
        match volumes.iter_mut().next() {
            Some((_, mut volume)) => {
                let mut follow = matches!(volume.bounds, crate::voxel::components::VolumeBounds::FollowCamera { .. });
                if ui.checkbox(&mut follow, "cascades follow the camera").changed() {
                    volume.bounds = if follow {
                        crate::voxel::components::VolumeBounds::default()
                    } else {
                        crate::voxel::components::VolumeBounds::FitStaticScene { margin: 0.5 }
                    };
                }
                if let crate::voxel::components::VolumeBounds::FollowCamera { cascades, cells, finest_cell_size } =
                    &mut volume.bounds
                {
                    let mut c = *cascades;
                    if ui.add(egui::Slider::new(&mut c, 1..=8).text("cascades")).changed() {
                        *cascades = c;
                    }
                    let mut n = *cells / 8;
                    if ui.add(egui::Slider::new(&mut n, 2..=32).text("cells per axis / 8")).changed() {
                        *cells = n * 8;
                    }
                    let mut size = *finest_cell_size;
                    if ui
                        .add(egui::Slider::new(&mut size, 0.01..=2.0).logarithmic(true).text("finest cell size"))
                        .changed()
                    {
                        *finest_cell_size = size;
                    }
                } else {
                    let mut cells = match volume.resolution {
                        VolumeResolution::Cells(n) => n,
                        VolumeResolution::CellSize(_) => assets.as_ref().map_or(128, |a| a.grid.dims.max_element()),
                    };
                    if ui.add(egui::Slider::new(&mut cells, 16..=512).text("cells (longest axis)")).changed() {
                        volume.resolution = VolumeResolution::Cells(cells);
                    }
                }
                // Gamma by hand, or chosen for a target bias (equation 3).
                let mut by_target = volume.target_bias.is_some();
                if ui.checkbox(&mut by_target, "gamma for a target bias").changed() {
                    volume.target_bias = by_target.then_some(0.02);
                }
                match &mut volume.target_bias {
                    Some(p) => {
                        ui.add(egui::Slider::new(p, 0.002..=0.2).logarithmic(true).text("target bias"));
                        match stats.get().gamma_for_target {
                            Some((_, g)) => ui.label(format!("gamma {g:.2}, measured on the static occluders")),
                            None => ui.label("gamma: not measured yet"),
                        };
                    }
                    None => {
                        ui.add(egui::Slider::new(&mut volume.gamma, 0.25..=8.0).logarithmic(true).text("gamma"));
                    }
                }
                ui.horizontal(|ui| {
                    ui.selectable_value(&mut volume.injection, VoxelInjection::Centroid, "centroid");
                    ui.selectable_value(&mut volume.injection, VoxelInjection::Conservative, "conservative");
                });
                ui.horizontal(|ui| {
                    ui.selectable_value(&mut volume.subdivision, VoxelSubdivision::Strips, "strips");
                    ui.selectable_value(&mut volume.subdivision, VoxelSubdivision::Uniform, "uniform");
                });
                let mut budget_m = volume.point_budget as f64 / (1 << 20) as f64;
                if ui
                    .add(egui::Slider::new(&mut budget_m, 0.25..=512.0).logarithmic(true).text("point budget (Mi)"))
                    .changed()
                {
                    volume.point_budget = (budget_m * (1 << 20) as f64) as u32;
                }
                ui.checkbox(&mut volume.point_counts, "per-voxel point counts");
                ui.checkbox(&mut volume.attributes, "per-voxel albedo and normal");
            }
            None => {
                ui.label("default volume (4 cascades of 192^3 following the camera)");
                if ui.button("add a VoxelVolume to edit").clicked() {
                    commands.spawn(VoxelVolume::default());
                }
            }
        }
        let s = stats.get();
        match &s.grid {
            Some(g) => {
                ui.label(format!("grid {}x{}x{}, cell {:.3}", g.dims.x, g.dims.y, g.dims.z, g.cell_size));
            }
            None => {
                ui.label("no voxel grid");
            }
        }
        for (l, c) in s.cascades.iter().enumerate() {
            ui.label(format!(
                "level {l}: cell {:.3}, window at {}, {} cells voxelized last frame, {} scrolls, {} rebuilds, {:.1} MB",
                c.cell_size,
                c.window_min,
                c.static_cells_last_frame,
                c.scrolls,
                c.rebuilds,
                c.bytes.total() as f64 / 1.0e6
            ));
        }
        if let Some(v) = count.voxels {
            ui.label(format!("voxels set: {v}"));
        }
        ui.label(format!(
            "static: {} instances, {} triangles; rebuilt {} times",
            s.static_instances, s.static_triangles, s.static_rebuilds
        ));
        ui.label(format!(
            "points: static {} ({} triangles queued), dynamic {} ({} instances)",
            s.static_counters.injected,
            s.static_counters.big_triangles,
            s.dynamic_counters.injected,
            s.dynamic_instances
        ));
        ui.label(format!(
            "estimated points: static {} points, dynamic {} per frame (budget {})",
            s.estimated_static_points,
            s.estimated_dynamic_points,
            assets.as_ref().map_or(0, |a| a.point_budget)
        ));
        if s.skipped_instances > 0 {
            ui.label(format!("{} occluders skipped (see the log)", s.skipped_instances));
        }

        ui.separator();
        ui.heading("GPU time (ms)");
        egui::Grid::new("hao_gpu_times").show(ui, |ui| {
            for span in [
                "hao/voxelize_static",
                "hao/voxelize_dynamic",
                "hao/resolve",
                "hao/trace",
                "hao/neighborhood",
                "hao/temporal",
                "hao/apply",
                "hao/gi_lighting",
                "hao/gi_probes",
                "hao/gi_write",
                "ssao",
            ] {
                ui.label(span);
                ui.label(gpu_ms(&store, span).map_or("-".to_string(), |t| format!("{t:.3}")));
                ui.end_row();
            }
        });
        ui.label("-: not run in the last second");
    });
    Ok(())
}
