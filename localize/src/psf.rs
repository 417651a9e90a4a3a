//! The pixel-integrated Gaussian PSF and its derivatives.
//!
//! Coordinates are in ROI pixels with the ImageJ convention: pixel column `i`
//! covers `[i, i + 1)`, so its centre is at `i + 0.5`, and the ROI's top-left
//! corner is `(0, 0)`. The expected fraction of an emitter's photons that
//! lands in pixel `(i, j)` is `Ex_i · Ey_j`, a product of two 1-D integrals,
//! so a whole `R × R` ROI costs `2 (R + 1)` erf evaluations, not `R²`.

use crate::erf::erfc_nonneg_with_gauss;

/// Largest ROI side the fitters accept (their work arrays live on the stack).
pub const MAX_SIDE: usize = 64;

const FRAC_1_SQRT_2PI: f64 = 0.398_942_280_401_432_7;

/// The 1-D pixel integrals of a Gaussian along one axis, with their
/// derivatives with respect to the centre and to σ.
#[derive(Clone, Debug)]
pub struct AxisTerms {
    /// Number of pixels filled.
    pub n: usize,
    /// `E_i = ∫_i^{i+1} N(u; c, σ) du`, the fraction of photons in pixel `i`.
    pub e: [f64; MAX_SIDE],
    /// `∂E_i/∂c`.
    pub dc: [f64; MAX_SIDE],
    /// `∂E_i/∂σ` (only filled when asked for).
    pub ds: [f64; MAX_SIDE],
}

impl Default for AxisTerms {
    fn default() -> Self {
        AxisTerms {
            n: 0,
            e: [0.0; MAX_SIDE],
            dc: [0.0; MAX_SIDE],
            ds: [0.0; MAX_SIDE],
        }
    }
}

impl AxisTerms {
    /// Fills the terms for `n ≤ MAX_SIDE` pixels, centre `c` (pixels) and
    /// width `sigma > 0` (pixels). `with_sigma` also fills `ds`.
    #[inline(always)]
    pub fn compute(&mut self, n: usize, c: f64, sigma: f64, with_sigma: bool) {
        debug_assert!(n <= MAX_SIDE && sigma > 0.0);
        self.n = n;
        let inv = std::f64::consts::FRAC_1_SQRT_2 / sigma;
        let pdf_scale = FRAC_1_SQRT_2PI / sigma;
        let inv_sigma = 1.0 / sigma;
        // State at the previous edge: tail mass beyond it (on its own side of
        // the centre), whether it lies right of the centre, pdf and u·pdf.
        let mut prev_tail = 0.0;
        let mut prev_right = false;
        let mut prev_pdf = 0.0;
        let mut prev_updf = 0.0;
        for edge in 0..=n {
            let u = edge as f64 - c;
            let z = u * inv;
            let a = z.abs();
            let (g, tail) = if a < 27.0 {
                let g = (-a * a).exp();
                (g, 0.5 * erfc_nonneg_with_gauss(a, g))
            } else {
                (0.0, 0.0)
            };
            let right = z >= 0.0;
            let pdf = g * pdf_scale;
            let updf = u * pdf;
            if edge > 0 {
                let i = edge - 1;
                // Mass in [u_prev, u] without cancelling two numbers near 1.
                let mass = match (prev_right, right) {
                    (true, true) => prev_tail - tail,
                    (false, false) => tail - prev_tail,
                    _ => 1.0 - prev_tail - tail,
                };
                self.e[i] = mass.max(0.0);
                self.dc[i] = prev_pdf - pdf;
                if with_sigma {
                    self.ds[i] = (prev_updf - updf) * inv_sigma;
                }
            }
            prev_tail = tail;
            prev_right = right;
            prev_pdf = pdf;
            prev_updf = updf;
        }
    }
}

/// The expected photon fraction of every pixel of an `side × side` ROI for an
/// emitter at `(x, y)` with width `sigma` (row-major).
pub fn psf_image(side: usize, x: f64, y: f64, sigma: f64) -> Vec<f64> {
    let mut ax = AxisTerms::default();
    let mut ay = AxisTerms::default();
    let side = side.min(MAX_SIDE);
    ax.compute(side, x, sigma, false);
    ay.compute(side, y, sigma, false);
    let mut out = Vec::with_capacity(side * side);
    for j in 0..side {
        for i in 0..side {
            out.push(ax.e[i] * ay.e[j]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrals_sum_to_one_and_derivatives_match_differences() {
        let (n, c, s) = (40usize, 19.3, 1.7);
        let mut t = AxisTerms::default();
        t.compute(n, c, s, true);
        let total: f64 = t.e[..n].iter().sum();
        assert!((total - 1.0).abs() < 1e-11, "{total}");
        // A pixel straddling the centre: compare with erf directly.
        let want = 0.5
            * (crate::erf::erf((20.0 - c) / (s * 2f64.sqrt()))
                - crate::erf::erf((19.0 - c) / (s * 2f64.sqrt())));
        assert!((t.e[19] - want).abs() < 1e-12);
        let h = 1e-6;
        let mut tp = AxisTerms::default();
        let mut tm = AxisTerms::default();
        tp.compute(n, c + h, s, true);
        tm.compute(n, c - h, s, true);
        let mut sp = AxisTerms::default();
        let mut sm = AxisTerms::default();
        sp.compute(n, c, s + h, true);
        sm.compute(n, c, s - h, true);
        for i in 0..n {
            let dc = (tp.e[i] - tm.e[i]) / (2.0 * h);
            let ds = (sp.e[i] - sm.e[i]) / (2.0 * h);
            assert!((dc - t.dc[i]).abs() < 1e-7, "dc[{i}] {dc} vs {}", t.dc[i]);
            assert!((ds - t.ds[i]).abs() < 1e-7, "ds[{i}] {ds} vs {}", t.ds[i]);
        }
    }

    #[test]
    fn far_tails_keep_relative_accuracy() {
        // Emitter far left of a 9-pixel axis: pixel masses are tiny but
        // positive and decreasing, never zero from cancellation.
        let mut t = AxisTerms::default();
        t.compute(9, -10.0, 1.0, false);
        for i in 0..8 {
            assert!(t.e[i] > t.e[i + 1] && t.e[i + 1] >= 0.0);
        }
        assert!(t.e[0] > 1e-25 && t.e[0] < 1e-20, "{}", t.e[0]);
        // Extremely narrow and extremely wide PSFs stay finite.
        t.compute(9, 4.5, 1e-6, true);
        assert!(t.e[..9]
            .iter()
            .chain(&t.dc[..9])
            .chain(&t.ds[..9])
            .all(|v| v.is_finite()));
        assert!((t.e[4] - 1.0).abs() < 1e-12);
        t.compute(9, 4.5, 1e6, true);
        assert!(t.e[..9]
            .iter()
            .chain(&t.dc[..9])
            .chain(&t.ds[..9])
            .all(|v| v.is_finite()));
    }
}
