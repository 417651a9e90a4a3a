//! The clock-enabled register group against a software register file:
//! random loads and holds, and the Verilog it writes (one enable for the
//! whole group, each lane loaded only under it).

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::stream::EnableRegs;
use smartagg_hdl::testbench::bench::{settle, Bench};

#[test]
fn enable_regs_load_only_when_enabled_and_hold_otherwise() {
    for (seed, load_p) in [(1, 0.5), (2, 0.05), (3, 0.95)] {
        let mut rng = common::rng(seed);
        let lanes = 5;
        let mut b = Bench::new(EnableRegs::<Bits<12>>::new(lanes), |u| &mut u.clock);
        let mut model = vec![0u64; lanes];
        let (mut loads, mut holds) = (0, 0);
        for cycle in 0..2000 {
            let u = &mut b.uut;
            let enable = rng.gen_bool(load_p);
            let values: Vec<u64> = (0..lanes).map(|_| rng.gen_range(0..4096)).collect();
            u.enable.next = enable;
            for (d, &v) in u.d.iter_mut().zip(&values) {
                d.next = v.to_bits();
            }
            settle(u);
            b.tick();
            if enable {
                model.copy_from_slice(&values);
                loads += 1;
            } else {
                holds += 1;
            }
            let q: Vec<u64> = b.uut.q.iter().map(|q| q.val().to_u64()).collect();
            assert_eq!(q, model, "seed {seed} cycle {cycle}");
        }
        assert!(
            loads > 0 && holds > 0,
            "seed {seed}: {loads} loads, {holds} holds"
        );
    }
}

#[test]
fn enable_regs_verilog_has_one_enable_for_the_group() {
    let mut regs = EnableRegs::<Bits<12>>::new(3);
    regs.connect_all();
    let v = generate_verilog(&regs);
    assert_eq!(v.matches("if (enable)").count(), 1, "{v}");
    for i in 0..3 {
        assert!(v.contains(&format!("q${i} <= d${i};")), "{v}");
        assert!(v.contains(&format!("input wire  [11:0] d${i}")), "{v}");
        assert!(v.contains(&format!("output reg  [11:0] q${i}")), "{v}");
    }
}
