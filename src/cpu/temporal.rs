//! The CPU twin of HAO's temporal accumulation (`src/ao/hao_temporal.wgsl`; functions carry the names of
//! their WGSL twins in `hao_common.wgsl`).
//!
//! Each frame traces few rays per pixel with the noise rotated, and the temporal pass blends the result into
//! a history that follows the surface:
//!
//! 1. **Reprojection.** The pixel's world position goes through the previous frame's `clip_from_world` to
//!    where the surface was; the history is read there with bilinear weights. Each of the four texels is kept
//!    only if it saw the same surface ([`history_accepts`]): its view depth within 2 % (plus a hundredth of
//!    a unit) of the depth this point had in the previous view, its normal within about 25 degrees. A
//!    disocclusion, or a surface that moved (its old place holds something else), keeps no texel and starts
//!    over.
//! 2. **Rectification.** The history is clamped to the current frame's 3x3 neighbourhood, its mean plus or
//!    minus two standard deviations and [`CLAMP_MARGIN`] ([`neighborhood_window`]): the window of the
//!    trace's 3x3 texels around the pixel's ([`trace_window`]). Where an occluder has gone, every ray of the
//!    neighbourhood now escapes, the window closes around 1 and the shadow it left is clamped away in one
//!    frame. A clamped history also loses weight, the more the further it was moved ([`clamped_count`]): an
//!    occluder gone leaves it [`CLAMPED_COUNT`] frames, a window a few rays narrowed by chance several.
//!    Away from occluders that moved, the window is never narrower than what the neighbourhood's rays can
//!    tell of its mean ([`sample_interval`]): nine rays that all escaped say the AO is above 0.69, not above
//!    0.9, so a pixel of AO 0.85 keeps its history instead of being lifted into a light speck (and one in a
//!    deep shadow, whose rays all hit, is not pushed into a dark one).
//! 3. **Where occluders move**, the clamp cannot tell a shadow arriving from noise when each pixel traces
//!    one or two rays. The voxel grid lists the occluders whose voxels changed in the last few frames
//!    (dynamic ones that moved, static ones added, changed or taken out): the box around each now and last
//!    frame, and how far its points moved ([`MovedVoxels`]; unknown for a static one). From them
//!    [`occlusion_change`] estimates how much the pixel's occlusion can have changed since last frame (the
//!    occlusion of a sphere the size of the box, times the share of its distance the occluder moved), and
//!    [`change_cap`] keeps the history that balances the lag it costs against the noise it removes: a
//!    history of `n` frames lags a change of `c` a frame by about `c (n - 1) / 2`, and leaves a variance
//!    of `s^2 / n` of the current frame's `s^2`; their sum is least near `n^3 = 2 s^2 / c^2`. A pixel whose
//!    cap is under `accumulation_frames` blends every frame, its stand-in between its own traces
//!    ([`uses_stand_in`]); one whose cap is above blends only its own traces, every fourth frame at half
//!    resolution, with the cap that balances blends that far apart ([`waiting_cap`]). So next to a moving
//!    prop the history keeps [`CHANGED_COUNT`] frames and follows the shadow within a frame or two, a metre away it keeps several,
//!    and far away, or around one that stands still, all of them.
//! 4. **Filter** ([`prefilter`]): the pixel's own trace is averaged with the trace's 3x3 texels around it
//!    that show its surface, weighed by a bilateral weight (a Gaussian in distance over
//!    `HybridAmbientOcclusion::denoise_radius` texels of the trace, and the depth and normal against the
//!    traced pixel's: [`bilateral_weight`](super::denoise::bilateral_weight)); near occluders that moved,
//!    whose history is short, over 5x5 texels at twice the width ([`CHANGED_FILTER_REACH`]). The blended
//!    history is then the AO PBR reads: there is no filter after accumulation.
//! 5. **Blend** ([`temporal_blend`]): with `c` frames of history, capped at
//!    `HybridAmbientOcclusion::accumulation_frames`, the new AO is `history + (current - history) / c`: the
//!    running mean of the last frames, an exponential average once the cap is reached. Where the view
//!    stands still (the pixel's surface reprojects onto the pixel itself, within [`STILL_TOLERANCE`]), the
//!    history is read from the pixel's own texel, exactly, and the cap is
//!    `HybridAmbientOcclusion::still_accumulation_frames` ([`history_limit`]): nothing resamples that
//!    history, and the change cap (3.) shortens it near anything that moves, so a still view settles
//!    further, its frame-to-frame change falling as one over the frames kept. There a pixel shows the AO
//!    it showed last frame while its history, longer than `accumulation_frames` and out of reach of
//!    anything that moved, stays within a standard error of it ([`stable_ao`]): a still view holds still.
//!
//! The history is kept at full resolution. A half-resolution trace traces one pixel of each 2x2 block a
//! frame, each pixel in turn (`cpu::ao::traced_pixel`), so every pixel accumulates its own rays, one trace
//! every fourth frame (every eighth in a checkerboard, which traces half the blocks a frame, alternating,
//! and keeps the others' last trace: [`TraceFrame::traced`]): a frame that traced another pixel of its
//! block, or none, leaves its history as it is
//! ([`temporal_update`]). A pixel with little history (a disocclusion: under [`STAND_IN_COUNT`] frames), or
//! near voxels that may have changed, blends the traced pixels of its neighbourhood that show its surface
//! in place of its own trace ([`stand_in`]) until its own comes. `accumulation_frames` counts a pixel's own
//! traces, so at half resolution the history spans four (eight) times as many frames.

/// Added to the neighbourhood window on each side, so that a pixel whose neighbours saw no occluder this
/// frame (common with few rays where AO is near 1) keeps its history.
pub const CLAMP_MARGIN: f32 = 0.1;

/// How many standard errors [`sample_interval`] reaches around the neighbourhood's mean (WGSL: `WINDOW_Z`):
/// as many as the window's deviations.
pub const WINDOW_Z: f32 = 2.0;

use super::ao::{texel_traced, trace_turn, traced_pixel};
use super::denoise::HistoryTexel;
use glam::{IVec2, UVec2, Vec2, Vec3};

/// The most frames of weight a history holds (its texel keeps them to an eighth in 10 bits:
/// [`HistoryTexel::stored`]; WGSL: `MAX_HISTORY_FRAMES`).
pub const MAX_HISTORY_FRAMES: f32 = 127.0;

/// How far, in pixels, a pixel's surface may reproject from the pixel itself for the view to count as still
/// there ([`history_limit`]; WGSL: `STILL_TOLERANCE`): a still camera's reprojection is the identity up to
/// rounding (about 1e-4 pixels at 1920x1080), and TAA's jitter moves it by a fraction of a pixel every frame.
pub const STILL_TOLERANCE: f32 = 0.01;

/// The most frames a pixel's history keeps (WGSL: `history_limit`): `max_count`
/// (`HybridAmbientOcclusion::accumulation_frames`), or where the view stands still there (its surface
/// reprojects onto the pixel itself, within [`STILL_TOLERANCE`]) `still_count`
/// (`still_accumulation_frames`), at least `max_count` and at most [`MAX_HISTORY_FRAMES`]. Without
/// accumulation (`max_count` 1), none either way.
pub fn history_limit(max_count: f32, still_count: f32, still: bool) -> f32 {
    if still && max_count > 1.0 { still_count.min(MAX_HISTORY_FRAMES).max(max_count) } else { max_count }
}

/// The fewest frames of weight a history keeps after it was clamped ([`clamped_count`]: all it had if
/// the clamp moved it little, down to this if it moved it far).
pub const CLAMPED_COUNT: f32 = 2.0;

/// The fewest frames of weight [`change_cap`] leaves a history near voxels that changed (the most it keeps
/// where the change is largest or unknown).
pub const CHANGED_COUNT: f32 = 2.0;

/// An occluder whose voxels changed in the last few frames (WGSL: `MovedOccluder` in `voxel_grid.wgsl`):
/// the box around it now and last frame, and the farthest any of its points moved (world units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovedVoxels {
    /// The box's min corner.
    pub min: Vec3,
    /// The box's max corner.
    pub max: Vec3,
    /// How far its points moved since last frame (world units; huge where unknown).
    pub motion: f32,
}

/// How much the occlusion at a surface point (`p`, unit normal `n`) can have changed since last frame
/// because of the occluders that moved (WGSL: `occlusion_change` in `hao_change.wgsl`), with the trace's
/// `max_distance` and `falloff`. Each counts as a sphere of its box's mean half-extent `r` at the box's
/// centre, `d` away: the share of the cosine-weighted hemisphere it covers, about `(r / d)^2` times how
/// far above the horizon it stands (`n . (c - p) / d + r / d`, within [0, 1]), weighed by the falloff at
/// its nearest point, times the share of that distance it moved (`motion / max(d, r)`, at most 1). A point
/// inside the box (on the occluder itself, or under it) counts it as covering its whole hemisphere: its
/// surroundings move past it. The sum over the occluders, at most 1. Not a bound: a scale of the change,
/// 0 where nothing moved.
pub fn occlusion_change(p: Vec3, n: Vec3, moved: &[MovedVoxels], max_distance: f32, falloff: f32) -> f32 {
    let mut change = 0.0;
    for m in moved {
        let center = (m.min + m.max) * 0.5;
        let half = (m.max - m.min) * 0.5;
        let r = ((half.x + half.y + half.z) / 3.0).max(1.0e-4);
        let d = center.distance(p).max(1.0e-4);
        let s = (r / d).min(1.0);
        let inside = p.cmpge(m.min).all() && p.cmple(m.max).all();
        let above = if inside { 1.0 } else { (n.dot(center - p) / d + s).clamp(0.0, 1.0) };
        let weight = super::ao::ao_falloff((d - r).max(0.0), max_distance, falloff);
        change += s * s * above * weight * (m.motion / d.max(r)).min(1.0);
    }
    change.min(1.0)
}

