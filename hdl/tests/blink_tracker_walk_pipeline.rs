//! The blink tracker's walk pipeline against its definition (the tracker
//! as a whole is checked against the model in `blink_tracker.rs`, the walk
//! stages and the walk step in `blink_tracker_walk_stages.rs`, where the
//! walk step serves as an oracle, as it does here): walks of M slots
//! started at random, with W2's slot done at random or at once, restarts
//! in the middle of a walk, and the walk's constants and slots' state
//! changed between walks. Every clock:
//! * W2 gives the slots in slot order, each once a walk, and none outside
//!   a walk; the last is marked;
//! * each slot's flags, anchor and bank as the walk read them, and what
//!   the walk step makes of them with the slot's word (the word the walk
//!   memory holds: the last one written back), the walk's inputs and its
//!   constants (N − end_trim, L_min, L_min + 1, L_max − 1 of the registers);
//! * at full speed (W2 done as soon as it holds a slot) slot k is out
//!   k + 2 clocks after the read stage starts: one slot a clock;
//! * with one slot, a walk that starts in the clock the previous one writes
//!   the slot back reads the word written.

mod common;

use common::walk::StepOut;
use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::slot_word::{AX, AY, BANK};
use smartagg_hdl::blink_tracker::{WalkPipeline, WalkStep, WalkedSlot};
use smartagg_hdl::testbench::bench::{settle, Bench};

const BW: usize = 5;

/// A slot's state as the walk reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Slot {
    busy: bool,
    live: bool,
    dip: bool,
    pend: bool,
    opened: bool,
    bridge: bool,
    ax: u64,
    ay: u64,
    bank: u64,
}

/// The walk's inputs, constant through a walk.
#[derive(Clone, Copy, Debug)]
struct Walk {
    kind: usize,
    t: u64,
    t1_ge_n: bool,
    n: u64,
    end_trim: u64,
    l_min: u64,
    l_max: u64,
}

/// What W2 gives for a slot.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Out {
    slot: u64,
    last: bool,
    was_busy: bool,
    bridge: bool,
    ax: u64,
    ay: u64,
    bank: u64,
    /// The walk step's outputs (the word written back stays inside the
    /// pipeline: 0 here).
    step: StepOut,
}

fn random_slot(rng: &mut impl Rng) -> Slot {
    Slot {
        busy: rng.gen(),
        live: rng.gen(),
        dip: rng.gen_bool(0.3),
        pend: rng.gen_bool(0.3),
        opened: rng.gen_bool(0.2),
        bridge: rng.gen(),
        ax: rng.gen_range(0..1024),
        ay: rng.gen_range(0..1024),
        bank: rng.gen_range(0..1 << BW),
    }
}

fn random_walk(rng: &mut impl Rng) -> Walk {
    let n = rng.gen_range(1..12);
    let l_min = rng.gen_range(1..20);
    Walk {
        kind: rng.gen_range(0..3),
        t: rng.gen_range(0..1u64 << 40),
        t1_ge_n: rng.gen(),
        n,
        end_trim: rng.gen_range(0..n),
        l_min,
        l_max: rng.gen_range(l_min.max(n)..40),
    }
}

/// W2's output for slot `k` of `s`, with walk word `word`, under `w`, and
/// the word the walk writes back: the free-standing walk step's.
fn expected(o: &mut WalkStep, k: usize, m: usize, s: &Slot, word: u64, w: &Walk) -> (Out, u64) {
    o.end_of_plane.next = w.kind == 0;
    o.finish.next = w.kind == 1;
    o.drain.next = w.kind == 2;
    o.t.next = w.t.to_bits();
    o.t1_ge_n.next = w.t1_ge_n;
    o.lmin.next = w.l_min.to_bits();
    o.lmin_p1.next = (w.l_min + 1).to_bits();
    o.lmax_m1.next = (w.l_max - 1).to_bits();
    o.n_mc.next = (w.n - w.end_trim).to_bits();
    o.mc_one.next = w.n - w.end_trim == 1;
    o.busy.next = s.busy;
    o.live.next = s.live;
    o.dip.next = s.dip;
    o.pend.next = s.pend;
    o.opened.next = s.opened;
    o.word.next = word.to_bits();
    settle(o);
    let step = StepOut::of_step(o);
    let out = Out {
        slot: k as u64,
        last: k + 1 == m,
        was_busy: s.busy,
        bridge: s.bridge,
        ax: s.ax,
        ay: s.ay,
        bank: s.bank,
        step: StepOut { word: 0, ..step },
    };
    (out, step.word)
}

fn got(u: &WalkedSlot<BW>) -> Out {
    Out {
        slot: u.slot.val().to_u64(),
        last: u.last.val(),
        was_busy: u.was_busy.val(),
        bridge: u.bridge.val(),
        ax: u.ax.val().to_u64(),
        ay: u.ay.val().to_u64(),
        bank: u.bank.val().to_u64(),
        step: StepOut::of_w2(u, 0),
    }
}

/// A walk in flight.
struct Flight {
    /// W2's output for each slot, and the word written back.
    expect: Vec<(Out, u64)>,
    /// The next slot out.
    next: usize,
    /// W2 is done with each slot as soon as it holds it.
    full: bool,
    /// The clock `start` was given.
    started: usize,
}

/// Counts of what the run exercised.
#[derive(Debug, Default)]
struct Seen {
    walks: usize,
    full_speed: usize,
    restarts_in_walk: usize,
    stalls: usize,
    written_back: usize,
    back_to_back: usize,
}

