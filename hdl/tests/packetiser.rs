//! The packetiser byte for byte against the model's encoder: the frozen
//! vectors of `model/tests/vectors/` (StreamStart, Blinks incl. the sensor
//! corner and the 5-byte varint with an escape code, Dropped, StreamEnd,
//! Overflow, and the short stream with two records dropped on the device),
//! random records of every kind, and random output-FIFO room (records
//! dropped whole, every gap announced by an Overflow record, nothing
//! corrupted).

mod common;

use common::records::{random_blink, random_dropped, random_end};

use proptest::prelude::*;
use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig};
use smartagg_hdl::packetiser::Packetiser;
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::{decode_all, encode_record, Encoder};
use smartagg_model::record::{
    flags, BlinkRecord, DroppedRecord, OverflowRecord, Record, MAX_PLANE,
};
use std::collections::HashMap;

const KERNEL: [u32; 7] = [4, 24, 60, 80, 60, 24, 4];

/// The configuration of the vectors' StreamStart (320×240, N = 108, 7 taps,
/// 32 slots, r_assoc 1), ROI side `r`, 32-bit counts.
fn config(r: usize) -> (PipelineConfig, BackHalfConfig) {
    config_h(r, 240)
}

/// [`config`] with another sensor height. The 3×3 vector is synthetic: its
/// ROI at the corner (319, 239) has counts below the last row, which a real
/// stream never has (ROI rows outside the sensor read 0); a taller sensor
/// keeps that row.
fn config_h(r: usize, height: usize) -> (PipelineConfig, BackHalfConfig) {
    let mut cfg = PipelineConfig::new(320, height, 108, KERNEL.to_vec(), 8, 1_234_567);
    cfg.slots = 32;
    cfg.roi_size = r;
    cfg.r_assoc = 1;
    cfg.l_min = 3;
    cfg.l_max = 10_000;
    let front = GatewareConfig::new(&cfg, 16, 128).unwrap();
    let bh = BackHalfConfig::new(&cfg, front, (1 << 31) - 1).unwrap();
    assert_eq!(bh.roi_count_bits(), 32);
    (cfg, bh)
}

/// One record to feed: the record and whether the FIFO has room for it.
struct Input {
    record: Record,
    /// Records the tracker lost before this one.
    lost: u32,
    room: bool,
}

fn parse_hex(text: &str) -> Vec<u8> {
    let digits: String = text
        .lines()
        .map(|l| l.split('#').next().unwrap())
        .flat_map(|l| l.chars().filter(|c| !c.is_whitespace()))
        .collect();
    (0..digits.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&digits[i..i + 2], 16).unwrap())
        .collect()
}

/// A frozen vector of the current format (`model/tests/vectors/`; the
/// older versions' are in its `v1/` and `v2/`).
fn vector(name: &str) -> Vec<u8> {
    let path = format!(
        "{}/../model/tests/vectors/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    parse_hex(&std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}")))
}

