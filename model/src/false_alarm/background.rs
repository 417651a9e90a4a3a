//! The background-only H process at one pixel over time ([`BackgroundProcess`]):
//! the pair terms of two windows sharing planes, the false-blink bound and
//! the confirmation length `L_min` it asks for.

use super::lattice::{background_classes, Prepared};
use super::tail::class_tail;
use super::{
    check_p, check_window, invalid, pixel_classes, FalseAlarmError, FalseBlinkBound, Neighbourhood,
    TailProbability, FIRST_SEGMENT_GRID, TERM_FLOOR,
};
use crate::kernel::IntegerKernel;
use crate::stats::Detection;
use std::sync::OnceLock;

/// The background-only H process at one pixel: caches P, P(E) and the
/// first-segment table of the false-blink bound.
#[derive(Debug)]
pub struct BackgroundProcess {
    pixels: Vec<(u64, u64)>,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
    single: TailProbability,
    pairs_exact: bool,
    /// `(P(E), P(U))`.
    lag_one: OnceLock<(f64, f64)>,
    /// `(r, f̂(r))` on the grid, ascending r, running minimum.
    first_table: OnceLock<Vec<(u32, f64)>>,
}

impl BackgroundProcess {
    /// Sets up the process; computes `P = P(H ≥ T_int)`.
    pub fn new(
        kernel: &IntegerKernel,
        n_window: u32,
        p_off: f64,
        threshold_int: u64,
    ) -> Result<Self, FalseAlarmError> {
        check_window(n_window)?;
        check_p("p_off", p_off)?;
        let pixels = pixel_classes(kernel)?;
        let classes = background_classes(&pixels, n_window as u64, p_off);
        let single = class_tail(&classes, threshold_int);
        let pairs_exact = Prepared::new(&classes, threshold_int).exact_feasible();
        Ok(BackgroundProcess {
            pixels,
            n_window,
            p_off,
            threshold_int,
            single,
            pairs_exact,
            lag_one: OnceLock::new(),
            first_table: OnceLock::new(),
        })
    }

    /// The process of a derived [`Detection`].
    pub fn from_detection(det: &Detection) -> Result<Self, FalseAlarmError> {
        Self::new(&det.kernel(), det.n_window, det.p_off, det.threshold_int)
    }

    /// `P(H ≥ T_int)` per pixel-plane.
    pub fn single(&self) -> TailProbability {
        self.single
    }

    /// `(P(X ≥ x), P(X < x))` for x in `0..=T`, X the sum over `planes`
    /// background planes (exact lattice; suffix and prefix sums, so neither
    /// is a `1 − y`).
    fn sf_cdf(&self, planes: u64, cutoff: f64) -> (Vec<f64>, Vec<f64>) {
        let t = self.threshold_int as usize;
        let l = Prepared::new(
            &background_classes(&self.pixels, planes, self.p_off),
            t as u64,
        )
        .run(cutoff);
        let mut sf = vec![0.0; t + 1];
        sf[t] = l.tail;
        for x in (0..t).rev() {
            sf[x] = sf[x + 1] + l.below[x];
        }
        let mut cdf = vec![0.0; t + 1];
        for x in 0..t {
            cdf[x + 1] = cdf[x] + l.below[x];
        }
        (sf, cdf)
    }

    /// Two windows sharing `shared` planes, with `a` and `d` private planes:
    /// `X = A + C`, `Y = C + D`. For each `g`, returns
    /// `Σ_{c<T} P(C=c)·g(P(A ≥ T−c), P(A < T−c), P(D ≥ T−c), P(D < T−c))
    ///  + P(C ≥ T)·g(1, 0, 1, 0)`; `g` encodes the event on (X, Y).
    fn joint(
        &self,
        shared: u64,
        a: u64,
        d: u64,
        gs: &[&dyn Fn(f64, f64, f64, f64) -> f64],
    ) -> Vec<f64> {
        let t = self.threshold_int as usize;
        if t == 0 {
            return gs.iter().map(|g| g(1.0, 0.0, 1.0, 0.0)).collect();
        }
        // Every event used here has probability ≥ P² (increasing events of
        // independent pixels are positively associated) or is compared with
        // such, so skipping 1e-13·P² of mass per class side keeps ~1e-11
        // relative accuracy while sparing most of the far terms.
        let p = self.single.p;
        let cutoff = (1e-13 * p * p).clamp(TERM_FLOOR, 1e-16);
        let c = Prepared::new(
            &background_classes(&self.pixels, shared, self.p_off),
            t as u64,
        )
        .run(cutoff);
        let (sf_a, cdf_a) = self.sf_cdf(a, cutoff);
        let (sf_d, cdf_d) = if d == a {
            (sf_a.clone(), cdf_a.clone())
        } else {
            self.sf_cdf(d, cutoff)
        };
        gs.iter()
            .map(|g| {
                let mut sum = c.tail * g(1.0, 0.0, 1.0, 0.0);
                for (cv, &m) in c.below.iter().enumerate() {
                    if m != 0.0 {
                        let x = t - cv;
                        sum += m * g(sf_a[x], cdf_a[x], sf_d[x], cdf_d[x]);
                    }
                }
                sum.min(1.0)
            })
            .collect()
    }

