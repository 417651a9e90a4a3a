//! Per-pixel estimators: pile-up-corrected rates of Bernoulli pixels, the
//! planes a requested precision needs, and robust summaries of a map.

/// `ln 20`: with no count in n planes, `p ≤ 1 − 0.05^{1/n}` at 95 %
/// confidence (exact Clopper–Pearson), i.e. `rate ≤ ln 20 / (n·τ)`.
pub const LN_20: f64 = 2.995_732_273_553_991;

/// How a rate estimate relates to the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RateKind {
    /// `0 < k < n`: the maximum-likelihood estimate with its delta-method sd.
    Estimate,
    /// `k = 0`: the estimate is 0; the 95 % upper bound is `ln 20 / (n·τ)`.
    NoCounts {
        /// 95 % upper bound of the rate, Hz.
        upper_95_hz: f64,
    },
    /// `k = n`: no finite MLE; the stored value is a finite lower estimate
    /// (the rate of `k = n − ½`).
    Saturated,
}

/// A pile-up-corrected rate from `k` ones in `n` planes of exposure τ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateEstimate {
    /// Rate, Hz (finite).
    pub rate_hz: f64,
    /// Its standard uncertainty, Hz (finite, > 0).
    pub sd_hz: f64,
    /// What kind of estimate this is.
    pub kind: RateKind,
}

/// `−ln(1 − k/n)` computed without cancellation at either end: `ln_1p` for
/// small `k/n`, the exact `(n − k)/n` near 1.
fn neg_ln_one_minus(k: f64, n: f64) -> f64 {
    let p = k / n;
    if p < 0.5 {
        -(-p).ln_1p()
    } else {
        -((n - k) / n).ln()
    }
}

/// The rate of a pixel that read 1 in `k` of `n` bit-planes of exposure `tau_s`.
///
/// Each plane reads 1 with `p = 1 − e^{−rate·τ}` (pile-up: any number of
/// events gives one 1), so the MLE is `rate = −ln(1 − k/n)/τ`, and by the
/// delta method (`Var p̂ = p(1−p)/n`, `d rate/dp = 1/((1−p)τ)`) its sd is
/// `√(p / (n(1 − p)))/τ = √(k / (n(n − k)))/τ`.
///
/// At the ends, where the MLE is 0 or infinite, the values stay finite:
/// * `k = 0`: rate 0, sd from `k = ½` (the resolution of the measurement),
///   and the exact 95 % upper bound `ln 20/(nτ)`;
/// * `k = n`: the rate and sd of `k = n − ½`, i.e. `ln(2n)/τ`, a lower
///   estimate (the truth is likely higher).
///
/// `n` must be at least 1 and `k ≤ n`; `tau_s > 0`.
pub fn rate_from_counts(k: u64, n: u64, tau_s: f64) -> RateEstimate {
    debug_assert!(n >= 1 && k <= n && tau_s > 0.0);
    let nf = n.max(1) as f64;
    let kf = (k.min(n)) as f64;
    let sd = |k: f64| (k / (nf * (nf - k))).sqrt() / tau_s;
    if k == 0 {
        RateEstimate {
            rate_hz: 0.0,
            sd_hz: sd(0.5),
            kind: RateKind::NoCounts {
                upper_95_hz: LN_20 / (nf * tau_s),
            },
        }
    } else if k >= n {
        let ks = nf - 0.5;
        RateEstimate {
            rate_hz: neg_ln_one_minus(ks, nf) / tau_s,
            sd_hz: sd(ks),
            kind: RateKind::Saturated,
        }
    } else {
        RateEstimate {
            rate_hz: neg_ln_one_minus(kf, nf) / tau_s,
            sd_hz: sd(kf),
            kind: RateKind::Estimate,
        }
    }
}

/// `1 − e^{−rate·τ}`: the probability that a plane reads 1.
pub fn plane_probability(rate_hz: f64, tau_s: f64) -> f64 {
    -(-rate_hz * tau_s).exp_m1()
}

/// The rate whose plane probability is `p` (inverse of [`plane_probability`]).
pub fn rate_of_probability(p: f64, tau_s: f64) -> f64 {
    -(-p).ln_1p() / tau_s
}

/// Planes needed for a relative rate uncertainty `rel` at plane probability
/// `p` (0 < p < 1): solving `√(p/(n(1−p)))/(−ln(1−p)) = rel` for n gives
/// `n = p / ((1 − p)·(rel·ln(1/(1−p)))²)`, about `1/(p·rel²)` for small p.
pub fn planes_for_precision(p: f64, rel: f64) -> f64 {
    let l = -(-p).ln_1p();
    p / ((1.0 - p) * (rel * l) * (rel * l))
}

/// The relative uncertainty of a rate at plane probability `p` after `n` planes.
pub fn relative_precision(p: f64, n: f64) -> f64 {
    (p / (n * (1.0 - p))).sqrt() / -(-p).ln_1p()
}

