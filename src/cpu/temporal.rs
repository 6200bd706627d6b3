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
//!    minus two standard deviations and [`CLAMP_MARGIN`] ([`neighborhood_window`]). Where an occluder has
//!    gone, every ray of the neighbourhood now escapes, the window closes around 1 and the shadow it left is
//!    clamped away in one frame. A clamped history also loses its weight: at most [`CLAMPED_COUNT`] frames.
//! 3. **Where occluders move**, the clamp cannot tell a shadow arriving from noise when each pixel traces
//!    two rays. The voxel grid knows where it may have changed: the boxes of the dynamic occluders, this
//!    frame and last (`VoxelGrid::changed`). A pixel within `max_distance` of one keeps at most
//!    [`CHANGED_COUNT`] frames of history, so a moving character's shadow follows it within a few frames
//!    while the still scene around it converges.
//! 4. **Blend** ([`temporal_blend`]): with `c` frames of history, capped at
//!    `HybridAmbientOcclusion::accumulation_frames`, the new AO is `history + (current - history) / c`: the
//!    running mean of the last frames, an exponential average once the cap is reached.

/// Added to the neighbourhood window on each side, so that a pixel whose neighbours saw no occluder this
/// frame (common with few rays where AO is near 1) keeps its history.
pub const CLAMP_MARGIN: f32 = 0.1;

/// The most frames of weight a history keeps after it was clamped.
pub const CLAMPED_COUNT: f32 = 2.0;

/// The most frames of weight a history keeps near voxels that may have changed.
pub const CHANGED_COUNT: f32 = 2.0;

/// The relative view-depth tolerance of [`history_accepts`].
pub const DEPTH_TOLERANCE: f32 = 0.02;

/// The least cosine between the current and the history normal of [`history_accepts`].
pub const NORMAL_TOLERANCE: f32 = 0.9;

/// Whether a history texel saw the surface a pixel sees now (WGSL: `history_accepts`): its view depth
/// against the depth the pixel's world position had in the previous view, and the cosine of their normals.
#[inline]
pub fn history_accepts(expected_depth: f32, history_depth: f32, normal_cosine: f32) -> bool {
    history_depth > 0.0
        && (history_depth - expected_depth).abs() <= DEPTH_TOLERANCE * expected_depth + 0.01
        && normal_cosine >= NORMAL_TOLERANCE
}

/// The clamping window of the history from the current AO of a pixel's 3x3 neighbourhood (WGSL:
/// `neighborhood_window`): `(sum, sum of squares, count)` of the neighbours that show geometry.
#[inline]
pub fn neighborhood_window(sum: f32, sum_squares: f32, count: f32) -> (f32, f32) {
    let mean = sum / count;
    let sigma = (sum_squares / count - mean * mean).max(0.0).sqrt();
    (mean - 2.0 * sigma - CLAMP_MARGIN, mean + 2.0 * sigma + CLAMP_MARGIN)
}

/// One pixel's blend (WGSL: `temporal_blend`): the history AO and its frames of weight (0: none), the
/// window, the current AO, the cap, and whether the voxels near the pixel may have changed. Returns the new
/// AO and its frames of weight.
#[inline]
pub fn temporal_blend(
    history: f32,
    history_count: f32,
    window: (f32, f32),
    current: f32,
    max_count: f32,
    near_change: bool,
) -> (f32, f32) {
    let mut h = history;
    let mut c = if near_change { history_count.min(CHANGED_COUNT) } else { history_count };
    if h < window.0 || h > window.1 {
        h = h.clamp(window.0, window.1);
        c = c.min(CLAMPED_COUNT);
    }
    let count = (c + 1.0).min(max_count.max(1.0));
    (if count <= 1.0 { current } else { h + (current - h) / count }, count)
}

