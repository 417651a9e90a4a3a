//! Simulated ROIs and frames with known truth, for tests and benchmarks.
//!
//! Frame ROIs: expected image `μ = g (N · psf + b) + d` (pixel-integrated
//! Gaussian), then Poisson draws; EMCCD adds the gamma-distributed
//! electron-multiplication register (output divided by the gain, so the mean
//! stays in photons and the variance doubles); sCMOS adds Gaussian read
//! noise. SPAD ROIs: the count of a pixel is the sum over bit-planes of
//! Bernoulli detections with `p = 1 − e^{−λ}`, i.e. exactly
//! `Bin(n_on, p_on) + Bin(n_off, p_off)`, drawn as two binomials.

use crate::crlb::Emitter;
use crate::erf::erf;
use crate::psf::psf_image;
use crate::roi::PixelMaps;
use crate::spad::SpadEmitter;
use rand::Rng;
use rand_distr::{Binomial, Distribution, Gamma, Normal, Poisson};

/// Expected value of every pixel of a `side × side` ROI (row-major).
pub fn expected_roi(side: usize, em: &Emitter, maps: Option<&PixelMaps>) -> Vec<f64> {
    let psf = psf_image(side, em.x, em.y, em.sigma);
    psf.iter()
        .enumerate()
        .map(|(k, &p)| {
            let (g, d) = maps.map_or((1.0, 0.0), |m| (m.gain[k], m.dark[k]));
            g * (em.photons * p + em.background) + d
        })
        .collect()
}

/// Draws a Poisson variate of mean `mu` (0 for `mu ≤ 0`).
pub fn poisson<R: Rng + ?Sized>(rng: &mut R, mu: f64) -> f64 {
    if mu > 0.0 && mu.is_finite() {
        Poisson::new(mu).map_or(0.0, |d| d.sample(rng))
    } else {
        0.0
    }
}

/// A Poisson ROI (ideal photon counting).
pub fn poisson_roi<R: Rng + ?Sized>(
    rng: &mut R,
    side: usize,
    em: &Emitter,
    maps: Option<&PixelMaps>,
) -> Vec<f64> {
    expected_roi(side, em, maps)
        .into_iter()
        .map(|mu| poisson(rng, mu))
        .collect()
}

/// An EMCCD ROI in photon units: Poisson photo-electrons, multiplied by a
/// gamma-distributed EM register of mean gain `em_gain`, divided by it.
pub fn emccd_roi<R: Rng + ?Sized>(
    rng: &mut R,
    side: usize,
    em: &Emitter,
    em_gain: f64,
) -> Vec<f64> {
    expected_roi(side, em, None)
        .into_iter()
        .map(|mu| {
            let n = poisson(rng, mu);
            if n > 0.0 {
                Gamma::new(n, em_gain).map_or(0.0, |g| g.sample(rng)) / em_gain
            } else {
                0.0
            }
        })
        .collect()
}

/// An sCMOS ROI in photo-electrons: Poisson plus Gaussian read noise of the
/// per-pixel variance `maps.read_var`.
pub fn scmos_roi<R: Rng + ?Sized>(
    rng: &mut R,
    side: usize,
    em: &Emitter,
    maps: &PixelMaps,
) -> Vec<f64> {
    expected_roi(side, em, Some(maps))
        .into_iter()
        .enumerate()
        .map(|(k, mu)| {
            let sd = maps.read_var[k].sqrt();
            poisson(rng, mu) + Normal::new(0.0, sd).map_or(0.0, |n| n.sample(rng))
        })
        .collect()
}

/// Per-plane detection rates (λ_on, λ_off) of every pixel of a SPAD ROI;
/// `maps.dark` is per plane.
pub fn spad_rates(side: usize, em: &SpadEmitter, maps: Option<&PixelMaps>) -> Vec<(f64, f64)> {
    let psf = psf_image(side, em.x, em.y, em.sigma);
    psf.iter()
        .enumerate()
        .map(|(k, &p)| {
            let (g, d) = maps.map_or((1.0, 0.0), |m| (m.gain[k], m.dark[k]));
            let off = g * em.background_per_plane + d;
            (g * em.signal_per_plane * p + off, off)
        })
        .collect()
}

/// A SPAD ROI aggregated over `n_on` planes with the molecule on and
/// `n_off` background-only planes.
pub fn spad_roi<R: Rng + ?Sized>(
    rng: &mut R,
    side: usize,
    em: &SpadEmitter,
    n_on: u32,
    n_off: u32,
    maps: Option<&PixelMaps>,
) -> Vec<u32> {
    spad_rates(side, em, maps)
        .into_iter()
        .map(|(lon, loff)| {
            binomial(rng, n_on, -(-lon).exp_m1()) + binomial(rng, n_off, -(-loff).exp_m1())
        })
        .collect()
}

fn binomial<R: Rng + ?Sized>(rng: &mut R, n: u32, p: f64) -> u32 {
    if n == 0 || !(p > 0.0) {
        return 0;
    }
    Binomial::new(n as u64, p.min(1.0)).map_or(0, |b| b.sample(rng) as u32)
}

/// Expected image of a whole frame (`width × height`, photons) with emitters
/// at frame pixel coordinates `(x, y, photons)`, PSF σ and uniform background.
pub fn expected_frame(
    width: usize,
    height: usize,
    emitters: &[(f64, f64, f64)],
    sigma: f64,
    background: f64,
) -> Vec<f64> {
    let mut img = vec![background; width * height];
    let s2 = std::f64::consts::SQRT_2 * sigma;
    let axis = |n: usize, c: f64| -> Vec<f64> {
        (0..n)
            .map(|i| 0.5 * (erf((i as f64 + 1.0 - c) / s2) - erf((i as f64 - c) / s2)))
            .collect()
    };
    for &(x, y, n) in emitters {
        let (ex, ey) = (axis(width, x), axis(height, y));
        for j in 0..height {
            if ey[j] < 1e-12 {
                continue;
            }
            for i in 0..width {
                img[j * width + i] += n * ex[i] * ey[j];
            }
        }
    }
    img
}
