//! `field-detection`: detection on the **whole sensor** — false blinks per
//! second on background alone, recall, records per blink, planes summed per
//! record and RMS error against blink duration, and candidates dropped at
//! SMLM density — for four schemes side by side, with the design's
//! predicted false-blink rate and recall beside the measured ones:
//! * **`field`**: the field design as `smartagg aggregate` defaults to
//!   (`model::field_design`): open and hold thresholds T_open, T_hold for a
//!   false-blink budget, its r_assoc and L_min, and `end_trim = ⌊N/2⌋` — a
//!   blink sums the bit-planes `[t_cross − N, t_drop − ⌊N/2⌋]`, to its
//!   estimated end `t_e`;
//! * **`field-v2`**: the same detection summed to `t_drop` (`end_trim = 0`),
//!   the default before packet format v3: the same tracks, `⌊N/2⌋` more
//!   planes (of background alone) in each dropped record;
//! * **`paper`**: the paper's literal scheme (one 3σ threshold,
//!   `L_min = 1`, `r_assoc = 1`, summed to `t_drop`);
//! * **`paper-lmin`**: the paper's threshold with the field's `L_min` from
//!   the false-alarm bound (what `smartagg params` suggested before the
//!   field design), summed to `t_drop`.
//!
//! Three recordings per camera, the same bit-planes for every scheme:
//! * **background**: no molecule, the study's light, the whole sensor;
//! * **durations**: one molecule on at a time at a random sub-pixel position
//!   (at least 12 pixels from the edges), blinks of 5–100 ms separated by
//!   `N·τ + 30 ms` of background (no two blinks share a window);
//! * **density**: the SMLM scene of `smartagg simulate --scene random`
//!   (50 emitters/µm², 30 ms mean on-time, 30 s mean off-time).
//!
//! Records are localised (Poisson MLE, σ fitted) and matched to the truth
//! by the studies' rule (within 53.3 nm, the planes the record summed —
//! `acquisition::record_planes` with its scheme's N and end_trim — overlapping the
//! blink's on-time).

use super::common::*;
use crate::acquisition::{field_design_config, paper_config, record_planes};
use crate::error::StudyError;
use crate::matching::{assign, outcome, Loc, Truth};
use crate::spec::DEFAULT_MATCH_RADIUS_NM;
use crate::timeline::{derive_seed, key_hash};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use smartagg_model::config::PipelineConfig;
use smartagg_model::false_alarm::l_min_for_target;
use smartagg_model::fast_engine::fast_pipeline;
use smartagg_model::field_design::FieldDesign;
use smartagg_model::params::{Camera, Preset, PresetName, SpadCamera};
use smartagg_model::record::{flags, BlinkRecord, Record};
use smartagg_model::stats::{self, Detection, DetectionInputs};
use smartagg_scene::{ExplicitBlink, Position, Scene, SpadSimulator};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Blink durations, ms.
pub const DURATIONS_MS: [f64; 8] = [5.0, 10.0, 15.0, 20.0, 30.0, 50.0, 70.0, 100.0];
/// Molecules are kept this far from the sensor's edges, pixels.
pub const EDGE_PX: f64 = 12.0;
/// A track whose anchor is within this many pixels (Chebyshev) of a blink's
/// true position, and whose summed planes overlap it, detected that blink.
pub const TRACK_PX: f64 = 3.0;

/// One scheme compared.
#[derive(Debug, Clone)]
pub struct SchemeSpec {
    /// Short id (CSV).
    pub id: &'static str,
    /// What it is.
    pub label: String,
    /// Its pipeline.
    pub cfg: PipelineConfig,
}

