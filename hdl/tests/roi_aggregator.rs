//! Tracker + ROI aggregator + bank pool against the golden pipeline: raw
//! bit-planes (blinking spots, background, hot pixels) go through the model
//! for stages 1–4; the gateware gets the model's above/candidate words with
//! the front half's row lag and the raw delayed/mask words, random stalls,
//! any END_TRIM, and reads every queued bank back as the packetiser would.
//! Checked: each Blink record's slot, anchor, times, tracker flags, MASKED
//! flag and all R×R counts, the order of all records, bank hand-over (a
//! bank is read only once its plane is swept, and every bank comes back),
//! and that the ROI row ring is never overrun.

mod common;

use proptest::prelude::*;
use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::{record_kind, BlinkTracker};
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig};
use smartagg_hdl::roi_aggregator::{BankPool, RoiAggregator};
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::config::PipelineConfig;
use smartagg_model::delay_line::DelayLine;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::pipeline::Pipeline;
use smartagg_model::plane::BitPlane;
use smartagg_model::record::{flags, Record};
use std::collections::VecDeque;

const W: usize = 16;
const H: usize = 8;
const P: usize = 4;
type Tracker = BlinkTracker<4, 3, 3>;
type Agg = RoiAggregator<4, 5, 7, 5, 3>;
type Pool = BankPool<3, 2>;

/// A queued record descriptor: kind, slot, flags, anchor, t0, t1, bank, tag.
type Queued = (u64, u8, u8, u16, u16, u64, u64, u64, u64);

#[derive(Debug, PartialEq, Eq)]
struct Blink {
    slot: u8,
    flags: u8,
    ax: u16,
    ay: u16,
    t_cross: u64,
    t_drop: u64,
    masked: bool,
    counts: Vec<u32>,
}

/// Planes with `spots` blinking pixels over a weak background.
fn planes(rng: &mut rand_chacha::ChaCha8Rng, n: usize, spots: usize, bg: f64) -> Vec<BitPlane> {
    let sp: Vec<(usize, usize, usize, usize)> = (0..spots)
        .map(|_| {
            let t0 = rng.gen_range(0..n.max(1));
            (
                rng.gen_range(0..W),
                rng.gen_range(0..H),
                t0,
                t0 + rng.gen_range(1..15),
            )
        })
        .collect();
    (0..n)
        .map(|t| {
            BitPlane::from_fn(W, H, |x, y| {
                let on = sp.iter().any(|&(sx, sy, a, b)| {
                    (a..b).contains(&t)
                        && sx.abs_diff(x) <= 1
                        && sy.abs_diff(y) <= 1
                        && (sx == x && sy == y || rng.gen_bool(0.5))
                });
                on || rng.gen_bool(bg)
            })
        })
        .collect()
}

fn word(plane: &BitPlane, x: usize, y: usize) -> u64 {
    plane.stream_word(P, y * plane.width() / P + x)
}

/// The registers of a run.
#[derive(Debug, Clone, Copy)]
struct Regs {
    slots: usize,
    n: u32,
    end_trim: u32,
    l_min: u32,
    l_max: u32,
    threshold: u32,
}

impl Regs {
    fn new(slots: usize, n: u32, end_trim: u32, l_min: u32, l_max: u32) -> Regs {
        Regs {
            slots,
            n,
            end_trim,
            l_min,
            l_max,
            threshold: 5,
        }
    }
}

fn run(seed: u64, n_planes: usize, spots: usize, regs: Regs, rate: f64) -> usize {
    let mut rng = common::rng(seed);
    let raw = planes(&mut rng, n_planes, spots, 0.05);
    let hot = [(rng.gen_range(0..W), rng.gen_range(0..H))];
    let (mask, _) = HotPixelMask::from_pixels(W, H, &hot);
    run_stream(&mut rng, raw, mask, regs, rate)
}

