//! `nanoruler`: GATTA-PAINT 80G nanorulers seen at once by the SPCIMAGER and
//! an EMCCD behind a 50/50 splitter (paper §4.1, Figs. 6 and 7).
//!
//! Six rulers (three markers 80 nm apart, random orientation) on a 2.56 µm
//! field: 48×48 SPCIMAGER pixels (53.3 nm) and 24×24 EMCCD pixels (106.7 nm)
//! at 150×. Every marker switches independently (on Exp(30 ms), off
//! Exp(3 s), as `Scene::nanorulers`); both cameras see **the same blinks** with half the photons
//! (molecule and background). Schemes: EMCCD frames (64 ms period, 34 ms
//! exposure: 30 ms dead time), SPCIMAGER fixed aggregation (640-plane =
//! 64 ms frames) and SPCIMAGER smart aggregation: the field design of the
//! 48×48 field, as `smartagg aggregate` defaults to (N from the paper's
//! statistics for the light reaching the SPAD; open threshold for 1 false
//! blink/s over the field, Eq. 7's threshold to hold, r_assoc = round(2σ),
//! L_min 1, end_trim ⌊N/2⌋), and the same with the paper's r_assoc = 1.
//!
//! Analysis as a user would do it, without the truth: ThunderSTORM-style
//! density filter (keep localisations with ≥ 3 others within 30 nm), the
//! localisations within 160 nm of a ruler's centre belong to it, the
//! ruler's axis is their principal axis, three markers are found by 1-D
//! k-means along it, refined by a three-component isotropic Gaussian
//! mixture (EM); marker position = component mean, spread = its per-axis
//! standard deviation, neighbour distances = distances between
//! consecutive marker positions. The truth is used only to report
//! detection, false positives, RMS error and marker-position error.

mod analysis;
mod plot;
mod report;

pub use analysis::{density_filter, gaussian_mixture, kmeans3, principal_axis, Component};
pub use report::write;

use super::common::*;
use crate::error::StudyError;
use crate::matching::{outcome, Loc, Truth};
use crate::timeline::{derive_seed, key_hash};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_localize::NoiseModel;
use smartagg_model::config::PipelineConfig;
use smartagg_model::field_design::FieldDesign;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_scene::Position;
use std::time::Instant;

/// Marker spacing, nm.
pub const SPACING_NM: f64 = 80.0;
/// Density filter: radius, nm.
pub const DENSITY_RADIUS_NM: f64 = 30.0;
/// Density filter: neighbours needed.
pub const DENSITY_MIN: usize = 3;
/// Localisations this close to a ruler's centre belong to it, nm.
pub const RULER_RADIUS_NM: f64 = 160.0;
/// Light of the sample relative to the study's: twice, so that each camera
/// behind the 50/50 splitter gets the study's light.
pub const SOURCE: f64 = 2.0;
/// Truth matching radius, nm.
pub const MATCH_NM: f64 = 53.3;
/// Field side in the sample, nm (48 SPCIMAGER or 24 EMCCD pixels at 150×).
pub const FIELD_NM: f64 = 2560.0;

const RULER_CENTRES: [(f64, f64); 6] = [
    (0.2, 0.3),
    (0.5, 0.3),
    (0.8, 0.3),
    (0.2, 0.7),
    (0.5, 0.7),
    (0.8, 0.7),
];

/// The schemes compared.
pub const SCHEMES: [&str; 4] = [
    "EMCCD 64 ms frames",
    "SPCIMAGER fixed 640 planes",
    "SPCIMAGER smart",
    "SPCIMAGER smart r_assoc 1",
];

/// Association radius of the second smart scheme: the paper's (and the
/// paper's scheme's) 1 pixel instead of the field design's round(2σ), to
/// show the duplicate tracks the design's radius avoids.
pub const NARROW_R_ASSOC: u32 = 1;

/// Options of the nanoruler study.
#[derive(Debug, Clone, Copy)]
pub struct NanorulerOptions {
    /// Seed.
    pub seed: u64,
    /// Simulated acquisition, s.
    pub seconds: f64,
    /// Mean off time of a marker, s.
    pub mean_off_s: f64,
    /// Mean on time (blink), s.
    pub mean_on_s: f64,
}

