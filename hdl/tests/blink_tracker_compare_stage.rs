//! The blink tracker's compare stage against its rules (the tracker as a
//! whole is checked against the model in `blink_tracker.rs`; the slot
//! compare and the opening windows against their definitions in
//! `blink_tracker_slots.rs` and `blink_tracker_blocks.rs`, and here serve
//! as oracles, evaluated apart): 40,000 clocks of random items, slot words,
//! Run, openings and restarts. Every clock:
//! * the flow: the decide stage takes the stage's item in Run unless it is
//!   replayed; the stage takes the item stage's item when it is empty or
//!   its item is decided, but not in the clock that decides an item ending
//!   the field's last row;
//! * the comparisons of the item (or, when replayed, of the candidate held)
//!   with every slot, computed only when the stage takes an item or
//!   replays;
//! * a candidate taken in the clock of an opening is replayed once: its
//!   association windows compared again, the rest of the item held;
//! * everything the stage holds, as it was taken.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
// The slot word's layout, which the stage slices with literals (`hdl_gen`
// takes no path constant): the test ties the two.
use smartagg_hdl::blink_tracker::slot_word::{AX, AY, FROW, WH, WL};
use smartagg_hdl::blink_tracker::{CompareStage, OpeningWindows, SlotCompare};
use smartagg_hdl::config::BackHalfConfig;
use smartagg_hdl::pipeline::{spcimager150_back_config, test_back_config};
use smartagg_hdl::testbench::bench::{settle, Bench};

/// The item stage's item, as the compare stage takes it.
#[derive(Clone, Copy, Debug, Default)]
struct Item {
    valid: bool,
    cand: bool,
    last: bool,
    eor: bool,
    lastrow: bool,
    cx: u64,
    cy: u64,
    word_col: u64,
    above: u64,
}

/// What the stage holds: the item and its comparisons, and what an opening
/// writes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Held {
    valid: bool,
    cand: bool,
    last: bool,
    eor: bool,
    lastrow: bool,
    cx: u64,
    cy: u64,
    near: u64,
    hits: u64,
    row_end: u64,
    open: [u64; 4],
}

/// A slot's `geo`, `win` and `bnd` words, at random near (`cx`, `cy`) of a
/// small corner of the field, so that every comparison goes both ways.
fn random_slot(rng: &mut impl Rng, p: usize) -> [u64; 3] {
    let c = |rng: &mut dyn rand::RngCore| rng.gen_range(0..12u64);
    let lanes = |rng: &mut dyn rand::RngCore| rng.gen_range(0..1u64 << p);
    let (x0, y0) = (c(rng), c(rng));
    let bnd = x0 | (x0 + c(rng)) << 10 | y0 << 20 | (y0 + c(rng)) << 30;
    let (wl, wh) = (rng.gen_range(0..3u64), rng.gen_range(0..3u64));
    let geo = c(rng) << AX | c(rng) << AY | wl << WL | wh << WH | c(rng) << FROW;
    let win = lanes(rng) | lanes(rng) << 32;
    [geo, win, bnd]
}

