//! The blink tracker's per-slot blocks of the compare and decide stages,
//! each against its definition (the tracker as a whole is checked against
//! the model in `blink_tracker.rs`):
//! * the slot compare: random slots of 3 and of 32, at 4 and 16 pixels per
//!   word, candidates on and just off the edges of the association
//!   windows, words in and just outside the rows and columns of the 3×3
//!   windows, with and without above bits in their lanes: `near`, `hits`
//!   and `row_end` of every slot by definition, and all 0 when not
//!   enabled or for slots past M;
//! * the on/off step: every combination of one slot's flags, and random
//!   flag sets of 1, 5 and 32 slots: the slots bridged, starting a dip and
//!   ending, by the model's rule, disjoint, none when not enabled or past M;
//! * the read multiplexer: random slot states of 3 and of 32 slots read at
//!   every index (past M included), on and off: the slot's flags, anchor
//!   and bank and its one-hot, 0 past M or when off;
//! * the slots' flags: 20,000 clocks of random commands (decide, the on/off
//!   step, openings, the three walks, restarts; one-hot slots and, one in
//!   ten, any bits) to 1, 5 and 32 slots, every flag of every slot after
//!   every clock by the tracker's rules, slot by slot.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::{OnOffStep, SlotCompare, SlotFlags, SlotMux};
use smartagg_hdl::testbench::bench::{settle, Bench};

/// One slot as the compare stage sees it.
#[derive(Clone, Copy, Debug)]
struct Slot {
    /// Association window: x from, x to, y from, y to.
    bounds: [u64; 4],
    anchor_row: u64,
    low_col: u64,
    high_col: u64,
    low_lanes: u64,
    high_lanes: u64,
    end_row: u64,
}

/// The compare stage's item.
#[derive(Clone, Copy, Debug)]
struct Item {
    cx: u64,
    cy: u64,
    word_col: u64,
    row: u64,
    above: u64,
}

/// The three outputs of one slot, by definition.
fn compared(s: &Slot, it: &Item) -> (bool, bool, bool) {
    let [xlo, xhi, ylo, yhi] = s.bounds;
    let near = (xlo..=xhi).contains(&it.cx) && (ylo..=yhi).contains(&it.cy);
    let in_rows = it.row.saturating_sub(1) <= s.anchor_row && s.anchor_row <= it.row + 1;
    let hits = in_rows
        && ((it.word_col == s.low_col && it.above & s.low_lanes != 0)
            || (it.word_col == s.high_col && it.above & s.high_lanes != 0));
    (near, hits, s.end_row == it.row)
}

fn random_slot(rng: &mut impl Rng, p: usize) -> Slot {
    let all = u64::MAX >> (64 - p);
    let (ax, ay) = (rng.gen_range(0..320u64), rng.gen_range(0..240u64));
    let r = rng.gen_range(0..4u64);
    let low_col = ax.saturating_sub(1) / p as u64;
    let high_col = (ax + 1) / p as u64;
    Slot {
        bounds: [ax.saturating_sub(r), ax + r, ay.saturating_sub(r), ay + r],
        anchor_row: ay,
        low_col,
        high_col,
        low_lanes: rng.gen::<u64>() & all,
        high_lanes: if high_col == low_col {
            0
        } else {
            rng.gen::<u64>() & all
        },
        end_row: (ay + 1).min(239),
    }
}

