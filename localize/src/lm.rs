//! Poisson maximum likelihood and least squares fits of the pixel-integrated
//! Gaussian, by Levenberg–Marquardt.
//!
//! Model of pixel `k = (i, j)`:
//! `μ_k = g_k · (N · Ex_i(x, σ) · Ey_j(y, σ) + b) + d_k`
//! with photons N, background b per pixel, relative efficiency g_k and known
//! dark counts d_k (the sCMOS model adds the read-noise variance v_k to both
//! data and μ). Parameters: `[x, y, N, b]`, plus `σ` when it is fitted.
//!
//! Each iteration evaluates the objective, its gradient and the Fisher
//! information (for Poisson `Σ ∂μ∂μᵀ/μ`, for least squares `JᵀJ`) in one pass
//! over the pixels, from `2 (R + 1)` erf evaluations; nothing is allocated.
//! The step solves `(H + λ diag H) δ = ∇` (Fisher scoring damped à la
//! Marquardt); a step is kept only if the objective does not decrease. The
//! fit stops when the Newton decrement `δᵀ∇` falls below 1e-6 (for Poisson,
//! in log-likelihood units): every parameter is then within 1e-3 of its own
//! standard deviation of the optimum. At convergence the Poisson `H` *is* the
//! Fisher information of the fitted model, so the Cramér–Rao bound costs one
//! 5×5 inversion.

use crate::fit::{Fit, FitOptions, FitStatus, NoiseModel};
use crate::linalg::{invert_spd, solve_spd};
use crate::psf::AxisTerms;
use crate::roi::{PixelMaps, RoiView};

/// Smallest expected value allowed in a pixel (keeps `ln μ` and `1/μ` finite
/// when background and dark counts are zero).
const MU_FLOOR: f64 = 1e-12;
/// Newton decrement at which the fit stops.
const DECREMENT_TOL: f64 = 1e-6;

/// Per-pixel knowledge seen by the fit loop; the uniform version compiles to
/// constants.
pub(crate) trait PixelModel {
    fn gain(&self, k: usize) -> f64;
    /// Added to μ (dark counts, sCMOS read variance).
    fn offset(&self, k: usize) -> f64;
    /// Added to the data (sCMOS read variance).
    fn shift(&self, k: usize) -> f64;
    fn ignored(&self, k: usize) -> bool;
}

pub(crate) struct Uniform;

impl PixelModel for Uniform {
    #[inline(always)]
    fn gain(&self, _k: usize) -> f64 {
        1.0
    }
    #[inline(always)]
    fn offset(&self, _k: usize) -> f64 {
        0.0
    }
    #[inline(always)]
    fn shift(&self, _k: usize) -> f64 {
        0.0
    }
    #[inline(always)]
    fn ignored(&self, _k: usize) -> bool {
        false
    }
}

pub(crate) struct Mapped<'a> {
    pub maps: &'a PixelMaps,
    pub scmos: bool,
}

impl PixelModel for Mapped<'_> {
    #[inline(always)]
    fn gain(&self, k: usize) -> f64 {
        self.maps.gain[k]
    }
    #[inline(always)]
    fn offset(&self, k: usize) -> f64 {
        if self.scmos {
            self.maps.dark[k] + self.maps.read_var[k]
        } else {
            self.maps.dark[k]
        }
    }
    #[inline(always)]
    fn shift(&self, k: usize) -> f64 {
        if self.scmos {
            self.maps.read_var[k]
        } else {
            0.0
        }
    }
    #[inline(always)]
    fn ignored(&self, k: usize) -> bool {
        self.maps.ignore[k]
    }
}

/// The objective's contribution of one pixel: (objective, residual factor r,
/// weight w) with gradient `Σ r ∂μ` and curvature `Σ w ∂μ∂μᵀ`.
pub(crate) trait Objective {
    fn pixel(n: f64, mu: f64) -> (f64, f64, f64);
    /// Lowest background allowed.
    const B_MIN: f64;
}

