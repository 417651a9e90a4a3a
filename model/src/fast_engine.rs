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
//!   instead. Threshold and candidates are one pass that skips rows below
//!   threshold and tests eight pixels at a time against their neighbours.
//!   On x86-64 with AVX2 (detected at run time) the same code is compiled a
//!   second time for AVX2, with explicit AVX2 compares in the scan.
//! * [`run_parallel`] splits the stream into time chunks. H at plane t depends
//!   only on planes `t−N+1 … t`, so a worker can start a chunk anywhere after
//!   warming its counts up on the N planes before it; the workers' per-plane
//!   results (candidates and above-threshold pixels) then feed the one
//!   sequential tracker, which is cheap. A reader thread pulls the planes
//!   meanwhile, and each worker takes the next chunk as soon as it is free.
//!   The output is byte-identical to the single-threaded golden pipeline for
//!   any chunk length and thread count, and memory is bounded by the chunk
//!   length, the threads, N and the field, not by the stream's length.

use crate::back_end::{Summing, TrackEnd, TrackStep, Tracking};
use crate::candidates::Candidate;
use crate::config::PipelineConfig;
use crate::delay_line::{DelayLine, SharedPlane};
use crate::pipeline::{check_plane_number, FrontEnd, Pipeline, PipelineError};
use crate::plane::BitPlane;
use crate::record::Record;
use std::collections::VecDeque;
use std::sync::Arc;

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
    /// Raster indices with H ≥ T_hold, ascending.
    above: Vec<u32>,
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
            above: Vec::new(),
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

    /// Raster indices of the pixels with `H_t ≥ T_int`, ascending.
    pub fn above(&self) -> &[u32] {
        &self.above
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
                    above.push((y * w + x) as u32);
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

    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        above_near(&self.above, self.width, self.height, x, y)
    }

    fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }
}

/// `row += w` for one kernel row, as 8-, 4- and 1-lane pieces so that the
/// compiler emits whole vector adds. Each piece is loaded into registers
/// before it is stored: after inlining the compiler cannot tell that `row`
/// and `w` do not overlap, and would otherwise keep the adds scalar.
#[inline(always)]
fn add_row<const K: usize>(row: &mut [u32; K], w: &[u32; K]) {
    let mut i = 0;
    while i + 8 <= K {
        let mut r: [u32; 8] = row[i..i + 8].try_into().expect("8 lanes");
        let v: [u32; 8] = w[i..i + 8].try_into().expect("8 lanes");
        for l in 0..8 {
            r[l] = r[l].wrapping_add(v[l]);
        }
        row[i..i + 8].copy_from_slice(&r);
        i += 8;
    }
    while i + 4 <= K {
        let mut r: [u32; 4] = row[i..i + 4].try_into().expect("4 lanes");
        let v: [u32; 4] = w[i..i + 4].try_into().expect("4 lanes");
        for l in 0..4 {
            r[l] = r[l].wrapping_add(v[l]);
        }
        row[i..i + 4].copy_from_slice(&r);
        i += 4;
    }
    while i < K {
        row[i] = row[i].wrapping_add(w[i]);
        i += 1;
    }
}

