//! The blink tracker's sub-blocks, each against its definition (the
//! tracker as a whole is checked against the model in `blink_tracker.rs`):
//! * the item stage: every non-flush word gives its candidate lanes in
//!   ascending order, or one item when it has none, whatever the compare
//!   stage's back-pressure; the word is popped with its last item; a flush
//!   word is never taken; a restart starts the head word over;
//! * the opening's windows: every anchor of the test field and of the
//!   SPCImager's 320×240, the 3×3 window's lane masks from the pixels it
//!   covers, the association window, the slot words' layout;
//! * the walk memory: random writes and walks, the word of the read
//!   stage's slot every clock (with one slot, the word written in the
//!   clock before);
//! * the walk step: random slots at the end of a plane, at the stream end
//!   and at the end of a drain plane, against the model's rules in plane
//!   numbers (`t_cross`, `t_drop`) where the step works in ages.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::{
    shadow, slot_word, walk_word, ItemStage, OpeningWindows, WalkMemory, WalkStep, WALK_WORD_BITS,
};
use smartagg_hdl::config::BackHalfConfig;
use smartagg_hdl::pipeline::{spcimager150_back_config, test_back_config};
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::record::flags;
use std::collections::VecDeque;

/// A word at the head of the tracker's input FIFO.
#[derive(Clone, Copy, Debug)]
struct Word {
    above: u64,
    cand: u64,
    x: u64,
    y: u64,
    flush: bool,
}

/// An item as the compare stage takes it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Item {
    cand: bool,
    last: bool,
    eor: bool,
    lastrow: bool,
    cx: u64,
    yc: u64,
    xc: u64,
    ym1: u64,
    yp1: u64,
    above: u64,
}

/// The items a word gives, by definition.
fn items_of(w: &Word, p: usize, words_per_row: u64, height: u64) -> Vec<Item> {
    let lanes: Vec<u64> = (0..p as u64).filter(|j| w.cand >> j & 1 == 1).collect();
    let item = |cand: bool, last: bool, lane: u64| Item {
        cand,
        last,
        eor: w.x == words_per_row - 1,
        lastrow: w.y == height - 1,
        cx: w.x * p as u64 + lane,
        yc: w.y,
        xc: w.x,
        ym1: w.y.saturating_sub(1),
        yp1: w.y + 1,
        above: w.above,
    };
    if lanes.is_empty() {
        return vec![item(false, true, 0)];
    }
    let n = lanes.len();
    lanes
        .into_iter()
        .enumerate()
        .map(|(i, lane)| item(true, i + 1 == n, lane))
        .collect()
}

