//! A bit-plane: one binary exposure of the whole sensor.
//!
//! Pixels are stored in raster order (row by row from the top, left to right
//! within a row); pixel (x, y) has raster index `y·width + x`.

use bitvec::prelude::*;

/// One binary bit-plane `B_t(x, y) ∈ {0, 1}`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BitPlane {
    width: usize,
    height: usize,
    bits: BitVec<u64, Lsb0>,
}

impl BitPlane {
    /// An all-zero plane.
    pub fn zeros(width: usize, height: usize) -> BitPlane {
        BitPlane {
            width,
            height,
            bits: bitvec![u64, Lsb0; 0; width * height],
        }
    }

    /// An all-one plane (every pixel saturated).
    pub fn ones(width: usize, height: usize) -> BitPlane {
        BitPlane {
            width,
            height,
            bits: bitvec![u64, Lsb0; 1; width * height],
        }
    }

    /// Builds a plane from a predicate on (x, y).
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> bool,
    ) -> BitPlane {
        let mut p = BitPlane::zeros(width, height);
        for y in 0..height {
            for x in 0..width {
                if f(x, y) {
                    p.set(x, y, true);
                }
            }
        }
        p
    }

    /// Wraps raster-order bits; `bits.len()` must equal `width·height`. Bits
    /// that start inside their first word (a vector cut from a slice) are
    /// moved to its first bit: a plane's [`BitPlane::words`] hold pixel i at
    /// bit `i % 64` of word `i / 64`, always.
    pub fn from_bits(width: usize, height: usize, mut bits: BitVec<u64, Lsb0>) -> Option<BitPlane> {
        bits.force_align();
        (bits.len() == width * height).then_some(BitPlane {
            width,
            height,
            bits,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixel at (x, y); panics if outside the plane.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> bool {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        self.bits[y * self.width + x]
    }

    /// The pixel at signed (x, y), 0 outside the plane (zero padding).
    #[inline]
    pub fn get_or_zero(&self, x: i64, y: i64) -> bool {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            false
        } else {
            self.bits[y as usize * self.width + x as usize]
        }
    }

    /// Up to 64 pixels of row `y` from column `x0` (signed) as bits, pixel
    /// `x0 + i` at bit i; pixels outside the plane read 0.
    #[inline]
    pub fn row_bits(&self, x0: i64, y: i64, len: usize) -> u64 {
        debug_assert!(len <= 64);
        let Some((start, n, shift)) = self.row_span(x0, y, len) else {
            return 0;
        };
        // Whole words (bitvec's generic load costs as much as the ROI sums).
        let words = self.words();
        let (w, b) = (start / 64, start % 64);
        let mut v = words[w] >> b;
        if b + n > 64 {
            v |= words[w + 1] << (64 - b);
        }
        if n < 64 {
            v &= (1u64 << n) - 1;
        }
        v << shift
    }

    /// The part of row `y` from column `x0` (signed), `len` pixels long,
    /// that lies on the plane: its first raster index, its length and its
    /// offset from `x0`; `None` when no pixel of it is on the plane.
    #[inline]
    fn row_span(&self, x0: i64, y: i64, len: usize) -> Option<(usize, usize, usize)> {
        if y < 0 || y >= self.height as i64 || len == 0 {
            return None;
        }
        let lo = x0.max(0);
        let hi = (x0 + len as i64).min(self.width as i64);
        (lo < hi).then(|| {
            let start = y as usize * self.width + lo as usize;
            (start, (hi - lo) as usize, (lo - x0) as usize)
        })
    }

    /// Sets the pixel at (x, y); panics if outside the plane.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, value: bool) {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        self.bits.set(y * self.width + x, value);
    }

    /// Raster-order bits.
    pub fn bits(&self) -> &BitSlice<u64, Lsb0> {
        &self.bits
    }

    /// Asks the CPU to bring the words of [`BitPlane::row_bits`]`(x0, y, len)`
    /// into its cache (a hint: no effect on any result). The ROI sums read a
    /// few words of the plane leaving the delay line, which is N planes old
    /// and, for a large field, far out of the cache: prefetched one plane
    /// ahead, they no longer wait on memory.
    #[inline]
    pub fn prefetch_row(&self, x0: i64, y: i64, len: usize) {
        if let Some((start, n, _)) = self.row_span(x0, y, len) {
            prefetch(&self.words()[start / 64..=(start + n - 1) / 64]);
        }
    }

    /// The raster-order bits as 64-bit words, pixel i at bit `i % 64` of word
    /// `i / 64` (every constructor starts the bits at a word's first bit).
    /// Bits past `width·height` in the last word are unspecified.
    pub fn words(&self) -> &[u64] {
        self.bits.as_raw_slice()
    }

    /// Stream word `idx` as the gateware's pixel port takes it: the `p`
    /// pixels `idx·p … idx·p + p − 1` in raster order, pixel `idx·p + i` in
    /// bit i.
    ///
    /// # Panics
    /// If `p` is not in 1..=64 or the word runs past the plane (a
    /// programming error: a stream word never straddles planes).
    pub fn stream_word(&self, p: usize, idx: usize) -> u64 {
        assert!((1..=64).contains(&p), "stream words of 1 to 64 pixels");
        self.bits[idx * p..(idx + 1) * p].load_le::<u64>()
    }

    /// Mutable raster-order words, laid out as [`BitPlane::words`]'s.
    pub fn words_mut(&mut self) -> &mut [u64] {
        self.bits.as_raw_mut_slice()
    }

    /// Clears the masked pixels in place (what
    /// [`HotPixelMask::apply`](crate::hot_pixel_mask::HotPixelMask::apply)
    /// does to a copy).
    pub fn mask_in_place(&mut self, mask: &crate::hot_pixel_mask::HotPixelMask) {
        for (w, &m) in self.words_mut().iter_mut().zip(mask.words()) {
            *w &= !m;
        }
    }

    /// Mutable raster-order bits.
    pub fn bits_mut(&mut self) -> &mut BitSlice<u64, Lsb0> {
        &mut self.bits
    }

    /// Makes this plane a copy of `src`, with the pixels of `mask` forced to
    /// 0 where a mask is given, reusing this plane's memory when the sizes
    /// agree (the delay line recycles the plane that left it).
    pub fn copy_masked(
        &mut self,
        src: &BitPlane,
        mask: Option<&crate::hot_pixel_mask::HotPixelMask>,
    ) {
        let aligned = |p: &BitPlane| p.bits.as_bitptr().bit().into_inner() == 0;
        if (self.width, self.height) == (src.width, src.height) && aligned(self) && aligned(src) {
            let dst = self.bits.as_raw_mut_slice();
            let from = src.bits.as_raw_slice();
            match mask {
                None => dst.copy_from_slice(from),
                Some(m) => {
                    for ((d, &s), &k) in dst.iter_mut().zip(from).zip(m.words()) {
                        *d = s & !k;
                    }
                }
            }
        } else {
            *self = match mask {
                Some(m) => m.apply(src),
                None => src.clone(),
            };
        }
    }

    /// Number of pixels that read 1.
    pub fn count_ones(&self) -> usize {
        self.bits.count_ones()
    }
}