/// Stages 3–4 for the eight pixels from `x0` of row `y` (`c0`: the row's
/// first cell in the haloed H, `w` the field's width, `s` the stride):
/// appends those at or above `thr` (hold) to `above`, and the local maxima
/// at or above `open` to `candidates`. A function, not a closure, so that it
/// is inlined into each instruction set's build with its compares.
#[inline(always)]
fn scan_block<const ISA: u8>(
    f: &[u32],
    above: &mut Vec<u32>,
    candidates: &mut Vec<Candidate>,
    (y, w, s): (usize, usize, usize),
    c0: usize,
    x0: usize,
    (thr, open): (u32, u32),
) {
    #[cfg(target_arch = "x86_64")]
    let (ab, cands) = if ISA >= AVX2 {
        // SAFETY: ISA ≥ AVX2 only inside `push_words_avx2`, which runs
        // only when the CPU has AVX2.
        unsafe { block8_avx2(f, c0 + x0, s, (thr, open)) }
    } else {
        block8(f, c0 + x0, s, (thr, open))
    };
    #[cfg(not(target_arch = "x86_64"))]
    let (ab, cands) = block8(f, c0 + x0, s, (thr, open));
    #[cfg(target_arch = "x86_64")]
    if ISA >= AVX2 {
        // SAFETY: as above.
        unsafe { push_bits8_avx2(above, ab, (y * w + x0) as u32) };
    } else {
        push_bits(above, ab, y * w + x0, |i| i as u32);
    }
    #[cfg(not(target_arch = "x86_64"))]
    push_bits(above, ab, y * w + x0, |i| i as u32);
    push_bits(candidates, cands, x0, |x| Candidate {
        x: x as u16,
        y: y as u16,
    });
}

/// Eight pixels from cell `c` of the haloed H (row stride `s`): the bit
/// masks of those at or above `thr` (hold), and of the candidates: at or
/// above `thr` and `open`, strictly above their four earlier neighbours in
/// raster order and at least their four later ones. The neighbours are read
/// only if a pixel reaches both levels (in a crowded field most pixels at
/// the hold level are below the open level). Lane-wise, so that it compiles
/// to vector compares.
#[inline(always)]
fn block8(f: &[u32], c: usize, s: usize, (thr, open): (u32, u32)) -> (u32, u32) {
    let load = |at: usize| -> [u32; 8] { f[at..at + 8].try_into().expect("8 lanes") };
    let v = load(c);
    let (mut above, mut opened) = (0u32, 0u32);
    for (l, &x) in v.iter().enumerate() {
        above |= u32::from(x >= thr) << l;
        opened |= u32::from(x >= open) << l;
    }
    let opened = above & opened;
    if opened == 0 {
        return (above, 0);
    }
    let (ul, u, ur, le) = (load(c - s - 1), load(c - s), load(c - s + 1), load(c - 1));
    let (ri, dl, d, dr) = (load(c + 1), load(c + s - 1), load(c + s), load(c + s + 1));
    let mut max = 0u32;
    for l in 0..8 {
        let m = (v[l] > ul[l])
            & (v[l] > u[l])
            & (v[l] > ur[l])
            & (v[l] > le[l])
            & (v[l] >= ri[l])
            & (v[l] >= dl[l])
            & (v[l] >= d[l])
            & (v[l] >= dr[l]);
        max |= u32::from(m) << l;
    }
    (above, opened & max)
}

/// [`block8`] with AVX2 compares and move-masks (the compiler's own
/// vectorisation of the lane loops builds the masks lane by lane). Unsigned
/// order is signed order after flipping the sign bit. The neighbours are
/// compared whenever a pixel reaches the hold level: a branch on the open
/// level too was slower in the dense scene (mispredicted) than the compares
/// it saved.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn block8_avx2(f: &[u32], c: usize, s: usize, (thr, open): (u32, u32)) -> (u32, u32) {
    use std::arch::x86_64::*;
    #[target_feature(enable = "avx2")]
    fn load(f: &[u32], at: usize) -> __m256i {
        let lanes = &f[at..at + 8];
        // SAFETY: `lanes` is 8 u32 = 32 readable bytes; the load is unaligned.
        let v = unsafe { _mm256_loadu_si256(lanes.as_ptr().cast()) };
        _mm256_xor_si256(v, _mm256_set1_epi32(i32::MIN))
    }
    #[target_feature(enable = "avx2")]
    fn mask(v: __m256i) -> u32 {
        _mm256_movemask_ps(_mm256_castsi256_ps(v)) as u32
    }
    let v = load(f, c);
    let t = _mm256_set1_epi32((thr ^ 0x8000_0000) as i32);
    // v ≥ thr ⇔ not (thr > v).
    let above = !mask(_mm256_cmpgt_epi32(t, v)) & 0xff;
    if above == 0 {
        return (0, 0);
    }
    let o = _mm256_set1_epi32((open ^ 0x8000_0000) as i32);
    let opened = above & !mask(_mm256_cmpgt_epi32(o, v));
    let earlier = _mm256_and_si256(
        _mm256_and_si256(
            _mm256_cmpgt_epi32(v, load(f, c - s - 1)),
            _mm256_cmpgt_epi32(v, load(f, c - s)),
        ),
        _mm256_and_si256(
            _mm256_cmpgt_epi32(v, load(f, c - s + 1)),
            _mm256_cmpgt_epi32(v, load(f, c - 1)),
        ),
    );
    // A later neighbour breaks the maximum only if it is strictly greater.
    let later_greater = _mm256_or_si256(
        _mm256_or_si256(
            _mm256_cmpgt_epi32(load(f, c + 1), v),
            _mm256_cmpgt_epi32(load(f, c + s - 1), v),
        ),
        _mm256_or_si256(
            _mm256_cmpgt_epi32(load(f, c + s), v),
            _mm256_cmpgt_epi32(load(f, c + s + 1), v),
        ),
    );
    let max = mask(_mm256_andnot_si256(later_greater, earlier));
    (above, opened & max)
}

