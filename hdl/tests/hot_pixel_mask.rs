//! The hot-pixel mask stage against the model's `HotPixelMask::apply`:
//! a random mask loaded through the load port, several planes, random stalls.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::hot_pixel_mask::HotPixelMask;
use smartagg_hdl::testbench::bench::{settle, Bench, Stalls};
use smartagg_model::config::PipelineConfig;
use smartagg_model::hot_pixel_mask::HotPixelMask as ModelMask;
use smartagg_model::plane::BitPlane;

const P: usize = 4;
const W: usize = 16;
const H: usize = 5;
type Dut = HotPixelMask<P, 5>; // 20 words -> 5 address bits

#[test]
fn hot_pixel_mask_equals_model() {
    let cfg = PipelineConfig::new(W, H, 3, vec![1, 2, 1], 2, 3);
    let g = GatewareConfig::new(&cfg, P, 3).unwrap();
    let mut bench = Bench::new(Dut::new(&g).unwrap(), |u| &mut u.clock);
    let mut rng = common::rng(81);
    let hot: Vec<(usize, usize)> = (0..12)
        .map(|_| (rng.gen_range(0..W), rng.gen_range(0..H)))
        .collect();
    let (mask, outside) = ModelMask::from_pixels(W, H, &hot);
    assert!(outside.is_empty() && mask.count() > 5);
    let mask_plane = BitPlane::from_fn(W, H, |x, y| mask.is_masked(x as i64, y as i64));
    let wpp = W * H / P;
    for idx in 0..wpp {
        bench.uut.load.next = true;
        bench.uut.load_address.next = (idx as u64).to_bits();
        bench.uut.load_data.next = mask_plane.stream_word(P, idx).to_bits();
        bench.tick();
    }
    bench.uut.load.next = false;
    let planes: Vec<BitPlane> = (0..4)
        .map(|_| BitPlane::from_fn(W, H, |_, _| rng.gen_bool(0.7)))
        .collect();
    let mut stalls = Stalls::new(82, 30);
    let (mut sent, mut got) = (0, Vec::new());
    while got.len() < planes.len() * wpp {
        let u = &mut bench.uut;
        let offer = sent < planes.len() * wpp && stalls.offer();
        u.word.valid.next = offer;
        if offer {
            u.word.sop.next = sent % wpp == 0;
            u.word.flush.next = false;
            // The MASK_ENABLE register: on for even planes, off for odd ones.
            u.enable.next = (sent / wpp).is_multiple_of(2);
            u.word.live.next = planes[sent / wpp].stream_word(P, sent % wpp).to_bits();
            sent += 1;
        }
        settle(u);
        if u.out.valid.val() {
            assert_eq!(u.out.sop.val(), got.len() % wpp == 0);
            got.push((u.out.live.val().to_u64(), u.out_mask.val().to_u64()));
        }
        bench.tick();
        assert!(bench.cycles < 10_000);
    }
    for (t, plane) in planes.iter().enumerate() {
        let enabled = t.is_multiple_of(2);
        let want = if enabled {
            mask.apply(plane)
        } else {
            plane.clone()
        };
        for idx in 0..wpp {
            let want_mask = if enabled {
                mask_plane.stream_word(P, idx)
            } else {
                0
            };
            assert_eq!(
                got[t * wpp + idx],
                (want.stream_word(P, idx), want_mask),
                "plane {t} word {idx}"
            );
        }
    }
}
