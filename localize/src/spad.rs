//! SPAD binomial maximum likelihood: exact under pile-up.
//!
//! A SPAD pixel reports at most one detection per bit-plane, so the count of
//! a pixel over `n` planes is binomial, not Poisson: with a detection rate λ
//! per plane, `p = 1 − e^{−λ}` per plane. Of the planes summed into a blink
//! record, about `n_on = t_e − t_s` carry the molecule and the remaining
//! `n_off` only background (docs/DESIGN.md §5), so a pixel count is
//!
//! `c_k = Bin(n_on, p_on,k) + Bin(n_off, p_off,k)`,
//! `λ_on,k = g_k (S · psf_k(x, y, σ) + B) + d_k`, `λ_off,k = g_k B + d_k`,
//!
//! with S the molecule's detections per on-plane before saturation (summed
//! over the PSF), B the background per pixel per plane, g_k the relative
//! efficiency (PRNU) and d_k the known dark counts per plane (DCR × τ).
//!
//! **Likelihood.** We use the *exact* log-likelihood of the sum of the two
//! binomials. The textbook convolution `P(c) = Σ_j Bin(j; n_off, p_off)
//! Bin(c − j; n_on, p_on)` costs O(c) per pixel (O(n²) over all counts), but
//! its terms, as a function of the split j, form a log-concave sequence whose
//! ratio `w_{j+1}/w_j` is a rational function of j: we walk it from the
//! smallest possible j, with that ratio, and stop once the terms decrease and
//! fall below 1e-17 of the sum — exact to double precision, typically 10–20
//! multiply-adds per pixel because the off-planes carry little light. The
//! same walk gives the posterior mean of the split, hence the exact score:
//! `∂ℓ/∂λ_on = (E[c_on | c] − n_on p_on) / p_on` (likewise for off). When one
//! part is empty the sum reduces to a single binomial, computed directly.
//!
//! **Curvature and bound.** Levenberg–Marquardt uses the moment-based
//! information `Σ_k ∂E_k ∂E_kᵀ / Var_k` with `E = n_on p_on + n_off p_off`,
//! `Var = n_on p_on q_on + n_off p_off q_off`; the reported Cramér–Rao bound
//! is its inverse at the estimate. For a single binomial this is exactly the
//! Fisher information; for the two-part sum it is a lower bound on it (the
//! bound is slightly conservative), the difference being tiny because the
//! off-part is small — a test enumerates the exact information to check.

use crate::fit::{Fit, FitOptions, FitStatus};
use crate::linalg::invert_spd;
use crate::lm::{levenberg_marquardt, Eval};
use crate::psf::AxisTerms;
use crate::roi::{check_shape, PixelMaps};
use crate::LocalizeError;
use smartagg_model::record::BlinkRecord;

/// Lowest background rate per plane the fit allows (keeps `ln p_off` finite).
const B_MIN: f64 = 1e-10;

/// One SPAD ROI with its bit-plane split.
#[derive(Clone, Copy, Debug)]
pub struct SpadRoi<'a> {
    /// ROI side, pixels.
    pub side: usize,
    /// Detections per pixel summed over all planes, row-major.
    pub counts: &'a [u32],
    /// Planes during which the molecule was on.
    pub n_on: u32,
    /// Planes with background only.
    pub n_off: u32,
    /// Optional maps: `gain` (PRNU), `dark` (**per plane**: DCR × exposure),
    /// `ignore` (hot pixels, pixels off the sensor). `read_var` is unused.
    pub maps: Option<&'a PixelMaps>,
}

impl<'a> SpadRoi<'a> {
    /// Wraps counts, checking shapes.
    pub fn new(
        side: usize,
        counts: &'a [u32],
        n_on: u32,
        n_off: u32,
        maps: Option<&'a PixelMaps>,
    ) -> Result<Self, LocalizeError> {
        check_shape(side, counts.len())?;
        if let Some(m) = maps {
            if m.side != side {
                return Err(LocalizeError::MapShape {
                    map: "pixel",
                    len: m.side * m.side,
                    expected: side * side,
                });
            }
            m.validate()?;
        }
        Ok(SpadRoi {
            side,
            counts,
            n_on,
            n_off,
            maps,
        })
    }

