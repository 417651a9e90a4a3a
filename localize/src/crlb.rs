//! Cramér–Rao bounds of the frame models, and Mortensen's closed forms.
//!
//! The Fisher information is always that of the model actually fitted
//! (pixel-integrated Gaussian, parameters `[x, y, N, b]` and σ when fitted):
//!
//! * Poisson: `I = Σ_k ∂μ_k ∂μ_kᵀ / μ_k`;
//! * EMCCD: the Poisson information divided by the excess-noise factor
//!   F² = 2 (high-gain limit);
//! * sCMOS: `Σ ∂μ∂μᵀ / (μ_k + v_k)` with the per-pixel read-noise variance
//!   v_k — the Poisson approximation of Huang et al. (2013), accurate when
//!   μ + v ≳ 1;
//! * SPAD binomial: see [`crate::spad::crlb_binomial`].
//!
//! The per-localisation `uncertainty [nm]` is `sqrt((var_x + var_y) / 2)`.

use crate::fit::NoiseModel;
use crate::linalg::invert_spd;
use crate::lm::{Mapped, PixelModel, Problem, Uniform};
use crate::roi::PixelMaps;

/// An emitter in ROI pixel coordinates (as in [`crate::fit::Fit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// Column, pixels from the ROI's left edge.
    pub x: f64,
    /// Row, pixels from the ROI's top edge.
    pub y: f64,
    /// PSF σ, pixels.
    pub sigma: f64,
    /// Photons detected from the emitter (all of them, also those falling
    /// outside the ROI).
    pub photons: f64,
    /// Background photons per pixel.
    pub background: f64,
}

/// Variances from a Cramér–Rao bound, pixels² (photons² for `photons`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crlb {
    /// Variance of x.
    pub var_x: f64,
    /// Variance of y.
    pub var_y: f64,
    /// Variance of the photon number.
    pub var_photons: f64,
}

impl Crlb {
    /// `sqrt((var_x + var_y)/2)`, the per-axis standard deviation reported
    /// as `uncertainty`.
    pub fn uncertainty(&self) -> f64 {
        ((self.var_x + self.var_y) / 2.0).sqrt()
    }
}

/// Cramér–Rao bound of a frame ROI (`side × side`) for the given noise model,
/// σ fixed or fitted; `None` when the information is singular.
pub fn crlb_frame(
    side: usize,
    em: &Emitter,
    maps: Option<&PixelMaps>,
    noise: NoiseModel,
    fit_sigma: bool,
) -> Option<Crlb> {
    let f2 = noise.excess_noise();
    match maps {
        None => bound(
            &Problem {
                side,
                model: Uniform,
                sigma_fixed: em.sigma,
            },
            em,
            f2,
            fit_sigma,
        ),
        Some(maps) => bound(
            &Problem {
                side,
                model: Mapped {
                    maps,
                    scmos: noise == NoiseModel::Scmos,
                },
                sigma_fixed: em.sigma,
            },
            em,
            f2,
            fit_sigma,
        ),
    }
}

fn bound<M: PixelModel>(prob: &Problem<M>, em: &Emitter, f2: f64, fit_sigma: bool) -> Option<Crlb> {
    let w = |mu: f64| 1.0 / (f2 * mu);
    if fit_sigma {
        let th = [em.x, em.y, em.photons, em.background, em.sigma];
        let c = invert_spd(&prob.weighted_outer(&th, w))?;
        Some(Crlb {
            var_x: c[0][0],
            var_y: c[1][1],
            var_photons: c[2][2],
        })
    } else {
        let th = [em.x, em.y, em.photons, em.background];
        let c = invert_spd(&prob.weighted_outer(&th, w))?;
        Some(Crlb {
            var_x: c[0][0],
            var_y: c[1][1],
            var_photons: c[2][2],
        })
    }
}

