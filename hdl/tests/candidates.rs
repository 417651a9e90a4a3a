//! Threshold and candidates against the model's `threshold::above` and
//! `candidates::find`: H planes with many ties (small values, plateaus) and
//! some peaks, peaks on the edges and corners, random stalls, a flush plane,
//! and restarts between streams with other thresholds — hysteresis
//! included: the above bits follow T_hold, the candidates T_int.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::candidates::Candidates;
use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_model::candidates::{find, Candidate};
use smartagg_model::config::PipelineConfig;
use smartagg_model::threshold::above;

const P: usize = 4;
const W: usize = 16;
const H: usize = 5;
type Dut = Candidates<7, 2>; // N_max 7, a = 2: HW 7; 4 words per row: LAW 2

fn random_h(rng: &mut rand_chacha::ChaCha8Rng) -> Vec<u32> {
    let mut h: Vec<u32> = (0..W * H).map(|_| rng.gen_range(0..4)).collect();
    // Plateaus of equal values and single peaks, anywhere (edges included).
    for _ in 0..4 {
        let (x, y, v) = (
            rng.gen_range(0..W),
            rng.gen_range(0..H),
            rng.gen_range(3..127),
        );
        h[y * W + x] = v;
        if rng.gen_bool(0.5) && x + 1 < W {
            h[y * W + x + 1] = v;
        }
        if rng.gen_bool(0.5) && y + 1 < H {
            h[(y + 1) * W + x] = v;
        }
    }
    h[0] = 100; // a corner peak
    h
}

#[test]
fn candidates_equal_model_with_ties_stalls_and_restart() {
    let cfg = PipelineConfig::new(W, H, 7, vec![1, 2, 1], 2, 2);
    let g = GatewareConfig::new(&cfg, P, 7).unwrap();
    let mut bench = Bench::new(Dut::new(&g).unwrap(), |u| &mut u.clock);
    let mut rng = common::rng(51);
    for (stream, thr, hold, planes) in [
        (0u64, 2u32, 2u32, 6usize),
        (1, 3, 3, 4),
        // Hysteresis: T_hold well below T_int.
        (2, 40, 2, 6),
        (3, 90, 1, 4),
    ] {
        let inputs: Vec<Vec<u32>> = (0..planes).map(|_| random_h(&mut rng)).collect();
        let (wpr, wpp) = (W / P, W / P * H);
        bench.uut.restart.next = true;
        bench.uut.valid.next = false;
        bench.uut.threshold.next = (thr as u64).to_bits();
        bench.uut.threshold_hold.next = (hold as u64).to_bits();
        bench.tick();
        bench.uut.restart.next = false;
        let mut stalls = Stalls::new(60 + stream, 30);
        let total = (planes + 1) * wpp;
        let (mut sent, mut idle) = (0, 0);
        let mut got_above: Vec<Vec<bool>> = Vec::new();
        let mut got_cand: Vec<Vec<Candidate>> = Vec::new();
        while idle < 20 {
            let u = &mut bench.uut;
            let offer = sent < total && stalls.offer();
            u.valid.next = offer;
            if offer {
                let (t, idx) = (sent / wpp, sent % wpp);
                let (x, y) = (idx % wpr, idx / wpr);
                u.flush.next = t == planes;
                u.x.next = (x as u64).to_bits();
                u.y.next = (y as u64).to_bits();
                for (i, f) in u.filtered.iter_mut().enumerate() {
                    let v = if t < planes {
                        inputs[t][y * W + x * P + i]
                    } else {
                        0
                    };
                    f.next = (v as u64).to_bits();
                }
                sent += 1;
            }
            settle(u);
            if u.out_valid.val() && !u.out_flush.val() {
                let (x, y) = (
                    u.out_x.val().to_u64() as usize,
                    u.out_y.val().to_u64() as usize,
                );
                if x == 0 && y == 0 {
                    got_above.push(vec![false; W * H]);
                    got_cand.push(Vec::new());
                }
                let a = got_above.last_mut().expect("first word is (0,0)");
                for i in 0..P {
                    a[y * W + x * P + i] = u.above[i].val();
                    if u.candidate[i].val() {
                        let c = Candidate {
                            x: (x * P + i) as u16,
                            y: y as u16,
                        };
                        got_cand.last_mut().unwrap().push(c);
                    }
                }
            }
            if sent == total {
                idle += 1;
            }
            bench.tick();
        }
        assert_eq!(got_above.len(), planes);
        for t in 0..planes {
            let want: Vec<bool> = above(&inputs[t], hold).iter().by_vals().collect();
            assert_eq!(got_above[t], want, "above bits (T_hold {hold}), plane {t}");
            if hold < thr {
                // The two levels differ on this plane's pixels.
                let open: Vec<bool> = above(&inputs[t], thr).iter().by_vals().collect();
                assert_ne!(got_above[t], open, "T_hold {hold} < T_int {thr}, plane {t}");
            }
            let want = find(&inputs[t], W, H, thr);
            assert!(!want.is_empty());
            assert_eq!(
                got_cand[t], want,
                "candidates (raster order), plane {t}, T_int {thr}"
            );
        }
    }
}
