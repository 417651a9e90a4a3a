//! [`run_parallel`]: the stream in time chunks over worker threads (stages
//! 1–4), the tracker and the sums each in a thread of their own (stages
//! 5–7); and [`FrontResults`], the workers' results kept for a second back
//! end.

use super::back_threads::{split_back_end, sum_parts, FrontChunk, ParallelStats, PlaneFront};
use super::chunks::{fill_chunk, put_plane, CellState, ChunkCell, ChunkPool, Filling, SourcePlane};
use super::near_ahead::{AheadTests, LiveAnchors, NearAhead};
use super::FastFrontEnd;
use crate::config::PipelineConfig;
use crate::pipeline::{FrontEnd, PipelineError};
use crate::plane::BitPlane;
use crate::record::Record;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};

/// A chunk's planes as the reader hands them on.
enum ChunkPlanes<P> {
    /// Copied in by the reader (its cell filled already).
    Copied(Arc<Vec<BitPlane>>),
    /// For the worker to copy in.
    Lent(Vec<P>),
}

/// A time chunk of the stream on its way to a worker: its planes, the cell
/// they are (or go) to, and the (up to N) planes before it, oldest first,
/// as ranges of earlier chunks' cells (shared with the jobs that had them,
/// not copied: at N ≈ 1,000 planes of 512×512 a copy would cost more than
/// the filtering).
struct Job<P> {
    index: usize,
    planes: ChunkPlanes<P>,
    cell: Arc<ChunkCell>,
    history: Vec<(Arc<ChunkCell>, std::ops::Range<usize>)>,
}

/// A chunk back from a worker, with stages 1–4 of each of its planes, or
/// why its planes could not be written.
struct Done<E> {
    index: usize,
    result: Result<FrontChunk, E>,
}

/// The time chunk [`run_parallel`] is best given for a window of `n_window`
/// planes: N, 512 at least, so that short windows still hand out chunks of
/// useful size. Every chunk re-reads the N planes before it to warm its
/// counts up, but only their ones (a few hundred a plane at SMLM light
/// levels, against a plane's filtering), while the chunks in flight, and
/// with them memory and the run's fill and drain, grow with the chunk: at
/// the SPAD512S's N = 1,009 on 16 threads, 4N held 49 chunks of 130 MB.
pub fn default_chunk(n_window: u32) -> usize {
    (n_window as usize).max(512)
}

/// Stages 1–4 of planes from stream start, kept with the planes so that
/// stages 5–7 can run alone on them ([`FrontResults::replay_back_end`]): how
/// `smartagg bench aggregate` measures the back end, the part of
/// [`run_parallel`] that the workers do not share.
#[derive(Debug, Clone)]
pub struct FrontResults {
    cfg: PipelineConfig,
    /// The planes in chunks of [`default_chunk`], each with its stages 1–4.
    chunks: Vec<FrontChunk>,
}

impl FrontResults {
    /// Stages 1–4 (the fast front end) of `planes`, from stream start.
    pub fn compute(cfg: &PipelineConfig, planes: &[BitPlane]) -> FrontResults {
        let planes: Vec<BitPlane> = match &cfg.hot_mask {
            Some(m) => planes.iter().map(|p| m.apply(p)).collect(),
            None => planes.to_vec(),
        };
        // Chunk by chunk, as the workers compute them.
        let chunk = default_chunk(cfg.n_window);
        let n = cfg.n_window as usize;
        let mut fe = FastFrontEnd::new(cfg);
        let mut seen = Vec::new();
        let mut fronts = (0..planes.len())
            .step_by(chunk)
            .map(|start| {
                let history: Vec<&BitPlane> =
                    planes[start.saturating_sub(n)..start].iter().collect();
                let end = (start + chunk).min(planes.len());
                chunk_fronts(
                    &mut fe,
                    cfg,
                    start as u64,
                    &history,
                    &planes[start..end],
                    &[],
                    &mut seen,
                )
            })
            .collect::<Vec<_>>()
            .into_iter();
        // The planes move into their chunks: no second copy.
        let mut planes = planes.into_iter().peekable();
        let mut chunks = Vec::new();
        while planes.peek().is_some() {
            let c: Vec<BitPlane> = planes.by_ref().take(chunk).collect();
            let (fronts, ahead) = fronts.next().expect("stages 1–4 of every chunk");
            chunks.push(FrontChunk {
                planes: Arc::new(c),
                fronts,
                ahead,
            });
        }
        FrontResults {
            cfg: cfg.clone(),
            chunks,
        }
    }

