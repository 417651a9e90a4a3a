//! The golden pipeline on hand-built scenes, and its invariants on random ones.

use proptest::prelude::*;
use smartagg_model::back_end::{Summing, TrackStep, Tracking};
use smartagg_model::blink_tracker::Slot;
use smartagg_model::config::PipelineConfig;
use smartagg_model::delay_line::DelayLine;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::pipeline::{run, FrontEnd, GoldenFrontEnd, Pipeline, PipelineError};
use smartagg_model::plane::BitPlane;
use smartagg_model::record::{flags, BlinkRecord, Record, StreamEnd};

const W: usize = 16;
const H: usize = 12;

/// N = 4, k1 = [1,2,1] (a = 2, so H at a lone pixel is 4·S), T_int = 8.
fn cfg(n: u32, threshold: u32) -> PipelineConfig {
    PipelineConfig::new(W, H, n, vec![1, 2, 1], 2, threshold)
}

/// A stream where pixel (x, y) reads 1 on the given planes.
fn spots(planes: usize, on: &[(usize, usize, std::ops::Range<usize>)]) -> Vec<BitPlane> {
    (0..planes)
        .map(|t| {
            BitPlane::from_fn(W, H, |x, y| {
                on.iter()
                    .any(|(sx, sy, r)| *sx == x && *sy == y && r.contains(&t))
            })
        })
        .collect()
}

fn blinks(records: &[Record]) -> Vec<BlinkRecord> {
    records
        .iter()
        .filter_map(|r| match r {
            Record::Blink(b) => Some(b.clone()),
            _ => None,
        })
        .collect()
}

fn end(records: &[Record]) -> StreamEnd {
    match records.last() {
        Some(Record::End(e)) => e.clone(),
        other => panic!("stream must end with an End record, got {other:?}"),
    }
}

fn roi_at(b: &BlinkRecord, x: i32, y: i32) -> u32 {
    let r = b.roi_size as i32;
    let (dx, dy) = (x - b.roi_x0(), y - b.roi_y0());
    assert!(dx >= 0 && dy >= 0 && dx < r && dy < r);
    b.counts[(dy * r + dx) as usize]
}

#[test]
fn single_blink_gives_one_record_with_exact_times_and_sum() {
    // Pixel (8,6) on for planes 10..=29. S(8,6) reaches 2 at t = 11 → H = 8 ≥ T.
    // Below from t = 32 (S = 1) and 33 (S = 0): t_drop = 32.
    let recs = run(cfg(4, 8), spots(40, &[(8, 6, 10..30)])).unwrap();
    assert!(matches!(recs[0], Record::Start(_)));
    let b = blinks(&recs);
    assert_eq!(b.len(), 1, "{recs:?}");
    let b = &b[0];
    assert_eq!((b.anchor_x, b.anchor_y), (8, 6));
    assert_eq!((b.t_cross, b.t_drop), (11, 32));
    assert_eq!((b.t_s, b.t_e), (11 - 2, 32 - 2));
    // Sum over [t_cross − N, t_drop] = [7, 32].
    assert_eq!(b.planes_summed, 26);
    assert_eq!(roi_at(b, 8, 6), 20);
    assert_eq!(b.counts.iter().sum::<u32>(), 20);
    assert_eq!(b.flags, 0);
    assert_eq!(b.roi_size, 3);
    let e = end(&recs);
    assert_eq!(
        (e.planes, e.blinks, e.unconfirmed, e.bridged_dips),
        (40, 1, 0, 0)
    );
}

#[test]
fn record_is_emitted_at_its_completion_plane() {
    let planes = spots(40, &[(8, 6, 10..30)]);
    // The drop (t_drop = 32) is known at plane 33; the last summed plane,
    // t_drop − end_trim, leaves the window N = 4 planes later.
    for (end_trim, at, summed) in [(0, 36, 26), (2, 34, 24), (3, 33, 23)] {
        let mut c = cfg(4, 8);
        c.end_trim = end_trim;
        let mut p = Pipeline::new(c).unwrap();
        for (t, plane) in planes.iter().enumerate() {
            let out = p.push_plane(plane).unwrap();
            assert_eq!(
                out.len(),
                usize::from(t == at),
                "end_trim {end_trim}, plane {t}: {out:?}"
            );
            if let Some(Record::Blink(b)) = out.first() {
                // [t_cross − N, t_drop − end_trim] = [7, 32 − end_trim].
                assert_eq!(b.planes_summed, summed);
                assert_eq!(roi_at(b, 8, 6), 20, "the spot is on at 10..=29");
            }
        }
    }
}