    /// The ROI of a blink record: `n_on = t_e − t_s` clamped to
    /// `[1, planes_summed]` (a record always has at least one on-plane; with
    /// no split information every plane counts as on), `n_off` the rest.
    pub fn from_record(
        rec: &'a BlinkRecord,
        maps: Option<&'a PixelMaps>,
    ) -> Result<Self, LocalizeError> {
        let (n_on, n_off) = on_off_split(rec);
        SpadRoi::new(rec.roi_size as usize, &rec.counts, n_on, n_off, maps)
    }
}

/// `(n_on, n_off)` of a record, see [`SpadRoi::from_record`].
pub fn on_off_split(rec: &BlinkRecord) -> (u32, u32) {
    let planes = rec.planes_summed as i64;
    let on = (rec.t_e.saturating_sub(rec.t_s)).clamp(1.min(planes), planes);
    (on as u32, (planes - on) as u32)
}

/// Exact log-likelihood of one pixel count (up to a constant independent of
/// the rates) and its derivatives with respect to `λ_on` and `λ_off`.
pub fn pixel_log_likelihood(
    c: u32,
    n_on: u32,
    n_off: u32,
    lam_on: f64,
    lam_off: f64,
) -> (f64, f64, f64) {
    let p_on = -(-lam_on).exp_m1();
    let p_off = -(-lam_off).exp_m1();
    if n_off == 0 || n_on == 0 {
        // A single binomial.
        let (n, lam, p) = if n_off == 0 {
            (n_on, lam_on, p_on)
        } else {
            (n_off, lam_off, p_off)
        };
        let c = c as f64;
        let ll = if c > 0.0 { c * p.ln() } else { 0.0 } - (n as f64 - c) * lam;
        let s = if c > 0.0 { c / p } else { 0.0 } - n as f64;
        return if n_off == 0 {
            (ll, s, 0.0)
        } else {
            (ll, 0.0, s)
        };
    }
    let j0 = c.saturating_sub(n_on);
    let j1 = c.min(n_off);
    let (cf, non, noff) = (c as f64, n_on as f64, n_off as f64);
    let j0f = j0 as f64;
    // θ-dependent part of the log of the first term (j = j0).
    let mut ll0 = -(noff - j0f) * lam_off - (non - cf + j0f) * lam_on;
    if j0 > 0 {
        ll0 += j0f * p_off.ln();
    }
    if c > j0 {
        ll0 += (cf - j0f) * p_on.ln();
    }
    // ρ = (p_off / q_off) · (q_on / p_on), the θ-dependent factor of the ratio.
    let rho = p_off / p_on * (lam_off - lam_on).exp();
    let mut w = 1.0f64;
    let mut sum = 1.0f64;
    let mut sum_j = j0f;
    let mut log_scale = 0.0f64;
    let mut j = j0;
    while j < j1 {
        let jf = j as f64;
        let ratio = (noff - jf) * (cf - jf) / ((jf + 1.0) * (non - cf + jf + 1.0)) * rho;
        w *= ratio;
        sum += w;
        sum_j += (jf + 1.0) * w;
        j += 1;
        if ratio < 1.0 && w < 1e-17 * sum {
            break;
        }
        if w > 1e250 {
            // Rescale so that a far-away mode cannot overflow.
            w *= 1e-250;
            sum *= 1e-250;
            sum_j *= 1e-250;
            log_scale += 250.0 * std::f64::consts::LN_10;
        }
    }
    let e_off = sum_j / sum;
    let e_on = cf - e_off;
    let ll = ll0 + sum.ln() + log_scale;
    let s_on = e_on / p_on - non;
    let s_off = e_off / p_off - noff;
    (ll, s_on, s_off)
}

/// Mean and variance of a pixel count, and `∂E/∂λ_on`, `∂E/∂λ_off`.
#[inline(always)]
fn moments(n_on: f64, n_off: f64, lam_on: f64, lam_off: f64) -> (f64, f64, f64, f64) {
    let q_on = (-lam_on).exp();
    let q_off = (-lam_off).exp();
    let p_on = -(-lam_on).exp_m1();
    let p_off = -(-lam_off).exp_m1();
    let e = n_on * p_on + n_off * p_off;
    let v = n_on * p_on * q_on + n_off * p_off * q_off;
    (e, v, n_on * q_on, n_off * q_off)
}

/// Which pixel knowledge a SPAD fit uses.
struct SpadPixels<'a> {
    maps: Option<&'a PixelMaps>,
}

