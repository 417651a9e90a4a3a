//! The DDR2 delay line with the behavioural MCB model against the model's
//! `DelayLine`: garbage in DDR2 before the first planes (they must read as
//! zero), command latency, refresh gaps, random stalls, the N drain planes
//! and a flush plane, restarts with another N while reads are in flight, and
//! an MCB too slow for the stream (the underrun flag, never a silent error).

mod common;

use rust_hdl::prelude::*;
use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::delay_line_ddr::DelayLineDdr;
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_hdl::testbench::mcb_model::{mcb_to_port, port_to_mcb, McbModel};
use smartagg_model::config::PipelineConfig;
use smartagg_model::delay_line::DelayLine as ModelDelayLine;
use smartagg_model::plane::BitPlane;

const P: usize = 4;
type Dut = DelayLineDdr<P, 3, 6>; // N_max 5 -> 3 bits; prefetch 64 words

struct Rig {
    dl: Bench<Dut>,
    mcb: Bench<McbModel>,
}

impl Rig {
    fn new(w: usize, h: usize, mcb: McbModel) -> Rig {
        let cfg = PipelineConfig::new(w, h, 3, vec![1, 2, 1], 2, 3);
        let g = GatewareConfig::new(&cfg, P, 5).unwrap();
        Rig {
            dl: Bench::new(Dut::new(&g).unwrap(), |u| &mut u.clock),
            mcb: Bench::new(mcb, |u| &mut u.clock),
        }
    }

    /// Settles the delay line with the MCB's outputs, then hands its
    /// commands to the MCB.
    fn settle(&mut self) {
        let (d, m) = (&mut self.dl.uut, &mut self.mcb.uut);
        mcb_to_port(&m.mcb, &mut d.mcb);
        settle(d);
        port_to_mcb(&d.mcb, &mut m.mcb);
        settle(m);
    }

    fn tick(&mut self) {
        self.dl.tick();
        self.mcb.tick();
    }
}

/// One stream; returns whether the delay line flagged an underrun. With
/// `abort`, the stream is cut off after that many clocks, unchecked (the
/// next stream's restart comes with its reads still in flight).
#[allow(clippy::too_many_arguments)]
fn run_stream(
    rig: &mut Rig,
    w: usize,
    h: usize,
    n: u32,
    seed: u64,
    planes: usize,
    stall: u64,
    abort: Option<usize>,
) -> bool {
    let mut rng = common::rng(seed);
    let stream = common::random_planes(&mut rng, w, h, planes, 0.3);
    let mut model = ModelDelayLine::new(n as usize, w, h);
    let mut expected: Vec<BitPlane> = stream.iter().map(|p| model.push(p.clone())).collect();
    expected.extend((0..n).map(|_| model.push(BitPlane::zeros(w, h))));
    let wpp = w * h / P;
    rig.dl.uut.restart.next = true;
    rig.dl.uut.n_window.next = (n as u64).to_bits();
    rig.dl.uut.word.valid.next = false;
    rig.settle();
    rig.tick();
    rig.dl.uut.restart.next = false;
    // Wait for calibration as the stream control does before a stream.
    while !rig.mcb.uut.mcb.calib_done.val() {
        rig.settle();
        rig.tick();
    }
    let mut stalls = Stalls::new(seed ^ 0x3c, stall);
    let stored = planes + n as usize;
    let total = (stored + 1) * wpp; // real, drain, one flush plane
    let (mut sent, mut got, mut cycles) = (0, Vec::new(), 0);
    while got.len() < stored * wpp {
        let u = &mut rig.dl.uut;
        let offer = sent < total && stalls.offer();
        u.word.valid.next = offer;
        if offer {
            let (t, idx) = (sent / wpp, sent % wpp);
            u.word.sop.next = idx == 0;
            u.word.drain.next = t >= planes && t < stored;
            u.word.flush.next = t == stored;
            u.word.live.next = if t < planes {
                stream[t].stream_word(P, idx).to_bits()
            } else {
                0.into()
            };
            sent += 1;
        }
        rig.settle();
        let u = &rig.dl.uut;
        if u.out.valid.val() && (!u.out.flush.val() || u.out.drain.val()) {
            got.push(u.out.delayed.val().to_u64());
        }
        rig.tick();
        cycles += 1;
        if abort == Some(cycles) {
            return false;
        }
        assert!(cycles < 200_000, "stream did not complete");
    }
    let under = rig.dl.uut.underrun.val();
    if !under {
        for (t, plane) in expected.iter().enumerate() {
            for idx in 0..wpp {
                assert_eq!(
                    got[t * wpp + idx],
                    plane.stream_word(P, idx),
                    "B_(t-N), plane {t} word {idx}, N = {n}"
                );
            }
        }
        assert!(!rig.dl.uut.write_error.val());
        assert!(!rig.mcb.uut.error.val(), "MCB protocol error");
    }
    under
}

