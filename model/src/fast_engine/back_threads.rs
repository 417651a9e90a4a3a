//! Stages 5–7 of [`run_parallel`](super::run_parallel) in threads, on the
//! workers' results: the tracker (stage 5) in a thread of its own, replaying
//! the workers' stages 1–4 and reading the answers they made ahead to its
//! tests; the ROI sums (stage 6) in [`sum_parts`] threads, each the slots
//! of one part; the records (stage 7) in the calling thread.

use super::above::AbovePlane;
use super::near_ahead::{Bound, LiveAnchors, NearAhead};
use super::parallel::{spawn_named, SUMS_THREAD, TRACKER_THREAD};
use crate::back_end::{Records, RoiSum, RoiSums, TrackEnd, TrackStep, Tracking};
use crate::blink_tracker::Slot;
use crate::candidates::Candidate;
use crate::config::PipelineConfig;
use crate::delay_line::{DelayLine, SharedPlane};
use crate::pipeline::{check_plane_number, FrontEnd, PipelineError};
use crate::plane::BitPlane;
use crate::record::Record;
use std::collections::VecDeque;
use std::sync::Arc;

/// Stages 1–4 of one plane, as computed by a worker.
#[derive(Debug, Clone, Default)]
pub(super) struct PlaneFront {
    pub(super) candidates: Vec<Candidate>,
    pub(super) above: AbovePlane,
}

/// A chunk's planes with the workers' results: stages 1–4 of each plane,
/// and the answers to the tracker's tests made ahead.
#[derive(Debug, Clone)]
pub(super) struct FrontChunk {
    pub(super) planes: Arc<Vec<BitPlane>>,
    pub(super) fronts: Vec<PlaneFront>,
    pub(super) ahead: NearAhead,
}

/// Replays precomputed stages 1–4 to the tracker (stage 5) of the back end,
/// with the answers the workers made ahead to its tests.
#[derive(Debug, Default)]
struct ReplayFrontEnd {
    width: usize,
    height: usize,
    queue: VecDeque<PlaneFront>,
    current: PlaneFront,
    /// The plane being tracked.
    t: u64,
    /// The current chunk's answers made ahead.
    ahead: NearAhead,
    /// Each slot's track's answers, when the workers made them.
    bound: Vec<Option<Bound>>,
    /// The tests so far, and those answered ahead.
    stats: std::cell::Cell<ParallelStats>,
}

impl ReplayFrontEnd {
    /// Takes a chunk's stages 1–4 and answers, and binds the live tracks in
    /// `slots` to them (the answers of the chunk before end with it);
    /// returns the live tracks' anchors, for the workers of later chunks.
    fn start_chunk(
        &mut self,
        fronts: Vec<PlaneFront>,
        ahead: NearAhead,
        slots: &[Slot],
    ) -> Vec<u32> {
        self.queue.extend(fronts);
        self.ahead = ahead;
        let mut live = Vec::new();
        for (b, slot) in self.bound.iter_mut().zip(slots) {
            *b = match slot {
                Slot::Busy(seg) if seg.live => {
                    let pixel = raster(self.width, seg.anchor_x, seg.anchor_y);
                    live.push(pixel);
                    self.ahead.find(pixel)
                }
                _ => None,
            };
        }
        live
    }

    /// Takes plane `t`'s stages 1–4 from the queue.
    fn next_plane(&mut self, t: u64) {
        self.t = t;
        self.current = self
            .queue
            .pop_front()
            .expect("a precomputed front end per plane");
        // The tests the workers did not answer read the plane's pixels at
        // the hold level: a worker wrote them a while ago, and on a large
        // field (thousands of them) each test would wait on memory. Fetch
        // the next plane's while this one is tracked.
        if let Some(next) = self.queue.front() {
            next.above.prefetch();
        }
    }

    /// Binds the tracks opened at the current plane to the workers' answers.
    fn bind(&mut self, opened: &[(u16, u16, u16)]) {
        for &(slot, x, y) in opened {
            self.bound[slot as usize] = self.ahead.find(raster(self.width, x, y));
        }
    }
}

