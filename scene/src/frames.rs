//! Frame cameras: EMCCD and sCMOS.
//!
//! Both integrate photons over an exposure window `[k·period, k·period +
//! exposure)`; with `exposure < period` the rest of the period is read-out
//! dead time during which light is lost (the paper's EMCCD lost 30 ms of
//! every 64 ms frame). Photon arrivals are Poisson throughout; molecule
//! photons are placed exactly as for the SPAD (see [`crate::spad`]).
//!
//! ## EMCCD
//!
//! Input electrons per pixel: Poisson of `QE·B·exposure + dark·period + CIC`
//! (dark current accumulates over the whole period; clock-induced charge is
//! modelled before the gain register) plus the detected molecule photons.
//! Electron multiplication of n > 0 input electrons at gain g gives
//! `n + Gamma(shape = n(g−1)/g, scale = g)` electrons: mean n·g, variance
//! n·g(g−1), so the excess noise factor is F² = 2 − 1/g — 1 without gain and
//! √2 at high gain, where this tends to the usual Gamma(n, g) model. Read
//! noise is Gaussian, `read_noise_e` input-referred (× g at the output).
//! ADU = offset + electrons / e_per_adu, rounded, clipped to 0..=65535; every
//! clipped pixel is counted ([`Frame::clipped`]).
//!
//! ## sCMOS
//!
//! Per-pixel maps ([`ScmosMaps`]): offset (normal around the camera's
//! offset), gain (normal, relative spread `gain_cv`), read noise (log-normal
//! with the camera's median), dark current (log-normal of the camera's mean,
//! relative spread DRNU) and QE (normal, relative spread PRNU, clamped to
//! [0, 1]). The spreads the camera parameters do not give are in
//! [`ScmosNonUniformity`]. Electrons: Poisson of `QE_i·B·exposure +
//! dark_i·period` plus molecule photons; ADU = offset_i + gain_i·(electrons +
//! read_noise_i·Z), rounded and clipped (counted).

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Gamma, Poisson};
use smartagg_model::params::{check_non_negative, check_range, Camera, EmccdCamera, ScmosCamera};

use crate::emission::Emission;
use crate::sampling::{poisson, rng_stream, std_normal, STREAM_MAPS, STREAM_PHOTONS};
use crate::scene::{Position, Scene};
use crate::timeline::Timeline;
use crate::truth::BlinkTruth;
use crate::SceneError;

/// One simulated frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Pixel values, ADU, raster order (what the camera writes; TIFF-ready).
    pub adu: Vec<u16>,
    /// Electrons before read noise and quantisation (EMCCD: after
    /// multiplication; sCMOS: photo-electrons plus dark), raster order.
    pub electrons: Vec<f64>,
    /// Pixels clipped to 0 or 65535 in this frame.
    pub clipped: u32,
}

/// Rounds and clips an ADU value, counting clipped pixels.
#[inline]
fn to_adu(v: f64, clipped: &mut u32) -> u16 {
    let r = v.round();
    if r < 0.0 {
        *clipped += 1;
        0
    } else if r > 65535.0 {
        *clipped += 1;
        65535
    } else {
        r as u16
    }
}

/// Simulates an EMCCD looking at a scene.
#[derive(Debug)]
pub struct EmccdSimulator {
    camera: EmccdCamera,
    width: u32,
    height: u32,
    pixel_nm: f64,
    sigma_px: f64,
    /// Mean input electrons per pixel per frame from background, dark and CIC.
    mean_in: f64,
    qe_map: Vec<f64>,
    emission: Emission,
    rng: ChaCha8Rng,
    frames: u64,
    clipped_total: u64,
}

impl EmccdSimulator {
    /// A simulator of `camera` looking at `scene`, reproducible from `seed`.
    pub fn new(
        camera: &EmccdCamera,
        scene: &Scene,
        seed: u64,
    ) -> Result<EmccdSimulator, SceneError> {
        let cam = Camera::Emccd(camera.clone());
        scene.validate(&cam)?;
        let pixel_nm = scene.pixel_nm(&cam);
        let sigma_px = scene.sigma_px(&cam);
        let bg = scene
            .light
            .background_per_pixel_hz(&scene.optics, camera.pixel_pitch_um);
        let mean_in = camera.qe * bg * camera.exposure_s
            + camera.dark_e_per_s * camera.frame_period_s
            + camera.cic_per_frame;
        let n = scene.width as usize * scene.height as usize;
        let timeline = Timeline::new(scene, pixel_nm, seed);
        Ok(EmccdSimulator {
            camera: camera.clone(),
            width: scene.width,
            height: scene.height,
            pixel_nm,
            sigma_px,
            mean_in,
            qe_map: vec![camera.qe; n],
            emission: Emission::new(
                timeline,
                scene.width as usize,
                scene.height as usize,
                pixel_nm,
                sigma_px,
            ),
            rng: rng_stream(seed, STREAM_PHOTONS),
            frames: 0,
            clipped_total: 0,
        })
    }

