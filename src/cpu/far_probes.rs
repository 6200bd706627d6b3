//! The far probes of voxel global illumination (WGSL `gi_probes.wgsl`, `write_probes` with `far` set): a
//! second, coarser window of probes around the camera, so that the surfaces beyond the near window
//! ([`super::probes`]) still get indirect light, written as a second irradiance volume that Bevy's PBR
//! blends with the near one.
//!
//! Where two irradiance volumes hold a point, Bevy 0.19 takes their weighted mean
//! (`irradiance_volume.wgsl`: the sum of each volume's light times its weight, over the weights' sum; a
//! `LightProbe` of no falloff weighs 1 everywhere inside it). Inside the near window that mean is half the
//! near volume's light and half the far one's. So the near volume is written to make up for it: a near
//! probe holds `2 w F + (1 - 2 w) C`, where `F` is its own light, `w` its [`ProbeWindow::edge_fade`] and `C`
//! the far volume's light at the probe's point as Bevy samples it ([`sample_faces`]). Bevy's mean at a
//! point of the near window is then `w F + (1 - w) C`, interpolated: the near light where it is whole, the
//! far light at the near window's edge, a blend between, without a seam where the near window ends (its
//! outermost probes hold `C`, and the far volume alone holds `C` just past them; but on a near axis of
//! fewer than 4 probes, which does not fade, the light steps there from `F` to `C`). It is exact (up to the
//! texels' f16 rounding) because the
//! far lattice's spacing is a whole multiple of the near one's ([`far_window`]): within a far probe cell,
//! `C` is trilinear, and the near volume's trilinear interpolation of its values at the near lattice points
//! reproduces it (a trilinear function sampled on a finer aligned lattice is interpolated exactly), but in
//! the near window's outer half spacing, where Bevy holds its outermost probes' value (there the mean is
//! half the far light at the outermost probe and half the far light at the point: a step of at most half
//! of how much the far light changes over half a near spacing, where the near window ends). The
//! far window holds the near one within its probes ([`far_counts_needed`]), where Bevy's sampling is not
//! clamped. Without binding arrays Bevy binds one irradiance volume; the far window is then off and the
//! near probes are written faded out to nothing (`w F`).

use super::probes::{ProbeWindow, probe_window, sample_faces};
use glam::{UVec3, Vec3};

/// The far window around `focus` for the near window's spacing `spacing`: `counts` probes `factor`
/// spacings apart, on the near lattice's every `factor`-th point (see [`probe_window`]).
pub fn far_window(focus: Vec3, spacing: f32, factor: u32, counts: UVec3) -> Option<ProbeWindow> {
    probe_window(focus, spacing * factor as f32, counts)
}

/// The fewest far probes along each axis that hold a near window of `near_counts` probes within their
/// span wherever the camera is (the near bounds reach half a near spacing past its probes; each window's
/// middle probe is its lattice point nearest the camera, so their middles differ by up to half of each
/// spacing), with a far spacing to spare.
pub fn far_counts_needed(near_counts: UVec3, factor: u32) -> UVec3 {
    let k = factor.max(1);
    // The far probes span (ceil(c / 2) - 1) far spacings on the short side of their middle; the near bounds
    // reach (floor(n / 2) + 0.5) near spacings on their long side, plus the two half-spacings.
    near_counts.map(|n| 2 * ((n / 2 + 1).div_ceil(k) + 3))
}

/// A near probe's faces as written into its irradiance volume (WGSL `write_probes`): its own light `own`
/// times its edge fade `fade` without a far window (`far` `None`), or with one `2 fade own + (1 - 2 fade)
/// far`, where `far` is the far volume's light at the probe ([`sample_faces`]; see the module's doc).
pub fn near_texel(own: [Vec3; 6], fade: f32, far: Option<[Vec3; 6]>) -> [Vec3; 6] {
    match far {
        None => own.map(|f| f * fade),
        Some(c) => std::array::from_fn(|k| own[k] * (2.0 * fade) + c[k] * (1.0 - 2.0 * fade)),
    }
}

