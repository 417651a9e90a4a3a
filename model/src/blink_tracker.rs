//! Stage 5 — blink tracking in M slots: when is each molecule on?
//!
//! Rules (docs/DESIGN.md §3, with the choices this model makes and the gateware
//! copies; `model/PACKETS.md` §8 is the same list as the stream's contract):
//!
//! * **Association.** A candidate within Chebyshev distance `r_assoc` of the
//!   anchor of a track that was active at the end of the previous plane — or
//!   that an earlier candidate of this plane opened (raster order) — belongs to
//!   it. Otherwise it opens a track in the lowest slot that was free at the end
//!   of the previous plane and not yet taken in this plane; its position becomes
//!   the fixed *anchor* and the plane its `t_cross`. With no such slot it is
//!   counted as dropped. Using the previous plane's slot states makes the
//!   decision independent of the order in which the gateware evaluates tracks
//!   and candidates within a plane. (With `r_assoc ≤ 1` a candidate next to an
//!   anchor keeps that track on; with a larger radius a candidate can be
//!   absorbed by a track that ends in the same plane — the next plane's
//!   candidate then opens a new track.)
//! * **Open.** Candidates are 3×3 maxima with H ≥ T_int (the *open* level,
//!   stage 4); so only a candidate opens a track.
//! * **On/off.** A track is *on* while the maximum of H over the 3×3 around
//!   its anchor is ≥ T_hold (the *hold* level, ≤ T_int: hysteresis, see
//!   [`crate::threshold`]). A first segment is on at its `t_cross` by
//!   definition and evaluated from the plane after it; a continuation
//!   segment is evaluated from its own `t_cross` (the plane after the cut).
//!   A single plane below is bridged (counted); `t_drop` is the first of two
//!   consecutive planes below, detected at `t_drop + 1`.
//! * **Confirmation.** A first segment is confirmed when its on-duration
//!   `t_drop − t_cross` reaches `L_min` (always `≥ 1`, since it is evaluated
//!   from `t_cross + 1`); otherwise its slot is freed at the end of the plane
//!   that detected the drop and nothing is emitted (counted). A continuation
//!   segment is always confirmed.
//! * **Cut.** A track still on (not in a dip) at a plane `t ≥ t_cross + L_max − 1`
//!   ends its segment there (`t_drop = t`, flag CUT) and continues in the same
//!   slot from `t + 1` as a CONTINUATION segment, so no slot or counter is held
//!   forever. Because a cut waits out a one-plane dip, a segment holds at most
//!   `L_max + 1` live planes.
//! * **Summation ranges** (stage 6). A segment sums only the delayed plane
//!   `B_{t−N}` that leaves the window, at the planes `t ≥ max(N, t_cross)`
//!   while it is live and, after a drop, while `t ≤ t_drop + N − end_trim`:
//!   the bit-planes `[max(0, t_cross − N), last]`, with `last = t_drop −
//!   end_trim` for a dropped segment, `t_drop − N` for a cut one (its
//!   continuation goes on from `t_drop + 1 − N`: a track's planes are summed
//!   once, in order, by one accumulator) and `t_drop` for a truncated one.
//!   `end_trim = 0` sums the paper's `[t_s − N/2, t_e + N/2]`; `⌊N/2⌋`
//!   stops at the estimated end `t_e`, leaving out the planes in which the
//!   window still held the blink after it ended.
//! * **Completion.** A confirmed segment completes at the end of the plane of
//!   its last sum: `t_drop + N − end_trim` for a dropped segment (first or
//!   continuation; `end_trim ≤ N − 1`, so after the drop is seen), the cut
//!   plane for a cut one. Records are emitted in order of completion plane,
//!   then slot; the slot is free again from the next plane (a cut slot holds
//!   its continuation).
//! * **Stream end.** Live segments end with `t_drop` = last plane (flag
//!   TRUNCATED). A continuation is confirmed; a first segment is confirmed
//!   when `e − t_cross ≥ L_min` with `e` = the last plane if it is in a dip,
//!   the plane after the stream otherwise (so a TRUNCATED record may have
//!   `t_drop − t_cross = L_min − 1`). Confirmed segments complete their sums
//!   from the delay line. A cut at the last plane leaves a continuation with
//!   `t_cross = t_drop + 1 = p` (CONTINUATION | TRUNCATED) that sums the
//!   last N planes.
//!
//! `model/PACKETS.md` §8 states these rules as the contract of the stream.

use crate::candidates::Candidate;
use crate::record::flags;

