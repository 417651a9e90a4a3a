//! The whole gateware pipeline against the golden model: the bytes of
//! `model::pipeline::run` + `model::packetiser::encode_stream` on a small
//! field (16×6, P = 4, k = 5, M = 4, 3×3 ROIs), with hot pixels, random
//! source stalls within the design's duty cycle, and the stream end with its
//! drain planes; hysteresis (T_hold below T_int); END_TRIM from 0 (the
//! paper's) to N − 1; also the register check at START (T_hold = 0 or
//! above T_int, END_TRIM ≥ N included) and an empty stream.

mod common;

use proptest::prelude::*;
use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::bundles::RuntimeRegisters;
use smartagg_hdl::designs::{TestPipeline, TestPipelineDdr};
use smartagg_hdl::pipeline::test_back_config;
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_hdl::testbench::mcb_model::{mcb_to_port, port_to_mcb, McbModel};
use smartagg_model::config::PipelineConfig;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::packetiser::encode_stream;
use smartagg_model::pipeline::run as model_run;
use smartagg_model::plane::BitPlane;
use smartagg_model::record::Record;

const W: usize = 16;
const H: usize = 6;
const P: usize = 4;

struct Stream {
    n: u32,
    threshold: u32,
    /// T_hold; `None`: T_int.
    threshold_hold: Option<u32>,
    end_trim: u32,
    l_min: u32,
    l_max: u32,
    planes: Vec<BitPlane>,
    hot: Vec<(usize, usize)>,
    mask_enable: bool,
}

fn model_config(s: &Stream) -> PipelineConfig {
    let mut cfg = PipelineConfig::new(W, H, s.n, vec![1, 4, 6, 4, 1], 4, s.threshold);
    cfg.threshold_hold = hold(s);
    cfg.end_trim = s.end_trim;
    cfg.slots = 4;
    cfg.roi_size = 3;
    cfg.r_assoc = 1;
    cfg.l_min = s.l_min;
    cfg.l_max = s.l_max;
    cfg.plane_period_ns = 100_000;
    if s.mask_enable {
        cfg.hot_mask = Some(HotPixelMask::from_pixels(W, H, &s.hot).0);
    }
    cfg
}

/// The T_hold register of a stream.
fn hold(s: &Stream) -> u32 {
    s.threshold_hold.unwrap_or(s.threshold)
}

/// T_hold at `pct` percent of the way from 1 to T_int (at most T_int).
fn hold_at(s: &Stream, pct: u32) -> Option<u32> {
    Some(1 + (s.threshold - 1) * pct.min(100) / 100)
}

/// The stream's runtime registers as the host writes them.
fn write_registers(regs: &mut RuntimeRegisters, s: &Stream, masked: u64) {
    regs.n.next = (s.n as u64).to_bits();
    regs.threshold.next = (s.threshold as u64).to_bits();
    regs.threshold_hold.next = (hold(s) as u64).to_bits();
    regs.end_trim.next = (s.end_trim as u64).to_bits();
    regs.l_min.next = (s.l_min as u64).to_bits();
    regs.l_max.next = (s.l_max as u64).to_bits();
    regs.period.next = 100_000u64.to_bits();
    regs.masked.next = masked.to_bits();
    regs.mask_enable.next = s.mask_enable;
}

fn start(b: &mut Bench<TestPipeline>, s: &Stream, mask_count: u64) {
    let u = &mut b.uut;
    write_registers(&mut u.regs, s, mask_count);
    u.start.next = true;
    b.tick();
    b.uut.start.next = false;
}

/// Runs a stream through the gateware; returns the bytes it put out and the
/// number of clocks.
fn gateware(s: &Stream, stall_percent: u64, seed: u64) -> (Vec<u8>, u64) {
    gateware_with(s, stall_percent, seed, false)
}

/// [`gateware`]; with `scramble`, once the stream runs the host rewrites
/// every register and tries to load a different mask on every clock.
fn gateware_with(s: &Stream, stall_percent: u64, seed: u64, scramble: bool) -> (Vec<u8>, u64) {
    gateware_paced(s, stall_percent, seed, scramble, Pace::Free).expect("internal buffer overflow")
}

/// How the source paces its words.
#[derive(Clone, Copy, PartialEq)]
enum Pace {
    /// Whenever the stream accepts words (a sensor; `stall_percent` sets the duty cycle).
    Free,
    /// Only while `ready` (the replay): the back half's room holds it back.
    Ready,
}