/// [`below`] in `ISA`'s build.
#[inline(always)]
fn below_run<const ISA: u8, const B: usize>(f: &[u32], c: usize, thr: u32) -> bool {
    #[cfg(target_arch = "x86_64")]
    if ISA >= AVX2 {
        // SAFETY: ISA ≥ AVX2 only inside `push_words_avx2`, which runs only
        // when the CPU has AVX2.
        return unsafe { below_avx2::<B>(f, c, thr) };
    }
    below::<B>(f, c, thr)
}

/// The set bits of every byte, ascending, then zeros: `PACKED[m][..k]` are
/// the k bits of `m`.
const PACKED: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut k, mut b) = (0, 0);
        while b < 8 {
            if m & (1 << b) != 0 {
                t[m][k] = b as u32;
                k += 1;
            }
            b += 1;
        }
        m += 1;
    }
    t
};

/// [`push_bits`] of the eight low bits of `bits` as `offset + i`, with one
/// 8-lane store and a length step: in a crowded field most blocks have
/// several pixels at the hold level, and a push per pixel cost more than
/// the compares that found them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn push_bits8_avx2(out: &mut Vec<u32>, bits: u32, offset: u32) {
    use std::arch::x86_64::*;
    let bits = bits & 0xff;
    if bits == 0 {
        return;
    }
    out.reserve(8);
    let len = out.len();
    let lanes = &PACKED[bits as usize];
    // SAFETY: `lanes` is 8 u32 = one unaligned 32-byte load; `reserve(8)`
    // made room for 8 u32 from `len`, of which the first `popcount` are
    // written values and become part of the vector.
    unsafe {
        let v = _mm256_add_epi32(
            _mm256_loadu_si256(lanes.as_ptr().cast()),
            _mm256_set1_epi32(offset as i32),
        );
        _mm256_storeu_si256(out.as_mut_ptr().add(len).cast(), v);
        out.set_len(len + bits.count_ones() as usize);
    }
}

/// Pushes `make(offset + i)` for every set bit i of `bits`, ascending.
#[inline(always)]
fn push_bits<T>(out: &mut Vec<T>, mut bits: u32, offset: usize, make: impl Fn(usize) -> T) {
    while bits != 0 {
        out.push(make(offset + bits.trailing_zeros() as usize));
        bits &= bits - 1;
    }
}

/// Whether all `B` cells from `c` are below `thr` (`B` a multiple of 8):
/// lane-wise maxima, reduced once.
#[inline(always)]
fn below<const B: usize>(f: &[u32], c: usize, thr: u32) -> bool {
    let g: &[u32; B] = f[c..c + B].try_into().expect("B cells");
    let mut m = [0u32; 8];
    for group in g.chunks_exact(8) {
        for l in 0..8 {
            m[l] = m[l].max(group[l]);
        }
    }
    m.iter().fold(0, |a, &v| a.max(v)) < thr
}

