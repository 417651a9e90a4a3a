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

/// §8.3–8.7: a continuation is evaluated from its own t_cross (the plane
/// after the cut), is confirmed however short it is, and completes once its
/// last summed plane has left the window, at t_drop + N − end_trim.
#[test]
fn a_continuation_is_evaluated_at_t_cross_always_confirmed_and_completes_after_its_last_plane() {
    // N = 2, L_min = 3, L_max = 3 (a valid configuration: L_max ≥ max(L_min, N)):
    // cut at plane 2; below at planes 3 and 4.
    let mut tr = BlinkTracker::new(1, 2, 0, 3, 3, 1);
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
    // detected at 4, completed at 3 + N = 5; 0 on-planes < L_min, still
    // confirmed. The cut summed [0 − N, 2 − N] (nothing), the continuation
    // [1, 3].
    assert_eq!(
        (*at, cont.segment.t_cross, cont.segment.t_drop),
        (5, 3, Some(3))
    );
    assert_eq!(first.segment.planes_summed(2, 0), Some(1));
    assert_eq!(cont.segment.planes_summed(2, 0), Some(3));
    assert_eq!(tr.counters().unconfirmed, 0);
    // end_trim = 1: the continuation sums [1, 2] and completes at 4.
    let mut tr = BlinkTracker::new(1, 2, 1, 3, 3, 1);
    let done = drive(&mut tr, &[true, true, true, false, false, false]);
    assert_eq!(done.len(), 2, "{done:?}");
    assert_eq!(done[1].0, 4);
    assert_eq!(done[1].1.segment.planes_summed(2, 1), Some(2));
}

/// §8.4, 8.7: a first segment is evaluated from t_cross + 1, confirmed when
/// t_drop − t_cross ≥ L_min, and completes once its last summed plane,
/// t_drop − end_trim, has left the window: at t_drop + N − end_trim.
#[test]
fn a_first_segment_confirms_at_l_min_and_completes_after_its_last_plane() {
    // N = 6, L_min = 2: on at 1, below at 2 and 3: t_drop = 2, confirmed
    // (2 − 0 ≥ 2), detected at 3, completed at 2 + 6 − end_trim.
    let on = [
        true, true, false, false, false, false, false, false, false, false,
    ];
    for (end_trim, at, summed) in [(0, 8, 3), (3, 5, 0), (5, 3, 0)] {
        let mut tr = BlinkTracker::new(1, 6, end_trim, 2, 100, 1);
        let done = drive(&mut tr, &on);
        assert_eq!(done.len(), 1, "{done:?}");
        assert_eq!((done[0].0, done[0].1.segment.t_drop), (at, Some(2)));
        // [max(0, 0 − 6), 2 − end_trim]: empty once end_trim > 2.
        assert_eq!(done[0].1.segment.planes_summed(6, end_trim), Some(summed));
    }
    // L_min = 3: the same track is unconfirmed, nothing completes.
    let mut tr = BlinkTracker::new(1, 6, 0, 3, 100, 1);
    assert!(drive(&mut tr, &on).is_empty());
    assert_eq!(tr.counters().unconfirmed, 1);
}

/// §8.8: at the stream end the plane after the stream counts as the drop of
/// a segment not in a dip, so a TRUNCATED record may have
/// t_drop − t_cross = L_min − 1; in a dip, the dip plane counts.
#[test]
fn stream_end_confirmation_counts_the_plane_after_the_stream() {
    // L_min = 3, 3 planes, on throughout: t_drop = 2 = t_cross + L_min − 1.
    let mut tr = BlinkTracker::new(1, 2, 0, 3, 100, 1);
    assert!(drive(&mut tr, &[true, true, true]).is_empty());
    let end = tr.finish(3);
    assert_eq!(end.len(), 1);
    let s = &end[0].segment;
    assert_eq!((s.t_cross, s.t_drop), (0, Some(2)));
    assert_ne!(s.end_flags & flags::TRUNCATED, 0);
    // In a dip at the last plane (3): 3 − 0 ≥ 3 confirmed, t_drop = 3.
    let mut tr = BlinkTracker::new(1, 2, 0, 3, 100, 1);
    drive(&mut tr, &[true, true, true, false]);
    let end = tr.finish(4);
    assert_eq!(end.len(), 1);
    assert_eq!(end[0].segment.t_drop, Some(3));
    // With L_min = 4 the same dip ends it unconfirmed.
    let mut tr = BlinkTracker::new(1, 2, 0, 4, 100, 1);
    drive(&mut tr, &[true, true, true, false]);
    assert!(tr.finish(4).is_empty());
    assert_eq!(tr.counters().unconfirmed, 1);
}

/// §8.8: a cut at the last plane leaves a continuation with
/// t_drop = t_cross − 1, CONTINUATION | TRUNCATED, which sums the last N
/// planes (the cut summed up to t_drop − N).
#[test]
fn a_cut_at_the_last_plane_leaves_a_continuation_of_the_last_window() {
    // N = 2, L_min = 1, L_max = 3: cut at plane 2, the last.
    let mut tr = BlinkTracker::new(1, 2, 0, 1, 3, 1);
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
    // Planes 1 and 2, whatever end_trim (a truncation sums to t_drop).
    assert_eq!(s.planes_summed(2, 0), Some(2));
    assert_eq!(s.planes_summed(2, 1), Some(2));
}
