//! The golden streaming pipeline: stages 0–7 of docs/DESIGN.md §3, one bit-plane
//! at a time, integer-exact. Clear beats fast: this is the reference that the
//! fast software engine and the gateware must equal byte for byte.
//!
//! Per plane `t` the order of work is:
//! 1. mask hot pixels (stage 0); push `B_t` into the delay line, get `B_{t−N}`;
//! 2. rolling count `S_t` (stage 1), filter `H_t = K ⊛ S_t` (stage 2);
//! 3. evaluate the tracks live at the end of plane t−1 against `H_t` (stage 5);
//! 4. threshold and 3×3-maximum candidates (stages 3–4), associated in raster
//!    order, opening tracks in free slots (stage 5);
//! 5. ROI sums of the delayed plane `B_{t−N}` (stage 6, the slots' ranges);
//! 6. cuts, completions and slot frees; records out in slot order, then one
//!    dropped-candidates record if any candidate found no slot (stage 7).
//!
//! At stream end ([`Pipeline::finish`]): the segments still held, in slot
//! order (live ones TRUNCATED), then the StreamEnd record. `model/PACKETS.md`
//! §8 states this order and the tracking rules as the stream's contract.
//!
//! Every stage's output of the last plane is observable (for co-simulation).

use crate::back_end::{Summing, TrackStep, Tracking};
use crate::blink_tracker::BlinkTracker;
use crate::candidates::{self, Candidate};
use crate::config::{ConfigError, PipelineConfig};
use crate::delay_line::{DelayLine, SharedPlane};
use crate::plane::BitPlane;
use crate::record::{Record, MAX_PLANE};
use crate::roi_aggregator::RoiAggregator;
use crate::rolling_count::RollingCount;
use crate::spatial_filter::SpatialFilter;
use crate::threshold;
use thiserror::Error;

/// Misuse of a running pipeline.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PipelineError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A plane of the wrong size.
    #[error(
        "bit-plane {plane} is {got_w}x{got_h} but the pipeline is configured for {want_w}x{want_h}"
    )]
    PlaneSize {
        /// Plane index.
        plane: u64,
        /// Width received.
        got_w: usize,
        /// Height received.
        got_h: usize,
        /// Width expected.
        want_w: usize,
        /// Height expected.
        want_h: usize,
    },
    /// More planes than the packet format can index.
    #[error("stream longer than 2^48 bit-planes")]
    TooManyPlanes,
    /// A plane pushed after [`Pipeline::finish`].
    #[error("the stream has already been finished")]
    Finished,
}

/// Stages 1–4 (rolling count, filter, threshold, candidates) behind one
/// interface, so that a faster implementation can replace the golden one while
/// the tracker, ROI sums and records (stages 5–7) stay the reference code.
pub trait FrontEnd {
    /// Consumes plane t (`live`, already masked) and `B_{t−N}` (`delayed`).
    fn push(&mut self, live: &BitPlane, delayed: &BitPlane);
    /// Whether max of `H_t` over the 3×3 around (x, y), clipped to the sensor, is ≥ T_hold.
    fn neighbourhood_on(&self, x: usize, y: usize) -> bool;
    /// The tracker's test of the track in `slot`, anchored at (x, y):
    /// [`FrontEnd::neighbourhood_on`]. A front end that has some of the
    /// answers already (the parallel engine's workers test their own tracks
    /// ahead of the tracker) gives them by slot.
    fn slot_on(&self, slot: usize, x: usize, y: usize) -> bool {
        let _ = slot;
        self.neighbourhood_on(x, y)
    }
    /// Candidates of plane t, raster order.
    fn candidates(&self) -> &[Candidate];
}

/// The reference front end: [`RollingCount`], [`SpatialFilter`],
/// [`threshold`] and [`candidates::find`], exactly as written.
#[derive(Debug, Clone)]
pub struct GoldenFrontEnd {
    width: usize,
    height: usize,
    threshold_int: u32,
    threshold_hold: u32,
    rolling: RollingCount,
    filter: SpatialFilter,
    filtered: Vec<u32>,
    candidates: Vec<Candidate>,
}