/// [`below`] with AVX2 unsigned maxima and one compare.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn below_avx2<const B: usize>(f: &[u32], c: usize, thr: u32) -> bool {
    use std::arch::x86_64::*;
    let g: &[u32; B] = f[c..c + B].try_into().expect("B cells");
    if thr == 0 {
        return false;
    }
    let p = g.as_ptr().cast::<__m256i>();
    // SAFETY: `g` is B u32 = B / 8 unaligned 32-byte loads.
    let mut m = unsafe { _mm256_loadu_si256(p) };
    for i in 1..B / 8 {
        m = _mm256_max_epu32(m, unsafe { _mm256_loadu_si256(p.add(i)) });
    }
    // Every lane < thr ⇔ max(lane, thr − 1) = thr − 1.
    let t = _mm256_set1_epi32((thr - 1) as i32);
    _mm256_movemask_epi8(_mm256_cmpeq_epi32(_mm256_max_epu32(m, t), t)) == -1
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

/// Replays precomputed stages 1–4 to the tracker (stage 5) of the back end.
#[derive(Debug, Default)]
struct ReplayFrontEnd {
    width: usize,
    height: usize,
    queue: VecDeque<PlaneFront>,
    current: PlaneFront,
}

impl ReplayFrontEnd {
    /// Takes the next plane's stages 1–4 from the queue.
    fn next_plane(&mut self) {
        self.current = self
            .queue
            .pop_front()
            .expect("a precomputed front end per plane");
        // The tracker's 3×3 tests binary-search the plane's pixels at the
        // hold level: a worker wrote them a while ago, and on a large field
        // (thousands of them) each search would wait on memory. Fetch the
        // next plane's while this one is tracked.
        if let Some(next) = self.queue.front() {
            crate::plane::prefetch(&next.above);
        }
    }
}

impl FrontEnd for ReplayFrontEnd {
    fn push(&mut self, _live: &BitPlane, _delayed: &BitPlane) {
        self.next_plane();
    }

    fn neighbourhood_on(&self, x: usize, y: usize) -> bool {
        above_near(&self.current.above, self.width, self.height, x, y)
    }

    fn candidates(&self) -> &[Candidate] {
        &self.current.candidates
    }
}

/// A time chunk of the stream on its way to a worker: its planes and the
/// (up to N) planes before it, oldest first, as ranges of earlier chunks
/// (shared with the jobs that had them, not copied: at N ≈ 1,000 planes of
/// 512×512 a copy would cost more than the filtering).
struct Job {
    index: usize,
    history: Vec<(Arc<Vec<BitPlane>>, std::ops::Range<usize>)>,
    planes: Arc<Vec<BitPlane>>,
}

/// A chunk back from a worker, with stages 1–4 of each of its planes.
struct Done {
    index: usize,
    planes: Arc<Vec<BitPlane>>,
    fronts: Vec<PlaneFront>,
}

/// The time chunk [`run_parallel`] is best given for a window of `n_window`
/// planes: every chunk re-reads the N planes before it to warm its counts
/// up, so a chunk of 4N or more keeps that below a quarter of its work; 512
/// at least, so that short windows still hand out chunks of useful size.
pub fn default_chunk(n_window: u32) -> usize {
    (4 * n_window as usize).max(512)
}

/// Stages 1–4 of planes from stream start, kept with the planes so that
/// stages 5–7 can run alone on them ([`FrontResults::replay_back_end`]): how
/// `smartagg bench aggregate` measures the back end, the part of
/// [`run_parallel`] that the workers do not share.
#[derive(Debug, Clone)]
pub struct FrontResults {
    cfg: PipelineConfig,
    /// The planes in chunks of [`default_chunk`], each with its stages 1–4.
    chunks: Vec<(Arc<Vec<BitPlane>>, Vec<PlaneFront>)>,
}

