//! The binary SPAD camera (SPCImager class).
//!
//! ## Physics
//!
//! Pixel `i` detects photons and dark counts as a Poisson process. During one
//! bit-plane exposure τ its expected number of events is
//! `Λ_i = (B·η_i + DCR_i)·τ + Σ_blinks flux·t_on·G_i·η_i`, where B is the
//! background photon rate per pixel (background per µm² × pixel area in the
//! sample plane), η_i = PDE × fill factor × (PRNU factor), G_i the
//! pixel-integrated PSF and t_on the blink's on-time within the exposure. The
//! pixel reads 1 if at least one event happened, so `P(1) = 1 − e^{−Λ_i}` —
//! pile-up is exact by construction of the sampler, not by a formula: the
//! background events and each detected molecule photon are sampled as events
//! and OR-ed into the plane.
//!
//! ## Per-pixel maps ([`generate_maps`], a [`SensorMaps`])
//!
//! * PRNU: `η_i = η · (1 + prnu · Z)`, Z standard normal, clamped to [0, 1]
//!   (the maps hold the factor, [`SensorMaps::efficiency`] the product);
//! * DRNU: `DCR_i = DCR_median · e^{s Z}` (log-normal, median DCR_median) with
//!   s chosen so that std/median = drnu, as the parameter is defined. A
//!   log-normal keeps rates positive and is right-skewed like measured SPAD
//!   DCR distributions;
//! * hot pixels: `round(hot_pixel_fraction · pixels)` pixels chosen at random
//!   have `hot_pixel_dcr_hz` (times the same log-normal factor) instead.
//!
//! ## Speed
//!
//! Background and dark counts are sparse (≈ 1 % of pixels per plane for the
//! SPCImager). Pixels are grouped by their per-plane probability p_i into
//! octaves `(2^{-(k+1)}, 2^{-k}]·p_top`; within a group the next candidate is
//! reached by a geometric jump with the group's largest p, and kept with
//! probability p_i/p_group (≥ ½) — exact thinning. Pixels with p ≥ ¼ (hot
//! pixels, bright backgrounds) are drawn one by one, p = 1 without a draw. A
//! group whose p is so small that the first jump passes its last pixel costs
//! one draw. Molecule photons are placed one by one (see the `emission`
//! module): their cost scales with the photons, not the pixels.
//!
//! The SPCImager's rolling shutter (row skew ≤ one plane) is ignored: every
//! row of plane k exposes `[k·period, k·period + exposure)`.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Exp1;
use smartagg_model::params::{Camera, SpadCamera};
use smartagg_model::plane::BitPlane;
use smartagg_model::recording::{BitOrder, RecordingHeader};
use smartagg_model::sensor_maps::SensorMaps;

use crate::emission::Emission;
use crate::sampling::{
    lognormal_sigma_for_spread, rng_stream, std_normal, STREAM_MAPS, STREAM_PHOTONS,
};
use crate::scene::{Position, Scene};
use crate::timeline::Timeline;
use crate::truth::BlinkTruth;
use crate::SceneError;

/// Draws the per-pixel maps of a `width × height` field from stream 0 of
/// `seed` (see the module docs for the distributions): the PRNU factor
/// `1 + prnu · Z` (at least 0; the efficiency `η · factor` is clamped to
/// [0, 1] where it is used, [`SensorMaps::efficiency`]), the log-normal DCR
/// and the hot pixels.
pub fn generate_maps(camera: &SpadCamera, width: u32, height: u32, seed: u64) -> SensorMaps {
    let n = width as usize * height as usize;
    let mut rng = rng_stream(seed, STREAM_MAPS);
    let s = lognormal_sigma_for_spread(camera.drnu);
    let mut prnu = Vec::with_capacity(n);
    let mut factor = Vec::with_capacity(n);
    for _ in 0..n {
        prnu.push((1.0 + camera.prnu * std_normal(&mut rng)).max(0.0));
        factor.push((s * std_normal(&mut rng)).exp());
    }
    let n_hot = ((camera.hot_pixel_fraction * n as f64).round() as usize).min(n);
    let mut hot = vec![false; n];
    for i in rand::seq::index::sample(&mut rng, n, n_hot) {
        hot[i] = true;
    }
    let dcr_hz = (0..n)
        .map(|i| {
            let base = if hot[i] {
                camera.hot_pixel_dcr_hz
            } else {
                camera.dcr_median_hz
            };
            base * factor[i]
        })
        .collect();
    SensorMaps {
        width,
        height,
        dcr_hz,
        prnu: Some(prnu),
        hot,
    }
}

/// Maps without any non-uniformity or hot pixel: the camera's η and median
/// DCR everywhere.
pub fn uniform_maps(camera: &SpadCamera, width: u32, height: u32) -> SensorMaps {
    SensorMaps::uniform(width, height, camera.dcr_median_hz)
}