/// Runs the packetiser over `inputs` (StreamStart registers and StreamEnd
/// counters taken from the inputs) and returns the bytes it emitted.
fn run<const RCW: usize, const CAW: usize, const BW: usize, const NW: usize, const PW: usize>(
    bh: &BackHalfConfig,
    seq_init: u32,
    inputs: &[Input],
    grant_rate: f64,
    seed: u64,
) -> Vec<u8> {
    let r = bh.roi_size;
    let h = bh.roi_half() as i64;
    let height = bh.front.height as i64;
    let mut rng = common::rng(seed);
    let mut b = Bench::new(Packetiser::<RCW, CAW, BW, NW, PW>::new(bh).unwrap(), |u| {
        &mut u.clock
    });
    let u = &mut b.uut;
    u.restart.next = true;
    u.seq_init.next = (seq_init as u64).to_bits();
    for i in inputs {
        match &i.record {
            Record::Start(s) => {
                u.settings.n_window.next = (s.n_window as u64).to_bits();
                u.settings.threshold.next = (s.threshold_int as u64).to_bits();
                u.settings.threshold_hold.next = (s.threshold_hold as u64).to_bits();
                u.settings.end_trim.next =
                    (s.end_trim.expect("a version-3 StreamStart") as u64).to_bits();
                u.settings.l_min.next = (s.l_min as u64).to_bits();
                u.settings.l_max.next = (s.l_max as u64).to_bits();
                u.settings.plane_period.next = (s.plane_period_ns as u64).to_bits();
                u.settings.masked_pixels.next = (s.masked_pixels as u64).to_bits();
            }
            Record::End(e) => {
                u.c_planes.next = e.planes.to_bits();
                u.totals.blinks.next = e.blinks.to_bits();
                u.totals.unconfirmed.next = e.unconfirmed.to_bits();
                u.totals.dropped.next = e.dropped_candidates.to_bits();
                u.totals.bridged.next = e.bridged_dips.to_bits();
                u.totals.cuts.next = e.cut_segments.to_bits();
            }
            _ => {}
        }
    }
    b.tick();
    b.uut.restart.next = false;
    // Banks: input k keeps its counts in bank k % 64; rows outside the
    // sensor hold garbage (the packetiser must read them as 0).
    let mut banks: HashMap<u64, (Vec<u32>, Vec<bool>)> = HashMap::new();
    let mut out = Vec::new();
    let mut k = 0;
    let mut pending: Option<u64> = None;
    let mut returned = Vec::new();
    let mut cycles = 0;
    while k < inputs.len() {
        cycles += 1;
        assert!(cycles < 2_000_000, "packetiser stuck at input {k}");
        let inp = &inputs[k];
        let bank = (k % 64) as u64;
        let u = &mut b.uut;
        u.record.valid.next = true;
        u.record.lost.next = (inp.lost as u64).to_bits();
        u.record.ready.next = true;
        u.record.bank.next = bank.to_bits();
        // Without room: less than the smallest record packet (Dropped, 28 bytes).
        u.fifo_free.next = if inp.room {
            60_000u64
        } else {
            rng.gen_range(0..28u64)
        }
        .to_bits();
        match &inp.record {
            Record::Start(_) => u.record.kind.next = 0.into(),
            Record::Blink(bl) => {
                u.record.kind.next = 1.into();
                u.record.slot.next = (bl.slot as u64).to_bits();
                u.record.flags.next = ((bl.flags & !flags::MASKED) as u64).to_bits();
                u.record.ax.next = (bl.anchor_x as u64).to_bits();
                u.record.ay.next = (bl.anchor_y as u64).to_bits();
                u.record.t0.next = bl.t_cross.to_bits();
                u.record.t1.next = bl.t_drop.to_bits();
                u.record.ts.next = (bl.t_s as u64 & MAX_PLANE).to_bits();
                u.record.te.next = (bl.t_e as u64 & MAX_PLANE).to_bits();
                u.record.planes.next = (bl.planes_summed as u64).to_bits();
                banks.entry(bank).or_insert_with(|| {
                    let mut counts = bl.counts.clone();
                    let mut masked = vec![false; r];
                    for dy in 0..r {
                        let y = bl.anchor_y as i64 - h + dy as i64;
                        if !(0..height).contains(&y) {
                            for c in &mut counts[dy * r..(dy + 1) * r] {
                                // Garbage the counters can hold (it must read 0).
                                *c = ((0xDEAD_BEEF_u64 ^ dy as u64) & ((1 << RCW) - 1)) as u32;
                            }
                            masked[dy] = true;
                        }
                    }
                    if bl.flags & flags::MASKED != 0 {
                        // The flag comes from one in-sensor row.
                        let inside: Vec<usize> = (0..r)
                            .filter(|&dy| {
                                (0..height).contains(&(bl.anchor_y as i64 - h + dy as i64))
                            })
                            .collect();
                        masked[inside[inside.len() / 2]] = true;
                    }
                    (counts, masked)
                });
            }
            Record::Dropped(d) => {
                u.record.kind.next = 2.into();
                u.record.t0.next = d.plane.to_bits();
                u.record.t1.next = (d.count as u64).to_bits();
                u.record.ax.next = (d.first_x as u64).to_bits();
                u.record.ay.next = (d.first_y as u64).to_bits();
            }
            Record::End(_) => u.record.kind.next = 3.into(),
            Record::Overflow(_) => unreachable!("the packetiser makes these"),
        }
        // The counter memory: a read granted now answers next clock.
        if let Some(addr) = pending.take() {
            let (counts, masked) = &banks[&(addr / r as u64)];
            let dy = (addr % r as u64) as usize;
            for dx in 0..r {
                u.rd_counts[dx].next = (counts[dy * r + dx] as u64).to_bits();
            }
            u.rd_masked.next = masked[dy];
        }
        u.rd_grant.next = false;
        settle(u);
        if u.rd_req.val() && rng.gen_bool(grant_rate) {
            u.rd_grant.next = true;
            settle(u);
            pending = Some(u.rd_addr.val().to_u64());
        }
        if u.out_valid.val() {
            out.push(u.out_byte.val().to_u64() as u8);
        }
        if u.fb_ret.val() {
            returned.push(u.fb_ret_bank.val().to_u64());
        }
        if u.r_pop.val() {
            k += 1;
        }
        b.tick();
    }
    let blinks = inputs
        .iter()
        .filter(|i| matches!(i.record, Record::Blink(_)))
        .count();
    assert_eq!(returned.len(), blinks, "every Blink's bank comes back");
    out
}