/// An item aimed at `s`: the candidate on or one off an edge of its
/// window, the word in or one outside its rows and columns, sparse above
/// bits.
fn item_near(rng: &mut impl Rng, s: &Slot, p: usize) -> Item {
    let [xlo, xhi, ylo, yhi] = s.bounds;
    let edge = |rng: &mut dyn rand::RngCore, lo: u64, hi: u64| -> u64 {
        let v = [lo.wrapping_sub(1), lo, (lo + hi) / 2, hi, hi + 1][rng.gen_range(0..5)];
        v.min(511)
    };
    let row = (s.anchor_row + rng.gen_range(0..5u64)).saturating_sub(2);
    let word_col = [
        s.low_col,
        s.high_col,
        s.low_col.wrapping_sub(1),
        s.high_col + 1,
    ][rng.gen_range(0..4)]
    .min(1023);
    let above = (0..p).fold(0, |a, j| a | (rng.gen_bool(0.5) as u64) << j);
    Item {
        cx: edge(rng, xlo, xhi),
        cy: edge(rng, ylo, yhi),
        word_col,
        row,
        above,
    }
}

fn slot_compare_case<const P: usize>(m: usize, seed: u64) {
    let mut u = SlotCompare::<P>::new(m);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mut rng = common::rng(seed);
    let mut seen = [[0usize; 2]; 3];
    for round in 0..3000 {
        let slots: Vec<Slot> = (0..m).map(|_| random_slot(&mut rng, P)).collect();
        for (i, s) in slots.iter().enumerate() {
            let b = s.bounds;
            u.bounds[i].next = (b[0] | b[1] << 10 | b[2] << 20 | b[3] << 30).to_bits();
            u.anchor_rows[i].next = s.anchor_row.to_bits();
            u.low_cols[i].next = s.low_col.to_bits();
            u.high_cols[i].next = s.high_col.to_bits();
            u.low_lanes[i].next = s.low_lanes.to_bits();
            u.high_lanes[i].next = s.high_lanes.to_bits();
            u.end_rows[i].next = s.end_row.to_bits();
        }
        let aim = rng.gen_range(0..m);
        let it = item_near(&mut rng, &slots[aim], P);
        u.cx.next = it.cx.to_bits();
        u.cy.next = it.cy.to_bits();
        u.word_col.next = it.word_col.to_bits();
        u.row.next = it.row.to_bits();
        u.row_m1.next = it.row.saturating_sub(1).to_bits();
        u.row_p1.next = (it.row + 1).to_bits();
        u.above.next = it.above.to_bits();
        let enable = round % 5 != 0;
        u.enable.next = enable;
        settle(&mut u);
        let (near, hits, row_end) = (
            u.near.val().to_u64(),
            u.hits.val().to_u64(),
            u.row_end.val().to_u64(),
        );
        for (i, s) in slots.iter().enumerate() {
            let want = compared(s, &it);
            let got = (
                near >> i & 1 == 1,
                hits >> i & 1 == 1,
                row_end >> i & 1 == 1,
            );
            if !enable {
                assert_eq!(got, (false, false, false), "slot {i} not enabled");
                continue;
            }
            assert_eq!(got, want, "m {m}, P {P}, slot {i} {s:?}, item {it:?}");
            for (k, w) in [want.0, want.1, want.2].into_iter().enumerate() {
                seen[k][w as usize] += 1;
            }
        }
        assert_eq!(
            near | hits | row_end,
            (near | hits | row_end) & (u64::MAX >> (64 - m))
        );
    }
    // Both answers of each comparison, many times.
    for (k, s) in seen.iter().enumerate() {
        assert!(s[0] >= 300 && s[1] >= 300, "output {k}: {s:?}");
    }
}

#[test]
fn slot_compare_is_the_windows_of_every_slot() {
    slot_compare_case::<4>(3, 31);
    slot_compare_case::<16>(3, 32);
    slot_compare_case::<4>(32, 33);
    slot_compare_case::<16>(32, 34);
}

/// Slot `i`'s on/off step by the model's rule: `(bridge, dip_starts, ends)`.
fn stepped(flags: &[u64; 6], i: usize) -> (bool, bool, bool) {
    let [active_before, busy, live, row_end, on, dip] = flags.map(|f| f >> i & 1 == 1);
    if !(active_before && busy && live && row_end) {
        return (false, false, false);
    }
    match (on, dip) {
        (true, dip) => (dip, false, false),
        (false, false) => (false, true, false),
        (false, true) => (false, false, true),
    }
}