fn case(m: usize, seed: u64, clocks: usize) -> Seen {
    let mut rng = common::rng(seed);
    let mut oracle = WalkStep::default();
    oracle.connect_all();
    let mut b = Bench::new(WalkPipeline::<BW>::new(m), |u| &mut u.clock);
    let mut slots: Vec<Slot> = (0..m).map(|_| random_slot(&mut rng)).collect();
    // The walk memory's words: what was written back, else zero.
    let mut memory = vec![0u64; m];
    let mut walk = random_walk(&mut rng);
    let mut flight: Option<Flight> = None;
    let mut seen = Seen::default();
    for clock in 0..clocks {
        let u = &mut b.uut;
        let idle = flight.is_none();
        let restart = !idle && rng.gen_bool(0.004);
        // Between walks: new slots, new inputs and constants.
        if idle && rng.gen_bool(0.3) {
            slots = (0..m).map(|_| random_slot(&mut rng)).collect();
            walk = random_walk(&mut rng);
        }
        let valid = u.w2.valid.val();
        let full = flight.as_ref().is_some_and(|f| f.full);
        let done = valid && (full || rng.gen_bool(0.5));
        let write_back = done && rng.gen_bool(0.8);
        // A walk starts between walks, or in the clock the last one's last
        // slot is done (as the tracker's next walk may).
        let ends = flight.as_ref().is_some_and(|f| done && f.next + 1 == m);
        let start = (idle || ends) && !restart && rng.gen_bool(0.4);
        u.restart.next = restart;
        u.start.next = start;
        u.done.next = done;
        u.write_back.next = write_back;
        u.end_of_plane.next = walk.kind == 0;
        u.finish.next = walk.kind == 1;
        u.drain.next = walk.kind == 2;
        u.t.next = walk.t.to_bits();
        u.t1_ge_n.next = walk.t1_ge_n;
        u.n.next = walk.n.to_bits();
        u.end_trim.next = walk.end_trim.to_bits();
        u.l_min.next = walk.l_min.to_bits();
        u.l_max.next = walk.l_max.to_bits();
        let flag = |f: fn(&Slot) -> bool| -> u64 {
            slots
                .iter()
                .enumerate()
                .map(|(i, s)| (f(s) as u64) << i)
                .sum()
        };
        u.busy.next = flag(|s| s.busy).to_bits();
        u.live.next = flag(|s| s.live).to_bits();
        u.dip.next = flag(|s| s.dip).to_bits();
        u.pend.next = flag(|s| s.pend).to_bits();
        u.opened.next = flag(|s| s.opened).to_bits();
        u.bridges.next = flag(|s| s.bridge).to_bits();
        for (i, s) in slots.iter().enumerate() {
            // The bits the walk does not read, at random.
            let rest = rng.gen::<u64>() >> (BANK + BW) << (BANK + BW);
            u.slot_geo[i].next = (rest | s.ax << AX | s.ay << AY | s.bank << BANK).to_bits();
        }
        settle(u);

        // What W2 gives.
        match &mut flight {
            None => assert!(!valid, "clock {clock}: W2 holds a slot outside a walk"),
            Some(Flight {
                expect,
                next,
                full,
                started,
            }) => {
                if valid {
                    assert!(*next < m, "clock {clock}: more than M slots");
                    assert_eq!(got(&u.w2), expect[*next].0, "clock {clock}: slot {next}");
                    assert_eq!(
                        u.w2.sel.val().to_u64(),
                        1 << *next,
                        "clock {clock}: one-hot"
                    );
                    if *full {
                        assert_eq!(clock, *started + 3 + *next, "clock {clock}: full speed");
                    }
                    if done {
                        if write_back {
                            memory[*next] = expect[*next].1;
                            seen.written_back += 1;
                        }
                        *next += 1;
                    } else {
                        seen.stalls += 1;
                    }
                } else if *full {
                    assert!(clock < *started + 3, "clock {clock}: full speed: a gap");
                }
            }
        }
        b.tick();
        if restart {
            seen.restarts_in_walk += 1;
            flight = None;
            continue;
        }
        if let Some(f) = flight.take_if(|f| f.next == m) {
            seen.walks += 1;
            seen.full_speed += f.full as usize;
        }
        if start {
            seen.back_to_back += (m == 1 && write_back) as usize;
            let expect = (0..m)
                .map(|k| expected(&mut oracle, k, m, &slots[k], memory[k], &walk))
                .collect();
            flight = Some(Flight {
                expect,
                next: 0,
                full: rng.gen_bool(0.3),
                started: clock,
            });
        }
    }
    seen
}

#[test]
fn walk_pipeline_walks_every_slot_in_order_with_its_step() {
    for (m, seed) in [(20, 71), (32, 72), (2, 73)] {
        let seen = case(m, seed, 30_000);
        assert!(
            seen.walks > 300
                && seen.full_speed > 100
                && seen.restarts_in_walk > 50
                && seen.stalls > 5_000
                && seen.written_back > 5_000,
            "{m} slots: {seen:?}"
        );
    }
}

#[test]
fn one_slot_walks_read_the_word_written_as_they_start() {
    let seen = case(1, 74, 30_000);
    assert!(
        seen.walks > 3_000 && seen.back_to_back > 1_000,
        "one slot: {seen:?}"
    );
}
