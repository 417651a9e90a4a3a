//! The gateware tracker against `model::blink_tracker::BlinkTracker` on
//! random H streams (blinking molecules with one- and two-plane dips,
//! neighbours within the association radius, short false alarms), random
//! word timing, few slots (exhaustion), short L_max (cuts), any END_TRIM
//! (0 ..= N − 1), a record queue that is sometimes full (losses counted),
//! and the stream end with its N drain planes.
//!
//! Checked: every record (kind, slot, flags, anchor, t_cross, t_drop,
//! Dropped count and first position, StreamEnd counters), the loss counts,
//! bank hand-over, and the ROI view (shadow) exactly when and where the ROI
//! aggregator reads it: for every row r of plane t once the tracker has done
//! `min(r + h + 2, H)` rows, and for the whole previous plane, which slots
//! sweep row r (sum the delayed plane, or start their counters) and with
//! which flags and anchor.

mod common;

use proptest::prelude::*;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::{record_kind, shadow, BlinkTracker, COORD_BITS};
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig};
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::blink_tracker::{BlinkTracker as Model, Completed, Slot};
use smartagg_model::candidates::{find, Candidate};
use smartagg_model::config::PipelineConfig;
use smartagg_model::record::flags;
use smartagg_model::threshold::neighbourhood_on;
use std::collections::VecDeque;

const W: usize = 16;
const H: usize = 8;
const P: usize = 4;
const THR: u32 = 6;
type Dut = BlinkTracker<4, 3, 3>;

/// Random H maps: background below threshold, blinking molecules (peaks
/// with lower neighbours), isolated one-plane false alarms.
fn scene(rng: &mut ChaCha8Rng, planes: usize, molecules: usize, noise: f64) -> Vec<Vec<u32>> {
    let mols: Vec<(usize, usize, Vec<bool>)> = (0..molecules)
        .map(|_| {
            let (x, y) = (rng.gen_range(0..W), rng.gen_range(0..H));
            let mut on = vec![false; planes];
            let mut t = rng.gen_range(0..planes / 2 + 1);
            while t < planes {
                let len = rng.gen_range(1..12);
                for v in on.iter_mut().skip(t).take(len) {
                    *v = true;
                }
                // Gaps of one plane (bridged) or more (a new blink).
                t += len + rng.gen_range(1..6);
            }
            (x, y, on)
        })
        .collect();
    (0..planes)
        .map(|t| {
            let mut h: Vec<u32> = (0..W * H).map(|_| rng.gen_range(0..3)).collect();
            for (x, y, on) in &mols {
                if on[t] {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (xx, yy) = (*x as i64 + dx, *y as i64 + dy);
                            if xx >= 0 && yy >= 0 && xx < W as i64 && yy < H as i64 {
                                let add = if dx == 0 && dy == 0 { 9 } else { 3 };
                                h[yy as usize * W + xx as usize] += add;
                            }
                        }
                    }
                }
            }
            if rng.gen_bool(noise) {
                let i = rng.gen_range(0..W * H);
                h[i] = h[i].max(THR + 1);
            }
            h
        })
        .collect()
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Rec {
    Start,
    Blink {
        slot: u8,
        flags: u8,
        ax: u16,
        ay: u16,
        t_cross: u64,
        t_drop: u64,
    },
    Dropped {
        plane: u64,
        count: u32,
        x: u16,
        y: u16,
    },
    End,
}

fn blink(c: &Completed) -> Rec {
    let s = &c.segment;
    Rec::Blink {
        slot: c.slot as u8,
        flags: s.end_flags
            | if s.continuation {
                flags::CONTINUATION
            } else {
                0
            },
        ax: s.anchor_x,
        ay: s.anchor_y,
        t_cross: s.t_cross,
        t_drop: s.t_drop.unwrap(),
    }
}

/// What the aggregator must see for one slot in one plane: whether it
/// sums the delayed plane (the model's `sums_delayed`), whether it is the
/// segment's first plane (its counters start; swept even without a sum).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct View {
    pre: bool,
    fresh: bool,
    ax: u16,
    ay: u16,
}