    /// `P2(r) = P(H_t ≥ T, H_{t+r} ≥ T)`: exact when the lattice is within
    /// budget, else `None`.
    pub fn pair(&self, r: u32) -> Option<f64> {
        let p = self.single.p;
        if r == 0 {
            return Some(p);
        }
        if r >= self.n_window {
            return Some(p * p);
        }
        if !self.pairs_exact {
            return None;
        }
        let n = self.n_window as u64;
        Some(self.joint(n - r as u64, r as u64, r as u64, &[&|sa, _, sd, _| sa * sd])[0])
    }

    /// `(P(E), P(U))` with `E = {H_t ≥ T or H_{t+1} ≥ T}` and the up-crossing
    /// `U = {H_{t−1} < T ≤ H_t}`; over budget, the bounds `2P` and `P`.
    fn lag_one(&self) -> (f64, f64) {
        *self.lag_one.get_or_init(|| {
            let p = self.single.p;
            if self.n_window == 1 {
                // Windows of one plane at consecutive planes are independent.
                return (1.0 - (1.0 - p) * (1.0 - p), (1.0 - p) * p);
            }
            if !self.pairs_exact {
                return ((2.0 * p).min(1.0), p);
            }
            // H_t = A + C, H_{t+1} = C + D: E ⇔ not both below, i.e.
            // 1 − P(A < x)·P(D < x) = sf_a + cdf_a·sf_d; U (the same law one
            // plane earlier) ⇔ A < x ≤ D: cdf_a·sf_d.
            let n = self.n_window as u64;
            let v = self.joint(
                n - 1,
                1,
                1,
                &[&|sa, ca, sd, _| sa + ca * sd, &|_, ca, sd, _| ca * sd],
            );
            (v[0], v[1])
        })
    }

    /// `P(E) = P(H_t ≥ T or H_{t+1} ≥ T)` (exact, or the bound 2P over budget).
    pub fn either(&self) -> f64 {
        self.lag_one().0
    }

    /// `P(U) = P(H_{t−1} < T ≤ H_t)`, the up-crossing probability per
    /// pixel-plane: an excursion can only start at an up-crossing (exact, or
    /// the bound P over budget).
    pub fn upcrossing(&self) -> f64 {
        self.lag_one().1
    }

    /// `P(H_t ≥ T, W ≥ T)` with W the sum over the N+1 planes
    /// `t+r−N+1 ..= t+r+1`, for `0 < r < N`: since weights are non-negative,
    /// `H_{t+r}, H_{t+r+1} ≤ W`, so `E(t+r) ⊂ {W ≥ T}`. Shared planes `N − r`,
    /// private r (H_t) and r + 1 (W). `None` over budget or outside `0 < r < N`.
    pub fn pair_with_wide_window(&self, r: u32) -> Option<f64> {
        if !self.pairs_exact || r == 0 || r >= self.n_window {
            return None;
        }
        let n = self.n_window as u64;
        let r = r as u64;
        Some(self.joint(n - r, r, r + 1, &[&|sa, _, sd, _| sa * sd])[0])
    }