pub(crate) struct PoissonObjective;

impl Objective for PoissonObjective {
    #[inline(always)]
    fn pixel(n: f64, mu: f64) -> (f64, f64, f64) {
        // Negative data (sCMOS after offset subtraction) are clamped: a Poisson
        // variable cannot be negative.
        let n = n.max(0.0);
        let inv = 1.0 / mu;
        (n * mu.ln() - mu, n * inv - 1.0, inv)
    }
    const B_MIN: f64 = 0.0;
}

pub(crate) struct LsqObjective;

impl Objective for LsqObjective {
    #[inline(always)]
    fn pixel(n: f64, mu: f64) -> (f64, f64, f64) {
        let r = n - mu;
        (-0.5 * r * r, r, 1.0)
    }
    const B_MIN: f64 = -1e12;
}

/// Objective, gradient and curvature at one parameter vector.
#[derive(Clone, Copy)]
pub(crate) struct Eval<const P: usize> {
    pub ll: f64,
    pub g: [f64; P],
    pub h: [[f64; P]; P],
}

/// The problem a fit works on.
pub(crate) struct Problem<'a, M> {
    pub data: &'a [f64],
    pub side: usize,
    pub model: M,
    /// σ when it is not a parameter.
    pub sigma_fixed: f64,
}

impl<M: PixelModel> Problem<'_, M> {
    /// Visits every pixel that is not ignored with (k, μ, ∂μ/∂θ).
    #[inline(always)]
    fn for_each_pixel<const P: usize>(
        &self,
        theta: &[f64; P],
        ax: &mut AxisTerms,
        ay: &mut AxisTerms,
        mut f: impl FnMut(usize, f64, &[f64; P]),
    ) {
        let fit_sigma = P == 5;
        let sigma = if fit_sigma {
            theta[P - 1]
        } else {
            self.sigma_fixed
        };
        let side = self.side;
        ax.compute(side, theta[0], sigma, fit_sigma);
        ay.compute(side, theta[1], sigma, fit_sigma);
        let (n_ph, b) = (theta[2], theta[3]);
        for j in 0..side {
            let ey = ay.e[j];
            let n_ey = n_ph * ey;
            let n_dey = n_ph * ay.dc[j];
            let n_sy = n_ph * ay.ds[j];
            for i in 0..side {
                let k = j * side + i;
                if self.model.ignored(k) {
                    continue;
                }
                let gain = self.model.gain(k);
                let ex = ax.e[i];
                let psf = ex * ey;
                let mu = (gain * (n_ph * psf + b) + self.model.offset(k)).max(MU_FLOOR);
                let mut d = [0.0; P];
                d[0] = gain * ax.dc[i] * n_ey;
                d[1] = gain * ex * n_dey;
                d[2] = gain * psf;
                d[3] = gain;
                if fit_sigma {
                    d[P - 1] = gain * (ax.ds[i] * n_ey + ex * n_sy);
                }
                f(k, mu, &d);
            }
        }
    }

    #[inline(always)]
    fn evaluate<const P: usize, O: Objective>(
        &self,
        theta: &[f64; P],
        ax: &mut AxisTerms,
        ay: &mut AxisTerms,
    ) -> Eval<P> {
        let mut ll = 0.0;
        let mut g = [0.0; P];
        let mut h = [[0.0; P]; P];
        let data = self.data;
        self.for_each_pixel(theta, ax, ay, |k, mu, d| {
            let (l, r, w) = O::pixel(data[k] + self.model.shift(k), mu);
            ll += l;
            for p in 0..P {
                g[p] += r * d[p];
                let wd = w * d[p];
                for q in p..P {
                    h[p][q] += wd * d[q];
                }
            }
        });
        for p in 0..P {
            for q in 0..p {
                h[p][q] = h[q][p];
            }
        }
        Eval { ll, g, h }
    }

    /// `Σ w(μ_k) ∂μ∂μᵀ` at θ (Fisher information for `w = 1/μ`).
    pub(crate) fn weighted_outer<const P: usize>(
        &self,
        theta: &[f64; P],
        w: impl Fn(f64) -> f64,
    ) -> [[f64; P]; P] {
        let mut ax = AxisTerms::default();
        let mut ay = AxisTerms::default();
        let mut h = [[0.0; P]; P];
        self.for_each_pixel(theta, &mut ax, &mut ay, |_, mu, d| {
            let wk = w(mu);
            for p in 0..P {
                for q in p..P {
                    h[p][q] += wk * d[p] * d[q];
                }
            }
        });
        for p in 0..P {
            for q in 0..p {
                h[p][q] = h[q][p];
            }
        }
        h
    }
}