impl View {
    fn sums(&self) -> bool {
        self.pre || self.fresh
    }
    fn covers(&self, r: usize, h: usize) -> bool {
        self.sums() && (self.ay as usize + h >= r) && (self.ay as usize <= r + h)
    }
}

struct Expected {
    records: Vec<Rec>,
    views: Vec<Vec<View>>, // per plane (real and drain), per slot
    counters: [u64; 5],    // blinks, unconfirmed, dropped, bridged, cuts
    /// The OR of the Blink records' flags.
    flags: u8,
    /// Blinks that summed no plane.
    empty: usize,
}

#[allow(clippy::too_many_arguments)]
fn model(
    hs: &[Vec<u32>],
    m: usize,
    n: u32,
    end_trim: u32,
    l_min: u32,
    l_max: u32,
    r: u32,
) -> Expected {
    let mut tr = Model::new(m, n, end_trim, l_min, l_max, r);
    let mut records = vec![Rec::Start];
    let mut views = Vec::new();
    let mut blinks = 0u64;
    let (mut all_flags, mut empty) = (0u8, 0usize);
    let mut note = |c: &Completed| {
        all_flags |= c.segment.flags(n);
        if c.segment.planes_summed(n, end_trim) == Some(0) {
            empty += 1;
        }
    };
    for (t, hmap) in hs.iter().enumerate() {
        let t = t as u64;
        tr.evaluate(t, |x, y| {
            neighbourhood_on(hmap, W, H, x as usize, y as usize, THR)
        });
        let cands: Vec<Candidate> = find(hmap, W, H, THR);
        let (_, drops) = tr.associate(t, &cands);
        views.push(
            (0..m)
                .map(|i| match &tr.slots()[i] {
                    Slot::Busy(s) => View {
                        pre: tr.sums_delayed(i, t),
                        fresh: s.t_cross == t,
                        ax: s.anchor_x,
                        ay: s.anchor_y,
                    },
                    Slot::Free => View {
                        pre: false,
                        fresh: false,
                        ax: 0,
                        ay: 0,
                    },
                })
                .collect(),
        );
        for c in tr.end_of_plane(t) {
            blinks += 1;
            note(&c);
            records.push(blink(&c));
        }
        if let Some(d) = drops {
            records.push(Rec::Dropped {
                plane: t,
                count: d.count,
                x: d.first.x,
                y: d.first.y,
            });
        }
    }
    let p = hs.len() as u64;
    if p > 0 {
        let done = tr.finish(p);
        for j in 0..n as u64 {
            let t = p + j;
            let mut v = vec![
                View {
                    pre: false,
                    fresh: false,
                    ax: 0,
                    ay: 0
                };
                m
            ];
            for c in &done {
                let s = &c.segment;
                // Drain plane t sums B_{t−N} while t − N ≤ the last plane
                // (a truncated segment: every drain plane).
                let last = s.last_plane(n, end_trim).unwrap();
                // (A cut at the last plane: the continuation starts at p.)
                v[c.slot] = View {
                    pre: t >= n as u64 && (t - n as u64) as i64 <= last,
                    fresh: s.t_cross == t,
                    ax: s.anchor_x,
                    ay: s.anchor_y,
                };
            }
            views.push(v);
        }
        for c in &done {
            blinks += 1;
            note(c);
            records.push(blink(c));
        }
    }
    records.push(Rec::End);
    let c = tr.counters();
    Expected {
        records,
        views,
        counters: [
            blinks,
            c.unconfirmed,
            c.dropped_candidates,
            c.bridged_dips,
            c.cut_segments,
        ],
        flags: all_flags,
        empty,
    }
}

#[derive(Clone, Copy)]
struct Params {
    seed: u64,
    planes: usize,
    molecules: usize,
    slots: usize,
    n: u32,
    end_trim: u32,
    l_min: u32,
    l_max: u32,
    r_assoc: u32,
    word_rate: f64,
    room_rate: f64,
    /// How often the free list shows a bank (a returned bank takes a few
    /// clocks to reach it while the queue already has room).
    bank_rate: f64,
}

