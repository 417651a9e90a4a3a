//! The rolling count against the model's `RollingCount` (fed by the model's
//! delay line): several planes, random stalls, a flush plane in between that
//! must not disturb the counts, and a restart whose first plane must ignore
//! the counters left by the previous stream.

mod common;

use rust_hdl::prelude::*;
use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::rolling_count::RollingCount;
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_model::config::PipelineConfig;
use smartagg_model::delay_line::DelayLine;
use smartagg_model::plane::BitPlane;
use smartagg_model::rolling_count::RollingCount as ModelRollingCount;

const P: usize = 4;
const W: usize = 16;
const H: usize = 3;
type Dut = RollingCount<P, 3, 4>; // N_max 7 -> 3 bits; 12 words -> 4 address bits

/// One stream: `planes` real planes, a flush plane after plane `flush_after`.
fn run_stream(bench: &mut Bench<Dut>, n: usize, seed: u64, planes: usize, flush_after: usize) {
    let mut rng = common::rng(seed);
    let stream = common::random_planes(&mut rng, W, H, planes, 0.35);
    let mut dl = DelayLine::new(n, W, H);
    let mut rc = ModelRollingCount::new(W, H);
    let mut inputs: Vec<(BitPlane, BitPlane, bool)> = Vec::new();
    let mut expected = Vec::new();
    for (t, p) in stream.iter().enumerate() {
        let old = dl.push(p.clone());
        rc.update(p, &old);
        inputs.push((p.clone(), old, false));
        expected.push(rc.counts().to_vec());
        if t == flush_after {
            inputs.push((BitPlane::ones(W, H), BitPlane::zeros(W, H), true));
        }
    }
    let wpr = W / P;
    let wpp = wpr * H;

    bench.uut.restart.next = true;
    bench.uut.valid.next = false;
    bench.tick();
    bench.uut.restart.next = false;

    let mut stalls = Stalls::new(seed, 40);
    let mut got: Vec<Vec<u32>> = Vec::new();
    let mut sent = 0;
    let total = inputs.len() * wpp;
    let mut idle = 0;
    while idle < 8 {
        let u = &mut bench.uut;
        let offer = sent < total && stalls.offer();
        u.valid.next = offer;
        if offer {
            let (t, idx) = (sent / wpp, sent % wpp);
            let (live, del, flush) = &inputs[t];
            u.flush.next = *flush;
            u.x.next = ((idx % wpr) as u64).to_bits();
            u.y.next = ((idx / wpr) as u64).to_bits();
            u.idx.next = (idx as u64).to_bits();
            u.live.next = live.stream_word(P, idx).to_bits();
            u.delayed.next = del.stream_word(P, idx).to_bits();
            sent += 1;
        }
        settle(u);
        if u.out_valid.val() {
            if u.out_flush.val() {
                assert!(
                    u.counts.iter().all(|c| c.val().to_u64() == 0),
                    "flush words carry zero counts"
                );
            } else {
                let (x, y) = (
                    u.out_x.val().to_u64() as usize,
                    u.out_y.val().to_u64() as usize,
                );
                if x == 0 && y == 0 {
                    got.push(vec![0; W * H]);
                }
                let plane = got.last_mut().expect("first output word is (0,0)");
                for (i, c) in u.counts.iter().enumerate() {
                    plane[y * W + x * P + i] = c.val().to_u64() as u32;
                }
            }
        }
        if sent == total {
            idle += 1;
        }
        bench.tick();
    }
    assert_eq!(got.len(), planes);
    for t in 0..planes {
        assert_eq!(got[t], expected[t], "S_t differs at plane {t} (N = {n})");
    }
}

#[test]
fn rolling_count_equals_model_with_stalls_flush_and_restart() {
    let cfg = PipelineConfig::new(W, H, 4, vec![1, 2, 1], 2, 3);
    let g = GatewareConfig::new(&cfg, P, 7).unwrap();
    let mut bench = Bench::new(Dut::new(&g).unwrap(), |u| &mut u.clock);
    run_stream(&mut bench, 4, 21, 12, 5);
    run_stream(&mut bench, 7, 22, 12, 20);
    run_stream(&mut bench, 1, 23, 4, 0);
}
