//! The pixels at or above the hold level (stage 3's output that the
//! tracker's 3×3 tests read), as the front end finds them and as a worker
//! of [`run_parallel`](super::run_parallel) hands them to the tracker.

/// The pixels of a plane at or above the hold level, as the front end's scan
/// finds them: their raster indices, ascending, and, for a worker
/// ([`AboveHold::keep_bits`]) on a crowded field, the same pixels as a
/// bitmap.
#[derive(Debug, Clone, Default)]
pub(super) struct AboveHold {
    /// Raster indices, ascending.
    pub(super) pixels: Vec<u32>,
    /// Pixel i at bit `i % 64` of word `i / 64`: empty unless kept, and
    /// this plane's only while `bits_on`.
    bits: Vec<u64>,
    /// Whether the scan sets the bitmap as it goes: the previous plane was
    /// crowded, so this one likely is (a sparse plane pays nothing for it).
    bits_on: bool,
}

impl AboveHold {
    /// Keeps a bitmap for a field of `pixels` pixels, for the planes handed
    /// on in that form ([`AboveHold::handed_on`]).
    pub(super) fn keep_bits(&mut self, pixels: usize) {
        if self.bits.is_empty() {
            self.bits = vec![0; pixels.div_ceil(64)];
        }
    }

    /// Empties both forms for the next plane.
    pub(super) fn clear(&mut self) {
        self.pixels.clear();
        if self.bits_on {
            self.bits.fill(0);
        }
    }

    /// Pixel `i` (the list is pushed by the caller) in the bitmap.
    #[inline(always)]
    pub(super) fn set_bit(&mut self, i: usize) {
        if self.bits_on {
            self.bits[i / 64] |= 1 << (i % 64);
        }
    }

    /// Pixels `i … i + 7` whose bits are set in `mask` (its low eight) in
    /// the bitmap; they may straddle two words.
    #[inline(always)]
    pub(super) fn set_bits8(&mut self, mask: u32, i: usize) {
        let mask = u64::from(mask & 0xff);
        if !self.bits_on || mask == 0 {
            return;
        }
        let (w, sh) = (i / 64, i % 64);
        self.bits[w] |= mask << sh;
        // A bit carried into the next word is a pixel of the field, so the
        // word exists.
        let carried = if sh > 56 { mask >> (64 - sh) } else { 0 };
        if carried != 0 {
            self.bits[w + 1] |= carried;
        }
    }

    /// The form a worker hands on: the bitmap when the list would be
    /// larger (a crowded plane: in the dense test scene 31,000 pixels, 125
    /// KB as a list, 9.6 KB as bits), the list otherwise.
    pub(super) fn handed_on(&mut self) -> AbovePlane {
        let crowded = !self.bits.is_empty() && self.pixels.len() > 2 * self.bits.len();
        let form = if crowded {
            if !self.bits_on {
                // The first crowded plane after sparse ones: from the list.
                self.bits.fill(0);
                for &p in &self.pixels {
                    self.bits[p as usize / 64] |= 1 << (p % 64);
                }
            }
            AbovePlane::Bits(self.bits.clone())
        } else {
            AbovePlane::Pixels(self.pixels.clone())
        };
        self.bits_on = crowded;
        form
    }
}

/// A plane's pixels at or above the hold level on their way from a worker to
/// the tracker, in the smaller of two forms: the tracker tests 3×3
/// neighbourhoods around its anchors in it ([`AbovePlane::near`]) and, on a
/// large field, would wait on memory for each search of a long list.
#[derive(Debug, Clone)]
pub(super) enum AbovePlane {
    /// Raster indices, ascending.
    Pixels(Vec<u32>),
    /// Pixel i at bit `i % 64` of word `i / 64`.
    Bits(Vec<u64>),
}

impl Default for AbovePlane {
    fn default() -> AbovePlane {
        AbovePlane::Pixels(Vec::new())
    }
}

impl AbovePlane {
    /// Whether any pixel of the 3×3 around (x, y) is at the hold level.
    pub(super) fn near(&self, width: usize, height: usize, x: usize, y: usize) -> bool {
        match self {
            AbovePlane::Pixels(p) => pixels_near(p, width, height, x, y),
            AbovePlane::Bits(b) => bits_near(b, width, height, x, y),
        }
    }

