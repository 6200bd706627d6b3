//! Equation 3: choosing the safety factor gamma for a tolerated bias, `gamma = -B ln(A p)`.
//!
//! `A = 1 / p_1` with `p_1` the bias at `gamma = 1`; `B = -E[gamma / ln(p / p_1)]` over measurements at other
//! factors. The paper fits `A` and `B` once and reuses them; here they are fitted on the geometry at hand:
//! the voxelize tool measures a few factors against the ground truth, and the plugin ([`calibrate`], for
//! `VoxelVolume::target_bias`) against the conservative voxelization of patches of the scene, which sets
//! every cell a triangle overlaps.

use super::grid::{VoxelGrid, VoxelOccupancy};
use super::mesh::TriangleMesh;
use super::tessellation::SubdivisionPattern;
use super::voxelize::{InjectionMode, VoxelizeSettings, voxelize_mesh};
use glam::{UVec3, Vec3};

/// A fitted bias model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasModel {
    /// `A = 1 / p_1`.
    pub a: f64,
    /// `B`, the mean of `-gamma / ln(p / p_1)`.
    pub b: f64,
    /// `p_1`, the bias measured at `gamma = 1` (a fraction, not a percentage).
    pub p1: f64,
}

impl BiasModel {
    /// Fits the model to `(gamma, bias)` samples, biases as fractions. Needs a sample at `gamma = 1` with a
    /// positive bias and at least one sample with `gamma > 1` and `0 < bias < p_1`; `None` otherwise (for
    /// example when gamma = 1 already has no bias, and any target is met by it).
    pub fn fit(samples: &[(f32, f64)]) -> Option<Self> {
        let p1 = samples.iter().find(|(g, _)| *g == 1.0)?.1;
        if p1 <= 0.0 {
            return None;
        }
        let terms: Vec<f64> = samples
            .iter()
            .filter(|(g, p)| *g > 1.0 && *p > 0.0 && *p < p1)
            .map(|(g, p)| -(*g as f64) / (p / p1).ln())
            .collect();
        if terms.is_empty() {
            return None;
        }
        let b = terms.iter().sum::<f64>() / terms.len() as f64;
        Some(Self { a: 1.0 / p1, b, p1 })
    }

    /// Equation 3: the gamma expected to give bias `p` (a fraction), `-B ln(A p)`, clamped to at least 1 and
    /// at most `max_gamma`. A target at or above `p_1` gives 1.
    pub fn gamma_for_bias(&self, p: f64, max_gamma: f32) -> f32 {
        if !(p > 0.0) {
            return max_gamma;
        }
        let g = -self.b * (self.a * p).ln();
        (g as f32).clamp(1.0, max_gamma)
    }
}

/// The gammas [`calibrate`] measures.
pub const CALIBRATION_GAMMAS: [f32; 7] = [1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0];
/// Patches [`calibrate`] samples, and their edge in cells.
pub const CALIBRATION_PATCHES: usize = 8;
/// See [`CALIBRATION_PATCHES`].
pub const CALIBRATION_PATCH_CELLS: u32 = 32;

/// What [`calibrate`] measured and fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// `(gamma, bias)` over the patches, biases as fractions.
    pub samples: Vec<(f32, f64)>,
    /// The model fitted to them (`None` when gamma 1 already misses nothing, or the bias does not fall).
    pub model: Option<BiasModel>,
    /// Cells the patches' conservative voxelization set (the truth the biases are measured against).
    pub truth_voxels: u64,
}

impl Calibration {
    /// The gamma for a target bias `p` (a fraction). Within the measured gammas, where the measured bias
    /// crosses `p`, interpolated linearly in `ln gamma` and `ln bias` (equation 3's law, extrapolated, puts
    /// gamma too low on curved meshes, whose bias falls more slowly than it predicts at high gamma); 1 when
    /// gamma 1 already meets `p`; past the last measured gamma, equation 3 fitted on the samples, at least
    /// that gamma and at most `max_gamma`.
    pub fn gamma_for_bias(&self, p: f64, max_gamma: f32) -> f32 {
        if !(p > 0.0) {
            return max_gamma;
        }
        let Some(k) = self.samples.iter().position(|s| s.1 <= p) else {
            let last = self.samples.last().map_or(1.0, |s| s.0);
            return self
                .model
                .map_or(max_gamma, |m| m.gamma_for_bias(p, max_gamma))
                .clamp(last.min(max_gamma), max_gamma);
        };
        if k == 0 {
            return 1.0;
        }
        let ((g0, b0), (g1, b1)) = (self.samples[k - 1], self.samples[k]);
        if !(b1 > 0.0) {
            // No miss at g1: the crossing is somewhere before it; take g1.
            return g1;
        }
        let t = (p.ln() - b0.ln()) / (b1.ln() - b0.ln());
        ((g0 as f64).ln() + t * ((g1 as f64).ln() - (g0 as f64).ln())).exp() as f32
    }
}

