//! Machinery shared by the experiment studies: scenes of explicit blinks,
//! SPAD recordings through the real pipeline and packet path, EMCCD frames,
//! record and frame localisation, summary statistics and plotting helpers.

use crate::acquisition::{field_design_config, record_planes, through_packets};
use crate::error::StudyError;
use crate::frames::{fit_options, FrameFitter, FrameMaps};
use crate::item::{record_maps, roi_view};
use crate::matching::Loc;
use plotters::prelude::*;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use smartagg_localize::{fit_roi, Estimator, NoiseModel};
use smartagg_model::config::PipelineConfig;
use smartagg_model::fast_engine::fast_pipeline;
use smartagg_model::field_design::FieldDesign;
use smartagg_model::params::{Camera, EmccdCamera, Preset, SpadCamera};
use smartagg_model::record::{BlinkRecord, Record};
use smartagg_model::stats::{self, Detection, DetectionInputs};
use smartagg_scene::{Blinking, EmccdSimulator, ExplicitBlink, Position, Scene, SpadSimulator};
use std::path::Path;
use std::time::Instant;

/// Localisations closer than this in consecutive frames are merged, nm.
pub const MERGE_NM: f64 = 40.0;

/// A localisation with the time span of the data it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TLoc {
    /// x, nm from the field's left edge.
    pub x_nm: f64,
    /// y, nm from the field's top edge.
    pub y_nm: f64,
    /// Start of the data, s.
    pub t0_s: f64,
    /// End of the data, s (exclusive).
    pub t1_s: f64,
    /// Fitted photons.
    pub photons: f64,
    /// Frames merged into it (1 for a record or an unmerged frame).
    pub frames: u32,
}

impl TLoc {
    /// The localisation as the matcher sees it.
    pub fn loc(&self) -> Loc {
        Loc {
            x_nm: self.x_nm,
            y_nm: self.y_nm,
            t0_s: self.t0_s,
            t1_s: self.t1_s,
            photons: self.photons,
        }
    }
}

/// A scene of exactly `blinks` for `preset` on a `w × h` field, with the
/// preset's light scaled by `light_factor` (0.5 behind a 50/50 splitter).
pub fn explicit_scene(
    preset: &Preset,
    w: u32,
    h: u32,
    light_factor: f64,
    blinks: Vec<ExplicitBlink>,
) -> Scene {
    let mut s = Scene::study(preset, 0.05).with_field(w, h);
    s.light.flux_hz *= light_factor;
    s.light.background_per_um2_hz *= light_factor;
    s.margin_px = 0.0;
    s.blinking = Blinking::Explicit(blinks);
    s
}

/// Independent on/off switching of each emitter of `positions` over
/// `[0, end_s)`: exponential on-times of mean `mean_on_s`, exponential
/// off-times of mean `mean_off_s`, each emitter starting part-way through
/// an off-time (uniform), so that every marker blinks from the start.
pub fn switching_blinks(
    rng: &mut ChaCha8Rng,
    positions: &[Position],
    mean_on_s: f64,
    mean_off_s: f64,
    end_s: f64,
) -> Vec<ExplicitBlink> {
    let exp = |rng: &mut ChaCha8Rng, mean: f64| -mean * (1.0 - rng.gen::<f64>()).ln();
    let mut out = Vec::new();
    for (e, p) in positions.iter().enumerate() {
        let mut t = rng.gen::<f64>() * exp(rng, mean_off_s);
        while t < end_s {
            let d = exp(rng, mean_on_s);
            out.push(ExplicitBlink {
                emitter: e as u64,
                position: *p,
                t_on_s: t,
                t_off_s: t + d,
                flux_factor: 1.0,
            });
            t += d + exp(rng, mean_off_s);
        }
    }
    out.sort_by(|a, b| a.t_on_s.total_cmp(&b.t_on_s));
    out
}

/// The paper's statistics for the light of `preset` and the smart scheme
/// on a `field × field` sensor: the field design, as `smartagg aggregate`
/// defaults to ([`crate::acquisition::field_design_config`]), with its association
/// radius unless `r_assoc` is given.
pub fn smart_config(
    preset: &Preset,
    field: u32,
    r_assoc: Option<u32>,
) -> Result<(Detection, FieldDesign, PipelineConfig), StudyError> {
    let det = stats::derive(&DetectionInputs::from_preset(preset, None)?)?;
    let (design, mut cfg) = field_design_config(&det, field, field, preset.period_s())?;
    if let Some(r) = r_assoc {
        cfg.r_assoc = r;
        cfg.validate()?;
    }
    Ok((det, design, cfg))
}

