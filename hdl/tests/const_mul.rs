//! The constant multiplier against `w · x mod 2^W`, and its signed-digit
//! form against the weight it must make.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::testbench::bench::settle;

#[test]
fn csd_digits_make_the_weight_with_the_fewest_terms() {
    use smartagg_hdl::const_mul::csd_digits;
    for w in 0u32..=70_000 {
        let d = csd_digits(w);
        let value: i64 = d
            .iter()
            .map(|&(s, neg)| if neg { -(1i64 << s) } else { 1i64 << s })
            .sum();
        assert_eq!(value, w as i64, "weight {w}: digits {d:?}");
        // Most significant first, strictly descending, never two adjacent.
        assert!(
            d.windows(2).all(|p| p[0].0 >= p[1].0 + 2),
            "weight {w}: {d:?}"
        );
        assert!(d.first().is_none_or(|&(_, neg)| !neg), "weight {w}: {d:?}");
        assert!(d.len() as u32 <= w.count_ones(), "weight {w}: {d:?}");
    }
    assert_eq!(csd_digits(29), vec![(5, false), (2, true), (0, false)]);
}

/// `ConstMul<W>` against `w · x mod 2^W` (the DSP form: with x narrowed to
/// its operand bits), x over the whole W bits.
fn const_mul_case<const W: usize>(seed: u64) {
    use smartagg_hdl::const_mul::ConstMul;
    let mut rng = common::rng(seed);
    for (w, dsp) in [
        0u32,
        1,
        2,
        3,
        7,
        10,
        29,
        54,
        66,
        255,
        1023,
        0xAAAA,
        u32::MAX,
    ]
    .into_iter()
    .flat_map(|w| [(w, None), (w, Some(12))])
    {
        let mut m = ConstMul::<W>::of((w, dsp));
        m.connect_all();
        for _ in 0..50 {
            let x: u64 = rng.gen::<u64>() >> (64 - W);
            m.x.next = x.to_bits();
            settle(&mut m);
            let operand = dsp.map_or(x as u128, |b| x as u128 & ((1 << b) - 1));
            let want = (operand * w as u128) & ((1u128 << W) - 1);
            assert_eq!(
                m.y.val().to_u64() as u128,
                want,
                "{w} * {x} in {W} bits (DSP {dsp:?})"
            );
        }
    }
}

#[test]
fn const_mul_equals_the_product_modulo_its_width() {
    const_mul_case::<16>(7);
    const_mul_case::<24>(8);
    const_mul_case::<40>(9);
    const_mul_case::<64>(10);
}