impl SpadPixels<'_> {
    #[inline(always)]
    fn gain(&self, k: usize) -> f64 {
        self.maps.map_or(1.0, |m| m.gain[k])
    }
    #[inline(always)]
    fn dark(&self, k: usize) -> f64 {
        self.maps.map_or(0.0, |m| m.dark[k])
    }
    #[inline(always)]
    fn ignored(&self, k: usize) -> bool {
        self.maps.is_some_and(|m| m.ignore[k])
    }
}

/// Visits every used pixel with (k, λ_on, λ_off, ∂λ_on/∂θ); `∂λ_off/∂θ` is
/// `g_k` on B (index 3) and zero elsewhere.
#[inline(always)]
fn for_each_pixel<const P: usize>(
    side: usize,
    px: &SpadPixels,
    theta: &[f64; P],
    sigma_fixed: f64,
    ax: &mut AxisTerms,
    ay: &mut AxisTerms,
    mut f: impl FnMut(usize, f64, f64, f64, &[f64; P]),
) {
    let fit_sigma = P == 5;
    let sigma = if fit_sigma { theta[P - 1] } else { sigma_fixed };
    ax.compute(side, theta[0], sigma, fit_sigma);
    ay.compute(side, theta[1], sigma, fit_sigma);
    let (s, b) = (theta[2], theta[3]);
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if px.ignored(k) {
                continue;
            }
            let g = px.gain(k);
            let d0 = px.dark(k);
            let psf = ax.e[i] * ay.e[j];
            let lam_off = g * b + d0;
            let lam_on = g * s * psf + lam_off;
            let mut dl = [0.0; P];
            dl[0] = g * s * ax.dc[i] * ay.e[j];
            dl[1] = g * s * ax.e[i] * ay.dc[j];
            dl[2] = g * psf;
            dl[3] = g;
            if fit_sigma {
                dl[P - 1] = g * s * (ax.ds[i] * ay.e[j] + ax.e[i] * ay.ds[j]);
            }
            f(k, lam_on, lam_off, g, &dl);
        }
    }
}

/// Moment-based information `Σ ∂E ∂Eᵀ / Var` at θ.
fn information<const P: usize>(
    side: usize,
    px: &SpadPixels,
    theta: &[f64; P],
    sigma_fixed: f64,
    n_on: u32,
    n_off: u32,
) -> [[f64; P]; P] {
    let mut ax = AxisTerms::default();
    let mut ay = AxisTerms::default();
    let mut h = [[0.0; P]; P];
    let (non, noff) = (n_on as f64, n_off as f64);
    for_each_pixel(
        side,
        px,
        theta,
        sigma_fixed,
        &mut ax,
        &mut ay,
        |_, lon, loff, g, dl| {
            let (_, v, de_on, de_off) = moments(non, noff, lon, loff);
            let mut de = [0.0; P];
            for p in 0..P {
                de[p] = de_on * dl[p];
            }
            de[3] += de_off * g;
            let iv = 1.0 / v.max(1e-300);
            for p in 0..P {
                for q in p..P {
                    h[p][q] += de[p] * de[q] * iv;
                }
            }
        },
    );
    for p in 0..P {
        for q in 0..p {
            h[p][q] = h[q][p];
        }
    }
    h
}