impl NanorulerOptions {
    /// Defaults (300 s, off Exp(3 s) as `Scene::nanorulers`), or 100 s with `quick`.
    pub fn new(seed: u64, quick: bool) -> NanorulerOptions {
        NanorulerOptions {
            seed,
            seconds: if quick { 100.0 } else { 300.0 },
            mean_off_s: 3.0,
            mean_on_s: 0.030,
        }
    }
}

/// One marker as found by one scheme.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Scheme index into [`SCHEMES`].
    pub scheme: usize,
    /// Ruler.
    pub ruler: usize,
    /// Marker along the axis (0, 1, 2).
    pub marker: usize,
    /// Centroid, nm.
    pub x_nm: f64,
    /// Centroid, nm.
    pub y_nm: f64,
    /// Distance to the nearest true marker, nm.
    pub error_nm: f64,
    /// Localisations in the cluster.
    pub locs: usize,
    /// Per-axis standard deviation about the centroid, nm.
    pub spread_nm: f64,
}

/// What one scheme gave.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SchemeResult {
    /// Localisations before the density filter.
    pub locs: usize,
    /// After it.
    pub kept: usize,
    /// Detections (records or frame candidates).
    pub detections: u32,
    /// Failed fits.
    pub failed: u32,
    /// True blinks with a matched localisation / true blinks.
    pub detection: f64,
    /// Detections without a matched localisation / detections.
    pub false_pos: f64,
    /// RMS error of matched localisations, nm.
    pub rms_nm: Option<f64>,
    /// Matched localisations per detected blink.
    pub locs_per_blink: f64,
    /// Neighbour distances (two per ruler), nm.
    pub distances: Vec<(usize, f64)>,
    /// Wall time (simulation + aggregation + fits), s.
    pub seconds: f64,
    /// The filtered localisations with their ruler.
    pub kept_locs: Vec<(usize, TLoc)>,
}

/// The whole study's result.
#[derive(Debug, Clone)]
pub struct NanorulerResult {
    /// Options used.
    pub opts: NanorulerOptions,
    /// True marker positions per ruler (sorted along the ruler).
    pub rulers: Vec<[Position; 3]>,
    /// True blinks simulated.
    pub blinks: usize,
    /// Per scheme.
    pub schemes: Vec<SchemeResult>,
    /// Every marker found.
    pub markers: Vec<Marker>,
    /// Paired comparisons on the blinks both schemes localised: (scheme a,
    /// scheme b, blinks, RMS of a, RMS of b), nm.
    pub paired: Vec<(usize, usize, usize, f64, f64)>,
    /// Smart aggregation's pipeline (the field design).
    pub smart: PipelineConfig,
    /// The field design it was built from.
    pub design: FieldDesign,
}

impl NanorulerResult {
    /// Median spread of a scheme's markers, nm.
    pub fn median_spread(&self, scheme: usize) -> Option<f64> {
        let v: Vec<f64> = self
            .markers
            .iter()
            .filter(|m| m.scheme == scheme)
            .map(|m| m.spread_nm)
            .collect();
        median(&v)
    }

    /// Median neighbour distance of a scheme, nm.
    pub fn median_distance(&self, scheme: usize) -> Option<f64> {
        let v: Vec<f64> = self.schemes[scheme].distances.iter().map(|d| d.1).collect();
        median(&v)
    }
}

fn ruler_positions(seed: u64) -> Vec<[Position; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(&[seed, key_hash("ruler-angles")]));
    RULER_CENTRES
        .iter()
        .map(|&(fx, fy)| {
            let a = rng.gen::<f64>() * std::f64::consts::PI;
            let (cx, cy) = (fx * FIELD_NM, fy * FIELD_NM);
            let (dx, dy) = (a.cos() * SPACING_NM, a.sin() * SPACING_NM);
            [-1.0, 0.0, 1.0].map(|m| Position {
                x_nm: cx + m * dx,
                y_nm: cy + m * dy,
            })
        })
        .collect()
}