impl FrontResults {
    /// Stages 1–4 (the fast front end) of `planes`, from stream start.
    pub fn compute(cfg: &PipelineConfig, planes: &[BitPlane]) -> FrontResults {
        let planes: Vec<BitPlane> = match &cfg.hot_mask {
            Some(m) => planes.iter().map(|p| m.apply(p)).collect(),
            None => planes.to_vec(),
        };
        let mut fronts = chunk_fronts(&mut FastFrontEnd::new(cfg), cfg, &[], &planes).into_iter();
        // The planes move into their chunks: no second copy.
        let chunk = default_chunk(cfg.n_window);
        let mut planes = planes.into_iter().peekable();
        let mut chunks = Vec::new();
        while planes.peek().is_some() {
            let c: Vec<BitPlane> = planes.by_ref().take(chunk).collect();
            let f = fronts.by_ref().take(c.len()).collect();
            chunks.push((Arc::new(c), f));
        }
        FrontResults {
            cfg: cfg.clone(),
            chunks,
        }
    }

    /// Planes held.
    pub fn len(&self) -> usize {
        self.chunks.iter().map(|(c, _)| c.len()).sum()
    }

    /// Whether no plane is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Stages 5–7 alone — the tracker, the ROI sums and the records — on the
    /// planes and their stages 1–4, as [`run_parallel`] runs them (the
    /// tracker a chunk ahead in a thread of its own): the records of the
    /// whole stream (start to end), the same as [`fast_pipeline`]'s on the
    /// same planes.
    pub fn replay_back_end(self) -> Result<Vec<Record>, PipelineError> {
        let cfg = self.cfg;
        cfg.validate()?;
        let mut out = vec![Record::Start(cfg.stream_start())];
        let end = split_back_end(&cfg, self.chunks.into_iter(), |r| out.push(r), || {})?;
        out.extend(end);
        Ok(out)
    }
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

/// Stages 5–7 on chunks in stream order (each chunk's planes with their
/// stages 1–4), in two threads: the tracker ([`Tracking`]) runs in a thread
/// of its own, a few hundred planes ahead of the ROI sums and the records
/// ([`Summing`]), which run in the calling thread. `sink` gets each plane's
/// records in stream order and `chunk_done` is called once a chunk's have
/// all gone; the records of the stream's end are returned (not sunk), so
/// that the caller can hold them back if the stream failed.
fn split_back_end<C>(
    cfg: &PipelineConfig,
    chunks: C,
    mut sink: impl FnMut(Record),
    chunk_done: impl FnMut(),
) -> Result<Vec<Record>, PipelineError>
where
    C: Iterator<Item = (Arc<Vec<BitPlane>>, Vec<PlaneFront>)> + Send,
{
    let (tx, rx) = std::sync::mpsc::sync_channel::<Tracked>(4);
    std::thread::scope(|scope| {
        let tracker = scope.spawn(move || -> TrackEnd {
            let mut tracking = Tracking::new(cfg);
            let mut front = ReplayFrontEnd {
                width: cfg.width,
                height: cfg.height,
                ..Default::default()
            };
            let mut t = 0u64;
            'chunks: for (planes, fronts) in chunks {
                front.queue.extend(fronts);
                let len = planes.len();
                for start in (0..len).step_by(HANDOFF) {
                    let range = start..(start + HANDOFF).min(len);
                    let steps = range
                        .clone()
                        .map(|_| {
                            front.next_plane();
                            let mut step = TrackStep::default();
                            tracking.step(t, &front, &mut step);
                            t += 1;
                            step
                        })
                        .collect();
                    let planes = planes.clone();
                    // A failed send: the sums have stopped.
                    if tx
                        .send(Tracked {
                            planes,
                            range,
                            steps,
                        })
                        .is_err()
                    {
                        break 'chunks;
                    }
                }
            }
            tracking.finish(t)
        });
        let mut chunk_done = chunk_done;
        let mut delay = DelayLine::new(cfg.n_window as usize, cfg.width, cfg.height);
        let mut summing = Summing::new(cfg);
        let mut t = 0u64;
        let mut result = Ok(());
        'chunks: for tracked in &rx {
            let planes = SharedPlane::within(&tracked.planes, tracked.range.clone());
            for (plane, step) in planes.zip(&tracked.steps) {
                if let Err(e) = check_plane_number(t) {
                    result = Err(e);
                    break 'chunks;
                }
                delay.push_shared(plane);
                summing
                    .step(t, step, &delay)
                    .into_iter()
                    .for_each(&mut sink);
                t += 1;
            }
            if tracked.range.end == tracked.planes.len() {
                chunk_done();
            }
        }
        // The tracker stops at its next send, and drops its chunks (which
        // stops whoever feeds them); `chunk_done` may hold what lets them
        // be fed, so it goes first.
        drop((rx, chunk_done));
        let end = tracker.join().expect("the tracker's thread panicked");
        result?;
        Ok(summing.finish(t, end, &delay))
    })
}