/// SPAD binomial maximum-likelihood fit of one ROI (σ fixed or fitted as in
/// `opts`; `opts.noise` is ignored: the noise model is the binomial itself).
///
/// The returned [`Fit`] has `photons = S · n_on` (pile-up-corrected
/// detections of the molecule), `background = B · (n_on + n_off)` per pixel,
/// and the Cramér–Rao bound of this model as its precision.
pub fn fit_binomial(roi: &SpadRoi, opts: &FitOptions) -> Fit {
    let side = roi.side;
    let sigma0 = opts.sigma.value();
    if check_shape(side, roi.counts.len()).is_err() {
        return Fit::failed(side, sigma0, FitStatus::InconsistentCounts);
    }
    let px = SpadPixels { maps: roi.maps };
    let planes = roi.n_on as u64 + roi.n_off as u64;
    let mut used = 0usize;
    let mut saturated = 0usize;
    let mut total = 0u64;
    for (k, &c) in roi.counts.iter().enumerate() {
        if px.ignored(k) {
            continue;
        }
        if c as u64 > planes {
            return Fit::failed(side, sigma0, FitStatus::InconsistentCounts);
        }
        used += 1;
        total += c as u64;
        saturated += (c as u64 == planes) as usize;
    }
    if used == 0 || total == 0 || planes == 0 {
        return Fit::failed(side, sigma0, FitStatus::NoSignal);
    }
    if saturated == used {
        return Fit::failed(side, sigma0, FitStatus::Saturated);
    }
    // Starting values: the Poisson guess on the counts, converted to rates per
    // plane by inverting p = 1 − e^{−λ} for the background.
    let as_f64: Vec<f64> = roi.counts.iter().map(|&c| c as f64).collect();
    let uniform = crate::lm::Uniform;
    let guess = match roi.maps {
        Some(maps) => {
            let m = crate::lm::Mapped { maps, scmos: false };
            // Dark map is per plane: the Poisson guess works on totals.
            let mut shifted = as_f64.clone();
            for (k, v) in shifted.iter_mut().enumerate() {
                *v -= maps.dark[k] * planes as f64;
            }
            crate::lm::initial_guess(&shifted, side, &m)
        }
        None => crate::lm::initial_guess(&as_f64, side, &uniform),
    };
    let Some([x0, y0, n0, b0]) = guess else {
        return Fit::failed(side, sigma0, FitStatus::NoSignal);
    };
    let b_plane = (b0 / planes as f64).clamp(0.0, 0.99);
    let b_init = (-(-b_plane).ln_1p()).max(B_MIN * 10.0);
    let s_init = (n0 / roi.n_on.max(1) as f64).max(1e-6);
    let r = side as f64;
    let smax = opts.sigma_max.min(r);
    let smin = opts.sigma_min.min(smax);
    let sigma_fixed = sigma0.clamp(1e-3, 1e4);
    let lo4 = [-1.0, -1.0, 1e-9, B_MIN];
    let hi4 = [r + 1.0, r + 1.0, 1e6, 50.0];
    let init4 = [x0, y0, s_init, b_init];
    let fit = if opts.sigma.is_fitted() {
        let init = [
            init4[0],
            init4[1],
            init4[2],
            init4[3],
            sigma0.clamp(smin, smax),
        ];
        let lo = [lo4[0], lo4[1], lo4[2], lo4[3], smin];
        let hi = [hi4[0], hi4[1], hi4[2], hi4[3], smax];
        solve::<5>(roi, &px, init, lo, hi, sigma_fixed, opts)
    } else {
        solve::<4>(roi, &px, init4, lo4, hi4, sigma_fixed, opts)
    };
    fit.sanitized(side)
}