/// Runs the study.
pub fn compute(opts: &NanorulerOptions) -> Result<NanorulerResult, StudyError> {
    let rulers = ruler_positions(opts.seed);
    let positions: Vec<Position> = rulers.iter().flatten().copied().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(&[opts.seed, key_hash("ruler-blinks")]));
    let blinks = switching_blinks(
        &mut rng,
        &positions,
        opts.mean_on_s,
        opts.mean_off_s,
        opts.seconds,
    );
    let truth: Vec<Truth> = blinks
        .iter()
        .map(|b| Truth {
            x_nm: b.position.x_nm,
            y_nm: b.position.y_nm,
            t_on_s: b.t_on_s,
            t_off_s: b.t_off_s.min(opts.seconds),
        })
        .collect();

    // Behind the splitter each camera gets half of the sample's light; the
    // sample is set so that this half is the study's light (50,000
    // photons/s per molecule, 70,000 photons/s/µm² background), the levels
    // the paper inferred from its camera outputs and fed to its simulations.
    let spad = Preset::new(PresetName::Spcimager, 150)?;
    let spad_px = spad.pixel_nm();
    let spad_side = (FIELD_NM / spad_px).round() as u32;
    let (_, design, cfg) = smart_config(&spad, spad_side, None)?;
    let (_, _, cfg_narrow) = smart_config(&spad, spad_side, Some(NARROW_R_ASSOC))?;
    let Camera::Spad(spad_cam) = spad.camera.clone() else {
        unreachable!("SPCIMAGER is a SPAD")
    };
    let mut emccd = Preset::new(PresetName::Emccd, 150)?;
    let em_cam = emccd_experiment(&mut emccd)?;
    let em_px = emccd.pixel_nm();
    let em_side = (FIELD_NM / em_px).round() as u32;
    let seed_spad = derive_seed(&[opts.seed, key_hash("ruler-spad")]);
    let seed_em = derive_seed(&[opts.seed, key_hash("ruler-emccd")]);
    let planes = (opts.seconds / spad_cam.plane_period_s).round() as u64;
    let period = spad_cam.plane_period_s;

    let spad_scene = explicit_scene(&spad, spad_side, spad_side, SOURCE * 0.5, blinks.clone());
    let em_scene = explicit_scene(&emccd, em_side, em_side, SOURCE * 0.5, blinks.clone());
    let (spad_res, em_res) = rayon::join(
        || -> Result<_, StudyError> {
            let t = Instant::now();
            let run = run_spad(
                &spad_cam,
                &spad_scene,
                seed_spad,
                planes,
                &[cfg.clone(), cfg_narrow.clone()],
                Some(640),
            )?;
            let shared = run.simulate_s;
            let a = Instant::now();
            let (smart, _, smart_failed) = fit_records(
                &run.records[0],
                &cfg,
                spad_side,
                spad_px,
                spad.sigma_px(),
                period,
            );
            let (narrow, _, narrow_failed) = fit_records(
                &run.records[1],
                &cfg_narrow,
                spad_side,
                spad_px,
                spad.sigma_px(),
                period,
            );
            // The two pipelines ran on the same planes: half the pipeline time each.
            let smart_s = run.pipeline_s / 2.0 + a.elapsed().as_secs_f64() / 2.0;
            let a = Instant::now();
            let fixed = localize_frames(
                &run.frames,
                spad_side,
                spad_px,
                spad.sigma_px(),
                NoiseModel::Poisson,
                640.0 * period,
                640.0 * period,
                false,
            )?;
            let fixed_s = a.elapsed().as_secs_f64();
            let _ = t;
            Ok((
                (smart, run.records[0].len(), smart_failed, shared + smart_s),
                (
                    narrow,
                    run.records[1].len(),
                    narrow_failed,
                    shared + smart_s,
                ),
                (fixed, shared + fixed_s),
            ))
        },
        || -> Result<_, StudyError> {
            let n = (opts.seconds / em_cam.frame_period_s).floor() as usize;
            let (frames, sim_s) = run_emccd(&em_cam, &em_scene, seed_em, n)?;
            let a = Instant::now();
            let l = localize_frames(
                &frames,
                em_side,
                em_px,
                emccd.sigma_px(),
                NoiseModel::Emccd,
                em_cam.frame_period_s,
                em_cam.exposure_s,
                false,
            )?;
            Ok((l, sim_s + a.elapsed().as_secs_f64()))
        },
    );
    let ((smart, narrow, fixed), em) = (spad_res?, em_res?);
    let ((fl, fc, ff), fixed_s) = fixed;
    let ((el, ec, ef), em_s) = em;
    let inputs: [(Vec<TLoc>, usize, usize, f64); 4] =
        [(el, ec, ef, em_s), (fl, fc, ff, fixed_s), smart, narrow];
    let mut schemes = Vec::new();
    let mut markers = Vec::new();
    let mut per_blink = Vec::new();
    for (s, (locs, detections, failed, seconds)) in inputs.into_iter().enumerate() {
        let as_loc: Vec<Loc> = locs.iter().map(TLoc::loc).collect();
        let o = outcome(&truth, &as_loc, MATCH_NM, detections as u32, failed as u32);
        per_blink.push(o.blinks.clone());
        let detected = o.blinks.iter().filter(|b| b.matches > 0).count();
        let matches: u32 = o.blinks.iter().map(|b| b.matches).sum();
        let sse: f64 = o.blinks.iter().map(|b| b.sse_nm2).sum();
        let kept = density_filter(&locs, DENSITY_RADIUS_NM, DENSITY_MIN);
        let mut res = SchemeResult {
            locs: locs.len(),
            kept: kept.len(),
            detections: detections as u32,
            failed: failed as u32,
            detection: detected as f64 / truth.len().max(1) as f64,
            false_pos: o.false_pos as f64 / (detections.max(1)) as f64,
            rms_nm: (matches > 0).then(|| (sse / matches as f64).sqrt()),
            locs_per_blink: matches as f64 / detected.max(1) as f64,
            seconds,
            ..Default::default()
        };
        for (r, ruler) in rulers.iter().enumerate() {
            let c = ruler[1];
            let mine: Vec<TLoc> = kept
                .iter()
                .filter(|l| {
                    (l.x_nm - c.x_nm).powi(2) + (l.y_nm - c.y_nm).powi(2)
                        <= RULER_RADIUS_NM * RULER_RADIUS_NM
                })
                .copied()
                .collect();
            res.kept_locs.extend(mine.iter().map(|l| (r, *l)));
            if mine.len() < 6 {
                continue;
            }
            let pts: Vec<(f64, f64)> = mine.iter().map(|l| (l.x_nm, l.y_nm)).collect();
            let ((ux, uy), (mx, my)) = principal_axis(&pts);
            let proj: Vec<f64> = pts
                .iter()
                .map(|p| (p.0 - mx) * ux + (p.1 - my) * uy)
                .collect();
            let a = kmeans3(&proj);
            let mut comps = gaussian_mixture(&pts, &a);
            comps.sort_by(|p, q| {
                let along = |c: &Component| (c.x - mx) * ux + (c.y - my) * uy;
                along(p).total_cmp(&along(q))
            });
            let mut cents = Vec::new();
            for (k, c) in comps.into_iter().enumerate() {
                if c.weight * (pts.len() as f64) < 2.0 {
                    continue;
                }
                let err = ruler
                    .iter()
                    .map(|t| ((t.x_nm - c.x).powi(2) + (t.y_nm - c.y).powi(2)).sqrt())
                    .fold(f64::INFINITY, f64::min);
                markers.push(Marker {
                    scheme: s,
                    ruler: r,
                    marker: k,
                    x_nm: c.x,
                    y_nm: c.y,
                    error_nm: err,
                    locs: (c.weight * pts.len() as f64).round() as usize,
                    spread_nm: c.sigma,
                });
                cents.push((c.x, c.y));
            }
            for w in cents.windows(2) {
                let d = ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt();
                res.distances.push((r, d));
            }
        }
        schemes.push(res);
    }
    let mut paired = Vec::new();
    for (a, b) in [(2, 1), (2, 0), (3, 1), (3, 0), (1, 0)] {
        let (mut sa, mut na, mut sb, mut nb, mut k) = (0.0, 0u32, 0.0, 0u32, 0usize);
        for (x, y) in per_blink[a].iter().zip(&per_blink[b]) {
            if x.matches > 0 && y.matches > 0 {
                sa += x.sse_nm2;
                na += x.matches;
                sb += y.sse_nm2;
                nb += y.matches;
                k += 1;
            }
        }
        if k > 0 {
            paired.push((a, b, k, (sa / na as f64).sqrt(), (sb / nb as f64).sqrt()));
        }
    }
    Ok(NanorulerResult {
        paired,
        opts: *opts,
        rulers,
        blinks: blinks.len(),
        schemes,
        markers,
        smart: cfg,
        design,
    })
}
