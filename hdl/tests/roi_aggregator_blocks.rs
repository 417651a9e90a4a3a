//! The ROI aggregator's sub-blocks, each against its definition (the
//! aggregator as a whole is checked against the golden pipeline in
//! `roi_aggregator.rs`):
//! * the lowest slot: the empty and the full set, every set of one or two
//!   slots, and random sets of every density: the index of the lowest
//!   slot, the set without it, and whether it is empty;
//! * the view multiplexer: random views of 3 and of 32 slots read at random
//!   indices (slots past M included),
//!   valid or not: the entry at `parity·M + slot`, 0 for a slot past M or
//!   when not valid;
//! * the row cover: random views of 3, 7 and 32 slots, anchors near the row
//!   (inside and just outside the ROI) and anywhere, random `pre | fresh`,
//!   for h = 1, 4, 15: a slot is set iff it sums or starts and its ROI
//!   `ay − h … ay + h` holds the row, and none when not enabled;
//! * the ROI row: random words of the two banks, every offset, either bank
//!   on the left, either word off the sensor: bit j of the result is bit
//!   `off + j` of the pair (left word low), for the delayed and the mask
//!   bits, at 4 and 16 pixels per word.

mod common;

use rand::Rng;
use rust_hdl::prelude::*;
use smartagg_hdl::roi_aggregator::{LowestSlot, RoiRow, RowCover, ViewMux};
use smartagg_hdl::testbench::bench::settle;

#[test]
fn lowest_slot_is_the_lowest_bit_of_the_set() {
    let mut u = LowestSlot::new();
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mut rng = common::rng(21);
    let mut sets: Vec<u32> = vec![0, u32::MAX];
    for i in 0..32 {
        sets.push(1 << i);
        for j in i + 1..32 {
            sets.push(1 << i | 1 << j);
        }
    }
    for &p in &[0.03, 0.2, 0.5, 0.9] {
        for _ in 0..2000 {
            sets.push((0..32).fold(0, |s, i| s | (rng.gen_bool(p) as u32) << i));
        }
    }
    let mut indices = std::collections::BTreeSet::new();
    for set in sets {
        u.slots.next = (set as u64).to_bits();
        settle(&mut u);
        let want = if set == 0 { 0 } else { set.trailing_zeros() };
        assert_eq!(u.index.val().to_u64() as u32, want, "set {set:#010x}");
        assert_eq!(
            u.rest.val().to_u64() as u32,
            set & set.wrapping_sub(1),
            "set {set:#010x}"
        );
        assert_eq!(u.any.val(), set != 0, "set {set:#010x}");
        indices.insert(want);
    }
    assert_eq!(indices.len(), 32);
}

fn view_case(m: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut u = ViewMux::new(m);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let mut entries: Vec<u64> = Vec::new();
    let mut read = std::collections::BTreeSet::new();
    for trial in 0..4000 {
        if trial % 50 == 0 {
            entries = (0..2 * m).map(|_| rng.gen()).collect();
            for (e, &v) in u.entries.iter_mut().zip(&entries) {
                e.next = v.to_bits();
            }
        }
        let valid = rng.gen_bool(0.8);
        let (parity, slot) = (rng.gen_range(0..2usize), rng.gen_range(0..32usize));
        u.valid.next = valid;
        u.index.next = ((parity << 5 | slot) as u64).to_bits();
        settle(&mut u);
        let want = if valid && slot < m {
            read.insert((parity, slot));
            entries[parity * m + slot]
        } else {
            0
        };
        assert_eq!(
            u.entry.val().to_u64(),
            want,
            "M {m}: parity {parity}, slot {slot}, valid {valid}"
        );
    }
    assert_eq!(read.len(), 2 * m, "every entry read");
}

#[test]
fn view_mux_reads_the_entry_at_parity_m_plus_slot() {
    view_case(3, 22);
    view_case(32, 23);
}