/// What a run observed besides the checks it makes itself.
struct Outcome {
    /// ROI view entries checked.
    views: usize,
    /// The model's records.
    records: usize,
    /// Clocks the tracker waited for the sweep.
    waited: usize,
    /// Records lost because the record queue was full (each announced by
    /// the `record.lost` of the next record pushed).
    lost: usize,
    /// Clocks a Blink waited for a bank: the queue had room, the free list
    /// showed none.
    bank_waits: usize,
    /// The OR of the model's Blink flags.
    flags: u8,
    /// The model's Blinks that summed no plane.
    empty: usize,
}

/// Runs a stream and checks it against the model.
fn run(pr: &Params) -> Outcome {
    let mut rng = common::rng(pr.seed);
    let hs = scene(&mut rng, pr.planes, pr.molecules, 0.3);
    run_on(pr, &hs, rng)
}

/// Runs the H maps `hs` (`pr.planes` and `pr.molecules` unused) with the
/// word timing drawn from `rng`.
fn run_on(pr: &Params, hs: &[Vec<u32>], mut rng: ChaCha8Rng) -> Outcome {
    let hs = hs.to_vec();
    let pr = &Params {
        planes: hs.len(),
        ..*pr
    };
    let exp = model(
        &hs,
        pr.slots,
        pr.n,
        pr.end_trim,
        pr.l_min,
        pr.l_max,
        pr.r_assoc,
    );

    let mut mcfg = PipelineConfig::new(W, H, pr.n, vec![1, 2, 1], 2, THR);
    mcfg.slots = pr.slots;
    mcfg.roi_size = 3;
    mcfg.r_assoc = pr.r_assoc;
    mcfg.end_trim = pr.end_trim;
    mcfg.l_min = pr.l_min;
    mcfg.l_max = pr.l_max;
    let front = GatewareConfig::new(&mcfg, P, 7).unwrap();
    let mut bh = BackHalfConfig::new(&mcfg, front, 64).unwrap();
    bh.queue_log2 = 2; // banks M + 4 fit 3 bits for M ≤ 4
    let h = bh.roi_half();
    let m = pr.slots;

    let mut b = Bench::new(Dut::new(&bh).unwrap(), |u| &mut u.clock);
    b.uut.restart.next = true;
    b.uut.emit_start.next = true;
    b.uut.n_window.next = (pr.n as u64).to_bits();
    b.uut.end_trim.next = (pr.end_trim as u64).to_bits();
    b.uut.l_min.next = (pr.l_min as u64).to_bits();
    b.uut.l_max.next = (pr.l_max as u64).to_bits();
    b.tick();
    b.uut.restart.next = false;

    // The word stream: real planes, N drain planes, one flush plane.
    let wpr = W / P;
    let words_per_plane = wpr * H;
    let total_planes = pr.planes + pr.n as usize + 1;
    let mut produced = 0usize;
    let mut fifo: VecDeque<(u64, u64, usize, usize, bool)> = VecDeque::new();
    let mut next_bank = 1000u64; // fresh banks never seen before
    let mut got: Vec<(Rec, u32, u64)> = Vec::new();
    let mut views_checked = 0usize;
    let mut cycles = 0usize;
    // Planes the aggregator has swept: it finishes a plane some random
    // clocks after the tracker has left it, so the tracker must often wait.
    let mut sweep = 0usize;
    let mut waited = 0usize;
    let mut bank_waits = 0usize;
    loop {
        cycles += 1;
        assert!(cycles < 200_000, "tracker did not finish");
        // Produce the next word of the stream.
        if produced < total_planes * words_per_plane && rng.gen_bool(pr.word_rate) {
            let (t, k) = (produced / words_per_plane, produced % words_per_plane);
            let (x, y) = (k % wpr, k / wpr);
            let (mut above, mut cand) = (0u64, 0u64);
            if t < pr.planes {
                let cands = find(&hs[t], W, H, THR);
                for i in 0..P {
                    let px = x * P + i;
                    if hs[t][y * W + px] >= THR {
                        above |= 1 << i;
                    }
                    if cands.contains(&Candidate {
                        x: px as u16,
                        y: y as u16,
                    }) {
                        cand |= 1 << i;
                    }
                }
            }
            if above != 0 || x == wpr - 1 {
                fifo.push_back((above, cand, x, y, t >= pr.planes));
            }
            produced += 1;
        }
        let u = &mut b.uut;
        if produced >= pr.planes * words_per_plane {
            u.stopping.next = true;
            u.planes_total.next = (pr.planes as u64).to_bits();
        }
        u.in_valid.next = !fifo.is_empty();
        if let Some(&(above, cand, x, y, fl)) = fifo.front() {
            u.in_above.next = above.to_bits();
            u.in_cand.next = cand.to_bits();
            u.in_x.next = (x as u64).to_bits();
            u.in_y.next = (y as u64).to_bits();
            u.in_flush.next = fl;
        }
        u.record.room.next = rng.gen_bool(pr.room_rate);
        u.fb_valid.next = rng.gen_bool(pr.bank_rate);
        u.fb_bank.next = (next_bank % 8).to_bits();
        u.swept.next = (sweep as u64).to_bits();
        settle(u);

        // The ROI view, where the aggregator may read it.
        let plane = u.plane.val().to_u64() as usize;
        let rows = u.rows_done.val().to_u64() as usize;
        // The sweep reads the view of its plane: the tracker is never more
        // than one plane ahead of it.
        assert!(
            plane <= sweep + 1,
            "the tracker is at plane {plane} while the sweep is on plane {sweep}, whose ROI view it has overwritten"
        );
        if plane == sweep + 1 && rows == H {
            waited += 1;
        }
        if u.bank_wait.val() {
            bank_waits += 1;
        }
        let view = |u: &Dut, par: usize, i: usize| {
            let w = u.sh[par * m + i].val().to_u64();
            let field = |at: usize| ((w >> at) & ((1 << COORD_BITS) - 1)) as u16;
            View {
                pre: w >> shadow::PRE & 1 == 1,
                fresh: w >> shadow::FRESH & 1 == 1,
                ax: field(shadow::AX),
                ay: field(shadow::AY),
            }
        };
        for (tt, all_rows) in [(plane as i64 - 1, true), (plane as i64, false)] {
            // Plane t − 1's view is needed until the sweep has finished it;
            // then the end of plane t writes the view of t + 1 over it.
            if tt < 0 || tt as usize >= exp.views.len() || (all_rows && sweep >= plane) {
                continue;
            }
            let tt = tt as usize;
            for r in 0..H {
                if !all_rows && rows < (r + h + 2).min(H) {
                    continue;
                }
                for i in 0..m {
                    let want = exp.views[tt][i];
                    let have = view(u, tt % 2, i);
                    assert_eq!(
                        have.covers(r, h),
                        want.covers(r, h),
                        "plane {tt} row {r} slot {i}: have {have:?} want {want:?} (tracker at {plane}/{rows})"
                    );
                    if want.covers(r, h) {
                        assert_eq!(have, want, "plane {tt} row {r} slot {i}");
                        views_checked += 1;
                    }
                }
            }
        }

        if u.record.push.val() && u.record.room.val() {
            let kind = u.record.kind.val().to_u64();
            let rec = match kind {
                record_kind::START => Rec::Start,
                record_kind::BLINK => Rec::Blink {
                    slot: u.record.slot.val().to_u64() as u8,
                    flags: u.record.flags.val().to_u64() as u8,
                    ax: u.record.ax.val().to_u64() as u16,
                    ay: u.record.ay.val().to_u64() as u16,
                    t_cross: u.record.t0.val().to_u64(),
                    t_drop: u.record.t1.val().to_u64(),
                },
                record_kind::DROPPED => Rec::Dropped {
                    plane: u.record.t0.val().to_u64(),
                    count: u.record.t1.val().to_u64() as u32,
                    x: u.record.ax.val().to_u64() as u16,
                    y: u.record.ay.val().to_u64() as u16,
                },
                _ => Rec::End,
            };
            let bank = u.record.bank.val().to_u64();
            if kind == record_kind::BLINK {
                // The slot hands over the bank it summed into and takes the fresh one.
                assert!(u.fb_pop.val(), "a queued blink takes a fresh bank");
            }
            got.push((rec, u.record.lost.val().to_u64() as u32, bank));
        }
        if u.fb_pop.val() {
            next_bank += 1;
        }
        if sweep < plane && rng.gen_bool(0.05) {
            sweep += 1;
        }
        if u.in_pop.val() {
            assert!(!fifo.is_empty());
            fifo.pop_front();
        }
        assert!(!u.bank_error.val());
        let finished = u.done.val();
        b.tick();
        if finished {
            break;
        }
    }

    let u = &b.uut;
    let counters = [
        u.totals.blinks.val().to_u64(),
        u.totals.unconfirmed.val().to_u64(),
        u.totals.dropped.val().to_u64(),
        u.totals.bridged.val().to_u64(),
        u.totals.cuts.val().to_u64(),
    ];
    // Records: the model's, minus the lost ones, each gap announced.
    let mut k = 0;
    let mut lost_total = 0;
    for (rec, lost, _) in &got {
        k += *lost as usize;
        lost_total += *lost as usize;
        assert!(k < exp.records.len(), "more records than the model");
        assert_eq!(rec, &exp.records[k], "record {k} (after {lost} lost)");
        k += 1;
    }
    assert_eq!(k, exp.records.len(), "records missing at the end");
    assert_eq!(
        counters, exp.counters,
        "blinks, unconfirmed, dropped, bridged, cuts"
    );
    if pr.room_rate >= 1.0 {
        assert_eq!(lost_total, 0);
    }
    Outcome {
        views: views_checked,
        records: exp.records.len(),
        waited,
        lost: lost_total,
        bank_waits,
        flags: exp.flags,
        empty: exp.empty,
    }
}

