//! Main world: the voxel grid's GPU assets, created and replaced as the [`VoxelVolume`] asks, and the
//! camera the cascades follow.

use super::pipelines::ATTRIBUTE_FORMATS;
use crate::cpu::attributes::SAMPLE_WORDS;
use crate::cpu::{self, VoxelGrid};
use crate::voxel::components::*;
use bevy::asset::RenderAssetUsages;
use bevy::camera::primitives::Aabb;
use bevy::image::ImageSampler;
use bevy::prelude::*;
use bevy::render::gpu_readback::Readback;
use bevy::render::render_resource::{Extent3d, TextureDescriptor, TextureDimension, TextureFormat, TextureUsages};
use bevy::render::renderer::{RenderAdapter, RenderDevice};
use bevy::render::storage::ShaderBuffer;

use super::changes::{OccluderChanges, world_aabb};
use super::stats::{CascadeLevelStats, LevelBytes, VoxelizationStats, read_voxelize_counters};
use crate::ao::HybridAmbientOcclusion;

/// Mip levels of the voxel texture at most (level `l` covers `2^l` cells per axis per texel).
pub const MAX_VOXEL_MIPS: u32 = 5;

/// The GPU side of the current voxel grid: handles to the buffers the voxelization passes write and the 3D
/// texture the sampling passes read. Present in the main world (and mirrored in the render world) while a
/// valid grid exists.
///
/// All buffers hold the grid in linear order `x + dims.x * (y + dims.y * z)`; occupancy is bit-packed,
/// 32 voxels per `u32` word. Read them back with Bevy's `Readback::buffer`.
#[derive(Resource, Clone, Debug)]
pub struct VoxelGridAssets {
    /// The grid of one level: for a single grid, the grid itself; for cascades, the storage of one cascade
    /// (origin at the lattice's, half a finest cell below the world origin, the finest cell size, `cells^3`
    /// dimensions). The buffers hold
    /// [`Self::levels`] such grids one after the other; a cascade level is stored toroidally (lattice cell `c`
    /// of its window at `c mod cells`).
    pub grid: VoxelGrid,
    /// Levels: 1 for a single grid, the cascade count for cascades.
    pub levels: u32,
    /// The cascades' shape, if the volume follows the camera.
    pub cascades: Option<cpu::CascadeShape>,
    /// Gamma and injection mode.
    pub settings: cpu::VoxelizeSettings,
    /// Most points per frame.
    pub point_budget: u32,
    /// Most triangles of added static occluders voxelized per frame ([`VoxelVolume::stream_budget`]).
    pub stream_budget: u32,
    /// This frame's occupancy: the static grid plus this frame's dynamic geometry.
    pub occupancy: Handle<ShaderBuffer>,
    /// The cached occupancy of static geometry alone.
    pub static_occupancy: Handle<ShaderBuffer>,
    /// This frame's per-voxel records, if kept: [`Self::sample_words`] `u32`s per voxel, the point count and,
    /// with attributes, the albedo and normal sums ([`crate::cpu::attributes`]).
    pub point_counts: Option<Handle<ShaderBuffer>>,
    /// The static geometry's records, if kept.
    pub static_point_counts: Option<Handle<ShaderBuffer>>,
    /// Words per voxel in the record buffers: 0 (none), 1 (point counts) or
    /// [`crate::cpu::attributes::SAMPLE_WORDS`] (counts and attribute sums).
    pub sample_words: u32,
    /// The average albedo (`Rgba8Unorm`) and normal (`Rgba8Snorm`) textures of multi-valued voxels
    /// ([`VoxelVolume::attributes`]), mip 0 only, laid out as [`Self::texture`]'s mip 0.
    pub attributes: Option<[Handle<Image>; 2]>,
    /// The voxel texture: 1 where occupied, 0 where empty, with a max-reduced mip chain.
    pub texture: Handle<Image>,
    /// Its format (`R8Unorm` where the adapter can write it from a shader, else `R32Float`).
    pub texture_format: TextureFormat,
    /// Its mip level count.
    pub mip_levels: u32,
    /// The size of one level in it: the grid's dimensions rounded up to a multiple of `2^(mip_levels - 1)`,
    /// so that every mip texel covers exactly `2^level` cells per axis (the padding is empty). Levels are
    /// stacked along z: level `l` starts at texel `z = l * texture_size.z`.
    pub texture_size: UVec3,
    /// The voxelization statistics counters (see [`crate::VoxelizeCounters`]).
    pub counters: Handle<ShaderBuffer>,
    /// Bumped whenever the assets are replaced (the render world then rebuilds the static grid).
    pub generation: u64,
}