impl GoldenFrontEnd {
    /// The golden stages 1–4 for a configuration.
    pub fn new(cfg: &PipelineConfig) -> GoldenFrontEnd {
        GoldenFrontEnd {
            width: cfg.width,
            height: cfg.height,
            threshold_int: cfg.threshold_int,
            threshold_hold: cfg.threshold_hold,
            rolling: RollingCount::new(cfg.width, cfg.height),
            filter: SpatialFilter::new(cfg.kernel.clone()),
            filtered: vec![0; cfg.width * cfg.height],
            candidates: Vec::new(),
        }
    }

    /// Stage 1 output: rolling counts `S_t`.
    pub fn counts(&self) -> &[u32] {
        self.rolling.counts()
    }

    /// Stage 2 output: `H_t`.
    pub fn filtered(&self) -> &[u32] {
        &self.filtered
    }
}

impl FrontEnd for GoldenFrontEnd {
    fn push(&mut self, live: &BitPlane, delayed: &BitPlane) {
        self.rolling.update(live, delayed);
        self.filtered = self
            .filter
            .apply(self.rolling.counts(), self.width, self.height);
        self.candidates =
            candidates::find(&self.filtered, self.width, self.height, self.threshold_int);
    }

    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        threshold::neighbourhood_on(
            &self.filtered,
            self.width,
            self.height,
            x,
            y,
            self.threshold_hold,
        )
    }

    fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }
}

/// The streaming smart-aggregation pipeline; `F` computes stages 1–4.
#[derive(Debug, Clone)]
pub struct Pipeline<F: FrontEnd = GoldenFrontEnd> {
    cfg: PipelineConfig,
    delay: DelayLine,
    front: F,
    tracking: Tracking,
    summing: Summing,
    /// The tracker's decisions of the current plane (kept between planes so
    /// that no plane allocates it).
    step: TrackStep,
    planes: u64,
    finished: bool,
}

impl Pipeline<GoldenFrontEnd> {
    /// The golden pipeline at stream start (all counts zero, all slots free).
    pub fn new(cfg: PipelineConfig) -> Result<Pipeline, PipelineError> {
        cfg.validate()?;
        let front = GoldenFrontEnd::new(&cfg);
        Pipeline::with_front_end(cfg, front)
    }

    /// Stage 1 output of the last plane: rolling counts `S_t`.
    pub fn counts(&self) -> &[u32] {
        self.front.counts()
    }

    /// Stage 2 output of the last plane: `H_t`.
    pub fn filtered(&self) -> &[u32] {
        self.front.filtered()
    }
}

impl<F: FrontEnd> Pipeline<F> {
    /// A pipeline at stream start whose stages 1–4 are computed by `front`
    /// (which must start from all-zero counts as well).
    pub fn with_front_end(cfg: PipelineConfig, front: F) -> Result<Pipeline<F>, PipelineError> {
        cfg.validate()?;
        let (w, h) = (cfg.width, cfg.height);
        Ok(Pipeline {
            delay: DelayLine::new(cfg.n_window as usize, w, h),
            front,
            tracking: Tracking::new(&cfg),
            summing: Summing::new(&cfg),
            step: TrackStep::default(),
            planes: 0,
            finished: false,
            cfg,
        })
    }

    /// The front end (stages 1–4).
    pub fn front_end(&self) -> &F {
        &self.front
    }

    /// The front end, mutably (to feed precomputed stages 1–4).
    pub fn front_end_mut(&mut self) -> &mut F {
        &mut self.front
    }

    /// The configuration.
    pub fn config(&self) -> &PipelineConfig {
        &self.cfg
    }

    /// The first record of the stream (the parameters).
    pub fn start_record(&self) -> Record {
        Record::Start(self.cfg.stream_start())
    }

    /// Planes processed so far.
    pub fn planes(&self) -> u64 {
        self.planes
    }