/// [`gateware_with`] with the source's pacing; `Err` if FAULT rose.
fn gateware_paced(
    s: &Stream,
    stall_percent: u64,
    seed: u64,
    scramble: bool,
    pace: Pace,
) -> Result<(Vec<u8>, u64), String> {
    let cfg = test_back_config(4, 3, 1).unwrap();
    let mut b = Bench::new(TestPipeline::new(&cfg).unwrap(), |u| &mut u.clock);
    // Load the mask (it is kept across streams; loaded while stopped).
    let (mask, _) = HotPixelMask::from_pixels(W, H, &s.hot);
    let mask_plane = BitPlane::from_fn(W, H, |x, y| mask.is_masked(x as i64, y as i64));
    let wpp = W * H / P;
    for idx in 0..wpp {
        b.uut.load.next = true;
        b.uut.load_address.next = (idx as u64).to_bits();
        b.uut.load_data.next = mask_plane.stream_word(P, idx).to_bits();
        b.tick();
    }
    b.uut.load.next = false;
    start(&mut b, s, mask.count() as u64);
    assert!(!b.uut.config_error.val());
    // The source starts sending once the stream runs (words before that,
    // like a sensor's, are ignored until the next plane's start).
    while !b.uut.running.val() {
        b.tick();
    }
    let mut stalls = Stalls::new(seed, stall_percent);
    let total = s.planes.len() * wpp;
    let mut sent = 0;
    let mut out = Vec::new();
    let start_cycle = b.cycles;
    loop {
        let u = &mut b.uut;
        settle(u);
        let offer = sent < total && stalls.offer() && (pace == Pace::Free || u.ready.val());
        u.in_valid.next = offer;
        if offer {
            let (t, idx) = (sent / wpp, sent % wpp);
            u.in_sop.next = idx == 0;
            u.in_live.next = s.planes[t].stream_word(P, idx).to_bits();
            sent += 1;
        }
        u.stop.next = sent == total;
        u.out_pop.next = true;
        if scramble {
            let c = b.cycles;
            u.regs.n.next = (c % 9).to_bits();
            u.regs.threshold.next = (c % 5).to_bits();
            u.regs.threshold_hold.next = (c % 7).to_bits();
            u.regs.end_trim.next = (c % 4).to_bits();
            u.regs.l_min.next = (1 + c % 3).to_bits();
            u.regs.l_max.next = (c % 70).to_bits();
            u.regs.mask_enable.next = c % 2 == 0;
            u.regs.masked.next = c.to_bits();
            u.load.next = true;
            u.load_address.next = ((c as usize) % wpp).to_bits();
            u.load_data.next = (c.wrapping_mul(0x9e37_79b9) & 0xf).to_bits();
        }
        settle(u);
        if u.out_valid.val() {
            out.push(u.out_data.val().to_u64() as u8);
        }
        if u.fault.val() {
            return Err(format!("FAULT at clock {}", b.cycles - start_cycle));
        }
        let ended = u.ended.val();
        b.tick();
        if ended && !b.uut.out_valid.val() {
            break;
        }
        assert!(b.cycles - start_cycle < 400_000, "stream did not end");
    }
    assert!(!b.uut.framing_error.val());
    Ok((out, b.cycles - start_cycle))
}

