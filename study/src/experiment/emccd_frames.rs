//! `emccd-frames`: the simulated EMCCD curve of the paper's Fig. 4 (right):
//! RMS localisation error against blink duration for 64 ms frames with
//! 34 ms exposure (30 ms dead time), with and without merging localisations
//! of consecutive frames within 40 nm.
//!
//! Scene as the study's (`Scene::study`): one molecule on at a time at a
//! random position of a 16×16 EMCCD field (106.7 nm pixels at 150×), every
//! blink of exactly the point's duration, gaps of 10 ms + Exp(40 ms),
//! 50,000 photons/s, 70,000 photons/s/µm². A localisation matches a blink
//! within 53.3 nm whose on-time overlaps the frame's *exposure* (merged:
//! from the first frame's start to the last frame's exposure end).

use super::common::*;
use crate::acquisition::Setup;
use crate::error::StudyError;
use crate::matching::{outcome, BlinkOutcome, Loc, Truth};
use crate::stats::{resample_indices, rms_estimate, Estimate};
use crate::timeline::{derive_seed, key_hash, place, Timeline};
use plotters::prelude::*;
use rayon::prelude::*;
use smartagg_localize::NoiseModel;
use smartagg_model::params::PresetName;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Schemes of the study.
pub const SCHEMES: [&str; 2] = ["EMCCD 64 ms frames", "EMCCD merged (40 nm)"];

/// One (duration, scheme) point.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePoint {
    /// Blink duration, ms.
    pub blink_ms: f64,
    /// Scheme index into [`SCHEMES`].
    pub scheme: usize,
    /// RMS error, nm, with its bootstrap interval.
    pub rms: Estimate,
    /// Blinks simulated.
    pub blinks: usize,
    /// Blinks with a matched localisation.
    pub detected: usize,
    /// Matched localisations.
    pub matches: u64,
    /// Detections (frame candidates; merged: chains).
    pub detections: u64,
    /// Detections without a match.
    pub false_pos: u64,
    /// Wall time of the point (simulation and both schemes), s.
    pub seconds: f64,
}

/// The study's result.
#[derive(Debug, Clone)]
pub struct EmccdFramesResult {
    /// Every point.
    pub points: Vec<FramePoint>,
    /// Blinks per point.
    pub blinks: usize,
}

impl EmccdFramesResult {
    /// The point of `scheme` at `blink_ms`.
    pub fn get(&self, blink_ms: f64, scheme: usize) -> Option<&FramePoint> {
        self.points
            .iter()
            .find(|p| p.scheme == scheme && (p.blink_ms - blink_ms).abs() < 1e-9)
    }
}

/// Durations of the study, ms.
pub fn durations(quick: bool) -> Vec<f64> {
    if quick {
        vec![20.0, 50.0, 100.0]
    } else {
        (1..=10).map(|k| 10.0 * k as f64).collect()
    }
}