/// Result of Levenberg–Marquardt.
pub(crate) struct LmOutcome<const P: usize> {
    pub theta: [f64; P],
    pub eval: Eval<P>,
    pub iterations: u32,
    pub converged: bool,
}

/// Maximises an objective from `init` within `[lo, hi]`; `evaluate` returns
/// objective, gradient and curvature at a parameter vector.
#[inline(always)]
pub(crate) fn levenberg_marquardt<const P: usize>(
    mut evaluate: impl FnMut(&[f64; P]) -> Eval<P>,
    init: [f64; P],
    lo: [f64; P],
    hi: [f64; P],
    max_iter: u32,
    decrement_scale: impl Fn(&Eval<P>) -> f64,
) -> LmOutcome<P> {
    let mut theta = init;
    for p in 0..P {
        theta[p] = theta[p].clamp(lo[p], hi[p]);
    }
    let mut cur = evaluate(&theta);
    let mut lambda = 1e-3;
    let mut converged = false;
    let mut iterations = 0;
    while iterations < max_iter {
        iterations += 1;
        let mut a = cur.h;
        let max_diag = (0..P).fold(0.0f64, |m, p| m.max(cur.h[p][p]));
        for p in 0..P {
            // A tiny ridge keeps a parameter with no influence (e.g. x when
            // N = 0) from making the system singular.
            a[p][p] = cur.h[p][p] * (1.0 + lambda) + 1e-12 * max_diag + 1e-300;
        }
        let Some(delta) = solve_spd(&a, &cur.g) else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
            continue;
        };
        let decrement: f64 = (0..P).map(|p| delta[p] * cur.g[p]).sum::<f64>() * (1.0 + lambda);
        if decrement.abs() < DECREMENT_TOL * decrement_scale(&cur) {
            converged = true;
            break;
        }
        let mut next = theta;
        for p in 0..P {
            next[p] = (theta[p] + delta[p]).clamp(lo[p], hi[p]);
        }
        let trial = evaluate(&next);
        if trial.ll >= cur.ll && trial.ll.is_finite() {
            theta = next;
            cur = trial;
            lambda = (lambda * 0.1).max(1e-9);
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                // No step improves the objective: we are at its maximum to
                // working precision (or stuck on a bound).
                converged = true;
                break;
            }
        }
    }
    LmOutcome {
        theta,
        eval: cur,
        iterations,
        converged,
    }
}