/// Runs a stream on `threads` worker threads in time chunks of `chunk` planes,
/// calling `sink` with every record in stream order (start record first,
/// stream-end record last). Errors from the plane source stop the run and are
/// returned. The source gives planes or references to them (the reader
/// copies each into a chunk it recycles).
///
/// A reader thread pulls the planes (decoding or simulating them) and masks
/// hot pixels; each worker takes the next chunk as soon as it is free (no
/// barrier between chunks) and computes its stages 1–4; stages 5–7 take
/// the chunks in stream order, in two threads (see [`crate::back_end`]): the
/// tracker in a thread of its own, the ROI sums and the records in the
/// calling thread, which calls `sink`. At most
/// `3·threads + 1` chunks are in flight, and the back end's delay line keeps
/// the chunks that hold its last N + 1 planes (by reference: no plane is
/// copied after the reader), so memory is bounded by `(3·threads + 3)·chunk
/// + (threads + 1)·N` planes, whatever the stream's length.
pub fn run_parallel<E, P, I, S>(
    cfg: PipelineConfig,
    planes: I,
    threads: usize,
    chunk: usize,
    mut sink: S,
) -> Result<(), ParallelError<E>>
where
    E: Send,
    P: std::borrow::Borrow<BitPlane> + Send,
    I: Iterator<Item = Result<P, E>> + Send,
    S: FnMut(Record),
{
    cfg.validate()
        .map_err(|e| ParallelError::Pipeline(e.into()))?;
    let threads = threads.max(1);
    let chunk = chunk.max(1);
    let n = cfg.n_window as usize;
    sink(Record::Start(cfg.stream_start()));

    let (job_tx, job_rx) = std::sync::mpsc::sync_channel::<Job>(threads);
    // Shared by the workers only: when the last one stops, the reader's
    // sends fail and it stops too.
    let job_rx = std::sync::Arc::new(std::sync::Mutex::new(job_rx));
    let (done_tx, done_rx) = std::sync::mpsc::sync_channel::<Done>(threads);
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
    std::thread::scope(|scope| -> Result<(), ParallelError<E>> {
        let reader_cfg = cfg.clone();
        let reader = scope.spawn(move || -> Result<(), ParallelError<E>> {
            let mut planes = planes;
            let mut history: VecDeque<(Arc<Vec<BitPlane>>, std::ops::Range<usize>)> =
                VecDeque::new();
            let (w, h) = (reader_cfg.width, reader_cfg.height);
            // Every chunk read, while anyone holds it: a chunk only the pool
            // holds is filled again in place, so that planes are not
            // allocated here and freed in bursts by another thread (on some
            // machines the heap then returns its pages and every chunk
            // faults them in again).
            let mut pool: Vec<Arc<Vec<BitPlane>>> = Vec::new();
            for index in 0.. {
                let mut batch = pool
                    .iter()
                    .position(|c| Arc::strong_count(c) == 1)
                    .and_then(|i| Arc::try_unwrap(pool.swap_remove(i)).ok())
                    .unwrap_or_default();
                let mut filled = 0;
                while filled < chunk {
                    match planes.next() {
                        // A plane of another size never reaches a worker.
                        Some(Ok(p)) if (p.borrow().width(), p.borrow().height()) != (w, h) => {
                            let p = p.borrow();
                            return Err(ParallelError::Pipeline(PipelineError::PlaneSize {
                                plane: (index * chunk + filled) as u64,
                                got_w: p.width(),
                                got_h: p.height(),
                                want_w: w,
                                want_h: h,
                            }));
                        }
                        Some(Ok(p)) => {
                            let (p, mask) = (p.borrow(), reader_cfg.hot_mask.as_ref());
                            match batch.get_mut(filled) {
                                Some(buf) => buf.copy_masked(p, mask),
                                None => batch.push(match mask {
                                    Some(m) => m.apply(p),
                                    None => p.clone(),
                                }),
                            }
                            filled += 1;
                        }
                        Some(Err(e)) => return Err(ParallelError::Source(e)),
                        None => break,
                    }
                }
                batch.truncate(filled);
                if batch.is_empty() {
                    break;
                }
                let full = batch.len() == chunk;
                let batch = Arc::new(batch);
                pool.push(batch.clone());
                let job_history: Vec<_> = history.iter().cloned().collect();
                // The last N planes read: ranges of this and earlier chunks.
                history.push_back((batch.clone(), 0..batch.len()));
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
                    history: job_history,
                    planes: batch,
                };
                if credit_rx.recv().is_err() || job_tx.send(job).is_err() || !full {
                    break;
                }
            }
            Ok(())
        });
        for _ in 0..threads {
            let (rx, tx) = (job_rx.clone(), done_tx.clone());
            scope.spawn(move || {
                let mut fe = FastFrontEnd::new(worker_cfg);
                loop {
                    let job = match rx.lock() {
                        Ok(rx) => rx.recv(),
                        Err(_) => return,
                    };
                    let Ok(job) = job else { return };
                    let history: Vec<&BitPlane> = job
                        .history
                        .iter()
                        .flat_map(|(c, r)| c[r.clone()].iter())
                        .collect();
                    let fronts = chunk_fronts(&mut fe, worker_cfg, &history, &job.planes);
                    let done = Done {
                        index: job.index,
                        planes: job.planes,
                        fronts,
                    };
                    if tx.send(done).is_err() {
                        return;
                    }
                }
            });
        }
        drop((job_rx, done_tx));
        // Stages 5–7 in stream order; chunks that come back early wait.
        let mut early: std::collections::BTreeMap<usize, Done> = Default::default();
        let mut next = 0;
        let in_order = std::iter::from_fn(move || loop {
            if let Some(d) = early.remove(&next) {
                next += 1;
                return Some((d.planes, d.fronts));
            }
            let d = done_rx.recv().ok()?;
            early.insert(d.index, d);
        });
        // The back end holds no credit: a failed send only means the reader
        // has finished.
        let back = split_back_end(&cfg, in_order, &mut sink, move || {
            let _ = credit_tx.send(());
        });
        // The back end has stopped the workers (their sends fail), hence
        // the reader.
        let read = reader.join().expect("the plane reader panicked");
        let end = back.map_err(ParallelError::Pipeline)?;
        read?;
        end.into_iter().for_each(&mut sink);
        Ok(())
    })
}

/// Stages 1–4 of every plane of a chunk. `history` holds the (up to N)
/// planes before it, oldest first: all N of them, or every plane since
/// stream start (earlier planes are zero).
fn chunk_fronts(
    fe: &mut FastFrontEnd,
    cfg: &PipelineConfig,
    history: &[&BitPlane],
    planes: &[BitPlane],
) -> Vec<PlaneFront> {
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
    fe.rewarm(history.iter().copied());
    planes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let delayed = (h + i).checked_sub(n).map_or(&zero, get);
            fe.push(p, delayed);
            PlaneFront {
                candidates: fe.candidates.clone(),
                above: fe.above.clone(),
            }
        })
        .collect()
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