/// Set by the rooms above the voxel grid that read its attributes (voxel GI): while `true`, the grid keeps
/// them as if [`VoxelVolume::attributes`] were on.
#[derive(Resource, Clone, Copy, Default, Debug, PartialEq, Eq)]
pub struct AttributesWanted(pub bool);

/// The world position the cascades are centred on this frame (the camera's), or `None`.
#[derive(Resource, Clone, Copy, Default, Debug, PartialEq)]
pub struct VoxelVolumeFocus(pub Option<Vec3>);

/// The texture format of the voxel texture on this adapter: `R8Unorm` if shaders can write it, else
/// `R32Float` (a WebGPU core storage format).
pub fn voxel_texture_format(adapter: &RenderAdapter) -> TextureFormat {
    if adapter
        .get_texture_format_features(TextureFormat::R8Unorm)
        .allowed_usages
        .contains(TextureUsages::STORAGE_BINDING)
    {
        TextureFormat::R8Unorm
    } else {
        TextureFormat::R32Float
    }
}

/// Remembers which configuration an error was reported for, so each is reported once.
#[derive(Default)]
pub(crate) struct ReportedVolume(Option<String>);

/// The entity whose `Readback` brings the counters back.
#[derive(Component)]
pub(crate) struct VoxelCountersReadback;

/// The camera the cascades follow: the active camera with [`HybridAmbientOcclusion`] of lowest order
/// (ties: lowest entity). Warns once when there are several.
pub(crate) fn update_voxel_focus(
    cameras: Query<(Entity, &Camera, &GlobalTransform), With<HybridAmbientOcclusion>>,
    mut focus: ResMut<VoxelVolumeFocus>,
    mut warned: Local<bool>,
) {
    let mut active: Vec<_> = cameras.iter().filter(|(_, c, _)| c.is_active).collect();
    active.sort_by_key(|(e, c, _)| (c.order, *e));
    if active.len() > 1 && !*warned {
        warn!(
            "bevy_hao: {} cameras have HybridAmbientOcclusion; the voxel cascades follow {} (lowest Camera::order), \
             and the others trace into the same cascades",
            active.len(),
            active[0].0
        );
        *warned = true;
    }
    let p = active.first().map(|(_, _, t)| t.translation()).filter(|p| p.is_finite());
    if focus.0 != p {
        focus.0 = p;
    }
}