/// One segment of a track, from `t_cross` on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    /// Anchor column.
    pub anchor_x: u16,
    /// Anchor row.
    pub anchor_y: u16,
    /// First live plane of the segment.
    pub t_cross: u64,
    /// Whether this segment continues a cut one.
    pub continuation: bool,
    /// Whether live planes are still being summed.
    pub live: bool,
    /// In a one-plane dip (the previous evaluated plane was below).
    pub in_dip: bool,
    /// The plane of the pending dip.
    pub dip_plane: u64,
    /// Last live plane, once the live range has ended.
    pub t_drop: Option<u64>,
    /// CUT / TRUNCATED bits decided by the tracker.
    pub end_flags: u8,
    /// Whether the segment will be emitted.
    pub confirmed: bool,
}

impl Segment {
    /// First plane summed into the ROI: `max(0, t_cross − N)`.
    pub fn first_plane(&self, n_window: u32) -> u64 {
        self.t_cross.saturating_sub(n_window as u64)
    }

    /// Last plane summed into the ROI, once the segment has ended (may be
    /// below [`Segment::first_plane`]: nothing summed): `t_drop − end_trim`
    /// after a drop, `t_drop − N` after a cut, `t_drop` when truncated.
    pub fn last_plane(&self, n_window: u32, end_trim: u32) -> Option<i64> {
        let d = self.t_drop? as i64;
        Some(if self.end_flags & flags::CUT != 0 {
            d - n_window as i64
        } else if self.end_flags & flags::TRUNCATED != 0 {
            d
        } else {
            d - end_trim as i64
        })
    }

    /// Planes summed into the ROI, once the segment has ended.
    pub fn planes_summed(&self, n_window: u32, end_trim: u32) -> Option<u64> {
        let last = self.last_plane(n_window, end_trim)?;
        Some((last + 1 - self.first_plane(n_window) as i64).max(0) as u64)
    }

    /// Flags this segment contributes to its record (CUT, CONTINUATION,
    /// TRUNCATED, PREROLL_CLIPPED).
    pub fn flags(&self, n_window: u32) -> u8 {
        let mut f = self.end_flags;
        if self.continuation {
            f |= flags::CONTINUATION;
        } else if self.t_cross < n_window as u64 {
            f |= flags::PREROLL_CLIPPED;
        }
        f
    }
}

/// A tracking slot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Slot {
    /// Available.
    Free,
    /// Holding a segment (live, or ended and waiting for its last sums).
    Busy(Segment),
}

/// What happened in a slot at the end of a plane.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Completed {
    /// The slot.
    pub slot: usize,
    /// The completed segment (with `t_drop` set).
    pub segment: Segment,
}

/// Totals kept by the tracker (reported in the stream-end record).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TrackerCounters {
    /// Tracks that ended before L_min planes.
    pub unconfirmed: u64,
    /// Candidates that found no free slot.
    pub dropped_candidates: u64,
    /// One-plane dips bridged.
    pub bridged_dips: u64,
    /// Segments cut at L_max.
    pub cut_segments: u64,
}

/// The M-slot blink tracker.
#[derive(Debug, Clone)]
pub struct BlinkTracker {
    slots: Vec<Slot>,
    n_window: u32,
    end_trim: u32,
    l_min: u32,
    l_max: u32,
    r_assoc: u32,
    /// Slot states at the end of the previous plane.
    active_prev: Vec<bool>,
    free_prev: Vec<bool>,
    counters: TrackerCounters,
    /// The anchors of the tracks active at the end of the previous plane, by
    /// row, for [`BlinkTracker::associate`]; rebuilt when `anchors_stale`.
    anchors: AnchorRows,
    /// Whether the active tracks changed since `anchors` was built.
    anchors_stale: bool,
}

/// Candidates dropped during one plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Drops {
    /// How many.
    pub count: u32,
    /// The first in raster order.
    pub first: Candidate,
}

impl BlinkTracker {
    /// A tracker with `slots` free slots (`end_trim ≤ N − 1`, see
    /// [`crate::config::PipelineConfig::end_trim`]).
    pub fn new(
        slots: usize,
        n_window: u32,
        end_trim: u32,
        l_min: u32,
        l_max: u32,
        r_assoc: u32,
    ) -> BlinkTracker {
        debug_assert!(end_trim < n_window.max(1));
        BlinkTracker {
            slots: vec![Slot::Free; slots],
            n_window,
            end_trim,
            l_min,
            l_max,
            r_assoc,
            active_prev: vec![false; slots],
            free_prev: vec![true; slots],
            counters: TrackerCounters::default(),
            anchors: AnchorRows::default(),
            anchors_stale: true,
        }
    }

