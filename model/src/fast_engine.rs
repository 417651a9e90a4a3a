//! The fast software engine: the same records (hence the same packet bytes)
//! as the golden pipeline, at or above the camera's rate.
//!
//! Only stages 1–4 are replaced — they are where the time goes (a dense filter
//! costs 2k multiply-adds per pixel per plane). Stages 5–7 (tracker, ROI sums,
//! records) are the golden code itself, through [`Pipeline::with_front_end`].
//!
//! * [`FastFrontEnd`] keeps H up to date *incrementally*: H changes only where
//!   `B_t` and `B_{t−N}` differ (a few percent of pixels at SMLM light levels),
//!   and each change adds `±K` to the k×k neighbourhood (row slices, vectorised;
//!   a halo of (k−1)/2 around the field removes every bounds check). When more
//!   than an eighth of the pixels change (saturated planes) it recomputes H
//!   densely from the rolling counts instead. Threshold and candidates then
//!   touch only the pixels above threshold.
//! * [`run_parallel`] splits the stream into time chunks. H at plane t depends
//!   only on planes `t−N+1 … t`, so a worker can start a chunk anywhere after
//!   warming its counts up on the N planes before it; the workers' per-plane
//!   results (candidates and above-threshold pixels) then feed the one
//!   sequential tracker, which is cheap. The output is byte-identical to the
//!   single-threaded golden pipeline for any chunk length and thread count.

use crate::candidates::Candidate;
use crate::config::PipelineConfig;
use crate::pipeline::{FrontEnd, Pipeline, PipelineError};
use crate::plane::BitPlane;
use crate::record::Record;
use crate::spatial_filter::SpatialFilter;
use std::collections::VecDeque;

/// Above this fraction of changed pixels a plane is filtered densely.
const DENSE_FRACTION: usize = 8;

/// Incremental stages 1–4.
#[derive(Debug, Clone)]
pub struct FastFrontEnd {
    width: usize,
    height: usize,
    half: usize,
    stride: usize,
    kernel_2d: Vec<u32>,
    k1: Vec<u32>,
    threshold_int: u32,
    /// Rolling counts S, raster order (kept for dense recomputation).
    counts: Vec<u16>,
    /// H with a halo of `half` on every side; halo cells are never read.
    filtered: Vec<u32>,
    /// Raster indices with H ≥ T_int, ascending.
    above: Vec<u32>,
    candidates: Vec<Candidate>,
    changed: Vec<(u32, bool)>,
}

impl FastFrontEnd {
    /// All-zero counts, as at stream start.
    pub fn new(cfg: &PipelineConfig) -> FastFrontEnd {
        let k = cfg.kernel.len();
        let half = k / 2;
        let stride = cfg.width + 2 * half;
        let mut kernel_2d = Vec::with_capacity(k * k);
        for &a in &cfg.kernel {
            for &b in &cfg.kernel {
                kernel_2d.push(a * b);
            }
        }
        FastFrontEnd {
            width: cfg.width,
            height: cfg.height,
            half,
            stride,
            kernel_2d,
            k1: cfg.kernel.clone(),
            threshold_int: cfg.threshold_int,
            counts: vec![0; cfg.width * cfg.height],
            filtered: vec![0; stride * (cfg.height + 2 * half)],
            above: Vec::new(),
            candidates: Vec::new(),
            changed: Vec::new(),
        }
    }