fn solve<const P: usize>(
    roi: &SpadRoi,
    px: &SpadPixels,
    init: [f64; P],
    lo: [f64; P],
    hi: [f64; P],
    sigma_fixed: f64,
    opts: &FitOptions,
) -> Fit {
    let side = roi.side;
    let (n_on, n_off) = (roi.n_on, roi.n_off);
    let (non, noff) = (n_on as f64, n_off as f64);
    let mut ax = AxisTerms::default();
    let mut ay = AxisTerms::default();
    let mut evaluate = |theta: &[f64; P]| -> Eval<P> {
        let mut ll = 0.0;
        let mut g = [0.0; P];
        let mut h = [[0.0; P]; P];
        for_each_pixel(
            side,
            px,
            theta,
            sigma_fixed,
            &mut ax,
            &mut ay,
            |k, lon, loff, gk, dl| {
                let (l, s_on, s_off) = pixel_log_likelihood(roi.counts[k], n_on, n_off, lon, loff);
                ll += l;
                for p in 0..P {
                    g[p] += s_on * dl[p];
                }
                g[3] += s_off * gk;
                let (_, v, de_on, de_off) = moments(non, noff, lon, loff);
                let mut de = [0.0; P];
                for p in 0..P {
                    de[p] = de_on * dl[p];
                }
                de[3] += de_off * gk;
                let iv = 1.0 / v.max(1e-300);
                for p in 0..P {
                    let w = de[p] * iv;
                    for q in p..P {
                        h[p][q] += w * de[q];
                    }
                }
            },
        );
        for p in 0..P {
            for q in 0..p {
                h[p][q] = h[q][p];
            }
        }
        Eval { ll, g, h }
    };
    let out = levenberg_marquardt(&mut evaluate, init, lo, hi, opts.max_iterations);
    let th = out.theta;
    let cov = invert_spd(&out.eval.h);
    let r = side as f64;
    let mut status = FitStatus::Ok;
    if !out.converged {
        status = FitStatus::NotConverged;
    } else if th[2] <= lo[2] * 1.000_001 || cov.is_some_and(|c| th[2] < c[2][2].sqrt()) {
        // No emitter, or one not distinguishable from zero at one standard
        // deviation.
        status = FitStatus::NoSignal;
    } else if th[0] < -0.5 || th[1] < -0.5 || th[0] > r + 0.5 || th[1] > r + 0.5 {
        status = FitStatus::OutsideRoi;
    } else if P == 5 && (th[P - 1] <= lo[P - 1] * 1.000_001 || th[P - 1] >= hi[P - 1] * 0.999_999) {
        status = FitStatus::SigmaAtBound;
    } else if cov.is_none() {
        status = FitStatus::Singular;
    }
    let (std_x, std_y, std_s) = match cov {
        Some(c) => (c[0][0].sqrt(), c[1][1].sqrt(), c[2][2].sqrt()),
        None => (r, r, 0.0),
    };
    let planes = non + noff;
    let pb = -(-th[3]).exp_m1();
    Fit {
        x: th[0],
        y: th[1],
        sigma: if P == 5 { th[P - 1] } else { sigma_fixed },
        photons: th[2] * non,
        background: th[3] * planes,
        bkgstd: (planes * pb * (1.0 - pb)).sqrt(),
        std_x,
        std_y,
        std_photons: std_s * non,
        status,
        iterations: out.iterations,
    }
}

/// The emitter of a SPAD ROI in this model's terms (for bounds and tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpadEmitter {
    /// Column, ROI pixels.
    pub x: f64,
    /// Row, ROI pixels.
    pub y: f64,
    /// PSF σ, pixels.
    pub sigma: f64,
    /// Molecule detections per on-plane before saturation (S).
    pub signal_per_plane: f64,
    /// Background detections per pixel per plane (B).
    pub background_per_plane: f64,
}

