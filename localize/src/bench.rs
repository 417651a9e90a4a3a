//! Accuracy and speed on simulated ROIs: what `smartagg bench localize`
//! prints and what the accuracy tests check (with fewer ROIs).
//!
//! Error is always reported beside run time: RMSE against the truth, the
//! Cramér–Rao bound of the model fitted (evaluated at the truth and averaged
//! as a variance over the ROIs), their ratio, the mean reported uncertainty
//! relative to the RMSE (calibration of the `uncertainty` column), failures,
//! and fits per second on the calling thread (one core).

use crate::crlb::{crlb_frame, Emitter};
use crate::fit::{fit_roi, Estimator, Fit, FitOptions, NoiseModel};
use crate::roi::{apply_hot_pixels, HotPixelMode, PixelMaps, RoiView};
use crate::spad::{crlb_binomial, fit_binomial, SpadEmitter, SpadRoi};
use crate::synth;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use std::time::Instant;

/// Measures the CPU time of the calling thread (what "one core" means on a
/// shared machine), falling back to wall-clock time where unavailable.
#[derive(Clone, Copy, Debug)]
pub struct CpuTimer {
    wall: Instant,
    cpu: Option<f64>,
}

impl CpuTimer {
    /// Starts the timer.
    pub fn start() -> CpuTimer {
        CpuTimer {
            wall: Instant::now(),
            cpu: thread_cpu_seconds(),
        }
    }

    /// Seconds of CPU time of this thread since `start` (wall-clock time if
    /// the platform has no thread CPU clock).
    pub fn seconds(&self) -> f64 {
        match (self.cpu, thread_cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => self.wall.elapsed().as_secs_f64(),
        }
    }

    /// Wall-clock seconds since `start`.
    pub fn wall_seconds(&self) -> f64 {
        self.wall.elapsed().as_secs_f64()
    }
}

#[cfg(unix)]
fn thread_cpu_seconds() -> Option<f64> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec into the valid pointer given.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    (rc == 0).then_some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
}

#[cfg(not(unix))]
fn thread_cpu_seconds() -> Option<f64> {
    None
}

/// Simulated frame-type ROIs: emitter uniformly within ±`jitter` px of the
/// ROI centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameScenario {
    /// ROI side, pixels.
    pub side: usize,
    /// PSF σ, pixels.
    pub sigma: f64,
    /// Emitter photons.
    pub photons: f64,
    /// Background photons per pixel.
    pub background: f64,
    /// Half-width of the uniform position jitter around the centre, pixels.
    pub jitter: f64,
    /// Number of ROIs.
    pub count: usize,
    /// Random seed.
    pub seed: u64,
    /// Camera noise (Poisson, EMCCD with gain 300, or sCMOS with `read_var`).
    pub noise: NoiseModel,
    /// sCMOS read-noise variance per pixel (photo-electrons²).
    pub read_var: f64,
}

impl FrameScenario {
    /// A 50 ms SPCImager blink as in the issue: 9×9, σ = 1.5 px, 230 photons,
    /// 5.9 background photons per pixel, ideal Poisson counts.
    pub fn spcimager_blink(count: usize, seed: u64) -> FrameScenario {
        FrameScenario {
            side: 9,
            sigma: 1.5,
            photons: 230.0,
            background: 5.9,
            jitter: 0.5,
            count,
            seed,
            noise: NoiseModel::Poisson,
            read_var: 0.0,
        }
    }
}

/// ROIs and their truth.
#[derive(Clone, Debug)]
pub struct FrameSet {
    /// ROI side.
    pub side: usize,
    /// All ROIs back to back, `side²` values each.
    pub data: Vec<f64>,
    /// The emitter of each ROI.
    pub truth: Vec<Emitter>,
    /// Per-pixel maps shared by all ROIs (sCMOS read variance), if any.
    pub maps: Option<PixelMaps>,
    /// The noise model simulated.
    pub noise: NoiseModel,
}