    /// Asks the memory for it ahead of the tests.
    pub(super) fn prefetch(&self) {
        match self {
            AbovePlane::Pixels(p) => crate::plane::prefetch(p),
            AbovePlane::Bits(b) => crate::plane::prefetch(b),
        }
    }
}

/// Whether any pixel of the 3×3 around (x, y) is in the ascending list `above`.
pub(super) fn pixels_near(above: &[u32], width: usize, height: usize, x: usize, y: usize) -> bool {
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(width - 1));
    (y.saturating_sub(1)..=(y + 1).min(height - 1)).any(|yy| {
        let (lo, hi) = ((yy * width + x0) as u32, (yy * width + x1) as u32);
        let i = above.partition_point(|&a| a < lo);
        i < above.len() && above[i] <= hi
    })
}

/// Whether any pixel of the 3×3 around (x, y) is set in the bitmap `bits`.
fn bits_near(bits: &[u64], width: usize, height: usize, x: usize, y: usize) -> bool {
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(width - 1));
    (y.saturating_sub(1)..=(y + 1).min(height - 1)).any(|yy| {
        let (lo, hi) = (yy * width + x0, yy * width + x1);
        // At most three bits, in one word or two.
        let span = (1u64 << (hi - lo + 1)) - 1;
        let (w, sh) = (lo / 64, lo % 64);
        let mut got = (bits[w] >> sh) & span;
        if sh + (hi - lo) >= 64 {
            got |= (bits[w + 1] << (64 - sh)) & span;
        }
        got != 0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Any field (widths that put rows anywhere in a word), any pixels,
        /// any point: the list's and the bitmap's 3×3 tests say what the
        /// definition says, and the bitmap set eight pixels at a time holds
        /// the same bits as one at a time.
        #[test]
        fn both_forms_answer_the_3x3_test(
            (w, h) in (1usize..150, 1usize..12),
            seed in proptest::collection::vec(any::<u8>(), 0..1800),
            (px, py) in (any::<prop::sample::Index>(), any::<prop::sample::Index>()),
        ) {
            let n = w * h;
            let on: Vec<bool> = (0..n).map(|i| seed.get(i).is_some_and(|&b| b < 40)).collect();
            let mut one = AboveHold::default();
            one.keep_bits(n);
            one.bits_on = true;
            let mut eight = one.clone();
            // The list alone: its bitmap is made when it is handed on.
            let mut listed = AboveHold::default();
            listed.keep_bits(n);
            for (i, _) in on.iter().enumerate().filter(|(_, &o)| o) {
                one.pixels.push(i as u32);
                one.set_bit(i);
                listed.pixels.push(i as u32);
                listed.set_bit(i);
            }
            for i in (0..n).step_by(8) {
                let mask = (0..8).filter(|&l| i + l < n && on[i + l]).fold(0u32, |m, l| m | 1 << l);
                eight.set_bits8(mask, i);
            }
            prop_assert_eq!(&one.bits, &eight.bits);
            let (x, y) = (px.index(w), py.index(h));
            let want = (y.saturating_sub(1)..=(y + 1).min(h - 1))
                .any(|yy| (x.saturating_sub(1)..=(x + 1).min(w - 1)).any(|xx| on[yy * w + xx]));
            prop_assert_eq!(pixels_near(&one.pixels, w, h, x, y), want);
            let one_pixels = one.pixels.clone();
            prop_assert_eq!(bits_near(&one.bits, w, h, x, y), want);
            let crowded = one.pixels.len() > 2 * one.bits.len();
            for held in [&mut one, &mut listed] {
                let handed = held.handed_on();
                prop_assert_eq!(handed.near(w, h, x, y), want);
                match handed {
                    AbovePlane::Bits(b) => {
                        prop_assert!(crowded);
                        prop_assert_eq!(&b, &eight.bits);
                    }
                    AbovePlane::Pixels(p) => {
                        prop_assert!(!crowded);
                        prop_assert_eq!(&p, &one_pixels);
                    }
                }
                // The next plane's scan sets the bitmap if this one was crowded.
                prop_assert_eq!(held.bits_on, crowded);
            }
        }
    }
}