/// Cramér–Rao covariance of the SPAD binomial model at the true emitter:
/// the inverse of `Σ ∂E∂Eᵀ/Var` over `[x, y, S, B]` (+ σ when `fit_sigma`).
/// Returns the variances of x and y (pixels²), or `None` when singular.
pub fn crlb_binomial(
    side: usize,
    em: &SpadEmitter,
    n_on: u32,
    n_off: u32,
    maps: Option<&PixelMaps>,
    fit_sigma: bool,
) -> Option<(f64, f64)> {
    let px = SpadPixels { maps };
    let base = [em.x, em.y, em.signal_per_plane, em.background_per_plane];
    if fit_sigma {
        let th = [base[0], base[1], base[2], base[3], em.sigma];
        let c = invert_spd(&information(side, &px, &th, em.sigma, n_on, n_off))?;
        Some((c[0][0], c[1][1]))
    } else {
        let c = invert_spd(&information(side, &px, &base, em.sigma, n_on, n_off))?;
        Some((c[0][0], c[1][1]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute-force log P(c) by convolution with full binomial coefficients.
    fn brute(c: u32, n_on: u32, n_off: u32, lon: f64, loff: f64) -> f64 {
        let lbin = |n: u32, k: u32, p: f64| -> f64 {
            if k > n {
                return f64::NEG_INFINITY;
            }
            let lc: f64 = (1..=k).map(|i| ((n - k + i) as f64 / i as f64).ln()).sum();
            let a = if k > 0 { k as f64 * p.ln() } else { 0.0 };
            let b = if n > k {
                (n - k) as f64 * (1.0 - p).ln()
            } else {
                0.0
            };
            lc + a + b
        };
        let (pon, poff) = (1.0 - (-lon).exp(), 1.0 - (-loff).exp());
        let mut s = 0.0;
        for j in 0..=c.min(n_off) {
            if c - j > n_on {
                continue;
            }
            s += (lbin(n_off, j, poff) + lbin(n_on, c - j, pon)).exp();
        }
        s.ln()
    }

    /// Log of the θ-independent binomial coefficients of the first term.
    fn constant(c: u32, n_on: u32, n_off: u32) -> f64 {
        let lc =
            |n: u32, k: u32| -> f64 { (1..=k).map(|i| ((n - k + i) as f64 / i as f64).ln()).sum() };
        let j0 = c.saturating_sub(n_on);
        lc(n_off, j0) + lc(n_on, c - j0)
    }

    #[test]
    fn exact_likelihood_matches_convolution_and_score_matches_difference() {
        for &(c, n_on, n_off, lon, loff) in &[
            (7u32, 40u32, 30u32, 0.2, 0.01),
            (0, 40, 30, 0.2, 0.01),
            (60, 40, 30, 2.5, 0.6),
            (70, 40, 30, 3.0, 0.5), // saturated pixel
            (35, 40, 30, 0.9, 0.02),
            (12, 0, 30, 0.0, 0.3),
            (12, 30, 0, 0.3, 0.0),
        ] {
            let (ll, son, soff) = pixel_log_likelihood(c, n_on, n_off, lon, loff);
            let want = if n_on == 0 || n_off == 0 {
                // Single binomial: constant is the one binomial coefficient.
                let (n, l) = if n_on == 0 {
                    (n_off, loff)
                } else {
                    (n_on, lon)
                };
                brute(c, n, 0, l, 1e-300) - constant(c, n, 0)
            } else {
                brute(c, n_on, n_off, lon, loff) - constant(c, n_on, n_off)
            };
            assert!(
                (ll - want).abs() < 1e-9 * want.abs().max(1.0),
                "c={c}: {ll} vs {want}"
            );
            let h = 1e-6;
            if n_on > 0 {
                let d = (pixel_log_likelihood(c, n_on, n_off, lon + h, loff).0
                    - pixel_log_likelihood(c, n_on, n_off, lon - h, loff).0)
                    / (2.0 * h);
                assert!(
                    (d - son).abs() < 1e-5 * son.abs().max(1.0),
                    "c={c}: son {son} vs {d}"
                );
            }
            if n_off > 0 {
                let d = (pixel_log_likelihood(c, n_on, n_off, lon, loff + h).0
                    - pixel_log_likelihood(c, n_on, n_off, lon, loff - h).0)
                    / (2.0 * h);
                assert!(
                    (d - soff).abs() < 1e-5 * soff.abs().max(1.0),
                    "c={c}: soff {soff} vs {d}"
                );
            }
        }
    }

    #[test]
    fn moment_information_bounds_exact_information() {
        // One pixel, one parameter (λ_on): exact Fisher information by
        // enumerating every count, against the moment-based (∂E)²/Var.
        let (n_on, n_off) = (60u32, 40u32);
        for &(lon, loff) in &[(0.7, 0.012), (0.05, 0.012), (2.0, 0.3)] {
            let mut exact = 0.0;
            let mut total = 0.0;
            for c in 0..=(n_on + n_off) {
                let ll = brute(c, n_on, n_off, lon, loff);
                let p = ll.exp();
                let (_, s, _) = pixel_log_likelihood(c, n_on, n_off, lon, loff);
                exact += p * s * s;
                total += p;
            }
            assert!((total - 1.0).abs() < 1e-9);
            let (_, v, de, _) = moments(n_on as f64, n_off as f64, lon, loff);
            let moment = de * de / v;
            assert!(moment <= exact * (1.0 + 1e-9), "{moment} > {exact}");
            assert!(moment >= 0.95 * exact, "moment {moment} vs exact {exact}");
        }
    }

    #[test]
    fn split_follows_record() {
        let rec = BlinkRecord {
            slot: 0,
            flags: 0,
            anchor_x: 10,
            anchor_y: 10,
            t_cross: 200,
            t_drop: 300,
            t_s: 146,
            t_e: 246,
            planes_summed: 209,
            roi_size: 3,
            counts: vec![0; 9],
        };
        assert_eq!(on_off_split(&rec), (100, 109));
        let mut r2 = rec.clone();
        r2.t_e = r2.t_s - 5;
        assert_eq!(on_off_split(&r2), (1, 208));
        r2.t_e = r2.t_s + 10_000;
        assert_eq!(on_off_split(&r2), (209, 0));
        r2.planes_summed = 0;
        assert_eq!(on_off_split(&r2), (0, 0));
    }
}
