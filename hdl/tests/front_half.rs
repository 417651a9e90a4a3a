//! The whole phase-1 pipeline (hot-pixel mask → block-RAM delay line → rolling count →
//! filter → threshold and candidates) against the model's stages run in the
//! order of `model/src/pipeline.rs`: random bit-planes with a blinking blob,
//! random stalls, runtime N below N_max, a flush plane at the end, and
//! hysteresis: the above bits at T_hold (the 70th percentile of H), the
//! candidates at T_int (the 90th).

mod common;

use proptest::prelude::*;
use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::front_half::{test_config, TestFrontHalf};
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_model::candidates::{find, Candidate};
use smartagg_model::delay_line::DelayLine;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::plane::BitPlane;
use smartagg_model::rolling_count::RollingCount;
use smartagg_model::spatial_filter::SpatialFilter;
use smartagg_model::threshold::above;

/// One stream of `planes` planes with window `n`, `stall_percent` stalls;
/// returns the number of candidates compared.
fn run(seed: u64, n: usize, stall_percent: u64, planes: usize) -> usize {
    let g = test_config();
    let (w, h, p) = (g.width, g.height, g.pixels_per_clock);
    let mut rng = common::rng(seed);
    let raw = common::random_planes(&mut rng, w, h, planes, 0.15);
    // Stage 0: a few hot pixels, loaded through the mask port.
    let hot: Vec<(usize, usize)> = (0..3)
        .map(|_| (rng.gen_range(0..w), rng.gen_range(0..h)))
        .collect();
    let (mask, _) = HotPixelMask::from_pixels(w, h, &hot);
    let mask_plane = BitPlane::from_fn(w, h, |x, y| mask.is_masked(x as i64, y as i64));
    let stream: Vec<BitPlane> = raw.iter().map(|b| mask.apply(b)).collect();

    // The model, stage by stage.
    let mut dl = DelayLine::new(n, w, h);
    let mut rc = RollingCount::new(w, h);
    let filter = SpatialFilter::new(g.kernel.clone());
    let filtered: Vec<Vec<u32>> = stream
        .iter()
        .map(|b| {
            let old = dl.push(b.clone());
            rc.update(b, &old);
            filter.apply(rc.counts(), w, h)
        })
        .collect();
    let mut all: Vec<u32> = filtered.iter().flatten().copied().collect();
    all.sort_unstable();
    let thr = all[all.len() * 9 / 10].max(1);
    let hold = all[all.len() * 7 / 10].clamp(1, thr);

    let mut bench = Bench::new(TestFrontHalf::new(&g).unwrap(), |u| &mut u.clock);
    bench.uut.restart.next = true;
    bench.uut.n_window.next = (n as u64).to_bits();
    bench.uut.threshold.next = g.threshold_register(thr).to_bits();
    bench.uut.threshold_hold.next = g.threshold_register(hold).to_bits();
    bench.tick();
    bench.uut.restart.next = false;
    let wpp = w * h / p;
    for idx in 0..wpp {
        bench.uut.load.next = true;
        bench.uut.load_address.next = (idx as u64).to_bits();
        bench.uut.load_data.next = mask_plane.stream_word(p, idx).to_bits();
        bench.tick();
    }
    bench.uut.load.next = false;

    let total = (planes + 1) * wpp;
    let mut stalls = Stalls::new(seed ^ 0x77, stall_percent);
    let (mut sent, mut idle) = (0, 0);
    let mut got_above: Vec<Vec<bool>> = Vec::new();
    let mut got_cand: Vec<Vec<Candidate>> = Vec::new();
    while idle < 60 {
        let u = &mut bench.uut;
        let offer = sent < total && stalls.offer();
        u.word.valid.next = offer;
        if offer {
            let (t, idx) = (sent / wpp, sent % wpp);
            u.word.sop.next = idx == 0;
            u.word.flush.next = t == planes;
            u.word.live.next = if t < planes {
                raw[t].stream_word(p, idx).to_bits()
            } else {
                0.into()
            };
            sent += 1;
        }
        settle(u);
        if u.out.valid.val() && !u.out.flush.val() {
            let (x, y) = (
                u.out.x.val().to_u64() as usize,
                u.out.y.val().to_u64() as usize,
            );
            if x == 0 && y == 0 {
                got_above.push(vec![false; w * h]);
                got_cand.push(Vec::new());
            }
            let a = got_above.last_mut().expect("first word is (0,0)");
            for i in 0..p {
                a[y * w + x * p + i] = u.out.above.val().get_bit(i);
                if u.out.candidate.val().get_bit(i) {
                    let c = Candidate {
                        x: (x * p + i) as u16,
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
    let mut candidates_seen = 0;
    for t in 0..planes {
        let want: Vec<bool> = above(&filtered[t], hold).iter().by_vals().collect();
        assert_eq!(got_above[t], want, "above-hold bits, plane {t}");
        let want = find(&filtered[t], w, h, thr);
        candidates_seen += want.len();
        assert_eq!(got_cand[t], want, "candidates, plane {t}");
    }
    candidates_seen
}

#[test]
fn front_half_equals_model_stages() {
    let seen = run(71, 5, 30, 12);
    assert!(seen > 0, "the stream exercises candidates");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    /// Any N up to N_max, any stall rate (none to most clocks).
    #[test]
    fn front_half_equals_model_for_any_window_and_stalls(seed in any::<u64>(), n in 1usize..=7, stall in 0u64..80) {
        run(seed, n, stall, 9);
    }
}