    /// Stage 4 output of the last plane: candidates in raster order.
    pub fn candidates(&self) -> &[Candidate] {
        self.front.candidates()
    }

    /// Stage 5 state: the tracker.
    pub fn tracker(&self) -> &BlinkTracker {
        self.tracking.tracker()
    }

    /// Stage 6 state: the ROI accumulators.
    pub fn rois(&self) -> &RoiAggregator {
        self.summing.rois()
    }

    /// Processes bit-plane `t = planes()` and returns the records completed by it.
    pub fn push_plane(&mut self, plane: &BitPlane) -> Result<Vec<Record>, PipelineError> {
        self.check(plane)?;
        // Stage 0. The delay line keeps the masked `B_t` and `B_{t−N}`;
        // both are read from it rather than copied.
        self.delay.push_masked(plane, self.cfg.hot_mask.as_ref());
        self.step()
    }

    /// [`Pipeline::push_plane`] for a plane whose hot pixels the caller has
    /// already forced to 0 with this configuration's mask, in a batch the
    /// caller shares (the parallel engine's reader masks each plane once,
    /// into chunks its back end shares): the same records, without masking
    /// the plane again, and the delay line keeps a reference to it instead
    /// of a copy.
    pub fn push_shared_plane(&mut self, plane: SharedPlane) -> Result<Vec<Record>, PipelineError> {
        self.check(plane.plane())?;
        self.delay.push_shared(plane);
        self.step()
    }

    /// Whether plane `t = planes()` may go in.
    fn check(&self, plane: &BitPlane) -> Result<(), PipelineError> {
        if self.finished {
            return Err(PipelineError::Finished);
        }
        let (w, h) = (self.cfg.width, self.cfg.height);
        if plane.width() != w || plane.height() != h {
            return Err(PipelineError::PlaneSize {
                plane: self.planes,
                got_w: plane.width(),
                got_h: plane.height(),
                want_w: w,
                want_h: h,
            });
        }
        check_plane_number(self.planes)
    }

    /// Stages 1–7 of plane `t = planes()`, just pushed into the delay line.
    fn step(&mut self) -> Result<Vec<Record>, PipelineError> {
        let t = self.planes;
        self.front.push(self.delay.newest(), self.delay.delayed());
        self.tracking.step(t, &self.front, &mut self.step);
        let out = self.summing.step(t, &self.step, &self.delay);
        self.planes += 1;
        Ok(out)
    }

    /// Ends the stream: closes live tracks (TRUNCATED), completes their
    /// sums from the delay line, and returns the last blink records and
    /// the stream-end record. Further planes are refused.
    pub fn finish(&mut self) -> Vec<Record> {
        if self.finished {
            return Vec::new();
        }
        self.finished = true;
        let end = self.tracking.finish(self.planes);
        self.summing.finish(self.planes, end, &self.delay)
    }
}

/// Whether plane `t` may go in: its number must fit the records' 48 bits.
pub(crate) fn check_plane_number(t: u64) -> Result<(), PipelineError> {
    if t > MAX_PLANE {
        Err(PipelineError::TooManyPlanes)
    } else {
        Ok(())
    }
}

/// Runs a whole stream through the golden pipeline: the start record, every
/// plane's records, and the records of [`Pipeline::finish`].
pub fn run<I>(cfg: PipelineConfig, planes: I) -> Result<Vec<Record>, PipelineError>
where
    I: IntoIterator<Item = BitPlane>,
{
    run_with(Pipeline::new(cfg)?, planes)
}

/// Runs a whole stream through a pipeline with any front end; the planes
/// may be given by value or by reference.
pub fn run_with<F, I>(mut p: Pipeline<F>, planes: I) -> Result<Vec<Record>, PipelineError>
where
    F: FrontEnd,
    I: IntoIterator,
    I::Item: std::borrow::Borrow<BitPlane>,
{
    let mut out = vec![p.start_record()];
    for plane in planes {
        out.extend(p.push_plane(std::borrow::Borrow::borrow(&plane))?);
    }
    out.extend(p.finish());
    Ok(out)
}
