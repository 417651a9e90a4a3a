//! Test helpers: an independent event-level SPAD sampler and two-sample tests.
#![allow(dead_code)]

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Exp, Normal};
use smartagg_model::sensor_maps::SensorMaps;
use smartagg_scene::ExplicitBlink;

/// Everything the event-level sampler needs, in physical units.
pub struct EventScene<'a> {
    pub maps: &'a SensorMaps,
    /// Each pixel's detection efficiency η_i.
    pub eta: &'a [f64],
    /// Background photons per pixel per second reaching the sensor (before η).
    pub background_photons_hz: f64,
    pub blinks: &'a [ExplicitBlink],
    /// Molecule flux, photons/s (times each blink's factor).
    pub flux_hz: f64,
    pub sigma_nm: f64,
    pub pixel_nm: f64,
    pub period_s: f64,
    pub exposure_s: f64,
}

/// One bit-plane from photon arrival times: every background photon, dark
/// count and molecule photon is an event with a time inside the exposure;
/// molecule photons land at a continuous Gaussian position (no pixel
/// integration), every photon is detected with probability η of the pixel it
/// lands in, and a pixel reads 1 if it has at least one event. Shares no code
/// with the simulator.
pub fn event_plane(s: &EventScene, k: u64, rng: &mut ChaCha8Rng) -> Vec<bool> {
    let w = s.maps.width as usize;
    let h = s.maps.height as usize;
    let t0 = k as f64 * s.period_s;
    let t1 = t0 + s.exposure_s;
    let mut bits = vec![false; w * h];
    for (i, bit) in bits.iter_mut().enumerate() {
        // Background photons: a Poisson process in time, each thinned by η_i.
        if s.background_photons_hz > 0.0 {
            let gap = Exp::new(s.background_photons_hz).unwrap();
            let mut t = t0 + gap.sample(rng);
            while t < t1 {
                if rng.gen::<f64>() < s.eta[i] {
                    *bit = true;
                    break;
                }
                t += gap.sample(rng);
            }
        }
        // Dark counts: a Poisson process of rate DCR_i.
        if !*bit && s.maps.dcr_hz[i] > 0.0 {
            let first = t0 + Exp::new(s.maps.dcr_hz[i]).unwrap().sample(rng);
            if first < t1 {
                *bit = true;
            }
        }
    }
    let normal = Normal::new(0.0, s.sigma_nm).unwrap();
    for b in s.blinks {
        let a = t0.max(b.t_on_s);
        let e = t1.min(b.t_off_s);
        let flux = s.flux_hz * b.flux_factor;
        if e <= a || flux <= 0.0 {
            continue;
        }
        let gap = Exp::new(flux).unwrap();
        let mut t = a + gap.sample(rng);
        while t < e {
            let x = b.position.x_nm + normal.sample(rng);
            let y = b.position.y_nm + normal.sample(rng);
            let (px, py) = ((x / s.pixel_nm).floor(), (y / s.pixel_nm).floor());
            if px >= 0.0 && py >= 0.0 && (px as usize) < w && (py as usize) < h {
                let i = py as usize * w + px as usize;
                if rng.gen::<f64>() < s.eta[i] {
                    bits[i] = true;
                }
            }
            t += gap.sample(rng);
        }
    }
    bits
}

/// Result of comparing two sets of per-pixel 1-counts over `n` planes each.
#[derive(Debug)]
pub struct TwoSample {
    /// Largest |z| over the cells where the pooled frequency is neither 0 nor 1.
    pub max_abs_z: f64,
    /// Σ z² over those cells.
    pub chi2: f64,
    /// Number of those cells (a pooled frequency of 0 or 1 means both
    /// samples agree exactly there).
    pub cells: usize,
}

impl TwoSample {
    /// χ² per degree of freedom.
    pub fn chi2_per_cell(&self) -> f64 {
        self.chi2 / self.cells.max(1) as f64
    }

    /// Upper bound on χ²/k for a correct sampler: 1 + 5·√(2/k).
    pub fn chi2_bound(&self) -> f64 {
        1.0 + 5.0 * (2.0 / self.cells.max(1) as f64).sqrt()
    }
}

/// Two-proportion z-test per cell (same number of planes `n` on both sides).
pub fn two_sample(a: &[u64], b: &[u64], n: u64) -> TwoSample {
    assert_eq!(a.len(), b.len());
    let nf = n as f64;
    let mut r = TwoSample {
        max_abs_z: 0.0,
        chi2: 0.0,
        cells: 0,
    };
    for (&x, &y) in a.iter().zip(b) {
        let p = (x + y) as f64 / (2.0 * nf);
        if p <= 0.0 || p >= 1.0 {
            continue;
        }
        let sd = (p * (1.0 - p) * 2.0 / nf).sqrt();
        let z = (x as f64 - y as f64) / nf / sd;
        r.max_abs_z = r.max_abs_z.max(z.abs());
        r.chi2 += z * z;
        r.cells += 1;
    }
    r
}
