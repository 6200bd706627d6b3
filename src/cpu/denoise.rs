//! The CPU twin of HAO's denoiser: the bilateral weight with which the neighborhood pass filters each
//! frame's trace before the temporal pass accumulates it (`src/ao/hao_neighborhood.wgsl`, the weight in
//! `hao_common.wgsl`; the filter itself is [`super::temporal::prefilter`]), and the history's texel as the
//! temporal pass stores it.

use glam::Vec3;

/// A texel of the temporal history as the denoiser reads it (WGSL: ao, view depth, packed normal, frames).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistoryTexel {
    /// The accumulated AO.
    pub ao: f32,
    /// View depth; 0 or less for the background, which the filter skips.
    pub depth: f32,
    /// The surface's normal.
    pub normal: Vec3,
    /// Frames of weight the history holds.
    pub frames: f32,
}

impl HistoryTexel {
    /// The texel as the temporal pass stores it, in 64 bits (WGSL: `pack_history`, read back by
    /// `unpack_history`): the AO to 1/8191, the view depth rounded to 11 bits of mantissa (within 1/4096 of
    /// itself), the frames of weight to an eighth (at most 127). The normal is kept as it is: the GPU's 11 bits
    /// per octahedral coordinate are finer than its tests tell.
    pub fn stored(self) -> Self {
        let depth = f32::from_bits(((self.depth.max(0.0).to_bits() + 0x800) >> 12) << 12);
        Self {
            ao: (self.ao.clamp(0.0, 1.0) * 8191.0).round() / 8191.0,
            depth,
            normal: self.normal,
            frames: (self.frames.clamp(0.0, super::temporal::MAX_HISTORY_FRAMES) * 8.0).round() / 8.0,
        }
    }
}

/// The weight of a tap `offset` texels away with view depth `depth` and normal along `direction` (any
/// length: the GPU passes the octahedral code's direction unnormalized), against the centre's (unit
/// `center_normal`; WGSL: `bilateral_weight`): a Gaussian in distance over `radius`, falling with the
/// relative depth difference and with the angle of the normals (the cosine to the 16th power, from the
/// squared cosine without a square root).
pub fn bilateral_weight(
    offset: f32,
    radius: f32,
    center_depth: f32,
    depth: f32,
    center_normal: Vec3,
    direction: Vec3,
) -> f32 {
    // The Gaussian in distance times the fall with depth, as one exponential.
    let spatial = offset * offset / (2.0 * (radius * radius).max(1.0));
    let relative_depth = (depth - center_depth).abs() / (0.02 * center_depth.abs() + 1.0e-4);
    let c = center_normal.dot(direction).max(0.0);
    // (A zero direction, which no octahedral code decodes to, weighs nothing.)
    let c2 = c * c / direction.length_squared().max(1.0e-30);
    (-spatial - relative_depth).exp() * c2.powi(8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bilateral_weight_falls_with_distance_depth_and_angle() {
        let n = Vec3::Z;
        let w = bilateral_weight(0.0, 2.0, 10.0, 10.0, n, n);
        assert!((w - 1.0).abs() < 1e-6);
        assert!(bilateral_weight(2.0, 2.0, 10.0, 10.0, n, n) < w);
        assert!(bilateral_weight(0.0, 2.0, 10.0, 10.5, n, n) < 0.1, "another surface");
        assert!(bilateral_weight(0.0, 2.0, 10.0, 10.0, n, Vec3::X) == 0.0, "a crease");
        assert!(bilateral_weight(0.0, 2.0, 10.0, 10.0, n, Vec3::ZERO) == 0.0, "no normal");
        // The tap's normal direction at any length (the GPU's unnormalized octahedral direction): the same
        // weight as the unit normal, the cosine to the 16th power.
        let d = Vec3::new(0.3, 0.0, 1.0);
        let unit = bilateral_weight(1.0, 2.0, 10.0, 10.0, n, d.normalize());
        assert!((bilateral_weight(1.0, 2.0, 10.0, 10.0, n, 0.6 * d) - unit).abs() < 1e-6);
        let spatial = (-1.0f32 / 8.0).exp();
        assert!((unit - spatial * d.normalize().z.powi(16)).abs() < 1e-6, "{unit}");
    }

    #[test]
    fn the_stored_history_keeps_what_the_filters_tell_apart() {
        let t = HistoryTexel { ao: 0.123456, depth: 12.3456, normal: Vec3::Z, frames: 15.06 }.stored();
        assert!((t.ao - 0.123456).abs() <= 0.5 / 8191.0 + 1e-7, "{}", t.ao);
        assert!(((t.depth - 12.3456) / 12.3456).abs() <= 1.0 / 4096.0, "{}", t.depth);
        assert_eq!(t.frames, 15.0);
        // The background (depth 0) stays the background; the caps hold.
        let b = HistoryTexel { ao: 2.0, depth: 0.0, normal: Vec3::Z, frames: 300.0 }.stored();
        assert_eq!((b.ao, b.depth, b.frames), (1.0, 0.0, 127.0));
        // Storing twice changes nothing.
        assert_eq!(t.stored(), t);
    }
}
