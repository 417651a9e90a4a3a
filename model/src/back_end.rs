//! Stages 5–7 in parts that can run in threads of their own: [`Tracking`]
//! (stage 5, the blink tracker's decisions), [`RoiSums`] (stage 6, the ROI
//! sums, for every slot or for a part of them) and [`Records`] (stage 7);
//! [`Summing`] is stages 6–7 in one.
//!
//! [`Pipeline`](crate::pipeline::Pipeline) runs them one after the other on
//! every plane. The parallel engine
//! ([`run_parallel`](crate::fast_engine::run_parallel)) runs the tracker a
//! chunk ahead in a thread of its own, the sums of each part of the slots in
//! another, and the records in a third. A plane's [`TrackStep`] carries all
//! that the sums and records need from the tracker, and each part's sums
//! come to the records in the tracker's order, so the records are the same
//! whichever way the parts run.

use crate::blink_tracker::{BlinkTracker, Completed, Drops, Slot, TrackerCounters};
use crate::config::PipelineConfig;
use crate::delay_line::DelayLine;
use crate::pipeline::FrontEnd;
use crate::record::{flags, BlinkRecord, DroppedRecord, Record, StreamEnd};
use crate::roi_aggregator::RoiAggregator;

/// What the tracker decided at one plane: all that the ROI sums and the
/// records of that plane need from it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TrackStep {
    /// Slots opened at this plane, with their anchors: (slot, x, y).
    pub opened: Vec<(u16, u16, u16)>,
    /// Slots that add the delayed plane `B_{t−N}` to their ROI, lowest first.
    pub summing: Vec<u16>,
    /// Segments completed at this plane, slot order.
    pub completed: Vec<Completed>,
    /// Slots freed at this plane that hold an ROI: it is emptied after the
    /// records.
    pub closed: Vec<u16>,
    /// Candidates that found no free slot at this plane.
    pub drops: Option<Drops>,
}

/// The tracker's end of the stream: what [`Summing::finish`] needs.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TrackEnd {
    /// The confirmed segments still held, slot order (live ones TRUNCATED):
    /// their sums are completed from the delay line.
    pub completed: Vec<Completed>,
    /// The tracker's totals, for the stream-end record.
    pub counters: TrackerCounters,
}

/// Stage 5 driven plane by plane: the tracks evaluated against the front
/// end's hold level, the candidates associated, the segments ended.
#[derive(Debug, Clone)]
pub struct Tracking {
    tracker: BlinkTracker,
    /// Slots whose ROI [`Summing`] holds (opened and not yet closed): a
    /// mirror, so that a step names only the ROIs to close.
    roi_open: Vec<bool>,
}

impl Tracking {
    /// A tracker with every slot free, for a validated configuration.
    pub fn new(cfg: &PipelineConfig) -> Tracking {
        Tracking {
            tracker: BlinkTracker::new(
                cfg.slots,
                cfg.n_window,
                cfg.end_trim,
                cfg.l_min,
                cfg.l_max,
                cfg.r_assoc,
            ),
            roi_open: vec![false; cfg.slots],
        }
    }

    /// The tracker.
    pub fn tracker(&self) -> &BlinkTracker {
        &self.tracker
    }

    /// Stage 5 of plane `t`, the front end having taken that plane: writes
    /// into `step` what the sums and records of the plane need.
    pub fn step<F: FrontEnd>(&mut self, t: u64, front: &F, step: &mut TrackStep) {
        self.tracker
            .evaluate_slots(t, |slot, x, y| front.slot_on(slot, x as usize, y as usize));
        let (opened, drops) = self.tracker.associate(t, front.candidates());
        step.opened.clear();
        for slot in opened {
            if let Slot::Busy(seg) = &self.tracker.slots()[slot] {
                step.opened.push((slot as u16, seg.anchor_x, seg.anchor_y));
                self.roi_open[slot] = true;
            }
        }
        step.summing.clear();
        // At most every slot: one allocation for a new step, not one each
        // time the list doubles (the parallel engine makes a step a plane).
        step.summing.reserve(self.roi_open.len());
        for slot in 0..self.roi_open.len() {
            if self.tracker.sums_delayed(slot, t) {
                step.summing.push(slot as u16);
            }
        }
        step.completed = self.tracker.end_of_plane(t);
        step.closed.clear();
        for (slot, (open, s)) in self
            .roi_open
            .iter_mut()
            .zip(self.tracker.slots())
            .enumerate()
        {
            if *open && *s == Slot::Free {
                *open = false;
                step.closed.push(slot as u16);
            }
        }
        step.drops = drops;
    }