impl FrontEnd for ReplayFrontEnd {
    fn push(&mut self, _live: &BitPlane, _delayed: &BitPlane) {
        self.next_plane(self.t + 1);
    }

    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        self.current.above.near(self.width, self.height, x, y)
    }

    fn slot_on(&self, slot: usize, x: usize, y: usize) -> bool {
        let ahead = self.bound[slot].and_then(|b| self.ahead.on(b, self.t));
        let mut stats = self.stats.get();
        stats.tracker_tests += 1;
        stats.answered_ahead += u64::from(ahead.is_some());
        self.stats.set(stats);
        ahead.unwrap_or_else(|| self.neighbourhood_on(x, y))
    }

    fn candidates(&self) -> &[Candidate] {
        &self.current.candidates
    }
}

/// Pixel (x, y)'s raster index on a field `width` wide.
fn raster(width: usize, x: u16, y: u16) -> u32 {
    (y as usize * width + x as usize) as u32
}

/// What a run of [`run_parallel`](super::run_parallel) did besides its records.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ParallelStats {
    /// The tracker's 3×3 tests: one a live track a plane.
    pub tracker_tests: u64,
    /// Of those, the ones the workers had made ahead (see the fast engine's
    /// module doc): the tracker read their answers instead of the plane.
    pub answered_ahead: u64,
}

/// The end of [`split_back_end`]'s stream.
pub(super) struct BackEnd {
    /// The records of the stream's end.
    pub(super) records: Vec<Record>,
    pub(super) stats: ParallelStats,
}

/// Planes of a chunk and the tracker's decisions at each, on their way from
/// the tracker's thread to the sums: a few hundred at a time, so that the
/// sums start soon after the tracker (a chunk can be thousands of planes).
struct Tracked {
    planes: Arc<Vec<BitPlane>>,
    range: std::ops::Range<usize>,
    steps: Vec<TrackStep>,
}

/// Planes the tracker hands to the sums at a time.
const HANDOFF: usize = 128;

/// What the tracker hands to each thread of ROI sums.
enum ToSums {
    Planes(Arc<Tracked>),
    /// The stream's end: the segments still held.
    End(Arc<TrackEnd>),
}

/// What a thread of ROI sums hands to the records: the ROIs its slots
/// completed, in order, at the tracker's planes, or at the stream's end.
enum FromSums {
    Planes(Arc<Tracked>, Vec<RoiSum>),
    End(Vec<RoiSum>),
}

/// The threads of ROI sums (stage 6) for `threads` workers: each sums the
/// slots of one part ([`RoiSums`]), on the same steps and planes. One
/// sums as fast as the tracker on a SPAD512S field; more workers feed more
/// planes.
pub fn sum_parts(threads: usize) -> usize {
    threads.div_ceil(8).clamp(1, 4)
}