/// Simulates a [`FrameScenario`].
pub fn simulate_frames(sc: &FrameScenario) -> FrameSet {
    let mut rng = StdRng::seed_from_u64(sc.seed);
    let c = sc.side as f64 / 2.0;
    let maps = (sc.noise == NoiseModel::Scmos).then(|| {
        let mut m = PixelMaps::uniform(sc.side);
        m.read_var.iter_mut().for_each(|v| *v = sc.read_var);
        m
    });
    let mut data = Vec::with_capacity(sc.count * sc.side * sc.side);
    let mut truth = Vec::with_capacity(sc.count);
    for _ in 0..sc.count {
        let em = Emitter {
            x: c + rng.gen_range(-sc.jitter..=sc.jitter),
            y: c + rng.gen_range(-sc.jitter..=sc.jitter),
            sigma: sc.sigma,
            photons: sc.photons,
            background: sc.background,
        };
        let roi = match sc.noise {
            NoiseModel::Poisson => synth::poisson_roi(&mut rng, sc.side, &em, None),
            NoiseModel::Emccd => synth::emccd_roi(&mut rng, sc.side, &em, 300.0),
            NoiseModel::Scmos => {
                synth::scmos_roi(&mut rng, sc.side, &em, maps.as_ref().expect("made above"))
            }
        };
        data.extend_from_slice(&roi);
        truth.push(em);
    }
    FrameSet {
        side: sc.side,
        data,
        truth,
        maps,
        noise: sc.noise,
    }
}

/// Accuracy and speed of one estimator on one set.
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    /// ROIs fitted.
    pub n: usize,
    /// Fits not ok (excluded from the error statistics, never hidden).
    pub failures: usize,
    /// Fits per second on one thread (thread CPU time).
    pub fits_per_s: f64,
    /// Per-axis RMSE, pixels: `sqrt(mean((dx² + dy²)/2))` over ok fits.
    pub rmse: f64,
    /// Per-axis Cramér–Rao bound, pixels: `sqrt(mean((var_x + var_y)/2))`.
    pub crlb: f64,
    /// Mean reported uncertainty (pixels) divided by the RMSE.
    pub reported_over_rmse: f64,
    /// Mean x error, pixels.
    pub bias_x: f64,
    /// Mean y error, pixels.
    pub bias_y: f64,
    /// Mean estimated photons divided by the true photons, minus 1.
    pub photon_bias: f64,
    /// Mean estimated σ minus the true σ, pixels.
    pub sigma_bias: f64,
    /// Mean iterations per fit.
    pub iterations: f64,
}

impl Score {
    /// RMSE / CRLB.
    pub fn ratio(&self) -> f64 {
        self.rmse / self.crlb
    }
}

fn summarise(
    fits: &[Fit],
    truth: &[(f64, f64, f64, f64)],
    crlb_vars: &[f64],
    seconds: f64,
) -> Score {
    let n = fits.len();
    let (mut se, mut bx, mut by, mut ph, mut sg, mut rep, mut it) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut ok = 0usize;
    for (f, &(x, y, photons, sigma)) in fits.iter().zip(truth) {
        if !f.status.is_ok() {
            continue;
        }
        ok += 1;
        let (dx, dy) = (f.x - x, f.y - y);
        se += (dx * dx + dy * dy) / 2.0;
        bx += dx;
        by += dy;
        ph += f.photons / photons - 1.0;
        sg += f.sigma - sigma;
        rep += f.uncertainty_px();
        it += f.iterations as f64;
    }
    let okf = ok.max(1) as f64;
    let rmse = (se / okf).sqrt();
    let crlb = (crlb_vars.iter().sum::<f64>() / crlb_vars.len().max(1) as f64).sqrt();
    Score {
        n,
        failures: n - ok,
        fits_per_s: n as f64 / seconds.max(1e-12),
        rmse,
        crlb,
        reported_over_rmse: rep / okf / rmse.max(1e-300),
        bias_x: bx / okf,
        bias_y: by / okf,
        photon_bias: ph / okf,
        sigma_bias: sg / okf,
        iterations: it / okf,
    }
}