    /// Stream end after `planes` planes: every segment still held ends.
    pub fn finish(&mut self, planes: u64) -> TrackEnd {
        let completed = if planes > 0 {
            self.tracker.finish(planes)
        } else {
            Vec::new()
        };
        self.roi_open.fill(false);
        TrackEnd {
            completed,
            counters: self.tracker.counters().clone(),
        }
    }
}

/// A completed segment's ROI: its counts and flags
/// ([`RoiAggregator::take`]).
pub type RoiSum = (Vec<u32>, u8);

/// Stage 6 driven plane by plane, for every slot or for a part of them
/// (`slot % parts == part`: parts can run in threads of their own, each
/// with the same steps and the same delay line): each slot's ROI sums of
/// the planes leaving the delay line.
#[derive(Debug, Clone)]
pub struct RoiSums {
    cfg: PipelineConfig,
    rois: RoiAggregator,
    part: usize,
    parts: usize,
}

impl RoiSums {
    /// Every ROI empty, for a validated configuration: the slots with
    /// `slot % parts == part` (`part < parts`).
    pub fn new(cfg: &PipelineConfig, part: usize, parts: usize) -> RoiSums {
        debug_assert!(part < parts);
        RoiSums {
            rois: RoiAggregator::new(cfg.slots, cfg.roi_size, cfg.width, cfg.height),
            cfg: cfg.clone(),
            part,
            parts,
        }
    }

    /// The ROI accumulators (the slots of other parts stay empty).
    pub fn rois(&self) -> &RoiAggregator {
        &self.rois
    }

    /// Whether this part sums `slot`.
    pub fn owns(&self, slot: usize) -> bool {
        slot % self.parts == self.part
    }

    /// Stage 6 of a plane, the delay line holding `B_t` (so that it gives
    /// `B_{t−N}`): pushes onto `done` the ROI of each of this part's
    /// segments that `step` completes, in its order.
    pub fn step(&mut self, step: &TrackStep, delay: &DelayLine, done: &mut Vec<RoiSum>) {
        let mask = self.cfg.hot_mask.as_ref();
        for &(slot, x, y) in &step.opened {
            if self.owns(slot as usize) {
                self.rois.open(slot as usize, x, y, mask);
            }
        }
        let delayed = delay.delayed();
        for &slot in &step.summing {
            if self.owns(slot as usize) {
                self.rois.add(slot as usize, delayed);
            }
        }
        for c in &step.completed {
            if self.owns(c.slot) {
                done.push(self.rois.take(c.slot).expect("a busy slot has an ROI"));
            }
        }
        for &slot in &step.closed {
            if self.owns(slot as usize) {
                self.rois.close(slot as usize);
            }
        }
        // The ROIs sum B_{t+1−N} next: fetch their rows meanwhile.
        self.rois.prefetch(delay.peek(0));
    }

    /// Stream end after `planes` planes, the delay line holding the last
    /// ones: pushes onto `done` the ROI of each of this part's segments
    /// still held, summed to its last plane, in `end`'s order.
    pub fn finish(
        &mut self,
        planes: u64,
        end: &TrackEnd,
        delay: &DelayLine,
        done: &mut Vec<RoiSum>,
    ) {
        if planes == 0 {
            return;
        }
        let n = self.cfg.n_window as u64;
        let (part, parts) = (self.part, self.parts);
        for c in end.completed.iter().filter(|c| c.slot % parts == part) {
            let seg = &c.segment;
            let first = seg
                .first_plane(self.cfg.n_window)
                .max(planes.saturating_sub(n));
            let last = seg
                .last_plane(self.cfg.n_window, self.cfg.end_trim)
                .expect("a finished segment has ended");
            // Planes not yet summed: u in [max(first, p − N), last], still
            // inside the delay line, which holds B_{p−N} … B_{p−1}.
            for u in first as i64..=last {
                let i = (u as u64 + n - planes) as usize;
                // A few planes ahead: these planes are old, out of cache.
                if u + 4 <= last {
                    self.rois.prefetch_slot(c.slot, delay.peek(i + 4));
                }
                self.rois.add(c.slot, delay.peek(i));
            }
            done.push(self.rois.take(c.slot).expect("a busy slot has an ROI"));
        }
        // The tracker has freed every slot.
        for slot in (part..self.cfg.slots).step_by(parts) {
            self.rois.close(slot);
        }
    }
}

/// Stage 7 driven plane by plane: the records, from the tracker's steps and
/// the completed segments' ROIs ([`RoiSums`]).
#[derive(Debug, Clone)]
pub struct Records {
    cfg: PipelineConfig,
    blinks: u64,
}

impl Records {
    /// No blink yet.
    pub fn new(cfg: &PipelineConfig) -> Records {
        Records {
            cfg: cfg.clone(),
            blinks: 0,
        }
    }