fn inputs(records: Vec<Record>) -> Vec<Input> {
    records
        .into_iter()
        .map(|record| Input {
            record,
            lost: 0,
            room: true,
        })
        .collect()
}

fn decoded(bytes: &[u8]) -> Vec<Record> {
    decode_all(bytes)
        .packets
        .into_iter()
        .map(|p| p.record)
        .collect()
}

#[test]
fn frozen_vectors_byte_for_byte() {
    let (_, bh9) = config(9);
    let (_, bh3) = config_h(3, 256);
    for (file, seq) in [
        ("stream_start.hex", 0),
        ("blink.hex", 1),
        ("blink_edge.hex", 2),
        ("dropped.hex", 4),
        ("stream_end.hex", 5),
    ] {
        let want = vector(file);
        let got = run::<32, 10, 7, 8, 520>(&bh9, seq, &inputs(decoded(&want)), 0.7, seq as u64);
        assert_eq!(got, want, "{file}");
    }
    let want = vector("blink_large.hex");
    let got = run::<32, 9, 7, 8, 520>(&bh3, 3, &inputs(decoded(&want)), 1.0, 3);
    assert_eq!(got, want, "blink_large.hex");
}

#[test]
fn overflow_vector_after_seven_records_dropped_on_the_device() {
    let (_, bh) = config(9);
    let d = Record::Dropped(DroppedRecord {
        plane: 9,
        count: 1,
        first_x: 3,
        first_y: 4,
    });
    let mut ins: Vec<Input> = (0..7)
        .map(|_| Input {
            record: d.clone(),
            lost: 0,
            room: false,
        })
        .collect();
    ins.push(Input {
        record: d.clone(),
        lost: 0,
        room: true,
    });
    let got = run::<32, 10, 7, 8, 520>(&bh, 42, &ins, 1.0, 9);
    let want = vector("overflow.hex");
    assert_eq!(&got[..want.len()], &want[..]);
    let mut tail = Vec::new();
    encode_record(&d, 49, &mut tail).unwrap();
    assert_eq!(&got[want.len()..], &tail[..]);
}

#[test]
fn stream_vector_with_two_records_dropped() {
    let (_, bh) = config(9);
    let want = vector("stream.hex");
    let recs: Vec<Record> = decoded(&want);
    // The Overflow record of the vector stands for records 3 and 4, which the
    // FIFO has no room for here.
    let mut ins = Vec::new();
    for r in recs {
        match r {
            Record::Overflow(o) => {
                for _ in 0..o.count {
                    ins.push(Input {
                        record: Record::Dropped(DroppedRecord {
                            plane: 1,
                            count: 2,
                            first_x: 3,
                            first_y: 4,
                        }),
                        lost: 0,
                        room: false,
                    });
                }
            }
            record => ins.push(Input {
                record,
                lost: 0,
                room: true,
            }),
        }
    }
    assert_eq!(run::<32, 10, 7, 8, 520>(&bh, 0, &ins, 0.5, 11), want);
}

