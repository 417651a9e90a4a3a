//! The blink tracker's register blocks that are not flags, each against its
//! rules (the tracker as a whole is checked against the model in
//! `blink_tracker.rs`):
//! * the slots' words: 20,000 clocks of random commands (the four walks,
//!   openings, restarts; one-hot slots and, one in ten, any bits; any
//!   field values) to 1, 5 and 32 slots with 4-, 16- and 32-bit lane masks
//!   and 6- and 14-bit banks, every word of every slot and every ROI view
//!   entry after every clock by the rules of the block's doc, slot by slot;
//! * the counters: 50,000 clocks of random events (Blink records,
//!   unconfirmed ends, bridges, cuts, drops with their positions, ends of
//!   planes, runs of bank waits up to 40 clocks, restarts), every output
//!   after every clock.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::{shadow, slot_word, SlotWords, TrackerCounters};
use smartagg_hdl::testbench::bench::Bench;

fn ones(n: usize) -> u64 {
    if n >= 64 {
        u64::MAX
    } else {
        (1 << n) - 1
    }
}

/// One clock's commands to the words.
#[derive(Clone, Copy, Debug, Default)]
struct WordCommands {
    restart: bool,
    parity: bool,
    walk_slot: u64,
    /// 0 none, 1 the end of a plane, 2 the end of a drain plane, 3 finish,
    /// 4 emit.
    walk: u8,
    was_busy: bool,
    next_bank: u64,
    walk_ax: u64,
    walk_ay: u64,
    next_pre: bool,
    next_fresh: bool,
    unconfirmed: bool,
    open: bool,
    open_slot: u64,
    open_geo: u64,
    open_win: u64,
    open_bnd: u64,
    open_view: u64,
    open_pre: bool,
}

/// The words of `m` slots: `geo`, `win`, `bnd` per slot, the ROI view.
#[derive(Clone, Debug)]
struct Words {
    geo: Vec<u64>,
    win: Vec<u64>,
    bnd: Vec<u64>,
    view: Vec<u64>,
}

/// The words after a clock of `c`, by the rules of the block's doc: every
/// word held through its bits in use, then the walk, the opening, the
/// restart, slot by slot.
fn words_after(w: &Words, c: &WordCommands, m: usize, p: usize, bw: usize) -> Words {
    let bank_mask = ones(bw) << slot_word::BANK;
    let geo_used = !((ones(slot_word::BANK_BITS_MAX) << slot_word::BANK) & !bank_mask);
    let win_used = ones(p) | ones(p) << 32;
    let view_used = ones(shadow::BANK + bw) | 1 << shadow::PRE | 1 << shadow::FRESH;
    let flags = 1 << shadow::PRE | 1 << shadow::FRESH;
    let mut n = Words {
        geo: w.geo.iter().map(|g| g & geo_used).collect(),
        win: w.win.iter().map(|g| g & win_used).collect(),
        bnd: w.bnd.clone(),
        view: w.view.iter().map(|g| g & view_used).collect(),
    };
    // The entries of planes t (this parity) and t + 1.
    let (this, next) = if c.parity { (m, 0) } else { (0, m) };
    for i in 0..m {
        if c.walk_slot >> i & 1 == 1 {
            let bank = c.next_bank << slot_word::BANK;
            if c.walk == 1 || c.walk == 4 && c.was_busy {
                n.geo[i] = w.geo[i] & geo_used & !bank_mask | bank;
            }
            if c.walk == 3 {
                let keep = if c.unconfirmed { !flags } else { u64::MAX };
                n.view[this + i] = w.view[this + i] & view_used & keep;
            }
            if c.walk == 1 || c.walk == 2 {
                n.view[next + i] = c.walk_ax << shadow::AX
                    | c.walk_ay << shadow::AY
                    | bank
                    | (c.next_pre as u64) << shadow::PRE
                    | ((c.next_fresh && c.walk == 1) as u64) << shadow::FRESH;
            }
        }
    }
    for i in 0..m {
        if c.open && c.open_slot >> i & 1 == 1 {
            n.geo[i] = w.geo[i] & bank_mask | c.open_geo;
            n.win[i] = c.open_win;
            n.bnd[i] = c.open_bnd;
            n.view[this + i] =
                w.geo[i] & bank_mask | c.open_view | (c.open_pre as u64) << shadow::PRE;
        }
    }
    if c.restart {
        for i in 0..m {
            n.geo[i] = (i as u64) << slot_word::BANK;
        }
        n.view.iter_mut().for_each(|v| *v = 0);
    }
    n
}