/// The same with the DDR2 delay line and the behavioural MCB model (command
/// latency, refresh gaps, garbage in unwritten memory).
fn gateware_ddr(s: &Stream, stall_percent: u64, seed: u64) -> Vec<u8> {
    let cfg = test_back_config(4, 3, 1).unwrap();
    let mut b = Bench::new(TestPipelineDdr::new(&cfg).unwrap(), |u| &mut u.clock);
    // Planes of this field are three DDR2 words: short latency and refresh
    // gaps, in proportion (the SPCImager's planes are 2400 words).
    let mut mcb = Bench::new(McbModel::new(4, 300, 6, 30, seed), |u| &mut u.clock);
    let (mask, _) = HotPixelMask::from_pixels(W, H, &s.hot);
    let mask_plane = BitPlane::from_fn(W, H, |x, y| mask.is_masked(x as i64, y as i64));
    let wpp = W * H / P;
    let step = |b: &mut Bench<TestPipelineDdr>, mcb: &mut Bench<McbModel>| {
        let (u, m) = (&mut b.uut, &mut mcb.uut);
        mcb_to_port(&m.mcb, &mut u.mcb);
        settle(u);
        port_to_mcb(&u.mcb, &mut m.mcb);
        settle(m);
    };
    for idx in 0..wpp {
        b.uut.load.next = true;
        b.uut.load_address.next = (idx as u64).to_bits();
        b.uut.load_data.next = mask_plane.stream_word(P, idx).to_bits();
        step(&mut b, &mut mcb);
        b.tick();
        mcb.tick();
    }
    b.uut.load.next = false;
    // START waits for the memory's calibration.
    while !b.uut.mem_ready.val() {
        step(&mut b, &mut mcb);
        b.tick();
        mcb.tick();
    }
    let u = &mut b.uut;
    write_registers(&mut u.regs, s, mask.count() as u64);
    u.start.next = true;
    step(&mut b, &mut mcb);
    b.tick();
    mcb.tick();
    b.uut.start.next = false;
    while !b.uut.running.val() {
        step(&mut b, &mut mcb);
        b.tick();
        mcb.tick();
    }
    let mut stalls = Stalls::new(seed, stall_percent);
    let total = s.planes.len() * wpp;
    let mut sent = 0;
    let mut out = Vec::new();
    let mut cycles = 0;
    loop {
        let u = &mut b.uut;
        let offer = sent < total && stalls.offer();
        u.in_valid.next = offer;
        if offer {
            let (t, idx) = (sent / wpp, sent % wpp);
            u.in_sop.next = idx == 0;
            u.in_live.next = s.planes[t].stream_word(P, idx).to_bits();
            sent += 1;
        }
        u.stop.next = sent == total;
        u.out_pop.next = true;
        step(&mut b, &mut mcb);
        let u = &b.uut;
        if u.out_valid.val() {
            out.push(u.out_data.val().to_u64() as u8);
        }
        assert!(!u.fault.val(), "internal overflow or DDR2 underrun");
        assert!(!mcb.uut.error.val(), "MCB protocol error");
        let ended = u.ended.val();
        b.tick();
        mcb.tick();
        cycles += 1;
        if ended && !b.uut.out_valid.val() {
            break;
        }
        assert!(cycles < 400_000, "stream did not end");
    }
    out
}

/// Whether `bytes` are the model's records with some missing, every gap
/// covered by an Overflow record, nothing corrupted.
fn lossy_but_exact(bytes: &[u8], records: &[Record]) -> bool {
    let d = smartagg_model::packet::decode_all(bytes);
    let s = &d.stats;
    if s.crc_errors + s.malformed + s.bytes_skipped + s.lost_in_transport + s.truncated_tail_bytes
        > 0
        || s.lost_on_device == 0
    {
        return false;
    }
    let mut delivered = 0;
    for p in &d.packets {
        match &p.record {
            Record::Overflow(_) => {}
            r => {
                if records.get(p.seq as usize) != Some(r) {
                    return false;
                }
                delivered += 1;
            }
        }
    }
    delivered + s.lost_on_device == records.len() as u64
        && matches!(d.packets.last().map(|p| &p.record), Some(Record::End(_)))
}

fn stream(seed: u64, planes: usize, n: u32, l_min: u32, extra: u32, mask_enable: bool) -> Stream {
    let mut rng = common::rng(seed);
    let planes = common::random_planes(&mut rng, W, H, planes, 0.08);
    let hot: Vec<(usize, usize)> = (0..2)
        .map(|_| (rng.gen_range(0..W), rng.gen_range(0..H)))
        .collect();
    let mut s = Stream {
        n,
        threshold: 1,
        threshold_hold: None,
        // The field design's END_TRIM.
        end_trim: n / 2,
        l_min,
        l_max: n.max(l_min) + extra,
        planes,
        hot,
        mask_enable,
    };
    // A threshold that some pixels cross: the 85th percentile of H.
    s.threshold = percentile_threshold(&s, 85);
    s
}

/// The stream with new random planes (as many) of pixel density `density`.
fn restream(mut s: Stream, seed: u64, density: f64) -> Stream {
    let mut rng = common::rng(seed);
    s.planes = common::random_planes(&mut rng, W, H, s.planes.len(), density);
    s
}

