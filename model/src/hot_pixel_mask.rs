//! Stage 0 — hot-pixel mask: masked pixels read as 0 everywhere downstream
//! (rolling count, filter, ROI sums). Which pixels are hot follows from
//! calibration: a pixel whose dark counts alone would cross the threshold.

use crate::plane::BitPlane;
use bitvec::prelude::*;

/// A set of masked (hot) pixels, in raster order like [`BitPlane`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HotPixelMask {
    width: usize,
    height: usize,
    masked: BitVec<u64, Lsb0>,
}

impl HotPixelMask {
    /// A mask with no pixel masked.
    pub fn new(width: usize, height: usize) -> HotPixelMask {
        HotPixelMask {
            width,
            height,
            masked: bitvec![u64, Lsb0; 0; width * height],
        }
    }

    /// A mask from a list of (x, y) pixels; pixels outside the sensor are ignored
    /// and returned so the caller can report them.
    pub fn from_pixels(
        width: usize,
        height: usize,
        pixels: &[(usize, usize)],
    ) -> (HotPixelMask, Vec<(usize, usize)>) {
        let mut m = HotPixelMask::new(width, height);
        let mut outside = Vec::new();
        for &(x, y) in pixels {
            if x < width && y < height {
                m.set(x, y, true);
            } else {
                outside.push((x, y));
            }
        }
        (m, outside)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Marks or unmarks a pixel.
    pub fn set(&mut self, x: usize, y: usize, hot: bool) {
        self.masked.set(y * self.width + x, hot);
    }

    /// Whether the pixel at signed (x, y) is masked (outside the sensor: no).
    pub fn is_masked(&self, x: i64, y: i64) -> bool {
        x >= 0
            && y >= 0
            && (x as usize) < self.width
            && (y as usize) < self.height
            && self.masked[y as usize * self.width + x as usize]
    }

    /// The mask as raster-order 64-bit words (pixel i at bit `i % 64` of
    /// word `i / 64`; 1 = masked), as [`BitPlane::words`] lays out a plane.
    pub fn words(&self) -> &[u64] {
        self.masked.as_raw_slice()
    }

    /// Number of masked pixels.
    pub fn count(&self) -> usize {
        self.masked.count_ones()
    }

    /// The plane with every masked pixel forced to 0.
    pub fn apply(&self, plane: &BitPlane) -> BitPlane {
        // B AND NOT mask on whole 64-pixel words (bit-by-bit chunk loads cost
        // as much as the fast engine's filter). Both start at bit 0 of a word
        // unless the plane was built from an offset bit-slice: then bit by bit.
        if plane.bits().as_bitptr().bit().into_inner() == 0 {
            let words: Vec<u64> = plane
                .words()
                .iter()
                .zip(self.masked.as_raw_slice())
                .map(|(&b, &m)| b & !m)
                .collect();
            let mut bits = BitVec::<u64, Lsb0>::from_vec(words);
            bits.truncate(plane.width() * plane.height());
            if let Some(out) = BitPlane::from_bits(plane.width(), plane.height(), bits) {
                return out;
            }
        }
        let mut out = plane.clone();
        for (o, m) in out.bits_mut().chunks_mut(64).zip(self.masked.chunks(64)) {
            let v = o.load_le::<u64>() & !m.load_le::<u64>();
            o.store_le(v);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masked_pixels_read_zero_and_others_pass() {
        let (mask, outside) =
            HotPixelMask::from_pixels(70, 3, &[(0, 0), (69, 2), (65, 1), (80, 0)]);
        assert_eq!(outside, vec![(80, 0)]);
        assert_eq!(mask.count(), 3);
        let out = mask.apply(&BitPlane::ones(70, 3));
        assert_eq!(out.count_ones(), 70 * 3 - 3);
        assert!(!out.get(0, 0) && !out.get(69, 2) && !out.get(65, 1) && out.get(64, 1));
        assert!(mask.is_masked(65, 1) && !mask.is_masked(-1, 0) && !mask.is_masked(70, 0));
    }
}