fn words_case<const BW: usize>(m: usize, p: usize, seed: u64) {
    let mut b = Bench::new(SlotWords::<BW>::new(m, p), |u| &mut u.clock);
    let mut rng = common::rng(seed);
    let mut want = Words {
        geo: vec![0; m],
        win: vec![0; m],
        bnd: vec![0; m],
        view: vec![0; 2 * m],
    };
    // Writes seen: banks, views of t + 1, `finish` clearing a view, openings.
    let mut seen = [0u32; 4];
    for clock in 0..20_000 {
        let c = WordCommands {
            restart: clock == 0 || rng.gen_bool(0.003),
            parity: rng.gen(),
            walk_slot: common::slot_bits(&mut rng, m),
            walk: rng.gen_range(0..5),
            was_busy: rng.gen_bool(0.7),
            next_bank: rng.gen::<u64>() & ones(BW),
            walk_ax: rng.gen::<u64>() & ones(10),
            walk_ay: rng.gen::<u64>() & ones(10),
            next_pre: rng.gen(),
            next_fresh: rng.gen(),
            unconfirmed: rng.gen(),
            open: rng.gen_bool(0.3),
            open_slot: common::slot_bits(&mut rng, m),
            open_geo: rng.gen(),
            open_win: rng.gen(),
            open_bnd: rng.gen(),
            open_view: rng.gen(),
            open_pre: rng.gen(),
        };
        let u = &mut b.uut;
        u.restart.next = c.restart;
        u.parity.next = c.parity;
        u.walk_slot.next = c.walk_slot.to_bits();
        u.end_of_plane.next = c.walk == 1;
        u.drain.next = c.walk == 2;
        u.finish.next = c.walk == 3;
        u.emit.next = c.walk == 4;
        u.was_busy.next = c.was_busy;
        u.next_bank.next = c.next_bank.to_bits();
        u.walk_ax.next = c.walk_ax.to_bits();
        u.walk_ay.next = c.walk_ay.to_bits();
        u.next_pre.next = c.next_pre;
        u.next_fresh.next = c.next_fresh;
        u.unconfirmed.next = c.unconfirmed;
        u.open.next = c.open;
        u.open_slot.next = c.open_slot.to_bits();
        u.open_geo.next = c.open_geo.to_bits();
        u.open_win.next = c.open_win.to_bits();
        u.open_bnd.next = c.open_bnd.to_bits();
        u.open_view.next = c.open_view.to_bits();
        u.open_pre.next = c.open_pre;
        b.tick();
        let n = words_after(&want, &c, m, p, BW);
        if !c.restart && c.walk_slot & ones(m) != 0 {
            seen[0] += (c.walk == 1 || c.walk == 4 && c.was_busy) as u32;
            seen[1] += (c.walk == 1 || c.walk == 2) as u32;
            seen[2] += (c.walk == 3 && c.unconfirmed && n.view != want.view) as u32;
        }
        seen[3] += (!c.restart && c.open && c.open_slot & ones(m) != 0) as u32;
        want = n;
        let u = &b.uut;
        for i in 0..m {
            for (got, wanted, name) in [
                (&u.geo[i], want.geo[i], "geo"),
                (&u.win[i], want.win[i], "win"),
                (&u.bnd[i], want.bnd[i], "bnd"),
            ] {
                assert_eq!(
                    got.val().to_u64(),
                    wanted,
                    "m {m}, clock {clock}, slot {i}: {name}, after {c:?}"
                );
            }
        }
        for (q, wanted) in want.view.iter().enumerate() {
            assert_eq!(
                u.sh[q].val().to_u64(),
                *wanted,
                "m {m}, clock {clock}, view entry {q}, after {c:?}"
            );
        }
    }
    assert!(seen.iter().all(|&s| s >= 20), "m {m}: {seen:?}");
}

