//! The fast software engine: the same records (hence the same packet bytes)
//! as the golden pipeline, at or above the camera's rate.
//!
//! Only stages 1–4 are replaced — they are where the time goes (a dense filter
//! costs 2k multiply-adds per pixel per plane). Stages 5–7 (tracker, ROI sums,
//! records) are the golden code itself, through [`Pipeline::with_front_end`].
//!
//! * [`FastFrontEnd`] keeps H up to date *incrementally*: H changes only where
//!   `B_t` and `B_{t−N}` differ (a few percent of pixels at SMLM light
//!   levels), found 64 pixels at a time as the set bits of `B_t XOR B_{t−N}`;
//!   each change adds `±K` to its k×k neighbourhood (branch-free: `+K` or the
//!   wrapping `−K`; each kernel row as whole vector adds; a halo around the
//!   field removes every bounds test). When more than an eighth of the pixels
//!   change (saturated planes) it recomputes H densely from the rolling counts
//!   instead. Threshold and candidates are one pass that skips runs of 64
//!   and 32 pixels below the hold level and tests eight pixels at a time
//!   against the two levels and their neighbours (`fast_engine/block.rs`).
//!   On x86-64 with AVX2 (detected at run time) the same code is compiled a
//!   second time for AVX2, with explicit AVX2 compares in the scan.
//! * [`run_parallel`] splits the stream into time chunks. H at plane t depends
//!   only on planes `t−N+1 … t`, so a worker can start a chunk anywhere after
//!   warming its counts up on the N planes before it; the workers' per-plane
//!   results (candidates and the pixels at the hold level, as a list or,
//!   on a crowded plane, as a bitmap: `fast_engine/above.rs`) then feed the
//!   one sequential tracker. Its 3×3 tests, which on a large field would
//!   each wait on memory, are made ahead by the workers on H while it is in
//!   their cache, at the pixels the tracks are likely anchored at (the
//!   chunk's candidates and the anchors the tracker last published:
//!   `fast_engine/near_ahead.rs`); the ROI sums run in threads of their own,
//!   each the slots of one part (`fast_engine/back_threads.rs`). A reader
//!   thread pulls the planes meanwhile, and each worker takes the next chunk
//!   as soon as it is free;
//!   planes lent (references, or a recording's planes at their indices:
//!   [`crate::recording::PlaneFile`]) are copied or read by that worker, not
//!   the reader (`fast_engine/chunks.rs`).
//!   The output is byte-identical to the single-threaded golden pipeline for
//!   any chunk length and thread count, and memory is bounded by the chunk
//!   length, the threads, N and the field, not by the stream's length.

mod above;
mod back_threads;
mod block;
mod chunks;
mod near_ahead;
mod parallel;

pub use back_threads::{sum_parts, ParallelStats};
pub use chunks::SourcePlane;
pub use parallel::{
    default_chunk, run_parallel, FrontResults, ParallelError, READER_THREAD, SUMS_THREAD,
    TRACKER_THREAD, WORKER_THREAD,
};

use crate::candidates::Candidate;
use crate::config::PipelineConfig;
use crate::pipeline::{FrontEnd, Pipeline, PipelineError};
use crate::plane::BitPlane;
use above::AboveHold;
use block::{add_row, below_run, scan_block};

/// The instruction sets [`FastFrontEnd`] is compiled for; the fastest one
/// the CPU reports is used, and each gives the same H, candidates and
/// above-threshold pixels (the tests run all of them on the CPUs that have
/// them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// Plain Rust, on any CPU (the compiler's own vectorisation).
    Portable,
    /// x86-64 AVX2: explicit 8-lane compares in the threshold scan. (An
    /// AVX-512 build, each kernel row of a changed pixel one masked 16-lane
    /// add, was slower on both machines measured: masked stores do not
    /// forward to the next footprint's loads.)
    Avx2,
}

impl Isa {
    /// The fastest instruction set this CPU runs.
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// The name printed by `smartagg bench aggregate`.
    pub fn as_str(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
        }
    }

    /// Every instruction set up to `self`, slowest first.
    pub fn up_to(self) -> impl Iterator<Item = Isa> {
        [Isa::Portable, Isa::Avx2]
            .into_iter()
            .filter(move |&i| i <= self)
    }
}

/// `Isa` as a const generic parameter of the compiled variants.
const PORTABLE: u8 = 0;
const AVX2: u8 = 1;

/// Above this fraction of changed pixels a plane is filtered densely (a
/// change costs k² scattered adds, a dense pass about 2k per pixel).
const DENSE_FRACTION: usize = 8;