/// Fits every ROI of `set` on the calling thread and scores the estimator.
/// The bound is that of the model fitted (σ fixed or fitted as in `opts`;
/// the centroid is compared with the σ-fixed bound).
pub fn score_frames(set: &FrameSet, estimator: Estimator, opts: &FitOptions) -> Score {
    let s2 = set.side * set.side;
    let maps = set.maps.as_ref();
    let mut fits = Vec::with_capacity(set.truth.len());
    let t0 = CpuTimer::start();
    for roi in set.data.chunks_exact(s2) {
        let view = RoiView {
            side: set.side,
            data: roi,
            maps,
        };
        fits.push(fit_roi(estimator, &view, opts));
    }
    let seconds = t0.seconds();
    let fit_sigma = opts.sigma.is_fitted() && estimator != Estimator::Centroid;
    let vars: Vec<f64> = set
        .truth
        .iter()
        .filter_map(|em| crlb_frame(set.side, em, maps, opts.noise, fit_sigma))
        .map(|c| (c.var_x + c.var_y) / 2.0)
        .collect();
    let truth: Vec<_> = set
        .truth
        .iter()
        .map(|e| (e.x, e.y, e.photons, e.sigma))
        .collect();
    summarise(&fits, &truth, &vars, seconds)
}

/// Fits per second on one core, robust to a shared machine: the set is
/// fitted `repeats` times in batches of `batch` ROIs on the calling thread,
/// each batch timed by thread CPU time; returns (median, best) over batches.
pub fn one_core_rate(
    set: &FrameSet,
    estimator: Estimator,
    opts: &FitOptions,
    batch: usize,
    repeats: usize,
) -> (f64, f64) {
    let s2 = set.side * set.side;
    let maps = set.maps.as_ref();
    let mut rates = Vec::new();
    let mut sink = 0.0;
    for _ in 0..repeats.max(1) {
        for chunk in set.data.chunks(s2 * batch.max(1)) {
            let t0 = CpuTimer::start();
            let mut n = 0;
            for roi in chunk.chunks_exact(s2) {
                let view = RoiView {
                    side: set.side,
                    data: roi,
                    maps,
                };
                sink += fit_roi(estimator, &view, opts).x;
                n += 1;
            }
            let dt = t0.seconds();
            if dt > 0.0 {
                rates.push(n as f64 / dt);
            }
        }
    }
    std::hint::black_box(sink);
    if rates.is_empty() {
        return (0.0, 0.0);
    }
    rates.sort_by(|a, b| a.total_cmp(b));
    (rates[rates.len() / 2], rates[rates.len() - 1])
}

/// Fits per second of an estimator on all cores (rayon), wall clock.
pub fn throughput_parallel(set: &FrameSet, estimator: Estimator, opts: &FitOptions) -> f64 {
    let s2 = set.side * set.side;
    let maps = set.maps.as_ref();
    let t0 = Instant::now();
    let ok = set
        .data
        .par_chunks_exact(s2)
        .map(|roi| {
            let view = RoiView {
                side: set.side,
                data: roi,
                maps,
            };
            fit_roi(estimator, &view, opts).status.is_ok() as usize
        })
        .sum::<usize>();
    std::hint::black_box(ok);
    set.truth.len() as f64 / t0.elapsed().as_secs_f64().max(1e-12)
}

