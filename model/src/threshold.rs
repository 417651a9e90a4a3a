//! Stage 3 — threshold, with hysteresis: two levels on the same `H_t`.
//!
//! * **Open.** A pixel can open a track only when `H_t ≥ T_int` (and it is a
//!   3×3 maximum, stage 4): T_int is set for the whole field's false-blink
//!   budget, so that background alone rarely opens a track anywhere.
//! * **Hold.** An open track stays on while the maximum of `H_t` over the
//!   3×3 around its anchor is `≥ T_hold` ([`neighbourhood_on`] with
//!   `T_hold`), `T_hold ≤ T_int`. A lower hold level keeps a blink's track on
//!   through the noise of its own signal, so that one blink gives one record
//!   whose live range spans the blink; with `T_hold = T_int` this is the
//!   paper's one-threshold rule.
//!
//! `T_int ≥ 1` always (with no background T = 0, and `H ≥ 0` would fire
//! everywhere); see [`crate::stats`] for how T_int follows from the paper's Eq. 7.

use bitvec::prelude::*;

/// Pixels whose filtered value reaches the threshold, raster order.
pub fn above(filtered: &[u32], threshold_int: u32) -> BitVec<u64, Lsb0> {
    filtered.iter().map(|&h| h >= threshold_int).collect()
}

/// Whether the maximum of H over the 3×3 neighbourhood of (x, y) (clipped to
/// the sensor) reaches the threshold: the on/off test of a track's anchor.
pub fn neighbourhood_on(
    filtered: &[u32],
    width: usize,
    height: usize,
    x: usize,
    y: usize,
    threshold_int: u32,
) -> bool {
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(width - 1));
    let (y0, y1) = (y.saturating_sub(1), (y + 1).min(height - 1));
    (y0..=y1).any(|yy| (x0..=x1).any(|xx| filtered[yy * width + xx] >= threshold_int))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threshold_is_inclusive() {
        let a = above(&[0, 4, 5, 6], 5);
        assert_eq!(
            a.iter().by_vals().collect::<Vec<_>>(),
            vec![false, false, true, true]
        );
    }

    #[test]
    fn neighbourhood_is_clipped_at_edges() {
        // 3x2 plane, only (2,1) reaches the threshold.
        let h = [0, 0, 0, 0, 0, 9];
        assert!(neighbourhood_on(&h, 3, 2, 1, 0, 9));
        assert!(neighbourhood_on(&h, 3, 2, 2, 1, 9));
        assert!(!neighbourhood_on(&h, 3, 2, 0, 0, 9));
        assert!(!neighbourhood_on(&h, 3, 2, 1, 0, 10));
    }
}