/// Starting values `[x, y, N, b]`: background from the mean of the valid
/// border pixels, position from the centroid of the excess over it, photons
/// from the summed excess. `None` when the ROI holds no counts at all.
pub(crate) fn initial_guess<M: PixelModel>(data: &[f64], side: usize, m: &M) -> Option<[f64; 4]> {
    let mut border_sum = 0.0;
    let mut border_n = 0usize;
    let mut total = 0.0;
    let mut valid = 0usize;
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if m.ignored(k) {
                continue;
            }
            let v = (data[k] - m.offset(k) + m.shift(k)) / m.gain(k);
            total += data[k].max(0.0);
            valid += 1;
            if i == 0 || j == 0 || i + 1 == side || j + 1 == side {
                border_sum += v;
                border_n += 1;
            }
        }
    }
    if valid == 0 || total <= 0.0 {
        return None;
    }
    let b = if border_n > 0 {
        (border_sum / border_n as f64).max(0.0)
    } else {
        0.0
    };
    let (mut sx, mut sy, mut s, mut net) = (0.0, 0.0, 0.0, 0.0);
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if m.ignored(k) {
                continue;
            }
            let v = (data[k] - m.offset(k) + m.shift(k)) / m.gain(k) - b;
            net += v;
            let w = v.max(0.0);
            s += w;
            sx += w * (i as f64 + 0.5);
            sy += w * (j as f64 + 0.5);
        }
    }
    let c = side as f64 / 2.0;
    let (x, y) = if s > 0.0 { (sx / s, sy / s) } else { (c, c) };
    let n = net.max(0.5 * s).max(1.0);
    Some([x, y, n, b])
}

/// True if any pixel that is not ignored holds a NaN or an infinity.
pub(crate) fn has_non_finite<M: PixelModel>(data: &[f64], m: &M) -> bool {
    data.iter()
        .enumerate()
        .any(|(k, v)| !v.is_finite() && !m.ignored(k))
}

/// Which objective.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Mle,
    Lsq,
}

/// Poisson (or EMCCD, or sCMOS) maximum-likelihood fit of one ROI.
pub fn fit_mle(roi: &RoiView, opts: &FitOptions) -> Fit {
    dispatch(roi, opts, Kind::Mle)
}

/// Unweighted least-squares fit of one ROI.
pub fn fit_lsq(roi: &RoiView, opts: &FitOptions) -> Fit {
    dispatch(roi, opts, Kind::Lsq)
}

fn dispatch(roi: &RoiView, opts: &FitOptions, kind: Kind) -> Fit {
    let scmos = opts.noise == NoiseModel::Scmos;
    let mut fit = match roi.maps {
        None => run(roi.data, roi.side, Uniform, opts, kind),
        Some(maps) => run(roi.data, roi.side, Mapped { maps, scmos }, opts, kind),
    };
    if let (true, Some(maps)) = (scmos, roi.maps) {
        // Background noise = shot noise of b plus the mean read variance.
        let mean_var = maps.read_var.iter().sum::<f64>() / maps.read_var.len().max(1) as f64;
        fit.bkgstd = (fit.background.max(0.0) + mean_var).sqrt();
    }
    fit.sanitized(roi.side)
}

fn run<M: PixelModel>(data: &[f64], side: usize, m: M, opts: &FitOptions, kind: Kind) -> Fit {
    let sigma0 = opts.sigma.value();
    if data.len() != side * side || side == 0 || side > crate::psf::MAX_SIDE {
        return Fit::failed(side, sigma0, FitStatus::NonFiniteInput);
    }
    if has_non_finite(data, &m) {
        return Fit::failed(side, sigma0, FitStatus::NonFiniteInput);
    }
    let Some(init4) = initial_guess(data, side, &m) else {
        return Fit::failed(side, sigma0, FitStatus::NoSignal);
    };
    let r = side as f64;
    let smax = opts.sigma_max.min(r);
    let smin = opts.sigma_min.min(smax);
    let b_min = match kind {
        Kind::Mle => PoissonObjective::B_MIN,
        Kind::Lsq => LsqObjective::B_MIN,
    };
    // Positions may wander a pixel beyond the ROI during the search; photons
    // stay positive so that the position keeps a gradient.
    let lo4 = [-1.0, -1.0, 1e-3, b_min];
    let hi4 = [r + 1.0, r + 1.0, 1e15, 1e15];
    let prob = Problem {
        data,
        side,
        model: m,
        sigma_fixed: sigma0.clamp(1e-3, 1e4),
    };
    if opts.sigma.is_fitted() {
        let init = [
            init4[0],
            init4[1],
            init4[2],
            init4[3],
            sigma0.clamp(smin, smax),
        ];
        let lo = [lo4[0], lo4[1], lo4[2], lo4[3], smin];
        let hi = [hi4[0], hi4[1], hi4[2], hi4[3], smax];
        finish::<5, M>(&prob, init, lo, hi, opts, kind)
    } else {
        finish::<4, M>(&prob, init4, lo4, hi4, opts, kind)
    }
}