/// Random words of a `P`-pixel configuration through the item stage,
/// with the compare stage taking an item on `take_p` of the clocks; a
/// restart now and then in the middle of a word.
fn item_stage_case<const P: usize>(cfg: &BackHalfConfig, take_p: f64, seed: u64) {
    let mut rng = common::rng(seed);
    let f = &cfg.front;
    let (wpr, height) = (f.words_per_row() as u64, f.height as u64);
    let mut b = Bench::new(ItemStage::<P>::new(cfg), |u| &mut u.clock);
    b.uut.restart.next = true;
    b.tick();
    b.uut.restart.next = false;
    let mut fifo: VecDeque<Word> = VecDeque::new();
    // The stage by definition: the item it holds, and how many items of the
    // head word it has taken.
    let mut held: Option<Item> = None;
    let mut progress = 0usize;
    let (mut taken, mut popped, mut flushes, mut restarts) = (0usize, 0usize, 0usize, 0usize);
    for cycle in 0..6000 {
        if fifo.len() < 3 && rng.gen_bool(0.7) {
            let lanes = (1u64 << P) - 1;
            // Mostly sparse candidates, sometimes every lane.
            let cand = match rng.gen_range(0..10) {
                0..=4 => 0,
                5..=7 => 1 << rng.gen_range(0..P),
                8 => rng.gen::<u64>() & lanes,
                _ => lanes,
            };
            fifo.push_back(Word {
                above: rng.gen::<u64>() & lanes,
                cand,
                x: rng.gen_range(0..wpr),
                y: rng.gen_range(0..height),
                flush: rng.gen_bool(0.1),
            });
        }
        let head = fifo.front().copied();
        let restart = rng.gen_bool(0.003);
        let take = rng.gen_bool(take_p);
        let u = &mut b.uut;
        u.in_valid.next = head.is_some();
        if let Some(w) = head {
            u.in_above.next = w.above.to_bits();
            u.in_cand.next = w.cand.to_bits();
            u.in_x.next = w.x.to_bits();
            u.in_y.next = w.y.to_bits();
            u.in_flush.next = w.flush;
        }
        u.restart.next = restart;
        u.take.next = take;
        settle(u);

        assert_eq!(u.valid.val(), held.is_some(), "cycle {cycle}: valid");
        if let (Some(h), true) = (held, take) {
            let got = Item {
                cand: u.cand.val(),
                last: u.last.val(),
                eor: u.eor.val(),
                lastrow: u.lastrow.val(),
                cx: u.cx.val().to_u64(),
                yc: u.yc.val().to_u64(),
                xc: u.xc.val().to_u64(),
                ym1: u.ym1.val().to_u64(),
                yp1: u.yp1.val().to_u64(),
                above: u.above.val().to_u64(),
            };
            assert_eq!(got, h, "cycle {cycle}: item taken");
            taken += 1;
        }
        if let Some(w) = head {
            assert_eq!(u.head_eor.val(), w.x == wpr - 1, "cycle {cycle}");
            assert_eq!(u.head_lastrow.val(), w.y == height - 1, "cycle {cycle}");
        }
        // The next clock, by definition: the stage takes the head word's
        // next item when it is empty or its item is taken; a restart
        // empties it and starts the head word over.
        let free = held.is_none() || take;
        if take {
            held = None;
        }
        let mut pop = false;
        let mut consumed = false;
        match head {
            Some(w) if !w.flush && free => {
                let all = items_of(&w, P, wpr, height);
                let item = all[progress];
                held = Some(item);
                progress += 1;
                if item.last {
                    pop = true;
                    progress = 0;
                }
            }
            Some(w) if w.flush => {
                // The tracker pops flush words itself, in Drain.
                consumed = rng.gen_bool(0.5);
                flushes += consumed as usize;
            }
            _ => {}
        }
        if restart {
            held = None;
            progress = 0;
            restarts += 1;
        }
        assert_eq!(b.uut.pop.val(), pop, "cycle {cycle}: pop");
        b.tick();
        if pop || consumed {
            fifo.pop_front();
            popped += pop as usize;
        }
    }
    assert!(
        taken > 1000 && popped > 300 && flushes > 50 && restarts > 5,
        "taken {taken}, popped {popped}, flush words {flushes}, restarts {restarts}"
    );
}

#[test]
fn item_stage_gives_every_candidate_lane_in_order_then_pops() {
    let cfg = test_back_config(4, 3, 1).unwrap();
    for (take_p, seed) in [(1.0, 1), (0.6, 2), (0.25, 3)] {
        item_stage_case::<4>(&cfg, take_p, seed);
    }
    let big = spcimager150_back_config().unwrap();
    item_stage_case::<16>(&big, 0.6, 4);
}