fn run_stream(
    rng: &mut rand_chacha::ChaCha8Rng,
    raw: Vec<BitPlane>,
    mask: HotPixelMask,
    regs: Regs,
    rate: f64,
) -> usize {
    let n_planes = raw.len();
    let Regs {
        slots,
        n,
        end_trim,
        l_min,
        l_max,
        threshold,
    } = regs;

    let mut cfg = PipelineConfig::new(W, H, n, vec![1, 2, 1], 2, threshold);
    cfg.slots = slots;
    cfg.roi_size = 3;
    cfg.end_trim = end_trim;
    cfg.l_min = l_min;
    cfg.l_max = l_max;
    cfg.hot_mask = Some(mask.clone());

    // The model: records and its stage 1-4 outputs per plane.
    let mut pipe = Pipeline::new(cfg.clone()).unwrap();
    let mut records = vec![pipe.start_record()];
    let mut fronts = Vec::new();
    for p in &raw {
        records.extend(pipe.push_plane(p).unwrap());
        let h = pipe.filtered().to_vec();
        let above: Vec<bool> = h.iter().map(|&v| v >= cfg.threshold_int).collect();
        let cands: Vec<bool> = {
            let mut c = vec![false; W * H];
            for cd in pipe.candidates() {
                c[cd.y as usize * W + cd.x as usize] = true;
            }
            c
        };
        fronts.push((above, cands));
    }
    records.extend(pipe.finish());
    let want: Vec<Record> = records;

    // The raw stream the gateware sees: the masked delayed planes, N drain
    // planes (delayed from the delay line).
    let masked: Vec<BitPlane> = raw.iter().map(|p| mask.apply(p)).collect();
    let mut dl = DelayLine::new(n as usize, W, H);
    let mut delayed: Vec<BitPlane> = masked.iter().map(|p| dl.push(p.clone())).collect();
    if n_planes > 0 {
        for _ in 0..n {
            delayed.push(dl.push(BitPlane::zeros(W, H)));
        }
    }
    let mask_plane = BitPlane::from_fn(W, H, |x, y| mask.is_masked(x as i64, y as i64));

    let front = GatewareConfig::new(&cfg, P, 7).unwrap();
    let mut bh = BackHalfConfig::new(&cfg, front, 64).unwrap();
    bh.queue_log2 = 2;
    let mut tr = Bench::new(Tracker::new(&bh).unwrap(), |u| &mut u.clock);
    let mut ag = Bench::new(Agg::new(&bh).unwrap(), |u| &mut u.clock);
    let mut pool = Bench::new(Pool::new(&bh).unwrap(), |u| &mut u.clock);
    tr.uut.restart.next = true;
    tr.uut.emit_start.next = true;
    ag.uut.restart.next = true;
    pool.uut.restart.next = true;
    tr.uut.n_window.next = (n as u64).to_bits();
    tr.uut.end_trim.next = (end_trim as u64).to_bits();
    tr.uut.l_min.next = (l_min as u64).to_bits();
    tr.uut.l_max.next = (l_max as u64).to_bits();
    tr.tick();
    ag.tick();
    pool.tick();
    tr.uut.restart.next = false;
    ag.uut.restart.next = false;
    pool.uut.restart.next = false;

    let wpr = W / P;
    let wpp = wpr * H;
    let lag = 2 * wpr + 3; // the front half's output lags its input by c + 1 rows and a few words
    let stream_planes = delayed.len();
    let total = (stream_planes + 1) * wpp + lag; // + the flush plane
    let mut g = 0usize;
    let mut fifo: VecDeque<(u64, u64, usize, usize, bool)> = VecDeque::new();
    let mut queue: VecDeque<Queued> = VecDeque::new();
    let mut got: Vec<Record> = Vec::new();
    let mut lost: VecDeque<usize> = VecDeque::new(); // records lost before each queued one
    let mut skips: Vec<usize> = Vec::new();
    let mut reading: Option<(usize, Vec<u32>, bool)> = None; // (row, counts, masked)
    let mut pending_read = false;
    let mut returned = 0usize;
    let mut cycles = 0;
    loop {
        cycles += 1;
        assert!(cycles < 100_000, "did not finish");
        let step = g < total && rng.gen_bool(rate);
        // Raw word g to the aggregator (real and drain planes only).
        let a = &mut ag.uut;
        a.in_valid.next = false;
        if step && g < stream_planes * wpp {
            let (t, k) = (g / wpp, g % wpp);
            let (x, y) = (k % wpr, k / wpr);
            a.in_valid.next = true;
            a.in_x.next = (x as u64).to_bits();
            a.in_delayed.next = word(&delayed[t], x, y).to_bits();
            a.in_mask.next = word(&mask_plane, x, y).to_bits();
        }
        // Front-half word g − lag to the tracker FIFO.
        if step && g >= lag {
            let f = g - lag;
            let (t, k) = (f / wpp, f % wpp);
            let (x, y) = (k % wpr, k / wpr);
            let (mut above, mut cand) = (0u64, 0u64);
            if t < n_planes {
                for i in 0..P {
                    let j = y * W + x * P + i;
                    above |= (fronts[t].0[j] as u64) << i;
                    cand |= (fronts[t].1[j] as u64) << i;
                }
            }
            if above != 0 || x == wpr - 1 {
                fifo.push_back((above, cand, x, y, t >= n_planes));
            }
        }
        if step {
            g += 1;
        }
        settle(&mut pool.uut);
        let t = &mut tr.uut;
        if g >= n_planes * wpp {
            t.stopping.next = true;
            t.planes_total.next = (n_planes as u64).to_bits();
        }
        t.in_valid.next = !fifo.is_empty();
        if let Some(&(above, cand, x, y, fl)) = fifo.front() {
            t.in_above.next = above.to_bits();
            t.in_cand.next = cand.to_bits();
            t.in_x.next = (x as u64).to_bits();
            t.in_y.next = (y as u64).to_bits();
            t.in_flush.next = fl;
        }
        t.record.room.next = queue.len() < 4;
        t.fb_valid.next = pool.uut.valid.val();
        t.fb_bank.next = pool.uut.bank.val();
        t.swept.next = ag.uut.planes_done.val();
        settle(t);
        // Wire the tracker to the aggregator and the pool.
        let a = &mut ag.uut;
        a.tr_plane.next = t.plane.val();
        a.tr_rows.next = t.rows_done.val();
        for q in 0..2 * slots {
            a.sh[q].next = t.sh[q].val();
        }
        pool.uut.pop.next = t.fb_pop.val();
        if t.record.push.val() && t.record.room.val() {
            lost.push_back(t.record.lost.val().to_u64() as usize);
            queue.push_back((
                t.record.kind.val().to_u64(),
                t.record.slot.val().to_u64() as u8,
                t.record.flags.val().to_u64() as u8,
                t.record.ax.val().to_u64() as u16,
                t.record.ay.val().to_u64() as u16,
                t.record.t0.val().to_u64(),
                t.record.t1.val().to_u64(),
                t.record.bank.val().to_u64(),
                t.record.tag.val().to_u64(),
            ));
        }
        if t.in_pop.val() {
            fifo.pop_front();
        }
        let tracker_done = t.done.val();

        // The packetiser's part: read queued banks row by row.
        let a = &mut ag.uut;
        a.rd_req.next = false;
        pool.uut.ret.next = false;
        settle(a);
        if pending_read {
            let (row, counts, m) = reading.as_mut().unwrap();
            for dx in 0..3 {
                counts.push(a.rd_counts[dx].val().to_u64() as u32);
            }
            *m |= a.rd_masked.val() && {
                let ay = queue[0].4 as i64;
                let y = ay - 1 + *row as i64;
                (0..H as i64).contains(&y)
            };
            *row += 1;
            pending_read = false;
        }
        if let Some(&(kind, slot, fl, ax, ay, t0, t1, bank, tag)) = queue.front() {
            match kind {
                record_kind::BLINK => {
                    if a.planes_done.val().to_u64() > tag {
                        if reading.is_none() {
                            reading = Some((0, Vec::new(), false));
                        }
                        let (row, counts, m) = reading.clone().unwrap();
                        if row < 3 {
                            a.rd_req.next = true;
                            a.rd_addr.next = (bank * 3 + row as u64).to_bits();
                            settle(a);
                            pending_read = a.rd_grant.val();
                        } else {
                            // ROI rows outside the sensor read 0.
                            let mut c = counts.clone();
                            for (dy, chunk) in c.chunks_mut(3).enumerate() {
                                let y = ay as i64 - 1 + dy as i64;
                                if !(0..H as i64).contains(&y) {
                                    chunk.fill(0);
                                }
                            }
                            {
                                skips.push(lost.pop_front().unwrap());
                                got.push(Record::Blink(smartagg_model::record::BlinkRecord {
                                    slot,
                                    flags: fl | if m { flags::MASKED } else { 0 },
                                    anchor_x: ax,
                                    anchor_y: ay,
                                    t_cross: t0,
                                    t_drop: t1,
                                    t_s: 0,
                                    t_e: 0,
                                    planes_summed: 0,
                                    roi_size: 3,
                                    counts: c,
                                }));
                            }
                            reading = None;
                            pool.uut.ret.next = true;
                            pool.uut.ret_bank.next = bank.to_bits();
                            returned += 1;
                            queue.pop_front();
                        }
                    }
                }
                _ => {
                    {
                        skips.push(lost.pop_front().unwrap());
                        got.push(match kind {
                            record_kind::START => Record::Start(cfg.stream_start()),
                            record_kind::DROPPED => {
                                Record::Dropped(smartagg_model::record::DroppedRecord {
                                    plane: t0,
                                    count: t1 as u32,
                                    first_x: ax,
                                    first_y: ay,
                                })
                            }
                            _ => Record::End(Default::default()),
                        });
                    }
                    queue.pop_front();
                }
            }
        }
        assert!(!a.overrun.val(), "ROI row ring overrun");
        tr.tick();
        ag.tick();
        pool.tick();
        if tracker_done && queue.is_empty() && reading.is_none() {
            break;
        }
    }

    // Compare with the model: blinks field by field, other records by kind;
    // records lost because the queue was full are skipped (and counted).
    let mut blinks = 0;
    let mut k = 0;
    for (h, skip) in got.iter().zip(&skips) {
        k += skip;
        let m = &want[k];
        match (h, m) {
            (Record::Blink(h), Record::Blink(m)) => {
                let keep = flags::CUT | flags::CONTINUATION | flags::TRUNCATED | flags::MASKED;
                let hb = Blink {
                    slot: h.slot,
                    flags: h.flags,
                    ax: h.anchor_x,
                    ay: h.anchor_y,
                    t_cross: h.t_cross,
                    t_drop: h.t_drop,
                    masked: h.flags & flags::MASKED != 0,
                    counts: h.counts.clone(),
                };
                let mb = Blink {
                    slot: m.slot,
                    flags: m.flags & keep,
                    ax: m.anchor_x,
                    ay: m.anchor_y,
                    t_cross: m.t_cross,
                    t_drop: m.t_drop,
                    masked: m.flags & flags::MASKED != 0,
                    counts: m.counts.clone(),
                };
                assert_eq!(hb, mb, "record {k}");
                blinks += 1;
            }
            (Record::Dropped(h), Record::Dropped(m)) => assert_eq!(h, m, "record {k}"),
            (Record::Start(_), Record::Start(_)) | (Record::End(_), Record::End(_)) => {}
            _ => panic!("record {k}: {h:?} vs {m:?}"),
        }
        k += 1;
    }
    assert_eq!(k, want.len(), "records missing at the end");
    assert_eq!(returned, blinks);
    blinks
}