#[test]
fn tracker_equals_model_with_cuts_dips_and_exhaustion() {
    let Outcome {
        views,
        records: recs,
        waited,
        ..
    } = run(&Params {
        seed: 11,
        planes: 40,
        molecules: 6,
        slots: 3,
        n: 3,
        end_trim: 2,
        l_min: 2,
        l_max: 5,
        r_assoc: 1,
        word_rate: 0.7,
        room_rate: 1.0,
        bank_rate: 1.0,
    });
    assert!(views > 100 && recs > 10, "views {views}, records {recs}");
    // The sweep fell behind, and the end of a plane waited for it.
    assert!(waited > 0, "the tracker never had to wait for the sweep");
}

#[test]
fn tracker_counts_records_lost_when_the_queue_is_full() {
    let out = run(&Params {
        seed: 12,
        planes: 30,
        molecules: 5,
        slots: 4,
        n: 2,
        end_trim: 0,
        l_min: 1,
        l_max: 3,
        r_assoc: 2,
        word_rate: 1.0,
        room_rate: 0.6,
        bank_rate: 1.0,
    });
    // Records were lost, and `run` has checked that every loss was counted
    // on the next record pushed (the records pushed are the model's with
    // exactly the announced ones missing).
    assert!(out.lost > 0, "no record was lost: the test shows nothing");
    assert!(out.records > 10, "records {}", out.records);
}