/// Every anchor of a configuration's field through the opening's windows,
/// against the windows by definition: the 3×3 window's columns
/// `[cx − 1, cx + 1]` clipped to the field, as the lanes of the words that
/// hold them; the last row `min(cy + 1, H − 1)`; the association window
/// `[c − r, c + r]` clipped at 0.
fn opening_case<const P: usize>(cfg: &BackHalfConfig, rows: impl Iterator<Item = usize>) {
    let (w, h, r) = (cfg.front.width, cfg.front.height, cfg.r_assoc as u64);
    let mut u = OpeningWindows::<P>::new(cfg);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let field = |v: u64, at: usize| (v & ((1 << 10) - 1)) << at;
    let mut checked = 0;
    for cy in rows {
        for cx in 0..w {
            u.cx.next = (cx as u64).to_bits();
            u.cy.next = (cy as u64).to_bits();
            u.lastrow.next = cy == h - 1;
            settle(&mut u);
            let (lo, hi) = (cx.saturating_sub(1), (cx + 1).min(w - 1));
            let (wl, wh) = (lo / P, hi / P);
            let lanes_of = |word: usize| -> u64 {
                (0..P)
                    .filter(|j| (lo..=hi).contains(&(word * P + j)))
                    .fold(0, |m, j| m | 1 << j)
            };
            let frow = (cy + 1).min(h - 1) as u64;
            let (x, y) = (cx as u64, cy as u64);
            let geo = field(x, slot_word::AX)
                | field(y, slot_word::AY)
                | field(wl as u64, slot_word::WL)
                | field(wh as u64, slot_word::WH)
                | field(frow, slot_word::FROW);
            let at = format!("anchor ({cx}, {cy})");
            assert_eq!(u.geo.val().to_u64(), geo, "{at}: geo");
            assert_eq!(
                u.win.val().to_u64(),
                lanes_of(wl) | lanes_of(wh) << 32,
                "{at}: win"
            );
            assert_eq!(
                u.sh.val().to_u64(),
                field(x, shadow::AX) | field(y, shadow::AY) | 1 << shadow::FRESH,
                "{at}: sh"
            );
            let bnd =
                x.saturating_sub(r) | (x + r) << 10 | y.saturating_sub(r) << 20 | (y + r) << 30;
            assert_eq!(u.bnd.val().to_u64(), bnd, "{at}: bnd");
            checked += 1;
        }
    }
    assert!(checked >= w * 2, "{checked} anchors");
}

#[test]
fn opening_windows_cover_the_3x3_and_the_association_window_of_every_anchor() {
    let cfg = test_back_config(4, 3, 1).unwrap();
    opening_case::<4>(&cfg, 0..cfg.front.height);
    let cfg = test_back_config(4, 3, 3).unwrap();
    opening_case::<4>(&cfg, 0..cfg.front.height);
    // The SPCImager's 320×240: the first, last and a few inner rows.
    let big = spcimager150_back_config().unwrap();
    opening_case::<16>(&big, [0, 1, 2, 117, 238, 239].into_iter());
}

/// Random writes and walks of `m` slots: the word of the read stage's slot
/// every clock is the slot's last word written (a clock ahead; with one
/// slot, also the word written in the clock before). Writes to the slot
/// the stage reads next are left out for M > 1, as the tracker's walk never
/// makes them (W2 writes slot k while the read stage reads k + 1 or k + 2).
fn walk_memory_case(m: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut b = Bench::new(WalkMemory::new(m), |u| &mut u.clock);
    b.uut.restart.next = true;
    b.tick();
    b.uut.restart.next = false;
    let word_mask = (1u64 << WALK_WORD_BITS) - 1;
    // Unwritten words read as zero in simulation.
    let mut mem = vec![0u64; m];
    let mut slot = 0usize;
    let (mut checked, mut moves, mut forwarded) = (0usize, 0usize, 0usize);
    for cycle in 0..4000 {
        let restart = rng.gen_bool(0.01);
        let advance = !restart && rng.gen_bool(0.6);
        let next = if restart {
            0
        } else if advance {
            (slot + 1) % m
        } else {
            slot
        };
        let write_slot = rng.gen_range(0..m);
        let write = rng.gen_bool(0.5) && (m == 1 || write_slot != next);
        let data = rng.gen::<u64>() & word_mask;
        let u = &mut b.uut;
        u.restart.next = restart;
        u.advance.next = advance;
        u.slot.next = (slot as u64).to_bits();
        u.slot_next.next = (next as u64).to_bits();
        u.write_enable.next = write;
        u.write_slot.next = (write_slot as u64).to_bits();
        u.write_data.next = data.to_bits();
        settle(u);
        if cycle > 0 {
            assert_eq!(
                u.word.val().to_u64(),
                mem[slot],
                "cycle {cycle}: word of slot {slot} (M = {m})"
            );
            checked += 1;
        }
        b.tick();
        if write {
            mem[write_slot] = data;
            forwarded += (m == 1) as usize;
        }
        moves += (next != slot) as usize;
        slot = next;
    }
    assert!(checked > 3000 && (m == 1 || moves > 1000) && (m > 1 || forwarded > 1000));
}

