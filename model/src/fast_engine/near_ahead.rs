//! The tracker's 3×3 tests answered ahead by the workers of
//! [`run_parallel`](super::run_parallel).
//!
//! Each plane, the tracker (stage 5, one thread) tests the 3×3 around the
//! anchor of every live track against the pixels at the hold level. On a
//! large field those pixels were written by a worker long before, and each
//! test waits on memory: half of the tracker's time on a SPAD512S-class
//! field, and the tracker is what holds that field back on 16 cores.
//!
//! An anchor is where a track's first candidate was, and a molecule that
//! stays on is a candidate again and again at the same few pixels. So each
//! worker, while a plane's H is in its cache, makes the test at every
//! pixel that has been a candidate so far in its chunk (up to a bound:
//! twice the slots), a bit a plane ([`AheadTests`]); the tracker takes a
//! track's answers from the chunk's bits when its anchor is among them
//! ([`NearAhead::find`], at each chunk's start and when a track opens),
//! and tests on the plane as before where it is not, or before the anchor
//! was first a candidate in the chunk. An answer is the same test on the
//! same H, made earlier: the records cannot change, only where the test is
//! made.

use super::FastFrontEnd;
use crate::pipeline::FrontEnd;
use std::sync::{Arc, Mutex, PoisonError};

/// The workers' answers over one chunk.
#[derive(Debug, Clone, Default)]
pub(super) struct NearAhead {
    /// The chunk's first plane.
    start: u64,
    /// The chunk's planes.
    planes: usize,
    /// Words of bits a pixel.
    words: usize,
    /// The pixels tested (raster index), with the chunk's plane from which
    /// on each was tested, in the order they were first candidates.
    pixels: Vec<(u32, u32)>,
    /// Pixel k's bits at `k · words`: bit `i % 64` of word `i / 64` set when
    /// the 3×3 around it is at the hold level at plane `start + i`.
    bits: Vec<u64>,
    /// Indices into `pixels`, by raster index.
    sorted: Vec<u32>,
}

/// A track of the tracker bound to the answers at its anchor.
#[derive(Debug, Clone, Copy)]
pub(super) struct Bound {
    pixel: u32,
    /// The first plane answered.
    from: u64,
}

impl NearAhead {
    /// The answers at raster index `pixel`, if it was tested.
    pub(super) fn find(&self, pixel: u32) -> Option<Bound> {
        let at = self
            .sorted
            .binary_search_by_key(&pixel, |&k| self.pixels[k as usize].0)
            .ok()?;
        let k = self.sorted[at];
        Some(Bound {
            pixel: k,
            from: self.start + u64::from(self.pixels[k as usize].1),
        })
    }

    /// The answer of `bound` at plane `t`, if it has one.
    #[inline]
    pub(super) fn on(&self, bound: Bound, t: u64) -> Option<bool> {
        // `from` is within the chunk, so is t from there on.
        if t < bound.from {
            return None;
        }
        let i = (t - self.start) as usize;
        if i >= self.planes {
            return None;
        }
        let w = self.bits[bound.pixel as usize * self.words + i / 64];
        Some(w >> (i % 64) & 1 != 0)
    }
}

/// The anchors of the tracker's live tracks (raster indices), as it last
/// published them at a chunk's start, for the workers to test from their
/// chunks' first planes: a track that lives through many chunks has an
/// anchor that may no longer be a candidate, or only late in a chunk. The
/// tracker is chunks behind the workers, so these are a guess (most tracks
/// that live that long live longer), which only decides where a test is
/// made.
#[derive(Debug, Default)]
pub(super) struct LiveAnchors(Mutex<Arc<Vec<u32>>>);

