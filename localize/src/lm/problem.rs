//! The frame model a fit works on: μ and its derivatives over the ROI, the
//! two vectorised passes that give objective, gradient and curvature, and
//! its adapter to the Levenberg–Marquardt iteration.

use super::iterate::{Eval, Evaluate};
use super::lanes::{block, curvature_row, lane_sum, load, store, LANES};
use super::model::{Objective, PixelModel};
use super::scratch::{Layout, INPUTS, TILES};
use crate::fastmath::Arith;
use crate::psf::AxisTerms;

/// Smallest expected value allowed in a pixel (keeps `ln μ` and `1/μ` finite
/// when background and dark counts are zero).
const MU_FLOOR: f64 = 1e-12;

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
    ///
    /// [`prepare`]: super::scratch::prepare
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
        // The loads and stores below are unchecked: their ranges are checked
        // here, once. Pass 1 reads and writes `t·np + k0 .. + LANES` with
        // `k0 + LANES ≤ nb ≤ np`; the tiles write `j·side + i0 .. + LANES`
        // with `i0 < side`, which ends before `side² + LANES ≤ np`.
        assert!(lay.nb.is_multiple_of(LANES) && lay.nb >= side * side && lay.nb + LANES <= np);
        let (inputs, rest) = scratch[..(INPUTS + TILES + 1 + P) * np].split_at_mut(INPUTS * np);
        let (tiles, outputs) = rest.split_at_mut(TILES * np);
        {
            let (xe, t) = tiles.split_at_mut(np);
            let (xdc, t) = t.split_at_mut(np);
            let (xds, t) = t.split_at_mut(np);
            let (ye, t) = t.split_at_mut(np);
            let (ydc, yds) = t.split_at_mut(np);
            // Whole blocks of four (fixed-size copies, no library memcpy);
            // rows in increasing order so that a spill is overwritten.
            let blocks = side.div_ceil(LANES);
            for j in 0..side {
                let (ej, dcj, dsj) = (ay.e[j], ay.dc[j], ay.ds[j]);
                for bi in 0..blocks {
                    let i0 = bi * LANES;
                    let q = j * side + i0;
                    let (e, dc, ds) = (block(&ax.e, i0), block(&ax.dc, i0), block(&ax.ds, i0));
                    // SAFETY: q + LANES ≤ side² + LANES ≤ np = len (asserted).
                    unsafe {
                        store(xe, q, e);
                        store(xdc, q, dc);
                        store(ye, q, [ej; LANES]);
                        store(ydc, q, [dcj; LANES]);
                        if fit_sigma {
                            store(xds, q, ds);
                            store(yds, q, [dsj; LANES]);
                        }
                    }
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
        while k0 < lay.nb {
            // SAFETY: k0 + LANES ≤ nb ≤ np, each array np long (asserted).
            let (data, gain, offset, used, ex, dcx, dsx, ey, dcy, dsy) = unsafe {
                let (gain, offset) = if M::UNIFORM {
                    ([1.0; LANES], [0.0; LANES])
                } else {
                    (load(gp, k0), load(op, k0))
                };
                (
                    load(dp, k0),
                    gain,
                    offset,
                    load(up, k0),
                    load(tiles, k0),
                    load(tiles, np + k0),
                    load(tiles, 2 * np + k0),
                    load(tiles, 3 * np + k0),
                    load(tiles, 4 * np + k0),
                    load(tiles, 5 * np + k0),
                )
            };
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
            // SAFETY: as the loads; outputs hold (1 + P) arrays of np.
            unsafe {
                store(outputs, k0, wv);
                for p in 0..P {
                    store(outputs, np + p * np + k0, d[p]);
                }
            }
            k0 += LANES;
        }
        let (w, d) = outputs.split_at(np);
        let mut h = [[0.0; P]; P];
        curvature_row::<P, 0, A>(w, d, lay.nb, np, &mut h);
        curvature_row::<P, 1, A>(w, d, lay.nb, np, &mut h);
        curvature_row::<P, 2, A>(w, d, lay.nb, np, &mut h);
        curvature_row::<P, 3, A>(w, d, lay.nb, np, &mut h);
        curvature_row::<P, 4, A>(w, d, lay.nb, np, &mut h);
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

/// The frame model with one objective.
pub(super) struct FrameEval<'p, M, O, A> {
    pub(super) prob: &'p Problem<M>,
    pub(super) ax: &'p mut AxisTerms,
    pub(super) ay: &'p mut AxisTerms,
    pub(super) scratch: &'p mut [f64],
    pub(super) layout: Layout,
    pub(super) kind: std::marker::PhantomData<(O, A)>,
}

impl<const P: usize, M: PixelModel, O: Objective, A: Arith> Evaluate<P> for FrameEval<'_, M, O, A> {
    #[inline(always)]
    fn eval(&mut self, theta: &[f64; P], objective: bool) -> Eval<P> {
        // The least-squares objective costs nothing extra: always computed.
        if objective || O::LEAST_SQUARES {
            self.prob
                .evaluate::<P, O, A, true>(theta, self.ax, self.ay, self.scratch, self.layout)
        } else {
            self.prob
                .evaluate::<P, O, A, false>(theta, self.ax, self.ay, self.scratch, self.layout)
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