/// Incremental stages 1–4.
#[derive(Debug, Clone)]
pub struct FastFrontEnd {
    width: usize,
    height: usize,
    half: usize,
    /// Cells around the field: `max(half, 1)`, so that the 3×3 candidate
    /// test can read a ring of zeros outside the field.
    pad: usize,
    stride: usize,
    k1: Vec<u32>,
    /// `K = k1 ⊗ k1`, row-major, for a pixel entering the window.
    kernel_plus: Vec<u32>,
    /// `−K` in wrapping arithmetic, for a pixel leaving it (no branch per add).
    kernel_minus: Vec<u32>,
    threshold_int: u32,
    threshold_hold: u32,
    /// Rolling counts S, raster order (kept for dense recomputation).
    counts: Vec<u16>,
    /// H with a halo of `pad` cells on every side. Halo cells collect the
    /// parts of `±K` that fall outside the field and are never read, except
    /// the ring next to the field, zeroed before each candidate scan.
    filtered: Vec<u32>,
    /// Scratch of the dense horizontal pass.
    horiz: Vec<u32>,
    /// The pixels with H ≥ T_hold.
    above: AboveHold,
    candidates: Vec<Candidate>,
    /// The instruction set the pushes run (the same code compiled for it).
    isa: Isa,
    /// Planes filtered densely (too many changed pixels for the sparse path).
    dense_planes: u64,
    /// Pixels whose bit entering the window differed from the bit leaving it.
    changed_pixels: u64,
}

impl FastFrontEnd {
    /// All-zero counts, as at stream start.
    pub fn new(cfg: &PipelineConfig) -> FastFrontEnd {
        let k = cfg.kernel.len();
        let half = k / 2;
        let pad = half.max(1);
        let stride = cfg.width + 2 * pad;
        let mut kernel_plus = Vec::with_capacity(k * k);
        for &a in &cfg.kernel {
            for &b in &cfg.kernel {
                kernel_plus.push(a * b);
            }
        }
        let kernel_minus = kernel_plus.iter().map(|w| w.wrapping_neg()).collect();
        FastFrontEnd {
            width: cfg.width,
            height: cfg.height,
            half,
            pad,
            stride,
            k1: cfg.kernel.clone(),
            kernel_plus,
            kernel_minus,
            threshold_int: cfg.threshold_int,
            threshold_hold: cfg.threshold_hold,
            counts: vec![0; cfg.width * cfg.height],
            filtered: vec![0; stride * (cfg.height + 2 * pad)],
            horiz: vec![0; cfg.width * cfg.height],
            above: AboveHold::default(),
            candidates: Vec::new(),
            isa: Isa::detect(),
            dense_planes: 0,
            changed_pixels: 0,
        }
    }