/// How many times its rays a trace texel traces where the occlusion can have changed by at least
/// [`CHANGE_RAYS_FROM`] ([`change_rays`]).
pub const CHANGE_RAYS_SCALE: u32 = 4;

/// The occlusion change ([`occlusion_change`]) from which a trace texel traces [`CHANGE_RAYS_SCALE`] times
/// its rays: where [`change_cap`] leaves a history of under 11 to 22 frames (with the neighbourhood's
/// deviation), too short for a ray or two a frame to converge in.
pub const CHANGE_RAYS_FROM: f32 = 0.002;

/// The rays a trace texel traces (WGSL: `change_rays` in `hao_change.wgsl`): `rays`, or
/// [`CHANGE_RAYS_SCALE`] times as many where the occlusion at its pixel can have changed by at least
/// [`CHANGE_RAYS_FROM`] since last frame ([`occlusion_change`]). Near a moving prop the history is short,
/// and more rays there are what keeps its AO smooth; the cost follows the share of the view near movers.
pub fn change_rays(rays: u32, change: f32) -> u32 {
    if change >= CHANGE_RAYS_FROM { rays * CHANGE_RAYS_SCALE } else { rays }
}

/// The occlusion change a frame ([`occlusion_change`]) from which a trace texel is filtered wider
/// ([`filters_wide`]): where a full history of 16 frames would lag the change by more than about 0.002
/// (`c (n - 1) / 2`), the frame-to-frame change a converged view keeps. Against 0.001 it lowered the noise
/// near a rolling ball and a walking character further and the error too (docs/figures.md).
pub const CHANGED_FILTER_FROM: f32 = 0.0003;

/// Whether the filter ([`prefilter`]) reaches [`CHANGED_FILTER_REACH`] texels, and the stand-in
/// ([`stand_in`]) averages filtered texels, around a trace texel whose pixel's occlusion can have changed
/// by `change` since last frame (WGSL: `filters_wide` in `hao_change.wgsl`; the trace marks the texel:
/// [`TracedTexel::changed`]).
pub fn filters_wide(change: f32) -> bool {
    change >= CHANGED_FILTER_FROM
}

/// How many texels each side the filter ([`prefilter`]) reaches around a trace texel whose occlusion the
/// occluders that moved near it can have changed ([`TracedTexel::changed`]; WGSL: `CHANGED_FILTER_REACH` in
/// `hao_neighborhood.wgsl`), at as many times its width (`denoise_radius`); elsewhere it reaches one texel.
/// There the history is short ([`change_cap`]) and the filter is most of what keeps the AO smooth: 5x5
/// texels at twice the width average about three times as many texels' worth as 3x3. The stand-in
/// ([`stand_in`]) averages the filtered texels there.
pub const CHANGED_FILTER_REACH: i32 = 2;

/// The least deviation [`change_cap`] takes a pixel's current AO to have: a few rays are never exact.
pub const CHANGE_NOISE_FLOOR: f32 = 0.1;

/// The texels the blended current AO averages, for its variance in [`change_cap`]: the filter's 3x3 texels
/// weigh about this many.
pub const CHANGE_NOISE_SAMPLES: f32 = 4.0;

/// The most frames of history a pixel keeps where its occlusion can have changed by `change` since last
/// frame ([`occlusion_change`]; WGSL: `change_cap`), given the window of its neighbourhood's traced AO
/// ([`neighborhood_window`], whose half-width is two deviations and [`CLAMP_MARGIN`]): the `n` that
/// balances lag and noise, `n^3 = 2 s^2 / c^2` with `s^2` the variance of the blended current AO (the
/// deviation, at least [`CHANGE_NOISE_FLOOR`], squared over [`CHANGE_NOISE_SAMPLES`]), at least
/// [`CHANGED_COUNT`]. Infinite where nothing changed. For a pixel that blends only its own traces, one every
/// few frames, [`waiting_cap`] shortens it.
///
/// (The balance is a box average's: capped at `n`, the history is an exponential average of weight
/// `1 / (n + 1)`, which lags twice as far and keeps half the noise, and whose balance is half as long,
/// `n^3 = s^2 / (4 c^2)`. Measured, that halved cap lowered the error near moving props and raised their
/// frame-to-frame change above Bevy's SSAO's: the change estimated is a bound, so it is kept long.)
pub fn change_cap(change: f32, window: (f32, f32)) -> f32 {
    if !(change > 0.0) {
        return f32::INFINITY;
    }
    (2.0 * current_variance(window) / (change * change)).cbrt().max(CHANGED_COUNT)
}

/// The variance of a pixel's blended current AO (WGSL: `current_variance`), from the window of its
/// neighbourhood's traced AO ([`neighborhood_window`], whose half-width is two deviations and
/// [`CLAMP_MARGIN`]): the deviation, at least [`CHANGE_NOISE_FLOOR`], squared over
/// [`CHANGE_NOISE_SAMPLES`].
pub fn current_variance(window: (f32, f32)) -> f32 {
    let sigma = ((window.1 - window.0) * 0.25 - CLAMP_MARGIN * 0.5).max(CHANGE_NOISE_FLOOR);
    sigma * sigma / CHANGE_NOISE_SAMPLES
}

/// The most frames of weight a history keeps after the window moved it by `shift` (WGSL: `clamped_count`):
/// as many as leave its noise, the current AO's deviation over their square root ([`current_variance`]),
/// no smaller than the shift, `n = s^2 / shift^2`, at least [`CLAMPED_COUNT`]. An occluder gone (the
/// window closes around 1 and a shadow of 0.4 is clamped to 0.9) keeps [`CLAMPED_COUNT`]; the window of a
/// few rays that all escaped this frame, which moves a history of 0.88 to 0.9, keeps several frames (6 for
/// a shift of 0.02), where a reset to [`CLAMPED_COUNT`] left a light speck that took a dozen traces to fade.
pub fn clamped_count(shift: f32, window: (f32, f32)) -> f32 {
    (current_variance(window) / (shift * shift)).max(CLAMPED_COUNT)
}

/// A pixel whose history holds fewer frames than this (or than `max_count`, if lower) blends its stand-in in the
/// frames without its own trace ([`uses_stand_in`]): a new history is noisier than its neighbourhood's traces,
/// and at half resolution a pixel waits up to 4 frames for its own (8 in a checkerboard). It is the least count a
/// clamped history leaves with ([`CLAMPED_COUNT`] + 1), so that detail finer than the window, which a clamp
/// cut short, is not then averaged away with its neighbours'.
pub const STAND_IN_COUNT: f32 = CLAMPED_COUNT + 1.0;

/// Whether a pixel without its own trace this frame blends its [`stand_in`] (WGSL: `uses_stand_in`): where
/// its history holds fewer than [`STAND_IN_COUNT`] frames (or `max_count`, if lower), the voxels near it
/// changed enough to cap its history under `max_count` ([`change_cap`]), or there is no accumulation.
pub fn uses_stand_in(count: f32, max_count: f32, cap: f32) -> bool {
    count < STAND_IN_COUNT.min(max_count) || cap < max_count || max_count <= 1.0
}

/// The cap of a pixel that blends only its own trace, one every `frames_per_trace` frames (4 at half
/// resolution, 8 in `Low`'s checkerboard; WGSL: `waiting_cap`), from the cap [`change_cap`] gives a pixel
/// that blends every frame: blends `T` frames apart lag `T` times as far, and the balance of lag and noise,
/// `n^3 = 2 s^2 / (T^2 c^2)`, is `T^(2/3)` times shorter. (Waiting with the every-frame cap, the walls of
/// Bevy's `ssao` example lagged a sphere's shadow creeping up them by up to 0.17; blending the stand-in
/// every frame instead blurred the contact under a walking character's feet.)
pub fn waiting_cap(cap: f32, frames_per_trace: f32) -> f32 {
    cap / frames_per_trace.max(1.0).powf(2.0 / 3.0)
}

/// The relative view-depth tolerance of [`history_accepts`].
pub const DEPTH_TOLERANCE: f32 = 0.02;

/// The least cosine between the current and the history normal of [`history_accepts`].
pub const NORMAL_TOLERANCE: f32 = 0.9;

/// Whether a history texel saw the surface a pixel sees now (WGSL: `history_accepts`): its view depth
/// against the depth the pixel's world position had in the previous view, and the cosine between the
/// pixel's unit `normal` and the texel's normal `direction` (any length: the GPU passes the octahedral
/// code's direction unnormalized), tested squared, without a square root.
#[inline]
pub fn history_accepts(expected_depth: f32, history_depth: f32, normal: Vec3, direction: Vec3) -> bool {
    let c = normal.dot(direction);
    history_depth > 0.0
        && (history_depth - expected_depth).abs() <= DEPTH_TOLERANCE * expected_depth + 0.01
        && c > 0.0
        && c * c >= NORMAL_TOLERANCE * NORMAL_TOLERANCE * direction.length_squared()
}