/// The `pct`th percentile of the filtered values H of a stream (at least 1).
fn percentile_threshold(s: &Stream, pct: usize) -> u32 {
    let mut p = smartagg_model::pipeline::Pipeline::new(model_config(s)).unwrap();
    let mut all = Vec::new();
    for pl in &s.planes {
        p.push_plane(pl).unwrap();
        all.extend_from_slice(p.filtered());
    }
    all.sort_unstable();
    all.get(all.len() * pct / 100).copied().unwrap_or(1).max(1)
}

fn check(s: &Stream, stall_percent: u64, seed: u64) -> Vec<Record> {
    check_with(s, stall_percent, seed, false, false)
}

fn check_with(
    s: &Stream,
    stall_percent: u64,
    seed: u64,
    ddr: bool,
    allow_loss: bool,
) -> Vec<Record> {
    let records = model_run(model_config(s), s.planes.clone()).unwrap();
    let want = encode_stream(&records).unwrap();
    let got = if ddr {
        gateware_ddr(s, stall_percent, seed)
    } else {
        gateware(s, stall_percent, seed).0
    };
    if allow_loss && got != want && lossy_but_exact(&got, &records) {
        // Records lost for want of room (a Blink every plane, with L_max = N
        // = 1, outruns the packetiser on a 24-word plane): still the model's
        // stream with every gap announced.
        return records;
    }
    if got != want {
        let d = smartagg_model::packet::decode_all(&got);
        let g: Vec<Record> = d.packets.into_iter().map(|p| p.record).collect();
        let first = got.iter().zip(&want).position(|(a, b)| a != b);
        panic!(
            "bytes differ (lengths {} vs {}, first difference at {first:?})\ngot  {got:02x?}\nwant {want:02x?}\ngateware: {g:#?}\nmodel: {records:#?}",
            got.len(),
            want.len()
        );
    }
    records
}

#[test]
fn pipeline_bytes_equal_the_model() {
    let s = stream(5, 24, 4, 2, 4, true);
    let recs = model_run(model_config(&s), s.planes.clone()).unwrap();
    let (got, _) = gateware(&s, 30, 1);
    assert_eq!(
        got,
        encode_stream(&recs).unwrap(),
        "no record lost, byte for byte"
    );
    let blinks = recs
        .iter()
        .filter(|r| matches!(r, Record::Blink(_)))
        .count();
    assert!(blinks >= 2, "the stream exercises blinks: {recs:?}");
    let blinks = recs
        .iter()
        .filter(|r| matches!(r, Record::Blink(_)))
        .count();
    assert!(blinks >= 2, "the stream exercises blinks: {recs:?}");
}

/// Hysteresis: T_hold well below T_int keeps tracks on longer than the
/// one-threshold rule; the gateware follows the model byte for byte.
#[test]
fn pipeline_with_hysteresis_bytes_equal_the_model() {
    let one = stream(5, 24, 4, 2, 4, true);
    let mut two = stream(5, 24, 4, 2, 4, true);
    two.threshold_hold = Some(percentile_threshold(&two, 50).min(two.threshold));
    assert!(hold(&two) < two.threshold);
    let recs = check(&two, 30, 1);
    assert!(
        recs.iter().any(|r| matches!(r, Record::Blink(_))),
        "{recs:?}"
    );
    let one_recs = model_run(model_config(&one), one.planes.clone()).unwrap();
    assert_ne!(recs, one_recs, "T_hold changes the records");
    // The StreamStart carries T_hold.
    match &recs[0] {
        Record::Start(st) => assert_eq!(st.threshold_hold, hold(&two)),
        r => panic!("{r:?}"),
    }
}

/// END_TRIM 0 (the paper's) and N − 1 on a stream with cuts (L_max = N)
/// that stops while tracks are live: the gateware follows the model byte
/// for byte, and the trim changes the planes the Blinks sum.
#[test]
fn pipeline_with_end_trim_cuts_and_stream_end_bytes_equal_the_model() {
    let base = stream(14, 30, 4, 1, 0, true);
    assert_eq!(base.l_max, base.n);
    let mut all = Vec::new();
    for end_trim in [0, 3] {
        let s = Stream {
            end_trim,
            planes: base.planes.clone(),
            hot: base.hot.clone(),
            ..base
        };
        let recs = check(&s, 50, 5);
        let blinks: Vec<_> = recs
            .iter()
            .filter_map(|r| match r {
                Record::Blink(b) => Some(b.clone()),
                _ => None,
            })
            .collect();
        let any = |f: u8| blinks.iter().any(|b| b.flags & f != 0);
        use smartagg_model::record::flags;
        assert!(
            any(flags::CUT) && any(flags::TRUNCATED) && any(flags::CONTINUATION),
            "END_TRIM {end_trim}: {blinks:#?}"
        );
        assert!(
            blinks
                .iter()
                .any(|b| b.flags & (flags::CUT | flags::TRUNCATED) == 0),
            "END_TRIM {end_trim}: no dropped segment: {blinks:#?}"
        );
        match &recs[0] {
            Record::Start(st) => assert_eq!(st.end_trim, Some(end_trim)),
            r => panic!("{r:?}"),
        }
        all.push(blinks);
    }
    assert_ne!(all[0], all[1], "END_TRIM changes the Blinks");
}