    fn first_table(&self) -> &[(u32, f64)] {
        self.first_table.get_or_init(|| {
            let n = self.n_window;
            let p = self.single.p;
            let g = FIRST_SEGMENT_GRID.min(n);
            let mut rs: Vec<u32> = (0..=g)
                .map(|i| ((i as u64 * n as u64 + g as u64 / 2) / g as u64) as u32)
                .collect();
            rs.dedup();
            let u = self.upcrossing().min(p);
            let mut table = Vec::with_capacity(rs.len());
            let mut best = f64::INFINITY;
            for r in rs {
                let f = if r == 0 {
                    u
                } else if r >= n {
                    u * self.either()
                } else {
                    self.pair_with_wide_window(r).map_or(u, |v| v.min(u))
                };
                best = best.min(f);
                table.push((r, best));
            }
            table
        })
    }

    /// The false-blink bound for on-length ≥ `min_length` (module docs).
    pub fn false_blink_bound(
        &self,
        min_length: u32,
        neighbourhood: Neighbourhood,
    ) -> Result<FalseBlinkBound, FalseAlarmError> {
        if min_length == 0 {
            return Err(invalid("min_length", 0.0, "must be at least 1 plane"));
        }
        let n1 = self.n_window as u64 + 1;
        let blocks = ((min_length as u64 - 1) / n1) as u32;
        let remainder = ((min_length as u64 - 1) % n1) as u32;
        let p = self.single.p;
        let base = FalseBlinkBound {
            min_length,
            neighbourhood,
            per_pixel_plane: p,
            blocks,
            remainder,
            single: p,
            either: p,
            upcrossing: p,
            first_segment: p,
            pair_terms_exact: self.pairs_exact,
            method: self.single.method,
        };
        if p == 0.0 {
            return Ok(FalseBlinkBound {
                per_pixel_plane: 0.0,
                either: 0.0,
                upcrossing: 0.0,
                first_segment: 0.0,
                ..base
            });
        }
        match neighbourhood {
            Neighbourhood::Pixel => {
                let e = self.either();
                let u = self.upcrossing().min(p);
                // L = 1 needs only f̂(0) = P(U); spare the grid.
                let (f_r, f_n) = if min_length == 1 {
                    (u, u)
                } else {
                    let table = self.first_table();
                    let f_r = table
                        .iter()
                        .rev()
                        .find(|(r, _)| *r <= remainder)
                        .map_or(u, |x| x.1);
                    (f_r, table.last().map_or(u, |x| x.1))
                };
                let mut bound = e.powf(blocks as f64) * f_r;
                if blocks >= 1 {
                    bound = bound.min(e.powf(blocks as f64 - 1.0) * f_n);
                }
                Ok(FalseBlinkBound {
                    per_pixel_plane: bound,
                    either: e,
                    upcrossing: u,
                    first_segment: f_r,
                    ..base
                })
            }
            Neighbourhood::Max3x3 => {
                let e = if min_length == 1 {
                    p
                } else {
                    (9.0 * self.either()).min(1.0)
                };
                Ok(FalseBlinkBound {
                    per_pixel_plane: p * if blocks == 0 {
                        1.0
                    } else {
                        e.powf(blocks as f64)
                    },
                    either: e,
                    first_segment: p,
                    ..base
                })
            }
        }
    }