/// Stages 5–7 on chunks in stream order (each chunk's planes with their
/// stages 1–4), in threads: the tracker ([`Tracking`]) in a thread of its
/// own, a few hundred planes ahead of `parts` threads of ROI sums
/// ([`RoiSums`], each the slots of one part), ahead of the records
/// ([`Records`]), which are made in the calling thread. `sink` gets each
/// plane's records in stream order and `chunk_done` is called once a
/// chunk's have all gone; the records of the stream's end are returned (not
/// sunk), so that the caller can hold them back if the stream failed.
pub(super) fn split_back_end<C>(
    cfg: &PipelineConfig,
    chunks: C,
    parts: usize,
    anchors: &LiveAnchors,
    mut sink: impl FnMut(Record),
    chunk_done: impl FnMut(),
) -> Result<BackEnd, PipelineError>
where
    C: Iterator<Item = FrontChunk> + Send,
{
    let parts = parts.max(1);
    let (to_sums, sums_in): (Vec<_>, Vec<_>) = (0..parts)
        .map(|_| std::sync::mpsc::sync_channel::<ToSums>(4))
        .unzip();
    let (sums_out, from_sums): (Vec<_>, Vec<_>) = (0..parts)
        .map(|_| std::sync::mpsc::sync_channel::<FromSums>(4))
        .unzip();
    std::thread::scope(|scope| {
        let tracker = spawn_named(
            scope,
            TRACKER_THREAD,
            move || -> (TrackEnd, ParallelStats) {
                let mut tracking = Tracking::new(cfg);
                let mut front = ReplayFrontEnd {
                    width: cfg.width,
                    height: cfg.height,
                    bound: vec![None; cfg.slots],
                    ..Default::default()
                };
                let mut t = 0u64;
                // A failed send: the sums have stopped.
                let send = |m: &dyn Fn() -> ToSums| to_sums.iter().all(|tx| tx.send(m()).is_ok());
                'chunks: for FrontChunk {
                    planes,
                    fronts,
                    ahead,
                } in chunks
                {
                    anchors.publish(front.start_chunk(fronts, ahead, tracking.tracker().slots()));
                    let len = planes.len();
                    for start in (0..len).step_by(HANDOFF) {
                        let range = start..(start + HANDOFF).min(len);
                        let steps = range
                            .clone()
                            .map(|_| {
                                front.next_plane(t);
                                let mut step = TrackStep::default();
                                tracking.step(t, &front, &mut step);
                                front.bind(&step.opened);
                                t += 1;
                                step
                            })
                            .collect();
                        let tracked = Arc::new(Tracked {
                            planes: planes.clone(),
                            range,
                            steps,
                        });
                        if !send(&|| ToSums::Planes(tracked.clone())) {
                            break 'chunks;
                        }
                    }
                }
                let end = tracking.finish(t);
                let shared = Arc::new(end.clone());
                send(&|| ToSums::End(shared.clone()));
                (end, front.stats.get())
            },
        );
        for (part, (rx, tx)) in sums_in.into_iter().zip(sums_out).enumerate() {
            spawn_named(scope, SUMS_THREAD, move || {
                let mut delay = DelayLine::new(cfg.n_window as usize, cfg.width, cfg.height);
                let mut sums = RoiSums::new(cfg, part, parts);
                let mut t = 0u64;
                for m in rx {
                    let out = match m {
                        ToSums::Planes(tracked) => {
                            let mut done = Vec::new();
                            let planes =
                                SharedPlane::within(&tracked.planes, tracked.range.clone());
                            for (plane, step) in planes.zip(&tracked.steps) {
                                delay.push_shared(plane);
                                sums.step(step, &delay, &mut done);
                                t += 1;
                            }
                            FromSums::Planes(tracked, done)
                        }
                        ToSums::End(end) => {
                            let mut done = Vec::new();
                            sums.finish(t, &end, &delay, &mut done);
                            FromSums::End(done)
                        }
                    };
                    // A failed send: the records have stopped.
                    if tx.send(out).is_err() {
                        return;
                    }
                }
            });
        }
        let mut chunk_done = chunk_done;
        let mut records = Records::new(cfg);
        let mut t = 0u64;
        let mut result = Ok(());
        let mut end_sums = None;
        'planes: loop {
            // One message from each part: the same planes, or the end.
            let mut tracked = None;
            let mut done = Vec::with_capacity(parts);
            for rx in &from_sums {
                match rx.recv() {
                    Ok(FromSums::Planes(planes, d)) => {
                        tracked = Some(planes);
                        done.push(d.into_iter());
                    }
                    Ok(FromSums::End(d)) => done.push(d.into_iter()),
                    // A part stopped: so did the tracker.
                    Err(_) => break 'planes,
                }
            }
            let Some(tracked) = tracked else {
                end_sums = Some(done);
                break;
            };
            let mut roi = |slot: usize| {
                done[slot % parts]
                    .next()
                    .expect("an ROI for each completed segment")
            };
            for step in &tracked.steps {
                if let Err(e) = check_plane_number(t) {
                    result = Err(e);
                    break 'planes;
                }
                records
                    .step(t, step, &mut roi)
                    .into_iter()
                    .for_each(&mut sink);
                t += 1;
            }
            if tracked.range.end == tracked.planes.len() {
                chunk_done();
            }
        }
        // The sums stop at their next send, then the tracker at its next
        // one, and drops its chunks (which stops whoever feeds them);
        // `chunk_done` may hold what lets them be fed, so it goes first.
        drop((from_sums, chunk_done));
        let (end, stats) = tracker.join().expect("the tracker's thread panicked");
        result?;
        let mut done = end_sums.expect("the sums of the stream's end");
        let records = records.finish(t, end, |slot| {
            done[slot % parts]
                .next()
                .expect("an ROI for each segment still held")
        });
        Ok(BackEnd { records, stats })
    })
}