    /// The next frame.
    pub fn next_frame(&mut self) -> Frame {
        let n = self.width as usize * self.height as usize;
        let c = &self.camera;
        let mut e_in = vec![0u32; n];
        if self.mean_in > 0.0 {
            let d = Poisson::new(self.mean_in).expect("positive finite mean");
            for e in e_in.iter_mut() {
                *e = d.sample(&mut self.rng) as u32;
            }
        }
        let t0 = self.frames as f64 * c.frame_period_s;
        let t1 = t0 + c.exposure_s;
        self.emission
            .deposit(t0, t1, &self.qe_map, c.qe, c.qe, &mut self.rng, |i, c| {
                e_in[i] = e_in[i].saturating_add(u32::try_from(c).unwrap_or(u32::MAX))
            });
        let g = c.em_gain;
        let read_sd_e = c.read_noise_e * g;
        let mut electrons = Vec::with_capacity(n);
        let mut adu = Vec::with_capacity(n);
        let mut clipped = 0u32;
        for &k in &e_in {
            let out = if k == 0 || g <= 1.0 {
                k as f64
            } else {
                let shape = k as f64 * (g - 1.0) / g;
                k as f64
                    + Gamma::new(shape, g)
                        .expect("positive shape and scale")
                        .sample(&mut self.rng)
            };
            electrons.push(out);
            let noisy = out + read_sd_e * std_normal(&mut self.rng);
            adu.push(to_adu(c.offset_adu + noisy / c.e_per_adu, &mut clipped));
        }
        self.frames += 1;
        self.clipped_total += clipped as u64;
        Frame {
            adu,
            electrons,
            clipped,
        }
    }

    /// Frames simulated so far.
    pub fn frames_done(&self) -> u64 {
        self.frames
    }

    /// Pixels clipped so far, all frames.
    pub fn clipped_total(&self) -> u64 {
        self.clipped_total
    }

    /// The emitters of the layout (see [`crate::SpadSimulator::emitters`]).
    pub fn emitters(&self) -> &[Position] {
        self.emission.timeline.population()
    }

    /// Images every blink with the stage drift `drift` (call it before the
    /// first plane or frame: blinks already imaged keep their photons).
    pub fn set_drift(&mut self, drift: crate::drift::DriftTrajectory) {
        self.emission.set_drift(drift);
    }

    /// Ground truth of every blink started so far.
    pub fn truth(&self) -> &[BlinkTruth] {
        &self.emission.timeline.blinks
    }

    /// Mean input electrons per pixel per frame from background, dark current and CIC.
    pub fn mean_background_electrons(&self) -> f64 {
        self.mean_in
    }

    /// The camera.
    pub fn camera(&self) -> &EmccdCamera {
        &self.camera
    }

    /// Field width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Field height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixel size in the sample plane, nm.
    pub fn pixel_nm(&self) -> f64 {
        self.pixel_nm
    }

    /// PSF σ, pixels.
    pub fn sigma_px(&self) -> f64 {
        self.sigma_px
    }
}

/// sCMOS non-uniformities that [`ScmosCamera`] does not specify.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScmosNonUniformity {
    /// Standard deviation of the per-pixel offset, ADU.
    pub offset_sd_adu: f64,
    /// Relative spread of the per-pixel gain.
    pub gain_cv: f64,
    /// σ of ln(read noise): the read-noise map is log-normal around the median.
    pub read_noise_log_sigma: f64,
}

impl Default for ScmosNonUniformity {
    /// 2 ADU offset spread, 1 % gain spread, read noise log-normal with σ_ln = 0.3
    /// (mean ≈ 1.05 × median with a long tail, as in published ORCA-Flash maps).
    fn default() -> Self {
        ScmosNonUniformity {
            offset_sd_adu: 2.0,
            gain_cv: 0.01,
            read_noise_log_sigma: 0.3,
        }
    }
}