    /// Planes held.
    pub fn len(&self) -> usize {
        self.chunks.iter().map(|c| c.planes.len()).sum()
    }

    /// Whether no plane is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Stages 5–7 alone — the tracker, the ROI sums and the records — on the
    /// planes and their stages 1–4, as [`run_parallel`] runs them for
    /// `threads` workers (the tracker, [`sum_parts`] threads of ROI sums and
    /// the records in threads of their own): the records of the whole
    /// stream (start to end), the same as
    /// [`fast_pipeline`](super::fast_pipeline)'s on the same planes. (No
    /// tracker runs beside the workers here, so the tests a worker makes
    /// ahead are those at its own candidates only.)
    pub fn replay_back_end(self, threads: usize) -> Result<Vec<Record>, PipelineError> {
        let cfg = self.cfg;
        cfg.validate()?;
        let mut out = vec![Record::Start(cfg.stream_start())];
        let anchors = LiveAnchors::default();
        let end = split_back_end(
            &cfg,
            self.chunks.into_iter(),
            sum_parts(threads),
            &anchors,
            |r| out.push(r),
            || {},
        )?;
        out.extend(end.records);
        Ok(out)
    }
}

/// The name of [`run_parallel`]'s reader thread (what `top -H` and
/// `/proc/PID/task/*/comm` show; `smartagg bench aggregate --stream` reports
/// the CPU of each role by these names). The records are made in the thread
/// that called [`run_parallel`].
pub const READER_THREAD: &str = "sa-reader";
/// The name of each of [`run_parallel`]'s worker threads (stages 1–4).
pub const WORKER_THREAD: &str = "sa-worker";
/// The name of [`run_parallel`]'s tracker thread (stage 5).
pub const TRACKER_THREAD: &str = "sa-tracker";
/// The name of each of [`run_parallel`]'s threads of ROI sums (stage 6).
pub const SUMS_THREAD: &str = "sa-sums";

/// Spawns `f` in `scope` as a thread named `name`; like `scope.spawn`, it
/// panics if the system cannot start a thread.
pub(super) fn spawn_named<'scope, T: Send + 'scope>(
    scope: &'scope std::thread::Scope<'scope, '_>,
    name: &str,
    f: impl FnOnce() -> T + Send + 'scope,
) -> std::thread::ScopedJoinHandle<'scope, T> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn_scoped(scope, f)
        .expect("the system could not start a thread")
}