/// The schemes of a camera on its whole sensor: the field design as
/// `smartagg aggregate` defaults to (`field`), the same summed to `t_drop`
/// (`field-v2`), the paper's (`paper`), and the paper's threshold with the
/// field's L_min (`paper-lmin`).
pub fn schemes(
    preset: &Preset,
    det: &Detection,
    width: u32,
    height: u32,
) -> Result<(FieldDesign, Vec<SchemeSpec>), StudyError> {
    let rate = 1.0 / preset.period_s();
    let (design, field) = field_design_config(det, width, height, preset.period_s())?;
    let base = paper_config(det, width, height, preset.period_s())?;
    let field_v2 = PipelineConfig {
        end_trim: 0,
        ..field.clone()
    };
    let l = l_min_for_target(
        &det.kernel(),
        det.n_window,
        det.p_off,
        det.threshold_int,
        width as u64 * height as u64,
        rate,
        1.0,
    )
    .map_err(|e| StudyError::Option {
        name: "l-min",
        why: e.to_string(),
    })?;
    let mut lmin = base.clone();
    lmin.l_min = l;
    lmin.l_max = lmin.l_max.max(l);
    for c in [&field, &field_v2, &base, &lmin] {
        c.validate()?;
    }
    Ok((
        design.clone(),
        vec![
            SchemeSpec {
                id: "field",
                label: format!(
                    "field design, the default of `smartagg aggregate`: T_open {} ({:.1} sd), T_hold {} ({:.1} sd), r_assoc {}, L_min {}, end_trim {} (a blink sums [t_cross − N, t_drop − {}], to its estimated end)",
                    design.threshold_open,
                    design.open_sigmas,
                    design.threshold_hold,
                    design.hold_sigmas,
                    design.r_assoc,
                    design.l_min,
                    design.end_trim,
                    design.end_trim
                ),
                cfg: field,
            },
            SchemeSpec {
                id: "field-v2",
                label: "field design summed to t_drop (end_trim 0), the default before packet format v3: the same detection, ⌊N/2⌋ more planes per dropped record".into(),
                cfg: field_v2,
            },
            SchemeSpec {
                id: "paper",
                label: format!(
                    "paper: one threshold T {} ({:.1} sd), r_assoc 1, L_min 1, end_trim 0 (sum to t_drop)",
                    det.threshold_int, design.hold_sigmas
                ),
                cfg: base,
            },
            SchemeSpec {
                id: "paper-lmin",
                label: format!("paper's T with the field's L_min = {l} (1 false blink/s bound), end_trim 0"),
                cfg: lmin,
            },
        ],
    ))
}

/// What one scheme made of one recording.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tally {
    /// Blink records (a CUT blink's CONTINUATION segments not counted).
    pub records: u64,
    /// Candidates dropped for want of a free slot.
    pub dropped: u64,
    /// Planes.
    pub planes: u64,
}

/// One point of the duration sweep for one scheme.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DurationPoint {
    /// Blink duration, ms.
    pub duration_ms: f64,
    /// Scheme id.
    pub scheme: &'static str,
    /// Blinks.
    pub blinks: u32,
    /// Blinks with at least one matched localisation.
    pub detected: u32,
    /// Blinks with a track opened near them (anchor within [`TRACK_PX`] of
    /// the true position, summed planes overlapping the blink), whatever
    /// its localisation: the detection alone.
    pub tracked: u32,
    /// Matched localisations.
    pub matched: u32,
    /// Σ planes summed (`planes_summed`, as the pipeline reports it) over
    /// the records of the matched localisations.
    pub matched_planes: u64,
    /// Records that matched no blink.
    pub false_records: u32,
    /// Σ squared error of the matches, nm².
    pub sse_nm2: f64,
    /// Predicted recall (field design only).
    pub predicted_recall: Option<f64>,
    /// Candidates dropped.
    pub dropped: u64,
}

impl DurationPoint {
    /// Detected / blinks.
    pub fn recall(&self) -> f64 {
        self.detected as f64 / self.blinks.max(1) as f64
    }
    /// Tracked / blinks.
    pub fn track_recall(&self) -> f64 {
        self.tracked as f64 / self.blinks.max(1) as f64
    }
    /// Matched localisations per detected blink.
    pub fn records_per_blink(&self) -> Option<f64> {
        (self.detected > 0).then(|| self.matched as f64 / self.detected as f64)
    }
    /// Mean planes summed per matched record.
    pub fn planes_per_match(&self) -> Option<f64> {
        (self.matched > 0).then(|| self.matched_planes as f64 / self.matched as f64)
    }
    /// RMS error of the matches, nm.
    pub fn rms_nm(&self) -> Option<f64> {
        (self.matched > 0).then(|| (self.sse_nm2 / self.matched as f64).sqrt())
    }
}

