//! The FWFT FIFO against a software queue: random pushes and pops (full
//! rate and stalled), refusal when full, restart.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::bram::RamStyle;
use smartagg_hdl::fifo::Fifo;
use smartagg_hdl::testbench::bench::{settle, Bench};
use std::collections::VecDeque;

fn run(style: RamStyle, push_p: f64, pop_p: f64, seed: u64, min_popped: usize) {
    let mut rng = common::rng(seed);
    let mut b = Bench::new(Fifo::<12, 3>::new(style), |u| &mut u.clock);
    b.uut.restart.next = true;
    b.tick();
    b.uut.restart.next = false;
    let mut model: VecDeque<(u64, usize)> = VecDeque::new();
    let mut refused = false;
    let mut popped = 0;
    for cycle in 0..3000 {
        let u = &mut b.uut;
        let push = rng.gen_bool(push_p);
        let pop = rng.gen_bool(pop_p);
        let v: u64 = rng.gen_range(0..4096);
        u.push.next = push;
        u.push_data.next = v.to_bits();
        u.pop.next = pop;
        settle(u);
        // Head and count visible before the clock.
        // A head entry pushed three clocks ago or earlier is visible; nothing
        // is visible that was not pushed.
        if u.out_valid.val() {
            assert_eq!(u.out_data.val().to_u64(), model[0].0, "cycle {cycle}");
        } else if let Some(&(_, at)) = model.front() {
            assert!(
                cycle < at + 3,
                "head pushed at {at} still hidden at {cycle}"
            );
        }
        assert_eq!(
            u.count.val().to_u64() as usize,
            model.len(),
            "cycle {cycle}"
        );
        let accepted = push && u.room.val();
        if push && !accepted {
            refused = true;
        }
        if pop && u.out_valid.val() {
            model.pop_front();
            popped += 1;
        }
        if accepted {
            model.push_back((v, cycle));
        }
        b.tick();
        assert_eq!(b.uut.overflow.val(), refused);
    }
    assert!(popped >= min_popped, "only {popped} entries went through");
}

#[test]
fn fifo_equals_a_queue_at_full_rate_and_with_stalls() {
    for (i, style) in [RamStyle::Block, RamStyle::Distributed]
        .into_iter()
        .enumerate()
    {
        run(style, 0.5, 0.5, 1 + i as u64, 1000);
        run(style, 0.9, 0.3, 3 + i as u64, 700); // fills up: refusals
        run(style, 0.3, 0.95, 5 + i as u64, 700);
        run(style, 0.5, 1.0, 9 + i as u64, 1200);
        // One in and one out every clock after the first three.
        run(style, 1.0, 1.0, 7 + i as u64, 2997);
    }
}