    /// The slots.
    pub fn slots(&self) -> &[Slot] {
        &self.slots
    }

    /// The totals so far.
    pub fn counters(&self) -> &TrackerCounters {
        &self.counters
    }

    /// Step 1 of a plane: evaluates every track that was live at the end of
    /// the previous plane with `on(anchor_x, anchor_y)`.
    pub fn evaluate(&mut self, t: u64, mut on: impl FnMut(u16, u16) -> bool) {
        self.evaluate_slots(t, |_, x, y| on(x, y));
    }

    /// [`BlinkTracker::evaluate`], with `on(slot, anchor_x, anchor_y)` told
    /// the slot of the track it tests (called once for each such slot,
    /// lowest first).
    pub fn evaluate_slots(&mut self, t: u64, mut on: impl FnMut(usize, u16, u16) -> bool) {
        for (i, slot) in self.slots.iter_mut().enumerate() {
            let Slot::Busy(seg) = slot else { continue };
            // A new track is on at its t_cross by definition; a continuation
            // segment is evaluated from its first plane.
            if !seg.live || (!seg.continuation && seg.t_cross >= t) {
                continue;
            }
            if on(i, seg.anchor_x, seg.anchor_y) {
                if seg.in_dip {
                    seg.in_dip = false;
                    self.counters.bridged_dips += 1;
                }
            } else if !seg.in_dip {
                seg.in_dip = true;
                seg.dip_plane = t;
            } else {
                // Second plane below: the blink ended at the first.
                seg.live = false;
                seg.in_dip = false;
                seg.t_drop = Some(seg.dip_plane);
                seg.confirmed =
                    seg.continuation || seg.dip_plane - seg.t_cross >= self.l_min as u64;
            }
        }
    }

    /// Step 2 of a plane: associates candidates (raster order) with tracks or
    /// opens new ones. Returns the slots opened, and the drops if any.
    pub fn associate(&mut self, t: u64, candidates: &[Candidate]) -> (Vec<usize>, Option<Drops>) {
        let mut opened: Vec<usize> = Vec::new();
        let mut drops: Option<Drops> = None;
        // The anchors that absorb a candidate: tracks active at the end of
        // t − 1 (listed by row, rebuilt only when that set changed: a dense
        // scene brings hundreds of candidates a plane against a set that
        // changes every few tens of planes), then each track this plane opens (few: read from their slots).
        if self.anchors_stale {
            self.anchors
                .rebuild(self.slots.iter().zip(&self.active_prev).filter_map(
                    |(s, &active)| match s {
                        Slot::Busy(seg) if active => Some((seg.anchor_x, seg.anchor_y)),
                        _ => None,
                    },
                ));
            self.anchors_stale = false;
        }
        let mut rows = self.anchors.sweep(self.r_assoc);
        // Slots free at the end of t − 1, lowest first; each is taken once.
        // Only the slot taken changes, and the search goes on past it, so
        // searching as it goes finds the same slots as listing them first.
        let mut first_free = 0;
        for c in candidates {
            let r = self.r_assoc;
            let opened_near = || {
                opened.iter().any(|&i| match &self.slots[i] {
                    Slot::Busy(seg) => near(seg.anchor_x, c.x, r) && near(seg.anchor_y, c.y, r),
                    Slot::Free => false,
                })
            };
            if rows.any_within(c.x, c.y) || opened_near() {
                continue;
            }
            let free = (first_free..self.slots.len())
                .find(|&i| self.free_prev[i] && self.slots[i] == Slot::Free);
            first_free = free.map_or(self.slots.len(), |i| i + 1);
            match free {
                Some(i) => {
                    self.slots[i] = Slot::Busy(Segment {
                        anchor_x: c.x,
                        anchor_y: c.y,
                        t_cross: t,
                        continuation: false,
                        live: true,
                        in_dip: false,
                        dip_plane: 0,
                        t_drop: None,
                        end_flags: 0,
                        confirmed: false,
                    });
                    opened.push(i);
                }
                None => {
                    self.counters.dropped_candidates += 1;
                    match &mut drops {
                        Some(d) => d.count += 1,
                        None => {
                            drops = Some(Drops {
                                count: 1,
                                first: *c,
                            })
                        }
                    }
                }
            }
        }
        (opened, drops)
    }

