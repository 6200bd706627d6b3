//! Equation 3: choosing the safety factor gamma for a tolerated bias, `gamma = -B ln(A p)`.
//!
//! `A = 1 / p_1` with `p_1` the bias at `gamma = 1`; `B = -E[gamma / ln(p / p_1)]` over measurements at other
//! factors. The paper fits `A` and `B` once and reuses them; here they are fitted on the mesh at hand (the
//! voxelize tool measures a few factors against the ground truth, then picks gamma).

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
