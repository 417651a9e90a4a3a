//! Binomial terms: `P(J = j)` for `J ~ Binomial(n, p)` by Loader's
//! saddle-point form and recurrences outward from the mode, with their
//! suffix sums.

use super::TERM_FLOOR;

/// `lgamma(n+1) − [(n+½)ln n − n + ½ln 2π]`, Stirling's error term.
fn stirlerr(n: f64) -> f64 {
    const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;
    if n <= 15.0 {
        let mut f = 1.0f64;
        let mut i = 2.0;
        while i <= n {
            f *= i;
            i += 1.0;
        }
        f.ln() - (n + 0.5) * n.ln() + n - HALF_LN_2PI
    } else {
        let nn = n * n;
        const S0: f64 = 1.0 / 12.0;
        const S1: f64 = 1.0 / 360.0;
        const S2: f64 = 1.0 / 1260.0;
        const S3: f64 = 1.0 / 1680.0;
        const S4: f64 = 1.0 / 1188.0;
        (S0 - (S1 - (S2 - (S3 - S4 / nn) / nn) / nn) / nn) / n
    }
}

/// `x ln(x/m) + m − x`, accurate also when x ≈ m (series in (x−m)/(x+m)).
fn bd0(x: f64, m: f64) -> f64 {
    if (x - m).abs() < 0.1 * (x + m) {
        let v = (x - m) / (x + m);
        let v2 = v * v;
        let mut s = (x - m) * v;
        let mut ej = 2.0 * x * v;
        let mut j = 1.0;
        loop {
            ej *= v2;
            let s1 = s + ej / (2.0 * j + 1.0);
            if s1 == s {
                return s1;
            }
            s = s1;
            j += 1.0;
        }
    } else {
        x * (x / m).ln() + m - x
    }
}

/// ln P(J = x), J ~ Binomial(n, p), 0 < p < 1 (Loader 2000).
fn ln_binomial_pmf(x: u64, n: u64, p: f64) -> f64 {
    let q = 1.0 - p;
    if x == 0 {
        return n as f64 * (-p).ln_1p();
    }
    if x == n {
        return n as f64 * p.ln();
    }
    let (xf, nf) = (x as f64, n as f64);
    let lc =
        stirlerr(nf) - stirlerr(xf) - stirlerr(nf - xf) - bd0(xf, nf * p) - bd0(nf - xf, nf * q);
    let lf = (2.0 * std::f64::consts::PI).ln() + xf.ln() + (-xf / nf).ln_1p();
    lc - 0.5 * lf
}

/// The binomial terms ≥ [`TERM_FLOOR`] (a contiguous range around the mode).
#[derive(Debug, Clone)]
pub(super) struct Terms {
    /// j of `pmf[0]`.
    pub(super) first: u64,
    pub(super) pmf: Vec<f64>,
    /// `suffix[i] = Σ_{l ≥ i} pmf[l]`, summed from the top.
    pub(super) suffix: Vec<f64>,
}

impl Terms {
    pub(super) fn new(n: u64, p: f64) -> Terms {
        let (first, pmf) = if n == 0 || p <= 0.0 {
            (0, vec![1.0])
        } else if p >= 1.0 {
            (n, vec![1.0])
        } else {
            let mode = (((n + 1) as f64 * p).floor() as u64).min(n);
            let top = ln_binomial_pmf(mode, n, p).exp();
            let odds = p / (1.0 - p);
            let mut up = Vec::new();
            let mut v = top;
            let mut j = mode;
            while j < n {
                v *= (n - j) as f64 / (j + 1) as f64 * odds;
                if v < TERM_FLOOR {
                    break;
                }
                up.push(v);
                j += 1;
            }
            let mut down = Vec::new();
            let mut v = top;
            let mut j = mode;
            while j > 0 {
                v *= j as f64 / (n - j + 1) as f64 / odds;
                if v < TERM_FLOOR {
                    break;
                }
                down.push(v);
                j -= 1;
            }
            let first = mode - down.len() as u64;
            let mut pmf: Vec<f64> = down.into_iter().rev().collect();
            pmf.push(top);
            pmf.extend(up);
            (first, pmf)
        };
        let mut suffix = vec![0.0; pmf.len()];
        let mut acc = 0.0;
        for i in (0..pmf.len()).rev() {
            acc += pmf[i];
            suffix[i] = acc;
        }
        Terms { first, pmf, suffix }
    }

    /// `P(J ≥ j)`.
    pub(super) fn sf(&self, j: u64) -> f64 {
        if j <= self.first {
            self.suffix[0]
        } else {
            let i = (j - self.first) as usize;
            self.suffix.get(i).copied().unwrap_or(0.0)
        }
    }

    /// Index range `[lo, hi]` keeping all but ≤ `cutoff` mass on each side.
    pub(super) fn significant(&self, cutoff: f64) -> (usize, usize) {
        let mut lo = 0;
        let mut below = 0.0;
        while lo + 1 < self.pmf.len() && below + self.pmf[lo] <= cutoff {
            below += self.pmf[lo];
            lo += 1;
        }
        let mut hi = self.pmf.len() - 1;
        while hi > lo && self.suffix[hi] <= cutoff {
            hi -= 1;
        }
        (lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn direct_pmf(j: u64, n: u64, p: f64) -> f64 {
        let mut c = 1.0f64;
        for i in 0..j {
            c = c * (n - i) as f64 / (i + 1) as f64;
        }
        c * p.powi(j as i32) * (1.0 - p).powi((n - j) as i32)
    }

    #[test]
    fn binomial_terms_match_direct_products() {
        for &(n, p) in &[(1u64, 0.3), (7, 0.5), (40, 0.01), (109, 0.0117), (300, 0.9)] {
            let t = Terms::new(n, p);
            let total: f64 = t.pmf.iter().sum();
            assert!((total - 1.0).abs() < 1e-13, "n {n} p {p}: {total}");
            for (i, &v) in t.pmf.iter().enumerate() {
                let j = t.first + i as u64;
                let d = direct_pmf(j, n, p);
                if d > 1e-250 {
                    assert!(((v - d) / d).abs() < 1e-11, "n {n} p {p} j {j}: {v} vs {d}");
                }
            }
            assert!((t.sf(0) - 1.0).abs() < 1e-13);
        }
        // Huge n: still normalised and centred (naive (1-p)^n underflows here).
        let t = Terms::new(80_000_000, 0.3);
        let total: f64 = t.pmf.iter().sum();
        assert!((total - 1.0).abs() < 1e-9, "{total}");
        assert!(t.first < 24_000_000 && t.first + (t.pmf.len() as u64) > 24_000_000);
        assert_eq!(Terms::new(10, 0.0).pmf, vec![1.0]);
        assert_eq!(Terms::new(10, 1.0).first, 10);
    }
}