    /// Whether slot `i` sums the delayed plane `B_{t−N}` into its ROI at plane `t`.
    pub fn sums_delayed(&self, i: usize, t: u64) -> bool {
        let n = self.n_window as u64;
        match &self.slots[i] {
            Slot::Busy(seg) if t >= n && t >= seg.t_cross => {
                seg.live
                    || seg
                        .last_plane(self.n_window, self.end_trim)
                        .is_some_and(|last| (t - n) as i64 <= last)
            }
            _ => false,
        }
    }

    /// Step 3 of a plane, after the ROI sums: cuts long tracks, completes
    /// segments, frees slots. Returns the completed confirmed segments in slot
    /// order; a cut slot continues with a fresh segment from `t + 1`.
    pub fn end_of_plane(&mut self, t: u64) -> Vec<Completed> {
        let mut done = Vec::new();
        let n = self.n_window as u64;
        for (i, slot) in self.slots.iter_mut().enumerate() {
            let Slot::Busy(seg) = slot else { continue };
            if seg.live && !seg.in_dip && t + 1 >= seg.t_cross + self.l_max as u64 {
                seg.live = false;
                seg.t_drop = Some(t);
                seg.end_flags |= flags::CUT;
                seg.confirmed = true;
                self.counters.cut_segments += 1;
            }
            if seg.live {
                continue;
            }
            if !seg.confirmed {
                self.counters.unconfirmed += 1;
                *slot = Slot::Free;
                continue;
            }
            // A cut completes at once; a drop once its last plane has left
            // the window (at `t_drop + N − end_trim`).
            let sums_done = seg.end_flags & flags::CUT != 0
                || seg
                    .last_plane(self.n_window, self.end_trim)
                    .is_some_and(|last| t as i64 >= last + n as i64);
            if !sums_done {
                continue;
            }
            done.push(Completed {
                slot: i,
                segment: seg.clone(),
            });
            if seg.end_flags & flags::CUT != 0 {
                *seg = Segment {
                    t_cross: t + 1,
                    continuation: true,
                    live: true,
                    in_dip: false,
                    dip_plane: 0,
                    t_drop: None,
                    end_flags: 0,
                    confirmed: true,
                    ..seg.clone()
                };
            } else {
                *slot = Slot::Free;
            }
        }
        self.snapshot();
        done
    }

    /// Stream end after `planes` planes: ends live tracks at the last plane
    /// (TRUNCATED) and returns every confirmed segment still held, slot order.
    /// Their sums are completed by the caller from the delay line.
    pub fn finish(&mut self, planes: u64) -> Vec<Completed> {
        let mut done = Vec::new();
        for (i, slot) in self.slots.iter_mut().enumerate() {
            let Slot::Busy(seg) = slot else { continue };
            if seg.live {
                let last = planes - 1;
                let on_until = if seg.in_dip { last } else { planes };
                seg.live = false;
                seg.t_drop = Some(last);
                seg.end_flags |= flags::TRUNCATED;
                seg.confirmed = seg.continuation || on_until - seg.t_cross >= self.l_min as u64;
            }
            if seg.confirmed {
                done.push(Completed {
                    slot: i,
                    segment: seg.clone(),
                });
            } else {
                self.counters.unconfirmed += 1;
            }
            *slot = Slot::Free;
        }
        self.snapshot();
        done
    }

    fn snapshot(&mut self) {
        for (i, s) in self.slots.iter().enumerate() {
            let active = matches!(s, Slot::Busy(seg) if seg.live);
            // A slot active before and after holds the same anchor (only a
            // free slot opens; a cut continues with its anchor).
            self.anchors_stale |= active != self.active_prev[i];
            self.active_prev[i] = active;
            self.free_prev[i] = *s == Slot::Free;
        }
    }
}

/// Whether `|a − c| ≤ r`, as `a − (c − r) ≤ 2r` in wrapping arithmetic (one
/// unsigned compare; coordinates are u16 and r ≤ 255, as the configuration
/// checks, so nothing wraps onto a near value).
fn near(a: u16, c: u16, r: u32) -> bool {
    u32::from(a).wrapping_sub(u32::from(c).wrapping_sub(r)) <= 2 * r
}

/// Track anchors sorted by row, then column.
#[derive(Debug, Clone, Default)]
struct AnchorRows {
    /// (row, column), ascending.
    by_row: Vec<(u16, u16)>,
}