#[test]
fn rois_equal_model_with_end_trim_cuts_and_stream_end() {
    let b = run(3, 40, 5, Regs::new(3, 4, 2, 2, 6), 0.8);
    assert!(b >= 3, "only {b} blinks");
}

#[test]
fn rois_equal_model_with_many_slots_at_the_design_rate() {
    run(4, 30, 8, Regs::new(4, 7, 3, 1, 9), 0.75);
}

#[test]
fn rois_equal_model_with_the_papers_end_trim() {
    let b = run(5, 40, 6, Regs::new(3, 4, 0, 1, 4), 0.7);
    assert!(b >= 3, "only {b} blinks");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10, ..ProptestConfig::default() })]
    #[test]
    fn rois_equal_model_on_random_streams(
        seed in any::<u64>(),
        n_planes in 0usize..30,
        spots in 0usize..8,
        slots in 2usize..=4,
        n in 1u32..=7,
        trim in 0u32..7,
        l_min in 1u32..=3,
        extra in 0u32..5,
        rate in 0.4f64..=0.8,
    ) {
        let regs = Regs::new(slots, n, trim % n, l_min, n.max(l_min) + extra);
        run(seed, n_planes, spots, regs, rate);
    }
}

/// A blink's opening plane sums the plane N before it, `B_{t_cross − N}`,
/// and a photon of that plane in the top row of its ROI must be counted:
/// the ROI's top row is swept before the tracker has opened the track
/// (its candidate is a row lower) unless the sweep waits for the tracker's
/// row `ay + h + 1`.
#[test]
fn opening_plane_sums_its_first_plane_even_in_the_rois_first_row() {
    let (sx, sy, on) = (8, 4, 6..13);
    let raw: Vec<BitPlane> = (0..20)
        .map(|t| {
            BitPlane::from_fn(W, H, |x, y| {
                (x == sx && y == sy && on.contains(&t)) || (x == sx - 1 && y == sy - 1 && t == 3)
            })
        })
        .collect();
    // T_int = 8: the blink crosses at its second plane, 7 (the photon of
    // plane 3 at the ROI's corner does not make plane 6 cross); N = 4, so
    // plane 7 sums B_3.
    let mut cfg = PipelineConfig::new(W, H, 4, vec![1, 2, 1], 2, 8);
    cfg.roi_size = 3;
    let recs = smartagg_model::pipeline::run(cfg, raw.clone()).unwrap();
    let b: Vec<_> = recs
        .iter()
        .filter_map(|r| match r {
            Record::Blink(b) => Some(b),
            _ => None,
        })
        .collect();
    assert_eq!((b.len(), b[0].t_cross, b[0].t_drop), (1, 7, 15));
    assert_eq!(b[0].counts[0], 1, "B_3 is summed at plane 7");
    let mut rng = common::rng(5);
    for rate in [0.5, 0.75] {
        let regs = Regs {
            threshold: 8,
            ..Regs::new(2, 4, 0, 1, 30)
        };
        assert_eq!(
            run_stream(&mut rng, raw.clone(), HotPixelMask::new(W, H), regs, rate),
            1
        );
    }
}