/// Per-pixel maps of an sCMOS field.
#[derive(Debug, Clone, PartialEq)]
pub struct ScmosMaps {
    /// Field width, pixels.
    pub width: u32,
    /// Field height, pixels.
    pub height: u32,
    /// Offset (bias), ADU.
    pub offset_adu: Vec<f64>,
    /// Gain, ADU per electron.
    pub gain_adu_per_e: Vec<f64>,
    /// Read noise, e⁻ rms.
    pub read_noise_e: Vec<f64>,
    /// Dark current, e⁻/s.
    pub dark_e_per_s: Vec<f64>,
    /// Quantum efficiency.
    pub qe: Vec<f64>,
}

impl ScmosMaps {
    /// Draws the maps from stream 0 of `seed` (see the module docs).
    pub fn generate(
        camera: &ScmosCamera,
        nu: &ScmosNonUniformity,
        width: u32,
        height: u32,
        seed: u64,
    ) -> ScmosMaps {
        let n = width as usize * height as usize;
        let mut rng = rng_stream(seed, STREAM_MAPS);
        let g0 = 1.0 / camera.e_per_adu;
        // Mean-preserving log-normal for the dark current: E = dark, CV = drnu.
        let s_dark = (1.0 + camera.drnu * camera.drnu).ln().sqrt();
        let mut m = ScmosMaps {
            width,
            height,
            offset_adu: Vec::with_capacity(n),
            gain_adu_per_e: Vec::with_capacity(n),
            read_noise_e: Vec::with_capacity(n),
            dark_e_per_s: Vec::with_capacity(n),
            qe: Vec::with_capacity(n),
        };
        for _ in 0..n {
            m.offset_adu
                .push(camera.offset_adu + nu.offset_sd_adu * std_normal(&mut rng));
            m.gain_adu_per_e
                .push((g0 * (1.0 + nu.gain_cv * std_normal(&mut rng))).max(0.0));
            m.read_noise_e
                .push(camera.read_noise_e * (nu.read_noise_log_sigma * std_normal(&mut rng)).exp());
            m.dark_e_per_s.push(
                camera.dark_e_per_s * (s_dark * std_normal(&mut rng) - 0.5 * s_dark * s_dark).exp(),
            );
            m.qe.push((camera.qe * (1.0 + camera.prnu * std_normal(&mut rng))).clamp(0.0, 1.0));
        }
        m
    }
}

/// Simulates an sCMOS camera looking at a scene.
#[derive(Debug)]
pub struct ScmosSimulator {
    camera: ScmosCamera,
    width: u32,
    height: u32,
    pixel_nm: f64,
    sigma_px: f64,
    maps: ScmosMaps,
    /// Mean electrons per pixel per frame from background and dark current.
    mean_bg: Vec<f64>,
    qe_min: f64,
    qe_max: f64,
    emission: Emission,
    rng: ChaCha8Rng,
    frames: u64,
    clipped_total: u64,
}

impl ScmosSimulator {
    /// A simulator with maps drawn from `seed` and the default non-uniformities.
    pub fn new(
        camera: &ScmosCamera,
        scene: &Scene,
        seed: u64,
    ) -> Result<ScmosSimulator, SceneError> {
        ScmosSimulator::with_non_uniformity(camera, scene, &ScmosNonUniformity::default(), seed)
    }

    /// A simulator with maps drawn from `seed` with the given non-uniformities.
    pub fn with_non_uniformity(
        camera: &ScmosCamera,
        scene: &Scene,
        nu: &ScmosNonUniformity,
        seed: u64,
    ) -> Result<ScmosSimulator, SceneError> {
        check_non_negative("offset_sd_adu", nu.offset_sd_adu)?;
        check_range("gain_cv", nu.gain_cv, 0.0, 1.0)?;
        check_range("read_noise_log_sigma", nu.read_noise_log_sigma, 0.0, 5.0)?;
        scene.validate(&Camera::Scmos(camera.clone()))?;
        let maps = ScmosMaps::generate(camera, nu, scene.width, scene.height, seed);
        ScmosSimulator::with_maps(camera, scene, maps, seed)
    }

