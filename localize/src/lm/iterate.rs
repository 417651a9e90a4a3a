//! The Levenberg–Marquardt iteration, generic over what it maximises (the
//! frame model here, the SPAD binomial likelihood in `spad`).

use crate::linalg::solve_spd;

/// Newton decrement at which the fit takes its last step and stops.
const DECREMENT_TOL: f64 = 5e-2;
/// Newton decrement below which steps are judged by the trapezoid rule on
/// the gradients instead of by the objective.
const TRAPEZOID_LIMIT: f64 = 1.0;

/// Objective, gradient and curvature at one parameter vector.
#[derive(Clone, Copy)]
pub(crate) struct Eval<const P: usize> {
    pub ll: f64,
    pub g: [f64; P],
    pub h: [[f64; P]; P],
}

/// Result of Levenberg–Marquardt.
pub(crate) struct LmOutcome<const P: usize> {
    pub theta: [f64; P],
    pub eval: Eval<P>,
    pub iterations: u32,
    pub converged: bool,
}

/// Something Levenberg–Marquardt can maximise. A trait rather than a
/// closure so that the evaluation is inlined into the AVX2 build of the fit.
pub(crate) trait Evaluate<const P: usize> {
    /// Gradient and curvature at θ, and the objective if `objective` (else
    /// it may be NaN).
    fn eval(&mut self, theta: &[f64; P], objective: bool) -> Eval<P>;
    /// Unit of the Newton decrement (1 for log-likelihoods).
    fn decrement_scale(&self, _e: &Eval<P>) -> f64 {
        1.0
    }
}

impl<const P: usize, F: FnMut(&[f64; P]) -> Eval<P>> Evaluate<P> for F {
    #[inline(always)]
    fn eval(&mut self, theta: &[f64; P], _objective: bool) -> Eval<P> {
        self(theta)
    }
}

/// `v` limited to `[lo, hi]` (`lo ≤ hi`); `f64::clamp` is not inlined into
/// the AVX2 build.
#[inline(always)]
#[allow(clippy::manual_clamp)]
pub(super) fn bound(v: f64, lo: f64, hi: f64) -> f64 {
    v.max(lo).min(hi)
}

/// Maximises an objective from `init` within `[lo, hi]`.
#[inline(always)]
pub(crate) fn levenberg_marquardt<const P: usize>(
    evaluator: &mut impl Evaluate<P>,
    init: [f64; P],
    lo: [f64; P],
    hi: [f64; P],
    max_iter: u32,
) -> LmOutcome<P> {
    let mut theta = init;
    for p in 0..P {
        theta[p] = bound(theta[p], lo[p], hi[p]);
    }
    let mut cur = evaluator.eval(&theta, true);
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
        let Some(mut delta) = solve_spd(&a, &cur.g) else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
            continue;
        };
        // Parameters on a bound whose step points outward are held there
        // (active set), so that a fit converging to a bound (σ of a hot
        // pixel, say) converges instead of pushing against it.
        let mut held = [false; P];
        let mut any = false;
        for p in 0..P {
            held[p] =
                (theta[p] <= lo[p] && delta[p] < 0.0) || (theta[p] >= hi[p] && delta[p] > 0.0);
            any |= held[p];
        }
        let mut g = cur.g;
        if any {
            for p in 0..P {
                if held[p] {
                    for q in 0..P {
                        a[p][q] = 0.0;
                        a[q][p] = 0.0;
                    }
                    a[p][p] = 1.0;
                    g[p] = 0.0;
                }
            }
            match solve_spd(&a, &g) {
                Some(d) => delta = d,
                None => {
                    lambda *= 10.0;
                    if lambda > 1e12 {
                        break;
                    }
                    continue;
                }
            }
        }
        let decrement: f64 = (0..P).map(|p| delta[p] * g[p]).sum::<f64>() * (1.0 + lambda);
        if decrement.abs() < DECREMENT_TOL * evaluator.decrement_scale(&cur) {
            // The remaining step is a small fraction of every parameter's
            // standard deviation: take it without checking (the quadratic
            // model is accurate there) and stop.
            for p in 0..P {
                theta[p] = bound(theta[p] + delta[p], lo[p], hi[p]);
            }
            converged = true;
            break;
        }
        let mut next = theta;
        for p in 0..P {
            next[p] = bound(theta[p] + delta[p], lo[p], hi[p]);
        }
        // Far from the optimum compare objectives; near it (the step within
        // about one standard deviation) the quadratic model is accurate and
        // the trapezoid rule on the gradients, ½ δ·(∇₀ + ∇₁), tells whether
        // the objective increased without computing it (no logarithms).
        let exact = decrement.abs() > TRAPEZOID_LIMIT * evaluator.decrement_scale(&cur);
        if exact && cur.ll.is_nan() {
            cur = evaluator.eval(&theta, true);
        }
        let trial = evaluator.eval(&next, exact);
        let better = if exact {
            trial.ll >= cur.ll && trial.ll.is_finite()
        } else {
            let gain: f64 = (0..P)
                .map(|p| (next[p] - theta[p]) * (cur.g[p] + trial.g[p]))
                .sum();
            gain >= 0.0 && gain.is_finite()
        };
        if better {
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