#[test]
fn one_plane_dip_is_bridged() {
    // N = 1: H follows the pixel directly. Off at plane 21 only.
    let recs = run(cfg(1, 4), spots(40, &[(8, 6, 10..21), (8, 6, 22..31)])).unwrap();
    let b = blinks(&recs);
    assert_eq!(b.len(), 1, "{recs:?}");
    assert_eq!((b[0].t_cross, b[0].t_drop), (10, 31));
    assert_eq!(roi_at(&b[0], 8, 6), 20);
    assert_eq!(end(&recs).bridged_dips, 1);
}

/// A blink whose H dips for two planes below the open level but not
/// below the hold level: one record with hysteresis, two with the paper's
/// one-threshold rule (the same planes).
#[test]
fn a_dip_between_the_hold_and_open_levels_keeps_one_track() {
    // N = 2: H at (8,6) is 4·S with S ∈ {0, 1, 2}. On for planes 10..30
    // except 21, so that S = 1 (H = 4) at planes 21 and 22.
    let mut on = vec![(8, 6, 10..20), (8, 6, 23..30)];
    on.extend([(8, 6, 20..21), (8, 6, 22..23)]);
    let planes = spots(40, &on);
    let mut paper = cfg(2, 8);
    paper.threshold_hold = 8;
    let one = run(paper.clone(), planes.clone()).unwrap();
    assert_eq!(
        blinks(&one).len(),
        2,
        "one threshold splits the blink: {one:?}"
    );
    let mut hyst = paper;
    hyst.threshold_hold = 4;
    let recs = run(hyst, planes).unwrap();
    let b = blinks(&recs);
    assert_eq!(b.len(), 1, "{recs:?}");
    // Opened at plane 11 (S = 2); held through the dip; the last on plane
    // is 29, S = 1 at 30 (H = 4 ≥ T_hold), 0 from 31: t_drop = 31.
    assert_eq!((b[0].t_cross, b[0].t_drop), (11, 31));
    // Every photon of the blink is summed: 10 + 2 + 7.
    assert_eq!(roi_at(&b[0], 8, 6), 19);
}

/// Below the open level nothing opens, however long H stays at the hold level.
#[test]
fn the_hold_level_never_opens_a_track() {
    // N = 2, every other plane: S = 1, H = 4 = T_hold < T_open = 8.
    let on: Vec<(usize, usize, std::ops::Range<usize>)> =
        (10..40).step_by(2).map(|t| (8, 6, t..t + 1)).collect();
    let mut c = cfg(2, 8);
    c.threshold_hold = 4;
    let recs = run(c, spots(50, &on)).unwrap();
    assert!(blinks(&recs).is_empty(), "{recs:?}");
}

/// Two blinks at once: 5 pixels apart they are two tracks; 3 pixels apart
/// (within r_assoc = 3) the second is a candidate beside a live anchor and
/// belongs to the first track, which r_assoc = 1 would not do.
#[test]
fn blinks_close_in_space_and_time_with_an_association_radius() {
    let mut c = cfg(2, 8);
    c.threshold_hold = 4;
    c.r_assoc = 3;
    let apart = run(c.clone(), spots(40, &[(4, 6, 10..20), (9, 6, 12..22)])).unwrap();
    let b = blinks(&apart);
    assert_eq!(b.len(), 2, "{apart:?}");
    assert_eq!(
        [(b[0].anchor_x, b[0].t_cross), (b[1].anchor_x, b[1].t_cross)],
        [(4, 11), (9, 13)]
    );
    let near_spots = spots(40, &[(4, 6, 10..20), (7, 6, 12..22)]);
    let near = run(c.clone(), near_spots.clone()).unwrap();
    let b = blinks(&near);
    assert_eq!(b.len(), 1, "{near:?}");
    assert_eq!((b[0].anchor_x, b[0].t_cross), (4, 11));
    c.r_assoc = 1;
    let b = blinks(&run(c, near_spots).unwrap());
    assert_eq!(
        b.iter()
            .map(|b| (b.anchor_x, b.t_cross))
            .collect::<Vec<_>>(),
        [(4, 11), (7, 13)]
    );
}

#[test]
fn two_planes_below_split_two_blinks() {
    let recs = run(cfg(1, 4), spots(40, &[(8, 6, 10..21), (8, 6, 23..31)])).unwrap();
    let b = blinks(&recs);
    assert_eq!(b.len(), 2, "{recs:?}");
    assert_eq!((b[0].t_cross, b[0].t_drop), (10, 21));
    assert_eq!((b[1].t_cross, b[1].t_drop), (23, 31));
    // The second blink's pre-roll (plane 22) is empty: it holds only its own 8 planes.
    assert_eq!(roi_at(&b[1], 8, 6), 8);
    assert_eq!(roi_at(&b[0], 8, 6), 11);
}