#[test]
fn slot_words_follow_the_walks_openings_and_restarts() {
    words_case::<6>(1, 4, 51);
    words_case::<6>(5, 16, 52);
    words_case::<14>(32, 32, 53);
}

/// The counters' outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Counts {
    blinks: u64,
    unconfirmed: u64,
    dropped: u64,
    bridged: u64,
    cuts: u64,
    plane_drops: u64,
    first: (u64, u64),
    bank_error: bool,
    /// The run of waits, modulo 16 (inside).
    waits: u64,
}

#[test]
fn tracker_counters_count_events_drops_and_a_lost_bank() {
    let mut b = Bench::new(TrackerCounters::default(), |u| &mut u.clock);
    let mut rng = common::rng(61);
    let mut want = Counts::default();
    let mut burst = 0u32;
    // Seen: Dropped records with a count, bank errors raised, restarts
    // that clear one.
    let mut seen = [0u32; 3];
    for clock in 0..50_000 {
        if burst == 0 && rng.gen_bool(0.02) {
            burst = rng.gen_range(1..=40);
        }
        let bank_wait = burst > 0;
        burst = burst.saturating_sub(1);
        let restart = clock == 0 || rng.gen_bool(0.001);
        let blink = rng.gen_bool(0.3);
        let unconfirmed_end = rng.gen_bool(0.2);
        let bridge = rng.gen_bool(0.2);
        let cut = rng.gen_bool(0.1);
        let drop = rng.gen_bool(0.3);
        let (x, y) = (rng.gen::<u64>() & 1023, rng.gen::<u64>() & 1023);
        let plane_end = rng.gen_bool(0.05);
        let u = &mut b.uut;
        u.restart.next = restart;
        u.blink.next = blink;
        u.unconfirmed_end.next = unconfirmed_end;
        u.bridge.next = bridge;
        u.cut.next = cut;
        u.drop.next = drop;
        u.drop_x.next = x.to_bits();
        u.drop_y.next = y.to_bits();
        u.plane_end.next = plane_end;
        u.bank_wait.next = bank_wait;
        b.tick();
        let w = want;
        want.blinks += blink as u64;
        want.unconfirmed += unconfirmed_end as u64;
        want.bridged += bridge as u64;
        want.cuts += cut as u64;
        if plane_end {
            seen[0] += (w.plane_drops != 0) as u32;
            want.plane_drops = 0;
        }
        if drop {
            want.dropped += 1;
            want.plane_drops = w.plane_drops + 1;
            if w.plane_drops == 0 {
                want.first = (x, y);
            }
        }
        want.waits = if bank_wait { (w.waits + 1) % 16 } else { 0 };
        if bank_wait && w.waits == 15 {
            seen[1] += !w.bank_error as u32;
            want.bank_error = true;
        }
        if restart {
            seen[2] += w.bank_error as u32;
            want = Counts {
                first: want.first,
                waits: want.waits,
                ..Counts::default()
            };
        }
        let u = &b.uut;
        let got = Counts {
            blinks: u.totals.blinks.val().to_u64(),
            unconfirmed: u.totals.unconfirmed.val().to_u64(),
            dropped: u.totals.dropped.val().to_u64(),
            bridged: u.totals.bridged.val().to_u64(),
            cuts: u.totals.cuts.val().to_u64(),
            plane_drops: u.plane_drops.val().to_u64(),
            first: (u.first_x.val().to_u64(), u.first_y.val().to_u64()),
            bank_error: u.bank_error.val(),
            waits: want.waits,
        };
        assert_eq!(got, want, "clock {clock}");
    }
    assert!(seen[0] >= 1000 && seen[1] >= 10 && seen[2] >= 5, "{seen:?}");
}