#[test]
fn pipeline_with_ddr2_delay_line_bytes_equal_the_model() {
    let s = stream(6, 20, 3, 2, 3, true);
    let recs = check_with(&s, 30, 3, true, false);
    assert!(
        recs.iter().any(|r| matches!(r, Record::Blink(_))),
        "{recs:?}"
    );
    let mut s = stream(6, 20, 3, 2, 3, true);
    s.threshold_hold = hold_at(&s, 30);
    check_with(&s, 30, 3, true, false);
    let s = stream(7, 14, 7, 1, 2, false);
    check_with(&s, 40, 4, true, false);
}

#[test]
fn registers_and_mask_are_latched_at_stream_start() {
    let s = stream(5, 24, 4, 2, 4, true);
    let recs = model_run(model_config(&s), s.planes.clone()).unwrap();
    let want = encode_stream(&recs).unwrap();
    // The same stream, with the registers and the mask rewritten while it runs.
    let (got, _) = gateware_with(&s, 30, 1, true);
    assert_eq!(got, want, "writes after START change nothing");
    let blinks = recs
        .iter()
        .filter(|r| matches!(r, Record::Blink(_)))
        .count();
    assert!(blinks >= 2, "the stream exercises blinks: {recs:?}");
}

#[test]
fn empty_stream_is_start_and_end() {
    let s = Stream {
        n: 3,
        threshold: 5,
        threshold_hold: None,
        end_trim: 1,
        l_min: 1,
        l_max: 10,
        planes: Vec::new(),
        hot: vec![(1, 1)],
        mask_enable: false,
    };
    let recs = check(&s, 0, 2);
    assert_eq!(recs.len(), 2);
}