/// Runs a stream on `threads` worker threads in time chunks of `chunk` planes,
/// calling `sink` with every record in stream order (start record first,
/// stream-end record last). Errors from the plane source stop the run and are
/// returned. The source gives planes away or lends references to them
/// ([`SourcePlane`]).
///
/// A reader thread pulls the planes (decoding or simulating them) into
/// chunks, copying the planes it is given into a chunk it recycles and
/// masking their hot pixels, or passing lent ones on; each worker takes the
/// next chunk as soon as it is free (no barrier between chunks), copies and
/// masks a lent chunk's planes into a recycled one, and computes its stages
/// 1–4, warmed up on the N planes before the chunk (the other chunks'
/// copies, by reference), and makes the tracker's 3×3 tests ahead at the
/// pixels its tracks are likely anchored at (`fast_engine/near_ahead.rs`);
/// stages 5–7 take the chunks in stream order, in threads (see
/// [`crate::back_end`] and `fast_engine/back_threads.rs`): the tracker in
/// a thread of its own, the ROI sums in [`sum_parts`] threads (each the
/// slots of one part), and the records in the calling thread, which calls
/// `sink`. At most `3·threads + 1` chunks are in flight, and the sums'
/// delay lines keep the chunks that hold their last N + 1 planes (by
/// reference: no plane is copied twice), so memory is bounded by
/// `(3·threads + 3)·chunk + (threads + 1)·N` planes, whatever the stream's
/// length. The answers made ahead take a bit a plane for each of at most
/// twice the slots a chunk.
pub fn run_parallel<E, P, I, S>(
    cfg: PipelineConfig,
    planes: I,
    threads: usize,
    chunk: usize,
    mut sink: S,
) -> Result<ParallelStats, ParallelError<E>>
where
    E: Send,
    P: SourcePlane<E>,
    I: Iterator<Item = Result<P, E>> + Send,
    S: FnMut(Record),
{
    cfg.validate()
        .map_err(|e| ParallelError::Pipeline(e.into()))?;
    let threads = threads.max(1);
    let chunk = chunk.max(1);
    let n = cfg.n_window as usize;
    sink(Record::Start(cfg.stream_start()));

    let (job_tx, job_rx) = std::sync::mpsc::sync_channel::<Job<P>>(threads);
    // Shared by the workers only: when the last one stops, the reader's
    // sends fail and it stops too.
    let job_rx = std::sync::Arc::new(std::sync::Mutex::new(job_rx));
    let (done_tx, done_rx) = std::sync::mpsc::sync_channel::<Done<E>>(threads);
    // Credits bound the chunks between the reader and the back end, however
    // unevenly the workers finish.
    let in_flight = 3 * threads + 1;
    let (credit_tx, credit_rx) = std::sync::mpsc::sync_channel::<()>(in_flight);
    for _ in 0..in_flight {
        credit_tx
            .send(())
            .expect("the credit channel holds them all");
    }
    let worker_cfg = &cfg;
    let pool = &ChunkPool::default();
    let anchors = &LiveAnchors::default();
    let failed = &Mutex::new(None);
    std::thread::scope(|scope| -> Result<ParallelStats, ParallelError<E>> {
        let (w, h) = (cfg.width, cfg.height);
        let reader = spawn_named(
            scope,
            READER_THREAD,
            move || -> Result<(), ParallelError<E>> {
                let mut planes = planes;
                let mut history: VecDeque<(Arc<ChunkCell>, std::ops::Range<usize>)> =
                    VecDeque::new();
                let mask = worker_cfg.hot_mask.as_ref();
                let mut scratch = Vec::new();
                for index in 0.. {
                    let (mut copied, mut lent) = (Vec::new(), Vec::new());
                    if P::WRITTEN_BY_READER {
                        copied = pool.take();
                    }
                    let mut len = 0;
                    while len < chunk {
                        match planes.next() {
                            // A plane of another size never reaches a worker.
                            Some(Ok(p)) if p.size() != (w, h) => {
                                let (got_w, got_h) = p.size();
                                return Err(ParallelError::Pipeline(PipelineError::PlaneSize {
                                    plane: (index * chunk + len) as u64,
                                    got_w,
                                    got_h,
                                    want_w: w,
                                    want_h: h,
                                }));
                            }
                            Some(Ok(p)) => {
                                if P::WRITTEN_BY_READER {
                                    put_plane(&mut copied, len, &p, mask, &mut scratch)
                                        .map_err(ParallelError::Source)?;
                                } else {
                                    lent.push(p);
                                }
                                len += 1;
                            }
                            Some(Err(e)) => return Err(ParallelError::Source(e)),
                            None => break,
                        }
                    }
                    if len == 0 {
                        break;
                    }
                    let full = len == chunk;
                    let cell = Arc::new(ChunkCell::default());
                    let planes = if P::WRITTEN_BY_READER {
                        copied.truncate(len);
                        let copied = Arc::new(copied);
                        pool.keep(&copied);
                        cell.set(CellState::Filled(copied.clone()));
                        ChunkPlanes::Copied(copied)
                    } else {
                        ChunkPlanes::Lent(lent)
                    };
                    let job_history: Vec<_> = history.iter().cloned().collect();
                    // The last N planes read: ranges of this and earlier chunks.
                    history.push_back((cell.clone(), 0..len));
                    let held: usize = history.iter().map(|(_, r)| r.len()).sum();
                    let mut excess = held.saturating_sub(n);
                    while excess > 0 {
                        let front = history.front_mut().expect("planes beyond N are held");
                        let drop = excess.min(front.1.len());
                        front.1.start += drop;
                        excess -= drop;
                        if front.1.is_empty() {
                            history.pop_front();
                        }
                    }
                    let job = Job {
                        index,
                        planes,
                        cell,
                        history: job_history,
                    };
                    if credit_rx.recv().is_err() || job_tx.send(job).is_err() || !full {
                        break;
                    }
                }
                Ok(())
            },
        );
        for _ in 0..threads {
            let (rx, tx) = (job_rx.clone(), done_tx.clone());
            spawn_named(scope, WORKER_THREAD, move || {
                let mut fe = FastFrontEnd::new(worker_cfg);
                let (mut scratch, mut seen) = (Vec::new(), Vec::new());
                loop {
                    let job = match rx.lock() {
                        Ok(rx) => rx.recv(),
                        Err(_) => return,
                    };
                    let Ok(job) = job else { return };
                    let planes = match job.planes {
                        ChunkPlanes::Copied(planes) => planes,
                        ChunkPlanes::Lent(source) => {
                            let filling = Filling(&job.cell);
                            let mut batch = pool.take();
                            let mask = worker_cfg.hot_mask.as_ref();
                            if let Err(e) = fill_chunk(&mut batch, &source, mask, &mut scratch) {
                                // The back end stops at this chunk; the
                                // workers of later ones stop at its cell.
                                drop(filling);
                                let _ = tx.send(Done {
                                    index: job.index,
                                    result: Err(e),
                                });
                                return;
                            }
                            let planes = Arc::new(batch);
                            pool.keep(&planes);
                            filling.fill(planes.clone());
                            planes
                        }
                    };
                    // The chunks before were taken first, so their workers
                    // are copying them (or have): a short wait at most.
                    let Some(history) = job
                        .history
                        .iter()
                        .map(|(cell, r)| cell.wait().map(|c| (c, r.clone())))
                        .collect::<Option<Vec<_>>>()
                    else {
                        return;
                    };
                    let history: Vec<&BitPlane> = history
                        .iter()
                        .flat_map(|(c, r)| c[r.clone()].iter())
                        .collect();
                    let start = (job.index * chunk) as u64;
                    let live = anchors.latest();
                    let (fronts, ahead) = chunk_fronts(
                        &mut fe, worker_cfg, start, &history, &planes, &live, &mut seen,
                    );
                    let done = Done {
                        index: job.index,
                        result: Ok(FrontChunk {
                            planes,
                            fronts,
                            ahead,
                        }),
                    };
                    if tx.send(done).is_err() {
                        return;
                    }
                }
            });
        }
        drop((job_rx, done_tx));
        // Stages 5–7 in stream order; chunks that come back early wait.
        // A chunk whose planes failed ends them: the records of the chunks
        // before it go out, as when the reader fails.
        let mut early: std::collections::BTreeMap<usize, Done<E>> = Default::default();
        let mut next = 0;
        let in_order = std::iter::from_fn(move || loop {
            if let Some(d) = early.remove(&next) {
                next += 1;
                return match d.result {
                    Ok(chunk) => Some(chunk),
                    Err(e) => {
                        *failed.lock().unwrap_or_else(PoisonError::into_inner) = Some(e);
                        None
                    }
                };
            }
            let d = done_rx.recv().ok()?;
            early.insert(d.index, d);
        });
        // The back end holds no credit: a failed send only means the reader
        // has finished.
        let back = split_back_end(
            &cfg,
            in_order,
            sum_parts(threads),
            anchors,
            &mut sink,
            move || {
                let _ = credit_tx.send(());
            },
        );
        // The back end has stopped the workers (their sends fail), hence
        // the reader.
        let read = reader.join().expect("the plane reader panicked");
        let end = back.map_err(ParallelError::Pipeline)?;
        // A chunk's error comes before any the reader met later.
        if let Some(e) = failed.lock().unwrap_or_else(PoisonError::into_inner).take() {
            return Err(ParallelError::Source(e));
        }
        read?;
        end.records.into_iter().for_each(&mut sink);
        Ok(end.stats)
    })
}