    /// Starts mid-stream: the counts of the N planes before the first plane
    /// that will be pushed (`window` holds them, oldest first, up to N).
    pub fn warmed_up<'a>(
        cfg: &PipelineConfig,
        window: impl IntoIterator<Item = &'a BitPlane>,
    ) -> FastFrontEnd {
        let mut fe = FastFrontEnd::new(cfg);
        fe.rewarm(window);
        fe
    }

    /// Starts again mid-stream in this front end's own memory, as
    /// [`FastFrontEnd::warmed_up`] does in new memory: a worker of
    /// [`run_parallel`] keeps one front end for all its chunks, so that no
    /// chunk maps and unmaps a megabyte of fresh pages.
    pub fn rewarm<'a>(&mut self, window: impl IntoIterator<Item = &'a BitPlane>) {
        let fe = self;
        fe.counts.fill(0);
        let total = fe.width * fe.height;
        for plane in window {
            // Only the ones count: iterate set bits, word by word.
            for (wi, &word) in plane.words().iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let idx = wi * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if idx < total {
                        fe.counts[idx] += 1;
                    }
                }
            }
        }
        fe.recompute_dense();
        fe.scan::<PORTABLE>();
    }

    /// The same front end without the AVX2 build: the portable code, on any
    /// CPU (for testing it where AVX2 exists, and for comparing speeds).
    pub fn portable(self) -> FastFrontEnd {
        self.with_isa(Isa::Portable)
    }

    /// The same front end running `isa`'s build, or the CPU's best if it
    /// lacks `isa` (for testing each build, and for comparing speeds).
    pub fn with_isa(mut self, isa: Isa) -> FastFrontEnd {
        self.isa = isa.min(Isa::detect());
        self
    }

    /// The instruction set the pushes run.
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Whether pushes run the AVX2 build of the front end.
    pub fn uses_avx2(&self) -> bool {
        self.isa >= Isa::Avx2
    }

    /// Planes so far whose H was recomputed densely, because more than an
    /// eighth of the pixels changed; the others were updated incrementally.
    pub fn dense_planes(&self) -> u64 {
        self.dense_planes
    }

    /// Pixels so far whose bit entering the window differed from the bit
    /// leaving it, summed over the planes: the work of stages 1–2 (each one
    /// adds `±K` around its pixel).
    pub fn changed_pixels(&self) -> u64 {
        self.changed_pixels
    }

    /// `H_t` at (x, y).
    pub fn filtered_at(&self, x: usize, y: usize) -> u32 {
        self.filtered[(y + self.pad) * self.stride + x + self.pad]
    }

    /// Rolling count `S_t` at (x, y).
    pub fn count_at(&self, x: usize, y: usize) -> u32 {
        u32::from(self.counts[y * self.width + x])
    }

    /// Raster indices of the pixels with `H_t ≥ T_hold` (the hold level), ascending.
    pub fn above(&self) -> &[u32] {
        &self.above.pixels
    }

    /// `H = K ⊛ S` over the whole field from the counts: a horizontal pass
    /// then a vertical one, each over contiguous rows (vectorises).
    #[inline(always)]
    fn recompute_dense(&mut self) {
        let (w, h, half, k) = (self.width, self.height, self.half, self.k1.len());
        let mut row = vec![0u32; w + 2 * half];
        for y in 0..h {
            for (r, &c) in row[half..half + w]
                .iter_mut()
                .zip(&self.counts[y * w..(y + 1) * w])
            {
                *r = u32::from(c);
            }
            let out = &mut self.horiz[y * w..(y + 1) * w];
            out.fill(0);
            for (i, &ki) in self.k1.iter().enumerate() {
                for (o, &s) in out.iter_mut().zip(&row[i..i + w]) {
                    *o = o.wrapping_add(ki.wrapping_mul(s));
                }
            }
        }
        for y in 0..h {
            let dst = (y + self.pad) * self.stride + self.pad;
            let out = &mut self.filtered[dst..dst + w];
            out.fill(0);
            for j in 0..k {
                let yy = y + j;
                if yy < half || yy - half >= h {
                    continue;
                }
                let kj = self.k1[j];
                let src = &self.horiz[(yy - half) * w..(yy - half + 1) * w];
                for (o, &s) in out.iter_mut().zip(src) {
                    *o = o.wrapping_add(kj.wrapping_mul(s));
                }
            }
        }
    }

    /// Stages 1–2 and 3–4 for one plane, given as raw words.
    #[inline(always)]
    fn push_words<const ISA: u8>(&mut self, live: &[u64], delayed: &[u64]) {
        let total = self.width * self.height;
        let words = total.div_ceil(64).min(live.len()).min(delayed.len());
        // Bits past the field in the last word are unspecified: mask them.
        let last_mask = match total % 64 {
            0 => !0u64,
            r => (1u64 << r) - 1,
        };
        let diff = |wi: usize| -> u64 {
            let d = live[wi] ^ delayed[wi];
            if wi + 1 == words {
                d & last_mask
            } else {
                d
            }
        };
        // The sparse pass counts the changes as it goes and gives up at the
        // first word that takes them past an eighth of the field (the same
        // planes as counting them first): the rest only updates the counts,
        // and H is recomputed from them.
        let limit = total / DENSE_FRACTION;
        let gave_up = match self.k1.len() {
            1 => self.sparse::<1>(live, delayed, words, last_mask, limit),
            3 => self.sparse::<3>(live, delayed, words, last_mask, limit),
            5 => self.sparse::<5>(live, delayed, words, last_mask, limit),
            7 => self.sparse::<7>(live, delayed, words, last_mask, limit),
            9 => self.sparse::<9>(live, delayed, words, last_mask, limit),
            11 => self.sparse::<11>(live, delayed, words, last_mask, limit),
            13 => self.sparse::<13>(live, delayed, words, last_mask, limit),
            15 => self.sparse::<15>(live, delayed, words, last_mask, limit),
            _ => self.sparse::<0>(live, delayed, words, last_mask, limit),
        };
        if let Some(from) = gave_up {
            for (wi, &entering) in live.iter().enumerate().take(words).skip(from) {
                let mut d = diff(wi);
                self.changed_pixels += u64::from(d.count_ones());
                while d != 0 {
                    let bit = d.trailing_zeros() as usize;
                    d &= d - 1;
                    let c = &mut self.counts[wi * 64 + bit];
                    *c = if (entering >> bit) & 1 == 1 {
                        *c + 1
                    } else {
                        *c - 1
                    };
                }
            }
            self.recompute_dense();
            self.dense_planes += 1;
        }
        self.scan::<ISA>();
    }

    /// Adds `±K` around every pixel whose bit entering the window differs
    /// from the bit leaving it, and updates its count. `K` is the kernel
    /// length (0: any length). Gives up before the first word that takes the
    /// changes past `limit`, and returns its index: the counts from that word
    /// on are then not updated, and H is not whole.
    #[inline(always)]
    fn sparse<const K: usize>(
        &mut self,
        live: &[u64],
        delayed: &[u64],
        words: usize,
        last_mask: u64,
        limit: usize,
    ) -> Option<usize> {
        let (width, height, stride, k) = (self.width, self.height, self.stride, self.k1.len());
        let (pad, half) = (self.pad, self.half);
        // Every footprint lies inside `filtered`: its top-left cell is at
        // most ((h − 1 + pad − half)·stride + w − 1 + pad − half) and it
        // spans k rows and k columns, so its last cell is at most
        // (h + pad + half − 1)·stride + w + pad + half − 1 < stride·(h + 2·pad)
        // (pad ≥ half). The raw row pointers below rely on it.
        assert!(pad >= half && K <= k && self.filtered.len() >= stride * (height + 2 * pad));
        assert!(self.kernel_plus.len() == k * k && self.kernel_minus.len() == k * k);
        let filtered = self.filtered.as_mut_ptr();
        let counts = &mut self.counts[..];
        // `±K` as local fixed-size rows: the stores through `filtered` (a raw
        // pointer the compiler must assume may alias anything reachable from
        // `self`) then do not force the weights' slice to be reloaded, cut
        // into rows and checked again for every change.
        let mut footprints = [[[0u32; K]; K]; 2];
        for (footprint, weights) in footprints
            .iter_mut()
            .zip([&self.kernel_minus, &self.kernel_plus])
        {
            for (dy, row) in footprint.iter_mut().enumerate() {
                row.copy_from_slice(&weights[dy * K..(dy + 1) * K]);
            }
        }
        // Position of each word's first pixel, stepped from word to word (no
        // division per word).
        let (mut wy, mut wx) = (0usize, 0usize);
        let mut changes = 0;
        for wi in 0..words {
            if wi > 0 {
                wx += 64;
                while wx >= width {
                    wx -= width;
                    wy += 1;
                }
            }
            let (a, b) = (live[wi], delayed[wi]);
            let mut d = a ^ b;
            if wi + 1 == words {
                d &= last_mask;
            }
            if d == 0 {
                continue;
            }
            let in_word = d.count_ones() as usize;
            if changes + in_word > limit {
                self.changed_pixels += changes as u64;
                return Some(wi);
            }
            changes += in_word;
            let first = wi * 64;
            let (mut y, mut x, mut at) = (wy, wx, first);
            while d != 0 {
                let bit = d.trailing_zeros() as usize;
                d &= d - 1;
                let idx = first + bit;
                x += idx - at;
                at = idx;
                while x >= width {
                    x -= width;
                    y += 1;
                }
                let plus = (a >> bit) & 1 == 1;
                let c = &mut counts[idx];
                *c = if plus { *c + 1 } else { *c - 1 };
                debug_assert!(x < width && y < height);
                // The footprint's top-left cell in the haloed layout.
                let base = (y + pad - half) * stride + x + pad - half;
                if K == 0 {
                    let weights = if plus {
                        &self.kernel_plus[..]
                    } else {
                        &self.kernel_minus[..]
                    };
                    for dy in 0..k {
                        // SAFETY: row dy of the footprint is inside `filtered`.
                        let row = unsafe {
                            std::slice::from_raw_parts_mut(filtered.add(base + dy * stride), k)
                        };
                        for (f, &wk) in row.iter_mut().zip(&weights[dy * k..(dy + 1) * k]) {
                            *f = f.wrapping_add(wk);
                        }
                    }
                } else {
                    // One pointer stepped a row at a time (no multiply per
                    // row).
                    let mut row = filtered.wrapping_add(base);
                    for wk in &footprints[usize::from(plus)] {
                        // SAFETY: each of the footprint's K rows is K cells
                        // inside `filtered`, and u32 cells are aligned as
                        // [u32; K].
                        add_row::<K>(unsafe { &mut *row.cast::<[u32; K]>() }, wk);
                        row = row.wrapping_add(stride);
                    }
                }
            }
        }
        self.changed_pixels += changes as u64;
        None
    }

    /// Stages 3–4: the pixels at or above the hold level and the candidates
    /// (at or above the open level) among them, in raster order, in one
    /// pass. Runs of 64 (then 32) pixels whose maximum is below the hold
    /// level are skipped at once; in the others, eight pixels at a time are
    /// compared with the two levels, and those at both with their eight
    /// neighbours (the zeroed ring stands for the outside of the field: an
    /// above-threshold pixel beats 0, which is the same as ignoring those
    /// neighbours).
    #[inline(always)]
    fn scan<const ISA: u8>(&mut self) {
        self.above.clear();
        self.candidates.clear();
        let (w, h, s, pad) = (self.width, self.height, self.stride, self.pad);
        let thr = self.threshold_hold;
        let open = self.threshold_int;
        let f = &mut self.filtered[..];
        let top = (pad - 1) * s + pad - 1;
        f[top..top + w + 2].fill(0);
        let bottom = (pad + h) * s + pad - 1;
        f[bottom..bottom + w + 2].fill(0);
        for y in 0..h {
            let r = (pad + y) * s + pad;
            f[r - 1] = 0;
            f[r + w] = 0;
        }
        let f = &self.filtered[..];
        let is_max = |c: usize| -> bool {
            let v = f[c];
            (v > f[c - s - 1])
                & (v > f[c - s])
                & (v > f[c - s + 1])
                & (v > f[c - 1])
                & (v >= f[c + 1])
                & (v >= f[c + s - 1])
                & (v >= f[c + s])
                & (v >= f[c + s + 1])
        };
        let above = &mut self.above;
        let candidates = &mut self.candidates;
        for y in 0..h {
            let c0 = (pad + y) * s + pad;
            let mut x0 = 0;
            // Runs of 64 cells, then of 32, whose maximum is below the hold
            // level are skipped at once (most of the field, most planes).
            for run in [64, 32] {
                while x0 + run <= w {
                    let below = if run == 64 {
                        below_run::<ISA, 64>(f, c0 + x0, thr)
                    } else {
                        below_run::<ISA, 32>(f, c0 + x0, thr)
                    };
                    if !below {
                        for at in (x0..x0 + run).step_by(8) {
                            scan_block::<ISA>(f, above, candidates, (y, w, s), c0, at, (thr, open));
                        }
                    }
                    x0 += run;
                }
            }
            while x0 + 8 <= w {
                scan_block::<ISA>(f, above, candidates, (y, w, s), c0, x0, (thr, open));
                x0 += 8;
            }
            for x in x0..w {
                let c = c0 + x;
                if f[c] >= thr {
                    above.pixels.push((y * w + x) as u32);
                    above.set_bit(y * w + x);
                    if f[c] >= open && is_max(c) {
                        candidates.push(Candidate {
                            x: x as u16,
                            y: y as u16,
                        });
                    }
                }
            }
        }
    }

    /// [`FastFrontEnd::push_words`] compiled for AVX2 (wider adds, compares
    /// and maxima in the filter and the threshold scan).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn push_words_avx2(&mut self, live: &[u64], delayed: &[u64]) {
        self.push_words::<AVX2>(live, delayed);
    }
}

impl FrontEnd for FastFrontEnd {
    fn push(&mut self, live: &BitPlane, delayed: &BitPlane) {
        let (lw, dw) = (live.words(), delayed.words());
        match self.isa {
            // SAFETY: `isa` is never above what `Isa::detect` found.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.push_words_avx2(lw, dw) },
            _ => self.push_words::<PORTABLE>(lw, dw),
        }
    }

    /// Read from H itself: no search of the pixels at the hold level, nine
    /// cells (the ring outside the field reads 0, below any level but 0, at
    /// which every pixel is).
    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        let (f, s) = (&self.filtered, self.stride);
        let c = (y + self.pad) * s + x + self.pad;
        let most = [c - s, c, c + s]
            .iter()
            .map(|&r| f[r - 1].max(f[r]).max(f[r + 1]))
            .max()
            .unwrap_or(0);
        most >= self.threshold_hold
    }

    fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }
}

/// The fast engine, single-threaded: the golden pipeline with [`FastFrontEnd`].
pub fn fast_pipeline(cfg: PipelineConfig) -> Result<Pipeline<FastFrontEnd>, PipelineError> {
    cfg.validate()?;
    let front = FastFrontEnd::new(&cfg);
    Pipeline::with_front_end(cfg, front)
}