/// A probe's faces as its window's irradiance volume holds them without a far window (WGSL `far_texel` and
/// `write_probes`): its history `faces` within f16's range, times its edge fade `fade`; nothing for a
/// probe not yet gathered (`None`).
pub fn far_texel(faces: Option<[Vec3; 6]>, fade: f32) -> [Vec3; 6] {
    faces.map_or([Vec3::ZERO; 6], |f| f.map(|f| f.min(Vec3::splat(F16_MAX)) * fade))
}

/// The largest finite f16, which the irradiance volumes' texels are held within.
pub const F16_MAX: f32 = 65504.0;

/// The faces Bevy's PBR reads at `p` from the near and the far volumes together (each a window and its
/// texels' faces): the mean of those that hold `p`, as Bevy weighs irradiance volumes of no falloff; `None`
/// where neither does.
pub fn sample_both(
    near: (&ProbeWindow, &dyn Fn(UVec3) -> [Vec3; 6]),
    far: Option<(&ProbeWindow, &dyn Fn(UVec3) -> [Vec3; 6])>,
    p: Vec3,
) -> Option<[Vec3; 6]> {
    let found: Vec<[Vec3; 6]> = std::iter::once(sample_faces(near.0, near.1, p))
        .chain(far.map(|(w, f)| sample_faces(w, f, p)))
        .flatten()
        .collect();
    (!found.is_empty()).then(|| std::array::from_fn(|k| found.iter().map(|f| f[k]).sum::<Vec3>() / found.len() as f32))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::probes::ambient_cube;
    use glam::IVec3;

    /// A smooth, uneven light over the world: faces that differ by face and by place.
    fn light(p: Vec3, k: usize) -> Vec3 {
        let s = (p.x * 0.37 + k as f32).sin() + (p.y * 0.23).cos() * (p.z * 0.31 + 0.5 * k as f32).sin();
        Vec3::new(2.0 + s, 3.0 - 0.5 * s, 1.5 + 0.25 * s * s)
    }

    #[test]
    fn bevys_mean_of_the_two_volumes_is_the_near_light_faded_into_the_far_one_without_a_seam() {
        for focus in [Vec3::new(0.3, 1.1, -0.2), Vec3::new(7.9, -3.3, 12.6), Vec3::new(-0.74, 0.26, 0.99)] {
            let (spacing, factor) = (0.5, 4);
            let near = probe_window(focus, spacing, UVec3::new(12, 8, 12)).unwrap();
            let counts = far_counts_needed(near.counts, factor);
            let far = far_window(focus, spacing, factor, counts).unwrap();
            // The far probes' texels: their light, faded toward their own edges.
            let far_texel = |w: UVec3| {
                let q = far.min + w.as_ivec3();
                std::array::from_fn(|k| light(far.position(q), k) * far.edge_fade(q))
            };
            // The near probes' light differs from the far volume's: its own light, doubled in x.
            let own = |q: IVec3| -> [Vec3; 6] { std::array::from_fn(|k| light(near.position(q), k) * 2.0) };
            let near_texel_at = |w: UVec3| {
                let q = near.min + w.as_ivec3();
                let c = sample_faces(&far, far_texel, near.position(q)).expect("the near probes lie in the far window");
                near_texel(own(q), near.edge_fade(q), Some(c))
            };
            let read = |p: Vec3| sample_both((&near, &near_texel_at), Some((&far, &far_texel)), p).unwrap();
            // Inside the near window: Bevy's mean is the near texels' fade-blend, interpolated: at a near probe
            // exactly `w F + (1 - w) C`.
            for i in (0..near.len()).step_by(7) {
                let q = near.lattice(i);
                let (w, p) = (near.edge_fade(q), near.position(q));
                let c = sample_faces(&far, far_texel, p).unwrap();
                let want: [Vec3; 6] = std::array::from_fn(|k| own(q)[k] * w + c[k] * (1.0 - w));
                let got = read(p);
                for k in 0..6 {
                    assert!((got[k] - want[k]).abs().max_element() < 1e-4, "{q} face {k}: {} {}", got[k], want[k]);
                }
            }
            // Where the near light is faded out, between the probes too, the far volume's light, exactly (the
            // far light is reproduced by the near volume's interpolation), within the near probes' span (in
            // the outer half spacing Bevy holds the outermost probes' value).
            let (first, last) = (near.position(near.min), near.position(near.min + near.counts.as_ivec3() - 1));
            for t in 0..400 {
                let f = Vec3::new((t as f32 * 0.618).fract(), (t as f32 * 0.414).fract(), (t as f32 * 0.732).fract());
                let p = first + (last - first) * f;
                let inner = (p / spacing - focus / spacing).abs();
                let reach = near.counts.as_vec3().map(|c| (c / 2.0).ceil() - 1.5);
                // Beyond the reach on some axis, with its neighbouring probes too: all faded to 0.
                if (0..3).any(|a| inner[a] > reach[a] + 1.0) {
                    let c = sample_faces(&far, far_texel, p).unwrap();
                    let got = read(p);
                    for k in 0..6 {
                        assert!((got[k] - c[k]).abs().max_element() < 1e-3, "{p} face {k}: {} {}", got[k], c[k]);
                    }
                }
            }
            // Across the near window's bounds, along a line through it: no step.
            let (lo, hi) = near.bounds();
            let n = Vec3::new(0.3, 0.8, -0.5).normalize();
            let mut last: Option<Vec3> = None;
            let steps = 400;
            for s in 0..=steps {
                let x = lo.x - 1.0 + (hi.x - lo.x + 2.0) * s as f32 / steps as f32;
                let p = Vec3::new(x, focus.y + 0.2, focus.z - 0.1);
                let e = ambient_cube(&read(p), n);
                if let Some(l) = last {
                    assert!((e - l).abs().max_element() < 0.2, "a step at x = {x}: {l} -> {e}");
                }
                last = Some(e);
            }
        }
    }

    #[test]
    fn the_far_window_holds_the_near_one_within_its_probes_wherever_the_camera_is() {
        for factor in [2, 3, 4, 16] {
            for near_counts in [UVec3::new(48, 24, 48), UVec3::new(5, 2, 127), UVec3::splat(128)] {
                let counts = far_counts_needed(near_counts, factor);
                for t in 0..500 {
                    let focus = Vec3::new(t as f32 * 0.731, t as f32 * -0.377, t as f32 * 1.913);
                    let near = probe_window(focus, 0.5, near_counts).unwrap();
                    let far = far_window(focus, 0.5, factor, counts).unwrap();
                    let (lo, hi) = near.bounds();
                    let first = far.position(far.min);
                    let last = far.position(far.min + far.counts.as_ivec3() - IVec3::ONE);
                    let spare = far.spacing * 0.999;
                    assert!(
                        (lo - first).min_element() >= spare && (last - hi).min_element() >= spare,
                        "factor {factor}, {near_counts}, focus {focus}"
                    );
                }
            }
        }
    }

    #[test]
    fn without_a_far_window_a_near_probe_fades_to_nothing() {
        let own = [Vec3::ONE; 6];
        assert_eq!(near_texel(own, 0.25, None), [Vec3::splat(0.25); 6]);
        // With one: its own light where whole, the far light where faded out.
        let c = [Vec3::splat(3.0); 6];
        assert_eq!(near_texel(own, 1.0, Some(c)), [Vec3::splat(-1.0); 6]);
        assert_eq!(near_texel(own, 0.0, Some(c)), c);
        // A far probe's texel: its faces within f16's range, then faded; nothing before its first update.
        assert_eq!(far_texel(None, 1.0), [Vec3::ZERO; 6]);
        assert_eq!(far_texel(Some([Vec3::splat(1.0e9); 6]), 0.5), [Vec3::splat(F16_MAX * 0.5); 6]);
    }
}