fn on_off_check(u: &mut OnOffStep, m: usize, flags: [u64; 6], enable: bool) -> [u64; 3] {
    let [active_before, busy, live, row_end, on, dip] = flags;
    u.enable.next = enable;
    u.active_before.next = active_before.to_bits();
    u.busy.next = busy.to_bits();
    u.live.next = live.to_bits();
    u.row_end.next = row_end.to_bits();
    u.on.next = on.to_bits();
    u.dip.next = dip.to_bits();
    settle(u);
    let got = [
        u.bridge.val().to_u64(),
        u.dip_starts.val().to_u64(),
        u.ends.val().to_u64(),
    ];
    for i in 0..32 {
        let want = if enable && i < m {
            stepped(&flags, i)
        } else {
            (false, false, false)
        };
        let bit = |v: u64| v >> i & 1 == 1;
        assert_eq!(
            (bit(got[0]), bit(got[1]), bit(got[2])),
            want,
            "m {m}, slot {i}, flags {flags:x?}, enable {enable}"
        );
    }
    assert_eq!(got[0] & got[1] | got[0] & got[2] | got[1] & got[2], 0);
    got
}

#[test]
fn on_off_step_bridges_dips_and_ends_blinks_by_the_models_rule() {
    // One slot: every combination of its six flags, enabled or not.
    let mut u = OnOffStep::new(1);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mut outcomes = std::collections::BTreeSet::new();
    for combo in 0..128u64 {
        let flags: [u64; 6] = std::array::from_fn(|k| combo >> k & 1);
        let got = on_off_check(&mut u, 1, flags, combo >> 6 == 1);
        outcomes.insert(got);
    }
    // Nothing, a bridge, a dip that starts, an end.
    assert_eq!(outcomes.len(), 4, "{outcomes:?}");
    // Many slots: random flag sets, dense enough that all four cases occur
    // in one clock.
    let mut rng = common::rng(35);
    for m in [1, 5, 32] {
        let mut u = OnOffStep::new(m);
        u.connect_all();
        let mut counts = [0u32; 3];
        for round in 0..2000 {
            let flags: [u64; 6] = std::array::from_fn(|k| {
                let p = if k < 4 { 0.8 } else { 0.5 };
                (0..32).fold(0, |f, j| f | (rng.gen_bool(p) as u64) << j)
            });
            let got = on_off_check(&mut u, m, flags, round % 4 != 0);
            for k in 0..3 {
                counts[k] += got[k].count_ones();
            }
        }
        assert!(counts.iter().all(|&c| c >= 100), "m {m}: {counts:?}");
    }
}

fn slot_mux_case(m: usize, seed: u64) {
    const BW: usize = 7;
    let mut u = SlotMux::<BW>::new(m);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mut rng = common::rng(seed);
    let mut read = std::collections::BTreeSet::new();
    for _ in 0..400 {
        let flags: [u64; 6] = std::array::from_fn(|_| rng.gen::<u32>() as u64);
        let anchors: Vec<(u64, u64, u64)> = (0..m)
            .map(|_| {
                let ax = rng.gen_range(0..1024u64);
                (ax, rng.gen_range(0..1024u64), rng.gen_range(0..1u64 << BW))
            })
            .collect();
        u.busy.next = flags[0].to_bits();
        u.live.next = flags[1].to_bits();
        u.dip.next = flags[2].to_bits();
        u.pend.next = flags[3].to_bits();
        u.opened.next = flags[4].to_bits();
        u.bridges.next = flags[5].to_bits();
        for (i, &(ax, ay, bank)) in anchors.iter().enumerate() {
            u.anchor_cols[i].next = ax.to_bits();
            u.anchor_rows[i].next = ay.to_bits();
            u.banks[i].next = bank.to_bits();
        }
        for slot in 0..(m as u64 + 8) {
            let enable = rng.gen_bool(0.8);
            u.slot.next = slot.to_bits();
            u.enable.next = enable;
            settle(&mut u);
            let got = (
                u.selected.val().to_u64(),
                [
                    u.s_busy.val(),
                    u.s_live.val(),
                    u.s_dip.val(),
                    u.s_pend.val(),
                    u.s_opened.val(),
                    u.s_bridge.val(),
                ],
                (
                    u.s_ax.val().to_u64(),
                    u.s_ay.val().to_u64(),
                    u.s_bank.val().to_u64(),
                ),
            );
            let i = slot as usize;
            let want = if enable && i < m {
                read.insert(i);
                (1 << i, flags.map(|f| f >> i & 1 == 1), anchors[i])
            } else {
                (0, [false; 6], (0, 0, 0))
            };
            assert_eq!(got, want, "m {m}, slot {slot}, enable {enable}");
        }
    }
    assert_eq!(read.len(), m);
}