fn row_case<const P: usize>(seed: u64) {
    let mut rng = common::rng(seed);
    let mut u = RoiRow::<P>::default();
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let top = if P == 64 { u64::MAX } else { (1u64 << P) - 1 };
    let mut offsets = std::collections::BTreeSet::new();
    for _ in 0..5000 {
        let words: [u64; 4] = std::array::from_fn(|_| rng.gen::<u64>() & top);
        let [even_d, even_m, odd_d, odd_m] = words;
        let (wq_odd, lo_ok, hi_ok) = (rng.gen_bool(0.5), rng.gen_bool(0.8), rng.gen_bool(0.8));
        let off = rng.gen_range(0..P);
        offsets.insert(off);
        u.even_delayed.next = even_d.to_bits();
        u.even_mask.next = even_m.to_bits();
        u.odd_delayed.next = odd_d.to_bits();
        u.odd_mask.next = odd_m.to_bits();
        u.wq_odd.next = wq_odd;
        u.lo_ok.next = lo_ok;
        u.hi_ok.next = hi_ok;
        u.off.next = (off as u64).to_bits();
        u.sh_hi.next = ((P - off) as u64).to_bits();
        settle(&mut u);
        // The left word is the even bank's when wq is odd; a word off the
        // sensor reads 0. Bit j is bit off + j of the pair, left word low.
        let cut = |even: u64, odd: u64| {
            let (left, right) = if wq_odd { (even, odd) } else { (odd, even) };
            let left = if lo_ok { left } else { 0 };
            let right = if hi_ok { right } else { 0 };
            let pair = |k: usize| {
                if k < P {
                    left >> k & 1
                } else {
                    right >> (k - P) & 1
                }
            };
            (0..P).fold(0u64, |w, j| w | pair(off + j) << j)
        };
        let case = format!("P {P}: off {off}, wq odd {wq_odd}, lo {lo_ok}, hi {hi_ok}");
        assert_eq!(u.delayed.val().to_u64(), cut(even_d, odd_d), "{case}");
        assert_eq!(u.mask.val().to_u64(), cut(even_m, odd_m), "{case}");
    }
    assert_eq!(offsets.len(), P, "every offset");
}

#[test]
fn roi_row_is_the_pairs_bits_from_the_offset() {
    row_case::<4>(24);
    row_case::<16>(25);
}

fn cover_case(m: usize, h: usize, seed: u64) {
    let mut rng = common::rng(seed);
    let mut u = RowCover::new(m, h);
    u.connect_all();
    check_all(&u).expect("rust-hdl design checks");
    let (mut covered, mut near_not) = (0, 0);
    for _ in 0..3000 {
        let ra = rng.gen_range(0..512i64);
        let parity = rng.gen_bool(0.5);
        let enable = rng.gen_bool(0.8);
        // Half the anchors near the row (inside and just outside the ROI),
        // the others anywhere; random flags.
        let entries: Vec<(i64, bool)> = (0..2 * m)
            .map(|_| {
                let ay = if rng.gen_bool(0.5) {
                    (ra + rng.gen_range(-(2 * h as i64) - 2..=2 * h as i64 + 2)).clamp(0, 511)
                } else {
                    rng.gen_range(0..512)
                };
                (ay, rng.gen_bool(0.7))
            })
            .collect();
        for (q, &(ay, sums)) in entries.iter().enumerate() {
            u.anchor_rows[q].next = (ay as u64).to_bits();
            u.sums_or_starts[q].next = sums;
        }
        u.parity.next = parity;
        u.row_hi.next = ((ra as usize + h) as u64).to_bits();
        u.enable.next = enable;
        settle(&mut u);
        let slots = u.slots.val().to_u64();
        for i in 0..32 {
            let want = enable && i < m && {
                let (ay, sums) = entries[parity as usize * m + i];
                sums && (ay - h as i64..=ay + h as i64).contains(&ra)
            };
            assert_eq!(
                slots >> i & 1 == 1,
                want,
                "M {m}, h {h}: row {ra}, slot {i}"
            );
            if i < m && enable {
                let (ay, sums) = entries[parity as usize * m + i];
                covered += want as usize;
                near_not += (sums && !want && (ay - ra).abs() <= 2 * h as i64 + 2) as usize;
            }
        }
    }
    assert!(
        covered > 500 && near_not > 500,
        "{covered} covered, {near_not} just outside"
    );
}

#[test]
fn row_cover_is_the_slots_whose_roi_covers_the_row() {
    cover_case(3, 1, 26);
    cover_case(32, 4, 27);
    cover_case(7, 15, 28);
}