    /// The smallest L whose bounded false-blink rate over `field_pixels`
    /// pixels at `plane_rate_hz` planes/s is ≤ `target_per_s`.
    pub fn l_min_for_target(
        &self,
        neighbourhood: Neighbourhood,
        field_pixels: u64,
        plane_rate_hz: f64,
        target_per_s: f64,
    ) -> Result<u32, FalseAlarmError> {
        if field_pixels == 0 {
            return Err(invalid("field_pixels", 0.0, "must be at least 1"));
        }
        if !plane_rate_hz.is_finite() || plane_rate_hz <= 0.0 {
            return Err(invalid(
                "plane_rate_hz",
                plane_rate_hz,
                "must be finite and > 0",
            ));
        }
        if !target_per_s.is_finite() || target_per_s <= 0.0 {
            return Err(invalid(
                "target_false_blinks_per_s",
                target_per_s,
                "must be finite and > 0",
            ));
        }
        let scale = field_pixels as f64 * plane_rate_hz;
        let ok = |b: f64| b * scale <= target_per_s;
        let p = self.single.p;
        if ok(self.false_blink_bound(1, neighbourhood)?.per_pixel_plane) {
            return Ok(1);
        }
        let n1 = self.n_window as u64 + 1;
        let e = match neighbourhood {
            Neighbourhood::Pixel => self.either(),
            Neighbourhood::Max3x3 => (9.0 * self.either()).min(1.0),
        };
        // End-of-block value: f̂(N)·e^m (Pixel) or P·e^(m+1) (Max3x3).
        let end = match neighbourhood {
            Neighbourhood::Pixel => self.first_table().last().map(|x| x.1).unwrap_or(p),
            Neighbourhood::Max3x3 => p * e,
        };
        if e >= 1.0 && !ok(end) {
            return Err(FalseAlarmError::TargetUnreachable {
                target_per_s,
                why: format!("background alone keeps H above T_int too often (P(E) = {e})"),
            });
        }
        // Smallest block m whose end reaches the target.
        let mut m: u64 = if ok(end) {
            0
        } else {
            ((target_per_s / (end * scale)).ln() / e.ln())
                .ceil()
                .max(0.0) as u64
        };
        while m > 0 && ok(end * e.powf(m as f64 - 1.0)) {
            m -= 1;
        }
        while !ok(end * e.powf(m as f64)) {
            m += 1;
        }
        let length = match neighbourhood {
            Neighbourhood::Max3x3 => 1 + (m + 1) * n1,
            Neighbourhood::Pixel => {
                let table = self.first_table();
                let r = table
                    .iter()
                    .find(|(_, f)| ok(f * e.powf(m as f64)))
                    .map(|x| x.0)
                    .unwrap_or(self.n_window);
                1 + m * n1 + r as u64
            }
        };
        u32::try_from(length).map_err(|_| FalseAlarmError::TargetUnreachable {
            target_per_s,
            why: format!("it needs {length} planes, beyond u32"),
        })
    }
}

/// Upper bound on background-only excursions of on-length ≥ `min_length`
/// per pixel-plane (see the [module docs](super) for the derivation).
pub fn false_blink_rate(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
    min_length: u32,
    neighbourhood: Neighbourhood,
) -> Result<FalseBlinkBound, FalseAlarmError> {
    BackgroundProcess::new(kernel, n_window, p_off, threshold_int)?
        .false_blink_bound(min_length, neighbourhood)
}

/// The smallest confirmation length `L_min` whose bounded single-pixel
/// ([`Neighbourhood::Pixel`]) false-blink rate over `field_pixels` pixels at
/// `plane_rate_hz` is ≤ `target_false_blinks_per_s`
/// ([`BackgroundProcess::l_min_for_target`] offers the 3×3 rule too).
/// `L_min = 1` is the paper's scheme (every crossing is a blink), right for
/// one molecule in a small field.
pub fn l_min_for_target(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
    field_pixels: u64,
    plane_rate_hz: f64,
    target_false_blinks_per_s: f64,
) -> Result<u32, FalseAlarmError> {
    BackgroundProcess::new(kernel, n_window, p_off, threshold_int)?.l_min_for_target(
        Neighbourhood::Pixel,
        field_pixels,
        plane_rate_hz,
        target_false_blinks_per_s,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bound_is_non_increasing_in_length() {
        let k = IntegerKernel::gaussian(1.2, 5, 6).unwrap();
        let bp = BackgroundProcess::new(&k, 12, 0.02, 700).unwrap();
        for nb in [Neighbourhood::Pixel, Neighbourhood::Max3x3] {
            let mut last = 1.0;
            for l in 1..60 {
                let b = bp.false_blink_bound(l, nb).unwrap().per_pixel_plane;
                assert!(b <= last && b >= 0.0, "{nb:?} L {l}: {b} > {last}");
                last = b;
            }
        }
        // l_min agrees with the bound it is defined from.
        let (pixels, rate) = (10_000u64, 1e4);
        for target in [1e3, 1.0, 1e-3] {
            let l = bp
                .l_min_for_target(Neighbourhood::Pixel, pixels, rate, target)
                .unwrap();
            let at = bp
                .false_blink_bound(l, Neighbourhood::Pixel)
                .unwrap()
                .per_pixel_plane;
            assert!(at * pixels as f64 * rate <= target, "L {l}");
            if l > 1 {
                let before = bp
                    .false_blink_bound(l - 1, Neighbourhood::Pixel)
                    .unwrap()
                    .per_pixel_plane;
                assert!(before * pixels as f64 * rate > target, "L {l} not minimal");
            }
        }
    }
}