#[test]
fn slot_mux_reads_the_walked_slot() {
    slot_mux_case(3, 36);
    slot_mux_case(32, 37);
}

/// One slot's flags, as the tracker's rules define them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Flags {
    busy: bool,
    live: bool,
    dip: bool,
    pend: bool,
    opened: bool,
    bridge: bool,
    active_before: bool,
    free_before: bool,
    hit: bool,
}

/// One clock's commands to the flags.
#[derive(Clone, Copy, Debug, Default)]
struct FlagCommands {
    restart: bool,
    decide: bool,
    hits: u64,
    step: bool,
    row_end: u64,
    open: bool,
    open_slot: u64,
    walk_slot: u64,
    /// 0 none, 1 the end of a plane, 2 finish, 3 emit.
    walk: u8,
    was_busy: bool,
    next_busy: bool,
    next_live: bool,
    cut: bool,
    ends: bool,
    unconfirmed: bool,
}

/// Slot `i`'s flags after a clock of `c` (slots past `m` are written only
/// by the restart). The rules of the tracker's doc, slot by slot: the
/// walk, the opening, the on/off step of the decided row, the restart.
fn flags_after(f: &Flags, c: &FlagCommands, i: usize, m: usize) -> Flags {
    let bit = |v: u64| v >> i & 1 == 1;
    let mut n = *f;
    // The on/off step reads the flags before the clock and the plane's hits
    // with the decided word's.
    let on = f.hit || bit(c.hits);
    if c.decide {
        n.hit = on;
    }
    if i < m && bit(c.walk_slot) {
        match c.walk {
            1 => {
                n.busy = c.next_busy;
                n.live = c.next_live;
                n.pend = false;
                n.bridge = false;
                if c.cut {
                    n.dip = false;
                }
                n.active_before = c.next_busy && c.next_live;
                n.free_before = !c.next_busy;
                n.opened = false;
                n.hit = false;
            }
            2 => {
                n.opened = false;
                if c.ends {
                    n.live = false;
                    n.dip = false;
                    if c.unconfirmed {
                        n.busy = false;
                    }
                }
            }
            3 if c.was_busy => n.busy = false,
            _ => {}
        }
    }
    if i < m && c.open && bit(c.open_slot) {
        n.busy = true;
        n.live = true;
        n.dip = false;
        n.opened = true;
    }
    if i < m && c.step && f.active_before && f.busy && f.live && bit(c.row_end) {
        match (on, f.dip) {
            (true, true) => {
                n.dip = false;
                n.bridge = true;
            }
            (false, false) => n.dip = true,
            (false, true) => {
                n.dip = false;
                n.live = false;
                n.pend = true;
            }
            (true, false) => {}
        }
    }
    if c.restart {
        n = Flags {
            dip: n.dip,
            free_before: i < m,
            ..Flags::default()
        };
    }
    n
}

