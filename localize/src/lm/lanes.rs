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

/// The sum of the lanes, pairwise.
#[inline(always)]
pub(super) fn lane_sum(a: &[f64; LANES]) -> f64 {
    (a[0] + a[1]) + (a[2] + a[3])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fastmath::Plain;
    use proptest::prelude::*;

    proptest! {
        /// Any weights and derivatives, any whole number of blocks, any
        /// padding of the parameter arrays: every row (and its mirror) is
        /// `Σ_k w_k d_R,k d_q,k` over the first `nb` pixels, padding unread.
        #[test]
        fn curvature_rows_are_the_weighted_sums(
            blocks in 0usize..6,
            pad in 0usize..5,
            seed in proptest::collection::vec(-4.0f64..4.0, 4 * 24 + 24),
        ) {
            const P: usize = 4;
            let nb = blocks * LANES;
            let np = nb + pad;
            let w: Vec<f64> = (0..nb).map(|k| seed[k].abs()).collect();
            // Padding is NaN: a sum that read it would not be finite.
            let d: Vec<f64> = (0..P * np)
                .map(|i| if i % np < nb { seed[24 + i % 96] } else { f64::NAN })
                .collect();
            let mut h = [[f64::NAN; P]; P];
            curvature_row::<P, 0, Plain>(&w, &d, nb, np, &mut h);
            curvature_row::<P, 1, Plain>(&w, &d, nb, np, &mut h);
            curvature_row::<P, 2, Plain>(&w, &d, nb, np, &mut h);
            curvature_row::<P, 3, Plain>(&w, &d, nb, np, &mut h);
            // A row past the parameters writes nothing.
            curvature_row::<P, 4, Plain>(&w, &d, nb, np, &mut h);
            for r in 0..P {
                for q in 0..P {
                    let want: f64 = (0..nb).map(|k| w[k] * d[r * np + k] * d[q * np + k]).sum();
                    prop_assert!((h[r][q] - want).abs() <= 1e-9 * (1.0 + want.abs()),
                        "h[{}][{}] = {} want {}", r, q, h[r][q], want);
                    prop_assert_eq!(h[r][q].to_bits(), h[q][r].to_bits());
                }
            }
        }
    }

    #[test]
    fn blocks_and_lane_sums() {
        let a: Vec<f64> = (0..8).map(f64::from).collect();
        assert_eq!(block(&a, 4), [4.0, 5.0, 6.0, 7.0]);
        let mut b = vec![0.0; 8];
        // SAFETY: 2 + LANES ≤ 8.
        unsafe { store(&mut b, 2, load(&a, 1)) };
        assert_eq!(b, [0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 0.0, 0.0]);
        assert_eq!(lane_sum(&[1.0, 2.0, 4.0, 8.0]), 15.0);
    }
}