/// The clamping window of the history from the current AO of a pixel's 3x3 neighbourhood (WGSL:
/// `neighborhood_window`): `(sum, sum of squares, count)` of the neighbours that show geometry, and the
/// `samples` (rays) they traced, or 0. The mean plus or minus two deviations and [`CLAMP_MARGIN`]; with
/// samples, at least the interval they tell the mean to lie in ([`sample_interval`]), which a window of
/// texels that happen to agree (all their rays escaped) would otherwise undercut.
#[inline]
pub fn neighborhood_window(sum: f32, sum_squares: f32, count: f32, samples: f32) -> (f32, f32) {
    let mean = sum / count;
    let sigma = (sum_squares / count - mean * mean).max(0.0).sqrt();
    let window = (mean - 2.0 * sigma - CLAMP_MARGIN, mean + 2.0 * sigma + CLAMP_MARGIN);
    if samples > 0.0 {
        let (lower, upper) = sample_interval(mean, samples);
        (window.0.min(lower), window.1.max(upper))
    } else {
        window
    }
}

/// Where the mean AO of a neighbourhood lies, from `samples` rays whose mean AO is `mean` (WGSL:
/// `sample_interval`): Wilson's score interval at [`WINDOW_Z`] standard errors. A ray's AO lies in [0, 1],
/// so its variance is at most `m (1 - m)`, a coin's, and the interval is the coin's: unlike the rays' own
/// spread, it does not close to a point where they all agree by chance (nine that escaped: (0.69, 1)).
#[inline]
pub fn sample_interval(mean: f32, samples: f32) -> (f32, f32) {
    let m = mean.clamp(0.0, 1.0);
    let z2n = WINDOW_Z * WINDOW_Z / samples;
    let centre = (m + 0.5 * z2n) / (1.0 + z2n);
    let half = WINDOW_Z / (1.0 + z2n) * ((m * (1.0 - m) + 0.25 * z2n) / samples).sqrt();
    (centre - half, centre + half)
}

/// One pixel's blend (WGSL: `temporal_blend`): the history AO and its frames of weight (0: none), the
/// window, the current AO, the cap, and the frames the history keeps where the voxels near the pixel
/// changed ([`change_cap`]; infinite where none did). Returns the new AO and its frames of weight.
#[inline]
pub fn temporal_blend(
    history: f32,
    history_count: f32,
    window: (f32, f32),
    current: f32,
    max_count: f32,
    cap: f32,
) -> (f32, f32) {
    let mut h = history;
    let mut c = history_count.min(cap);
    if h < window.0 || h > window.1 {
        let clamped = h.clamp(window.0, window.1);
        c = c.min(clamped_count(clamped - h, window));
        h = clamped;
    }
    let count = (c + 1.0).min(max_count.max(1.0));
    (if count <= 1.0 { current } else { h + (current - h) / count }, count)
}

/// How many standard errors of a still pixel's history the AO it shows may stray from the history
/// ([`stable_ao`]; WGSL: `STABLE_Z`).
pub const STABLE_Z: f32 = 1.0;

/// The AO a pixel shows and the frames of weight of the history it was taken from (WGSL: `stable_ao`),
/// from what it showed last frame (`shown`: `None` where the view does not stand still there,
/// [`history_limit`], or the pixel has no history) and its new history's AO and frames of weight (`ao`,
/// `count`; [`temporal_update`]), with `max_count` (`HybridAmbientOcclusion::accumulation_frames`) and the
/// window of its neighbourhood's trace, and the cap the occluders that moved near it put on its history
/// ([`change_cap`]). Where the history is longer than a moving view keeps (`count > max_count`: the view
/// stands still), nothing that moved could change it enough to cap it (`cap` at least
/// [`MAX_HISTORY_FRAMES`]: it changes by under a ten-thousandth a frame), holds less than twice the frames
/// of the one shown (a history that doubled knows enough more to be shown) and lies within [`STABLE_Z`]
/// standard errors of what the pixel showed (the current AO's variance, [`current_variance`], over
/// `2 count - 1`, an exponential average's), the pixel shows the same AO again; else the history's. Each
/// new trace moves a converged history by a 127th of its difference from it, a flicker Bevy's SSAO, whose
/// noise does not move, has not: the pixel keeps one of its history's past values instead, about as likely
/// right as the present one, until the history leaves it or doubles. Anywhere the history is cut or
/// follows a change (near a moving occluder, after a clamp, in a moving view) it shows the history.
pub fn stable_ao(
    shown: Option<(f32, f32)>,
    ao: f32,
    count: f32,
    max_count: f32,
    cap: f32,
    window: (f32, f32),
) -> (f32, f32) {
    match shown {
        Some((shown, shown_count))
            if count > max_count
                && cap >= MAX_HISTORY_FRAMES
                && count < 2.0 * shown_count
                && (ao - shown).abs() <= stable_reach(count, window) =>
        {
            (shown, shown_count)
        }
        _ => (ao, count),
    }
}

/// What the GPU keeps of [`stable_ao`]'s result (WGSL: `pack2x16unorm` in the temporal pass): the AO and the
/// frames over [`MAX_HISTORY_FRAMES`], to 1/65535 each.
pub fn shown_stored((ao, count): (f32, f32)) -> (f32, f32) {
    let unorm16 = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() / 65535.0;
    (unorm16(ao), unorm16(count / MAX_HISTORY_FRAMES) * MAX_HISTORY_FRAMES)
}

/// How far [`stable_ao`] lets a pixel's shown AO stray from its history of `count` frames: [`STABLE_Z`]
/// standard errors of the history (WGSL: in `stable_ao`).
fn stable_reach(count: f32, window: (f32, f32)) -> f32 {
    STABLE_Z * (current_variance(window) / (2.0 * count - 1.0).max(1.0)).sqrt()
}

/// A texel of the trace: the AO traced from a pixel, with that pixel's view depth and normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TracedTexel {
    /// The noisy AO.
    pub ao: f32,
    /// The traced pixel's view depth.
    pub depth: f32,
    /// The traced pixel's normal.
    pub normal: Vec3,
    /// Whether occluders moved near the traced pixel, enough for it to be filtered wider ([`filters_wide`],
    /// [`CHANGED_FILTER_REACH`]; WGSL: the packed texel's fourth field, 1).
    pub changed: bool,
}

impl TracedTexel {
    /// The texel as the trace stores it: packed as a texel of the history with no frames (WGSL
    /// `pack_history`; [`HistoryTexel::stored`](super::denoise::HistoryTexel::stored)), the AO to 1/8191 and
    /// the view depth to 11 bits of mantissa.
    pub fn stored(self) -> Self {
        let frames = if self.changed { 1.0 } else { 0.0 };
        let h = super::denoise::HistoryTexel { ao: self.ao, depth: self.depth, normal: self.normal, frames }.stored();
        Self { ao: h.ao, depth: h.depth, normal: h.normal, changed: h.frames > 0.5 }
    }
}

/// The trace's 3x3 texels around `texel` that exist and show geometry, with their offsets from it, in the
/// order the passes read them (rows, then columns).
fn neighbourhood(
    trace: &[Option<TracedTexel>],
    trace_size: UVec2,
    texel: UVec2,
) -> impl Iterator<Item = (IVec2, TracedTexel)> + '_ {
    neighbourhood_within(trace, trace_size, texel, 1)
}

/// The trace's texels within `reach` texels of `texel` each way (a square of `2 reach + 1` a side) that exist
/// and show geometry, with their offsets from it, in the order the passes read them (rows, then columns).
fn neighbourhood_within(
    trace: &[Option<TracedTexel>],
    trace_size: UVec2,
    texel: UVec2,
    reach: i32,
) -> impl Iterator<Item = (IVec2, TracedTexel)> + '_ {
    let side = 2 * reach + 1;
    (0..side * side).filter_map(move |k| {
        let d = IVec2::new(k % side - reach, k / side - reach);
        let t = texel.as_ivec2() + d;
        let inside = t.cmpge(IVec2::ZERO).all() && t.cmplt(trace_size.as_ivec2()).all();
        inside.then(|| trace[(t.y as u32 * trace_size.x + t.x as u32) as usize].map(|v| (d, v))).flatten()
    })
}

/// The window that bounds the history of the pixels of trace texel `texel` (WGSL: `hao_neighborhood.wgsl`,
/// once per texel of the trace): [`neighborhood_window`] over its 3x3 texels that show geometry, each of
/// `rays` rays, at least their [`sample_interval`] unless occluders moved near the texel (its
/// [`TracedTexel::changed`]: there a window that closes is how a shadow left behind is cleared); `(-1, 2)`,
/// none, where none shows geometry.
pub fn trace_window(trace: &[Option<TracedTexel>], trace_size: UVec2, texel: UVec2, rays: u32) -> (f32, f32) {
    let (mut sum, mut squares, mut n) = (0.0f32, 0.0f32, 0.0f32);
    for (_, v) in neighbourhood(trace, trace_size, texel) {
        sum += v.ao;
        squares += v.ao * v.ao;
        n += 1.0;
    }
    let centre = trace.get((texel.y * trace_size.x + texel.x) as usize).copied().flatten();
    let samples = if centre.is_some_and(|c| !c.changed) { n * rays as f32 } else { 0.0 };
    if n > 0.0 { neighborhood_window(sum, squares, n, samples) } else { (-1.0, 2.0) }
}