/// What a SPAD recording gave.
#[derive(Debug, Clone, Default)]
pub struct SpadRun {
    /// Per pipeline: its blink records, decoded from its packet stream.
    pub records: Vec<Vec<BlinkRecord>>,
    /// Fixed frames (sums of `fixed_planes` bit-planes), raster order.
    pub frames: Vec<Vec<f64>>,
    /// Wall time simulating, s.
    pub simulate_s: f64,
    /// Wall time in pipelines and the packet path, s.
    pub pipeline_s: f64,
    /// Planes simulated.
    pub planes: u64,
}

/// Simulates `planes` bit-planes of `scene`, runs every pipeline of `cfgs`
/// on them (fast engine; records through the packetiser and decoder) and
/// sums fixed frames of `fixed_planes` planes when given.
pub fn run_spad(
    camera: &SpadCamera,
    scene: &Scene,
    seed: u64,
    planes: u64,
    cfgs: &[PipelineConfig],
    fixed_planes: Option<u64>,
) -> Result<SpadRun, StudyError> {
    let t0 = Instant::now();
    let mut sim = SpadSimulator::new(camera, scene, seed)?;
    let mut out = SpadRun {
        simulate_s: t0.elapsed().as_secs_f64(),
        planes,
        ..Default::default()
    };
    let n_px = (scene.width * scene.height) as usize;
    let mut pipes = cfgs
        .iter()
        .map(|c| fast_pipeline(c.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut streams: Vec<Vec<Record>> = pipes.iter().map(|p| vec![p.start_record()]).collect();
    let mut acc = vec![0f64; n_px];
    for t in 0..planes {
        let a = Instant::now();
        let plane = sim.next_plane();
        let b = Instant::now();
        out.simulate_s += (b - a).as_secs_f64();
        for (p, s) in pipes.iter_mut().zip(streams.iter_mut()) {
            s.extend(p.push_plane(&plane)?);
        }
        out.pipeline_s += b.elapsed().as_secs_f64();
        if let Some(fp) = fixed_planes {
            for (wi, &word) in plane.words().iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let i = wi * 64 + bits.trailing_zeros() as usize;
                    if i < n_px {
                        acc[i] += 1.0;
                    }
                    bits &= bits - 1;
                }
            }
            if (t + 1) % fp == 0 {
                out.frames
                    .push(std::mem::replace(&mut acc, vec![0f64; n_px]));
            }
        }
    }
    let a = Instant::now();
    for (mut p, mut s) in pipes.into_iter().zip(streams) {
        s.extend(p.finish());
        out.records.push(through_packets(&s)?.0);
    }
    out.pipeline_s += a.elapsed().as_secs_f64();
    Ok(out)
}

/// EMCCD frames of `scene` in photo-electrons (the camera's calibration
/// undone as a user would), with the wall time spent.
pub fn run_emccd(
    camera: &EmccdCamera,
    scene: &Scene,
    seed: u64,
    frames: usize,
) -> Result<(Vec<Vec<f64>>, f64), StudyError> {
    let t0 = Instant::now();
    let mut sim = EmccdSimulator::new(camera, scene, seed)?;
    let k = camera.e_per_adu / camera.em_gain;
    let out = (0..frames)
        .map(|_| {
            sim.next_frame()
                .adu
                .iter()
                .map(|&a| (a as f64 - camera.offset_adu) * k)
                .collect()
        })
        .collect();
    Ok((out, t0.elapsed().as_secs_f64()))
}

/// Fits every record's ROI (Poisson MLE, σ fitted from the optics' σ) of a
/// pipeline configured with `cfg`; failed fits are dropped and counted. A
/// localisation spans the planes its record summed
/// ([`crate::acquisition::record_planes`]).
/// Returns (localisations, record index of each, failed fits).
pub fn fit_records(
    records: &[BlinkRecord],
    cfg: &PipelineConfig,
    field: u32,
    pixel_nm: f64,
    sigma_px: f64,
    period_s: f64,
) -> (Vec<TLoc>, Vec<usize>, usize) {
    let opts = fit_options(sigma_px, true, NoiseModel::Poisson);
    let (mut locs, mut idx, mut failed) = (Vec::new(), Vec::new(), 0);
    for (i, rec) in records.iter().enumerate() {
        let maps = record_maps(rec, field);
        let data: Vec<f64> = rec.counts.iter().map(|&c| c as f64).collect();
        let f = fit_roi(Estimator::Mle, &roi_view(&data, maps.as_ref()), &opts);
        if !f.status.is_ok() {
            failed += 1;
            continue;
        }
        let planes = record_planes(rec, cfg);
        locs.push(TLoc {
            x_nm: (rec.roi_x0() as f64 + f.x) * pixel_nm,
            y_nm: (rec.roi_y0() as f64 + f.y) * pixel_nm,
            t0_s: planes.start as f64 * period_s,
            t1_s: planes.end as f64 * period_s,
            photons: f.photons,
            frames: 1,
        });
        idx.push(i);
    }
    (locs, idx, failed)
}