#[test]
fn bad_registers_refuse_to_start() {
    let cfg = test_back_config(4, 3, 1).unwrap();
    let mut b = Bench::new(TestPipeline::new(&cfg).unwrap(), |u| &mut u.clock);
    let good = Stream {
        n: 3,
        threshold: 5,
        threshold_hold: Some(2),
        end_trim: 1,
        l_min: 2,
        l_max: 10,
        planes: Vec::new(),
        hot: Vec::new(),
        mask_enable: false,
    };
    type Bad = fn(&mut Stream);
    let bad: [Bad; 12] = [
        |s| s.n = 0,
        |s| s.n = 8, // above N_max = 7
        |s| s.threshold = 0,
        |s| s.threshold_hold = Some(0),
        |s| s.threshold_hold = Some(6), // above T_int = 5
        |s| s.threshold_hold = Some(u32::MAX),
        |s| s.end_trim = 3,       // N = 3
        |s| s.end_trim = 1 << 16, // 0 in its low bits
        |s| s.end_trim = u32::MAX,
        |s| s.l_min = 0,
        |s| s.l_max = 2,  // below N
        |s| s.l_max = 65, // above the generated L_max,max = 64
    ];
    for f in bad {
        let mut s = Stream {
            planes: Vec::new(),
            hot: Vec::new(),
            ..good
        };
        f(&mut s);
        start(&mut b, &s, 0);
        // The check decides on the clock after START.
        assert!(!b.uut.running.val());
        b.tick();
        assert!(b.uut.config_error.val() && !b.uut.running.val());
    }
    start(&mut b, &good, 0);
    b.tick();
    b.tick();
    assert!(!b.uut.config_error.val() && b.uut.running.val());
    // T_hold = T_int (the one-threshold rule) and T_hold = 1, END_TRIM 0
    // and N − 1 are accepted too.
    for (t_hold, end_trim) in [(5, 1), (1, 1), (2, 0), (2, 2)] {
        let mut b = Bench::new(TestPipeline::new(&cfg).unwrap(), |u| &mut u.clock);
        let s = Stream {
            planes: Vec::new(),
            hot: Vec::new(),
            threshold_hold: Some(t_hold),
            end_trim,
            ..good
        };
        start(&mut b, &s, 0);
        b.tick();
        b.tick();
        assert!(
            !b.uut.config_error.val() && b.uut.running.val(),
            "T_hold {t_hold}, END_TRIM {end_trim}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4, ..ProptestConfig::default() })]
    #[test]
    fn pipeline_bytes_equal_the_model_for_any_registers(
        seed in any::<u64>(),
        planes in 1usize..20,
        n in 1u32..=7,
        l_min in 1u32..=3,
        extra in 0u32..6,
        mask_enable in any::<bool>(),
        stall in 25u64..60,
        // T_hold from 1 to T_int (about one case in six at T_int).
        hold_pct in 0u32..=120,
        trim in 0u32..7,
    ) {
        let mut s = stream(seed, planes, n, l_min, extra, mask_enable);
        s.threshold_hold = hold_at(&s, hold_pct);
        s.end_trim = trim % n;
        check_with(&s, stall, seed, false, true);
    }
}

/// A dense stream (a cut Blink on most planes, L_max = N = 1) at the
/// sensor's duty cycle: the packetiser falls behind, the record queue fills
/// and records are lost and announced — never a FAULT. (Before the tracker
/// waited for the bank of the record the packetiser had just finished, a
/// Blink pushed in the clocks between the queue's room and that bank's
/// return to the free list raised the bank FAULT: the SPCImager 60× stream-end
/// co-simulation failure.)
#[test]
fn full_record_queue_loses_records_without_fault() {
    let mut losses = 0;
    for seed in 0..4u64 {
        let mut s = restream(stream(seed, 60, 1, 1, 0, false), seed ^ 99, 0.08);
        s.threshold = percentile_threshold(&s, 90);
        let records = model_run(model_config(&s), s.planes.clone()).unwrap();
        let want = encode_stream(&records).unwrap();
        // `gateware` asserts that FAULT never rises; 55 % stalls keep the
        // source within the design's duty cycle.
        let (got, _) = gateware(&s, 55, seed);
        if got != want {
            assert!(lossy_but_exact(&got, &records), "seed {seed}");
            losses += 1;
        }
    }
    assert!(losses >= 2, "the queue overflowed in {losses} of 4 streams");
}

/// A source that sends a word on every clock on which `ready` is high (the
/// replay's pacing) never overflows the back half, however dense the scene,
/// and gives the model's bytes; the same dense stream sent on every clock
/// regardless overflows it (FAULT), so it is `ready` that holds it back.
#[test]
fn a_source_paced_by_ready_sends_every_clock_without_fault() {
    let mut blind_faults = 0;
    for seed in 0..3u64 {
        let mut s = restream(stream(seed, 30, 3, 1, 2, false), seed ^ 7, 0.3);
        s.threshold = 1;
        let records = model_run(model_config(&s), s.planes.clone()).unwrap();
        let want = encode_stream(&records).unwrap();
        let (got, _) = gateware_paced(&s, 0, seed, false, Pace::Ready)
            .unwrap_or_else(|e| panic!("seed {seed}: paced by ready: {e}"));
        assert!(
            got == want || lossy_but_exact(&got, &records),
            "seed {seed}: the paced stream is not the model's"
        );
        if gateware_paced(&s, 0, seed, false, Pace::Free).is_err() {
            blind_faults += 1;
        }
    }
    assert!(
        blind_faults > 0,
        "the dense streams never overflowed an unpaced back half"
    );
    // On a sparse stream, paced by `ready`, it takes fewer clocks than at
    // the sensor's duty cycle (a word every other clock), with the same
    // bytes. (This 6-row field's 12-row ROI ring allows little backlog: the
    // co-simulation of the 64×64 demo design measures the real gain.)
    let mut s = stream(5, 24, 4, 2, 4, false);
    s.threshold = percentile_threshold(&s, 99);
    let (fast, fast_clocks) = gateware_paced(&s, 0, 1, false, Pace::Ready).unwrap();
    let (duty, duty_clocks) = gateware(&s, 50, 1);
    assert_eq!(fast, duty);
    assert!(
        fast_clocks < duty_clocks,
        "paced by ready {fast_clocks} clocks, at the duty cycle {duty_clocks}"
    );
}
