//! The threshold comparators against the model's `threshold::above`,
//! including values equal to T_int (inclusive) and the extremes of HW bits.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::sim::settle;
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