/// Hot pixels: each pixel of each ROI is hot with probability `fraction`;
/// the pipeline masked it (it reads 0). Scores the Poisson MLE when hot
/// pixels are ignored or interpolated.
pub fn score_hot_pixels(
    sc: &FrameScenario,
    fraction: f64,
    mode: HotPixelMode,
    opts: &FitOptions,
) -> Score {
    let set = simulate_frames(sc);
    let mut rng = StdRng::seed_from_u64(sc.seed ^ 0x5eed_ba5e);
    let s2 = sc.side * sc.side;
    let mut fits = Vec::with_capacity(sc.count);
    let mut seconds = 0.0;
    for roi in set.data.chunks_exact(s2) {
        let hot: Vec<bool> = (0..s2)
            .map(|_| rng.gen_bool(fraction.clamp(0.0, 1.0)))
            .collect();
        let mut data: Vec<f64> = roi
            .iter()
            .zip(&hot)
            .map(|(&v, &h)| if h { 0.0 } else { v })
            .collect();
        let mut maps = PixelMaps::uniform(sc.side);
        let t0 = CpuTimer::start();
        // Shapes are consistent by construction.
        let _ = apply_hot_pixels(&mut data, &hot, mode, &mut maps);
        let view = RoiView {
            side: sc.side,
            data: &data,
            maps: Some(&maps),
        };
        fits.push(crate::lm::fit_mle(&view, opts));
        seconds += t0.seconds();
    }
    let vars: Vec<f64> = set
        .truth
        .iter()
        .filter_map(|em| crlb_frame(sc.side, em, None, opts.noise, opts.sigma.is_fitted()))
        .map(|c| (c.var_x + c.var_y) / 2.0)
        .collect();
    let truth: Vec<_> = set
        .truth
        .iter()
        .map(|e| (e.x, e.y, e.photons, e.sigma))
        .collect();
    summarise(&fits, &truth, &vars, seconds)
}

/// Hot pixels in SPAD blink ROIs: each pixel of each ROI is hot with
/// probability `fraction` and masked by the pipeline (reads 0). Scores the
/// SPAD binomial MLE when hot pixels are ignored or interpolated (the
/// interpolated count is rounded: the binomial needs whole counts).
pub fn score_spad_hot_pixels(
    set: &SpadSet,
    fraction: f64,
    mode: HotPixelMode,
    opts: &FitOptions,
) -> Score {
    let sc = &set.scenario;
    let s2 = sc.side * sc.side;
    let mut rng = StdRng::seed_from_u64(sc.seed ^ 0x5eed_ba5e);
    let mut fits = Vec::with_capacity(set.truth.len());
    let mut seconds = 0.0;
    for roi in set.counts.chunks_exact(s2) {
        let hot: Vec<bool> = (0..s2)
            .map(|_| rng.gen_bool(fraction.clamp(0.0, 1.0)))
            .collect();
        let mut data: Vec<f64> = roi
            .iter()
            .zip(&hot)
            .map(|(&v, &h)| if h { 0.0 } else { v as f64 })
            .collect();
        let mut maps = PixelMaps::uniform(sc.side);
        let t0 = CpuTimer::start();
        let _ = apply_hot_pixels(&mut data, &hot, mode, &mut maps);
        let counts: Vec<u32> = data.iter().map(|&v| v.round() as u32).collect();
        let r = SpadRoi {
            side: sc.side,
            counts: &counts,
            n_on: sc.n_on,
            n_off: sc.n_off,
            maps: Some(&maps),
        };
        fits.push(fit_binomial(&r, opts));
        seconds += t0.seconds();
    }
    let vars: Vec<f64> = set
        .truth
        .iter()
        .filter_map(|em| {
            crlb_binomial(sc.side, em, sc.n_on, sc.n_off, None, opts.sigma.is_fitted())
        })
        .map(|(vx, vy)| (vx + vy) / 2.0)
        .collect();
    let truth: Vec<_> = set
        .truth
        .iter()
        .map(|e| (e.x, e.y, e.signal_per_plane * sc.n_on as f64, e.sigma))
        .collect();
    summarise(&fits, &truth, &vars, seconds)
}