#[test]
fn walk_memory_reads_the_read_stages_slot_a_clock_ahead() {
    for (m, seed) in [(1, 5), (2, 6), (3, 7), (32, 8)] {
        walk_memory_case(m, seed);
    }
}

/// A slot at the walk of plane t, in the model's plane numbers.
#[derive(Clone, Copy, Debug)]
struct WalkCase {
    busy: bool,
    live: bool,
    dip: bool,
    pend: bool,
    opened: bool,
    conf: bool,
    cont: bool,
    trunc: bool,
    t_cross: u64,
    t_drop: u64,
}

/// What the walk does, by the model's rules (`model::blink_tracker`'s
/// end of plane, `finish` and drain planes; PACKETS.md §8).
#[derive(Debug, PartialEq)]
struct WalkOutcome {
    cut: bool,
    unconf: bool,
    comp: bool,
    flags: u64,
    tc: u64,
    td: u64,
    n_busy: bool,
    n_live: bool,
    n_pre: bool,
    n_fresh: bool,
    fin_end: bool,
    fin_unconf: bool,
    /// The written word's fields that the next walk reads: age, dage (of a
    /// dropped segment: while live it is never read), conf, cont, trunc.
    age: u64,
    dage: Option<u64>,
    conf: bool,
    cont: bool,
    trunc: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum WalkKind {
    EndOfPlane,
    Finish,
    Drain,
}

struct Rules {
    n: u64,
    end_trim: u64,
    l_min: u64,
    l_max: u64,
}

fn walk_by_the_rules(c: &WalkCase, t: u64, kind: WalkKind, r: &Rules) -> WalkOutcome {
    // A slot opened in plane t starts a first segment there.
    let (t_cross, conf, cont, trunc) = if c.opened {
        (t, false, false, false)
    } else {
        (c.t_cross, c.conf, c.cont, c.trunc)
    };
    // A blink whose on/off step ended it in plane t ended at t − 1.
    let (t_drop, conf1) = if c.pend {
        (t - 1, cont || (t - 1) - t_cross >= r.l_min)
    } else {
        (c.t_drop, conf)
    };
    let dropped_done = t >= t_drop + r.n - r.end_trim;
    let cut = c.busy && c.live && !c.dip && t + 1 >= t_cross + r.l_max;
    let unconf = c.busy && !c.live && !conf1;
    let comp = cut || (c.busy && !c.live && conf1 && dropped_done);
    let n_busy = if kind == WalkKind::Drain {
        c.busy
    } else {
        // A completion frees the slot, unless it is a cut.
        c.busy && !unconf && (cut || !comp)
    };
    let n_live = c.live || cut;
    // The stream end (t = p): a live track ends at p − 1, confirmed if it
    // was on L_min planes (to p − 1 if it is in a dip, else to p).
    let on_until = if c.dip { t - 1 } else { t };
    let fin_end = c.busy && c.live;
    let fconf = cont || on_until - t_cross >= r.l_min;
    let mut flag_bits = 0;
    if cut {
        flag_bits |= flags::CUT as u64;
    }
    if cont {
        flag_bits |= flags::CONTINUATION as u64;
    }
    if trunc {
        flag_bits |= flags::TRUNCATED as u64;
    }
    let (age, dage, w_conf, w_cont, w_trunc) = match kind {
        WalkKind::EndOfPlane if cut => (0, Some(1), true, true, false),
        WalkKind::EndOfPlane => (
            t + 1 - t_cross,
            (!n_live).then(|| t + 1 - t_drop),
            conf1,
            cont,
            trunc,
        ),
        WalkKind::Finish if fin_end => (t - t_cross, Some(1), fconf, cont, true),
        WalkKind::Finish => (
            t - t_cross,
            (!c.live).then(|| t - t_drop),
            conf,
            cont,
            trunc,
        ),
        WalkKind::Drain => (
            t + 1 - t_cross,
            (!n_live).then(|| t + 1 - t_drop),
            conf,
            cont,
            trunc,
        ),
    };
    WalkOutcome {
        cut,
        unconf,
        comp,
        flags: flag_bits,
        tc: t_cross,
        td: if cut { t } else { t_drop },
        n_busy,
        n_live,
        // The delayed plane of t + 1 is summed by a live or truncated
        // segment, and by a dropped one up to its last plane
        // t_drop − end_trim, i.e. while t + 1 ≤ t_drop + N − end_trim.
        n_pre: n_busy && t + 1 >= r.n && (n_live || trunc || t < t_drop + r.n - r.end_trim),
        n_fresh: n_busy && cut,
        fin_end,
        fin_unconf: fin_end && !fconf,
        age,
        dage,
        conf: w_conf,
        cont: w_cont,
        trunc: w_trunc,
    }
}

#[test]
fn walk_step_follows_the_models_rules_in_ages() {
    let mut rng = common::rng(9);
    let mut u = WalkStep::default();
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mask18 = (1u64 << 18) - 1;
    let (mut cuts, mut comps, mut unconfs, mut fin_unconfs) = (0, 0, 0, 0);
    for case in 0..30_000 {
        let n = rng.gen_range(1..=12u64);
        let r = Rules {
            n,
            end_trim: rng.gen_range(0..n),
            l_min: rng.gen_range(1..=6),
            l_max: 0,
        };
        let r = Rules {
            l_max: rng.gen_range(r.l_min.max(n)..=r.l_min.max(n) + 8),
            ..r
        };
        let kind = [WalkKind::EndOfPlane, WalkKind::Finish, WalkKind::Drain][rng.gen_range(0..3)];
        let t = rng.gen_range(2..60u64);
        // The stream end's `finish` ends live tracks; in the drain planes
        // that follow no track is live. Only the end of a real plane sees
        // openings and drops of that plane (`opened`, `pend`), and only the
        // drain planes truncated segments.
        let live = kind != WalkKind::Drain && rng.gen_bool(0.5);
        // A live segment is cut before it reaches L_max; a dropped one
        // completes N − end_trim planes after its drop (in the drain
        // planes it is followed for up to 2N).
        let t_cross = t - rng.gen_range(0..=t.min(r.l_max - 1));
        let end_plane = kind == WalkKind::EndOfPlane;
        let pend = end_plane && !live && t_cross < t && rng.gen_bool(0.5);
        let follow = if end_plane { n - r.end_trim } else { 2 * n };
        let t_drop = if live || pend {
            0
        } else {
            rng.gen_range(t_cross.max(t.saturating_sub(follow))..t.max(t_cross + 1))
        };
        let opened = end_plane && live && t_cross == t && rng.gen_bool(0.7);
        let c = WalkCase {
            busy: rng.gen_bool(0.85),
            live,
            dip: live && t_cross < t && rng.gen_bool(0.3),
            pend,
            opened,
            conf: !live && !pend && rng.gen_bool(0.6),
            cont: !opened && rng.gen_bool(0.3),
            trunc: kind == WalkKind::Drain && rng.gen_bool(0.5),
            t_cross,
            t_drop,
        };
        let age = if opened {
            rng.gen::<u64>() & mask18 // a previous track's word
        } else {
            t - t_cross
        };
        let dage = if live || pend {
            rng.gen::<u64>() & mask18 // meaningless until the drop
        } else {
            t - t_drop
        };
        let word = age << walk_word::AGE
            | dage << walk_word::DAGE
            | (c.conf as u64) << walk_word::CONF
            | (c.cont as u64) << walk_word::CONT
            | (c.trunc as u64) << walk_word::TRUNC;
        u.end_of_plane.next = kind == WalkKind::EndOfPlane;
        u.finish.next = kind == WalkKind::Finish;
        u.drain.next = kind == WalkKind::Drain;
        u.busy.next = c.busy;
        u.live.next = c.live;
        u.dip.next = c.dip;
        u.pend.next = c.pend;
        u.opened.next = c.opened;
        u.word.next = word.to_bits();
        u.t.next = t.to_bits();
        u.t1_ge_n.next = t + 1 >= r.n;
        u.lmin.next = r.l_min.to_bits();
        u.lmin_p1.next = (r.l_min + 1).to_bits();
        u.lmax_m1.next = (r.l_max - 1).to_bits();
        u.n_mc.next = (r.n - r.end_trim).to_bits();
        u.mc_one.next = r.n - r.end_trim == 1;
        settle(&mut u);
        let want = walk_by_the_rules(&c, t, kind, &r);
        let w = u.word_next.val().to_u64();
        let got = WalkOutcome {
            cut: u.cut.val(),
            unconf: u.unconf.val(),
            comp: u.comp.val(),
            flags: u.flags.val().to_u64(),
            tc: u.tc.val().to_u64(),
            td: u.td.val().to_u64(),
            n_busy: u.n_busy.val(),
            n_live: u.n_live.val(),
            n_pre: u.n_pre.val(),
            n_fresh: u.n_fresh.val(),
            fin_end: u.fin_end.val(),
            fin_unconf: u.fin_unconf.val(),
            age: w >> walk_word::AGE & mask18,
            dage: want.dage.map(|_| w >> walk_word::DAGE & mask18),
            conf: w >> walk_word::CONF & 1 == 1,
            cont: w >> walk_word::CONT & 1 == 1,
            trunc: w >> walk_word::TRUNC & 1 == 1,
        };
        // What the tracker does not use is not compared: the record of a
        // segment that does not complete (the stream end's records are
        // emitted later, from the words `finish` writes), the state of a
        // slot freed, the end-of-plane decisions at the stream end and in a
        // drain plane.
        let relevant = |o: &WalkOutcome| {
            let record = o.comp && end_plane;
            let kept = o.n_busy || (kind == WalkKind::Finish && c.busy);
            (
                end_plane.then_some((o.cut, o.unconf, o.comp, o.n_live, o.n_fresh)),
                (kind != WalkKind::Finish).then_some((o.n_busy, o.n_pre)),
                record.then_some((o.flags, o.tc, o.td)),
                (kind == WalkKind::Finish).then_some((o.fin_end, o.fin_unconf)),
                kept.then_some((o.age, o.dage, o.conf, o.cont, o.trunc)),
            )
        };
        assert_eq!(
            relevant(&got),
            relevant(&want),
            "case {case}: {kind:?} at t = {t}, {c:?}, N {} end_trim {} L_min {} L_max {}",
            r.n,
            r.end_trim,
            r.l_min,
            r.l_max
        );
        cuts += want.cut as usize;
        comps += (want.comp && !want.cut) as usize;
        unconfs += want.unconf as usize;
        fin_unconfs += (kind == WalkKind::Finish && want.fin_unconf) as usize;
    }
    assert!(
        cuts > 300 && comps > 300 && unconfs > 300 && fin_unconfs > 100,
        "cuts {cuts}, completions {comps}, unconfirmed {unconfs}, finish unconfirmed {fin_unconfs}"
    );
}
