//! The CPU twin of HAO's denoiser (`src/ao/hao_denoise.wgsl`, `hao_denoise_vertical.wgsl`): the bilateral
//! weight of a tap.

use glam::Vec3;

/// The weight of a tap `offset` texels away with view depth `depth` and normal `normal`, against the
/// centre's (WGSL: `bilateral_weight`): a Gaussian in distance over `radius`, falling with the relative
/// depth difference and with the angle of the normals.
pub fn bilateral_weight(
    offset: f32,
    radius: f32,
    center_depth: f32,
    depth: f32,
    center_normal: Vec3,
    normal: Vec3,
) -> f32 {
    let spatial = (-offset * offset / (2.0 * (radius * radius).max(1.0))).exp();
    let depth_w = (-(depth - center_depth).abs() / (0.02 * center_depth.abs() + 1.0e-4)).exp();
    let c = center_normal.dot(normal).max(0.0);
    spatial * depth_w * c.powi(16)
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
    }
}