    /// Starts mid-stream: the counts of the N planes before the first plane
    /// that will be pushed (`window` holds them, oldest first, up to N).
    pub fn warmed_up<'a>(
        cfg: &PipelineConfig,
        window: impl IntoIterator<Item = &'a BitPlane>,
    ) -> FastFrontEnd {
        let mut fe = FastFrontEnd::new(cfg);
        for plane in window {
            for (c, b) in fe.counts.iter_mut().zip(plane.bits().iter().by_vals()) {
                *c += b as u16;
            }
        }
        fe.recompute_dense();
        fe
    }

    /// `H_t` at (x, y).
    pub fn filtered_at(&self, x: usize, y: usize) -> u32 {
        self.filtered[(y + self.half) * self.stride + x + self.half]
    }

    /// Raster indices of the pixels with `H_t ≥ T_int`, ascending.
    pub fn above(&self) -> &[u32] {
        &self.above
    }

    fn recompute_dense(&mut self) {
        let counts: Vec<u32> = self.counts.iter().map(|&c| c as u32).collect();
        let h = SpatialFilter::new(self.k1.clone()).apply(&counts, self.width, self.height);
        for y in 0..self.height {
            let dst = (y + self.half) * self.stride + self.half;
            self.filtered[dst..dst + self.width]
                .copy_from_slice(&h[y * self.width..(y + 1) * self.width]);
        }
    }

    fn add_kernel(&mut self, x: usize, y: usize, plus: bool) {
        // Fixed kernel sizes let the compiler keep each row in vector registers.
        match self.k1.len() {
            3 => self.add_kernel_k::<3>(x, y, plus),
            5 => self.add_kernel_k::<5>(x, y, plus),
            7 => self.add_kernel_k::<7>(x, y, plus),
            9 => self.add_kernel_k::<9>(x, y, plus),
            11 => self.add_kernel_k::<11>(x, y, plus),
            13 => self.add_kernel_k::<13>(x, y, plus),
            _ => self.add_kernel_any(x, y, plus),
        }
    }

    fn add_kernel_k<const K: usize>(&mut self, x: usize, y: usize, plus: bool) {
        for dy in 0..K {
            let row = (y + dy) * self.stride + x;
            let dst: &mut [u32; K] = (&mut self.filtered[row..row + K])
                .try_into()
                .expect("K cells");
            let w: &[u32; K] = self.kernel_2d[dy * K..(dy + 1) * K]
                .try_into()
                .expect("K weights");
            if plus {
                for i in 0..K {
                    dst[i] = dst[i].wrapping_add(w[i]);
                }
            } else {
                for i in 0..K {
                    dst[i] = dst[i].wrapping_sub(w[i]);
                }
            }
        }
    }

    fn add_kernel_any(&mut self, x: usize, y: usize, plus: bool) {
        let k = self.k1.len();
        for dy in 0..k {
            let row = (y + dy) * self.stride + x;
            let dst = &mut self.filtered[row..row + k];
            let w = &self.kernel_2d[dy * k..(dy + 1) * k];
            if plus {
                for (d, &kw) in dst.iter_mut().zip(w) {
                    *d = d.wrapping_add(kw);
                }
            } else {
                for (d, &kw) in dst.iter_mut().zip(w) {
                    *d = d.wrapping_sub(kw);
                }
            }
        }
    }

    fn scan_above(&mut self) {
        self.above.clear();
        let thr = self.threshold_int;
        for y in 0..self.height {
            let start = (y + self.half) * self.stride + self.half;
            let row = &self.filtered[start..start + self.width];
            // Cheap rejection of whole 16-pixel blocks first (vectorises).
            for (bi, block) in row.chunks(16).enumerate() {
                if block.iter().fold(0u32, |m, &v| m | u32::from(v >= thr)) == 0 {
                    continue;
                }
                for (j, &v) in block.iter().enumerate() {
                    if v >= thr {
                        self.above.push((y * self.width + bi * 16 + j) as u32);
                    }
                }
            }
        }
    }

    fn find_candidates(&mut self) {
        self.candidates.clear();
        let (w, h) = (self.width as i64, self.height as i64);
        for &i in &self.above {
            let (x, y) = (
                (i as usize % self.width) as i64,
                (i as usize / self.width) as i64,
            );
            let v = self.filtered_at(x as usize, y as usize);
            let at = |dx: i64, dy: i64| -> Option<u32> {
                let (xx, yy) = (x + dx, y + dy);
                (xx >= 0 && yy >= 0 && xx < w && yy < h)
                    .then(|| self.filtered_at(xx as usize, yy as usize))
            };
            let earlier = [(-1, -1), (0, -1), (1, -1), (-1, 0)];
            let later = [(1, 0), (-1, 1), (0, 1), (1, 1)];
            if earlier
                .iter()
                .all(|&(dx, dy)| at(dx, dy).is_none_or(|n| v > n))
                && later
                    .iter()
                    .all(|&(dx, dy)| at(dx, dy).is_none_or(|n| v >= n))
            {
                self.candidates.push(Candidate {
                    x: x as u16,
                    y: y as u16,
                });
            }
        }
    }
}