impl AnchorRows {
    fn rebuild(&mut self, anchors: impl Iterator<Item = (u16, u16)>) {
        self.by_row.clear();
        self.by_row.extend(anchors.map(|(x, y)| (y, x)));
        self.by_row.sort_unstable();
    }

    /// A search of these anchors for candidates in raster order, at radius `r`.
    fn sweep(&self, r: u32) -> RowSweep<'_> {
        RowSweep {
            by_row: &self.by_row,
            r,
            first: 0,
            row: 0,
        }
    }
}

/// [`AnchorRows`] searched for one plane's candidates: the first anchor of a
/// row within `r` of the last candidate's row only moves forward while the
/// candidates do (raster order), so a plane costs its candidates plus its
/// anchors, and a candidate only meets the anchors of its rows.
struct RowSweep<'a> {
    by_row: &'a [(u16, u16)],
    r: u32,
    /// The first anchor whose row is ≥ `row − r`.
    first: usize,
    /// The last candidate's row.
    row: u16,
}

impl RowSweep<'_> {
    /// Whether an anchor lies within `r` of (x, y) on both axes.
    fn any_within(&mut self, x: u16, y: u16) -> bool {
        let top = u32::from(y).saturating_sub(self.r);
        if y < self.row {
            // Out of raster order: search again from the start.
            self.first = self.by_row.partition_point(|&(ay, _)| u32::from(ay) < top);
        } else {
            while self
                .by_row
                .get(self.first)
                .is_some_and(|&(ay, _)| u32::from(ay) < top)
            {
                self.first += 1;
            }
        }
        self.row = y;
        let bottom = u32::from(y) + self.r;
        self.by_row[self.first..]
            .iter()
            .take_while(|&&(ay, _)| u32::from(ay) <= bottom)
            .any(|&(_, ax)| near(ax, x, self.r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The association rule exactly as the module docs state it, slot by
    /// slot: the oracle for [`BlinkTracker::associate`].
    fn associate_reference(
        tr: &mut BlinkTracker,
        t: u64,
        candidates: &[Candidate],
    ) -> (Vec<usize>, Option<Drops>) {
        let mut opened: Vec<usize> = Vec::new();
        let mut drops: Option<Drops> = None;
        let r = tr.r_assoc as i64;
        for c in candidates {
            let near = |seg: &Segment| {
                (seg.anchor_x as i64 - c.x as i64).abs() <= r
                    && (seg.anchor_y as i64 - c.y as i64).abs() <= r
            };
            let absorbed = tr.slots.iter().enumerate().any(|(i, s)| match s {
                Slot::Busy(seg) => (tr.active_prev[i] || opened.contains(&i)) && near(seg),
                Slot::Free => false,
            });
            if absorbed {
                continue;
            }
            let free = (0..tr.slots.len())
                .find(|&i| tr.free_prev[i] && !opened.contains(&i) && tr.slots[i] == Slot::Free);
            match free {
                Some(i) => {
                    tr.slots[i] = Slot::Busy(Segment {
                        anchor_x: c.x,
                        anchor_y: c.y,
                        t_cross: t,
                        continuation: false,
                        live: true,
                        in_dip: false,
                        dip_plane: 0,
                        t_drop: None,
                        end_flags: 0,
                        confirmed: false,
                    });
                    opened.push(i);
                }
                None => {
                    tr.counters.dropped_candidates += 1;
                    match &mut drops {
                        Some(d) => d.count += 1,
                        None => {
                            drops = Some(Drops {
                                count: 1,
                                first: *c,
                            })
                        }
                    }
                }
            }
        }
        (opened, drops)
    }

    proptest! {
        /// Anchors anywhere on a u16 field (its edges included), any radius
        /// the configuration allows, candidates near some of them and
        /// anywhere, in raster order or not: each answer of one sweep is the
        /// square around its candidate.
        #[test]
        fn row_sweep_is_the_square_around_each_candidate(
            anchors in proptest::collection::vec((any::<u16>(), any::<u16>()), 1..40),
            picks in proptest::collection::vec(
                (any::<prop::sample::Index>(), -300i32..300, -300i32..300), 0..30),
            anywhere in proptest::collection::vec((any::<u16>(), any::<u16>()), 0..4),
            edges in any::<bool>(),
            r in 0u32..=255,
            raster in any::<bool>(),
        ) {
            let mut all = anchors.clone();
            if edges {
                all.extend([(0, 0), (u16::MAX, u16::MAX), (0, u16::MAX), (u16::MAX, 0)]);
            }
            let mut list = AnchorRows::default();
            list.rebuild(all.iter().copied());
            let mut cands: Vec<(u16, u16)> = picks
                .iter()
                .filter_map(|&(i, dx, dy)| {
                    let (ax, ay) = all[i.index(all.len())];
                    Some((u16::try_from(ax as i32 + dx).ok()?, u16::try_from(ay as i32 + dy).ok()?))
                })
                .chain(anywhere)
                .collect();
            if raster {
                cands.sort_by_key(|&(x, y)| (y, x));
            }
            let mut sweep = list.sweep(r);
            for (x, y) in cands {
                let expected = all.iter().any(|&(ax, ay)| {
                    (ax as i64 - x as i64).abs() <= r as i64
                        && (ay as i64 - y as i64).abs() <= r as i64
                });
                prop_assert_eq!(sweep.any_within(x, y), expected, "({}, {}) r {}", x, y, r);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// Any slot states (busy or free, active or not at the end of the
        /// previous plane, anchors on a small field so that neighbours are
        /// common) and any raster-ordered candidates, or the same candidates
        /// with two swapped: the same slots open, the same drops, the same
        /// slot states and counters as the oracle.
        #[test]
        fn association_equals_the_stated_rule(
            slots in proptest::collection::vec(
                (any::<bool>(), 0u16..12, 0u16..40, any::<bool>(), any::<bool>()), 1..40),
            cands in proptest::collection::btree_set((0u16..12, 0u16..40), 0..80),
            r_assoc in 0u32..6,
            swap in proptest::option::of((any::<prop::sample::Index>(), any::<prop::sample::Index>())),
        ) {
            let mut tr = BlinkTracker::new(slots.len(), 20, 0, 3, 100, r_assoc);
            for (i, &(busy, x, y, active, free_prev)) in slots.iter().enumerate() {
                if busy {
                    tr.slots[i] = Slot::Busy(Segment {
                        anchor_x: x,
                        anchor_y: y,
                        t_cross: 3,
                        continuation: false,
                        live: active,
                        in_dip: false,
                        dip_plane: 0,
                        t_drop: None,
                        end_flags: 0,
                        confirmed: false,
                    });
                }
                tr.active_prev[i] = active;
                tr.free_prev[i] = free_prev;
            }
            // Raster order: by row, then column.
            let mut cs: Vec<Candidate> = cands.iter().map(|&(x, y)| Candidate { x, y }).collect();
            cs.sort_by_key(|c| (c.y, c.x));
            if let (Some((i, j)), false) = (swap, cs.is_empty()) {
                let (i, j) = (i.index(cs.len()), j.index(cs.len()));
                cs.swap(i, j);
            }
            let mut oracle = tr.clone();
            let got = tr.associate(9, &cs);
            let want = associate_reference(&mut oracle, 9, &cs);
            prop_assert_eq!(got, want);
            prop_assert_eq!(&tr.slots, &oracle.slots);
            prop_assert_eq!(tr.counters(), oracle.counters());
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        /// Plane after plane (tracks opening, dropping, dipping, cut,
        /// completing and freeing their slots, so the set of active anchors
        /// changes and stays as it was in turns): the tracker that lists its
        /// anchors only when that set changed opens, drops and completes as
        /// the oracle does at every plane.
        #[test]
        fn association_over_planes_equals_the_stated_rule(
            planes in proptest::collection::vec(
                (proptest::collection::btree_set((0u16..10, 0u16..16), 0..12),
                 proptest::collection::vec(any::<bool>(), 8)),
                1..60),
            slots in 1usize..8,
            r_assoc in 0u32..4,
            l_max in 2u32..12,
        ) {
            let mut tr = BlinkTracker::new(slots, 4, 1, 2, l_max, r_assoc);
            let mut oracle = tr.clone();
            for (t, (cands, on)) in planes.iter().enumerate() {
                let t = t as u64;
                let cs: Vec<Candidate> = cands.iter().map(|&(y, x)| Candidate { x, y }).collect();
                tr.evaluate_slots(t, |i, _, _| on[i]);
                oracle.evaluate_slots(t, |i, _, _| on[i]);
                let got = tr.associate(t, &cs);
                let want = associate_reference(&mut oracle, t, &cs);
                prop_assert_eq!(got, want, "plane {}", t);
                prop_assert_eq!(tr.end_of_plane(t), oracle.end_of_plane(t));
                prop_assert_eq!(&tr.slots, &oracle.slots);
                prop_assert_eq!(tr.counters(), oracle.counters());
            }
        }
    }
}