/// Mortensen et al. (Nat. Methods 2010), MLE of a pixelated Gaussian: the
/// per-axis variance `F² σa²/N · (1 + ∫₀¹ ln t / (1 + t/τ) dt)⁻¹` with
/// `σa² = σ² + a²/12` and `τ = 2π σa² b / (N a²)`. Units: σ and `a` in the
/// same length unit (the result is in its square), b photons per pixel.
pub fn mortensen_mle_variance(
    sigma: f64,
    a: f64,
    photons: f64,
    background: f64,
    excess: f64,
) -> f64 {
    let sa2 = sigma * sigma + a * a / 12.0;
    let tau = 2.0 * std::f64::consts::PI * sa2 * background / (photons * a * a);
    excess * sa2 / photons / (1.0 + log_integral(tau))
}

/// Mortensen's least-squares formula (the one ThunderSTORM reports):
/// `F² σa²/N · (16/9 + 8π σa² b / (N a²))`.
pub fn mortensen_lsq_variance(
    sigma: f64,
    a: f64,
    photons: f64,
    background: f64,
    excess: f64,
) -> f64 {
    let sa2 = sigma * sigma + a * a / 12.0;
    excess * sa2 / photons
        * (16.0 / 9.0 + 8.0 * std::f64::consts::PI * sa2 * background / (photons * a * a))
}

/// `∫₀¹ ln t / (1 + t/τ) dt` (≤ 0; 0 for τ = 0), by the substitution
/// `t = e^{−u}` and composite Simpson on `u ∈ [0, 60]`.
fn log_integral(tau: f64) -> f64 {
    if tau <= 0.0 {
        return 0.0;
    }
    // ∫₀^∞ −u e^{−u} / (1 + e^{−u}/τ) du
    let f = |u: f64| {
        let e = (-u).exp();
        -u * e / (1.0 + e / tau)
    };
    let n = 6000;
    let h = 60.0 / n as f64;
    let mut s = f(0.0) + f(60.0);
    for i in 1..n {
        s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_integral_limits() {
        // τ → ∞: ∫ ln t dt = −1 (background dominates, variance diverges).
        assert!((log_integral(1e9) + 1.0).abs() < 1e-6);
        // τ → 0: the integral vanishes like −τ (ln τ)² / 2.
        let t: f64 = 1e-9;
        let v = log_integral(t);
        assert!(v < 0.0 && v.abs() < t * t.ln().powi(2), "{v}");
        assert!(log_integral(0.1) < 0.0 && log_integral(0.1) > -1.0);
    }

    #[test]
    fn emccd_doubles_the_poisson_variance() {
        let em = Emitter {
            x: 4.5,
            y: 4.5,
            sigma: 1.5,
            photons: 500.0,
            background: 3.0,
        };
        let p = crlb_frame(9, &em, None, NoiseModel::Poisson, false).unwrap();
        let e = crlb_frame(9, &em, None, NoiseModel::Emccd, false).unwrap();
        assert!((e.var_x / p.var_x - 2.0).abs() < 1e-9);
        // Fitting σ can only cost precision (nothing in x for a centred
        // emitter, by symmetry; a lot in the photon number).
        let pf = crlb_frame(9, &em, None, NoiseModel::Poisson, true).unwrap();
        assert!(pf.var_x >= p.var_x * (1.0 - 1e-12));
        assert!(pf.var_photons > 1.2 * p.var_photons);
        // sCMOS read noise costs precision too.
        let mut maps = PixelMaps::uniform(9);
        maps.read_var.iter_mut().for_each(|v| *v = 2.0);
        let s = crlb_frame(9, &em, Some(&maps), NoiseModel::Scmos, false).unwrap();
        assert!(s.var_x > p.var_x);
        let s0 = crlb_frame(
            9,
            &em,
            Some(&PixelMaps::uniform(9)),
            NoiseModel::Scmos,
            false,
        )
        .unwrap();
        assert!((s0.var_x / p.var_x - 1.0).abs() < 1e-12);
    }
}
