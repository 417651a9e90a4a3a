//! Small sampling helpers shared by the cameras and the timeline.

use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Gamma, Poisson};

/// Random stream of the camera maps.
pub(crate) const STREAM_MAPS: u64 = 0;
/// Random stream of the emitter layout.
pub(crate) const STREAM_LAYOUT: u64 = 1;
/// Random stream of the blinking.
pub(crate) const STREAM_BLINKING: u64 = 2;
/// Random stream of photons and noise.
pub(crate) const STREAM_PHOTONS: u64 = 3;
/// Random stream of the stage drift (a random trajectory only).
pub(crate) const STREAM_DRIFT: u64 = 4;

/// The ChaCha8 stream `stream` of `seed`.
pub(crate) fn rng_stream(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream);
    r
}

/// A Poisson variate of mean `mean` (0 for a mean of 0 or less).
///
/// Small means (the usual case: a molecule gives well under one photon per
/// bit-plane) use sequential inversion of the CDF — one exponential and one
/// uniform — instead of building a `rand_distr::Poisson` (two logarithms and
/// a log-gamma) on every call; larger means use `rand_distr`.
#[inline]
pub(crate) fn poisson<R: Rng + ?Sized>(rng: &mut R, mean: f64) -> u64 {
    if !(mean > 0.0 && mean.is_finite()) {
        return 0;
    }
    if mean < 10.0 {
        let u = rng.gen::<f64>();
        let mut p = (-mean).exp();
        let mut cdf = p;
        let mut k = 0u64;
        // p > 0 until far beyond any u < 1 can reach for mean < 10.
        while u >= cdf && p > 0.0 {
            k += 1;
            p *= mean / k as f64;
            cdf += p;
        }
        return k;
    }
    // `Poisson::new` only fails for a non-positive or non-finite mean.
    Poisson::new(mean)
        .expect("positive finite mean")
        .sample(rng) as u64
}

/// A uniform variate in (0, 1] (never 0, so its logarithm is finite).
#[inline]
pub(crate) fn uniform_open0<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    1.0 - rng.gen::<f64>()
}

/// An exponential variate of mean `mean` (0 when `mean` is 0).
#[inline]
pub(crate) fn exponential<R: Rng + ?Sized>(rng: &mut R, mean: f64) -> f64 {
    -mean * uniform_open0(rng).ln()
}

/// A factor of mean 1 and relative spread `cv`: Gamma(1/cv², cv²), exactly 1
/// for `cv = 0`. Gamma keeps it positive and right-skewed like blink
/// intensities.
///
/// Below `cv = 1e-6` the shape would be over 10¹² (infinite for a
/// subnormal cv): the normal limit `1 + cv·Z` is used, which differs from
/// the Gamma by far less than f64 resolves.
pub(crate) fn unit_gamma<R: Rng + ?Sized>(rng: &mut R, cv: f64) -> f64 {
    if cv.is_nan() || cv <= 0.0 {
        return 1.0;
    }
    if cv < 1e-6 {
        return (1.0 + cv * std_normal(rng)).max(0.0);
    }
    let shape = 1.0 / (cv * cv);
    // Valid for any positive finite cv.
    Gamma::new(shape, cv * cv)
        .expect("positive shape and scale")
        .sample(rng)
}

/// σ of ln X for a log-normal X whose std/median equals `rel_spread`:
/// with v = e^{σ²}, std/median = √(v(v−1)), so v = (1 + √(1 + 4d²))/2.
pub(crate) fn lognormal_sigma_for_spread(rel_spread: f64) -> f64 {
    if rel_spread <= 0.0 {
        return 0.0;
    }
    let v = 0.5 * (1.0 + (1.0 + 4.0 * rel_spread * rel_spread).sqrt());
    v.ln().sqrt()
}

/// A standard normal variate (rand_distr's ziggurat).
#[inline]
pub(crate) fn std_normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    rng.sample(rand_distr::StandardNormal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lognormal_sigma_gives_the_spread() {
        for d in [0.01, 0.02, 0.5, 3.0] {
            let s = lognormal_sigma_for_spread(d);
            let v = (s * s).exp();
            assert!(((v * (v - 1.0)).sqrt() - d).abs() < 1e-12 * d.max(1.0));
        }
        assert_eq!(lognormal_sigma_for_spread(0.0), 0.0);
    }

    #[test]
    fn small_mean_poisson_has_the_right_pmf() {
        let mut r = rng_stream(2, 0);
        for mean in [0.03, 0.7, 4.0, 9.9] {
            let n = 200_000;
            let mut hist = [0u64; 40];
            for _ in 0..n {
                hist[poisson(&mut r, mean).min(39) as usize] += 1;
            }
            let mut pk = (-mean).exp();
            for (k, &h) in hist.iter().enumerate().take(25) {
                if k > 0 {
                    pk *= mean / k as f64;
                }
                let e = n as f64 * pk;
                if e > 20.0 {
                    let z = (h as f64 - e) / e.sqrt();
                    assert!(z.abs() < 5.0, "mean {mean}, k {k}: {h} vs {e}");
                }
            }
        }
    }

    #[test]
    fn unit_gamma_of_a_vanishing_spread_is_one() {
        let mut r = rng_stream(3, 0);
        for cv in [1e-320, f64::MIN_POSITIVE, 1e-200, 1e-7, 0.0, -1.0, f64::NAN] {
            let v = unit_gamma(&mut r, cv);
            assert!(v.is_finite() && (v - 1.0).abs() < 1e-5, "cv {cv}: {v}");
        }
        let v = unit_gamma(&mut r, 0.5);
        assert!(v.is_finite() && v >= 0.0);
    }

    #[test]
    fn poisson_of_zero_and_huge_means() {
        let mut r = rng_stream(1, 0);
        assert_eq!(poisson(&mut r, 0.0), 0);
        assert_eq!(poisson(&mut r, -1.0), 0);
        let k = poisson(&mut r, 1e12);
        assert!((k as f64 - 1e12).abs() < 1e7);
    }
}