/// Stages 1–4 of every plane of a chunk that begins at plane `start`, and
/// the answers to the tracker's tests made ahead over it. `history` holds
/// the (up to N) planes before it, oldest first: all N of them, or every
/// plane since stream start (earlier planes are zero). `live` are the
/// anchors the tracker last published, and `seen` the worker's scratch for
/// the answers (a bitmap of the field, all clear).
fn chunk_fronts(
    fe: &mut FastFrontEnd,
    cfg: &PipelineConfig,
    start: u64,
    history: &[&BitPlane],
    planes: &[BitPlane],
    live: &[u32],
    seen: &mut Vec<u64>,
) -> (Vec<PlaneFront>, NearAhead) {
    let n = cfg.n_window as usize;
    let zero = BitPlane::zeros(cfg.width, cfg.height);
    let h = history.len();
    // Plane i of the chunk is at h + i in `history ++ planes`.
    let get = |j: usize| -> &BitPlane {
        if j < h {
            history[j]
        } else {
            &planes[j - h]
        }
    };
    fe.above.keep_bits(cfg.width * cfg.height);
    fe.rewarm(history.iter().copied());
    let mut tests = AheadTests::new(start, planes.len(), cfg.width, cfg.slots);
    if seen.is_empty() {
        *seen = vec![0; (cfg.width * cfg.height).div_ceil(64)];
    }
    tests.seed(live, seen);
    let fronts = planes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let delayed = (h + i).checked_sub(n).map_or(&zero, get);
            fe.push(p, delayed);
            tests.plane(fe, seen);
            PlaneFront {
                candidates: fe.candidates.clone(),
                above: fe.above.handed_on(),
            }
        })
        .collect();
    (fronts, tests.finish(seen))
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