fn case<const P: usize>(cfg: &BackHalfConfig, seed: u64) {
    let m = cfg.slots;
    let mut b = Bench::new(CompareStage::<P>::new(cfg), |u| &mut u.clock);
    let mut slots = SlotCompare::<P>::new(m);
    slots.connect_all();
    let mut opening = OpeningWindows::<P>::new(cfg);
    opening.connect_all();
    let mut rng = common::rng(seed);
    let last_row = cfg.front.height as u64 - 1;
    let mut held = Held::default();
    let mut replay = false;
    // Seen: takes; decided items; replays; replays whose comparisons
    // differ from the first ones; last items of the field (the stage
    // takes nothing); items held by a stage outside Run; restarts with a
    // replay pending; comparisons with a slot near; hit; ending its row.
    let mut seen = [0u32; 10];
    let mut words: Vec<[u64; 3]> = (0..m).map(|_| random_slot(&mut rng, P)).collect();
    for clock in 0..40_000 {
        // (As an opening writes its slot.)
        if rng.gen_bool(0.5) {
            let k = rng.gen_range(0..m);
            words[k] = random_slot(&mut rng, P);
        }
        let cy = rng.gen_range(0..14u64).min(last_row);
        let it = Item {
            valid: rng.gen_bool(0.7),
            cand: rng.gen_bool(0.5),
            last: rng.gen_bool(0.5),
            eor: rng.gen_bool(0.4),
            lastrow: rng.gen_bool(0.3),
            cx: rng.gen_range(0..14),
            cy,
            word_col: rng.gen_range(0..3),
            above: rng.gen_range(0..1u64 << P),
        };
        let run = rng.gen_bool(0.8);
        let open = rng.gen_bool(0.3);
        let restart = rng.gen_bool(0.01);

        let u = &mut b.uut;
        u.restart.next = restart;
        u.run.next = run;
        u.open.next = open;
        u.item_valid.next = it.valid;
        u.item_cand.next = it.cand;
        u.item_last.next = it.last;
        u.item_eor.next = it.eor;
        u.item_lastrow.next = it.lastrow;
        u.item_cx.next = it.cx.to_bits();
        u.item_cy.next = it.cy.to_bits();
        u.item_word_col.next = it.word_col.to_bits();
        u.item_row_m1.next = it.cy.saturating_sub(1).to_bits();
        u.item_row_p1.next = (it.cy + 1).to_bits();
        u.item_above.next = it.above.to_bits();
        for (k, w) in words.iter().enumerate() {
            u.slot_geo[k].next = w[0].to_bits();
            u.slot_win[k].next = w[1].to_bits();
            u.slot_bnd[k].next = w[2].to_bits();
        }
        settle(u);

        // The rules.
        let go = run && held.valid && !replay;
        let step = go && held.last && held.eor;
        let end_item = step && held.lastrow;
        let take = !replay && (!held.valid || run) && !end_item;
        let (cx, cy) = if replay {
            (held.cx, held.cy)
        } else {
            (it.cx, it.cy)
        };
        let enable = replay || take && it.valid;
        for (k, w) in words.iter().enumerate() {
            slots.bounds[k].next = (w[2] & ((1 << 40) - 1)).to_bits();
            slots.anchor_rows[k].next = (w[0] >> AY & 1023).to_bits();
            slots.low_cols[k].next = (w[0] >> WL & 1023).to_bits();
            slots.high_cols[k].next = (w[0] >> WH & 1023).to_bits();
            slots.end_rows[k].next = (w[0] >> FROW & 1023).to_bits();
            slots.low_lanes[k].next = (w[1] & ((1 << P) - 1)).to_bits();
            slots.high_lanes[k].next = (w[1] >> 32 & ((1 << P) - 1)).to_bits();
        }
        slots.cx.next = cx.to_bits();
        slots.cy.next = cy.to_bits();
        slots.word_col.next = it.word_col.to_bits();
        slots.row.next = it.cy.to_bits();
        slots.row_m1.next = it.cy.saturating_sub(1).to_bits();
        slots.row_p1.next = (it.cy + 1).to_bits();
        slots.above.next = it.above.to_bits();
        slots.enable.next = enable;
        settle(&mut slots);
        opening.cx.next = it.cx.to_bits();
        opening.cy.next = it.cy.to_bits();
        opening.lastrow.next = it.lastrow;
        settle(&mut opening);
        let compared = [
            slots.near.val().to_u64(),
            slots.hits.val().to_u64(),
            slots.row_end.val().to_u64(),
        ];

        let at = format!("clock {clock}");
        assert_eq!(u.go.val(), go, "{at}: go");
        assert_eq!(u.candidate.val(), go && held.cand, "{at}: candidate");
        assert_eq!(u.step.val(), step, "{at}: step");
        assert_eq!(u.take.val(), take, "{at}: take");
        let out = Held {
            valid: held.valid,
            cand: held.cand,
            last: held.last,
            eor: held.eor,
            lastrow: u.lastrow.val(),
            cx: u.cx.val().to_u64(),
            cy: u.cy.val().to_u64(),
            near: u.near.val().to_u64(),
            hits: u.hits.val().to_u64(),
            row_end: u.row_end.val().to_u64(),
            open: [
                u.open_geo.val().to_u64(),
                u.open_win.val().to_u64(),
                u.open_view.val().to_u64(),
                u.open_bnd.val().to_u64(),
            ],
        };
        assert_eq!(out, held, "{at}: held");

        seen[0] += take as u32;
        seen[1] += go as u32;
        seen[2] += replay as u32;
        seen[3] += (replay && compared[0] != held.near) as u32;
        seen[4] += end_item as u32;
        seen[5] += (!run && held.valid && !replay) as u32;
        seen[6] += (restart && (replay || open && it.valid && it.cand && take)) as u32;
        for (k, c) in compared.iter().enumerate() {
            seen[7 + k] += (enable && *c != 0) as u32;
        }

        // The next clock's state.
        let mut next = held;
        if replay {
            next.near = compared[0];
        }
        if end_item {
            next.valid = false;
        }
        if take {
            next = Held {
                valid: it.valid,
                cand: it.cand,
                last: it.last,
                eor: it.eor,
                lastrow: it.lastrow,
                cx: it.cx,
                cy: it.cy,
                near: compared[0],
                hits: compared[1],
                row_end: compared[2],
                open: [
                    opening.geo.val().to_u64(),
                    opening.win.val().to_u64(),
                    opening.sh.val().to_u64(),
                    opening.bnd.val().to_u64(),
                ],
            };
        }
        replay = open && it.valid && it.cand && take;
        if restart {
            next.valid = false;
            replay = false;
        }
        held = next;
        b.tick();
    }
    assert!(seen[..6].iter().all(|&n| n >= 200), "coverage {seen:?}");
    assert!(seen[6] >= 5, "coverage {seen:?}");
    assert!(seen[7..].iter().all(|&n| n >= 1000), "coverage {seen:?}");
}

#[test]
fn compare_stage_takes_compares_replays_and_holds_by_its_rules() {
    case::<4>(&test_back_config(4, 3, 1).unwrap(), 61);
    case::<16>(&spcimager150_back_config().unwrap(), 62);
}