/// Runs the study.
pub fn compute(
    seed: u64,
    quick: bool,
    blinks: Option<u32>,
) -> Result<EmccdFramesResult, StudyError> {
    let n = blinks.unwrap_or(if quick { 300 } else { 500 }) as usize;
    let mut setup = Setup::new(PresetName::Emccd, 150)?;
    let cam = emccd_experiment(&mut setup.preset)?;
    let pts: Vec<Vec<FramePoint>> = durations(quick)
        .par_iter()
        .map(|&ms| -> Result<Vec<FramePoint>, StudyError> {
            let t0 = Instant::now();
            let s = derive_seed(&[seed, key_hash("emccd-frames"), (ms * 1000.0) as u64]);
            let tl = Timeline::one_at_a_time(s, n, ms / 1000.0);
            let blinks = place(&tl.blinks, setup.field_nm(), setup.margin_nm);
            let truth: Vec<Truth> = blinks.iter().map(Truth::from).collect();
            let explicit = blinks
                .iter()
                .enumerate()
                .map(|(i, b)| smartagg_scene::ExplicitBlink {
                    emitter: i as u64,
                    position: smartagg_scene::Position {
                        x_nm: b.x_nm,
                        y_nm: b.y_nm,
                    },
                    t_on_s: b.t_on_s,
                    t_off_s: b.t_off_s,
                    flux_factor: 1.0,
                })
                .collect();
            let scene = explicit_scene(&setup.preset, setup.field, setup.field, 1.0, explicit);
            let frames_n = (tl.end_s / cam.frame_period_s).ceil() as usize;
            let (frames, _) = run_emccd(&cam, &scene, derive_seed(&[s, 1]), frames_n)?;
            let idx = resample_indices(s, n, crate::spec::DEFAULT_BOOTSTRAP as usize);
            let mut out = Vec::new();
            for (k, merge) in [false, true].into_iter().enumerate() {
                let (locs, candidates, failed) = localize_frames(
                    &frames,
                    setup.field,
                    setup.pixel_nm,
                    setup.sigma_px,
                    NoiseModel::Emccd,
                    cam.frame_period_s,
                    cam.exposure_s,
                    merge,
                )?;
                let loc: Vec<Loc> = locs.iter().map(TLoc::loc).collect();
                // Merged: a chain is one detection; failed fits stay as they are.
                let detections = if merge {
                    locs.len() + failed
                } else {
                    candidates
                };
                let o = outcome(&truth, &loc, 53.3, detections as u32, failed as u32);
                let b: &[BlinkOutcome] = &o.blinks;
                out.push(FramePoint {
                    blink_ms: ms,
                    scheme: k,
                    rms: rms_estimate(b, &idx),
                    blinks: n,
                    detected: b.iter().filter(|x| x.matches > 0).count(),
                    matches: b.iter().map(|x| x.matches as u64).sum(),
                    detections: o.detections as u64,
                    false_pos: o.false_pos as u64,
                    seconds: 0.0,
                });
            }
            let secs = t0.elapsed().as_secs_f64();
            for p in &mut out {
                p.seconds = secs;
            }
            Ok(out)
        })
        .collect::<Result<_, _>>()?;
    Ok(EmccdFramesResult {
        points: pts.into_iter().flatten().collect(),
        blinks: n,
    })
}

fn f1(v: Option<f64>) -> String {
    v.map_or("—".into(), |x| format!("{x:.1}"))
}