/// The accumulation over a still camera (reprojection is the identity), frame by frame: the twin that the
/// GPU test holds the temporal pass to. `frames[k]` is frame `k`'s current AO, `width x height`, with `NaN`
/// for pixels that show no geometry; the result is the AO after the last frame.
pub fn accumulate_still(frames: &[Vec<f32>], width: usize, height: usize, max_count: f32) -> Vec<f32> {
    let mut ao = vec![f32::NAN; width * height];
    let mut count = vec![0.0f32; width * height];
    for frame in frames {
        let mut next_ao = ao.clone();
        let mut next_count = count.clone();
        for y in 0..height {
            for x in 0..width {
                let i = y * width + x;
                let current = frame[i];
                if current.is_nan() {
                    next_count[i] = 0.0;
                    continue;
                }
                let (mut sum, mut squares, mut n) = (0.0f32, 0.0f32, 0.0f32);
                for dy in -1i32..=1 {
                    for dx in -1i32..=1 {
                        let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                        if nx < 0 || ny < 0 || nx >= width as i32 || ny >= height as i32 {
                            continue;
                        }
                        let v = frame[ny as usize * width + nx as usize];
                        if !v.is_nan() {
                            sum += v;
                            squares += v * v;
                            n += 1.0;
                        }
                    }
                }
                let window = neighborhood_window(sum, squares, n);
                let (h, c) = if count[i] > 0.0 { (ao[i], count[i]) } else { (current, 0.0) };
                let (a, k) = temporal_blend(h, c, window, current, max_count, false);
                next_ao[i] = a;
                next_count[i] = k;
            }
        }
        ao = next_ao;
        count = next_count;
    }
    ao
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_still_pixel_averages_its_frames_up_to_the_cap() {
        let window = (-10.0, 10.0);
        let (mut ao, mut c) = (0.0, 0.0);
        for (k, x) in [0.2f32, 0.4, 0.9, 0.5].into_iter().enumerate() {
            (ao, c) = temporal_blend(ao, c, window, x, 16.0, false);
            assert_eq!(c, k as f32 + 1.0);
        }
        assert!((ao - 0.5).abs() < 1e-6, "{ao}");
        // At the cap, an exponential average with weight 1/cap.
        let (a, c) = temporal_blend(0.5, 4.0, window, 1.0, 4.0, false);
        assert_eq!((a, c), (0.625, 4.0));
        // A cap of 1 keeps no history.
        assert_eq!(temporal_blend(0.5, 9.0, window, 0.1, 1.0, false), (0.1, 1.0));
    }

    #[test]
    fn a_history_outside_the_window_is_clamped_and_loses_its_weight() {
        // An occluder has gone: the neighbourhood reads 1 everywhere, the old shadow of 0.4 is clamped to
        // 0.9 and weighs two frames.
        let window = neighborhood_window(9.0, 9.0, 9.0);
        assert_eq!(window, (0.9, 1.1));
        let (ao, c) = temporal_blend(0.4, 16.0, window, 1.0, 16.0, false);
        assert!((ao - (0.9 + 0.1 / 3.0)).abs() < 1e-6 && c == 3.0, "{ao} {c}");
    }

    #[test]
    fn near_moving_occluders_the_history_is_short() {
        // A shadow arrives (the clamp cannot see it in two-ray noise): far from any change the pixel moves
        // 1/16 of the way, near one a third.
        let window = (0.0, 1.2);
        assert_eq!(temporal_blend(1.0, 16.0, window, 0.52, 16.0, false).0, 0.97);
        let (ao, c) = temporal_blend(1.0, 16.0, window, 0.52, 16.0, true);
        assert!((ao - 0.84).abs() < 1e-6 && c == 3.0, "{ao} {c}");
    }

    #[test]
    fn reprojected_texels_are_kept_only_on_the_same_surface() {
        assert!(history_accepts(10.0, 10.1, 0.99));
        assert!(!history_accepts(10.0, 11.0, 0.99), "another surface behind");
        assert!(!history_accepts(10.0, 10.0, 0.5), "a crease");
        assert!(!history_accepts(10.0, 0.0, 1.0), "no history (background or never written)");
    }

    #[test]
    fn a_still_noisy_pixel_converges_to_its_mean() {
        // Two-ray AO of a surface whose true AO is 0.75: each pixel reads 0.5 or 1.0, alternating per frame,
        // its neighbours the other way (the trace's noise is decorrelated between pixels).
        let (w, h) = (3, 3);
        let frames: Vec<Vec<f32>> =
            (0..32).map(|k| (0..w * h).map(|i| if (i + k) % 2 == 0 { 0.5 } else { 1.0 }).collect()).collect();
        let ao = accumulate_still(&frames, w, h, 32.0);
        assert!(ao.iter().all(|a| (a - 0.75).abs() < 0.02), "{ao:?}");
        let one = accumulate_still(&frames[..1], w, h, 32.0);
        assert_eq!(one, frames[0]);
    }
}
