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
//! The step solves `(H + λ diag H) δ = ∇` (Fisher scoring damped à la
//! Marquardt); a step is kept only if the objective does not decrease. When
//! the Newton decrement `δᵀ∇` falls below 0.01 (log-likelihood units: the
//! step is below 0.1 standard deviation in every parameter) the fit takes
//! that last step unchecked and stops. At convergence the Poisson `H` *is*
//! the Fisher information of the fitted model, so the Cramér–Rao bound costs
//! one 5×5 inversion.

#[cfg(target_arch = "x86_64")]
use crate::fastmath::Fused;
use crate::fastmath::{ln_and_recip, Arith, Plain};
use crate::fit::{Fit, FitOptions, FitStatus, NoiseModel};
use crate::linalg::{invert_spd, solve_spd};
use crate::psf::AxisTerms;
use crate::roi::{PixelMaps, RoiView};

/// Smallest expected value allowed in a pixel (keeps `ln μ` and `1/μ` finite
/// when background and dark counts are zero).
const MU_FLOOR: f64 = 1e-12;
/// Newton decrement at which the fit takes its last step and stops.
const DECREMENT_TOL: f64 = 1e-2;
/// Newton decrement below which steps are judged by the trapezoid rule on
/// the gradients instead of by the objective.
const TRAPEZOID_LIMIT: f64 = 1.0;

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
    fn pixel<A: Arith>(n: f64, mu: f64) -> (f64, f64, f64);
    /// Residual factor and weight only (no objective).
    fn pixel_grad<A: Arith>(n: f64, mu: f64) -> (f64, f64);
    /// Lowest background allowed.
    const B_MIN: f64;
    /// Whether the objective is a (negative half) sum of squares.
    const LEAST_SQUARES: bool;
}

pub(crate) struct PoissonObjective;

impl Objective for PoissonObjective {
    #[inline(always)]
    fn pixel<A: Arith>(n: f64, mu: f64) -> (f64, f64, f64) {
        // Negative data (sCMOS after offset subtraction) are clamped: a Poisson
        // variable cannot be negative.
        let n = n.max(0.0);
        let (ln, inv) = ln_and_recip::<A>(mu);
        (A::madd(n, ln, -mu), A::madd(n, inv, -1.0), inv)
    }
    #[inline(always)]
    fn pixel_grad<A: Arith>(n: f64, mu: f64) -> (f64, f64) {
        let inv = 1.0 / mu;
        (A::madd(n.max(0.0), inv, -1.0), inv)
    }
    const B_MIN: f64 = 0.0;
    const LEAST_SQUARES: bool = false;
}

pub(crate) struct LsqObjective;

impl Objective for LsqObjective {
    #[inline(always)]
    fn pixel<A: Arith>(n: f64, mu: f64) -> (f64, f64, f64) {
        let r = n - mu;
        (-0.5 * r * r, r, 1.0)
    }
    #[inline(always)]
    fn pixel_grad<A: Arith>(n: f64, mu: f64) -> (f64, f64) {
        (n - mu, 1.0)
    }
    const B_MIN: f64 = -1e12;
    const LEAST_SQUARES: bool = true;
}

/// Objective, gradient and curvature at one parameter vector.
#[derive(Clone, Copy)]
pub(crate) struct Eval<const P: usize> {
    pub ll: f64,
    pub g: [f64; P],
    pub h: [[f64; P]; P],
}

/// Pixels per vectorised block (four f64 lanes: one AVX2 register).
const LANES: usize = 4;

thread_local! {
    /// Per-thread work arrays of the pixel passes (weights and derivatives),
    /// grown once to the largest ROI seen.
    static SCRATCH: std::cell::Cell<Vec<f64>> = const { std::cell::Cell::new(Vec::new()) };
}

/// Layout of the pixel arrays: the ROI's pixels row-major and flat, padded
/// to a whole number of blocks; padding lanes are masked out.
#[derive(Clone, Copy)]
struct Layout {
    side: usize,
    /// Entries per array, `side²` rounded up to a multiple of [`LANES`].
    np: usize,
}

impl Layout {
    #[inline(always)]
    fn new(side: usize) -> Layout {
        Layout {
            side,
            np: (side * side).div_ceil(LANES) * LANES,
        }
    }
}

/// Number of input arrays: data (+ shift), gain, offset, use.
const INPUTS: usize = 4;
/// Number of per-iteration arrays of the separable model: the column terms
/// `Ex, ∂Ex/∂x, ∂Ex/∂σ` and row terms `Ey, ∂Ey/∂y, ∂Ey/∂σ` of every pixel.
const TILES: usize = 6;