/// Probability above which a pixel is drawn on its own rather than by jumps.
const DENSE_P: f64 = 0.25;

/// Which pixels a group jumps over.
#[derive(Debug)]
enum Members {
    /// Every raster index `0..n`; `Some(bitmap)` marks the members (the rest
    /// are candidates that are always rejected). Used for a group holding at
    /// least half the field: jumping over raster indices directly avoids a
    /// cache miss per candidate on a list of indices.
    Raster(usize, Option<Vec<u64>>),
    /// Raster indices, ascending.
    List(Vec<u32>),
}

#[derive(Debug)]
struct Group {
    members: Members,
    /// −ln(1 − p_group) (> 0): jumps are ⌊E / rate⌋ with E ~ Exp(1).
    rate: f64,
    /// Keep ratios p_i / p_group; `None` when all equal 1.
    keep: Option<Keep>,
}

/// Keep ratios, indexed like the candidates (raster index or list position).
///
/// A uniform draw u is compared first with `⌊256·r⌋/256 ≤ r` and
/// `(⌊256·r⌋+1)/256 > r` from a byte table that stays in cache; only when u
/// falls between the two (probability < 1/256) is the exact ratio read.
/// The decision is therefore exactly `u < r`.
#[derive(Debug)]
struct Keep {
    /// ⌊256·r⌋ (0..=256 would not fit: r = 1 is stored as 255 with the exact
    /// ratio deciding the last 1/256).
    coarse: Vec<u8>,
    exact: Vec<f64>,
}

impl Keep {
    fn new(exact: Vec<f64>) -> Keep {
        let coarse = exact
            .iter()
            .map(|&r| (r * 256.0).floor().clamp(0.0, 255.0) as u8)
            .collect();
        Keep { coarse, exact }
    }

    #[inline]
    fn keep(&self, j: usize, u: f64) -> bool {
        let c = self.coarse[j] as f64 * (1.0 / 256.0);
        if u < c {
            true
        } else if u >= c + 1.0 / 256.0 {
            false
        } else {
            u < self.exact[j]
        }
    }
}

impl Group {
    fn len(&self) -> usize {
        match &self.members {
            Members::Raster(n, _) => *n,
            Members::List(v) => v.len(),
        }
    }
}

/// Exact Bernoulli sampler of background and dark counts.
#[derive(Debug)]
struct BackgroundSampler {
    groups: Vec<Group>,
    /// (pixel, p) drawn one by one.
    dense: Vec<(u32, f64)>,
}

impl BackgroundSampler {
    fn new(p: &[f64]) -> BackgroundSampler {
        let n = p.len();
        let mut dense = Vec::new();
        let mut by_octave: std::collections::BTreeMap<i32, Vec<u32>> = Default::default();
        for (i, &pi) in p.iter().enumerate() {
            if pi.is_nan() || pi <= 0.0 {
                continue;
            }
            if pi >= DENSE_P {
                dense.push((i as u32, pi));
            } else {
                let k = (DENSE_P / pi).log2().floor() as i32;
                by_octave.entry(k).or_default().push(i as u32);
            }
        }
        let groups = by_octave
            .into_values()
            .map(|pixels| {
                let pmax = pixels.iter().map(|&i| p[i as usize]).fold(0.0, f64::max);
                let ratio = |i: u32| p[i as usize] / pmax;
                let uniform = pixels.iter().all(|&i| ratio(i) >= 1.0);
                let (members, keep) = if 2 * pixels.len() >= n {
                    let bitmap = (pixels.len() < n).then(|| {
                        let mut b = vec![0u64; n.div_ceil(64)];
                        for &i in &pixels {
                            b[i as usize >> 6] |= 1 << (i & 63);
                        }
                        b
                    });
                    let keep = (!uniform).then(|| {
                        let mut k = vec![0.0; n];
                        for &i in &pixels {
                            k[i as usize] = ratio(i);
                        }
                        Keep::new(k)
                    });
                    (Members::Raster(n, bitmap), keep)
                } else {
                    let keep =
                        (!uniform).then(|| Keep::new(pixels.iter().map(|&i| ratio(i)).collect()));
                    (Members::List(pixels), keep)
                };
                Group {
                    members,
                    rate: -(-pmax).ln_1p(),
                    keep,
                }
            })
            .collect();
        BackgroundSampler { groups, dense }
    }