impl FrontEnd for FastFrontEnd {
    fn push(&mut self, live: &BitPlane, delayed: &BitPlane) {
        self.changed.clear();
        let (lw, dw) = (live.words(), delayed.words());
        let total = self.width * self.height;
        for (wi, (&a, &b)) in lw.iter().zip(dw).enumerate() {
            let mut diff = a ^ b;
            while diff != 0 {
                let bit = diff.trailing_zeros() as usize;
                diff &= diff - 1;
                let idx = wi * 64 + bit;
                if idx < total {
                    self.changed.push((idx as u32, (a >> bit) & 1 == 1));
                }
            }
        }
        for &(idx, plus) in &self.changed {
            let c = &mut self.counts[idx as usize];
            *c = if plus { *c + 1 } else { *c - 1 };
        }
        if self.changed.len() * DENSE_FRACTION > total {
            self.recompute_dense();
        } else {
            let changed = std::mem::take(&mut self.changed);
            for &(idx, plus) in &changed {
                self.add_kernel(idx as usize % self.width, idx as usize / self.width, plus);
            }
            self.changed = changed;
        }
        self.scan_above();
        self.find_candidates();
    }

    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        above_near(&self.above, self.width, self.height, x, y)
    }

    fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }
}

/// Whether any pixel of the 3×3 around (x, y) is in the ascending list `above`.
fn above_near(above: &[u32], width: usize, height: usize, x: usize, y: usize) -> bool {
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(width - 1));
    (y.saturating_sub(1)..=(y + 1).min(height - 1)).any(|yy| {
        let (lo, hi) = ((yy * width + x0) as u32, (yy * width + x1) as u32);
        let i = above.partition_point(|&a| a < lo);
        i < above.len() && above[i] <= hi
    })
}

/// The fast engine, single-threaded: the golden pipeline with [`FastFrontEnd`].
pub fn fast_pipeline(cfg: PipelineConfig) -> Result<Pipeline<FastFrontEnd>, PipelineError> {
    cfg.validate()?;
    let front = FastFrontEnd::new(&cfg);
    Pipeline::with_front_end(cfg, front)
}

/// Stages 1–4 of one plane, as computed by a worker.
#[derive(Debug, Clone, Default)]
struct PlaneFront {
    candidates: Vec<Candidate>,
    above: Vec<u32>,
}

/// Replays precomputed stages 1–4 to the sequential back end.
#[derive(Debug, Default)]
struct ReplayFrontEnd {
    width: usize,
    height: usize,
    queue: VecDeque<PlaneFront>,
    current: PlaneFront,
}

impl FrontEnd for ReplayFrontEnd {
    fn push(&mut self, _live: &BitPlane, _delayed: &BitPlane) {
        self.current = self
            .queue
            .pop_front()
            .expect("a precomputed front end per plane");
    }

    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        above_near(&self.current.above, self.width, self.height, x, y)
    }

    fn candidates(&self) -> &[Candidate] {
        &self.current.candidates
    }
}