/// With room in the queue but the free list momentarily empty, a Blink
/// waits for the returning bank: nothing is lost, no bank FAULT.
#[test]
fn tracker_waits_for_a_returning_bank() {
    let out = run(&Params {
        seed: 13,
        planes: 40,
        molecules: 6,
        slots: 4,
        n: 2,
        end_trim: 1,
        l_min: 1,
        l_max: 3,
        r_assoc: 1,
        word_rate: 1.0,
        room_rate: 1.0,
        bank_rate: 0.5,
    });
    assert!(out.records > 10, "records {}", out.records);
    assert!(out.bank_waits > 0, "no Blink ever waited for a bank");
    // `run` checks that `bank_error` never rose; with room always there,
    // nothing may be lost.
    assert_eq!(out.lost, 0);
}

/// H maps of `planes` planes with molecules `(x, y, on planes)` over a
/// quiet background (below the threshold everywhere else).
fn molecules(planes: usize, mols: &[(usize, usize, std::ops::Range<usize>)]) -> Vec<Vec<u32>> {
    (0..planes)
        .map(|t| {
            let mut h = vec![1u32; W * H];
            for (x, y, on) in mols {
                if on.contains(&t) {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (xx, yy) = (*x as i64 + dx, *y as i64 + dy);
                            if xx >= 0 && yy >= 0 && xx < W as i64 && yy < H as i64 {
                                h[yy as usize * W + xx as usize] +=
                                    if dx == 0 && dy == 0 { 9 } else { 3 };
                            }
                        }
                    }
                }
            }
            h
        })
        .collect()
}

