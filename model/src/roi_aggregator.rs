//! Stage 6 — ROI aggregation: each slot sums the *raw* (masked) bit-planes of
//! its blink in an R×R ROI centred on the anchor.
//!
//! At plane t a slot adds the delayed plane `B_{t−N}` while the planes of
//! its segment come out of the delay line, `[max(0, t_cross − N), last]`
//! (the [tracker](crate::blink_tracker) decides the range). Pixels outside the sensor
//! count 0 and set the EDGE flag; masked (hot) pixels count 0 (the plane arrives
//! masked) and set the MASKED flag. ROIs of neighbouring tracks may overlap;
//! each counts its photons independently. A count never exceeds
//! `N + L_max + 1`, which the configuration guarantees fits 32 bits.

use crate::hot_pixel_mask::HotPixelMask;
use crate::plane::BitPlane;
use crate::record::flags;

/// The counts of one slot's ROI.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RoiAccumulator {
    x0: i64,
    y0: i64,
    size: usize,
    counts: Vec<u32>,
    flags: u8,
}

impl RoiAccumulator {
    /// The counts so far, row-major from the top-left pixel.
    pub fn counts(&self) -> &[u32] {
        &self.counts
    }

    /// EDGE / MASKED flags of this ROI.
    pub fn flags(&self) -> u8 {
        self.flags
    }

    fn add(&mut self, plane: &BitPlane) {
        for dy in 0..self.size {
            // One row of the ROI at a time, visiting only the pixels that read 1.
            let mut bits = plane.row_bits(self.x0, self.y0 + dy as i64, self.size);
            while bits != 0 {
                let dx = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                self.counts[dy * self.size + dx] += 1;
            }
        }
    }
}

/// One ROI accumulator per tracking slot.
#[derive(Debug, Clone)]
pub struct RoiAggregator {
    size: usize,
    width: usize,
    height: usize,
    slots: Vec<Option<RoiAccumulator>>,
}

impl RoiAggregator {
    /// `slots` empty accumulators of side `size` (odd) on a `width × height` sensor.
    pub fn new(slots: usize, size: usize, width: usize, height: usize) -> RoiAggregator {
        RoiAggregator {
            size,
            width,
            height,
            slots: vec![None; slots],
        }
    }

    /// Starts slot `slot` at zero around the anchor.
    pub fn open(&mut self, slot: usize, anchor_x: u16, anchor_y: u16, mask: Option<&HotPixelMask>) {
        let half = (self.size / 2) as i64;
        let (x0, y0) = (anchor_x as i64 - half, anchor_y as i64 - half);
        let s = self.size as i64;
        let mut f = 0;
        if x0 < 0 || y0 < 0 || x0 + s > self.width as i64 || y0 + s > self.height as i64 {
            f |= flags::EDGE;
        }
        if let Some(m) = mask {
            if (0..s).any(|dy| (0..s).any(|dx| m.is_masked(x0 + dx, y0 + dy))) {
                f |= flags::MASKED;
            }
        }
        self.slots[slot] = Some(RoiAccumulator {
            x0,
            y0,
            size: self.size,
            counts: vec![0; self.size * self.size],
            flags: f,
        });
    }

    /// Adds a plane to slot `slot` (no-op for an empty slot).
    pub fn add(&mut self, slot: usize, plane: &BitPlane) {
        if let Some(acc) = &mut self.slots[slot] {
            acc.add(plane);
        }
    }

    /// The accumulator of a slot.
    pub fn get(&self, slot: usize) -> Option<&RoiAccumulator> {
        self.slots[slot].as_ref()
    }

    /// Prefetches the rows of `plane` that every open slot's ROI covers (a
    /// cache hint, see [`BitPlane::prefetch_row`]): the pipeline calls it
    /// with the plane that leaves the delay line next.
    pub fn prefetch(&self, plane: &BitPlane) {
        for slot in 0..self.slots.len() {
            self.prefetch_slot(slot, plane);
        }
    }

    /// [`RoiAggregator::prefetch`] for one slot (no-op for an empty slot).
    pub fn prefetch_slot(&self, slot: usize, plane: &BitPlane) {
        if let Some(acc) = &self.slots[slot] {
            for dy in 0..acc.size {
                plane.prefetch_row(acc.x0, acc.y0 + dy as i64, acc.size);
            }
        }
    }

    /// Returns the counts and flags of `slot` and restarts it at zero (same anchor).
    pub fn take(&mut self, slot: usize) -> Option<(Vec<u32>, u8)> {
        let acc = self.slots[slot].as_mut()?;
        let counts = std::mem::replace(&mut acc.counts, vec![0; acc.size * acc.size]);
        Some((counts, acc.flags))
    }

    /// Empties a slot.
    pub fn close(&mut self, slot: usize) {
        self.slots[slot] = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_roi_counts_only_inside_and_is_flagged() {
        let mut agg = RoiAggregator::new(2, 3, 4, 4);
        agg.open(0, 0, 0, None);
        agg.open(1, 2, 2, None);
        let p = BitPlane::ones(4, 4);
        agg.add(0, &p);
        agg.add(0, &p);
        agg.add(1, &p);
        let (c0, f0) = agg.take(0).unwrap();
        assert_eq!(c0, vec![0, 0, 0, 0, 2, 2, 0, 2, 2]);
        assert_eq!(f0, flags::EDGE);
        assert_eq!(agg.get(0).unwrap().counts(), &[0; 9]);
        assert_eq!(agg.get(1).unwrap().counts(), &[1; 9]);
        assert_eq!(agg.get(1).unwrap().flags(), 0);
    }

    #[test]
    fn masked_pixel_in_roi_sets_flag() {
        let (mask, _) = HotPixelMask::from_pixels(8, 8, &[(5, 5)]);
        let mut agg = RoiAggregator::new(1, 3, 8, 8);
        agg.open(0, 4, 4, Some(&mask));
        assert_eq!(agg.get(0).unwrap().flags(), flags::MASKED);
        agg.open(0, 1, 1, Some(&mask));
        assert_eq!(agg.get(0).unwrap().flags(), 0);
    }
}
