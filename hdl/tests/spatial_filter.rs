//! The spatial filter against the model's `SpatialFilter::apply`: random
//! count planes (0..=N_max, with bright blobs), random stalls, a flush plane
//! to push out the last rows, two kernels (k = 5, and k = 9 with c = P), and
//! a restart between two streams.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::spatial_filter::SpatialFilter;
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_model::config::PipelineConfig;
use smartagg_model::spatial_filter::SpatialFilter as ModelFilter;

const P: usize = 4;

fn random_counts(rng: &mut rand_chacha::ChaCha8Rng, w: usize, h: usize, n_max: u32) -> Vec<u32> {
    let (cx, cy) = (rng.gen_range(0..w) as i64, rng.gen_range(0..h) as i64);
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            if (x - cx).abs() <= 1 && (y - cy).abs() <= 1 {
                n_max
            } else {
                rng.gen_range(0..=n_max)
            }
        })
        .collect()
}

fn run<const CW: usize, const VW: usize, const HW: usize, const LAW: usize>(
    w: usize,
    h: usize,
    kernel: Vec<u32>,
    shift: u8,
    n_max: u32,
    seed: u64,
    dsp_multipliers: usize,
) {
    let cfg = PipelineConfig::new(w, h, n_max, kernel.clone(), shift, 1);
    let g = GatewareConfig {
        dsp_multipliers,
        ..GatewareConfig::new(&cfg, P, n_max).unwrap()
    };
    let mut bench = Bench::new(SpatialFilter::<CW, VW, HW, LAW>::new(&g).unwrap(), |u| {
        &mut u.clock
    });
    let model = ModelFilter::new(kernel);
    let mut rng = common::rng(seed);
    for (stream, planes) in [(0u64, 5usize), (1, 3)] {
        let inputs: Vec<Vec<u32>> = (0..planes)
            .map(|_| random_counts(&mut rng, w, h, n_max))
            .collect();
        let expected: Vec<Vec<u32>> = inputs.iter().map(|s| model.apply(s, w, h)).collect();
        let (wpr, wpp) = (w / P, w / P * h);
        bench.uut.restart.next = true;
        bench.uut.valid.next = false;
        bench.tick();
        bench.uut.restart.next = false;
        let mut stalls = Stalls::new(seed + stream, 35);
        let total = (planes + 1) * wpp; // + one flush plane
        let (mut sent, mut idle) = (0, 0);
        let mut got: Vec<Vec<u32>> = Vec::new();
        while idle < 40 {
            let u = &mut bench.uut;
            let offer = sent < total && stalls.offer();
            u.valid.next = offer;
            if offer {
                let (t, idx) = (sent / wpp, sent % wpp);
                let (x, y) = (idx % wpr, idx / wpr);
                u.flush.next = t == planes;
                u.x.next = (x as u64).to_bits();
                u.y.next = (y as u64).to_bits();
                for (i, c) in u.counts.iter_mut().enumerate() {
                    let v = if t < planes {
                        inputs[t][y * w + x * P + i]
                    } else {
                        0
                    };
                    c.next = (v as u64).to_bits();
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
                    got.push(vec![u32::MAX; w * h]);
                }
                let plane = got.last_mut().expect("first output word is (0,0)");
                for (i, f) in u.filtered.iter().enumerate() {
                    plane[y * w + x * P + i] = f.val().to_u64() as u32;
                }
            }
            if sent == total {
                idle += 1;
            }
            bench.tick();
        }
        assert_eq!(got.len(), planes, "every plane comes out once");
        for t in 0..planes {
            assert_eq!(
                got[t], expected[t],
                "H differs at plane {t} of stream {stream}"
            );
        }
    }
}

#[test]
fn spatial_filter_k5_equals_model() {
    // N_max 7: CW 3, a = 4: VW 7, HW 11; 4 words per row: LAW 2.
    run::<3, 7, 11, 2>(16, 6, vec![1, 4, 6, 4, 1], 4, 7, 31, 0);
}

#[test]
fn spatial_filter_k1_without_line_buffer_rows_equals_model() {
    // One tap: no row above to buffer (the column word holds nothing).
    // N_max 7: CW 3, a = 1: VW 4, HW 5; 4 words per row: LAW 2.
    run::<3, 4, 5, 2>(16, 6, vec![2], 1, 7, 34, 0);
}

#[test]
fn spatial_filter_k9_context_of_a_whole_word_equals_model() {
    // c = 4 = P; N_max 5: CW 3, a = 5: VW 8, HW 13; 3 words per row: LAW 2.
    run::<3, 8, 13, 2>(12, 7, vec![1, 2, 3, 4, 12, 4, 3, 2, 1], 5, 5, 32, 0);
}

#[test]
fn spatial_filter_with_some_multiplies_in_dsp_slices_equals_model() {
    // As above, with 13 of the 40 multiplies in DSP slices: some lanes of
    // a pass multiply in LUTs, the others in DSPs.
    run::<3, 8, 13, 2>(12, 7, vec![1, 2, 3, 4, 12, 4, 3, 2, 1], 5, 5, 33, 13);
    // Every multiply that saves an adder (the weights 3 and 12) in a DSP.
    run::<3, 7, 11, 2>(16, 6, vec![1, 4, 6, 4, 1], 4, 7, 34, 1000);
}

#[test]
fn the_filter_puts_its_costliest_multiplies_in_dsp_slices() {
    // SPCImager 150x: k1 = 2 10 29 54 66; 29 and 54 take two adders, 10 and
    // 66 one, 2 none. The XC6SLX45's 58 slices take the 32 horizontal
    // multiplies by 29 and 54 (two 24-bit adders each), then 26 of the
    // vertical ones (two 16-bit adders) before any single-adder weight.
    let v = smartagg_hdl::front_half::verilog(
        SpatialFilter::<8, 16, 24, 5>::new(&smartagg_hdl::front_half::spcimager150_config())
            .unwrap(),
    );
    // Operands: horizontal pairs 17 bits (two 16-bit vertical sums),
    // vertical pairs 9 bits (two 8-bit counts).
    let h = |w: u32| v.matches(&format!("y = x[16:0] * 24'd{w};")).count();
    let vert = |w: u32| v.matches(&format!("y = x[8:0] * 16'd{w};")).count();
    assert_eq!((h(29), h(54)), (16, 16));
    assert_eq!(vert(29) + vert(54), 26);
    assert_eq!(v.matches(" * ").count(), 58, "DSP multiplies");
    assert_eq!(v.matches("'d10;").count() + v.matches("'d66;").count(), 0);
}