/// What stands in for a pixel's own trace where its block traced another pixel (WGSL: `stand_in` in
/// `hao_temporal.wgsl`): the mean of the trace's 3x3 texels around `texel` that show its surface (its view
/// depth `depth` and normal `normal`, [`history_accepts`]), else of all that show geometry, else 1. Where
/// occluders moved near its traced pixel ([`TracedTexel::changed`]), the mean of their AO filtered
/// ([`prefilter`] with `radius`), which is wider there.
pub fn stand_in(
    trace: &[Option<TracedTexel>],
    trace_size: UVec2,
    texel: UVec2,
    depth: f32,
    normal: Vec3,
    radius: u32,
) -> f32 {
    let wide = trace[(texel.y * trace_size.x + texel.x) as usize].is_some_and(|t| t.changed);
    let (mut sum, mut n, mut same_sum, mut same_n) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for (d, v) in neighbourhood(trace, trace_size, texel) {
        let ao = if wide { prefilter(trace, trace_size, (texel.as_ivec2() + d).as_uvec2(), radius) } else { v.ao };
        sum += ao;
        n += 1.0;
        if history_accepts(depth, v.depth, normal, v.normal) {
            same_sum += ao;
            same_n += 1.0;
        }
    }
    if same_n > 0.0 {
        same_sum / same_n
    } else if n > 0.0 {
        sum / n
    } else {
        1.0
    }
}

/// Trace texel `texel`'s AO filtered over its 3x3 texels (WGSL: `hao_neighborhood.wgsl`, once per texel of
/// the trace), which the pixel it traced blends into its history: the texels that show geometry, each weighed
/// by [`bilateral_weight`](super::denoise::bilateral_weight) (its distance in texels over `radius`,
/// `HybridAmbientOcclusion::denoise_radius`, and its depth and normal against the traced pixel's). Where
/// occluders moved near it ([`TracedTexel::changed`]) over its texels within [`CHANGED_FILTER_REACH`], at
/// that many times the width. Radius 0, or a texel that shows no geometry: its AO as traced (1 for the
/// background).
pub fn prefilter(trace: &[Option<TracedTexel>], trace_size: UVec2, texel: UVec2, radius: u32) -> f32 {
    let Some(center) = trace[(texel.y * trace_size.x + texel.x) as usize] else { return 1.0 };
    let reach = if center.changed { CHANGED_FILTER_REACH } else { 1 };
    let mut sum = Vec2::ZERO;
    for (d, v) in neighbourhood_within(trace, trace_size, texel, reach) {
        let w = super::denoise::bilateral_weight(
            d.as_vec2().length(),
            radius as f32 * reach as f32,
            center.depth,
            v.depth,
            center.normal,
            v.normal,
        );
        sum += Vec2::new(w * v.ao, w);
    }
    if radius > 0 && sum.y > 0.0 { sum.x / sum.y } else { center.ao }
}

/// One pixel's new history and frames of weight (WGSL: the end of `temporal`), from its reprojected history
/// (`count` 0: none), the window, its own trace this frame (`None` where its block traced another pixel),
/// its stand-in ([`stand_in`]), `HybridAmbientOcclusion::accumulation_frames` (`max_count`), the most
/// frames the history keeps ([`history_limit`]: more where the view stands still) and those it keeps where
/// the voxels near it changed ([`change_cap`]). A frame without its own trace keeps the history as it is,
/// unless the history is short, the voxels near it changed or there is no accumulation
/// ([`uses_stand_in`]): then the stand-in is blended as a trace. A pixel that blends only its own traces,
/// one every `frames_per_trace` frames, keeps at most [`waiting_cap`] frames. Either way it keeps at most
/// `limit` frames of weight: a frame that cuts the limit cuts every pixel's history.
#[allow(clippy::too_many_arguments)]
pub fn temporal_update(
    history: f32,
    count: f32,
    window: (f32, f32),
    own: Option<f32>,
    stand_in: f32,
    max_count: f32,
    limit: f32,
    cap: f32,
    frames_per_trace: f32,
) -> (f32, f32) {
    let every_frame = uses_stand_in(count, max_count, cap);
    match own {
        Some(current) if every_frame => temporal_blend(history, count, window, current, limit, cap),
        Some(current) => temporal_blend(history, count, window, current, limit, waiting_cap(cap, frames_per_trace)),
        None if every_frame => temporal_blend(history, count, window, stand_in, limit, cap),
        // (Never more frames than the limit: a frame that cuts it, as a change of the settings does, cuts
        // every pixel's, traced or not.)
        None => (history, count.min(limit)),
    }
}

/// One frame of the trace: its number and whether it ran in a checkerboard (which pixels a half-resolution
/// trace traced), and its texels (`None` where the traced pixel shows no geometry).
pub struct TraceFrame {
    /// The frame number (`GpuHaoSettings::frame`).
    pub number: u32,
    /// Whether the frame traced half the texels (`GpuHaoSettings::checkerboard`): the others hold the last
    /// frame's.
    pub checkerboard: bool,
    /// Rays each texel traced (`GpuHaoSettings::rays`; more near occluders that moved, which the window
    /// does not count on).
    pub rays: u32,
    /// The trace, one texel per pixel, or per 2x2 block at half resolution, as the trace's buffer holds it
    /// after the frame's trace.
    pub texels: Vec<Option<TracedTexel>>,
}

impl TraceFrame {
    /// The trace's buffer after frame `number`: the texels the frame traces ([`texel_traced`]) from `trace`,
    /// the others as the `previous` frame left them. Without a previous frame every texel is traced and the
    /// frame is not a checkerboard's (the GPU's first frame of a view, which has no last trace to keep).
    pub fn traced(
        number: u32,
        checkerboard: bool,
        rays: u32,
        trace_size: UVec2,
        previous: Option<&TraceFrame>,
        mut trace: impl FnMut(UVec2) -> Option<TracedTexel>,
    ) -> Self {
        let checkerboard = checkerboard && previous.is_some();
        let texels = (0..trace_size.x * trace_size.y)
            .map(|i| {
                let t = UVec2::new(i % trace_size.x, i / trace_size.x);
                match previous {
                    Some(previous) if !texel_traced(t, number, checkerboard) => previous.texels[i as usize],
                    _ => trace(t),
                }
            })
            .collect();
        TraceFrame { number, checkerboard, rays, texels }
    }
}

