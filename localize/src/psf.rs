//! The pixel-integrated Gaussian PSF and its derivatives.
//!
//! Coordinates are in ROI pixels with the ImageJ convention: pixel column `i`
//! covers `[i, i + 1)`, so its centre is at `i + 0.5`, and the ROI's top-left
//! corner is `(0, 0)`. The expected fraction of an emitter's photons that
//! lands in pixel `(i, j)` is `Ex_i · Ey_j`, a product of two 1-D integrals,
//! so a whole `R × R` ROI costs `2 (R + 1)` erf evaluations, not `R²`.

use crate::fastmath::{erfc_nonneg, exp_nonpositive, Arith, Plain};

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
    pub fn compute(&mut self, n: usize, c: f64, sigma: f64, with_sigma: bool) {
        self.compute_with::<Plain>(n, c, sigma, with_sigma);
    }

    /// [`AxisTerms::compute`] with the fit's arithmetic.
    #[inline(always)]
    pub(crate) fn compute_with<A: Arith>(
        &mut self,
        n: usize,
        c: f64,
        sigma: f64,
        with_sigma: bool,
    ) {
        debug_assert!(n <= MAX_SIDE && sigma > 0.0);
        self.n = n;
        let inv = std::f64::consts::FRAC_1_SQRT_2 / sigma;
        let pdf_scale = FRAC_1_SQRT_2PI / sigma;
        let inv_sigma = 1.0 / sigma;
        // Pixels in blocks of four (fixed-size arrays: the lanes vectorise).
        // Block b needs edges 4b..4b+4: its own four lower edges and the
        // first edge of the next block, passed along in registers rather than
        // through memory. Lanes past `n` (up to the next multiple of four)
        // get the masses of virtual pixels beyond the ROI: finite, and masked
        // out by the fits.
        assert!(n <= MAX_SIDE);
        let mut lower = edge_block::<A>(0, c, inv, pdf_scale);
        for blk in 0..n.div_ceil(4) {
            // The next block's first edge is needed only if it bounds a real
            // pixel; otherwise it would serve virtual pixels alone.
            let next = if 4 * (blk + 1) <= n {
                edge_block::<A>(blk + 1, c, inv, pdf_scale)
            } else {
                EdgeBlock::default()
            };
            let t1 = shift_in(&lower.tail, &next.tail);
            let r1 = shift_in(&lower.right, &next.right);
            let p1 = shift_in(&lower.pdf, &next.pdf);
            let u1 = shift_in(&lower.updf, &next.updf);
            let (t0, r0, p0, u0) = (lower.tail, lower.right, lower.pdf, lower.updf);
            let mut e = [0.0; 4];
            let mut dc = [0.0; 4];
            let mut ds = [0.0; 4];
            for l in 0..4 {
                // Mass in [u_i, u_{i+1}] without cancelling two numbers near
                // 1: both edges right of the centre, both left, or straddling.
                let both_right = t0[l] - t1[l];
                let both_left = t1[l] - t0[l];
                let straddle = 1.0 - t0[l] - t1[l];
                let mass = if r0[l] > 0.5 {
                    both_right
                } else if r1[l] < 0.5 {
                    both_left
                } else {
                    straddle
                };
                e[l] = mass.max(0.0);
                dc[l] = p0[l] - p1[l];
                ds[l] = (u0[l] - u1[l]) * inv_sigma;
            }
            let i0 = 4 * blk;
            self.e[i0..i0 + 4].copy_from_slice(&e);
            self.dc[i0..i0 + 4].copy_from_slice(&dc);
            if with_sigma {
                self.ds[i0..i0 + 4].copy_from_slice(&ds);
            }
            lower = next;
        }
    }
}

/// Values at edges `4 blk .. 4 blk + 4` for centre `c`, `inv = 1/(σ√2)`,
/// `pdf_scale = 1/(σ√2π)`. Computed for every lane then selected
/// (branch-free); beyond |z| = 26 erfc < 1e-295 counts as zero.
#[inline(always)]
fn edge_block<A: Arith>(blk: usize, c: f64, inv: f64, pdf_scale: f64) -> EdgeBlock {
    let mut out = EdgeBlock::default();
    for l in 0..4 {
        let u = (4 * blk + l) as f64 - c;
        let z = u * inv;
        let a = z.abs();
        let inside = a < 26.0;
        let g0 = exp_nonpositive::<A>(-a * a);
        let t0 = 0.5 * erfc_nonneg::<A>(a.min(26.0), g0);
        let g = if inside { g0 } else { 0.0 };
        out.tail[l] = if inside { t0 } else { 0.0 };
        out.right[l] = if z >= 0.0 { 1.0 } else { 0.0 };
        out.pdf[l] = g * pdf_scale;
        out.updf[l] = u * out.pdf[l];
    }
    out
}

/// `[a1, a2, a3, b0]`: the upper edges of a block of pixels.
#[inline(always)]
fn shift_in(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    [a[1], a[2], a[3], b[0]]
}

/// Values at four consecutive pixel edges.
#[derive(Clone, Copy, Default)]
struct EdgeBlock {
    /// Tail mass beyond the edge, on its side of the centre.
    tail: [f64; 4],
    /// 1 if the edge is right of the centre, else 0.
    right: [f64; 4],
    /// Gaussian pdf at the edge.
    pdf: [f64; 4],
    /// Offset from the centre times the pdf.
    updf: [f64; 4],
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
