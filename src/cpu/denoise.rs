//! The CPU twin of HAO's denoiser and upsampling (`src/ao/hao_denoise.wgsl`, `hao_upsample.wgsl`): the
//! bilateral weight of a tap and the taps through which a full-resolution pixel reads a half-resolution
//! trace.

use glam::{IVec2, UVec2, Vec3};

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

/// The texels of a half-resolution image (`size` texels) that full-resolution `pixel` reads when it is
/// upsampled (WGSL: `upsample`), each with its weight before [`bilateral_weight`]'s depth and normal terms.
/// A texel's value stands for its 2x2 block's middle (the trace samples the block's pixels in turn), so a
/// pixel's centre lies a quarter of a texel from the nearest: the 2x2 nearest texels, weighed linearly
/// (clamped to the image).
pub fn upsample_taps(pixel: UVec2, size: UVec2) -> [(IVec2, f32); 4] {
    let u = (pixel.as_vec2() + 0.5) * 0.5 - 0.5;
    let base = u.floor().as_ivec2();
    let f = u - u.floor();
    std::array::from_fn(|k| {
        let o = IVec2::new(k as i32 & 1, k as i32 >> 1);
        let t = (base + o).clamp(IVec2::ZERO, size.as_ivec2() - 1);
        let wx = if o.x == 1 { f.x } else { 1.0 - f.x };
        let wy = if o.y == 1 { f.y } else { 1.0 - f.y };
        (t, wx * wy)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upsampling_is_bilinear_between_block_middles() {
        // Pixel 2 lies a quarter of a texel before texel 1's middle, pixel 3 a quarter after.
        let size = UVec2::new(8, 8);
        let weights = |p: UVec2| {
            let mut w: Vec<(IVec2, f32)> = upsample_taps(p, size).into_iter().filter(|t| t.1 > 0.0).collect();
            w.sort_by_key(|t| (t.0.y, t.0.x));
            w
        };
        let w = weights(UVec2::new(2, 3));
        let expect = [((0, 1), 0.25 * 0.75), ((1, 1), 0.75 * 0.75), ((0, 2), 0.25 * 0.25), ((1, 2), 0.75 * 0.25)];
        assert_eq!(w.len(), 4, "{w:?}");
        for ((texel, weight), ((x, y), e)) in w.iter().zip(expect) {
            assert_eq!(*texel, IVec2::new(x, y));
            assert!((weight - e).abs() < 1e-6, "{texel} {weight} {e}");
        }
        // At the border the taps are clamped to the image, the weights still sum to one.
        let sum: f32 = upsample_taps(UVec2::ZERO, size).iter().map(|t| t.1).sum();
        assert!((sum - 1.0).abs() < 1e-6);
    }

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