/// Asks the CPU to bring every cache line that `s` touches into its cache
/// (a hint: no effect on any result). Used where a read far out of the
/// cache is known a plane ahead: the ROI rows of the plane that leaves the
/// delay line next, the next plane's pixels at the hold level.
#[inline]
pub(crate) fn prefetch<T>(s: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        const LINE: usize = 64;
        let base = s.as_ptr().cast::<i8>();
        // From the start of the first line to the end of the slice.
        let skew = base as usize % LINE;
        let mut offset = 0;
        while offset < skew + std::mem::size_of_val(s) {
            // SAFETY: SSE is part of the x86-64 baseline; a prefetch never
            // faults, and every address lies in a line that `s` touches.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(base.wrapping_sub(skew).wrapping_add(offset)) };
            offset += LINE;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = s;
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn bits_cut_from_a_slice_give_aligned_words() {
        let plane = BitPlane::from_fn(37, 5, |x, y| (x * 3 + y * 7) % 5 < 2);
        for head in [1, 3, 63] {
            let mut longer = bitvec![u64, Lsb0; 1; head];
            longer.extend_from_bitslice(plane.bits());
            let cut = BitVec::from_bitslice(&longer[head..]);
            assert_ne!(
                cut.as_bitptr().bit().into_inner(),
                0,
                "the cut starts mid-word"
            );
            let p = BitPlane::from_bits(37, 5, cut).unwrap();
            assert_eq!(p, plane);
            for i in 0..37 * 5 {
                let bit = (p.words()[i / 64] >> (i % 64)) & 1 == 1;
                assert_eq!(bit, p.get(i % 37, i / 37), "pixel {i}");
            }
            assert_eq!(p.row_bits(-3, 2, 20), plane.row_bits(-3, 2, 20));
        }
    }

    proptest! {
        #[test]
        fn row_bits_equals_pixel_reads(w in 1usize..90, h in 1usize..4, x0 in -70i64..100, y in -2i64..6, len in 0usize..=64, seed in any::<u64>()) {
            let p = BitPlane::from_fn(w, h, |x, y| (seed.rotate_left((x * 7 + y * 13) as u32 % 64)) & 1 == 1);
            let bits = p.row_bits(x0, y, len);
            for i in 0..64 {
                let expect = i < len && p.get_or_zero(x0 + i as i64, y);
                prop_assert_eq!((bits >> i) & 1 == 1, expect, "bit {}", i);
            }
        }

        /// A prefetch anywhere, on or off the plane, is only a hint: it
        /// neither panics nor changes a bit.
        #[test]
        fn prefetch_row_anywhere_changes_nothing(w in 1usize..200, h in 1usize..4, x0 in -300i64..300, y in -3i64..7, len in 0usize..=64, seed in any::<u64>()) {
            let p = BitPlane::from_fn(w, h, |x, y| (seed.rotate_left((x * 7 + y * 13) as u32 % 64)) & 1 == 1);
            let before = p.clone();
            p.prefetch_row(x0, y, len);
            prop_assert_eq!(p, before);
        }
    }
}