/// Writes points.csv, emccd-frames.png and summary.md.
pub fn write(dir: &Path, r: &EmccdFramesResult) -> Result<(Vec<PathBuf>, Vec<String>), StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io(dir, e))?;
    let (mut files, mut warnings) = (Vec::new(), Vec::new());
    let mut csv = String::from(
        "blink_ms,scheme,rms_nm,rms_lo_nm,rms_hi_nm,blinks,detected,matches,detections,false_pos,seconds\n",
    );
    for p in &r.points {
        let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.3}"));
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{:.2}",
            p.blink_ms,
            SCHEMES[p.scheme],
            o(p.rms.value),
            o(p.rms.lo),
            o(p.rms.hi),
            p.blinks,
            p.detected,
            p.matches,
            p.detections,
            p.false_pos,
            p.seconds
        );
    }
    let path = dir.join("points.csv");
    write_text(&path, &csv)?;
    files.push(path);
    let png = dir.join("emccd-frames.png");
    match plot(&png, r) {
        Ok(()) => files.push(png),
        Err(e) => warnings.push(e.to_string()),
    }
    let mut m = String::new();
    let _ = writeln!(m, "# Study `emccd-frames`: EMCCD error against blink duration, 64 ms frames with 30 ms dead time (paper Fig. 4 right)\n\n![emccd-frames](emccd-frames.png)\n\n## Set-up\n");
    let _ = writeln!(m, "- **Scene**: the study's (docs/DESIGN.md §4): one molecule on at a time at a random position of a 16×16 EMCCD field (106.7 nm pixels at 150×, 3σ margins), every blink of exactly the point's duration, gaps of 10 ms + Exp(40 ms); 50,000 photons/s, 70,000 photons/s/µm²; {} blinks per point.", r.blinks);
    let _ = writeln!(m, "- **EMCCD**: the preset (iXon-class) with the paper's experimental timing: 64 ms frame period, 34 ms exposure (30 ms read-out dead time in which light is lost). ThunderSTORM detection (wavelet, 1.5 × std F1), 9×9 EMCCD Poisson MLE (F² = 2), σ fitted. **Merged**: localisations of consecutive frames within 40 nm joined (localize crate's merge, intensity-weighted).");
    let _ = writeln!(m, "- **Truth matching**: a localisation matches a blink within 53.3 nm whose on-time overlaps the frame's exposure (merged: from the first frame's start to the last frame's exposure end); nearest wins. Every match counts in the RMS. FP = detections (candidates; merged: chains and failed fits) without a match / detections. 95 % bootstrap intervals over blinks.\n");
    let _ = writeln!(m, "## Results\n\n| blink ms | scheme | RMS nm [95 % CI] | detection | FP | locs/blink | time s |\n|---|---|---|---|---|---|---|");
    for p in &r.points {
        let _ = writeln!(
            m,
            "| {} | {} | {} [{}, {}] | {:.1} % | {:.1} % | {:.2} | {:.1} |",
            p.blink_ms,
            SCHEMES[p.scheme],
            f1(p.rms.value),
            f1(p.rms.lo),
            f1(p.rms.hi),
            100.0 * p.detected as f64 / p.blinks.max(1) as f64,
            100.0 * p.false_pos as f64 / p.detections.max(1) as f64,
            p.matches as f64 / p.detected.max(1) as f64,
            p.seconds
        );
    }
    let _ = writeln!(m, "\nTime: wall seconds for the point (simulation, both schemes' fits; points run in parallel).\n\n## Where this differs from the paper, and why\n\n{}", super::notes::with_source("emccd-frames", super::notes::EMCCD_FRAMES));
    for w in &warnings {
        let _ = writeln!(m, "\n**Warning**: {w}");
    }
    let path = dir.join("summary.md");
    write_text(&path, &m)?;
    files.push(path);
    Ok((files, warnings))
}

fn plot(path: &Path, r: &EmccdFramesResult) -> Result<(), StudyError> {
    let root = BitMapBackend::new(path, (1000, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let xmax = r.points.iter().map(|p| p.blink_ms).fold(0.0, f64::max) + 5.0;
    let ymax = r
        .points
        .iter()
        .filter_map(|p| p.rms.hi.or(p.rms.value))
        .fold(0.0, f64::max)
        .max(1.0)
        * 1.15;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "EMCCD, 64 ms frames with 30 ms dead time (Fig. 4 right, simulated)",
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..xmax, 0.0..ymax)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("blink duration (ms)")
        .y_desc("RMS localisation error (nm)")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (s, name) in SCHEMES.iter().enumerate() {
        let col = colour(s);
        let pts: Vec<&FramePoint> = r.points.iter().filter(|p| p.scheme == s).collect();
        chart
            .draw_series(LineSeries::new(
                pts.iter()
                    .filter_map(|p| p.rms.value.map(|v| (p.blink_ms, v))),
                col.stroke_width(2),
            ))
            .map_err(|e| plot_err(path, e))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
        for p in &pts {
            if let (Some(lo), Some(hi)) = (p.rms.lo, p.rms.hi) {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(p.blink_ms, lo), (p.blink_ms, hi)],
                        col.stroke_width(1),
                    )))
                    .map_err(|e| plot_err(path, e))?;
            }
            if let Some(v) = p.rms.value {
                chart
                    .draw_series(std::iter::once(Circle::new(
                        (p.blink_ms, v),
                        4,
                        col.filled(),
                    )))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}