    /// The records of plane `t`, in the order of `model/PACKETS.md` §8;
    /// `roi(slot)` gives each completed segment's ROI, in `step`'s order.
    pub fn step(
        &mut self,
        t: u64,
        step: &TrackStep,
        mut roi: impl FnMut(usize) -> RoiSum,
    ) -> Vec<Record> {
        // Most planes complete nothing: no allocation then.
        let mut out = Vec::with_capacity(step.completed.len() + usize::from(step.drops.is_some()));
        for c in &step.completed {
            let sum = roi(c.slot);
            out.push(self.blink(c, sum));
        }
        if let Some(d) = step.drops {
            out.push(Record::Dropped(DroppedRecord {
                plane: t,
                count: d.count,
                first_x: d.first.x,
                first_y: d.first.y,
            }));
        }
        out
    }

    /// Stream end after `planes` planes: the segments still held, in
    /// `end`'s (slot) order, then the stream-end record; `roi(slot)` as for
    /// [`Records::step`].
    pub fn finish(
        &mut self,
        planes: u64,
        end: TrackEnd,
        mut roi: impl FnMut(usize) -> RoiSum,
    ) -> Vec<Record> {
        let mut out = Vec::with_capacity(end.completed.len() + 1);
        if planes > 0 {
            for c in &end.completed {
                let sum = roi(c.slot);
                out.push(self.blink(c, sum));
            }
        }
        let counters = end.counters;
        out.push(Record::End(StreamEnd {
            planes,
            blinks: self.blinks,
            unconfirmed: counters.unconfirmed,
            dropped_candidates: counters.dropped_candidates,
            bridged_dips: counters.bridged_dips,
            cut_segments: counters.cut_segments,
        }));
        out
    }

    fn blink(&mut self, c: &Completed, (counts, roi_flags): RoiSum) -> Record {
        let seg = &c.segment;
        let n = self.cfg.n_window;
        let half = (n / 2) as i64;
        let t_drop = seg.t_drop.expect("a completed segment has ended");
        let f = seg.flags(n) | roi_flags;
        let t_s = if seg.continuation {
            seg.t_cross as i64
        } else {
            seg.t_cross as i64 - half
        };
        let t_e = if f & (flags::CUT | flags::TRUNCATED) != 0 {
            t_drop as i64
        } else {
            t_drop as i64 - half
        };
        self.blinks += 1;
        Record::Blink(BlinkRecord {
            slot: c.slot as u8,
            flags: f,
            anchor_x: seg.anchor_x,
            anchor_y: seg.anchor_y,
            t_cross: seg.t_cross,
            t_drop,
            t_s,
            t_e,
            planes_summed: seg
                .planes_summed(n, self.cfg.end_trim)
                .expect("a completed segment has ended") as u32,
            roi_size: self.cfg.roi_size as u8,
            counts,
        })
    }
}

/// Stages 6–7 driven plane by plane in one thread: each slot's ROI sums of
/// the planes leaving the delay line ([`RoiSums`], every slot), and the
/// records ([`Records`]).
#[derive(Debug, Clone)]
pub struct Summing {
    sums: RoiSums,
    records: Records,
    done: Vec<RoiSum>,
}

impl Summing {
    /// Every ROI empty, for a validated configuration.
    pub fn new(cfg: &PipelineConfig) -> Summing {
        Summing {
            sums: RoiSums::new(cfg, 0, 1),
            records: Records::new(cfg),
            done: Vec::new(),
        }
    }

    /// The ROI accumulators.
    pub fn rois(&self) -> &RoiAggregator {
        self.sums.rois()
    }

    /// Stages 6–7 of plane `t`, the delay line holding `B_t` (so that it
    /// gives `B_{t−N}`): the plane's records, in the order of
    /// `model/PACKETS.md` §8.
    pub fn step(&mut self, t: u64, step: &TrackStep, delay: &DelayLine) -> Vec<Record> {
        self.sums.step(step, delay, &mut self.done);
        let mut done = self.done.drain(..);
        self.records.step(t, step, |_| {
            done.next().expect("an ROI for each completed segment")
        })
    }

    /// Stream end after `planes` planes, the delay line holding the last
    /// ones: the segments still held summed to their last plane, in slot
    /// order, then the stream-end record.
    pub fn finish(&mut self, planes: u64, end: TrackEnd, delay: &DelayLine) -> Vec<Record> {
        self.sums.finish(planes, &end, delay, &mut self.done);
        let mut done = self.done.drain(..);
        self.records.finish(planes, end, |_| {
            done.next().expect("an ROI for each completed segment")
        })
    }
}