/// Runs a stream on `threads` worker threads in time chunks of `chunk` planes,
/// calling `sink` with every record in stream order (start record first,
/// stream-end record last). Memory is bounded by `threads × chunk + N` planes,
/// whatever the length of the stream. Errors from the plane source stop the
/// run and are returned.
pub fn run_parallel<E, I, S>(
    cfg: PipelineConfig,
    planes: I,
    threads: usize,
    chunk: usize,
    mut sink: S,
) -> Result<(), ParallelError<E>>
where
    E: Send,
    I: Iterator<Item = Result<BitPlane, E>> + Send,
    S: FnMut(Record),
{
    cfg.validate()
        .map_err(|e| ParallelError::Pipeline(e.into()))?;
    let threads = threads.max(1);
    let chunk = chunk.max(1);
    let n = cfg.n_window as usize;
    let mut back = Pipeline::with_front_end(
        cfg.clone(),
        ReplayFrontEnd {
            width: cfg.width,
            height: cfg.height,
            ..Default::default()
        },
    )
    .map_err(ParallelError::Pipeline)?;
    sink(back.start_record());

    type Batch = (Vec<BitPlane>, Vec<PlaneFront>);
    let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Batch, E>>(1);
    let worker_cfg = cfg.clone();
    std::thread::scope(|scope| -> Result<(), ParallelError<E>> {
        // Producer: reads planes, computes stages 1–4 of a batch of chunks in
        // parallel, and hands the batch to the back end.
        scope.spawn(move || {
            let mut planes = planes;
            let mut history: VecDeque<BitPlane> = VecDeque::with_capacity(n);
            loop {
                let mut batch = Vec::with_capacity(threads * chunk);
                for _ in 0..threads * chunk {
                    match planes.next() {
                        Some(Ok(p)) => batch.push(match &worker_cfg.hot_mask {
                            Some(m) => m.apply(&p),
                            None => p,
                        }),
                        Some(Err(e)) => {
                            let _ = tx.send(Err(e));
                            return;
                        }
                        None => break,
                    }
                }
                if batch.is_empty() {
                    return;
                }
                let fronts = front_ends(&worker_cfg, &history, &batch, chunk);
                for p in batch.iter().skip(batch.len().saturating_sub(n)) {
                    if history.len() == n {
                        history.pop_front();
                    }
                    history.push_back(p.clone());
                }
                let full = batch.len() == threads * chunk;
                if tx.send(Ok((batch, fronts))).is_err() || !full {
                    return;
                }
            }
        });
        for msg in rx {
            let (batch, fronts) = msg.map_err(ParallelError::Source)?;
            back.front_end_mut().queue.extend(fronts);
            for plane in &batch {
                for r in back.push_plane(plane).map_err(ParallelError::Pipeline)? {
                    sink(r);
                }
            }
        }
        Ok(())
    })?;
    for r in back.finish() {
        sink(r);
    }
    Ok(())
}

/// Stages 1–4 of every plane of `batch`, one scoped thread per chunk.
/// `history` holds the (up to N) planes before the batch, oldest first: all N
/// of them, or every plane since stream start (earlier planes are zero).
fn front_ends(
    cfg: &PipelineConfig,
    history: &VecDeque<BitPlane>,
    batch: &[BitPlane],
    chunk: usize,
) -> Vec<PlaneFront> {
    let n = cfg.n_window as usize;
    let zero = BitPlane::zeros(cfg.width, cfg.height);
    // Plane i of the batch has global offset h + i in `history ++ batch`.
    let h = history.len();
    let get = |j: isize| -> &BitPlane {
        if j < 0 {
            &zero
        } else if (j as usize) < h {
            &history[j as usize]
        } else {
            &batch[j as usize - h]
        }
    };
    let one_chunk = |c: usize| -> Vec<PlaneFront> {
        let start = c * chunk;
        let end = (start + chunk).min(batch.len());
        let g0 = (h + start) as isize;
        // Before the stream start the planes are zero; `history` holds at most N.
        let window = (g0 - n as isize..g0).filter(|&j| j >= 0).map(get);
        let mut fe = FastFrontEnd::warmed_up(cfg, window);
        (start..end)
            .map(|i| {
                let g = (h + i) as isize;
                fe.push(&batch[i], get(g - n as isize));
                PlaneFront {
                    candidates: fe.candidates.clone(),
                    above: fe.above.clone(),
                }
            })
            .collect()
    };
    let chunks = batch.len().div_ceil(chunk);
    if chunks == 1 {
        return one_chunk(0);
    }
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..chunks).map(|c| s.spawn(move || one_chunk(c))).collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a front-end worker panicked"))
            .collect()
    })
}

/// Why a parallel run stopped.
#[derive(Debug, thiserror::Error)]
pub enum ParallelError<E> {
    /// The plane source failed.
    #[error("reading bit-planes: {0}")]
    Source(E),
    /// The pipeline refused a plane or the configuration.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
}
