//! Stage 2 — spatial filter `H_t = K ⊛ S_t` with the separable integer kernel
//! `K = k1 ⊗ k1`, zero padding outside the sensor.
//!
//! The filter runs on the rolling counts rather than on each bit-plane: by
//! linearity `K ⊛ Σ_u B_u = Σ_u K ⊛ B_u`, so H equals the paper's rolling sum of
//! filtered planes (Eq. 8) exactly, in integers. It is computed as a horizontal
//! pass (row by row, as pixels stream in) followed by a vertical pass over the
//! last k rows of the horizontal result — the k − 1 line buffers of the gateware.
//! `H ≤ N·2^(2a)`, which [`PipelineConfig`](crate::config::PipelineConfig)
//! guarantees fits 32 bits.

/// The separable integer filter.
#[derive(Debug, Clone)]
pub struct SpatialFilter {
    k1: Vec<u32>,
}

impl SpatialFilter {
    /// A filter with the 1-D integer kernel `k1` (odd length).
    pub fn new(k1: Vec<u32>) -> SpatialFilter {
        assert!(!k1.len().is_multiple_of(2), "kernel length must be odd");
        SpatialFilter { k1 }
    }

    /// Half-width c = (k − 1)/2.
    pub fn half(&self) -> usize {
        self.k1.len() / 2
    }

    /// Horizontal pass of one row: `Σ_i k1[i] · row[x + i − c]`, zero outside.
    pub fn horizontal(&self, row: &[u32], out: &mut [u32]) {
        let c = self.half() as i64;
        let w = row.len() as i64;
        for (x, o) in out.iter_mut().enumerate() {
            let mut acc = 0u32;
            for (i, &k) in self.k1.iter().enumerate() {
                let xi = x as i64 + i as i64 - c;
                if (0..w).contains(&xi) {
                    acc += k * row[xi as usize];
                }
            }
            *o = acc;
        }
    }

    /// `H = K ⊛ S` over a whole `width × height` plane of counts (raster order).
    pub fn apply(&self, counts: &[u32], width: usize, height: usize) -> Vec<u32> {
        let mut horiz = vec![0u32; width * height];
        for y in 0..height {
            self.horizontal(
                &counts[y * width..(y + 1) * width],
                &mut horiz[y * width..(y + 1) * width],
            );
        }
        let c = self.half() as i64;
        let mut out = vec![0u32; width * height];
        for y in 0..height {
            for (j, &k) in self.k1.iter().enumerate() {
                let yj = y as i64 + j as i64 - c;
                if !(0..height as i64).contains(&yj) {
                    continue;
                }
                let src = &horiz[yj as usize * width..(yj as usize + 1) * width];
                for (o, &h) in out[y * width..(y + 1) * width].iter_mut().zip(src) {
                    *o += k * h;
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delay_line::DelayLine;
    use crate::plane::BitPlane;
    use crate::rolling_count::RollingCount;
    use proptest::prelude::*;

    /// Direct 2-D convolution with K = k1 ⊗ k1, zero padding: the definition.
    fn direct(k1: &[u32], img: &[u32], w: usize, h: usize) -> Vec<u32> {
        let c = (k1.len() / 2) as i64;
        let mut out = vec![0; w * h];
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let mut acc = 0;
                for (j, &kj) in k1.iter().enumerate() {
                    for (i, &ki) in k1.iter().enumerate() {
                        let (xx, yy) = (x + i as i64 - c, y + j as i64 - c);
                        if xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64 {
                            acc += ki * kj * img[(yy * w as i64 + xx) as usize];
                        }
                    }
                }
                out[(y * w as i64 + x) as usize] = acc;
            }
        }
        out
    }

    fn symmetric_kernel() -> impl Strategy<Value = Vec<u32>> {
        proptest::collection::vec(0u32..40, 0..4).prop_flat_map(|side| {
            (1u32..100).prop_map(move |centre| {
                let mut k: Vec<u32> = side.iter().rev().copied().collect();
                k.push(centre);
                k.extend(side.iter().copied());
                k
            })
        })
    }

    proptest! {
        #[test]
        fn separable_equals_direct(k1 in symmetric_kernel(), w in 1usize..12, h in 1usize..12, seed in any::<u64>()) {
            let img: Vec<u32> = (0..w * h).map(|i| ((seed >> (i % 60)) & 7) as u32).collect();
            prop_assert_eq!(SpatialFilter::new(k1.clone()).apply(&img, w, h), direct(&k1, &img, w, h));
        }

        /// Paper Eq. 8: the rolling sum of filtered bit-planes equals the filter
        /// of the rolling counts, exactly.
        #[test]
        fn eq8_rolling_sum_of_filtered_planes_equals_filtered_rolling_count(
            k1 in symmetric_kernel(), n in 1usize..9, w in 1usize..10, h in 1usize..10, planes in 1usize..25, seed in any::<u64>()
        ) {
            let mut s = seed | 1;
            let mut rnd = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let stream: Vec<BitPlane> = (0..planes).map(|_| BitPlane::from_fn(w, h, |_, _| rnd() % 4 == 0)).collect();
            let f = SpatialFilter::new(k1.clone());
            let mut dl = DelayLine::new(n, w, h);
            let mut rc = RollingCount::new(w, h);
            let filtered: Vec<Vec<u32>> = stream.iter().map(|p| {
                let b: Vec<u32> = p.bits().iter().by_vals().map(u32::from).collect();
                direct(&k1, &b, w, h)
            }).collect();
            for (t, p) in stream.iter().enumerate() {
                let old = dl.push(p.clone());
                rc.update(p, &old);
                let h_t = f.apply(rc.counts(), w, h);
                let mut eq8 = vec![0u32; w * h];
                for fu in &filtered[t.saturating_sub(n - 1)..=t] {
                    for (a, b) in eq8.iter_mut().zip(fu) { *a += b; }
                }
                prop_assert_eq!(h_t, eq8);
            }
        }
    }
}