fn flags_case(m: usize, seed: u64) {
    let mut b = Bench::new(SlotFlags::new(m), |u| &mut u.clock);
    let mut rng = common::rng(seed);
    let mut want = [Flags::default(); 32];
    // Events seen: bridges, dips started, ends, openings, walks of each kind.
    let mut seen = [0u32; 7];
    for clock in 0..20_000 {
        let c = FlagCommands {
            restart: clock == 0 || rng.gen_bool(0.003),
            decide: rng.gen_bool(0.6),
            hits: rng.gen::<u32>() as u64 & rng.gen::<u32>() as u64,
            step: rng.gen_bool(0.4),
            row_end: rng.gen::<u32>() as u64 | rng.gen::<u32>() as u64,
            open: rng.gen_bool(0.3),
            open_slot: common::slot_bits(&mut rng, m),
            walk_slot: common::slot_bits(&mut rng, m),
            walk: rng.gen_range(0..4),
            was_busy: rng.gen_bool(0.7),
            next_busy: rng.gen_bool(0.6),
            next_live: rng.gen_bool(0.6),
            cut: rng.gen_bool(0.3),
            ends: rng.gen_bool(0.5),
            unconfirmed: rng.gen_bool(0.5),
        };
        let u = &mut b.uut;
        u.restart.next = c.restart;
        u.decide.next = c.decide;
        u.hits.next = c.hits.to_bits();
        u.step.next = c.step;
        u.row_end.next = c.row_end.to_bits();
        u.open.next = c.open;
        u.open_slot.next = c.open_slot.to_bits();
        u.walk_slot.next = c.walk_slot.to_bits();
        u.end_of_plane.next = c.walk == 1;
        u.finish.next = c.walk == 2;
        u.emit.next = c.walk == 3;
        u.was_busy.next = c.was_busy;
        u.next_busy.next = c.next_busy;
        u.next_live.next = c.next_live;
        u.cut.next = c.cut;
        u.ends.next = c.ends;
        u.unconfirmed.next = c.unconfirmed;
        b.tick();
        for (i, w) in want.iter_mut().enumerate() {
            let n = flags_after(w, &c, i, m);
            if i < m && !c.restart {
                seen[0] += (n.bridge && !w.bridge) as u32;
                seen[1] += (n.dip && !w.dip) as u32;
                seen[2] += (n.pend && !w.pend) as u32;
                seen[3] += (n.opened && !w.opened) as u32;
                if c.walk != 0 && bit_of(c.walk_slot, i) {
                    seen[3 + c.walk as usize] += 1;
                }
            }
            *w = n;
        }
        let u = &mut b.uut;
        let outputs = [
            (u.busy.val().to_u64(), "busy"),
            (u.live.val().to_u64(), "live"),
            (u.dip.val().to_u64(), "dip"),
            (u.pend.val().to_u64(), "pend"),
            (u.opened.val().to_u64(), "opened"),
            (u.bridges.val().to_u64(), "bridges"),
            (u.active_before.val().to_u64(), "active_before"),
            (u.free_before.val().to_u64(), "free_before"),
        ];
        for (i, w) in want.iter().enumerate() {
            let wanted = [
                w.busy,
                w.live,
                w.dip,
                w.pend,
                w.opened,
                w.bridge,
                w.active_before,
                w.free_before,
            ];
            for ((got, name), wanted) in outputs.iter().zip(wanted) {
                assert_eq!(
                    bit_of(*got, i),
                    wanted,
                    "m {m}, clock {clock}, slot {i}: {name}, after {c:?}"
                );
            }
        }
    }
    assert!(seen.iter().all(|&s| s >= 20), "m {m}: {seen:?}");
}

fn bit_of(v: u64, i: usize) -> bool {
    v >> i & 1 == 1
}

#[test]
fn slot_flags_follow_the_walks_openings_and_on_off_steps() {
    flags_case(1, 41);
    flags_case(5, 42);
    flags_case(32, 43);
}