#[test]
fn ddr2_delay_line_equals_model_with_latency_refresh_and_garbage() {
    let (w, h) = (64, 32); // 64 words per plane, bursts of 8
                           // 20-clock command latency, a 40-clock refresh every 300 clocks.
    let mut rig = Rig::new(w, h, McbModel::new(20, 300, 40, 50, 7));
    assert!(!run_stream(&mut rig, w, h, 3, 11, 9, 30, None));
    // Restart with another N; reads of the first stream may still arrive.
    assert!(!run_stream(&mut rig, w, h, 5, 12, 8, 0, None));
    assert!(!run_stream(&mut rig, w, h, 1, 13, 4, 50, None));
    assert!(rig.mcb.uut.words_written() > 0);
}

#[test]
fn ddr2_delay_line_small_planes() {
    let (w, h) = (16, 4); // two 32-bit words per plane, one-word bursts
    let mut rig = Rig::new(w, h, McbModel::new(5, 100, 10, 3, 9));
    assert!(!run_stream(&mut rig, w, h, 4, 21, 10, 20, None));
    assert!(!run_stream(&mut rig, w, h, 2, 22, 6, 0, None));
}

#[test]
fn too_slow_memory_is_flagged() {
    let (w, h) = (32, 8);
    let mut rig = Rig::new(w, h, McbModel::new(400, 300, 40, 5, 3));
    assert!(
        run_stream(&mut rig, w, h, 3, 31, 6, 0, None),
        "underrun must be flagged"
    );
}

#[test]
fn read_decisions_that_cannot_keep_up_are_refused() {
    // P = 32: one stream word per 32-bit DDR2 word; 64×4 planes are 8 words
    // read in one-word bursts, a read command every clock.
    let cfg = PipelineConfig::new(64, 4, 3, vec![1, 2, 1], 2, 3);
    let g = GatewareConfig::new(&cfg, 32, 5).unwrap();
    let err = DelayLineDdr::<32, 3, 6>::new(&g).err().expect("refused");
    assert!(err.to_string().contains("one-word bursts"), "{err}");
    // 64×8 planes read in two-word bursts keep up.
    let cfg = PipelineConfig::new(64, 8, 3, vec![1, 2, 1], 2, 3);
    let g = GatewareConfig::new(&cfg, 32, 5).unwrap();
    assert!(DelayLineDdr::<32, 3, 6>::new(&g).is_ok());
}

#[test]
fn restarts_with_reads_in_flight_lose_nothing() {
    // Streams cut off at many points (a burst's words without their
    // command, reads in flight, a read waiting for the port, words arriving
    // on the restart's clock), some cut again a few clocks into the next
    // stream (while the first one's reads still arrive), each followed by a
    // whole stream that must equal the model: the old streams' reads are
    // discarded, none of the new stream's. N = 3: plane 3 (from clock
    // 1,536) is the first to read.
    let (w, h) = (64, 32);
    let mut rig = Rig::new(w, h, McbModel::new(12, 300, 40, 50, 5));
    for (i, cut) in (700..3200).step_by(97).enumerate() {
        let seed = 40 + i as u64;
        run_stream(&mut rig, w, h, 3, seed, 9, 0, Some(cut));
        if i % 2 == 1 {
            run_stream(&mut rig, w, h, 3, seed + 50, 9, 0, Some(3 + i % 7));
        }
        assert!(
            !run_stream(&mut rig, w, h, 2, seed + 100, 4, 0, None),
            "cut at {cut}"
        );
    }
}