    #[inline]
    fn sample(&self, rng: &mut ChaCha8Rng, words: &mut [u64]) {
        for g in &self.groups {
            let n = g.len();
            let mut j = 0usize;
            loop {
                // Failures before the next success: ⌊E / −ln(1 − p)⌋ with
                // E = −ln U ~ Exp(1), drawn by rand_distr's ziggurat (no log).
                let skip = rng.sample::<f64, _>(Exp1) / g.rate;
                // Also stops on NaN (cannot happen: E ≥ 0 finite, rate > 0).
                if skip.is_nan() || skip >= (n - j) as f64 {
                    break;
                }
                j += skip as usize;
                let px = match &g.members {
                    Members::Raster(_, None) => j,
                    Members::Raster(_, Some(bitmap)) => {
                        if bitmap[j >> 6] >> (j & 63) & 1 == 0 {
                            j += 1;
                            continue;
                        }
                        j
                    }
                    Members::List(v) => v[j] as usize,
                };
                // Thinning by p_i/p_group.
                let keep = match &g.keep {
                    None => true,
                    Some(k) => k.keep(j, rng.gen::<f64>()),
                };
                if keep {
                    words[px >> 6] |= 1u64 << (px & 63);
                }
                j += 1;
            }
        }
        for &(px, p) in &self.dense {
            if p >= 1.0 || rng.gen::<f64>() < p {
                let px = px as usize;
                words[px >> 6] |= 1u64 << (px & 63);
            }
        }
    }
}

/// Simulates the bit-planes of a SPAD camera looking at a scene.
#[derive(Debug)]
pub struct SpadSimulator {
    camera: SpadCamera,
    width: u32,
    height: u32,
    pixel_nm: f64,
    sigma_px: f64,
    maps: SensorMaps,
    eta: Vec<f64>,
    background_hz: Vec<f64>,
    eta_min: f64,
    eta_max: f64,
    sampler: BackgroundSampler,
    emission: Emission,
    rng: ChaCha8Rng,
    planes: u64,
}

impl SpadSimulator {
    /// A simulator with maps drawn from `seed` ([`generate_maps`]).
    pub fn new(camera: &SpadCamera, scene: &Scene, seed: u64) -> Result<SpadSimulator, SceneError> {
        scene.validate(&Camera::Spad(camera.clone()))?;
        let maps = generate_maps(camera, scene.width, scene.height, seed);
        SpadSimulator::with_maps(camera, scene, maps, seed)
    }

    /// A simulator with the given per-pixel maps (e.g. measured ones, or the
    /// same maps under different photon seeds).
    pub fn with_maps(
        camera: &SpadCamera,
        scene: &Scene,
        maps: SensorMaps,
        seed: u64,
    ) -> Result<SpadSimulator, SceneError> {
        let cam = Camera::Spad(camera.clone());
        scene.validate(&cam)?;
        if maps.width != scene.width || maps.height != scene.height {
            return Err(SceneError::MapShape {
                maps: (maps.width, maps.height),
                field: (scene.width, scene.height),
            });
        }
        maps.validate()?;
        let eta = maps.efficiency(camera.eta());
        let pixel_nm = scene.pixel_nm(&cam);
        let sigma_px = scene.sigma_px(&cam);
        let light_per_px = scene
            .light
            .background_per_pixel_hz(&scene.optics, camera.pixel_pitch_um);
        let background_hz: Vec<f64> = eta
            .iter()
            .zip(&maps.dcr_hz)
            .map(|(&e, &d)| light_per_px * e + d)
            .collect();
        let tau = camera.exposure_s;
        let p: Vec<f64> = background_hz
            .iter()
            .map(|&l| -(-l * tau).exp_m1())
            .collect();
        let sampler = BackgroundSampler::new(&p);
        let eta_max = eta.iter().copied().fold(0.0, f64::max);
        let eta_min = eta.iter().copied().fold(1.0, f64::min);
        let timeline = Timeline::new(scene, pixel_nm, seed);
        let emission = Emission::new(
            timeline,
            scene.width as usize,
            scene.height as usize,
            pixel_nm,
            sigma_px,
        );
        Ok(SpadSimulator {
            camera: camera.clone(),
            width: scene.width,
            height: scene.height,
            pixel_nm,
            sigma_px,
            maps,
            eta,
            background_hz,
            eta_min,
            eta_max,
            sampler,
            emission,
            rng: rng_stream(seed, STREAM_PHOTONS),
            planes: 0,
        })
    }

    /// The next bit-plane.
    pub fn next_plane(&mut self) -> BitPlane {
        let n = self.width as usize * self.height as usize;
        let mut words = vec![0u64; n.div_ceil(64)];
        self.next_plane_words(&mut words);
        let mut bits = bitvec::vec::BitVec::<u64, bitvec::order::Lsb0>::from_vec(words);
        bits.truncate(n);
        BitPlane::from_bits(self.width as usize, self.height as usize, bits)
            .expect("length is width*height")
    }