/// Borrows this thread's scratch buffer, sized for the input arrays and the
/// `1 + params` output arrays (weights, derivatives) of [`Layout`]. Give it
/// back with [`return_scratch`]. (No closure runs the fit: closures would not
/// inherit the AVX2 build.)
#[inline(always)]
fn take_scratch(lay: Layout, params: usize) -> Vec<f64> {
    let mut buf = SCRATCH.with(|c| c.take());
    let need = lay.np * (INPUTS + TILES + 1 + params);
    if buf.len() < need {
        buf.resize(need, 0.0);
    }
    buf
}

#[inline(always)]
fn return_scratch(buf: Vec<f64>) {
    SCRATCH.with(|c| c.set(buf));
}

/// Copies the ROI into the input arrays once per fit: data plus shift (0
/// where ignored: NaN in an ignored pixel never reaches a sum), gain,
/// offset, and use (1 or 0); padding lanes get use 0 and a harmless μ > 0,
/// and the padding of the tile arrays is zeroed.
#[inline(always)]
fn prepare<M: PixelModel>(data: &[f64], m: &M, lay: Layout, scratch: &mut [f64]) {
    let np = lay.np;
    let n = lay.side * lay.side;
    let (dp, rest) = scratch[..(INPUTS + TILES) * np].split_at_mut(np);
    let (gp, rest) = rest.split_at_mut(np);
    let (op, rest) = rest.split_at_mut(np);
    let (up, tiles) = rest.split_at_mut(np);
    for k in 0..n {
        let used = !m.ignored(k);
        dp[k] = if used { data[k] + m.shift(k) } else { 0.0 };
        gp[k] = m.gain(k);
        op[k] = m.offset(k);
        up[k] = if used { 1.0 } else { 0.0 };
    }
    dp[n..].fill(0.0);
    gp[n..].fill(1.0);
    op[n..].fill(1.0);
    up[n..].fill(0.0);
    for t in 0..TILES {
        tiles[t * np + n..(t + 1) * np].fill(0.0);
    }
}

/// Row `R` of the curvature, `h[R][q] = Σ_k w_k d_R,k d_q,k` for `q ≥ R`
/// (mirrored), over padded pixel arrays `w` and `d` (P arrays of `np`).
#[inline(always)]
fn curvature_row<const P: usize, const R: usize, A: Arith>(
    w: &[f64],
    d: &[f64],
    np: usize,
    h: &mut [[f64; P]; P],
) {
    if R >= P {
        return;
    }
    let dr = &d[R * np..(R + 1) * np];
    let mut acc = [[0.0; LANES]; P];
    let mut k = 0;
    while k < np {
        let (wk, drk) = (block(w, k), block(dr, k));
        let mut wd = [0.0; LANES];
        for l in 0..LANES {
            wd[l] = wk[l] * drk[l];
        }
        for q in R..P {
            let dq = block(&d[q * np..(q + 1) * np], k);
            for l in 0..LANES {
                acc[q][l] = A::madd(wd[l], dq[l], acc[q][l]);
            }
        }
        k += LANES;
    }
    for q in R..P {
        h[R][q] = lane_sum(&acc[q]);
        h[q][R] = h[R][q];
    }
}

/// The `LANES` values of `a` from `k` as an array (one bounds check).
#[inline(always)]
fn block(a: &[f64], k: usize) -> [f64; LANES] {
    block_of::<LANES>(a, k)
}

/// The `W` values of `a` from `k` as an array (one bounds check).
#[inline(always)]
fn block_of<const W: usize>(a: &[f64], k: usize) -> [f64; W] {
    let mut out = [0.0; W];
    out.copy_from_slice(&a[k..k + W]);
    out
}

#[inline(always)]
fn lane_sum(a: &[f64; LANES]) -> f64 {
    (a[0] + a[1]) + (a[2] + a[3])
}

/// The problem a fit works on.
pub(crate) struct Problem<M> {
    pub side: usize,
    pub model: M,
    /// σ when it is not a parameter.
    pub sigma_fixed: f64,
}

impl<M: PixelModel> Problem<M> {
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

