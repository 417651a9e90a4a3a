//! The Gaussian PSF integrated over each pixel.
//!
//! The paper approximates the PSF by a Gaussian of σ = r/3, r = 0.61 λ/NA
//! ([`Optics::psf_sigma_nm`](smartagg_model::params::Optics::psf_sigma_nm)).
//! A 2-D isotropic Gaussian is separable, so the fraction of the molecule's
//! photons landing in pixel (i, j) is exactly `gx[i] · gy[j]`, where `gx[i]`
//! is the 1-D Gaussian's mass in `[i, i+1)` (pixel units), computed from
//! erf/erfc: sub-pixel exact, no sampling grid. The complementary form is used
//! in the tails so that tiny fractions stay accurate (no 1 − 1 cancellation).

use std::f64::consts::SQRT_2;

/// Mass of the Gaussian N(`centre`, `sigma`²) in `[a, b]`, accurate in the tails.
pub fn gaussian_mass(a: f64, b: f64, centre: f64, sigma: f64) -> f64 {
    let s = sigma * SQRT_2;
    let za = (a - centre) / s;
    let zb = (b - centre) / s;
    let v = if za >= 0.0 {
        0.5 * (libm::erfc(za) - libm::erfc(zb))
    } else if zb <= 0.0 {
        0.5 * (libm::erfc(-zb) - libm::erfc(-za))
    } else {
        0.5 * (libm::erf(zb) + libm::erf(-za))
    };
    v.max(0.0)
}

/// Profiles stop this many σ from the centre. The mass beyond is
/// 2·Φ(−13) ≈ 1e-38 of the total: no 53-bit uniform draw can select a pixel
/// out there, so sampling is unchanged, and the in-field fraction changes by
/// less than one part in 10³⁷.
const SUPPORT_SIGMAS: f64 = 13.0;

/// The pixel-integrated 1-D profile of one emitter along one axis of the
/// field, with its cumulative sum for sampling.
#[derive(Debug, Clone)]
pub struct AxisProfile {
    /// First pixel with (possibly) non-zero mass.
    start: usize,
    /// Cumulative mass: `cum[k] = Σ_{j ≤ k} g[start + j]`.
    cum: Vec<f64>,
}

impl AxisProfile {
    /// Profile of a Gaussian centred at `centre_px` (pixel units, pixel `k`
    /// covers `[k, k+1)`) of width `sigma_px` over pixels `0..len`, within
    /// 13 σ of the centre.
    pub fn new(centre_px: f64, sigma_px: f64, len: usize) -> AxisProfile {
        let reach = SUPPORT_SIGMAS * sigma_px;
        let lo = (centre_px - reach).floor().max(0.0);
        let hi = (centre_px + reach).ceil().min(len as f64);
        // NaN (a non-finite centre) also yields an empty profile.
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return AxisProfile {
                start: 0,
                cum: Vec::new(),
            };
        }
        let (lo, hi) = (lo as usize, hi as usize);
        let mut cum = Vec::with_capacity(hi - lo);
        let mut acc = 0.0;
        for k in lo..hi {
            acc += gaussian_mass(k as f64, k as f64 + 1.0, centre_px, sigma_px);
            cum.push(acc);
        }
        AxisProfile { start: lo, cum }
    }

    /// Fraction of the emitter's photons that fall inside the field along this axis.
    pub fn total(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// The pixels that may hold mass (the rest hold none).
    pub fn support(&self) -> std::ops::Range<usize> {
        self.start..self.start + self.cum.len()
    }

    /// Mass in pixel `k`.
    pub fn mass(&self, k: usize) -> f64 {
        if k < self.start || k >= self.start + self.cum.len() {
            return 0.0;
        }
        let j = k - self.start;
        self.cum[j] - if j == 0 { 0.0 } else { self.cum[j - 1] }
    }

    /// The pixel a photon lands in, given `u` uniform in [0, 1): inversion of
    /// the cumulative mass (conditional on landing inside the field).
    /// Must not be called when [`Self::total`] is 0.
    #[inline]
    pub fn sample(&self, u: f64) -> usize {
        let target = u * self.total();
        let j = self.cum.partition_point(|&c| c <= target);
        self.start + j.min(self.cum.len() - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masses_sum_to_one_and_match_a_riemann_sum() {
        let p = AxisProfile::new(10.3, 1.5, 40);
        // Missing: the tail left of pixel 0, 6.9 sigma out.
        let missing = 0.5 * libm::erfc(10.3 / (1.5 * SQRT_2));
        assert!((p.total() - (1.0 - missing)).abs() < 1e-14);
        // Midpoint rule with 10,000 sub-intervals per pixel.
        for k in [6usize, 10, 11, 14] {
            let n = 10_000;
            let mut s = 0.0;
            for i in 0..n {
                let x = k as f64 + (i as f64 + 0.5) / n as f64;
                s += (-(x - 10.3f64).powi(2) / (2.0 * 1.5 * 1.5)).exp();
            }
            s /= n as f64 * 1.5 * (2.0 * std::f64::consts::PI).sqrt();
            assert!(
                (p.mass(k) - s).abs() < 1e-9,
                "pixel {k}: {} vs {s}",
                p.mass(k)
            );
        }
    }

    #[test]
    fn tails_stay_accurate() {
        // 20 sigma out: mass ~ 2.7e-89, and erf(b)-erf(a) would give 0.
        let m = gaussian_mass(20.0, 21.0, 0.0, 1.0);
        assert!(m > 1e-90 && m < 1e-87, "{m}");
        assert_eq!(gaussian_mass(1e6, 1e6 + 1.0, 0.0, 1.0), 0.0);
    }

    #[test]
    fn edge_fraction_and_outside() {
        // Centre on the left edge: half the mass is in the field.
        let p = AxisProfile::new(0.0, 2.0, 100);
        assert!((p.total() - 0.5).abs() < 1e-14);
        let far = AxisProfile::new(-1000.0, 2.0, 100);
        assert_eq!(far.total(), 0.0);
    }

    #[test]
    fn sampling_never_picks_an_empty_pixel() {
        let p = AxisProfile::new(3.5, 0.2, 8);
        for i in 0..1000 {
            let k = p.sample(i as f64 / 1000.0);
            assert!(p.mass(k) > 0.0);
        }
        assert!(p.mass(p.sample(1.0 - f64::EPSILON)) > 0.0);
    }
}
