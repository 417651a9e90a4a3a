//! Stage 1 — rolling count `S_t = Σ_{u=t−N+1..t} B_u` per pixel, kept
//! incrementally as `S_t = S_{t−1} + B_t − B_{t−N}` with `B_{t−N}` from the
//! [delay line](crate::delay_line). `0 ≤ S ≤ N` always, so a counter of
//! ⌈log2(N+1)⌉ bits never wraps.

use crate::plane::BitPlane;

/// Per-pixel counts of ones over the last N bit-planes.
#[derive(Debug, Clone)]
pub struct RollingCount {
    width: usize,
    height: usize,
    counts: Vec<u32>,
}

impl RollingCount {
    /// All counts zero (the stream is preceded by zero planes).
    pub fn new(width: usize, height: usize) -> RollingCount {
        RollingCount {
            width,
            height,
            counts: vec![0; width * height],
        }
    }

    /// Adds the newest plane and removes the plane leaving the window.
    pub fn update(&mut self, newest: &BitPlane, leaving: &BitPlane) {
        debug_assert_eq!((newest.width(), newest.height()), (self.width, self.height));
        for ((c, b_new), b_old) in self
            .counts
            .iter_mut()
            .zip(newest.bits().iter().by_vals())
            .zip(leaving.bits().iter().by_vals())
        {
            // A one can only leave the window if it entered it N planes ago.
            *c = *c + b_new as u32 - b_old as u32;
        }
    }

    /// The counts `S_t`, raster order.
    pub fn counts(&self) -> &[u32] {
        &self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delay_line::DelayLine;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn equals_direct_window_sum(n in 1usize..7, seed in any::<u64>(), planes in 1usize..30) {
            let (w, h) = (5, 3);
            let mut rng = seed;
            let mut next = move || { rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17; rng };
            let stream: Vec<BitPlane> = (0..planes).map(|_| BitPlane::from_fn(w, h, |_, _| next() % 3 == 0)).collect();
            let mut dl = DelayLine::new(n, w, h);
            let mut rc = RollingCount::new(w, h);
            for (t, p) in stream.iter().enumerate() {
                let old = dl.push(p.clone());
                rc.update(p, &old);
                for y in 0..h { for x in 0..w {
                    let direct = stream[t.saturating_sub(n - 1)..=t].iter().filter(|q| q.get(x, y)).count() as u32;
                    prop_assert_eq!(rc.counts()[y * w + x], direct);
                }}
            }
        }
    }
}