/// Simulated SPAD blink ROIs (bit-plane aggregates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpadScenario {
    /// ROI side, pixels.
    pub side: usize,
    /// PSF σ, pixels.
    pub sigma: f64,
    /// Molecule detections per on-plane before saturation (S).
    pub signal_per_plane: f64,
    /// Background detections per pixel per plane (B).
    pub background_per_plane: f64,
    /// Planes with the molecule on.
    pub n_on: u32,
    /// Background-only planes.
    pub n_off: u32,
    /// Emitter position relative to the ROI centre, pixels (fixed offset).
    pub offset: (f64, f64),
    /// Half-width of the uniform jitter added to the offset, pixels.
    pub jitter: f64,
    /// Number of ROIs.
    pub count: usize,
    /// Random seed.
    pub seed: u64,
}

/// SPAD ROIs and their truth.
#[derive(Clone, Debug)]
pub struct SpadSet {
    /// The scenario.
    pub scenario: SpadScenario,
    /// All ROIs back to back.
    pub counts: Vec<u32>,
    /// The emitter of each ROI.
    pub truth: Vec<SpadEmitter>,
}

/// Simulates a [`SpadScenario`].
pub fn simulate_spad(sc: &SpadScenario) -> SpadSet {
    let mut rng = StdRng::seed_from_u64(sc.seed);
    let c = sc.side as f64 / 2.0;
    let mut counts = Vec::with_capacity(sc.count * sc.side * sc.side);
    let mut truth = Vec::with_capacity(sc.count);
    for _ in 0..sc.count {
        let j = sc.jitter;
        let em = SpadEmitter {
            x: c + sc.offset.0 + if j > 0.0 { rng.gen_range(-j..=j) } else { 0.0 },
            y: c + sc.offset.1 + if j > 0.0 { rng.gen_range(-j..=j) } else { 0.0 },
            sigma: sc.sigma,
            signal_per_plane: sc.signal_per_plane,
            background_per_plane: sc.background_per_plane,
        };
        counts.extend(synth::spad_roi(
            &mut rng, sc.side, &em, sc.n_on, sc.n_off, None,
        ));
        truth.push(em);
    }
    SpadSet {
        scenario: *sc,
        counts,
        truth,
    }
}

/// Scores the SPAD binomial MLE ([`Estimator::SpadMle`]) or a frame
/// estimator applied to the counts as if they were Poisson. Photon bias is
/// relative to `S · n_on` (what an ideal, non-saturating counter would have
/// detected); the bound is the binomial one.
pub fn score_spad(set: &SpadSet, estimator: Estimator, opts: &FitOptions) -> Score {
    let sc = &set.scenario;
    let s2 = sc.side * sc.side;
    let as_f64: Vec<f64> = set.counts.iter().map(|&c| c as f64).collect();
    let mut fits = Vec::with_capacity(set.truth.len());
    let t0 = CpuTimer::start();
    for (k, roi) in set.counts.chunks_exact(s2).enumerate() {
        let fit = match estimator {
            Estimator::SpadMle => {
                let r = SpadRoi {
                    side: sc.side,
                    counts: roi,
                    n_on: sc.n_on,
                    n_off: sc.n_off,
                    maps: None,
                };
                fit_binomial(&r, opts)
            }
            other => {
                let view = RoiView {
                    side: sc.side,
                    data: &as_f64[k * s2..(k + 1) * s2],
                    maps: None,
                };
                fit_roi(other, &view, opts)
            }
        };
        fits.push(fit);
    }
    let seconds = t0.seconds();
    let vars: Vec<f64> = set
        .truth
        .iter()
        .filter_map(|em| {
            crlb_binomial(sc.side, em, sc.n_on, sc.n_off, None, opts.sigma.is_fitted())
        })
        .map(|(vx, vy)| (vx + vy) / 2.0)
        .collect();
    let truth: Vec<_> = set
        .truth
        .iter()
        .map(|e| (e.x, e.y, e.signal_per_plane * sc.n_on as f64, e.sigma))
        .collect();
    summarise(&fits, &truth, &vars, seconds)
}
