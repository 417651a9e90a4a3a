//! The threshold comparators against the model's `threshold::above`,
//! including values equal to T_int (inclusive) and the extremes of HW bits.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::testbench::bench::settle;
use smartagg_hdl::threshold::Threshold;
use smartagg_model::threshold::above;

#[test]
fn threshold_equals_model() {
    let mut uut = Threshold::<11>::new(8);
    uut.connect_all();
    check_all(&uut).unwrap();
    let mut rng = common::rng(41);
    for round in 0..200 {
        let t: u32 = if round % 50 == 0 {
            2047
        } else {
            rng.gen_range(1..2048)
        };
        let h: Vec<u32> = (0..8)
            .map(|i| match i {
                0 => t,
                1 => t - 1,
                2 => 2047,
                _ => rng.gen_range(0..2048),
            })
            .collect();
        uut.threshold.next = (t as u64).to_bits();
        for (s, &v) in uut.filtered.iter_mut().zip(&h) {
            s.next = (v as u64).to_bits();
        }
        settle(&mut uut);
        let want: Vec<bool> = above(&h, t).iter().by_vals().collect();
        let got: Vec<bool> = uut.above.iter().map(|a| a.val()).collect();
        assert_eq!(got, want, "H = {h:?}, T_int = {t}");
    }
}

/// Hysteresis as the candidate finder builds it: two comparator banks on the
/// same H, one at T_int (candidates) and one at T_hold ≤ T_int (the above
/// bits): each equals the model's `above` at its own level, and a pixel
/// with T_hold ≤ H < T_int is above the hold level only.
#[test]
fn two_levels_follow_t_int_and_t_hold() {
    let mut open = Threshold::<11>::new(8);
    let mut hold = Threshold::<11>::new(8);
    open.connect_all();
    hold.connect_all();
    let mut rng = common::rng(43);
    let mut between = 0;
    for _ in 0..200 {
        let t_int: u32 = rng.gen_range(2..2048);
        let t_hold: u32 = rng.gen_range(1..=t_int);
        let h: Vec<u32> = (0..8)
            .map(|i| match i {
                0 => t_int,
                1 => t_int - 1,
                2 => t_hold,
                3 => t_hold - 1,
                _ => rng.gen_range(0..2048),
            })
            .collect();
        open.threshold.next = (t_int as u64).to_bits();
        hold.threshold.next = (t_hold as u64).to_bits();
        for ((a, b), &v) in open
            .filtered
            .iter_mut()
            .zip(hold.filtered.iter_mut())
            .zip(&h)
        {
            a.next = (v as u64).to_bits();
            b.next = (v as u64).to_bits();
        }
        settle(&mut open);
        settle(&mut hold);
        let got_open: Vec<bool> = open.above.iter().map(|a| a.val()).collect();
        let got_hold: Vec<bool> = hold.above.iter().map(|a| a.val()).collect();
        let want_open: Vec<bool> = above(&h, t_int).iter().by_vals().collect();
        let want_hold: Vec<bool> = above(&h, t_hold).iter().by_vals().collect();
        assert_eq!(got_open, want_open, "H = {h:?}, T_int = {t_int}");
        assert_eq!(got_hold, want_hold, "H = {h:?}, T_hold = {t_hold}");
        for i in 0..8 {
            assert!(!got_open[i] || got_hold[i], "above T_int but not T_hold");
            between += (got_hold[i] && !got_open[i]) as usize;
        }
    }
    assert!(between > 0, "some H between the levels");
}
