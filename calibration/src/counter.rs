//! Per-pixel counts of ones over many bit-planes.
//!
//! Counting bit by bit costs one operation per pixel that reads 1: cheap for
//! a dark recording (≈ 1 % ones) but not for a flat (≈ 25 %). The counter
//! keeps 8 *bit-sliced* counters instead: slice s holds bit s of every
//! pixel's count, 64 pixels per word, and adding a plane is a ripple-carry
//! add of the plane's word into the slices (`sum = slice ^ carry`,
//! `carry = slice & carry`), which stops as soon as the carry is zero. After
//! 255 planes (the most 8 bits hold) the slices are added into 64-bit
//! totals and cleared.

use smartagg_model::plane::BitPlane;

use super::CalibrationError;

/// Bits of the sliced counters: flushed every `2^SLICES − 1` planes.
const SLICES: usize = 8;
const FLUSH_EVERY: u32 = (1 << SLICES) - 1;

/// Counts, per pixel, the bit-planes in which it read 1.
#[derive(Debug, Clone)]
pub struct PlaneCounter {
    width: u32,
    height: u32,
    pixels: usize,
    words: usize,
    /// Slice s of word w at `s * words + w`.
    slices: Vec<u64>,
    pending: u32,
    totals: Vec<u64>,
    planes: u64,
}

/// The result of counting: per-pixel ones over `planes` bit-planes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlaneCounts {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Bit-planes counted.
    pub planes: u64,
    /// Ones per pixel, raster order.
    pub ones: Vec<u64>,
}

impl PlaneCounter {
    /// A counter for `width × height` planes.
    pub fn new(width: u32, height: u32) -> PlaneCounter {
        let pixels = width as usize * height as usize;
        let words = pixels.div_ceil(64);
        PlaneCounter {
            width,
            height,
            pixels,
            words,
            slices: vec![0; words * SLICES],
            pending: 0,
            totals: vec![0; pixels],
            planes: 0,
        }
    }

    /// Adds one bit-plane; a plane of another size is an error.
    pub fn push(&mut self, plane: &BitPlane) -> Result<(), CalibrationError> {
        if plane.width() != self.width as usize || plane.height() != self.height as usize {
            return Err(CalibrationError::SizeMismatch {
                what: format!("bit-plane {}", self.planes),
                expected: (self.width, self.height),
                found: (plane.width() as u32, plane.height() as u32),
            });
        }
        self.push_words(plane.words());
        Ok(())
    }

    /// Adds one plane given as 64-pixel words (pixel i at bit `i % 64` of
    /// word `i / 64`); bits past the last pixel are ignored.
    pub fn push_words(&mut self, words: &[u64]) {
        let n = self.words;
        let tail_bits = self.pixels % 64;
        for (w, &word) in words.iter().enumerate().take(n) {
            let mut carry = if w + 1 == n && tail_bits != 0 {
                word & ((1u64 << tail_bits) - 1)
            } else {
                word
            };
            let mut s = 0;
            while carry != 0 {
                let slot = &mut self.slices[s * n + w];
                let x = *slot;
                *slot = x ^ carry;
                carry &= x;
                s += 1;
            }
        }
        self.planes += 1;
        self.pending += 1;
        if self.pending == FLUSH_EVERY {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let n = self.words;
        for w in 0..n {
            let mut any = 0u64;
            for s in 0..SLICES {
                any |= self.slices[s * n + w];
            }
            if any == 0 {
                continue;
            }
            let base = w * 64;
            let last = (self.pixels - base).min(64);
            for s in 0..SLICES {
                let mut bits = self.slices[s * n + w];
                self.slices[s * n + w] = 0;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if b < last {
                        self.totals[base + b] += 1 << s;
                    }
                }
            }
        }
        self.pending = 0;
    }

    /// Planes counted so far.
    pub fn planes(&self) -> u64 {
        self.planes
    }

    /// The counts so far.
    pub fn finish(mut self) -> PlaneCounts {
        self.flush();
        PlaneCounts {
            width: self.width,
            height: self.height,
            planes: self.planes,
            ones: self.totals,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    proptest! {
        #[test]
        fn sliced_counts_equal_bit_by_bit_counts(w in 1u32..140, h in 1u32..4, planes in 0usize..700, p in 0.0f64..1.0, seed: u64) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut c = PlaneCounter::new(w, h);
            let mut naive = vec![0u64; (w * h) as usize];
            for _ in 0..planes {
                let plane = BitPlane::from_fn(w as usize, h as usize, |_, _| rng.gen_bool(p));
                for i in plane.bits().iter_ones() {
                    naive[i] += 1;
                }
                c.push(&plane).unwrap();
            }
            let counts = c.finish();
            prop_assert_eq!(counts.planes, planes as u64);
            prop_assert_eq!(counts.ones, naive);
        }
    }

    #[test]
    fn padding_bits_and_wrong_sizes() {
        let mut c = PlaneCounter::new(3, 3);
        for _ in 0..600 {
            c.push_words(&[u64::MAX]);
        }
        let r = c.finish();
        assert_eq!(r.ones, vec![600; 9]);
        let mut c = PlaneCounter::new(3, 3);
        let e = c.push(&BitPlane::zeros(3, 4)).unwrap_err().to_string();
        assert!(e.contains("3x3") && e.contains("3x4"), "{e}");
    }
}
