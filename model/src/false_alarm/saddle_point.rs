//! The Lugannani–Rice saddle-point approximation of the tail, the fallback
//! when the exact lattice is over budget.

use super::lattice::Class;
use crate::stats::normal_sf;

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Per class: `(log MGF, tilted mean q, q(1−q))` at s, without overflow.
fn tilted(w: f64, p: f64, s: f64) -> (f64, f64, f64) {
    let sw = s * w;
    if p >= 1.0 {
        return (sw, 1.0, 0.0);
    }
    if sw > 0.0 {
        let e = (-sw).exp();
        let d = p + (1.0 - p) * e;
        let q = p / d;
        let one_minus_q = (1.0 - p) * e / d;
        (sw + d.ln(), q, q * one_minus_q)
    } else {
        let e = sw.exp();
        let d = 1.0 + p * sw.exp_m1();
        let q = p * e / d;
        let one_minus_q = (1.0 - p) / d;
        (d.ln(), q, q * one_minus_q)
    }
}

/// Lugannani–Rice with the second continuity correction (module docs).
pub(super) fn saddle_point_tail(classes: &[Class], x: u64) -> f64 {
    let cls: Vec<Class> = classes
        .iter()
        .copied()
        .filter(|c| c.weight > 0 && c.trials > 0 && c.p > 0.0)
        .collect();
    let hmin: f64 = cls
        .iter()
        .filter(|c| c.p >= 1.0)
        .map(|c| c.weight as f64 * c.trials as f64)
        .sum();
    let hmax: f64 = cls.iter().map(|c| c.weight as f64 * c.trials as f64).sum();
    let xf = x as f64;
    if xf <= hmin {
        return 1.0;
    }
    if xf > hmax {
        return 0.0;
    }
    if xf == hmax {
        return cls
            .iter()
            .map(|c| c.trials as f64 * c.p.ln())
            .sum::<f64>()
            .exp();
    }
    let delta = cls
        .iter()
        .filter(|c| c.p < 1.0)
        .fold(0u64, |g, c| gcd(g, c.weight))
        .max(1) as f64;
    let xt = xf - delta / 2.0;
    if xt <= hmin {
        return 1.0;
    }
    let cgf = |s: f64| {
        let (mut k0, mut k1, mut k2) = (0.0, 0.0, 0.0);
        for c in &cls {
            let (w, n) = (c.weight as f64, c.trials as f64);
            let (l, q, v) = tilted(w, c.p, s);
            k0 += n * l;
            k1 += n * w * q;
            k2 += n * w * w * v;
        }
        (k0, k1, k2)
    };
    let wmax = cls.iter().map(|c| c.weight).max().unwrap_or(1) as f64;
    let (_, mean, _) = cgf(0.0);
    let (mut lo, mut hi) = if mean < xt {
        let mut hi = 1.0 / wmax;
        while cgf(hi).1 < xt && hi < 1e6 {
            hi *= 2.0;
        }
        (0.0, hi)
    } else {
        let mut lo = -1.0 / wmax;
        while cgf(lo).1 > xt && lo > -1e6 {
            lo *= 2.0;
        }
        (lo, 0.0)
    };
    let mut s = 0.5 * (lo + hi);
    for _ in 0..200 {
        let (_, k1, k2) = cgf(s);
        if k1 < xt {
            lo = s;
        } else {
            hi = s;
        }
        let newton = if k2 > 0.0 {
            s - (k1 - xt) / k2
        } else {
            f64::NAN
        };
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - s).abs() <= 1e-15 * s.abs().max(1e-300) {
            s = next;
            break;
        }
        s = next;
    }
    let (k0, _, k2) = cgf(s);
    if k2.is_nan() || k2 <= 0.0 {
        return if xt > mean { 0.0 } else { 1.0 };
    }
    let r = s.signum() * (2.0 * (s * xt - k0).max(0.0)).sqrt();
    if r.abs() < 1e-6 {
        // Centre of the distribution: the limit 1/2 − κ3/(6√(2π)κ2^{3/2}).
        let k3: f64 = cls
            .iter()
            .map(|c| {
                let (w, n) = (c.weight as f64, c.trials as f64);
                n * w * w * w * c.p * (1.0 - c.p) * (1.0 - 2.0 * c.p)
            })
            .sum();
        let v = 0.5 - k3 / (6.0 * (2.0 * std::f64::consts::PI).sqrt() * k2.powf(1.5));
        return v.clamp(0.0, 1.0);
    }
    let u = 2.0 / delta * (s * delta / 2.0).sinh() * k2.sqrt();
    let phi = (-0.5 * r * r).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let p = normal_sf(r) + phi * (1.0 / u - 1.0 / r);
    if p.is_finite() {
        p.clamp(0.0, 1.0)
    } else {
        normal_sf(r)
    }
}