#[test]
fn blinks_at_the_four_corners_are_flagged_edge_and_counted_inside() {
    let corners = [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1)];
    let on: Vec<_> = corners.iter().map(|&(x, y)| (x, y, 5..15)).collect();
    let recs = run(cfg(4, 8), spots(30, &on)).unwrap();
    let b = blinks(&recs);
    assert_eq!(b.len(), 4, "{recs:?}");
    for (rec, &(x, y)) in b.iter().zip(&corners) {
        assert_eq!((rec.anchor_x as usize, rec.anchor_y as usize), (x, y));
        assert!(rec.has(flags::EDGE));
        assert_eq!(roi_at(rec, x as i32, y as i32), 10);
        assert_eq!(rec.counts.iter().sum::<u32>(), 10);
        // Records of one completion plane come in slot order.
        assert_eq!(
            rec.slot as usize,
            corners.iter().position(|c| *c == (x, y)).unwrap()
        );
    }
}

#[test]
fn slot_exhaustion_is_counted_and_reported() {
    let mut c = cfg(1, 4);
    c.slots = 1;
    let recs = run(c, spots(20, &[(3, 3, 5..10), (12, 8, 5..10)])).unwrap();
    let b = blinks(&recs);
    assert_eq!(b.len(), 1);
    assert_eq!((b[0].anchor_x, b[0].anchor_y), (3, 3));
    let drops: Vec<_> = recs
        .iter()
        .filter_map(|r| match r {
            Record::Dropped(d) => Some(d.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(drops.len(), 5, "one dropped record per plane 5..=9");
    assert!(drops
        .iter()
        .all(|d| d.count == 1 && (d.first_x, d.first_y) == (12, 8)));
    assert_eq!(end(&recs).dropped_candidates, 5);
}

#[test]
fn track_shorter_than_l_min_emits_nothing() {
    let mut c = cfg(1, 4);
    c.l_min = 5;
    let recs = run(c.clone(), spots(30, &[(8, 6, 10..14)])).unwrap();
    assert!(blinks(&recs).is_empty());
    assert_eq!(end(&recs).unconfirmed, 1);
    // Exactly L_min planes on is confirmed.
    let recs = run(c, spots(30, &[(8, 6, 10..15)])).unwrap();
    assert_eq!(blinks(&recs).len(), 1);
}

#[test]
fn empty_planes_give_no_blink() {
    let recs = run(cfg(4, 1), spots(50, &[])).unwrap();
    assert_eq!(recs.len(), 2);
    assert_eq!(end(&recs).planes, 50);
}

#[test]
fn saturated_planes_give_one_track_and_no_wrap() {
    // Every pixel on: H is a plateau inside, lower at the borders; the tie rule
    // gives exactly one candidate, the first interior pixel (1,1).
    let planes: Vec<BitPlane> = (0..60)
        .map(|t| {
            if (10..40).contains(&t) {
                BitPlane::ones(W, H)
            } else {
                BitPlane::zeros(W, H)
            }
        })
        .collect();
    let mut p = Pipeline::new(cfg(8, 8)).unwrap();
    let mut recs = vec![p.start_record()];
    for plane in &planes {
        recs.extend(p.push_plane(plane).unwrap());
        assert!(
            p.counts().iter().all(|&s| s <= 8),
            "rolling count never exceeds N"
        );
        assert!(p.candidates().len() <= 1);
    }
    recs.extend(p.finish());
    let b = blinks(&recs);
    assert_eq!(b.len(), 1);
    assert_eq!((b[0].anchor_x, b[0].anchor_y), (1, 1));
    assert!(b[0].counts.iter().all(|&c| c == 30), "{:?}", b[0].counts);
}

#[test]
fn stuck_pixel_is_cut_at_l_max_into_contiguous_segments_without_wrap() {
    // A pixel stuck at 1 from plane 0: the track never ends. L_max = 10 cuts it.
    let mut c = cfg(4, 8);
    c.l_max = 10;
    let recs = run(c.clone(), spots(45, &[(5, 5, 0..45)])).unwrap();
    let b = blinks(&recs);
    assert!(b.len() >= 4, "{b:?}");
    assert!(
        b[0].has(flags::CUT) && !b[0].has(flags::CONTINUATION) && b[0].has(flags::PREROLL_CLIPPED)
    );
    for w in b.windows(2) {
        assert!(w[1].has(flags::CONTINUATION));
        assert_eq!(w[1].t_cross, w[0].t_drop + 1, "segments are contiguous");
        assert_eq!(w[1].slot, w[0].slot);
    }
    let last = b.last().unwrap();
    assert!(last.has(flags::TRUNCATED));
    assert_eq!(last.t_drop, 44);
    // Every plane of the stream is summed exactly once across the segments.
    let total: u32 = b.iter().map(|r| roi_at(r, 5, 5)).sum();
    assert_eq!(total, 45);
    for r in &b {
        assert!(r.planes_summed as u64 <= c.max_planes_summed());
        assert!(r.planes_summed <= c.l_max + 1 + c.n_window);
    }
}

#[test]
fn masked_hot_pixel_is_invisible() {
    let mut c = cfg(1, 4);
    let (mask, _) = HotPixelMask::from_pixels(W, H, &[(5, 5)]);
    c.hot_mask = Some(mask);
    let recs = run(c, spots(30, &[(5, 5, 0..30), (6, 5, 10..20)])).unwrap();
    let b = blinks(&recs);
    assert_eq!(b.len(), 1, "only the real blink next to the hot pixel");
    assert!(b[0].has(flags::MASKED));
    assert_eq!(roi_at(&b[0], 5, 5), 0);
    assert_eq!(roi_at(&b[0], 6, 5), 10);
}

#[test]
fn wrong_plane_size_and_push_after_finish_are_errors() {
    let mut p = Pipeline::new(cfg(4, 8)).unwrap();
    let e = p.push_plane(&BitPlane::zeros(W + 1, H)).unwrap_err();
    assert!(matches!(e, PipelineError::PlaneSize { .. }));
    assert!(e.to_string().contains("17x12"));
    p.finish();
    assert_eq!(
        p.push_plane(&BitPlane::zeros(W, H)),
        Err(PipelineError::Finished)
    );
}

/// A random scene: sparse background plus a few blinking 2x2 spots.
fn random_stream(seed: u64, planes: usize, spots: usize, bg_per_mille: u64) -> Vec<BitPlane> {
    let mut s = seed | 1;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    let sp: Vec<(usize, usize, usize, usize)> = (0..spots)
        .map(|_| {
            let start = (rnd() % planes as u64) as usize;
            let len = 1 + (rnd() % 40) as usize;
            (
                (rnd() % W as u64) as usize,
                (rnd() % H as u64) as usize,
                start,
                start + len,
            )
        })
        .collect();
    (0..planes)
        .map(|t| {
            BitPlane::from_fn(W, H, |x, y| {
                let lit = sp.iter().any(|&(sx, sy, a, b)| {
                    (a..b).contains(&t) && (x == sx || x == sx + 1) && (y == sy || y == sy + 1)
                });
                (lit && rnd() % 4 != 0) || rnd() % 1000 < bg_per_mille
            })
        })
        .collect()
}

/// The configuration of the random-stream properties.
fn random_cfg(
    n: u32,
    thr: u32,
    slots: usize,
    l_min: u32,
    r_assoc: u32,
    trim: u32,
) -> PipelineConfig {
    let mut c = cfg(n, thr);
    c.slots = slots;
    c.l_min = l_min;
    c.l_max = n.max(l_min).max(12);
    c.r_assoc = r_assoc;
    c.end_trim = trim % n;
    c
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Invariants every stream must satisfy: ROI counts equal the direct sum of
    /// the raw planes over [first plane, t_drop]; t_s, t_e and planes_summed
    /// follow their definitions; records come in completion order; totals match.
    #[test]
    fn records_match_direct_sums(seed in any::<u64>(), n in 1u32..8, thr in 1u32..40, planes in 1usize..120,
                                 spots in 0usize..6, bg in 0u64..60, slots in 1usize..5, l_min in 1u32..6, r_assoc in 0u32..3,
                                 trim in 0u32..8) {
        let stream = random_stream(seed, planes, spots, bg);
        let c = random_cfg(n, thr, slots, l_min, r_assoc, trim);
        let recs = run(c.clone(), stream.clone()).unwrap();
        let b = blinks(&recs);
        let half = (n / 2) as i64;
        let mut last_completion = 0u64;
        let mut last_slot_in_plane: Option<u8> = None;
        for r in &b {
            // Summed: [max(0, t_cross − N), t_drop − end_trim]; a cut ends at
            // t_drop − N, a truncation at t_drop.
            let first = r.t_cross.saturating_sub(n as u64);
            let end = if r.has(flags::CUT) { r.t_drop + 1 - n as u64 } else if r.has(flags::TRUNCATED) { r.t_drop + 1 } else { (r.t_drop + 1).saturating_sub(c.end_trim as u64) }.max(first);
            prop_assert_eq!(r.planes_summed as u64, end - first);
            let expected_ts = if r.has(flags::CONTINUATION) { r.t_cross as i64 } else { r.t_cross as i64 - half };
            prop_assert_eq!(r.t_s, expected_ts);
            let cut_or_trunc = r.has(flags::CUT) || r.has(flags::TRUNCATED);
            prop_assert_eq!(r.t_e, if cut_or_trunc { r.t_drop as i64 } else { r.t_drop as i64 - half });
            prop_assert!(r.t_drop >= r.t_cross || r.has(flags::CONTINUATION));
            prop_assert!(r.planes_summed as u64 <= c.max_planes_summed());
            for dy in 0..r.roi_size as i32 {
                for dx in 0..r.roi_size as i32 {
                    let (x, y) = (r.roi_x0() + dx, r.roi_y0() + dy);
                    let direct = (first..end).filter(|&u| stream[u as usize].get_or_zero(x as i64, y as i64)).count() as u32;
                    prop_assert_eq!(r.counts[(dy * r.roi_size as i32 + dx) as usize], direct);
                }
            }
            // Completion plane: cut → t_drop; truncated → end; else once
            // the last summed plane has left the window, t_drop + N − end_trim.
            let completion = if r.has(flags::TRUNCATED) { planes as u64 } else if r.has(flags::CUT) { r.t_drop } else {
                (r.t_drop + n as u64 - c.end_trim as u64).min(planes as u64)
            };
            prop_assert!(completion >= last_completion, "records out of completion order");
            if completion == last_completion {
                if let Some(s) = last_slot_in_plane { prop_assert!(r.slot > s, "slot order within a plane"); }
            }
            last_slot_in_plane = Some(r.slot);
            last_completion = completion;
        }
        let e = end(&recs);
        prop_assert_eq!(e.planes, planes as u64);
        prop_assert_eq!(e.blinks, b.len() as u64);
        let dropped: u64 = recs.iter().filter_map(|r| match r { Record::Dropped(d) => Some(d.count as u64), _ => None }).sum();
        prop_assert_eq!(e.dropped_candidates, dropped);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// The back end's halves are joined only by each plane's `TrackStep`:
    /// the tracker run over the whole stream first, and the sums and
    /// records after it, give the pipeline's records. After every plane a
    /// slot holds an ROI exactly while it holds a segment.
    #[test]
    fn the_tracker_run_ahead_of_the_sums_gives_the_same_records(
        seed in any::<u64>(), n in 1u32..8, thr in 1u32..40, planes in 1usize..120,
        spots in 0usize..6, bg in 0u64..60, slots in 1usize..5, l_min in 1u32..6,
        r_assoc in 0u32..3, trim in 0u32..8,
    ) {
        let stream = random_stream(seed, planes, spots, bg);
        let c = random_cfg(n, thr, slots, l_min, r_assoc, trim);
        let want = run(c.clone(), stream.clone()).unwrap();

        let zero = BitPlane::zeros(W, H);
        let mut front = GoldenFrontEnd::new(&c);
        let mut tracking = Tracking::new(&c);
        let mut steps = Vec::new();
        let mut busy = Vec::new();
        for (t, plane) in stream.iter().enumerate() {
            let delayed = t.checked_sub(n as usize).map_or(&zero, |d| &stream[d]);
            front.push(plane, delayed);
            let mut step = TrackStep::default();
            tracking.step(t as u64, &front, &mut step);
            steps.push(step);
            busy.push(tracking.tracker().slots().iter().map(|s| *s != Slot::Free).collect::<Vec<_>>());
        }
        let track_end = tracking.finish(planes as u64);

        let mut got = vec![Record::Start(c.stream_start())];
        let mut delay = DelayLine::new(n as usize, W, H);
        let mut summing = Summing::new(&c);
        for (t, (plane, step)) in stream.iter().zip(&steps).enumerate() {
            delay.push_masked(plane, None);
            got.extend(summing.step(t as u64, step, &delay));
            let held: Vec<bool> = (0..slots).map(|s| summing.rois().get(s).is_some()).collect();
            prop_assert_eq!(&held, &busy[t], "plane {}", t);
        }
        got.extend(summing.finish(planes as u64, track_end, &delay));
        prop_assert_eq!(got, want);
    }
}