/// The new summation rule's corners, with END_TRIM = 0 (the paper's) and
/// 2 (of N = 4): a track on from plane 0 to the end, cut every L_max = N
/// planes (its first segment, cut at N − 1, sums nothing; a cut at the last
/// plane leaves a continuation that sums the N drain planes), a drop whose
/// completion falls after the stream end with END_TRIM 0 and before it with
/// 2, a one-plane blink whose drop at t_drop = 1 < END_TRIM sums nothing,
/// a track in a dip at the stream end, and one that drops mid-stream.
#[test]
fn tracker_equals_model_with_end_trim_cuts_and_the_stream_end() {
    let hs = molecules(
        12,
        &[
            (5, 3, 0..12), // cut at 3 (empty), 7 and 11 (the last plane)
            (12, 5, 2..7), // t_drop 7, completes at 11 − END_TRIM
            (2, 6, 9..11), // in a dip at the stream end: TRUNCATED
            (9, 1, 5..9),  // t_drop 9: completes at 13 (drain) or 11
            (13, 1, 0..1), // t_drop 1: empty with END_TRIM 2
        ],
    );
    for (end_trim, seed) in [(0, 31), (2, 32), (3, 33)] {
        let pr = Params {
            seed,
            planes: 0,
            molecules: 0,
            slots: 4,
            n: 4,
            end_trim,
            l_min: 1,
            l_max: 4,
            r_assoc: 1,
            word_rate: 0.8,
            room_rate: 1.0,
            bank_rate: 1.0,
        };
        let out = run_on(&pr, &hs, common::rng(seed));
        let want = flags::CUT | flags::CONTINUATION | flags::TRUNCATED;
        assert_eq!(
            out.flags & want,
            want,
            "END_TRIM {end_trim}: flags {:#x}",
            out.flags
        );
        // The first segment cut at N − 1, and with END_TRIM ≥ 2 the
        // one-plane blink too.
        let empty = if end_trim >= 2 { 2 } else { 1 };
        assert_eq!(out.empty, empty, "END_TRIM {end_trim}: empty segments");
        assert_eq!(out.lost, 0);
    }
}

/// A track opened by the last item of plane 7 (a candidate in the last
/// word of the last row, N = 1, L_max = 1): the first word of plane 8 must
/// be compared with the opened slot's window, not in the clock of the
/// opening (once it was, and the slot's on/off step of plane 8 ran at row
/// 0 with a stale window row: a dip, then a bridge the model never saw).
#[test]
fn tracker_compares_the_next_plane_with_a_slot_the_last_item_opened() {
    run(&Params {
        seed: 9268933700957470773,
        planes: 24,
        molecules: 4,
        slots: 3,
        n: 1,
        end_trim: 0,
        l_min: 1,
        l_max: 1,
        r_assoc: 0,
        word_rate: 0.8114189009782796,
        room_rate: 1.0,
        bank_rate: 1.0,
    });
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]
    /// Any window, end trim, confirmation length, cut length, radius, slot
    /// count and timing.
    #[test]
    fn tracker_equals_model_on_random_streams(
        seed in any::<u64>(),
        planes in 0usize..30,
        molecules in 0usize..8,
        slots in 1usize..=4,
        n in 1u32..=7,
        trim in 0u32..7,
        l_min in 1u32..=4,
        extra in 0u32..6,
        r_assoc in 0u32..=2,
        word_rate in 0.3f64..=1.0,
    ) {
        let l_max = n.max(l_min) + extra;
        let end_trim = trim % n;
        run(&Params { seed, planes, molecules, slots, n, end_trim, l_min, l_max, r_assoc, word_rate, room_rate: 1.0, bank_rate: 1.0 });
    }
}