/// Computes the grid the [`VoxelVolume`] asks for, checks it against the device's limits, and replaces the
/// [`VoxelGridAssets`] when it changed.
#[allow(clippy::too_many_arguments)]
pub(crate) fn update_voxel_volume(
    mut commands: Commands,
    volumes: Query<&VoxelVolume>,
    occluders: Query<(&GlobalTransform, &Aabb)>,
    changes: Res<OccluderChanges>,
    mut fitted: Local<Option<(u64, Option<(Vec3, Vec3)>)>>,
    mut current: Option<ResMut<VoxelGridAssets>>,
    device: Option<Res<RenderDevice>>,
    adapter: Option<Res<RenderAdapter>>,
    mut buffers: ResMut<Assets<ShaderBuffer>>,
    mut images: ResMut<Assets<Image>>,
    readbacks: Query<Entity, With<VoxelCountersReadback>>,
    stats: Res<VoxelizationStats>,
    (gamma_for_target, wanted): (Res<super::calibration::GammaForTarget>, Res<AttributesWanted>),
    mut reported: Local<ReportedVolume>,
    mut warned: Local<bevy::platform::collections::HashSet<String>>,
    mut generation: Local<u64>,
) {
    let _span = stats.cpu_span(|t| &mut t.update_volume);
    let (Some(device), Some(adapter)) = (device, adapter) else { return };
    let mut iter = volumes.iter();
    let given = iter.next().copied().unwrap_or_default();
    if iter.next().is_some() && reported.0.as_deref() != Some("several") {
        warn!("bevy_hao: more than one VoxelVolume; using the first");
        reported.0 = Some("several".into());
    }
    // Invalid values are replaced, each reported once.
    let (volume, fixes) = given.sanitized();
    for f in fixes {
        if warned.insert(f.clone()) {
            warn!("bevy_hao: {f}");
        }
    }
    let remove = |commands: &mut Commands| {
        if current.is_some() {
            commands.remove_resource::<VoxelGridAssets>();
            stats.update(|s| {
                s.grid = None;
                s.cascades.clear();
            });
        }
        for e in &readbacks {
            commands.entity(e).despawn();
        }
    };
    let shape = volume.cascade_shape();
    let (grid, levels, mip_levels) = if let Some(shape) = shape {
        let grid = shape.validate().and_then(|_| {
            VoxelGrid::new(shape.lattice_origin(), shape.finest_cell_size, UVec3::splat(shape.cells))
                .map_err(cpu::CascadeError::Grid)
        });
        match grid {
            Ok(g) => (g, shape.levels, cpu::cascade::CASCADE_MIP_LEVELS),
            Err(e) => {
                report(
                    &mut reported,
                    format!("bevy_hao: the voxel cascades are invalid ({e}); voxel occlusion is off"),
                );
                remove(&mut commands);
                return;
            }
        }
    } else {
        let bounds = match volume.bounds {
            VolumeBounds::World { min, max } => Some((min, max)),
            VolumeBounds::FitStaticScene { margin } => {
                // The static set's bounds, summed again only when it changed.
                let bounds = match *fitted {
                    Some((version, bounds)) if version == changes.static_version => bounds,
                    _ => {
                        let bounds = static_bounds(&changes, &occluders, &mut warned);
                        *fitted = Some((changes.static_version, bounds));
                        bounds
                    }
                };
                bounds.map(|(lo, hi)| (lo - Vec3::splat(margin.max(0.0)), hi + Vec3::splat(margin.max(0.0))))
            }
            VolumeBounds::FollowCamera { .. } => unreachable!("handled above"),
        };
        let Some((min, max)) = bounds else {
            // Nothing static to fit to yet.
            remove(&mut commands);
            return;
        };
        match volume.grid_for_bounds(min, max) {
            Ok(g) => (g, 1, (32 - g.dims.max_element().leading_zeros()).clamp(1, MAX_VOXEL_MIPS)),
            Err(e) => {
                report(&mut reported, format!("bevy_hao: the voxel volume is invalid ({e}); voxel occlusion is off"));
                remove(&mut commands);
                return;
            }
        }
    };
    let limits = device.limits();
    let align = 1u32 << (mip_levels - 1);
    let texture_size = (grid.dims + UVec3::splat(align - 1)) / align * align;
    let level_words = grid.occupancy_word_count() as u64;
    let words_bytes = level_words * 4 * levels as u64;
    let voxel_bytes = grid.voxel_count() * 4 * levels as u64;
    let binding_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    let refusal = if texture_size.max_element().max(texture_size.z * levels) > limits.max_texture_dimension_3d {
        Some(format!(
            "{levels} voxel grid level(s) of {}x{}x{} exceed the device's Limits::max_texture_dimension_3d ({})",
            grid.dims.x, grid.dims.y, grid.dims.z, limits.max_texture_dimension_3d
        ))
    } else if words_bytes > binding_limit {
        Some(format!(
            "{levels} voxel grid level(s) of {}x{}x{} need {words_bytes} bytes of occupancy bits, over the device's \
             Limits::max_storage_buffer_binding_size ({})",
            grid.dims.x, grid.dims.y, grid.dims.z, limits.max_storage_buffer_binding_size
        ))
    } else if shape.is_some() && !grid.voxel_count().is_multiple_of(32) {
        Some("cascade levels must hold a multiple of 32 voxels".to_string())
    } else {
        None
    };
    if let Some(msg) = refusal {
        report(
            &mut reported,
            format!("bevy_hao: {msg}; lower VoxelVolume's resolution or cascades. Voxel occlusion is off"),
        );
        remove(&mut commands);
        return;
    }
    let mut attributes = volume.attributes || wanted.0;
    let attribute_bytes = voxel_bytes * SAMPLE_WORDS as u64;
    // Fallbacks, not refusals: warned once each (the grid is still built).
    let mut fallback = |msg: String| {
        if warned.insert(msg.clone()) {
            warn!("{msg}");
        }
    };
    if attributes && attribute_bytes > binding_limit {
        fallback(format!(
            "bevy_hao: per-voxel albedo and normal sums for {levels} level(s) of {}x{}x{} need {attribute_bytes} \
                 bytes, over the device's Limits::max_storage_buffer_binding_size ({}); VoxelVolume::attributes is \
                 off (lower the resolution or the cascades)",
            grid.dims.x, grid.dims.y, grid.dims.z, limits.max_storage_buffer_binding_size
        ));
        attributes = false;
    }
    let mut point_counts = volume.point_counts || attributes;
    if point_counts && voxel_bytes > binding_limit {
        fallback(format!(
            "bevy_hao: per-voxel point counts for {levels} level(s) of {}x{}x{} need {voxel_bytes} bytes, over the \
                 device's Limits::max_storage_buffer_binding_size ({}); point counts are off",
            grid.dims.x, grid.dims.y, grid.dims.z, limits.max_storage_buffer_binding_size
        ));
        point_counts = false;
    }
    let sample_words = if attributes { SAMPLE_WORDS } else { point_counts as u32 };
    let counts_bytes = voxel_bytes * sample_words as u64;
    let mut settings = volume.voxelize_settings();
    // A target bias sets gamma once it has been measured (until then, `gamma` is used).
    if let (Some(_), Some(gamma)) = (volume.target_bias, gamma_for_target.gamma) {
        settings.gamma = gamma;
    }
    let texture_format = voxel_texture_format(&adapter);
    if let Some(cur) = &mut current
        && cur.grid == grid
        && cur.levels == levels
        && cur.cascades == shape
        && cur.sample_words == sample_words
        && cur.settings == settings
        && cur.point_budget == volume.point_budget
        && cur.texture_format == texture_format
    {
        // The streaming budget changes no voxel: the same grid, with the new budget.
        if cur.stream_budget != volume.stream_budget {
            cur.stream_budget = volume.stream_budget;
        }
        return;
    }
    *generation += 1;
    let buffer = |bytes: u64, buffers: &mut Assets<ShaderBuffer>| {
        buffers.add(ShaderBuffer::with_size(bytes.max(4) as usize, RenderAssetUsages::RENDER_WORLD))
    };
    // The voxel texture and the attribute textures share the layout: levels stacked along z.
    let image = |label: &'static str, format: TextureFormat, mips: u32, sampler: ImageSampler| Image {
        data: None,
        texture_descriptor: TextureDescriptor {
            label: Some(label),
            size: Extent3d {
                width: texture_size.x,
                height: texture_size.y,
                depth_or_array_layers: texture_size.z * levels,
            },
            mip_level_count: mips,
            sample_count: 1,
            dimension: TextureDimension::D3,
            format,
            usage: TextureUsages::TEXTURE_BINDING | TextureUsages::STORAGE_BINDING | TextureUsages::COPY_SRC,
            view_formats: &[],
        },
        sampler,
        asset_usage: RenderAssetUsages::RENDER_WORLD,
        ..default()
    };
    let texture = image("hao_voxel_texture", texture_format, mip_levels, ImageSampler::linear());
    let attribute_textures = attributes
        .then(|| ATTRIBUTE_FORMATS.map(|f| images.add(image("hao_voxel_attributes", f, 1, ImageSampler::nearest()))));
    let assets = VoxelGridAssets {
        grid,
        levels,
        cascades: shape,
        settings,
        point_budget: volume.point_budget,
        stream_budget: volume.stream_budget,
        occupancy: buffer(words_bytes, &mut buffers),
        static_occupancy: buffer(words_bytes, &mut buffers),
        point_counts: point_counts.then(|| buffer(counts_bytes, &mut buffers)),
        static_point_counts: point_counts.then(|| buffer(counts_bytes, &mut buffers)),
        sample_words,
        attributes: attribute_textures,
        texture: images.add(texture),
        texture_format,
        mip_levels,
        texture_size,
        counters: buffer(super::stats::counter_words(levels) as u64 * 4, &mut buffers),
        generation: *generation,
    };
    for e in &readbacks {
        commands.entity(e).despawn();
    }
    commands
        .spawn((
            Readback::buffer(assets.counters.clone()),
            VoxelCountersReadback,
            Name::new("hao voxel counters readback"),
        ))
        .observe(read_voxelize_counters);
    let texel_bytes = texture_format.block_copy_size(None).unwrap_or(4) as u64;
    let level_texels: u64 = (0..mip_levels).map(|m| (texture_size >> m).as_u64vec3().element_product()).sum();
    let bytes = LevelBytes {
        occupancy: 2 * level_words * 4,
        texture: level_texels * texel_bytes,
        point_counts: 2 * grid.voxel_count() * 4 * sample_words as u64,
        attributes: if attributes { (texture_size.as_u64vec3().element_product()) * 8 } else { 0 },
    };
    stats.update(|s| {
        s.grid = Some(grid);
        s.cascades = (0..levels)
            .map(|l| CascadeLevelStats {
                origin: grid.origin,
                cell_size: shape.map_or(grid.cell_size, |c| c.cell_size(l)),
                bytes,
                ..default()
            })
            .collect();
    });
    debug!(
        "bevy_hao: voxel grid {levels} x {}x{}x{}, cell {} at {}",
        grid.dims.x, grid.dims.y, grid.dims.z, grid.cell_size, grid.origin
    );
    commands.insert_resource(assets);
    reported.0 = None;
}