fn finish<const P: usize, M: PixelModel>(
    prob: &Problem<M>,
    init: [f64; P],
    lo: [f64; P],
    hi: [f64; P],
    opts: &FitOptions,
    kind: Kind,
) -> Fit {
    let npix = prob.side * prob.side;
    let mut ax = AxisTerms::default();
    let mut ay = AxisTerms::default();
    let out = match kind {
        Kind::Mle => levenberg_marquardt(
            |t: &[f64; P]| prob.evaluate::<P, PoissonObjective>(t, &mut ax, &mut ay),
            init,
            lo,
            hi,
            opts.max_iterations,
            |_| 1.0,
        ),
        Kind::Lsq => levenberg_marquardt(
            |t: &[f64; P]| prob.evaluate::<P, LsqObjective>(t, &mut ax, &mut ay),
            init,
            lo,
            hi,
            opts.max_iterations,
            // Least squares: decrement in data² units, scaled by the residual
            // variance so that the rule means the same as for Poisson.
            |e| (-2.0 * e.ll / (npix as f64 - P as f64).max(1.0)).max(1e-12),
        ),
    };
    let th = out.theta;
    let f2 = opts.noise.excess_noise();
    let sigma = if P == 5 { th[P - 1] } else { prob.sigma_fixed };
    // Precision of the estimate.
    let cov = match kind {
        Kind::Mle => invert_spd(&out.eval.h).map(|mut c| {
            for row in c.iter_mut() {
                for v in row.iter_mut() {
                    *v *= f2;
                }
            }
            c
        }),
        Kind::Lsq => {
            // Sandwich: (JᵀJ)⁻¹ (Jᵀ V J) (JᵀJ)⁻¹ with V = F² μ the noise variance.
            let meat = prob.weighted_outer(&th, |mu| f2 * mu);
            invert_spd(&out.eval.h).map(|bread| {
                let mut c = [[0.0; P]; P];
                for p in 0..P {
                    for q in 0..P {
                        let mut s = 0.0;
                        for a in 0..P {
                            for b in 0..P {
                                s += bread[p][a] * meat[a][b] * bread[b][q];
                            }
                        }
                        c[p][q] = s;
                    }
                }
                c
            })
        }
    };
    let mut status = FitStatus::Ok;
    let r = prob.side as f64;
    if !out.converged {
        status = FitStatus::NotConverged;
    } else if th[2] <= lo[2] * 1.000_001 {
        status = FitStatus::NoSignal;
    } else if th[0] < -0.5 || th[1] < -0.5 || th[0] > r + 0.5 || th[1] > r + 0.5 {
        status = FitStatus::OutsideRoi;
    } else if P == 5 && (th[P - 1] <= lo[P - 1] * 1.000_001 || th[P - 1] >= hi[P - 1] * 0.999_999) {
        status = FitStatus::SigmaAtBound;
    } else if cov.is_none() {
        status = FitStatus::Singular;
    }
    let (std_x, std_y, std_n) = match cov {
        Some(c) => (c[0][0].sqrt(), c[1][1].sqrt(), c[2][2].sqrt()),
        None => (r, r, 0.0),
    };
    let bg = th[3];
    Fit {
        x: th[0],
        y: th[1],
        sigma,
        photons: th[2],
        background: bg,
        bkgstd: (f2 * bg.max(0.0)).sqrt(),
        std_x,
        std_y,
        std_photons: std_n,
        status,
        iterations: out.iterations,
    }
}