/// Equation 3 fitted on a scene: the world-space triangles `triangles` are voxelized in up to
/// [`CALIBRATION_PATCHES`] patches of [`CALIBRATION_PATCH_CELLS`]^3 cells of `cell_size`, centred on
/// triangles picked by area (evenly through the running total of their areas), in conservative mode (every cell a triangle overlaps: the truth)
/// and in centroid mode at [`CALIBRATION_GAMMAS`]; the bias at each gamma is the share of the truth's
/// cells that centroid mode missed, over all patches. `None` if no patch holds a voxel.
pub fn calibrate(triangles: &[[Vec3; 3]], cell_size: f32, pattern: SubdivisionPattern) -> Option<Calibration> {
    let valid: Vec<[Vec3; 3]> = triangles.iter().copied().filter(|t| t.iter().all(|p| p.is_finite())).collect();
    if valid.is_empty() || !(cell_size > 0.0 && cell_size.is_finite()) {
        return None;
    }
    let half = CALIBRATION_PATCH_CELLS as f32 / 2.0;
    let dims = UVec3::splat(CALIBRATION_PATCH_CELLS);
    let mut truth_voxels = 0u64;
    let mut missed = [0u64; CALIBRATION_GAMMAS.len()];
    // Patch centres spread by area (bias is a share of the surface's cells): at evenly spaced fractions of
    // the running total of the triangles' areas.
    let mut running = 0.0f64;
    let cumulative: Vec<f64> = valid
        .iter()
        .map(|t| {
            running += (t[1] - t[0]).cross(t[2] - t[0]).length() as f64;
            running
        })
        .collect();
    let patches = CALIBRATION_PATCHES.min(valid.len());
    for k in 0..patches {
        let at = (k as f64 + 0.5) / patches as f64 * running;
        let t = valid[cumulative.partition_point(|&c| c < at).min(valid.len() - 1)];
        let centre = (t[0] + t[1] + t[2]) / 3.0;
        let origin = ((centre / cell_size).floor() - Vec3::splat(half)) * cell_size;
        let Ok(grid) = VoxelGrid::new(origin, cell_size, dims) else { continue };
        let (lo, hi) = (origin, grid.world_max());
        let mut mesh = TriangleMesh::default();
        for t in &valid {
            let (tlo, thi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            if tlo.cmple(hi).all() && thi.cmpge(lo).all() {
                let base = mesh.positions.len() as u32;
                mesh.positions.extend_from_slice(t);
                mesh.triangles.push([base, base + 1, base + 2]);
            }
        }
        let run = |mode: InjectionMode, gamma: f32| {
            let out = VoxelOccupancy::new(grid, false);
            voxelize_mesh(&mesh, grid.grid_from_world(), &VoxelizeSettings { gamma, mode, pattern }, &out);
            out
        };
        let truth = run(InjectionMode::Conservative, 1.0);
        truth_voxels += truth.set_voxel_count();
        for (m, &gamma) in missed.iter_mut().zip(&CALIBRATION_GAMMAS) {
            *m += truth.count_not_in(&run(InjectionMode::Centroid, gamma));
        }
    }
    if truth_voxels == 0 {
        return None;
    }
    let samples: Vec<(f32, f64)> =
        CALIBRATION_GAMMAS.iter().zip(missed).map(|(&g, m)| (g, m as f64 / truth_voxels as f64)).collect();
    let model = BiasModel::fit(&samples);
    Some(Calibration { samples, model, truth_voxels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_logarithmic_law_exactly() {
        // Data made from gamma = -B ln(p / p1) with B = 2, p1 = 0.2: p = p1 exp(-gamma / B).
        let p1 = 0.2;
        let samples: Vec<(f32, f64)> = [1.0f32, 2.0, 4.0, 6.0]
            .iter()
            .map(|&g| (g, if g == 1.0 { p1 } else { p1 * (-(g as f64) / 2.0).exp() }))
            .collect();
        let m = BiasModel::fit(&samples).unwrap();
        assert!((m.b - 2.0).abs() < 1e-9);
        assert!((m.a - 5.0).abs() < 1e-9);
        let target = p1 * (-1.5f64).exp();
        assert!((m.gamma_for_bias(target, 16.0) - 3.0).abs() < 1e-5);
        assert_eq!(m.gamma_for_bias(0.5, 16.0), 1.0);
        assert_eq!(m.gamma_for_bias(1e-30, 16.0), 16.0);
    }

    #[test]
    fn refuses_to_fit_without_the_needed_samples() {
        assert_eq!(BiasModel::fit(&[(2.0, 0.1)]), None);
        assert_eq!(BiasModel::fit(&[(1.0, 0.0), (2.0, 0.0)]), None);
        assert_eq!(BiasModel::fit(&[(1.0, 0.1), (2.0, 0.0)]), None);
    }
}