impl LiveAnchors {
    /// Replaces the anchors.
    pub(super) fn publish(&self, pixels: Vec<u32>) {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner) = Arc::new(pixels);
    }

    /// The anchors last published.
    pub(super) fn latest(&self) -> Arc<Vec<u32>> {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

/// A worker's tests over a chunk, plane by plane.
#[derive(Debug)]
pub(super) struct AheadTests {
    ahead: NearAhead,
    /// The most pixels tested.
    most: usize,
    width: usize,
    /// The next plane, from the chunk's start.
    plane: u32,
}

impl AheadTests {
    /// No pixel tested yet, for the chunk of `planes` planes that begins at
    /// plane `start`, on a field `width` wide tracked in `slots` slots.
    pub(super) fn new(start: u64, planes: usize, width: usize, slots: usize) -> AheadTests {
        AheadTests {
            ahead: NearAhead {
                start,
                planes,
                words: planes.div_ceil(64),
                ..Default::default()
            },
            most: 2 * slots,
            width,
            plane: 0,
        }
    }

    /// Tests `pixels` too (anchors of the tracker's live tracks, as it last
    /// published them: [`LiveAnchors`]), from the chunk's first plane, before
    /// any plane is taken; `seen` as for [`AheadTests::plane`].
    pub(super) fn seed(&mut self, pixels: &[u32], seen: &mut [u64]) {
        debug_assert_eq!(self.plane, 0);
        for &p in pixels {
            self.add(p as usize, seen);
        }
    }

    /// Tests pixel `p` from the next plane on, unless it is tested already
    /// or the bound is reached.
    fn add(&mut self, p: usize, seen: &mut [u64]) {
        let a = &mut self.ahead;
        if a.pixels.len() < self.most && seen[p / 64] >> (p % 64) & 1 == 0 {
            seen[p / 64] |= 1 << (p % 64);
            a.pixels.push((p as u32, self.plane));
            a.bits.resize(a.bits.len() + a.words, 0);
        }
    }

    /// The tests at the chunk's next plane, which `front` has just taken:
    /// its new candidates' pixels join those tested. `seen` is a bitmap of
    /// the field with the pixels tested set (all clear at the chunk's start;
    /// [`AheadTests::finish`] clears it again).
    pub(super) fn plane(&mut self, front: &FastFrontEnd, seen: &mut [u64]) {
        for c in &front.candidates {
            if self.ahead.pixels.len() == self.most {
                break;
            }
            self.add(c.y as usize * self.width + c.x as usize, seen);
        }
        let a = &mut self.ahead;
        let i = self.plane as usize;
        let (word, bit) = (i / 64, i % 64);
        for (k, &(p, _)) in a.pixels.iter().enumerate() {
            let (x, y) = (p as usize % self.width, p as usize / self.width);
            a.bits[k * a.words + word] |= u64::from(front.neighbourhood_on(x, y)) << bit;
        }
        self.plane += 1;
    }

    /// The answers, `seen` cleared.
    pub(super) fn finish(mut self, seen: &mut [u64]) -> NearAhead {
        let a = &mut self.ahead;
        debug_assert!(self.plane as usize <= a.planes);
        for &(p, _) in &a.pixels {
            seen[p as usize / 64] &= !(1 << (p % 64));
        }
        a.sorted = (0..a.pixels.len() as u32).collect();
        a.sorted.sort_unstable_by_key(|&k| a.pixels[k as usize].0);
        self.ahead
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::PipelineConfig;
    use crate::plane::BitPlane;
    use proptest::prelude::*;

    proptest! {
        /// Any field and planes, thresholds and slots: the test on H says
        /// what the test on the pixels at the hold level says, at every
        /// pixel (the edges included); the answers of a chunk that starts
        /// anywhere are that test, for the anchors published (from the
        /// chunk's start) and the pixels that were candidates (from the
        /// plane they first were), within the chunk only, for the first
        /// twice-the-slots of those pixels.
        #[test]
        fn the_answers_made_ahead_are_the_tests(
            (w, h) in (1usize..40, 1usize..12),
            seeds in proptest::collection::vec(any::<u64>(), 24),
            (thr_int, hold_below) in (0u32..40, 0u32..20),
            slots in 1usize..6,
            start in 0usize..12,
            live in proptest::collection::vec(any::<prop::sample::Index>(), 0..8),
        ) {
            let mut cfg = PipelineConfig::new(w, h, 4, vec![1, 2, 1], 0, thr_int);
            cfg.threshold_hold = thr_int.saturating_sub(hold_below);
            cfg.slots = slots;
            let planes: Vec<BitPlane> = seeds
                .iter()
                .map(|&s| BitPlane::from_fn(w, h, |x, y| {
                    let v = s.rotate_left((x * 7 + y * 13) as u32 % 64);
                    v & 3 == 0
                }))
                .collect();
            let live: Vec<u32> = live.iter().map(|i| i.index(w * h) as u32).collect();
            let zero = BitPlane::zeros(w, h);
            let mut front = FastFrontEnd::new(&cfg);
            let mut tests = AheadTests::new(start as u64, planes.len() - start, w, slots);
            let mut seen = vec![0; (w * h).div_ceil(64)];
            tests.seed(&live, &mut seen);
            // The pixels tested, in the order they join, and from which
            // plane of the chunk.
            let mut tested: Vec<(u32, usize)> = Vec::new();
            let mut join = |p: u32, i: usize| {
                if tested.len() < 2 * slots && !tested.iter().any(|&(q, _)| q == p) {
                    tested.push((p, i));
                }
            };
            live.iter().for_each(|&p| join(p, 0));
            let mut want = Vec::new();
            for (t, p) in planes.iter().enumerate() {
                front.push(p, t.checked_sub(4).map_or(&zero, |d| &planes[d]));
                // The test on H is the test on the pixels at the hold level.
                let on: Vec<bool> = (0..w * h)
                    .map(|i| super::super::above::pixels_near(front.above(), w, h, i % w, i / w))
                    .collect();
                for (i, &o) in on.iter().enumerate() {
                    prop_assert_eq!(front.neighbourhood_on(i % w, i / w), o);
                }
                if t >= start {
                    tests.plane(&front, &mut seen);
                    for c in front.candidates() {
                        join((c.y as usize * w + c.x as usize) as u32, t - start);
                    }
                    want.push(on);
                }
            }
            let ahead = tests.finish(&mut seen);
            prop_assert!(seen.iter().all(|&s| s == 0));
            prop_assert_eq!(ahead.pixels.len(), tested.len());
            for p in 0..(w * h) as u32 {
                let first = tested.iter().find(|&&(q, _)| q == p).map(|&(_, i)| i);
                let bound = ahead.find(p);
                prop_assert_eq!(bound.is_some(), first.is_some());
                let (Some(bound), Some(first)) = (bound, first) else { continue };
                prop_assert_eq!(bound.from, (start + first) as u64);
                for (i, on) in want.iter().enumerate() {
                    let got = ahead.on(bound, (start + i) as u64);
                    prop_assert_eq!(got, (i >= first).then_some(on[p as usize]));
                }
                prop_assert_eq!(ahead.on(bound, planes.len() as u64), None);
            }
        }
    }
}