/// Localises frames (ThunderSTORM defaults, Poisson or EMCCD MLE, σ
/// fitted); frame `k` exposes `[k·period, k·period + exposure)`. With
/// `merge`, localisations of consecutive frames within 40 nm are joined
/// (their span covers all their frames). Returns (localisations,
/// candidates, failed fits).
#[allow(clippy::too_many_arguments)]
pub fn localize_frames(
    frames: &[Vec<f64>],
    side: u32,
    pixel_nm: f64,
    sigma_px: f64,
    noise: NoiseModel,
    period_s: f64,
    exposure_s: f64,
    merge: bool,
) -> Result<(Vec<TLoc>, usize, usize), StudyError> {
    let fitter = FrameFitter::new(fit_options(sigma_px, true, noise));
    let mut all = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        all.extend(fitter.localize(
            f,
            side as usize,
            side as usize,
            &FrameMaps::default(),
            pixel_nm,
            k as u64 + 1,
        )?);
    }
    let candidates = all.len();
    let failed = all.iter().filter(|l| !l.status.is_ok()).count();
    let all = if merge {
        smartagg_localize::merge::merge_consecutive(&all, MERGE_NM, 0).0
    } else {
        all
    };
    let locs = all
        .iter()
        .filter(|l| l.status.is_ok())
        .map(|l| {
            let d = l.detections.max(1) as u64;
            let first = l.frame - 1;
            TLoc {
                x_nm: l.x_nm,
                y_nm: l.y_nm,
                t0_s: first as f64 * period_s,
                t1_s: (first + d - 1) as f64 * period_s + exposure_s,
                photons: l.intensity,
                frames: d as u32,
            }
        })
        .collect();
    Ok((locs, candidates, failed))
}

/// Median of `v` (NaN-free), `None` if empty.
pub fn median(v: &[f64]) -> Option<f64> {
    quantile(v, 0.5)
}

/// Quantile `q` of `v` (linear interpolation), `None` if empty.
pub fn quantile(v: &[f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    Some(crate::stats::percentile(&s, q))
}

/// Wilson 95 % interval of a proportion `k / n`.
pub fn wilson(k: f64, n: f64) -> (f64, f64) {
    if n <= 0.0 {
        return (0.0, 1.0);
    }
    let z = 1.959_964f64;
    let p = k / n;
    let d = 1.0 + z * z / n;
    let c = (p + z * z / (2.0 * n)) / d;
    let h = z * ((p * (1.0 - p) / n + z * z / (4.0 * n * n)).max(0.0)).sqrt() / d;
    ((c - h).max(0.0), (c + h).min(1.0))
}

/// Writes a text file atomically (beside the target, then renamed into
/// place, so a failure never leaves a half-written result), naming it in the
/// error.
pub fn write_text(path: &Path, text: &str) -> Result<(), StudyError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    // 0666 less the umask, as `fs::write` would (tempfile's default is 0600).
    #[cfg(unix)]
    builder
        .permissions(<std::fs::Permissions as std::os::unix::fs::PermissionsExt>::from_mode(0o666));
    let mut tmp = builder
        .tempfile_in(dir)
        .map_err(|e| StudyError::io(path, e))?;
    std::io::Write::write_all(&mut tmp, text.as_bytes()).map_err(|e| StudyError::io(path, e))?;
    tmp.persist(path)
        .map_err(|e| StudyError::io(path, e.error))?;
    Ok(())
}

/// A plotting error on `path`.
pub fn plot_err(path: &Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Plot {
        path: path.to_path_buf(),
        why: e.to_string(),
    }
}

/// Colour of series `i`.
pub fn colour(i: usize) -> RGBColor {
    const C: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
    ];
    C[i % C.len()]
}

/// The EMCCD preset with the paper's experimental timing (64 ms frames,
/// 34 ms exposure: 30 ms dead time).
pub fn emccd_experiment(preset: &mut Preset) -> Result<EmccdCamera, StudyError> {
    match &mut preset.camera {
        Camera::Emccd(c) => {
            c.frame_period_s = 0.064;
            c.exposure_s = 0.034;
            c.validate()?;
            Ok(c.clone())
        }
        _ => Err(StudyError::Option {
            name: "camera",
            why: "the EMCCD preset is not an EMCCD".into(),
        }),
    }
}
