//! The walk pipeline's W1 and W2 stages against their definition, clock
//! by clock: a slot offered by the read stage moves into W1 when W1 is
//! empty or moves on; W1 moves into W2 when W2 is empty or the tracker is
//! `done` with it, and W2 then holds W1's slot with what [`WalkStep`] makes
//! of it under the walk's inputs of that clock (a second, free-standing
//! `WalkStep` computes it); a restart empties both. Random slots, random
//! offers, stalls and walk inputs every clock, stretches at full speed (one
//! slot a clock), and restarts with slots in flight.

mod common;

use common::walk::StepOut;
use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::{WalkStages, WalkStep};
use smartagg_hdl::testbench::bench::{settle, Bench};

/// A slot as the read stage gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Slot {
    slot: u64,
    last: bool,
    busy: bool,
    live: bool,
    dip: bool,
    pend: bool,
    opened: bool,
    bridge: bool,
    ax: u64,
    ay: u64,
    bank: u64,
    word: u64,
}

/// The walk's inputs of one clock.
#[derive(Clone, Copy, Debug)]
struct Walk {
    kind: usize,
    t: u64,
    t1_ge_n: bool,
    lmin: u64,
    lmax_m1: u64,
    n_mc: u64,
}

/// Drives the walk's inputs of a block that has them (`WalkStep`, and
/// `WalkStages`, which passes them to its own).
macro_rules! drive_walk {
    ($u:expr, $w:expr) => {{
        $u.end_of_plane.next = $w.kind == 0;
        $u.finish.next = $w.kind == 1;
        $u.drain.next = $w.kind == 2;
        $u.t.next = $w.t.to_bits();
        $u.t1_ge_n.next = $w.t1_ge_n;
        $u.lmin.next = $w.lmin.to_bits();
        $u.lmin_p1.next = ($w.lmin + 1).to_bits();
        $u.lmax_m1.next = $w.lmax_m1.to_bits();
        $u.n_mc.next = $w.n_mc.to_bits();
        $u.mc_one.next = $w.n_mc == 1;
    }};
}

const M: u64 = 20;

fn random_slot(rng: &mut impl Rng) -> Slot {
    let slot = rng.gen_range(0..M);
    // Mostly ages near the walk's limits (L_min, L_max, N − end_trim), so
    // that every comparison of the step goes both ways.
    let mut word = rng.gen::<u64>() & ((1 << 39) - 1);
    if rng.gen_bool(0.8) {
        let (age, dage) = (rng.gen_range(0..42u64), rng.gen_range(0..14u64));
        word = word >> 36 << 36 | dage << 18 | age;
    }
    Slot {
        slot,
        last: slot == M - 1,
        busy: rng.gen(),
        live: rng.gen(),
        dip: rng.gen_bool(0.3),
        pend: rng.gen_bool(0.3),
        opened: rng.gen_bool(0.2),
        bridge: rng.gen(),
        ax: rng.gen_range(0..1024),
        ay: rng.gen_range(0..1024),
        bank: rng.gen_range(0..32),
        word,
    }
}

fn random_walk(rng: &mut impl Rng) -> Walk {
    let lmin = rng.gen_range(1..20);
    Walk {
        kind: rng.gen_range(0..3),
        t: rng.gen_range(0..1u64 << 40),
        t1_ge_n: rng.gen(),
        lmin,
        lmax_m1: rng.gen_range(lmin..40),
        n_mc: rng.gen_range(1..12),
    }
}

/// The walk step of `s` under `w`, from the free-standing block.
fn step_of(o: &mut WalkStep, s: &Slot, w: &Walk) -> StepOut {
    drive_walk!(o, w);
    o.busy.next = s.busy;
    o.live.next = s.live;
    o.dip.next = s.dip;
    o.pend.next = s.pend;
    o.opened.next = s.opened;
    o.word.next = s.word.to_bits();
    settle(o);
    StepOut::of_step(o)
}

#[test]
fn walk_stages_hold_each_slot_and_its_step_in_order_under_stalls_and_restarts() {
    let mut rng = common::rng(61);
    let mut oracle = WalkStep::default();
    oracle.connect_all();
    let mut b = Bench::new(WalkStages::<5>::default(), |u| &mut u.clock);
    let (mut w1, mut w2): (Option<Slot>, Option<(Slot, StepOut)>) = (None, None);
    let (mut taken, mut out, mut held, mut stalls, mut restarts) = (0, 0, 0, 0, 0);
    for clock in 0..40_000 {
        // Stretches at full speed (every slot offered, W2 done at once),
        // the rest at random.
        let full_speed = clock % 1000 < 150;
        let s = random_slot(&mut rng);
        let w = random_walk(&mut rng);
        let offer = full_speed || rng.gen_bool(0.6);
        let done = full_speed || rng.gen_bool(0.5);
        let restart = !full_speed && rng.gen_bool(0.01);
        let u = &mut b.uut;
        u.offer.next = offer;
        u.s_sel.next = (1u64 << s.slot).to_bits();
        u.s_slot.next = s.slot.to_bits();
        u.s_last.next = s.last;
        u.s_busy.next = s.busy;
        u.s_live.next = s.live;
        u.s_dip.next = s.dip;
        u.s_pend.next = s.pend;
        u.s_opened.next = s.opened;
        u.s_bridge.next = s.bridge;
        u.s_ax.next = s.ax.to_bits();
        u.s_ay.next = s.ay.to_bits();
        u.s_bank.next = s.bank.to_bits();
        u.s_word.next = s.word.to_bits();
        drive_walk!(u, w);
        u.done.next = done;
        u.restart.next = restart;
        settle(u);
        // The definition.
        let w2_ready = w2.is_none() || done;
        let w1_ready = w1.is_none() || w2_ready;
        let take = offer && w1_ready;
        assert_eq!(u.take.val(), take, "clock {clock}: take");
        assert_eq!(u.w2.valid.val(), w2.is_some(), "clock {clock}: W2 valid");
        if let Some((slot, step)) = w2 {
            let got_slot = Slot {
                slot: u.w2.slot.val().to_u64(),
                last: u.w2.last.val(),
                busy: u.w2.was_busy.val(),
                bridge: u.w2.bridge.val(),
                ax: u.w2.ax.val().to_u64(),
                ay: u.w2.ay.val().to_u64(),
                bank: u.w2.bank.val().to_u64(),
                ..slot
            };
            assert_eq!(got_slot, slot, "clock {clock}: W2's slot");
            assert_eq!(
                u.w2.sel.val().to_u64(),
                1 << slot.slot,
                "clock {clock}: one-hot"
            );
            let got_step = StepOut::of_w2(&u.w2, u.word.val().to_u64());
            assert_eq!(got_step, step, "clock {clock}: W2's step");
            out += done as usize;
            stalls += !done as usize;
        }
        held += (offer && !take) as usize;
        taken += take as usize;
        let loaded = w1.map(|slot| (slot, step_of(&mut oracle, &slot, &w)));
        b.tick();
        if restart {
            (w1, w2) = (None, None);
            restarts += 1;
            continue;
        }
        if w2_ready {
            w2 = loaded;
        }
        if take {
            w1 = Some(s);
        } else if w2_ready {
            w1 = None;
        }
    }
    assert!(
        taken > 15_000 && out > 15_000 && held > 2_000 && stalls > 5_000 && restarts > 200,
        "{taken} taken, {out} out, {held} held back, {stalls} stalls, {restarts} restarts"
    );
}
