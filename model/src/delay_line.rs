//! Stage 1a — the N-plane delay line: returns `B_{t−N}` when `B_t` goes in.
//!
//! Planes before stream start are all zero, so for `t < N` it returns a zero
//! plane (the gateware must force this: DDR2 powers up with garbage). The same
//! delayed stream serves the rolling count (stage 1) and the ROI sums
//! (stage 6), which add the planes from `t_cross − N` on as they leave.

use crate::hot_pixel_mask::HotPixelMask;
use crate::plane::BitPlane;
use std::collections::VecDeque;
use std::sync::Arc;

/// One plane of a batch of planes that its owner shares: what the parallel
/// engine hands its back end (its chunks), so that the delay line keeps a
/// reference instead of a copy.
#[derive(Debug, Clone)]
pub struct SharedPlane {
    batch: Arc<Vec<BitPlane>>,
    index: usize,
}

impl SharedPlane {
    /// Every plane of `batch`, in order.
    pub fn every(batch: &Arc<Vec<BitPlane>>) -> impl Iterator<Item = SharedPlane> + '_ {
        SharedPlane::within(batch, 0..batch.len())
    }

    /// The planes of `batch` in `range` (clipped to the batch), in order.
    pub fn within(
        batch: &Arc<Vec<BitPlane>>,
        range: std::ops::Range<usize>,
    ) -> impl Iterator<Item = SharedPlane> + '_ {
        (range.start..range.end.min(batch.len())).map(|index| SharedPlane {
            batch: batch.clone(),
            index,
        })
    }

    /// The plane.
    pub fn plane(&self) -> &BitPlane {
        &self.batch[self.index]
    }
}

/// A plane in the line: its own copy, or a shared one.
#[derive(Debug, Clone)]
enum Held {
    Own(BitPlane),
    Shared(SharedPlane),
}

impl Held {
    fn plane(&self) -> &BitPlane {
        match self {
            Held::Own(p) => p,
            Held::Shared(s) => s.plane(),
        }
    }
}

/// A first-in first-out line of the last N bit-planes, plus the one that
/// has just left (`B_{t−N}`, read by the rolling count and the ROI sums).
/// A copied plane goes into the memory of the copy that left: no plane is
/// allocated per push. A [`SharedPlane`] is kept by reference, not copied.
#[derive(Debug, Clone)]
pub struct DelayLine {
    n: usize,
    /// `B_{t−N} … B_t` once full (N + 1 planes); `B_0 … B_t` before.
    planes: VecDeque<Held>,
    zero: BitPlane,
}

impl DelayLine {
    /// A delay line of `n ≥ 1` planes of `width × height`, initially all zero.
    pub fn new(n: usize, width: usize, height: usize) -> DelayLine {
        assert!(n >= 1, "a delay line holds at least one plane");
        DelayLine {
            n,
            planes: VecDeque::with_capacity(n + 1),
            zero: BitPlane::zeros(width, height),
        }
    }

    /// Pushes `B_t` and returns `B_{t−N}` (zero for `t < N`).
    pub fn push(&mut self, plane: BitPlane) -> BitPlane {
        self.push_masked(&plane, None);
        self.delayed().clone()
    }

    /// Pushes a copy of `B_t`, with the pixels of `mask` forced to 0 where a
    /// mask is given, into the memory of the plane that leaves;
    /// [`DelayLine::delayed`] is then `B_{t−N}`.
    pub fn push_masked(&mut self, plane: &BitPlane, mask: Option<&HotPixelMask>) {
        let mut buf = match self.make_room() {
            Some(Held::Own(buf)) => buf,
            _ => self.zero.clone(),
        };
        buf.copy_masked(plane, mask);
        self.planes.push_back(Held::Own(buf));
    }

    /// Pushes a plane that is already masked, keeping a reference to it.
    pub fn push_shared(&mut self, plane: SharedPlane) {
        self.make_room();
        self.planes.push_back(Held::Shared(plane));
    }

    /// Takes out the plane that left before this push, once the line is full.
    fn make_room(&mut self) -> Option<Held> {
        if self.planes.len() == self.n + 1 {
            self.planes.pop_front()
        } else {
            None
        }
    }

    /// `B_{t−N}` after `B_t` went in (zero for `t < N`).
    pub fn delayed(&self) -> &BitPlane {
        if self.planes.len() == self.n + 1 {
            self.planes[0].plane()
        } else {
            &self.zero
        }
    }

    /// The plane pushed last (`B_t`; zero before the first push).
    pub fn newest(&self) -> &BitPlane {
        self.planes.back().map_or(&self.zero, Held::plane)
    }

