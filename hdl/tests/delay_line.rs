//! The block-RAM delay line against the model's `DelayLine`: several planes,
//! the N drain planes of the stream end (the last N planes come out again),
//! random stalls, a runtime N below N_max, then a second stream after a
//! restart (old memory contents must not leak: planes before the stream are zero).

mod common;

use rust_hdl::prelude::*;
use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::delay_line::DelayLine;
use smartagg_hdl::testbench::bench::{Bench, Stalls};
use smartagg_model::config::PipelineConfig;
use smartagg_model::delay_line::DelayLine as ModelDelayLine;

const P: usize = 4;
type Dut = DelayLine<P, 7, 3>; // 5 planes x 16 words -> 80 words, 7 address bits; N_max 5 -> 3 bits

fn run_stream(bench: &mut Bench<Dut>, n: u32, seed: u64, planes: usize) {
    let (w, h) = (16, 4);
    let mut rng = common::rng(seed);
    let stream = common::random_planes(&mut rng, w, h, planes, 0.3);
    let mut model = ModelDelayLine::new(n as usize, w, h);
    let expected: Vec<_> = stream.iter().map(|p| model.push(p.clone())).collect();
    // The N drain planes of the stream end: B_{p−N} … B_{p−1} come out.
    let drained: Vec<_> = (0..n)
        .map(|_| model.push(smartagg_model::plane::BitPlane::zeros(w, h)))
        .collect();
    let wpp = w * h / P;

    let u = &mut bench.uut;
    u.restart.next = true;
    u.n_window.next = (n as u64).to_bits();
    u.word.valid.next = false;
    bench.tick();
    bench.uut.restart.next = false;

    let mut stalls = Stalls::new(seed ^ 0x5a5a, 30);
    let mut got_live = Vec::new();
    let mut got_delayed = Vec::new();
    let mut positions = Vec::new();
    let mut got_drain = Vec::new();
    let n_drain = n as usize;
    // Real planes, N drain planes, one flush plane.
    let total = (planes + n_drain + 1) * wpp;
    let mut sent = 0;
    while got_live.len() < planes * wpp || got_drain.len() < n_drain * wpp {
        let u = &mut bench.uut;
        let offer = sent < total && stalls.offer();
        u.word.valid.next = offer;
        if offer {
            let (t, idx) = (sent / wpp, sent % wpp);
            u.word.sop.next = idx == 0;
            u.word.drain.next = t >= planes && t < planes + n_drain;
            u.word.flush.next = t == planes + n_drain;
            u.side.next = ((sent as u64 * 7) & 15).to_bits();
            u.word.live.next = if t < planes {
                stream[t].stream_word(P, idx).to_bits()
            } else {
                0.into()
            };
            sent += 1;
        }
        smartagg_hdl::testbench::bench::settle(u);
        if u.out.valid.val() && u.out.drain.val() {
            assert!(u.out.flush.val(), "drain words are flush downstream");
            got_drain.push(u.out.delayed.val().to_u64());
        }
        if u.out.valid.val() && !u.out.flush.val() {
            assert_eq!(
                u.out.side.val().to_u64(),
                ((got_live.len() as u64 * 7) & 15),
                "side bits ride along"
            );
            got_live.push(u.out.live.val().to_u64());
            got_delayed.push(u.out.delayed.val().to_u64());
            positions.push((
                u.out.x.val().to_u64(),
                u.out.y.val().to_u64(),
                u.out.idx.val().to_u64(),
            ));
        }
        bench.tick();
        assert!(bench.cycles < 100_000, "stream did not complete");
    }
    for (j, plane) in drained.iter().enumerate() {
        for idx in 0..wpp {
            assert_eq!(
                got_drain[j * wpp + idx],
                plane.stream_word(P, idx),
                "drain plane {j} word {idx}, N = {n}"
            );
        }
    }
    for t in 0..planes {
        for idx in 0..wpp {
            let k = t * wpp + idx;
            assert_eq!(
                positions[k],
                ((idx % (w / P)) as u64, (idx / (w / P)) as u64, idx as u64)
            );
            assert_eq!(
                got_live[k],
                stream[t].stream_word(P, idx),
                "live, plane {t} word {idx}"
            );
            assert_eq!(
                got_delayed[k],
                expected[t].stream_word(P, idx),
                "B_(t-N), plane {t} word {idx}, N = {n}"
            );
        }
    }
}

#[test]
fn delay_line_equals_model_with_stalls_and_restart() {
    let cfg = PipelineConfig::new(16, 4, 3, vec![1, 2, 1], 2, 3);
    let g = GatewareConfig::new(&cfg, P, 5).unwrap();
    let mut bench = Bench::new(Dut::new(&g).unwrap(), |u| &mut u.clock);
    run_stream(&mut bench, 3, 11, 8);
    // Second stream, other N: the memory still holds the first stream's planes.
    run_stream(&mut bench, 5, 12, 7);
    run_stream(&mut bench, 1, 13, 3);
}

#[test]
fn mismatched_type_is_an_error() {
    let cfg = PipelineConfig::new(16, 4, 3, vec![1, 2, 1], 2, 3);
    let g = GatewareConfig::new(&cfg, P, 9).unwrap();
    let e = Dut::new(&g)
        .err()
        .expect("N_max 9 needs other widths")
        .to_string();
    assert!(e.contains("AW") || e.contains("NW"), "{e}");
}