    /// The next bit-plane as raw 64-pixel words (pixel `i` at bit `i % 64` of
    /// word `i / 64`, as in [`BitPlane`]); `words` must hold
    /// ⌈width·height/64⌉ words and is overwritten.
    pub fn next_plane_words(&mut self, words: &mut [u64]) {
        let n = self.width as usize * self.height as usize;
        assert_eq!(
            words.len(),
            n.div_ceil(64),
            "next_plane_words: wrong buffer length"
        );
        words.fill(0);
        self.sampler.sample(&mut self.rng, words);
        let t0 = self.planes as f64 * self.camera.plane_period_s;
        let t1 = t0 + self.camera.exposure_s;
        self.emission.deposit(
            t0,
            t1,
            &self.eta,
            self.eta_min,
            self.eta_max,
            &mut self.rng,
            |i, _| words[i >> 6] |= 1u64 << (i & 63),
        );
        self.planes += 1;
    }

    /// Bit-planes simulated so far.
    pub fn planes_done(&self) -> u64 {
        self.planes
    }

    /// Pixel-planes simulated so far (planes × pixels).
    pub fn pixel_planes_done(&self) -> u64 {
        self.planes * self.width as u64 * self.height as u64
    }

    /// Start time of the next plane, s.
    pub fn time_s(&self) -> f64 {
        self.planes as f64 * self.camera.plane_period_s
    }

    /// Images every blink with the stage drift `drift` (call it before the
    /// first plane or frame: blinks already imaged keep their photons).
    pub fn set_drift(&mut self, drift: crate::drift::DriftTrajectory) {
        self.emission.set_drift(drift);
    }

    /// Ground truth of every blink started so far; photon counts cover the
    /// planes simulated so far.
    pub fn truth(&self) -> &[BlinkTruth] {
        &self.emission.timeline.blinks
    }

    /// The emitters of the layout: emitter `e` of the truth sits at
    /// `emitters()[e]` (empty for one-at-a-time random positions, where every
    /// blink has its own emitter, and for explicit blinks).
    pub fn emitters(&self) -> &[Position] {
        self.emission.timeline.population()
    }

    /// The per-pixel maps.
    pub fn maps(&self) -> &SensorMaps {
        &self.maps
    }

    /// Each pixel's detection efficiency η_i (the camera's η times its
    /// PRNU factor, clamped to [0, 1]), raster order.
    pub fn efficiency(&self) -> &[f64] {
        &self.eta
    }

    /// Per-pixel rate of background detections plus dark counts, Hz.
    pub fn background_rate_hz(&self) -> &[f64] {
        &self.background_hz
    }

    /// The camera.
    pub fn camera(&self) -> &SpadCamera {
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

    /// A `.spad` header for `planes` planes of this simulation.
    pub fn recording_header(&self, planes: u64, bit_order: BitOrder) -> RecordingHeader {
        RecordingHeader {
            width: self.width,
            height: self.height,
            plane_period_ns: ((self.camera.plane_period_s * 1e9).round() as u64).max(1),
            exposure_ns: ((self.camera.exposure_s * 1e9).round() as u64).max(1),
            bit_order,
            planes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampler_groups_bound_the_thinning() {
        let p = [0.0, 1e-300, 0.01, 0.011, 0.006, 0.3, 1.0, 0.2];
        let s = BackgroundSampler::new(&p);
        assert_eq!(s.dense.len(), 2);
        for g in &s.groups {
            if let Some(k) = &g.keep {
                assert!(k.exact.iter().all(|&x| x > 0.5 && x <= 1.0), "{k:?}");
            }
        }
        let in_groups: usize = s
            .groups
            .iter()
            .map(|g| match &g.members {
                Members::List(v) => v.len(),
                Members::Raster(..) => panic!("no group holds half of 8 pixels here"),
            })
            .sum();
        assert_eq!(in_groups, 5);
    }

    #[test]
    fn sampler_frequencies_match_p() {
        let p: Vec<f64> = (0..64)
            .map(|i| 0.002 * (i % 7) as f64 + 0.3 * (i == 5) as u8 as f64)
            .collect();
        let s = BackgroundSampler::new(&p);
        let mut rng = rng_stream(9, 3);
        let mut counts = [0u32; 64];
        let planes = 200_000;
        for _ in 0..planes {
            let mut w = [0u64; 1];
            s.sample(&mut rng, &mut w);
            for (i, c) in counts.iter_mut().enumerate() {
                *c += ((w[0] >> i) & 1) as u32;
            }
        }
        for i in 0..64 {
            let exp = p[i] * planes as f64;
            let sd = (planes as f64 * p[i] * (1.0 - p[i])).sqrt().max(1e-9);
            let z = (counts[i] as f64 - exp) / sd;
            if p[i] == 0.0 {
                assert_eq!(counts[i], 0);
            } else {
                assert!(z.abs() < 5.0, "pixel {i}: {} vs {exp}", counts[i]);
            }
        }
    }
}