    /// The plane that will come out `i + 1` pushes from now (`i < N`), i.e.
    /// `B_{t−N+1+i}` after `B_t` went in; zero where that plane precedes the stream.
    /// Used to complete the ROI sums at stream end.
    pub fn peek(&self, i: usize) -> &BitPlane {
        // planes[j] is B_{t+1−len+j}: B_{t−N+1+i} is at j = i + len − N.
        match (i + self.planes.len()).checked_sub(self.n) {
            Some(j) if j < self.planes.len() => self.planes[j].plane(),
            _ => &self.zero,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn returns_plane_from_n_ago_and_zero_before() {
        let mut d = DelayLine::new(3, 4, 1);
        let planes: Vec<BitPlane> = (0..8)
            .map(|t| BitPlane::from_fn(4, 1, |x, _| (t >> x) & 1 == 1))
            .collect();
        for (t, p) in planes.iter().enumerate() {
            let out = d.push(p.clone());
            assert_eq!(d.newest(), p);
            if t < 3 {
                assert_eq!(out.count_ones(), 0);
            } else {
                assert_eq!(out, planes[t - 3]);
            }
        }
        // After B_7 went in, the next three outputs are B_5, B_6, B_7.
        assert_eq!(d.peek(0), &planes[5]);
        assert_eq!(d.peek(2), &planes[7]);
    }

    #[test]
    fn pushes_reuse_the_plane_that_left_and_apply_the_mask() {
        let (mask, _) = HotPixelMask::from_pixels(70, 2, &[(3, 0), (66, 1)]);
        let mut d = DelayLine::new(2, 70, 2);
        let planes: Vec<BitPlane> = (0..6u64)
            .map(|t| BitPlane::from_fn(70, 2, |x, y| !(x + y + t as usize).is_multiple_of(3)))
            .collect();
        for (t, p) in planes.iter().enumerate() {
            d.push_masked(p, Some(&mask));
            assert_eq!(d.newest(), &mask.apply(p));
            if t >= 2 {
                assert_eq!(d.delayed(), &mask.apply(&planes[t - 2]));
            } else {
                assert_eq!(d.delayed().count_ones(), 0);
            }
        }
        // A plane of another size replaces the buffer instead of copying into it.
        let mut small = BitPlane::zeros(3, 1);
        small.copy_masked(&planes[0], None);
        assert_eq!(small, planes[0]);
    }

    #[test]
    fn shared_and_copied_planes_come_out_alike() {
        let planes: Vec<BitPlane> = (0..12u64)
            .map(|t| {
                BitPlane::from_fn(5, 2, |x, y| {
                    (t * 7 + x as u64 * 3 + y as u64).is_multiple_of(4)
                })
            })
            .collect();
        let batch = Arc::new(planes.clone());
        let mut every: Vec<SharedPlane> = SharedPlane::every(&batch).collect();
        assert!(every.iter().map(SharedPlane::plane).eq(planes.iter()));
        // A range of the batch, clipped to it.
        let within = |r| SharedPlane::within(&batch, r).map(|s| s.plane().clone());
        assert!(within(3..7).eq(planes[3..7].iter().cloned()));
        assert!(within(10..20).eq(planes[10..].iter().cloned()));
        assert_eq!(within(12..20).count(), 0);
        let (mut copied, mut mixed) = (DelayLine::new(3, 5, 2), DelayLine::new(3, 5, 2));
        for (t, p) in planes.iter().enumerate() {
            copied.push_masked(p, None);
            // Runs of shared planes between copies, so that a copy also
            // follows a shared plane out of the line.
            if t % 5 < 3 {
                mixed.push_shared(every[t].clone());
            } else {
                mixed.push_masked(p, None);
            }
            assert_eq!(mixed.newest(), p);
            assert_eq!(mixed.delayed(), copied.delayed(), "plane {t}");
            for i in 0..3 {
                assert_eq!(mixed.peek(i), copied.peek(i), "plane {t}, peek {i}");
            }
        }
        // The line holds N + 1 planes, so it keeps no more of the batch.
        every.clear();
        drop(mixed);
        assert_eq!(Arc::strong_count(&batch), 1);
    }

    #[test]
    fn peek_before_the_line_is_full_is_zero() {
        let mut d = DelayLine::new(4, 2, 1);
        d.push(BitPlane::ones(2, 1));
        assert_eq!(d.peek(0).count_ones(), 0);
        assert_eq!(d.peek(2).count_ones(), 0);
        assert_eq!(d.peek(3).count_ones(), 2);
    }
}
