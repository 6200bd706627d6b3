// Hybrid ambient occlusion where voxels changed: how much a pixel's occlusion can have changed since last
// frame because of the occluders whose voxels changed (`voxel_grid.moved`), and how much history that leaves
// it. The temporal pass caps the history with it; the trace traces more rays where the cap is short.
// CPU twin: `bevy_hao::cpu::temporal` (`occlusion_change`, `change_cap`). The voxel grid is bound at group 2.
#define_import_path bevy_hao::hao_change

#import bevy_hao::hao_common::{ao_falloff, current_variance, CHANGED_COUNT}
#import bevy_hao::voxel_grid::{voxel_grid, MAX_MOVED_OCCLUDERS}

// cpu/temporal.rs: CHANGE_RAYS_FROM, CHANGE_RAYS_SCALE
const CHANGE_RAYS_SCALE: u32 = 4u;
const CHANGE_RAYS_FROM: f32 = 0.002;

// cpu/temporal.rs: change_rays. The rays a trace texel traces: `rays`, or CHANGE_RAYS_SCALE times as many
// where the occlusion at its pixel can have changed by at least CHANGE_RAYS_FROM since last frame.
fn change_rays(rays: u32, change: f32) -> u32 {
    return select(rays, rays * CHANGE_RAYS_SCALE, change >= CHANGE_RAYS_FROM);
}

// cpu/temporal.rs: CHANGED_FILTER_FROM
const CHANGED_FILTER_FROM: f32 = 0.0003;

// cpu/temporal.rs: filters_wide. Whether the filter reaches wider, and the stand-in averages filtered texels,
// around a trace texel whose pixel's occlusion can have changed by `change` since last frame.
fn filters_wide(change: f32) -> bool {
    return change >= CHANGED_FILTER_FROM;
}

// cpu/temporal.rs: occlusion_change, for one occluder (`occlusion_change` sums it over `voxel_grid.moved`). How much
// the occlusion at `p` (unit normal `n`) can have changed since last frame because of an occluder in the box
// [lo, hi] that moved `motion`: a sphere of the box's mean half-extent at its centre, the share of the
// hemisphere it covers, above the horizon, weighed by the falloff at its nearest point, times the share of
// its distance it moved; a point inside the box counts it as covering its whole hemisphere.
fn moved_occlusion_change(p: vec3<f32>, n: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>, motion: f32, max_distance: f32, falloff: f32) -> f32 {
    let center = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let r = max((half.x + half.y + half.z) / 3.0, 1.0e-4);
    let d = max(length(center - p), 1.0e-4);
    let s = min(r / d, 1.0);
    let inside = all(p >= lo) && all(p <= hi);
    let above = select(clamp(dot(n, center - p) / d + s, 0.0, 1.0), 1.0, inside);
    let weight = ao_falloff(max(d - r, 0.0), max_distance, falloff);
    return s * s * above * weight * min(motion / max(d, r), 1.0);
}

// cpu/temporal.rs: change_cap. The most frames of history a pixel keeps where its occlusion can have changed
// by `change` since last frame, given its neighbourhood's window: n^3 = 2 s^2 / c^2, at least CHANGED_COUNT;
// huge where nothing changed.
fn change_cap(change: f32, window: vec2<f32>) -> f32 {
    if !(change > 0.0) {
        return 1.0e30;
    }
    return max(pow(2.0 * current_variance(window) / (change * change), 1.0 / 3.0), CHANGED_COUNT);
}

// cpu/temporal.rs: occlusion_change. How much the occlusion at `p` (unit normal `n`) can have changed since
// last frame because of the occluders that moved, at most 1.
fn occlusion_change(p: vec3<f32>, n: vec3<f32>, max_distance: f32, falloff: f32) -> f32 {
    var change = 0.0;
    for (var i = 0u; i < min(voxel_grid.moved_count, MAX_MOVED_OCCLUDERS); i++) {
        let m = voxel_grid.moved[i];
        change += moved_occlusion_change(p, n, m.min, m.max, m.motion, max_distance, falloff);
    }
    return min(change, 1.0);
}