/// The study of one camera.
#[derive(Debug, Clone)]
pub struct CameraResult {
    /// Preset.
    pub preset: PresetName,
    /// Objective.
    pub objective: u32,
    /// Sensor, pixels.
    pub width: u32,
    /// Sensor, pixels.
    pub height: u32,
    /// The design.
    pub design: FieldDesign,
    /// The schemes.
    pub schemes: Vec<(String, String)>,
    /// Background-only seconds and each scheme's tally.
    pub background: (f64, Vec<Tally>),
    /// SMLM-density seconds and each scheme's tally.
    pub density: (f64, Vec<Tally>),
    /// The duration sweep.
    pub points: Vec<DurationPoint>,
    /// Wall time, s.
    pub wall_s: f64,
}

/// The whole study.
#[derive(Debug, Clone)]
pub struct FieldResult {
    /// Seed.
    pub seed: u64,
    /// Quick run.
    pub quick: bool,
    /// Blinks per duration.
    pub blinks: u32,
    /// Per camera.
    pub cameras: Vec<CameraResult>,
}

/// Runs `planes` planes of `scene` through every scheme; returns each
/// scheme's records and tally.
fn record(
    camera: &SpadCamera,
    scene: &Scene,
    seed: u64,
    planes: u64,
    cfgs: &[PipelineConfig],
) -> Result<Vec<(Vec<BlinkRecord>, Tally)>, StudyError> {
    let mut sim = SpadSimulator::new(camera, scene, seed)?;
    let mut pipes = cfgs
        .iter()
        .map(|c| fast_pipeline(c.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut out: Vec<(Vec<BlinkRecord>, Tally)> = vec![Default::default(); cfgs.len()];
    let take = |recs: Vec<Record>, o: &mut (Vec<BlinkRecord>, Tally)| {
        for r in recs {
            match r {
                Record::Blink(b) => {
                    if !b.has(flags::CONTINUATION) {
                        o.1.records += 1;
                    }
                    o.0.push(b);
                }
                Record::End(e) => {
                    o.1.dropped = e.dropped_candidates;
                    o.1.planes = e.planes;
                }
                _ => {}
            }
        }
    };
    for _ in 0..planes {
        let plane = sim.next_plane();
        for (p, o) in pipes.iter_mut().zip(out.iter_mut()) {
            take(p.push_plane(&plane)?, o);
        }
    }
    for (mut p, o) in pipes.into_iter().zip(out.iter_mut()) {
        take(p.finish(), o);
    }
    Ok(out)
}

/// The spad camera of a preset.
fn spad(preset: &Preset) -> Result<SpadCamera, StudyError> {
    match &preset.camera {
        Camera::Spad(c) => Ok(c.clone()),
        _ => Err(StudyError::Option {
            name: "preset",
            why: "field-detection needs a SPAD preset".into(),
        }),
    }
}

/// Runs the study for one camera.
pub fn compute_camera(
    name: PresetName,
    objective: u32,
    seed: u64,
    quick: bool,
    blinks: u32,
) -> Result<CameraResult, StudyError> {
    let t0 = Instant::now();
    let preset = Preset::new(name, objective)?;
    let camera = spad(&preset)?;
    let det = stats::derive(&DetectionInputs::from_preset(&preset, None)?)?;
    let (w, h) = preset.camera.size();
    let (design, specs) = schemes(&preset, &det, w, h)?;
    let cfgs: Vec<PipelineConfig> = specs.iter().map(|s| s.cfg.clone()).collect();
    let period = preset.period_s();
    let key = derive_seed(&[seed, key_hash(name.as_str()), objective as u64]);

    // Background only.
    let bg_s = if quick { 1.0 } else { 10.0 };
    let empty = explicit_scene(&preset, w, h, 1.0, Vec::new());
    // SMLM density.
    let dens_s = if quick { 0.5 } else { 3.0 };
    let dense = Scene::smlm(&preset);
    let jobs: Vec<usize> = (0..DURATIONS_MS.len() + 2).collect();
    let pixel_nm = preset.pixel_nm();
    let sigma_px = preset.sigma_px();
    let gap_s = det.n_window as f64 * period + 0.030;
    enum Out {
        Tally(Vec<Tally>),
        Points(Vec<DurationPoint>),
    }
    let outs: Vec<Out> = jobs
        .par_iter()
        .map(|&j| -> Result<Out, StudyError> {
            if j == 0 {
                let planes = (bg_s / period).round() as u64;
                let r = record(&camera, &empty, derive_seed(&[key, 1]), planes, &cfgs)?;
                return Ok(Out::Tally(r.into_iter().map(|x| x.1).collect()));
            }
            if j == 1 {
                let planes = (dens_s / period).round() as u64;
                let r = record(&camera, &dense, derive_seed(&[key, 2]), planes, &cfgs)?;
                return Ok(Out::Tally(r.into_iter().map(|x| x.1).collect()));
            }
            let d_ms = DURATIONS_MS[j - 2];
            let d = d_ms * 1e-3;
            let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(&[key, 3, j as u64]));
            let (wn, hn) = (w as f64 * pixel_nm, h as f64 * pixel_nm);
            let m = EDGE_PX * pixel_nm;
            let mut list = Vec::new();
            let mut t = gap_s;
            for i in 0..blinks {
                list.push(ExplicitBlink {
                    emitter: i as u64,
                    position: Position {
                        x_nm: rng.gen_range(m..wn - m),
                        y_nm: rng.gen_range(m..hn - m),
                    },
                    t_on_s: t,
                    t_off_s: t + d,
                    flux_factor: 1.0,
                });
                t += d + gap_s;
            }
            let scene = explicit_scene(&preset, w, h, 1.0, list.clone());
            let planes = (t / period).round() as u64;
            let runs = record(
                &camera,
                &scene,
                derive_seed(&[key, 4, j as u64]),
                planes,
                &cfgs,
            )?;
            let truth: Vec<Truth> = list
                .iter()
                .map(|b| Truth {
                    x_nm: b.position.x_nm,
                    y_nm: b.position.y_nm,
                    t_on_s: b.t_on_s,
                    t_off_s: b.t_off_s,
                })
                .collect();
            let mut pts = Vec::new();
            for ((recs, tally), spec) in runs.iter().zip(&specs) {
                let (tl, idx, failed) = fit_records(recs, &spec.cfg, w, pixel_nm, sigma_px, period);
                let locs: Vec<Loc> = tl.iter().map(TLoc::loc).collect();
                let matched_planes: u64 = assign(&truth, &locs, DEFAULT_MATCH_RADIUS_NM)
                    .iter()
                    .zip(&idx)
                    .filter(|(m, _)| m.is_some())
                    .map(|(_, &i)| u64::from(recs[i].planes_summed))
                    .sum();
                let o = outcome(
                    &truth,
                    &locs,
                    DEFAULT_MATCH_RADIUS_NM,
                    recs.len() as u32,
                    failed as u32,
                );
                let detected = o.blinks.iter().filter(|b| b.matches > 0).count() as u32;
                let tracked = truth
                    .iter()
                    .filter(|b| {
                        recs.iter().any(|r| {
                            let p = record_planes(r, &spec.cfg);
                            let (t0, t1) = (p.start as f64 * period, p.end as f64 * period);
                            (r.anchor_x as f64 + 0.5 - b.x_nm / pixel_nm).abs() <= TRACK_PX
                                && (r.anchor_y as f64 + 0.5 - b.y_nm / pixel_nm).abs() <= TRACK_PX
                                && t0 < b.t_off_s
                                && t1 > b.t_on_s
                        })
                    })
                    .count() as u32;
                let matched: u32 = o.blinks.iter().map(|b| b.matches).sum();
                pts.push(DurationPoint {
                    duration_ms: d_ms,
                    scheme: spec.id,
                    blinks,
                    detected,
                    tracked,
                    matched,
                    matched_planes,
                    false_records: o.false_pos,
                    sse_nm2: o.blinks.iter().map(|b| b.sse_nm2).sum(),
                    predicted_recall: (spec.id == "field")
                        .then(|| design.recall((d / period).round() as u32)),
                    dropped: tally.dropped,
                });
            }
            Ok(Out::Points(pts))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut background = (bg_s, Vec::new());
    let mut density = (dens_s, Vec::new());
    let mut points = Vec::new();
    for (j, o) in outs.into_iter().enumerate() {
        match o {
            Out::Tally(t) if j == 0 => background.1 = t,
            Out::Tally(t) => density.1 = t,
            Out::Points(p) => points.extend(p),
        }
    }
    Ok(CameraResult {
        preset: name,
        objective,
        width: w,
        height: h,
        design,
        schemes: specs
            .iter()
            .map(|s| (s.id.to_string(), s.label.clone()))
            .collect(),
        background,
        density,
        points,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// The cameras of the study: SPCImager at 150× and 60×, and the projected sensor.
pub const CAMERAS: [(PresetName, u32); 3] = [
    (PresetName::Spcimager, 150),
    (PresetName::Spcimager, 60),
    (PresetName::SpcimagerProjected, 150),
];

/// Runs the study (quick: SPCImager 150× only, fewer blinks and seconds).
pub fn compute(seed: u64, quick: bool, blinks: Option<u32>) -> Result<FieldResult, StudyError> {
    let k = blinks.unwrap_or(if quick { 20 } else { 100 });
    let cams: &[(PresetName, u32)] = if quick { &CAMERAS[..1] } else { &CAMERAS };
    let cameras = cams
        .iter()
        .map(|&(p, o)| compute_camera(p, o, seed, quick, k))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(FieldResult {
        seed,
        quick,
        blinks: k,
        cameras,
    })
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.digits$}"))
}

/// The summary's table of one camera.
pub fn summary_camera(c: &CameraResult) -> String {
    let mut s = String::new();
    let d = &c.design;
    let _ = writeln!(
        s,
        "## {} {}×, {}×{} pixels\n",
        c.preset.as_str(),
        c.objective,
        c.width,
        c.height
    );
    let _ = writeln!(
        s,
        "Field design: N = {}, T_open = {} ({:.2} sd of background H), T_hold = {} ({:.2} sd), r_assoc = {}, L_min = {}, end_trim = {} (a blink sums the planes [t_cross − N, t_drop − end_trim]); predicted background false blinks ≤ {:.3}/s (budget {}/s); shortest blink detected with ≥ 90 % (predicted): {}.\n",
        d.n_window,
        d.threshold_open,
        d.open_sigmas,
        d.threshold_hold,
        d.hold_sigmas,
        d.r_assoc,
        d.l_min,
        d.end_trim,
        d.predicted_false_blinks_per_s,
        d.budget_per_s,
        d.shortest_blink_planes.map_or("none".into(), |p| format!(
            "{:.1} ms ({p} planes)",
            p as f64 * d.plane_rate_hz.recip() * 1e3
        ))
    );
    for (id, label) in &c.schemes {
        let _ = writeln!(s, "* `{id}`: {label}");
    }
    let _ = writeln!(
        s,
        "\n| scheme | false blinks/s, background only ({:.0} s) | dropped candidates/s, background | dropped candidates/s, SMLM density ({:.1} s) |",
        c.background.0, c.density.0
    );
    let _ = writeln!(s, "|---|---|---|---|");
    for (i, (id, _)) in c.schemes.iter().enumerate() {
        let b = &c.background.1[i];
        let dn = &c.density.1[i];
        let _ = writeln!(
            s,
            "| {id} | {:.2} ({} records){} | {:.0} | {:.0} |",
            b.records as f64 / c.background.0,
            b.records,
            if id == "field" {
                format!("; predicted ≤ {:.3}", d.predicted_false_blinks_per_s)
            } else {
                String::new()
            },
            b.dropped as f64 / c.background.0,
            dn.dropped as f64 / c.density.0,
        );
    }
    let _ = writeln!(
        s,
        "\n| duration, ms | scheme | recall (predicted) | tracked | records per detected blink | planes summed per matched record | RMS error, nm | unmatched records | dropped candidates |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for p in &c.points {
        let (lo, hi) = wilson(p.detected as f64, p.blinks as f64);
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} [{:.3}, {:.3}]{} | {:.3} | {} | {} | {} | {} | {} |",
            p.duration_ms,
            p.scheme,
            p.recall(),
            lo,
            hi,
            p.predicted_recall
                .map_or(String::new(), |r| format!(" ({r:.3})")),
            p.track_recall(),
            opt(p.records_per_blink(), 3),
            opt(p.planes_per_match(), 0),
            opt(p.rms_nm(), 1),
            p.false_records,
            p.dropped
        );
    }
    let _ = writeln!(s, "\nWall time: {:.0} s.\n", c.wall_s);
    s
}

/// Writes `points.csv` and `summary.md` to `dir`.
pub fn write(dir: &Path, r: &FieldResult) -> Result<(Vec<PathBuf>, Vec<String>), StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io(dir, e))?;
    let mut csv = String::from(
        "preset,objective,duration_ms,scheme,blinks,detected,recall,predicted_recall,tracked,matched,records_per_blink,planes_per_match,rms_nm,false_records,dropped\n",
    );
    for c in &r.cameras {
        for p in &c.points {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{:.4},{},{},{},{},{},{},{},{}",
                c.preset.as_str(),
                c.objective,
                p.duration_ms,
                p.scheme,
                p.blinks,
                p.detected,
                p.recall(),
                p.predicted_recall
                    .map_or(String::new(), |v| format!("{v:.4}")),
                p.tracked,
                p.matched,
                p.records_per_blink()
                    .map_or(String::new(), |v| format!("{v:.4}")),
                p.planes_per_match()
                    .map_or(String::new(), |v| format!("{v:.1}")),
                p.rms_nm().map_or(String::new(), |v| format!("{v:.2}")),
                p.false_records,
                p.dropped
            );
        }
    }
    let mut md = format!(
        "# Detection on the whole sensor\n\n`smartagg study field-detection --seed {}{}`: {} blinks per duration, one molecule on at a time; background-only and SMLM-density recordings of the whole sensor; the study's light (see `study/src/experiment/field_detection.rs`). Schemes: `field` is the field design as `smartagg aggregate` defaults to (open and hold thresholds for a false-blink budget, its r_assoc and L_min, end_trim = ⌊N/2⌋: a blink sums the bit-planes [t_cross − N, t_drop − ⌊N/2⌋], to its estimated end); `field-v2` the same detection summed to t_drop (end_trim 0, the default before packet format v3); `paper` the paper's one 3σ threshold with L_min = 1 and r_assoc = 1, summed to t_drop; `paper-lmin` the paper's threshold with L_min from the false-alarm bound, summed to t_drop. Recall is the fraction of blinks with a localisation within {} nm whose summed planes overlap them in time (the interval is Wilson's 95 %; in brackets the field design's prediction); *tracked* is the fraction with a track opened within {} pixels of them whose summed planes overlap them in time, whatever its localisation: the detection alone; *planes summed per matched record* is the mean `planes_summed` of the records whose localisation matched a blink.\n\n",
        r.seed,
        if r.quick { " --quick" } else { "" },
        r.blinks,
        DEFAULT_MATCH_RADIUS_NM,
        TRACK_PX
    );
    for c in &r.cameras {
        md.push_str(&summary_camera(c));
    }
    let files = vec![dir.join("points.csv"), dir.join("summary.md")];
    write_text(&files[0], &csv)?;
    write_text(&files[1], &md)?;
    Ok((files, Vec::new()))
}
