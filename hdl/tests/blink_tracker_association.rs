//! The blink tracker's association against the model's rule (the tracker
//! as a whole is checked against the model in `blink_tracker.rs`): 30,000
//! clocks of random slot flags (busy; active and free at the end of t − 1,
//! opened in this plane; free slots anywhere in the 32 bits, or none) and
//! association windows, a candidate decided on most clocks. Every clock:
//! absorbed by a busy slot near it that was active at the end of t − 1 or
//! opened in this plane, else opened in the lowest slot free by the
//! previous clock's flags, else dropped.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::blink_tracker::Association;
use smartagg_hdl::testbench::bench::{settle, Bench};

/// 32 random bits, each set with probability `p`.
fn bits(rng: &mut impl Rng, p: f64) -> u64 {
    (0..32).fold(0, |w, i| w | (rng.gen_bool(p) as u64) << i)
}

#[test]
fn association_absorbs_opens_the_lowest_free_slot_or_drops() {
    let mut b = Bench::new(Association::default(), |u| &mut u.clock);
    let mut rng = common::rng(97);
    // The slots free by the previous clock's flags (none at power-up).
    let mut free_prev = 0u64;
    // Seen: openings, drops, absorptions, absorptions by a track opened in
    // this plane only, candidates near busy slots that absorb nothing,
    // openings in slot 16 or above, openings where this clock's flags show
    // another lowest free slot than the previous clock's, candidates near
    // slots active or opened but not busy that absorb nothing.
    let mut seen = [0u32; 8];
    for clock in 0..30_000 {
        let busy = bits(&mut rng, 0.5);
        // (In the tracker both are busy; the block's rule asks for busy too.)
        let active_before = bits(&mut rng, 0.35);
        let opened = bits(&mut rng, 0.05);
        let free_before = if rng.gen_bool(0.2) {
            0
        } else {
            (bits(&mut rng, 0.3) << rng.gen_range(0..32)) & 0xffff_ffff
        };
        let near_rate = rng.gen_range(0.0..0.15);
        let near = bits(&mut rng, near_rate);
        let candidate = rng.gen_bool(0.6);

        let u = &mut b.uut;
        u.candidate.next = candidate;
        u.busy.next = busy.to_bits();
        u.active_before.next = active_before.to_bits();
        u.opened.next = opened.to_bits();
        u.free_before.next = free_before.to_bits();
        u.near.next = near.to_bits();
        settle(u);

        let absorbed = busy & (active_before | opened) & near != 0;
        let lowest = free_prev & free_prev.wrapping_neg();
        let open = candidate && !absorbed && free_prev != 0;
        let drop = candidate && !absorbed && free_prev == 0;
        assert_eq!(u.open.val(), open, "clock {clock}: open");
        assert_eq!(u.drop.val(), drop, "clock {clock}: drop");
        assert_eq!(u.open_slot.val().to_u64(), lowest, "clock {clock}: slot");

        let free_now = free_before & !opened;
        seen[0] += open as u32;
        seen[1] += drop as u32;
        seen[2] += (candidate && absorbed) as u32;
        seen[3] +=
            (candidate && busy & opened & near != 0 && busy & active_before & near == 0) as u32;
        seen[4] += (candidate && busy & near != 0 && !absorbed) as u32;
        seen[5] += (open && lowest >= 1 << 16) as u32;
        seen[6] += (open && free_now & free_now.wrapping_neg() != lowest) as u32;
        seen[7] += (candidate && !busy & (active_before | opened) & near != 0 && !absorbed) as u32;
        b.tick();
        free_prev = free_now;
    }
    assert!(seen.iter().all(|&n| n >= 100), "coverage {seen:?}");
}