/// The accumulation over a still camera (reprojection is the identity), frame by frame: the twin that the
/// GPU test holds the temporal pass to. `pixels` are the view's (`view_size`), each with its view depth and
/// normal (`None`: background), and how much its occlusion can have changed each frame (`change`,
/// [`occlusion_change`]: the voxels are the same, the occluders near it move); `frames` the trace of each
/// frame, at half resolution or not. The result is the AO each pixel shows after the last frame
/// ([`stable_ao`]; NaN for the background). Each pixel's own trace is filtered ([`prefilter`]) with the filter's `radius`
/// (`HybridAmbientOcclusion::denoise_radius`). Every pixel's history keeps up to `still_count` frames
/// (`still_accumulation_frames`: [`history_limit`]), the view being still; `max_count` is
/// `accumulation_frames`.
#[allow(clippy::too_many_arguments)]
pub fn accumulate_still(
    frames: &[TraceFrame],
    pixels: &[Option<(f32, Vec3)>],
    change: &[f32],
    view_size: UVec2,
    half_resolution: bool,
    max_count: f32,
    still_count: f32,
    radius: u32,
) -> Vec<f32> {
    let limit = history_limit(max_count, still_count, true);
    let trace_size = if half_resolution { (view_size + UVec2::ONE) / 2 } else { view_size };
    let mut ao = vec![f32::NAN; pixels.len()];
    let mut count = vec![0.0f32; pixels.len()];
    let mut shown = vec![(f32::NAN, 0.0); pixels.len()];
    for frame in frames {
        for (i, pixel) in pixels.iter().enumerate() {
            let Some((depth, normal)) = *pixel else { continue };
            let p = UVec2::new(i as u32 % view_size.x, i as u32 / view_size.x);
            let texel = if half_resolution { p / 2 } else { p };
            let turn = trace_turn(frame.number, frame.checkerboard);
            let own = (texel_traced(texel, frame.number, frame.checkerboard)
                && traced_pixel(texel, turn, view_size, half_resolution) == p
                && frame.texels[(texel.y * trace_size.x + texel.x) as usize].is_some())
            .then(|| prefilter(&frame.texels, trace_size, texel, radius));
            let window = trace_window(&frame.texels, trace_size, texel, frame.rays);
            // (The GPU reads the stand-in only where `temporal_update` uses it.)
            let stand_in = stand_in(&frame.texels, trace_size, texel, depth, normal, radius);
            // (The GPU caps only a pixel with history.)
            let cap = if count[i] > 0.0 { change_cap(change[i], window) } else { f32::INFINITY };
            let frames_per_trace = match (half_resolution, frame.checkerboard) {
                (false, _) => 1.0,
                (true, false) => 4.0,
                (true, true) => 8.0,
            };
            let (a, c) =
                temporal_update(ao[i], count[i], window, own, stand_in, max_count, limit, cap, frames_per_trace);
            // The view stands still: what the pixel showed last frame, where it had a history.
            shown[i] = shown_stored(stable_ao((count[i] > 0.0).then_some(shown[i]), a, c, max_count, cap, window));
            // As the GPU stores it (`HistoryTexel::stored`).
            let stored = HistoryTexel { ao: a, depth, normal, frames: c }.stored();
            (ao[i], count[i]) = (stored.ao, stored.frames);
        }
    }
    shown.into_iter().map(|(ao, _)| ao).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No change near the pixel: no cap.
    const NONE: f32 = f32::INFINITY;

    #[test]
    fn a_still_pixel_averages_its_frames_up_to_the_cap() {
        let window = (-10.0, 10.0);
        let (mut ao, mut c) = (0.0, 0.0);
        for (k, x) in [0.2f32, 0.4, 0.9, 0.5].into_iter().enumerate() {
            (ao, c) = temporal_blend(ao, c, window, x, 16.0, NONE);
            assert_eq!(c, k as f32 + 1.0);
        }
        assert!((ao - 0.5).abs() < 1e-6, "{ao}");
        // At the cap, an exponential average with weight 1/cap.
        let (a, c) = temporal_blend(0.5, 4.0, window, 1.0, 4.0, NONE);
        assert_eq!((a, c), (0.625, 4.0));
        // A cap of 1 keeps no history, whatever the window (the GPU does not compute it then).
        assert_eq!(temporal_blend(0.5, 9.0, window, 0.1, 1.0, NONE), (0.1, 1.0));
        assert_eq!(temporal_blend(0.5, 9.0, (0.0, 0.0), 0.1, 1.0, CHANGED_COUNT), (0.1, 1.0));
    }

    #[test]
    fn a_history_outside_the_window_is_clamped_and_loses_its_weight() {
        // An occluder has gone: the neighbourhood reads 1 everywhere, the old shadow of 0.4 is clamped to
        // 0.9 and weighs two frames.
        let window = neighborhood_window(9.0, 9.0, 9.0, 0.0);
        assert_eq!(window, (0.9, 1.1));
        let (ao, c) = temporal_blend(0.4, 16.0, window, 1.0, 16.0, NONE);
        assert!((ao - (0.9 + 0.1 / 3.0)).abs() < 1e-6 && c == 3.0, "{ao} {c}");
        // Nine rays that all escaped by chance around a pixel of AO 0.88: the history, moved by 0.02, keeps
        // as many frames as hide a bias of 0.02 in their noise (0.1^2 / 4 / 0.02^2, about 6), not 2.
        assert!((clamped_count(0.02, window) - 6.25).abs() < 1e-3);
        let (ao, c) = temporal_blend(0.88, 16.0, window, 1.0, 16.0, NONE);
        assert!((c - 7.25).abs() < 1e-3 && (ao - (0.9 + 0.1 / 7.25)).abs() < 1e-5, "{ao} {c}");
        // A history moved less keeps all of it; a wide window (noisy neighbours) counts more noise.
        assert_eq!(temporal_blend(0.895, 16.0, window, 1.0, 16.0, NONE).1, 16.0);
        assert!(clamped_count(0.05, (0.0, 1.2)) > clamped_count(0.05, window));
    }

    #[test]
    fn near_moving_occluders_the_history_is_short() {
        // A shadow arrives (the clamp cannot see it in two-ray noise): far from any change the pixel moves
        // 1/16 of the way, near one a third.
        let window = (0.0, 1.2);
        assert_eq!(temporal_blend(1.0, 16.0, window, 0.52, 16.0, NONE).0, 0.97);
        let (ao, c) = temporal_blend(1.0, 16.0, window, 0.52, 16.0, CHANGED_COUNT);
        assert!((ao - 0.84).abs() < 1e-6 && c == 3.0, "{ao} {c}");
    }

    #[test]
    fn the_occlusion_change_falls_with_distance_and_stops_behind_the_surface_and_past_reach() {
        // A ball of radius 0.5 rolled 2.5 cm; points on a floor (normal +y) at 0.5, 1, 2 m from its contact.
        let ball = |x: f32| MovedVoxels {
            min: Vec3::new(x - 0.5, 0.0, -0.5),
            max: Vec3::new(x + 0.5, 1.0, 0.5),
            motion: 0.025,
        };
        let change = |p: Vec3, n: Vec3| occlusion_change(p, n, &[ball(0.0)], 3.0, 1.0);
        let at = [0.5, 1.0, 2.0].map(|x| change(Vec3::new(x, 0.0, 0.0), Vec3::Y));
        assert!(at[0] > at[1] && at[1] > at[2] && at[2] > 0.0, "{at:?}");
        // Under 0.05 a frame next to it, a few thousandths two metres away.
        assert!(at[0] < 0.05 && at[2] < 0.005, "{at:?}");
        // Facing away (under a floor), beyond the reach, or with nothing moving: no change.
        assert_eq!(change(Vec3::new(1.0, -0.2, 0.0), -Vec3::Y), 0.0);
        assert_eq!(change(Vec3::new(5.0, 0.0, 0.0), Vec3::Y), 0.0);
        assert_eq!(occlusion_change(Vec3::ZERO, Vec3::Y, &[], 3.0, 1.0), 0.0);
        // On the ball itself (in its box), a change as large as its motion's share of its size; an unknown
        // motion, all.
        let own = change(Vec3::new(0.0, 1.0, 0.0), Vec3::Y);
        assert!((own - 0.05).abs() < 1e-6, "{own}");
        let unknown = MovedVoxels { motion: 1.0e30, ..ball(0.0) };
        assert_eq!(occlusion_change(Vec3::new(0.0, 1.0, 0.0), Vec3::Y, &[unknown], 3.0, 1.0), 1.0);
    }

    #[test]
    fn the_change_cap_balances_lag_against_noise() {
        let window = neighborhood_window(4.5, 4.5 * 0.5 + 2.25 * 0.25, 9.0, 0.0);
        // No change: no cap. The largest change: CHANGED_COUNT.
        assert_eq!(change_cap(0.0, window), f32::INFINITY);
        assert_eq!(change_cap(f32::NAN, window), f32::INFINITY);
        assert_eq!(change_cap(1.0, window), CHANGED_COUNT);
        // Between, n^3 = 2 s^2 / c^2: a tenth of the change, about 4.6 times the frames.
        let (a, b) = (change_cap(0.01, window), change_cap(0.001, window));
        assert!((b / a - 100f32.cbrt()).abs() < 1e-3, "{a} {b}");
        let sigma = (window.1 - window.0) * 0.25 - CLAMP_MARGIN * 0.5;
        assert!((a.powi(3) - 2.0 * sigma * sigma / CHANGE_NOISE_SAMPLES / 1.0e-4).abs() < 0.01 * a.powi(3));
        // A neighbourhood that agrees (no deviation) still counts a few rays' noise: a finite cap.
        let quiet = change_cap(0.001, (0.8 - CLAMP_MARGIN, 0.8 + CLAMP_MARGIN));
        let floor = (2.0 * CHANGE_NOISE_FLOOR * CHANGE_NOISE_FLOOR / CHANGE_NOISE_SAMPLES / 1.0e-6).cbrt();
        assert!((quiet - floor).abs() < 1e-3 * floor, "{quiet} {floor}");
    }

    #[test]
    fn reprojected_texels_are_kept_only_on_the_same_surface() {
        // A normal 0.99 (8 degrees) and 0.5 (60 degrees) from +z, at the length the GPU leaves an
        // octahedral code's direction (0.6): the test takes the cosine whatever the length.
        let tilted = |cosine: f32| 0.6 * Vec3::new((1.0 - cosine * cosine).sqrt(), 0.0, cosine);
        assert!(history_accepts(10.0, 10.1, Vec3::Z, tilted(0.99)));
        assert!(!history_accepts(10.0, 11.0, Vec3::Z, tilted(0.99)), "another surface behind");
        assert!(!history_accepts(10.0, 10.0, Vec3::Z, tilted(0.5)), "a crease");
        assert!(!history_accepts(10.0, 10.0, Vec3::Z, -Vec3::Z), "a face turned away");
        assert!(!history_accepts(10.0, 0.0, Vec3::Z, Vec3::Z), "no history (background or never written)");
        assert!(!history_accepts(10.0, 10.0, Vec3::Z, Vec3::ZERO), "no normal");
        assert!(history_accepts(10.0, 10.0, Vec3::Z, tilted(NORMAL_TOLERANCE + 1e-3)));
        assert!(!history_accepts(10.0, 10.0, Vec3::Z, tilted(NORMAL_TOLERANCE - 1e-3)), "just past the tolerance");
    }

    /// A still view of `w x h` pixels, all showing one flat surface facing the camera at depth 10.
    fn flat(w: u32, h: u32) -> Vec<Option<(f32, Vec3)>> {
        vec![Some((10.0, Vec3::Z)); (w * h) as usize]
    }

    fn texel(ao: f32) -> Option<TracedTexel> {
        Some(TracedTexel { ao, depth: 10.0, normal: Vec3::Z, changed: false })
    }

    #[test]
    fn a_still_noisy_pixel_converges_to_its_mean() {
        // Two-ray AO of a surface whose true AO is 0.75: each pixel reads 0.5 or 1.0, alternating per frame,
        // its neighbours the other way (the trace's noise is decorrelated between pixels).
        let (w, h) = (3, 3);
        let frames: Vec<TraceFrame> = (0..32)
            .map(|k| TraceFrame {
                number: k,
                checkerboard: false,
                rays: 1,
                texels: (0..w * h).map(|i| texel(if (i + k) % 2 == 0 { 0.5 } else { 1.0 })).collect(),
            })
            .collect();
        let size = UVec2::new(w, h);
        let ao = accumulate_still(&frames, &flat(w, h), &vec![0.0; flat(w, h).len()], size, false, 32.0, 32.0, 0);
        assert!(ao.iter().all(|a| (a - 0.75).abs() < 0.02), "{ao:?}");
        // After one frame, the frame's AO as the history stores it (to 1/8191).
        let one = accumulate_still(&frames[..1], &flat(w, h), &vec![0.0; flat(w, h).len()], size, false, 32.0, 32.0, 0);
        assert!(one.iter().zip(&frames[0].texels).all(|(a, t)| (a - t.unwrap().ao).abs() <= 0.5 / 8191.0), "{one:?}");
    }

    #[test]
    fn at_half_resolution_each_pixel_accumulates_its_own_traces() {
        // A 4x4 view traced at half resolution: the pixels of odd columns see AO 0.9, of even ones 0.2 (detail
        // finer than a block). Each frame traces one pixel of each block, in turn.
        let size = UVec2::new(4, 4);
        let truth = |p: UVec2| if p.x % 2 == 1 { 0.9 } else { 0.2 };
        let frames: Vec<TraceFrame> = (0..64)
            .map(|k| TraceFrame {
                number: k,
                checkerboard: false,
                rays: 1,
                texels: (0..4u32)
                    .map(|t| texel(truth(crate::cpu::ao::traced_pixel(UVec2::new(t % 2, t / 2), k, size, true))))
                    .collect(),
            })
            .collect();
        let ao = accumulate_still(&frames, &flat(4, 4), &vec![0.0; flat(4, 4).len()], size, true, 4.0, 4.0, 0);
        for (i, a) in ao.iter().enumerate() {
            let p = UVec2::new(i as u32 % 4, i as u32 / 4);
            // 16 traces of its own: the stand-in of the first frame (the block's traced pixel) weighs under 1 %.
            assert!((a - truth(p)).abs() < 0.02, "pixel {p}: {a}, not {}", truth(p));
        }
        // After the first frame alone the untraced pixels hold their neighbourhood's traces.
        let first = accumulate_still(&frames[..1], &flat(4, 4), &vec![0.0; flat(4, 4).len()], size, true, 4.0, 4.0, 0);
        // (As the history stores them, to 1/8191.)
        assert!((first[0] - 0.2).abs() <= 0.5 / 8191.0, "traced: {}", first[0]);
        assert!((first[1] - 0.2).abs() <= 0.5 / 8191.0, "its block's traced pixel stands in: {}", first[1]);
    }

    #[test]
    fn in_a_checkerboard_each_pixel_accumulates_its_own_traces() {
        // An 8x8 view traced at half resolution in a checkerboard: each pixel sees its own AO, which no
        // other pixel of its block shares. Each frame traces half the blocks, each block one of its pixels.
        let size = UVec2::new(8, 8);
        let trace_size = UVec2::new(4, 4);
        let truth = |p: UVec2| 0.1 + 0.8 * ((p.x * 3 + p.y * 5) % 7) as f32 / 6.0;
        let mut frames: Vec<TraceFrame> = Vec::new();
        for k in 0..160 {
            let traced = TraceFrame::traced(k, true, 1, trace_size, frames.last(), |t| {
                texel(truth(traced_pixel(t, trace_turn(k, !frames.is_empty()), size, true)))
            });
            frames.push(traced);
        }
        assert!(!frames[0].checkerboard && frames[1].checkerboard, "the first frame traces every texel");
        // Each frame after the first keeps half the texels as they were.
        let kept = (0..16).filter(|&i| frames[9].texels[i].unwrap().ao == frames[8].texels[i].unwrap().ao).count();
        assert_eq!(kept, 8);
        let ao = accumulate_still(&frames, &flat(8, 8), &vec![0.0; flat(8, 8).len()], size, true, 4.0, 4.0, 0);
        for (i, a) in ao.iter().enumerate() {
            let p = UVec2::new(i as u32 % 8, i as u32 / 8);
            // 20 traces of its own, one every eighth frame: the first frames' stand-ins weigh under 1 %.
            assert!((a - truth(p)).abs() < 0.02, "pixel {p}: {a}, not {}", truth(p));
        }
    }

    /// The mean error against `truth` of a flat view of 128x96 pixels after `frames` frames of a noisy
    /// trace at half resolution, in a checkerboard or not, accumulated over 16 frames and filtered with
    /// radius 1: one binary ray a frame, 1 with probability `truth` of the traced pixel. The mean over four
    /// fixed pseudo-random sequences (one alone moves it by a few percent).
    fn converged_error(checkerboard: bool, frames: u32, truth: impl Fn(UVec2) -> f32) -> f32 {
        let (size, trace_size) = (UVec2::new(128, 96), UVec2::new(64, 48));
        let seeds = [0x2545_f491_4f6c_dd1d_u64, 0x9e37_79b9_7f4a_7c15, 0xd1b5_4a32_d192_ed03, 0x8cb9_2ba7_2f3d_8dd7];
        let mut total = 0.0;
        for mut state in seeds {
            let mut random = move || {
                // xorshift64: [0, 1).
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 40) as f32 / (1u64 << 24) as f32
            };
            let mut traces: Vec<TraceFrame> = Vec::new();
            for k in 0..frames {
                let turn = trace_turn(k, checkerboard && !traces.is_empty());
                let traced = TraceFrame::traced(k, checkerboard, 1, trace_size, traces.last(), |t| {
                    texel(if random() < truth(traced_pixel(t, turn, size, true)) { 1.0 } else { 0.0 })
                });
                traces.push(traced);
            }
            let ao = accumulate_still(
                &traces,
                &flat(size.x, size.y),
                &vec![0.0; flat(size.x, size.y).len()],
                size,
                true,
                16.0,
                16.0,
                1,
            );
            let pixel = |i: usize| UVec2::new(i as u32 % size.x, i as u32 / size.x);
            total += ao.iter().enumerate().map(|(i, a)| (a - truth(pixel(i))).abs()).sum::<f32>() / ao.len() as f32;
        }
        total / seeds.len() as f32
    }

    #[test]
    fn a_checkerboard_converges_as_the_whole_trace_on_uniform_ao() {
        // Each pixel accumulates as many traces of its own in a checkerboard, each filtered over as many
        // texels: on uniform AO the still error is the same once converged (after four times the history's
        // frames, 260 and 516, as `ao_compare` waits).
        let errors =
            |truth: &dyn Fn(UVec2) -> f32| (converged_error(false, 260, truth), converged_error(true, 516, truth));
        let (whole, checkerboard) = errors(&|_| 0.6);
        // Where the AO varies, it does not: in every other frame of the checkerboard the four texels beside
        // a traced one were traced by another pixel of their blocks (the previous turn's), so the filter
        // blurs the AO, the more the finer its variation (docs/figures.md).
        let smooth = |p: UVec2| 0.5 + 0.3 * (p.x as f32 * 0.21).sin() * (p.y as f32 * 0.17).cos();
        let fine = |p: UVec2| smooth(p) + if (p.x + p.y).is_multiple_of(2) { 0.05 } else { -0.05 };
        let ((smooth_whole, smooth_checkerboard), (fine_whole, fine_checkerboard)) = (errors(&smooth), errors(&fine));
        println!(
            "still error, whole trace / checkerboard: uniform AO {whole:.4} / {checkerboard:.4}, smooth \
             {smooth_whole:.4} / {smooth_checkerboard:.4}, with a pixel-sized pattern {fine_whole:.4} / \
             {fine_checkerboard:.4}"
        );
        assert!((checkerboard - whole).abs() < 0.02 * whole, "{checkerboard} against {whole}");
    }

    #[test]
    fn a_frame_without_the_pixels_own_trace_keeps_its_history() {
        let window = (0.0, 1.2);
        assert_eq!(temporal_update(0.4, 6.0, window, None, 0.9, 16.0, 16.0, NONE, 1.0), (0.4, 6.0));
        // Its own trace is blended; with no history, or near a change, the stand-in is.
        assert_eq!(temporal_update(0.4, 3.0, window, Some(0.8), 0.9, 16.0, 16.0, NONE, 1.0), (0.5, 4.0));
        assert_eq!(temporal_update(0.0, 0.0, window, None, 0.9, 16.0, 16.0, NONE, 1.0), (0.9, 1.0));
        // A short history (under STAND_IN_COUNT frames) blends the stand-in until the pixel's own trace
        // comes; not where the cap is that short itself.
        let (ao, c) = temporal_update(0.4, 2.0, window, None, 0.9, 16.0, 16.0, NONE, 1.0);
        assert!((ao - (0.4 + 0.5 / 3.0)).abs() < 1e-6 && c == 3.0, "{ao} {c}");
        assert_eq!(
            temporal_update(0.4, STAND_IN_COUNT, window, None, 0.9, 16.0, 16.0, NONE, 1.0),
            (0.4, STAND_IN_COUNT)
        );
        // A history the window clamped keeps its own (CLAMPED_COUNT + 1 frames are not a short history).
        let (_, clamped) = temporal_update(0.0, 16.0, (0.5, 1.0), Some(0.9), 0.9, 16.0, 16.0, NONE, 1.0);
        assert!(!uses_stand_in(clamped, 16.0, NONE));
        // A still pixel (a limit of 127) whose cap is above `max_count` waits for its own trace, 4 frames
        // at half resolution, and blends it with the cap 4^(2/3) times shorter; at full resolution the cap.
        assert!(!uses_stand_in(100.0, 16.0, 40.0));
        assert_eq!(temporal_update(0.4, 100.0, window, None, 0.81, 16.0, 127.0, 40.0, 4.0), (0.4, 100.0));
        let waiting = 40.0 / 4f32.powf(2.0 / 3.0);
        let (ao, c) = temporal_update(0.4, 100.0, window, Some(0.81), 0.0, 16.0, 127.0, 40.0, 4.0);
        assert!((ao - (0.4 + 0.41 / (waiting + 1.0))).abs() < 1e-6 && c == waiting + 1.0, "{ao} {c}");
        assert_eq!(waiting_cap(40.0, 1.0), 40.0);
        let (_, c) = temporal_update(0.4, 100.0, window, Some(0.81), 0.0, 16.0, 127.0, 40.0, 1.0);
        assert_eq!(c, 41.0);
        assert_eq!(temporal_update(0.4, 2.0, window, None, 0.9, 2.0, 2.0, NONE, 1.0), (0.4, 2.0));
        let (ao, c) = temporal_update(0.4, 6.0, window, None, 1.0, 16.0, 16.0, CHANGED_COUNT, 1.0);
        assert!((ao - 0.6).abs() < 1e-6 && c == 3.0, "{ao} {c}");
        // No accumulation: the stand-in is the frame's AO.
        assert_eq!(temporal_update(0.4, 1.0, window, None, 0.9, 1.0, 1.0, NONE, 1.0), (0.9, 1.0));
    }

    #[test]
    fn a_still_view_keeps_a_longer_history_than_a_moving_one() {
        // Moving (or jittered), accumulation_frames; still, still_accumulation_frames, within the bounds.
        assert_eq!(history_limit(16.0, 127.0, false), 16.0);
        assert_eq!(history_limit(16.0, 127.0, true), 127.0);
        assert_eq!(history_limit(16.0, 8.0, true), 16.0, "never fewer than accumulation_frames");
        assert_eq!(history_limit(16.0, 1000.0, true), MAX_HISTORY_FRAMES, "never more than the texel holds");
        assert_eq!(history_limit(1.0, 127.0, true), 1.0, "no accumulation");
        // A converged still pixel at the limit moves a 127th of the way to a new trace; and its count
        // survives the texel's packing.
        let window = (-10.0, 10.0);
        let limit = history_limit(16.0, 127.0, true);
        let (ao, c) = temporal_update(0.5, 127.0, window, Some(1.0), 0.0, 16.0, limit, NONE, 1.0);
        assert!((ao - (0.5 + 0.5 / 127.0)).abs() < 1e-6 && c == 127.0, "{ao} {c}");
        let stored = HistoryTexel { ao, depth: 10.0, normal: Vec3::Z, frames: c }.stored();
        assert_eq!(stored.frames, 127.0);
        // A frame without its own trace still keeps the history as it is: the stand-in follows
        // accumulation_frames, not the limit.
        assert_eq!(temporal_update(0.5, 40.0, window, None, 0.0, 16.0, limit, NONE, 1.0), (0.5, 40.0));
        // A frame that cuts the limit (the settings changed, or the view moves) cuts the history of every
        // pixel, those without their own trace too, which would otherwise keep their 127 frames.
        assert_eq!(temporal_update(0.5, 127.0, window, None, 0.0, 16.0, 16.0, NONE, 1.0), (0.5, 16.0));
        assert_eq!(history_limit(200.0, 127.0, true), 200.0, "no panic on a max_count past the texel's");
        // Near a change the change cap shortens it as before.
        let (_, c) = temporal_update(0.5, 127.0, window, Some(1.0), 0.0, 16.0, limit, CHANGED_COUNT, 1.0);
        assert_eq!(c, CHANGED_COUNT + 1.0);
    }

    #[test]
    fn a_still_view_settles_further_with_a_longer_history() {
        // Four binary rays a frame at full resolution over uniform AO 0.6, no filter: the frame-to-frame
        // change of the last frames falls about as one over the frames kept (16 against 127: 8 times). (With
        // one ray, a neighbourhood whose nine texels all read 1, one frame in a hundred, clamps the history
        // and cuts it short.)
        let size = UVec2::new(32, 32);
        let change = |still_count: f32| {
            let mut state = 0x2545_f491_4f6c_dd1d_u64;
            let mut random = move || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 40) as f32 / (1u64 << 24) as f32
            };
            let frames: Vec<TraceFrame> = (0..400)
                .map(|k| TraceFrame {
                    number: k,
                    checkerboard: false,
                    rays: 4,
                    texels: (0..size.x * size.y)
                        .map(|_| texel((0..4).map(|_| if random() < 0.6 { 0.25 } else { 0.0 }).sum()))
                        .collect(),
                })
                .collect();
            let pixels = flat(size.x, size.y);
            let zero = vec![0.0; pixels.len()];
            let a = accumulate_still(&frames[..399], &pixels, &zero, size, false, 16.0, still_count, 0);
            let b = accumulate_still(&frames, &pixels, &zero, size, false, 16.0, still_count, 0);
            a.iter().zip(&b).map(|(a, b)| (a - b).abs()).sum::<f32>() / a.len() as f32
        };
        let (short, long) = (change(16.0), change(127.0));
        assert!(long < short / 5.0, "{long} against {short}");
    }

    #[test]
    fn the_filter_averages_the_texels_surface_only() {
        // A 3x3 trace on one surface: the center reads 1, its four side neighbours 0, the corners 0.5.
        let size = UVec2::new(3, 3);
        let ao = |i: usize| match i {
            4 => 1.0,
            _ if i % 2 == 1 => 0.0,
            _ => 0.5,
        };
        let mut trace: Vec<Option<TracedTexel>> = (0..9).map(|i| texel(ao(i))).collect();
        let (side, corner) = ((-1.0f32 / 2.0).exp(), (-1.0f32).exp());
        let expected = (1.0 + 4.0 * corner * 0.5) / (1.0 + 4.0 * side + 4.0 * corner);
        let got = prefilter(&trace, size, UVec2::ONE, 1);
        assert!((got - expected).abs() < 1e-6, "{got} {expected}");
        // Wider, the neighbours weigh more.
        assert!(prefilter(&trace, size, UVec2::ONE, 2) < got);
        // Radius 0 is no filter: the texel as traced.
        assert_eq!(prefilter(&trace, size, UVec2::ONE, 0), 1.0);
        // Another surface (far behind), a crease and the background weigh nothing.
        for i in [0, 1, 2, 3] {
            trace[i] = Some(TracedTexel { ao: 0.0, depth: 50.0, normal: Vec3::Z, changed: false });
        }
        for i in [5, 6, 7] {
            trace[i] = Some(TracedTexel { ao: 0.0, depth: 10.0, normal: Vec3::X, changed: false });
        }
        trace[8] = None;
        assert_eq!(prefilter(&trace, size, UVec2::ONE, 2), 1.0);
        // The background is open.
        assert_eq!(prefilter(&trace, size, UVec2::new(2, 2), 1), 1.0);
    }

    #[test]
    fn where_occluders_moved_the_filter_reaches_twice_as_far_at_twice_the_width() {
        // A 7x7 trace of one surface, in a checkerboard of 0 and 1 (two-ray noise, decorrelated between
        // texels), with a shadow of 0 two texels to the right of the middle.
        let size = UVec2::new(7, 7);
        let noisy = |changed: bool| -> Vec<Option<TracedTexel>> {
            (0..49)
                .map(|i| {
                    let (x, y) = (i % 7, i / 7);
                    let ao = if x == 5 || (x + y) % 2 == 0 { 0.0 } else { 1.0 };
                    Some(TracedTexel { ao, depth: 10.0, normal: Vec3::Z, changed })
                })
                .collect()
        };
        let middle = UVec2::new(3, 3);
        let narrow = prefilter(&noisy(false), size, middle, 1);
        let wide = prefilter(&noisy(true), size, middle, 1);
        // By hand: the 5x5 texels at width 2, against the 3x3 at width 1 (which the shadow does not reach).
        let (mut sum, mut weights) = (0.0f32, 0.0f32);
        for dy in -2i32..=2 {
            for dx in -2i32..=2 {
                let (x, y) = (3 + dx, 3 + dy);
                let ao = if x == 5 || (x + y) % 2 == 0 { 0.0 } else { 1.0 };
                let w = (-((dx * dx + dy * dy) as f32) / 8.0).exp();
                (sum, weights) = (sum + w * ao, weights + w);
            }
        }
        assert!((wide - sum / weights).abs() < 1e-6, "{wide} against {}", sum / weights);
        assert!(wide < narrow, "the shadow two texels away counts: {wide} {narrow}");
        // Off, it is off either way; and the flag survives the texel's packing.
        assert_eq!(prefilter(&noisy(true), size, middle, 0), 0.0);
        assert!(TracedTexel { ao: 0.5, depth: 10.0, normal: Vec3::Z, changed: true }.stored().changed);
        assert!(!TracedTexel { ao: 0.5, depth: 10.0, normal: Vec3::Z, changed: false }.stored().changed);
    }

    #[test]
    fn a_window_of_rays_that_agree_by_chance_stays_as_wide_as_they_can_tell() {
        // Nine one-ray texels that all escaped: their spread is nil, but nine rays only tell that the
        // mean is above 0.69 (Wilson's interval at two standard errors).
        let (lower, upper) = sample_interval(1.0, 9.0);
        assert!((lower - 9.0 / 13.0).abs() < 1e-5 && (upper - 1.0).abs() < 1e-5, "{lower} {upper}");
        let (lower, upper) = sample_interval(0.0, 9.0);
        assert!(lower.abs() < 1e-5 && (upper - 4.0 / 13.0).abs() < 1e-5, "{lower} {upper}");
        // It holds the mean, and closes as the rays grow in number.
        for m in [0.0, 0.1, 0.5, 0.85, 1.0] {
            let (a, b) = sample_interval(m, 9.0);
            let (c, d) = sample_interval(m, 900.0);
            let holds = |lo: f32, hi: f32| lo <= m + 1e-6 && m <= hi + 1e-6;
            assert!(holds(a, b) && holds(c, d) && d - c < (b - a) * 0.2, "{m}: {a} {b} {c} {d}");
        }
        let escaped = TracedTexel { ao: 1.0, depth: 10.0, normal: Vec3::Z, changed: false };
        let open = Some(escaped);
        let size = UVec2::new(3, 3);
        let window = trace_window(&[open; 9], size, UVec2::ONE, 1);
        assert!((window.0 - 9.0 / 13.0).abs() < 1e-5 && (window.1 - 1.1).abs() < 1e-6, "{window:?}");
        // A pixel of AO 0.85 keeps its 127 frames: no light speck.
        let (ao, count) = temporal_blend(0.85, 126.0, window, 1.0, 127.0, NONE);
        assert!((ao - (0.85 + 0.15 / 127.0)).abs() < 1e-6 && count == 127.0, "{ao} {count}");
        // More rays tell more; near occluders that moved the window closes as before, so that the shadow
        // one left is cleared at once.
        assert!(trace_window(&[open; 9], size, UVec2::ONE, 4).0 > window.0);
        let mut moved = [open; 9];
        moved[4] = Some(TracedTexel { changed: true, ..escaped });
        assert_eq!(trace_window(&moved, size, UVec2::ONE, 1), (0.9, 1.1));
        // A noisy neighbourhood's window is as wide as its spread already.
        assert_eq!(neighborhood_window(4.5, 4.5, 9.0, 9.0), neighborhood_window(4.5, 4.5, 9.0, 0.0));
    }

    #[test]
    fn the_stand_in_is_taken_from_the_pixels_own_surface() {
        // A 3x3 trace: the middle row shows the pixel's surface (AO 0.5), the rows above and below a surface
        // far behind it (AO 1): the stand-in is 0.5, the window spans both.
        let far = Some(TracedTexel { ao: 1.0, depth: 40.0, normal: Vec3::Z, changed: false });
        let trace = [far, far, far, texel(0.5), texel(0.5), texel(0.5), far, far, far];
        let size = UVec2::new(3, 3);
        assert_eq!(stand_in(&trace, size, UVec2::ONE, 10.0, Vec3::Z, 1), 0.5);
        let window = trace_window(&trace, size, UVec2::ONE, 1);
        assert!(window.0 < 0.5 && window.1 > 1.0, "{window:?}");
        // A surface none of the texels shows: the mean of all of them.
        assert_eq!(stand_in(&trace, size, UVec2::ONE, 20.0, Vec3::Z, 1), (6.0 + 1.5) / 9.0);
        // At the corner, the four texels inside the trace: two far (1), two on the surface (0.5).
        assert_eq!(stand_in(&trace, size, UVec2::ZERO, 40.0, Vec3::Z, 1), 1.0);
        assert_eq!(trace_window(&trace, size, UVec2::ZERO, 1), neighborhood_window(3.0, 2.5, 4.0, 4.0));
        // No texel shows geometry: no window, the stand-in open.
        assert_eq!(trace_window(&[None; 9], size, UVec2::ONE, 1), (-1.0, 2.0));
        assert_eq!(stand_in(&[None; 9], size, UVec2::ONE, 10.0, Vec3::Z, 1), 1.0);
    }

    #[test]
    fn a_converged_still_pixel_shows_the_same_ao_until_its_history_leaves_it() {
        // Window (0.5, 0.9): the current AO's deviation 0.05 (its floor, 0.1, halved), so a history of 100
        // frames may stray 0.05 / sqrt(199), about 0.0035, from what the pixel shows.
        let window = (0.5, 0.9);
        assert!((stable_reach(100.0, window) - 0.05 / 199f32.sqrt()).abs() < 1e-6);
        assert_eq!(stable_ao(Some((0.6, 60.0)), 0.603, 100.0, 16.0, NONE, window), (0.6, 60.0));
        assert_eq!(stable_ao(Some((0.6, 60.0)), 0.597, 100.0, 16.0, NONE, window), (0.6, 60.0));
        assert_eq!(stable_ao(Some((0.6, 60.0)), 0.605, 100.0, 16.0, NONE, window), (0.605, 100.0));
        // A history that doubled since is shown.
        assert_eq!(stable_ao(Some((0.6, 50.0)), 0.603, 100.0, 16.0, NONE, window), (0.603, 100.0));
        // A history no longer than a moving view keeps (cut by a change near the pixel or a clamp), or a
        // pixel that showed nothing of its surface (a moving view, no history): the history.
        assert_eq!(stable_ao(Some((0.6, 12.0)), 0.603, 16.0, 16.0, NONE, window), (0.603, 16.0));
        assert_eq!(stable_ao(None, 0.603, 100.0, 16.0, NONE, window), (0.603, 100.0));
        // Near an occluder that moved enough to cap a history of 127 frames, the history.
        assert_eq!(stable_ao(Some((0.6, 60.0)), 0.603, 100.0, 16.0, 100.0, window), (0.603, 100.0));
        assert_eq!(stable_ao(Some((0.6, 60.0)), 0.603, 100.0, 16.0, 127.0, window), (0.6, 60.0));
        // A noisier neighbourhood, a longer reach (0.125 / sqrt(199), about 0.0089); NaN shown (never
        // written) is never kept.
        assert_eq!(stable_ao(Some((0.6, 60.0)), 0.608, 100.0, 16.0, NONE, (0.0, 1.2)), (0.6, 60.0));
        assert_eq!(stable_ao(Some((f32::NAN, 60.0)), 0.603, 100.0, 16.0, NONE, window), (0.603, 100.0));
        // As the GPU keeps it.
        assert_eq!(shown_stored((0.5, 127.0)), (32768.0 / 65535.0, 127.0));
    }

    #[test]
    fn a_still_pixel_flickers_less_and_is_as_right() {
        // A pixel of AO 0.7 traced every frame with noise of deviation 0.058 (uniform within 0.1), its history
        // up to 127 frames: after it converged, the history moves every frame, what the pixel shows seldom,
        // and the one is about as far from the truth as the other.
        let (window, truth) = ((0.5, 0.9), 0.7);
        let mut seed = 12345u32;
        let mut noise = move || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 0.2 - 0.1
        };
        let (mut ao, mut count, mut shown): (f32, f32, Option<(f32, f32)>) = (0.0, 0.0, None);
        let (mut history_moves, mut shown_moves, mut history_error, mut shown_error) = (0, 0, 0.0, 0.0);
        for frame in 0..4000 {
            let before = (ao, shown);
            (ao, count) = temporal_blend(ao, count, window, truth + noise(), 127.0, NONE);
            let s = stable_ao(shown, ao, count, 16.0, NONE, window);
            shown = Some(s);
            let s = s.0;
            if frame >= 1000 {
                history_moves += (ao != before.0) as u32;
                shown_moves += (Some(s) != before.1.map(|b| b.0)) as u32;
                history_error += (ao - truth).abs();
                shown_error += (s - truth).abs();
            }
        }
        let (history_error, shown_error) = (history_error / 3000.0, shown_error / 3000.0);
        println!(
            "moves in 3000 frames: history {history_moves}, shown {shown_moves}; error {history_error:.5}, {shown_error:.5}"
        );
        assert_eq!(history_moves, 3000);
        assert!(shown_moves < 150, "{shown_moves}");
        assert!(shown_error < 1.25 * history_error, "{shown_error} against {history_error}");
    }
}
