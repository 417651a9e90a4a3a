//! The tracking rules of `model/PACKETS.md` §8 where a reader could expect
//! otherwise, pinned on the tracker itself (plane by plane as the pipeline
//! drives it: evaluate, associate, end of plane).

use smartagg_model::blink_tracker::{BlinkTracker, Completed};
use smartagg_model::candidates::Candidate;
use smartagg_model::record::flags;

const C: Candidate = Candidate { x: 5, y: 5 };

/// Drives planes `0..on.len()`: a candidate at plane 0, the anchor on or
/// below at every later plane as `on` says. Returns the completions with
/// their plane.
fn drive(tr: &mut BlinkTracker, on: &[bool]) -> Vec<(u64, Completed)> {
    let mut done = Vec::new();
    for (t, &is_on) in on.iter().enumerate() {
        let t = t as u64;
        tr.evaluate(t, |_, _| is_on);
        let cands: &[Candidate] = if t == 0 { &[C] } else { &[] };
        tr.associate(t, cands);
        done.extend(tr.end_of_plane(t).into_iter().map(|c| (t, c)));
    }
    done
}

/// §8.3–8.5, 8.7: a continuation is evaluated from its own t_cross (the
/// plane after the cut), is confirmed however short it is, and completes at
/// t_drop + 1.
#[test]
fn a_continuation_is_evaluated_at_t_cross_always_confirmed_and_completes_at_t_drop_plus_1() {
    // N = 2, L_min = 3, L_max = 3 (a valid configuration: L_max ≥ max(L_min, N)):
    // cut at plane 2; below at planes 3 and 4.
    let mut tr = BlinkTracker::new(1, 2, 3, 3, 1);
    let done = drive(&mut tr, &[true, true, true, false, false, false]);
    assert_eq!(done.len(), 2, "{done:?}");
    let (at, first) = &done[0];
    assert_eq!(
        (*at, first.segment.t_cross, first.segment.t_drop),
        (2, 0, Some(2))
    );
    assert_ne!(first.segment.end_flags & flags::CUT, 0);
    let (at, cont) = &done[1];
    assert!(cont.segment.continuation);
    // Evaluated at plane 3 (its t_cross): below at 3 and 4, so t_drop = 3,
    // detected and completed at 4; 0 on-planes < L_min, still confirmed.
    assert_eq!(
        (*at, cont.segment.t_cross, cont.segment.t_drop),
        (4, 3, Some(3))
    );
    assert_eq!(tr.counters().unconfirmed, 0);
}

/// §8.4, 8.7: a first segment is evaluated from t_cross + 1, confirmed when
/// t_drop − t_cross ≥ L_min, and completes at max(t_drop + 1, t_cross + N − 1).
#[test]
fn a_first_segment_confirms_at_l_min_and_waits_for_its_pre_roll() {
    // N = 6, L_min = 2: on at 1, below at 2 and 3: t_drop = 2, confirmed
    // (2 − 0 ≥ 2), detected at 3, completed at t_cross + N − 1 = 5.
    let mut tr = BlinkTracker::new(1, 6, 2, 100, 1);
    let done = drive(&mut tr, &[true, true, false, false, false, false, false]);
    assert_eq!(done.len(), 1, "{done:?}");
    assert_eq!((done[0].0, done[0].1.segment.t_drop), (5, Some(2)));
    // L_min = 3: the same track is unconfirmed, nothing completes.
    let mut tr = BlinkTracker::new(1, 6, 3, 100, 1);
    assert!(drive(&mut tr, &[true, true, false, false, false, false, false]).is_empty());
    assert_eq!(tr.counters().unconfirmed, 1);
}

/// §8.8: at the stream end the plane after the stream counts as the drop of
/// a segment not in a dip, so a TRUNCATED record may have
/// t_drop − t_cross = L_min − 1; in a dip, the dip plane counts.
#[test]
fn stream_end_confirmation_counts_the_plane_after_the_stream() {
    // L_min = 3, 3 planes, on throughout: t_drop = 2 = t_cross + L_min − 1.
    let mut tr = BlinkTracker::new(1, 2, 3, 100, 1);
    assert!(drive(&mut tr, &[true, true, true]).is_empty());
    let end = tr.finish(3);
    assert_eq!(end.len(), 1);
    let s = &end[0].segment;
    assert_eq!((s.t_cross, s.t_drop), (0, Some(2)));
    assert_ne!(s.end_flags & flags::TRUNCATED, 0);
    // In a dip at the last plane (3): 3 − 0 ≥ 3 confirmed, t_drop = 3.
    let mut tr = BlinkTracker::new(1, 2, 3, 100, 1);
    drive(&mut tr, &[true, true, true, false]);
    let end = tr.finish(4);
    assert_eq!(end.len(), 1);
    assert_eq!(end[0].segment.t_drop, Some(3));
    // With L_min = 4 the same dip ends it unconfirmed.
    let mut tr = BlinkTracker::new(1, 2, 4, 100, 1);
    drive(&mut tr, &[true, true, true, false]);
    assert!(tr.finish(4).is_empty());
    assert_eq!(tr.counters().unconfirmed, 1);
}

/// §8.8: a cut at the last plane leaves an empty continuation:
/// CONTINUATION | TRUNCATED with t_drop = t_cross − 1.
#[test]
fn a_cut_at_the_last_plane_leaves_an_empty_segment() {
    // N = 2, L_min = 1, L_max = 3: cut at plane 2, the last.
    let mut tr = BlinkTracker::new(1, 2, 1, 3, 1);
    let done = drive(&mut tr, &[true, true, true]);
    assert_eq!(done.len(), 1);
    let end = tr.finish(3);
    assert_eq!(end.len(), 1);
    let s = &end[0].segment;
    assert!(s.continuation);
    assert_eq!((s.t_cross, s.t_drop), (3, Some(2)));
    assert_eq!(
        s.flags(2) & (flags::CONTINUATION | flags::TRUNCATED),
        flags::CONTINUATION | flags::TRUNCATED
    );
}
