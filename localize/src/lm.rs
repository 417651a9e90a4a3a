//! Poisson maximum likelihood and least squares fits of the pixel-integrated
//! Gaussian, by Levenberg–Marquardt.
//!
//! Model of pixel `k = (i, j)`:
//! `μ_k = g_k · (N · Ex_i(x, σ) · Ey_j(y, σ) + b) + d_k`
//! with photons N, background b per pixel, relative efficiency g_k and known
//! dark counts d_k (the sCMOS model adds the read-noise variance v_k to both
//! data and μ). Parameters: `[x, y, N, b]`, plus `σ` when it is fitted.
//!
//! Each iteration evaluates the objective, its gradient and the curvature
//! (for Poisson the Fisher information `Σ ∂μ∂μᵀ/μ`, for least squares `JᵀJ`)
//! from `2 (R + 1)` erf evaluations and two vectorised passes over the
//! pixels: the first computes μ, ∂μ, objective and gradient and stores the
//! weighted derivatives; the second sums the curvature a few entries at a
//! time (so that the accumulators stay in registers). Work arrays live in a
//! per-thread scratch buffer allocated once: nothing is allocated per fit.
//! Blocks are loaded without per-load bounds checks, their whole index range
//! being asserted once per pass (bounds checks were a fifth of a fit's
//! instructions); on x86-64 the fit is also compiled for AVX2+FMA and that
//! build is chosen at run time.
//!
//! The step solves `(H + λ diag H) δ = ∇` (Fisher scoring damped à la
//! Marquardt); a step is kept only if the objective does not decrease —
//! judged, once the step is within about one standard deviation (Newton
//! decrement below 1), by the trapezoid rule on the gradients, which needs
//! no logarithms. When the Newton decrement `δᵀ∇` falls below 0.05
//! (log-likelihood units: the step is below 0.22 standard deviation in every
//! parameter, where the quadratic model is accurate) the fit takes that last
//! step unchecked and stops. Measured on 20 000 ROIs (230 photons, σ
//! fitted): RMSE/CRLB 1.018 against 1.020 with a 5× tighter rule, for a fifth
//! fewer iterations. At convergence the Poisson `H` *is* the Fisher
//! information of the fitted model, so the Cramér–Rao bound costs one 5×5
//! inversion.

mod iterate;
mod lanes;
mod model;
mod problem;
mod scratch;

#[cfg(target_arch = "x86_64")]
use crate::fastmath::Fused;
use crate::fastmath::{Arith, Plain};
use crate::fit::{Fit, FitOptions, FitStatus, NoiseModel};
use crate::linalg::invert_spd;
use crate::roi::RoiView;
use iterate::bound;
pub(crate) use iterate::{levenberg_marquardt, Eval};
pub(crate) use model::{
    has_non_finite, initial_guess, LsqObjective, Mapped, Objective, PixelModel, PoissonObjective,
    Uniform,
};
use problem::FrameEval;
pub(crate) use problem::Problem;
use scratch::{prepare, return_scratch, take_scratch, Layout, Scratch};

/// Which objective.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Mle,
    Lsq,
}

/// Poisson (or EMCCD, or sCMOS) maximum-likelihood fit of one ROI.
pub fn fit_mle(roi: &RoiView, opts: &FitOptions) -> Fit {
    dispatch_best(roi, opts, Kind::Mle)
}

/// Unweighted least-squares fit of one ROI.
pub fn fit_lsq(roi: &RoiView, opts: &FitOptions) -> Fit {
    dispatch_best(roi, opts, Kind::Lsq)
}

/// Runs the fit compiled for AVX2 when the CPU has it (four f64 lanes per
/// instruction instead of two); the results are the same to rounding.
fn dispatch_best(roi: &RoiView, opts: &FitOptions, kind: Kind) -> Fit {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports AVX2 and FMA, checked just above.
            return unsafe { dispatch_avx2_fma(roi, opts, kind) };
        }
    }
    dispatch::<Plain>(roi, opts, kind)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn dispatch_avx2_fma(roi: &RoiView, opts: &FitOptions, kind: Kind) -> Fit {
    dispatch::<Fused>(roi, opts, kind)
}

#[inline(always)]
fn dispatch<A: Arith>(roi: &RoiView, opts: &FitOptions, kind: Kind) -> Fit {
    let scmos = opts.noise == NoiseModel::Scmos;
    let mut fit = match roi.maps {
        None => run::<_, A>(roi.data, roi.side, Uniform, opts, kind),
        Some(maps) => run::<_, A>(roi.data, roi.side, Mapped { maps, scmos }, opts, kind),
    };
    if let (true, Some(maps)) = (scmos, roi.maps) {
        // Background noise = shot noise of b plus the mean read variance.
        let mean_var = maps.read_var.iter().sum::<f64>() / maps.read_var.len().max(1) as f64;
        fit.bkgstd = (fit.background.max(0.0) + mean_var).sqrt();
    }
    fit.sanitized(roi.side)
}

#[inline(always)]
fn run<M: PixelModel, A: Arith>(
    data: &[f64],
    side: usize,
    m: M,
    opts: &FitOptions,
    kind: Kind,
) -> Fit {
    let sigma0 = opts.sigma.value();
    if data.len() != side * side || side == 0 || side > crate::psf::MAX_SIDE {
        return Fit::failed(side, sigma0, FitStatus::NonFiniteInput);
    }
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
        side,
        model: m,
        sigma_fixed: bound(sigma0, 1e-3, 1e4),
    };
    let lay = Layout::new(side);
    let mut scratch = take_scratch(lay, 5);
    let fit = match prepare(data, &prob.model, lay, &mut scratch.buf) {
        Err(status) => Fit::failed(side, sigma0, status),
        Ok(init4) if opts.sigma.is_fitted() => {
            let init = [
                init4[0],
                init4[1],
                init4[2],
                init4[3],
                sigma0.max(smin).min(smax),
            ];
            let lo = [lo4[0], lo4[1], lo4[2], lo4[3], smin];
            let hi = [hi4[0], hi4[1], hi4[2], hi4[3], smax];
            finish::<5, M, A>(&prob, init, lo, hi, opts, kind, &mut scratch, lay)
        }
        Ok(init4) => finish::<4, M, A>(&prob, init4, lo4, hi4, opts, kind, &mut scratch, lay),
    };
    return_scratch(scratch);
    fit
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn finish<const P: usize, M: PixelModel, A: Arith>(
    prob: &Problem<M>,
    init: [f64; P],
    lo: [f64; P],
    hi: [f64; P],
    opts: &FitOptions,
    kind: Kind,
    scratch: &mut Scratch,
    layout: Layout,
) -> Fit {
    let Scratch { buf, ax, ay } = scratch;
    let out = match kind {
        Kind::Mle => levenberg_marquardt(
            &mut FrameEval::<M, PoissonObjective, A> {
                prob,
                ax,
                ay,
                scratch: buf,
                layout,
                kind: std::marker::PhantomData,
            },
            init,
            lo,
            hi,
            opts.max_iterations,
        ),
        Kind::Lsq => levenberg_marquardt(
            &mut FrameEval::<M, LsqObjective, A> {
                prob,
                ax,
                ay,
                scratch: buf,
                layout,
                kind: std::marker::PhantomData,
            },
            init,
            lo,
            hi,
            opts.max_iterations,
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