    /// A simulator with the given maps.
    pub fn with_maps(
        camera: &ScmosCamera,
        scene: &Scene,
        maps: ScmosMaps,
        seed: u64,
    ) -> Result<ScmosSimulator, SceneError> {
        let cam = Camera::Scmos(camera.clone());
        scene.validate(&cam)?;
        let n = scene.width as usize * scene.height as usize;
        for len in [
            maps.offset_adu.len(),
            maps.gain_adu_per_e.len(),
            maps.read_noise_e.len(),
            maps.dark_e_per_s.len(),
            maps.qe.len(),
        ] {
            if len != n || maps.width != scene.width || maps.height != scene.height {
                return Err(SceneError::MapSize {
                    expected: n,
                    found: len,
                });
            }
        }
        for i in 0..n {
            check_range("offset_adu (map)", maps.offset_adu[i], -1e6, 1e6)?;
            check_non_negative("gain_adu_per_e (map)", maps.gain_adu_per_e[i])?;
            check_non_negative("read_noise_e (map)", maps.read_noise_e[i])?;
            check_non_negative("dark_e_per_s (map)", maps.dark_e_per_s[i])?;
            check_range("qe (map)", maps.qe[i], 0.0, 1.0)?;
        }
        let pixel_nm = scene.pixel_nm(&cam);
        let sigma_px = scene.sigma_px(&cam);
        let bg = scene
            .light
            .background_per_pixel_hz(&scene.optics, camera.pixel_pitch_um);
        let mean_bg = (0..n)
            .map(|i| {
                maps.qe[i] * bg * camera.exposure_s + maps.dark_e_per_s[i] * camera.frame_period_s
            })
            .collect();
        let qe_max = maps.qe.iter().copied().fold(0.0, f64::max);
        let qe_min = maps.qe.iter().copied().fold(1.0, f64::min);
        let timeline = Timeline::new(scene, pixel_nm, seed);
        Ok(ScmosSimulator {
            camera: camera.clone(),
            width: scene.width,
            height: scene.height,
            pixel_nm,
            sigma_px,
            maps,
            mean_bg,
            qe_min,
            qe_max,
            emission: Emission::new(
                timeline,
                scene.width as usize,
                scene.height as usize,
                pixel_nm,
                sigma_px,
            ),
            rng: rng_stream(seed, STREAM_PHOTONS),
            frames: 0,
            clipped_total: 0,
        })
    }

    /// The next frame.
    pub fn next_frame(&mut self) -> Frame {
        let n = self.width as usize * self.height as usize;
        let mut e: Vec<u64> = self
            .mean_bg
            .iter()
            .map(|&m| poisson(&mut self.rng, m))
            .collect();
        let t0 = self.frames as f64 * self.camera.frame_period_s;
        let t1 = t0 + self.camera.exposure_s;
        self.emission.deposit(
            t0,
            t1,
            &self.maps.qe,
            self.qe_min,
            self.qe_max,
            &mut self.rng,
            |i, c| e[i] = e[i].saturating_add(c),
        );
        let mut electrons = Vec::with_capacity(n);
        let mut adu = Vec::with_capacity(n);
        let mut clipped = 0u32;
        let m = &self.maps;
        for (i, &ei) in e.iter().enumerate() {
            let el = ei as f64;
            electrons.push(el);
            let noisy = el + m.read_noise_e[i] * std_normal(&mut self.rng);
            adu.push(to_adu(
                m.offset_adu[i] + m.gain_adu_per_e[i] * noisy,
                &mut clipped,
            ));
        }
        self.frames += 1;
        self.clipped_total += clipped as u64;
        Frame {
            adu,
            electrons,
            clipped,
        }
    }

    /// Frames simulated so far.
    pub fn frames_done(&self) -> u64 {
        self.frames
    }

    /// Pixels clipped so far, all frames.
    pub fn clipped_total(&self) -> u64 {
        self.clipped_total
    }

    /// The emitters of the layout (see [`crate::SpadSimulator::emitters`]).
    pub fn emitters(&self) -> &[Position] {
        self.emission.timeline.population()
    }

    /// Images every blink with the stage drift `drift` (call it before the
    /// first plane or frame: blinks already imaged keep their photons).
    pub fn set_drift(&mut self, drift: crate::drift::DriftTrajectory) {
        self.emission.set_drift(drift);
    }

    /// Ground truth of every blink started so far.
    pub fn truth(&self) -> &[BlinkTruth] {
        &self.emission.timeline.blinks
    }

    /// The per-pixel maps.
    pub fn maps(&self) -> &ScmosMaps {
        &self.maps
    }

    /// The camera.
    pub fn camera(&self) -> &ScmosCamera {
        &self.camera
    }

    /// Field width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Field height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixel size in the sample plane, nm.
    pub fn pixel_nm(&self) -> f64 {
        self.pixel_nm
    }

    /// PSF σ, pixels.
    pub fn sigma_px(&self) -> f64 {
        self.sigma_px
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adu_clipping_is_counted() {
        let mut c = 0;
        assert_eq!(to_adu(-3.0, &mut c), 0);
        assert_eq!(to_adu(70000.0, &mut c), 65535);
        assert_eq!(to_adu(12.4, &mut c), 12);
        assert_eq!(c, 2);
    }
}