/// Median of the values (mean of the middle two for an even count); `None` if empty.
pub fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Mean and sample standard deviation (n − 1); sd 0 for fewer than 2 values.
pub fn mean_sd(values: &[f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let m = values.iter().sum::<f64>() / n;
    if values.len() < 2 {
        return Some((m, 0.0));
    }
    let var = values.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    Some((m, var.sqrt()))
}

/// `1.4826 × MAD`: a standard deviation that ignores outliers (equal to
/// the sd for normally distributed values).
pub fn robust_sd(values: &[f64]) -> Option<f64> {
    let m = median(values)?;
    let dev: Vec<f64> = values.iter().map(|x| (x - m).abs()).collect();
    Some(1.482_602_218_505_602 * median(&dev)?)
}

/// A spread with the measurement noise removed: `√max(0, s² − noise²)`.
pub fn noise_corrected(spread: f64, noise: f64) -> f64 {
    (spread * spread - noise * noise).max(0.0).sqrt()
}

/// Running per-pixel mean and variance (Welford), numerically stable for
/// any number of frames.
#[derive(Debug, Clone)]
pub struct Welford {
    n: Vec<u64>,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl Welford {
    /// Accumulators for `pixels` pixels.
    pub fn new(pixels: usize) -> Welford {
        Welford {
            n: vec![0; pixels],
            mean: vec![0.0; pixels],
            m2: vec![0.0; pixels],
        }
    }

    /// Adds one value of pixel `i`.
    #[inline]
    pub fn push(&mut self, i: usize, x: f64) {
        self.n[i] += 1;
        let d = x - self.mean[i];
        self.mean[i] += d / self.n[i] as f64;
        self.m2[i] += d * (x - self.mean[i]);
    }

    /// Values seen at pixel `i`.
    pub fn count(&self, i: usize) -> u64 {
        self.n[i]
    }

    /// Mean at pixel `i` (0 with no value).
    pub fn mean(&self, i: usize) -> f64 {
        self.mean[i]
    }

    /// Sample variance (n − 1) at pixel `i` (0 with fewer than 2 values).
    pub fn variance(&self, i: usize) -> f64 {
        if self.n[i] < 2 {
            0.0
        } else {
            (self.m2[i] / (self.n[i] - 1) as f64).max(0.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interior_estimate_is_the_mle_with_delta_method_sd() {
        let tau = 1e-4;
        let e = rate_from_counts(100, 10_000, tau);
        assert_eq!(e.kind, RateKind::Estimate);
        let p: f64 = 0.01;
        assert!((e.rate_hz - (-(1.0 - p).ln() / tau)).abs() < 1e-9);
        let sd = (p / (10_000.0 * (1.0 - p))).sqrt() / tau;
        assert!((e.sd_hz - sd).abs() < 1e-9 * sd);
        // Near 1 the exact (n − k)/n form is used: no cancellation.
        let e = rate_from_counts(999_999_999, 1_000_000_000, 1.0);
        assert!((e.rate_hz - (1e9f64).ln()).abs() < 1e-9, "{}", e.rate_hz);
        // Tiny p: ln_1p keeps full precision.
        let e = rate_from_counts(1, 1u64 << 50, 1.0);
        assert!((e.rate_hz / 2f64.powi(-50) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn extremes_are_finite_and_labelled() {
        for n in [1u64, 2, 3, 10, 1 << 40] {
            let z = rate_from_counts(0, n, 1e-4);
            assert_eq!(z.rate_hz, 0.0);
            assert!(z.sd_hz.is_finite() && z.sd_hz > 0.0);
            match z.kind {
                RateKind::NoCounts { upper_95_hz } => {
                    // Exact: P(no count | rate = bound) = 5 %.
                    let p = plane_probability(upper_95_hz, 1e-4);
                    assert!(((n as f64 * (-p).ln_1p()).exp() - 0.05).abs() < 1e-9);
                }
                other => panic!("{other:?}"),
            }
            let s = rate_from_counts(n, n, 1e-4);
            assert_eq!(s.kind, RateKind::Saturated);
            assert!(s.rate_hz.is_finite() && s.sd_hz.is_finite() && s.sd_hz > 0.0);
            assert!((s.rate_hz - (2.0 * n as f64).ln() / 1e-4).abs() < 1e-6 * s.rate_hz);
            if n > 1 {
                // A lower estimate: above every non-saturated estimate.
                assert!(s.rate_hz > rate_from_counts(n - 1, n, 1e-4).rate_hz);
            }
        }
    }

    #[test]
    fn planes_for_precision_inverts_relative_precision() {
        for p in [1e-9, 1e-4, 0.01, 0.3, 0.9] {
            for rel in [0.01, 0.05, 0.2] {
                let n = planes_for_precision(p, rel);
                assert!((relative_precision(p, n) / rel - 1.0).abs() < 1e-9);
            }
        }
        // SPCImager: 100 Hz, 100 µs, 5 % → about 1/(p·rel²) = 40,000 planes.
        let n = planes_for_precision(plane_probability(100.0, 1e-4), 0.05);
        assert!((n - 40_000.0).abs() < 500.0, "{n}");
    }

    #[test]
    fn robust_summaries() {
        let mut v: Vec<f64> = (0..1001).map(|i| i as f64).collect();
        assert_eq!(median(&v), Some(500.0));
        v.push(1e12);
        let sd = robust_sd(&v).unwrap();
        assert!((sd / (250.5 * 1.4826) - 1.0).abs() < 0.01, "{sd}");
        assert_eq!(median(&[]), None);
        assert!((noise_corrected(0.05, 0.03) - 0.04).abs() < 1e-15);
        assert_eq!(noise_corrected(0.01, 0.03), 0.0);
        let mut w = Welford::new(1);
        for x in [1e9 + 1.0, 1e9 + 2.0, 1e9 + 3.0] {
            w.push(0, x);
        }
        assert!((w.mean(0) - (1e9 + 2.0)).abs() < 1e-6 && (w.variance(0) - 1.0).abs() < 1e-6);
    }
}