fn report(reported: &mut ReportedVolume, msg: String) {
    if reported.0.as_deref() != Some(msg.as_str()) {
        error!("{msg}");
        reported.0 = Some(msg);
    }
}

/// The union of the static occluders' world bounds (those with non-finite bounds left out, with a warning).
fn static_bounds(
    changes: &OccluderChanges,
    occluders: &Query<(&GlobalTransform, &Aabb)>,
    warned: &mut bevy::platform::collections::HashSet<String>,
) -> Option<(Vec3, Vec3)> {
    let mut acc: Option<(Vec3, Vec3)> = None;
    let mut non_finite = 0;
    for (transform, aabb) in changes.static_entities().filter_map(|e| occluders.get(e).ok()) {
        let (lo, hi) = world_aabb(aabb, transform);
        if !(lo.is_finite() && hi.is_finite()) {
            // A NaN or infinite vertex: leave it out rather than lose the whole grid.
            non_finite += 1;
            continue;
        }
        acc = Some(acc.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
    }
    if non_finite > 0 {
        let msg = format!(
            "bevy_hao: {non_finite} static occluder(s) have non-finite bounds (NaN or infinite vertices) and are \
             left out when fitting the voxel grid"
        );
        if warned.insert(msg.clone()) {
            warn!("{msg}");
        }
    }
    acc
}