    /// Objective (if `OBJECTIVE`), gradient and curvature at θ. `scratch`
    /// holds the input arrays filled by [`prepare`], then the tiles and the
    /// weights and derivatives written here.
    ///
    /// The 1-D terms of both axes are spread over every pixel (tiles), then
    /// pass 1 visits all pixels flat in blocks of [`LANES`] (padding lanes
    /// masked): μ, ∂μ, objective and gradient, storing `w` and `∂μ`; pass 2
    /// sums the curvature one row at a time (see [`curvature_row`]). Every
    /// block is a fixed-size array, so the lanes vectorise.
    #[inline(always)]
    fn evaluate<const P: usize, O: Objective, A: Arith, const OBJECTIVE: bool>(
        &self,
        theta: &[f64; P],
        ax: &mut AxisTerms,
        ay: &mut AxisTerms,
        scratch: &mut [f64],
        lay: Layout,
    ) -> Eval<P> {
        let fit_sigma = P == 5;
        let sigma = if fit_sigma {
            theta[P - 1]
        } else {
            self.sigma_fixed
        };
        let side = lay.side;
        let np = lay.np;
        ax.compute_with::<A>(side, theta[0], sigma, fit_sigma);
        ay.compute_with::<A>(side, theta[1], sigma, fit_sigma);
        let (inputs, rest) = scratch[..(INPUTS + TILES + 1 + P) * np].split_at_mut(INPUTS * np);
        let (tiles, outputs) = rest.split_at_mut(TILES * np);
        {
            let (xe, t) = tiles.split_at_mut(np);
            let (xdc, t) = t.split_at_mut(np);
            let (xds, t) = t.split_at_mut(np);
            let (ye, t) = t.split_at_mut(np);
            let (ydc, yds) = t.split_at_mut(np);
            for j in 0..side {
                let r = j * side..(j + 1) * side;
                xe[r.clone()].copy_from_slice(&ax.e[..side]);
                xdc[r.clone()].copy_from_slice(&ax.dc[..side]);
                ye[r.clone()].fill(ay.e[j]);
                ydc[r.clone()].fill(ay.dc[j]);
                if fit_sigma {
                    xds[r.clone()].copy_from_slice(&ax.ds[..side]);
                    yds[r].fill(ay.ds[j]);
                }
            }
        }
        let (dp, rest) = inputs.split_at(np);
        let (gp, rest) = rest.split_at(np);
        let (op, up) = rest.split_at(np);
        let (n_ph, b) = (theta[2], theta[3]);
        let mut ll = [0.0; LANES];
        let mut g = [[0.0; LANES]; P];
        let mut k0 = 0;
        while k0 < np {
            let data = block(dp, k0);
            let gain = block(gp, k0);
            let offset = block(op, k0);
            let used = block(up, k0);
            let ex = block(tiles, k0);
            let dcx = block(tiles, np + k0);
            let dsx = block(tiles, 2 * np + k0);
            let ey = block(tiles, 3 * np + k0);
            let dcy = block(tiles, 4 * np + k0);
            let dsy = block(tiles, 5 * np + k0);
            let mut d = [[0.0; LANES]; P];
            let mut wv = [0.0; LANES];
            for l in 0..LANES {
                let psf = ex[l] * ey[l];
                let n_ey = n_ph * ey[l];
                let mu = (gain[l] * A::madd(n_ph, psf, b) + offset[l]).max(MU_FLOOR);
                d[0][l] = gain[l] * dcx[l] * n_ey;
                d[1][l] = gain[l] * ex[l] * (n_ph * dcy[l]);
                d[2][l] = gain[l] * psf;
                d[3][l] = gain[l];
                if fit_sigma {
                    d[P - 1][l] = gain[l] * A::madd(dsx[l], n_ey, ex[l] * (n_ph * dsy[l]));
                }
                let (r, w) = if OBJECTIVE {
                    let (lk, r, w) = O::pixel::<A>(data[l], mu);
                    ll[l] = A::madd(used[l], lk, ll[l]);
                    (r, w)
                } else {
                    O::pixel_grad::<A>(data[l], mu)
                };
                let rv = r * used[l];
                for p in 0..P {
                    g[p][l] = A::madd(rv, d[p][l], g[p][l]);
                }
                wv[l] = w * used[l];
            }
            outputs[k0..k0 + LANES].copy_from_slice(&wv);
            for p in 0..P {
                let off = np + p * np + k0;
                outputs[off..off + LANES].copy_from_slice(&d[p]);
            }
            k0 += LANES;
        }
        let (w, d) = outputs.split_at(np);
        let mut h = [[0.0; P]; P];
        // One sweep per curvature row, the row index a compile-time constant
        // so that its accumulators are unrolled into registers.
        curvature_row::<P, 0, A>(w, d, np, &mut h);
        curvature_row::<P, 1, A>(w, d, np, &mut h);
        curvature_row::<P, 2, A>(w, d, np, &mut h);
        curvature_row::<P, 3, A>(w, d, np, &mut h);
        curvature_row::<P, 4, A>(w, d, np, &mut h);
        let mut out = Eval {
            ll: if OBJECTIVE { lane_sum(&ll) } else { f64::NAN },
            g: [0.0; P],
            h,
        };
        for p in 0..P {
            out.g[p] = lane_sum(&g[p]);
        }
        out
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

/// The frame model with one objective.
struct FrameEval<'p, M, O, A> {
    prob: &'p Problem<M>,
    ax: AxisTerms,
    ay: AxisTerms,
    scratch: &'p mut [f64],
    layout: Layout,
    kind: std::marker::PhantomData<(O, A)>,
}

impl<const P: usize, M: PixelModel, O: Objective, A: Arith> Evaluate<P> for FrameEval<'_, M, O, A> {
    #[inline(always)]
    fn eval(&mut self, theta: &[f64; P], objective: bool) -> Eval<P> {
        // The least-squares objective costs nothing extra: always computed.
        if objective || O::LEAST_SQUARES {
            self.prob.evaluate::<P, O, A, true>(
                theta,
                &mut self.ax,
                &mut self.ay,
                self.scratch,
                self.layout,
            )
        } else {
            self.prob.evaluate::<P, O, A, false>(
                theta,
                &mut self.ax,
                &mut self.ay,
                self.scratch,
                self.layout,
            )
        }
    }
    #[inline(always)]
    fn decrement_scale(&self, e: &Eval<P>) -> f64 {
        if O::LEAST_SQUARES {
            // Least squares: decrement in data² units, scaled by the residual
            // variance so that the rule means the same as for Poisson.
            let npix = (self.prob.side * self.prob.side) as f64;
            (-2.0 * e.ll / (npix - P as f64).max(1.0)).max(1e-12)
        } else {
            1.0
        }
    }
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
        theta[p] = theta[p].clamp(lo[p], hi[p]);
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
                theta[p] = (theta[p] + delta[p]).clamp(lo[p], hi[p]);
            }
            converged = true;
            break;
        }
        let mut next = theta;
        for p in 0..P {
            next[p] = (theta[p] + delta[p]).clamp(lo[p], hi[p]);
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
        let lay = Layout::new(side);
        let mut scratch = take_scratch(lay, 5);
        prepare(data, &prob.model, lay, &mut scratch);
        let fit = finish::<5, M, A>(&prob, init, lo, hi, opts, kind, &mut scratch, lay);
        return_scratch(scratch);
        fit
    } else {
        let lay = Layout::new(side);
        let mut scratch = take_scratch(lay, 4);
        prepare(data, &prob.model, lay, &mut scratch);
        let fit = finish::<4, M, A>(&prob, init4, lo4, hi4, opts, kind, &mut scratch, lay);
        return_scratch(scratch);
        fit
    }
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
    scratch: &mut [f64],
    layout: Layout,
) -> Fit {
    let out = match kind {
        Kind::Mle => levenberg_marquardt(
            &mut FrameEval::<M, PoissonObjective, A> {
                prob,
                ax: AxisTerms::default(),
                ay: AxisTerms::default(),
                scratch,
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
                ax: AxisTerms::default(),
                ay: AxisTerms::default(),
                scratch,
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

#[doc(hidden)]
pub fn bench_evaluate(data: &[f64], side: usize, theta: [f64; 5], reps: usize) -> f64 {
    #[target_feature(enable = "avx2,fma")]
    unsafe fn inner(data: &[f64], side: usize, theta: [f64; 5], reps: usize) -> f64 {
        let prob = Problem {
            side,
            model: Uniform,
            sigma_fixed: 1.5,
        };
        let mut ax = AxisTerms::default();
        let mut ay = AxisTerms::default();
        let mut s = 0.0;
        let lay = Layout::new(side);
        let mut scratch = take_scratch(lay, 5);
        prepare(data, &prob.model, lay, &mut scratch);
        for r in 0..reps {
            let mut t = theta;
            t[0] += r as f64 * 1e-9;
            let e = prob.evaluate::<5, PoissonObjective, Fused, true>(
                &t,
                &mut ax,
                &mut ay,
                &mut scratch,
                lay,
            );
            s += e.ll + e.h[1][2];
        }
        s
    }
    unsafe { inner(data, side, theta, reps) }
}
#[doc(hidden)]
pub fn bench_axis(reps: usize) -> f64 {
    #[target_feature(enable = "avx2,fma")]
    unsafe fn inner(reps: usize) -> f64 {
        let mut ax = AxisTerms::default();
        let mut s = 0.0;
        for r in 0..reps {
            ax.compute_with::<Fused>(9, 4.5 + r as f64 * 1e-9, 1.5, true);
            s += ax.e[3] + ax.ds[2];
        }
        s
    }
    unsafe { inner(reps) }
}