fn random_records(seed: u64, n: usize) -> Vec<Record> {
    let (mut cfg, _) = config(9);
    // END_TRIM in the StreamStart (≤ N − 1 = 107).
    cfg.end_trim = 77;
    let mut rng = common::rng(seed);
    let mut recs = vec![Record::Start(cfg.stream_start())];
    for _ in 0..n {
        recs.push(if rng.gen_bool(0.7) {
            Record::Blink(random_blink(&mut rng, 9))
        } else {
            Record::Dropped(random_dropped(&mut rng))
        });
    }
    recs.push(Record::End(random_end(&mut rng)));
    recs
}

#[test]
fn random_records_equal_the_model_encoder() {
    let (_, bh) = config(9);
    let recs = random_records(21, 12);
    let mut want = Vec::new();
    let mut enc = Encoder::new();
    for r in &recs {
        enc.push(r, &mut want).unwrap();
    }
    assert_eq!(
        run::<32, 10, 7, 8, 520>(&bh, 0, &inputs(recs), 0.6, 21),
        want
    );
}

#[test]
fn empty_segment_reads_its_bank_like_any_other() {
    // A first segment cut before plane N summed no plane: its bank holds
    // zero counts and its ROI's mask flags (the aggregator swept it in its
    // opening plane), read like any other.
    let (_, bh) = config(9);
    let bl = BlinkRecord {
        slot: 4,
        flags: flags::CUT | flags::PREROLL_CLIPPED | flags::MASKED,
        anchor_x: 100,
        anchor_y: 50,
        t_cross: 0,
        t_drop: 107,
        t_s: -54,
        t_e: 107,
        planes_summed: 0,
        roi_size: 9,
        counts: vec![0; 81],
    };
    let mut want = Vec::new();
    encode_record(&Record::Blink(bl.clone()), 0, &mut want).unwrap();
    assert_eq!(
        run::<32, 10, 7, 8, 520>(&bh, 0, &inputs(vec![Record::Blink(bl)]), 1.0, 5),
        want
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    /// With random FIFO room and records lost before the queue, the stream
    /// decodes without corruption or transport loss, every record that
    /// arrives equals the model's record of its sequence number, and the
    /// Overflow records account for exactly the others.
    #[test]
    fn drops_are_whole_records_and_every_gap_is_announced(seed in any::<u64>()) {
        let (_, bh) = config(9);
        let recs = random_records(seed, 10);
        let mut rng = common::rng(seed ^ 5);
        let n = recs.len();
        let ins: Vec<Input> = recs
            .iter()
            .enumerate()
            .map(|(i, r)| Input {
                record: r.clone(),
                lost: 0,
                room: i == 0 || i == n - 1 || rng.gen_bool(0.6),
            })
            .collect();
        // Records lost before the queue: remove some, tell the next one.
        let mut fed = Vec::new();
        let mut lost = 0;
        for (i, mut inp) in ins.into_iter().enumerate() {
            if i > 0 && i < n - 1 && rng.gen_bool(0.15) {
                lost += 1;
                continue;
            }
            inp.lost = lost;
            lost = 0;
            fed.push(inp);
        }
        let bytes = run::<32, 10, 7, 8, 520>(&bh, 0, &fed, 0.8, seed);
        let d = decode_all(&bytes);
        prop_assert!(!d.stats.any_loss() || d.stats.lost_on_device > 0, "{}", d.stats);
        prop_assert_eq!(d.stats.crc_errors + d.stats.malformed + d.stats.bytes_skipped + d.stats.lost_in_transport, 0);
        let mut delivered = 0u64;
        for p in &d.packets {
            match &p.record {
                Record::Overflow(OverflowRecord { .. }) => {}
                r => {
                    prop_assert_eq!(r, &recs[p.seq as usize]);
                    delivered += 1;
                }
            }
        }
        prop_assert_eq!(delivered + d.stats.lost_on_device, n as u64);
        prop_assert!(matches!(d.packets.last().map(|p| &p.record), Some(Record::End(_))));
    }
}

#[test]
fn three_by_three_rois_too() {
    let (_, bh) = config(3);
    let mut rng = common::rng(77);
    let recs: Vec<Record> = (0..8)
        .map(|_| Record::Blink(random_blink(&mut rng, 3)))
        .collect();
    let mut want = Vec::new();
    let mut enc = Encoder::starting_at(1);
    for r in &recs {
        enc.push(r, &mut want).unwrap();
    }
    assert_eq!(
        run::<32, 9, 7, 8, 520>(&bh, 1, &inputs(recs), 0.9, 77),
        want
    );
}

/// [`config`] with the ROI counters of a real design: L_max ≤ 255 and
/// N_max = 128 make them 9 bits wide, so the packetiser keeps length
/// accumulators for k = 0 ..= 9 only.
fn config_narrow(r: usize) -> (PipelineConfig, BackHalfConfig) {
    let mut cfg = PipelineConfig::new(320, 240, 108, KERNEL.to_vec(), 8, 1_234_567);
    cfg.slots = 32;
    cfg.roi_size = r;
    cfg.r_assoc = 1;
    cfg.l_min = 3;
    cfg.l_max = 200;
    let front = GatewareConfig::new(&cfg, 16, 128).unwrap();
    let bh = BackHalfConfig::new(&cfg, front, 255).unwrap();
    assert_eq!(bh.roi_count_bits(), 9);
    (cfg, bh)
}

#[test]
fn narrow_counters_keep_accumulators_up_to_their_width_only() {
    use smartagg_hdl::packetiser::rice_candidates;
    use smartagg_model::rice;
    assert_eq!(rice_candidates(9), 10);
    assert_eq!(rice_candidates(32), 32);
    let (_, bh) = config_narrow(9);
    let mut rng = common::rng(91);
    let top = (1u32 << bh.roi_count_bits()) - 1;
    let mut ks = std::collections::BTreeSet::new();
    let recs: Vec<Record> = (0..24)
        .map(|i| {
            let mut b = random_blink(&mut rng, 9);
            for (j, c) in b.counts.iter_mut().enumerate() {
                let (x, y) = (
                    b.anchor_x as i64 - 4 + (j % 9) as i64,
                    b.anchor_y as i64 - 4 + (j / 9) as i64,
                );
                // Every count a 9-bit counter can hold, the extremes included:
                // all at the top, half at the top and half at 0, uniform;
                // pixels outside the sensor stay 0.
                if (0..320).contains(&x) && (0..240).contains(&y) {
                    *c = match i % 4 {
                        0 => top,
                        1 => {
                            if rng.gen_bool(0.5) {
                                top
                            } else {
                                0
                            }
                        }
                        _ => *c % (top + 1),
                    };
                }
            }
            ks.insert(rice::choose(&b.counts).1);
            Record::Blink(b)
        })
        .collect();
    // The model's choices span small and large k (the largest possible is
    // below the counter width: the base makes one offset 0).
    assert!(ks.contains(&0) && ks.iter().any(|&k| k >= 7), "{ks:?}");
    assert!(ks.iter().all(|&k| (k as usize) < rice_candidates(9)));
    let mut want = Vec::new();
    let mut enc = Encoder::starting_at(1);
    for r in &recs {
        enc.push(r, &mut want).unwrap();
    }
    assert_eq!(
        run::<9, 10, 7, 8, 520>(&bh, 1, &inputs(recs), 0.8, 91),
        want
    );
}

/// The finisher's derived Blink fields (planes summed, t_s, t_e, EDGE and
/// PREROLL_CLIPPED) against the model's segments on random descriptors of
/// every kind: dropped, cut and truncated first segments (`t_cross` below
/// and above N) and continuations (the one the stream end leaves after a
/// cut at the last plane too), every N and END_TRIM.
#[test]
fn record_finisher_equals_the_models_blink_fields() {
    use smartagg_hdl::record_finisher::RecordFinisher;
    use smartagg_model::blink_tracker::Segment;
    let (_, bh) = config(9);
    let mut f = RecordFinisher::<8>::new(&bh).unwrap();
    f.connect_all();
    check_all(&f).unwrap();
    let mut rng = common::rng(404);
    let (w, h) = (bh.front.width as i64, bh.front.height as i64);
    let half = bh.roi_half() as i64;
    let mut kinds = [0usize; 6];
    for i in 0..20_000 {
        let n = rng.gen_range(1..=108u32);
        let c = rng.gen_range(0..n);
        let l_max = n + rng.gen_range(0..20);
        let kind = i % 6;
        let n64 = n as u64;
        // 0 dropped first, 1 cut first, 2 truncated first, 3 dropped
        // continuation, 4 cut continuation, 5 truncated continuation.
        let continuation = kind >= 3;
        let t_cross = if continuation {
            rng.gen_range(n64..n64 + 300)
        } else if rng.gen_bool(0.5) {
            rng.gen_range(0..n64)
        } else {
            rng.gen_range(0..n64 + 300)
        };
        let (t_drop, end) = match kind % 3 {
            0 => (
                t_cross + rng.gen_range(if continuation { 0 } else { 1 }..=l_max as u64),
                0,
            ),
            1 => (t_cross + l_max as u64 - 1 + rng.gen_range(0..2), flags::CUT),
            _ => {
                // A continuation the stream end truncates at once.
                let d = if continuation && rng.gen_bool(0.3) {
                    t_cross - 1
                } else {
                    t_cross + rng.gen_range(0..=l_max as u64)
                };
                (d, flags::TRUNCATED)
            }
        };
        let seg = Segment {
            anchor_x: rng.gen_range(0..w as u16),
            anchor_y: rng.gen_range(0..h as u16),
            t_cross,
            continuation,
            live: false,
            in_dip: false,
            dip_plane: 0,
            t_drop: Some(t_drop),
            end_flags: end,
            confirmed: true,
        };
        let planes = seg.planes_summed(n, c).unwrap();
        if planes == 0 {
            kinds[kind] += 1;
        }
        let (ax, ay) = (seg.anchor_x as i64, seg.anchor_y as i64);
        let edge = ax < half || ay < half || ax + half >= w || ay + half >= h;
        let hn = (n / 2) as i64;
        let t_s = if continuation {
            t_cross as i64
        } else {
            t_cross as i64 - hn
        };
        let t_e = if end != 0 {
            t_drop as i64
        } else {
            t_drop as i64 - hn
        };
        f.n_window.next = (n as u64).to_bits();
        f.end_trim.next = (c as u64).to_bits();
        f.kind.next = 1.into();
        f.flags.next = ((seg.flags(n) & !flags::PREROLL_CLIPPED) as u64).to_bits();
        f.ax.next = (seg.anchor_x as u64).to_bits();
        f.ay.next = (seg.anchor_y as u64).to_bits();
        f.t0.next = t_cross.to_bits();
        f.t1.next = t_drop.to_bits();
        f.tag.next = 0.into();
        f.planes_done.next = 0.into();
        settle(&mut f);
        let what = format!("{seg:?}, N {n}, END_TRIM {c}");
        assert_eq!(f.o_planes.val().to_u64(), planes, "{what}");
        assert_eq!(
            f.o_flags.val().to_u64() as u8,
            seg.flags(n) | if edge { flags::EDGE } else { 0 },
            "{what}"
        );
        assert_eq!(f.o_ts.val().to_u64(), t_s as u64 & MAX_PLANE, "{what}");
        assert_eq!(f.o_te.val().to_u64(), t_e as u64 & MAX_PLANE, "{what}");
    }
    // Empty segments of the kinds that have them: first segments dropped
    // before END_TRIM or cut before N.
    assert!(kinds[0] > 0 && kinds[1] > 0, "{kinds:?}");
    assert_eq!(kinds[2] + kinds[3] + kinds[4] + kinds[5], 0, "{kinds:?}");
}