/// Generates the tracker of `w`×`h` with `l_max_max` and checks that it is
/// accepted when `ok`, and otherwise refused with an error naming `field`.
fn check_generation(w: usize, h: usize, l_max_max: Option<u32>, ok: bool, field: &str) {
    let mut mcfg = PipelineConfig::new(w, h, 4, vec![1, 2, 1], 2, THR);
    mcfg.slots = 4;
    mcfg.roi_size = 3;
    let front = GatewareConfig::new(&mcfg, P, 7).unwrap();
    let mut bh = BackHalfConfig::new(&mcfg, front, l_max_max.unwrap_or(mcfg.l_max)).unwrap();
    bh.queue_log2 = 2;
    let what = format!("{w}x{h}, L_max,max {l_max_max:?}");
    match Dut::new(&bh) {
        Ok(_) => assert!(ok, "{what} accepted"),
        Err(e) => {
            assert!(!ok, "{what} refused: {e}");
            assert!(e.to_string().contains(field), "{e}");
        }
    }
}

/// The slot ages are `AGE_BITS` wide: an L_max,max whose ages
/// (L_max,max + 2·N_max + 2) would not fit is refused, naming the field;
/// the largest that fits is accepted.
#[test]
fn tracker_refuses_an_l_max_max_its_ages_cannot_hold() {
    use smartagg_hdl::blink_tracker::AGE_BITS;
    let mcfg = PipelineConfig::new(W, H, 4, vec![1, 2, 1], 2, THR);
    let n_max = GatewareConfig::new(&mcfg, P, 7).unwrap().n_max as u32;
    let fits = (1u32 << AGE_BITS) - 2 * n_max - 3;
    check_generation(W, H, Some(fits), true, "l_max_max");
    check_generation(W, H, Some(fits + 1), false, "l_max_max");
}

/// A field wider or taller than the tracker's coordinates hold is refused.
#[test]
fn tracker_refuses_a_field_its_coordinates_cannot_hold() {
    use smartagg_hdl::blink_tracker::MAX_FIELD;
    check_generation(MAX_FIELD, H, None, true, "width/height");
    check_generation(MAX_FIELD + P, H, None, false, "width/height");
    check_generation(W, MAX_FIELD, None, true, "width/height");
    check_generation(W, MAX_FIELD + 1, None, false, "width/height");
}

/// The packed per-slot flags hold `MAX_SLOTS` slots: more are refused
/// with the back half's configuration, naming the field; `MAX_SLOTS`
/// itself builds a tracker.
#[test]
fn tracker_refuses_more_slots_than_its_flags_hold() {
    use smartagg_hdl::config::MAX_SLOTS;
    let config = |slots: usize| {
        let mut mcfg = PipelineConfig::new(W, H, 4, vec![1, 2, 1], 2, THR);
        mcfg.slots = slots;
        mcfg.roi_size = 3;
        let front = GatewareConfig::new(&mcfg, P, 7).unwrap();
        BackHalfConfig::new(&mcfg, front, mcfg.l_max)
    };
    let mut bh = config(MAX_SLOTS).unwrap();
    bh.queue_log2 = 2;
    // 32 + 4 banks: 6-bit bank indices.
    BlinkTracker::<4, 3, 6>::new(&bh).unwrap();
    let e = config(MAX_SLOTS + 1).unwrap_err().to_string();
    assert!(
        e.contains("slots") && e.contains(&MAX_SLOTS.to_string()),
        "{e}"
    );
}
