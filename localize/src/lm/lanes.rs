//! Fixed-size blocks of pixels: unchecked loads and stores, lane sums, and
//! the curvature rows, written so that the lanes vectorise.

use crate::fastmath::Arith;

/// Pixels per vectorised block (four f64 lanes: one AVX2 register).
pub(super) const LANES: usize = 4;

/// Row `R` of the curvature, `h[R][q] = Σ_k w_k d_R,k d_q,k` for `q ≥ R`
/// (mirrored), over the first `nb` entries of the pixel arrays `w` and `d`
/// (P arrays of stride `np`). One sweep per row, the row a compile-time
/// constant so that its accumulators are unrolled into registers.
#[inline(always)]
pub(super) fn curvature_row<const P: usize, const R: usize, A: Arith>(
    w: &[f64],
    d: &[f64],
    nb: usize,
    np: usize,
    h: &mut [[f64; P]; P],
) {
    if R >= P {
        return;
    }
    // Every load below is at `q·np + k` with `k + LANES ≤ nb ≤ np`, q < P.
    assert!(nb.is_multiple_of(LANES) && nb <= np && w.len() >= nb && d.len() >= P * np);
    let mut acc = [[0.0; LANES]; P];
    let mut k = 0;
    while k < nb {
        // SAFETY: checked by the assertion above.
        let (wk, drk) = unsafe { (load(w, k), load(d, R * np + k)) };
        let mut wd = [0.0; LANES];
        for l in 0..LANES {
            wd[l] = wk[l] * drk[l];
        }
        for q in R..P {
            // SAFETY: as above.
            let dq = unsafe { load(d, q * np + k) };
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
pub(super) fn block(a: &[f64], k: usize) -> [f64; LANES] {
    block_of::<LANES>(a, k)
}

/// The `LANES` values of `a` from `k`, without a bounds check: the pixel
/// passes check their whole index range once, up front, instead of once per
/// load (bounds checks were a fifth of a fit's instructions).
///
/// # Safety
/// `k + LANES <= a.len()`.
#[inline(always)]
pub(super) unsafe fn load(a: &[f64], k: usize) -> [f64; LANES] {
    debug_assert!(k + LANES <= a.len());
    // SAFETY: in bounds by the caller's contract; [f64; LANES] has the
    // alignment of f64 and no invalid bit patterns.
    unsafe { a.as_ptr().add(k).cast::<[f64; LANES]>().read() }
}

/// Stores `LANES` values into `a` from `k`, without a bounds check.
///
/// # Safety
/// `k + LANES <= a.len()`.
#[inline(always)]
pub(super) unsafe fn store(a: &mut [f64], k: usize, v: [f64; LANES]) {
    debug_assert!(k + LANES <= a.len());
    // SAFETY: in bounds by the caller's contract.
    unsafe { a.as_mut_ptr().add(k).cast::<[f64; LANES]>().write(v) }
}

/// The `W` values of `a` from `k` as an array (one bounds check).
#[inline(always)]
fn block_of<const W: usize>(a: &[f64], k: usize) -> [f64; W] {
    let mut out = [0.0; W];
    out.copy_from_slice(&a[k..k + W]);
    out
}

#[inline(always)]
pub(super) fn lane_sum(a: &[f64; LANES]) -> f64 {
    (a[0] + a[1]) + (a[2] + a[3])
}
