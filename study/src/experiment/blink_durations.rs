//! `blink-durations`: blink durations estimated by smart aggregation
//! (`t_e − t_s` of the records, CUT/CONTINUATION segments joined) and by
//! the EMCCD (consecutive frames with a localisation within 40 nm), against
//! the true distribution (paper Fig. 5); the estimator's bias, derived and
//! measured; and why smart aggregation gives more than one record per blink.
//!
//! Smart aggregation is the field design of the study field, as `smartagg
//! aggregate` defaults to ([`smart_config`]), and the same with the paper's
//! association radius r_assoc = 1 on the same bit-planes, to show the
//! duplicate tracks that the design's round(2σ) avoids.
//!
//! Scene: one molecule on at a time at a random position of the study
//! field (SPCIMAGER 32×32 at 150×, EMCCD 16×16 with 64 ms frames and 30 ms
//! dead time), exponential blink durations of mean 30 ms, gaps of 30 ms +
//! Exp(40 ms) (longer than the window, so that consecutive blinks never
//! share a window), study light. The same blinks for both cameras.
//!
//! ## Bias of `t_e − t_s` (derivation)
//!
//! `t_s = t_cross − ⌊N/2⌋` and `t_e = t_drop − ⌊N/2⌋`, so `t_e − t_s =
//! t_drop − t_cross` (`end_trim` changes only the planes summed). At the
//! molecule's pixel a window holding `k` on-planes has mean
//! `H = N·E(F_off) + k·Δ` (Δ = E F_on − E F_off). A track opens when H
//! reaches T_open and drops when H falls below T_hold, the paper's Eq. 7
//! threshold `T = N·E(F_off) + 3√(N·Var F_off)`. The mean reaches a
//! threshold T' at the on-count `k(T') = (T' − N·E(F_off))/Δ`; for the hold
//! level, with Eq. 6's `√N = 3(√Var F_off + √Var F_on)/Δ`, this is
//! `k_hold = N·√Var F_off / (√Var F_off + √Var F_on)`. The window's
//! on-count rises through `k_open` at `t_on + k_open` and falls through
//! `k_hold` at `t_off + N − k_hold` (for any duration D ≥ k_open), so
//! `t_drop − t_cross ≈ D + N − k_open − k_hold`, plus about one plane for
//! the two-plane drop rule and a first-passage term (noise makes H reach
//! T_open early and leave T_hold late). If instead a threshold were reached
//! by the first on-plane (bright molecule, k → 1) the window would add
//! N − 1 planes; here both on-counts are large fractions of N. The estimate
//! is corrected by subtracting the derived `N − k_open − k_hold + 1`
//! planes; the measured remaining bias is reported.

use super::common::*;
use crate::acquisition::{record_planes, Setup};
use crate::error::StudyError;
use crate::matching::{outcome, Loc, Truth};
use crate::timeline::{derive_seed, key_hash};
use plotters::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use smartagg_localize::NoiseModel;
use smartagg_model::config::PipelineConfig;
use smartagg_model::params::{Camera, PresetName};
use smartagg_model::record::{flags, BlinkRecord};
use smartagg_scene::{ExplicitBlink, Position};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Mean blink duration, s.
pub const MEAN_ON_S: f64 = 0.030;
/// Blinks per work item (one recording each).
pub const BLOCK: usize = 100;
/// Association radius of the second smart scheme: the paper's 1 pixel (the
/// first is the field design's own, round(2σ)).
pub const NARROW_R_ASSOC: u32 = 1;

/// A record joined with its CUT/CONTINUATION segments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joined {
    /// Estimated start, planes.
    pub t_s: i64,
    /// Estimated end, planes.
    pub t_e: i64,
    /// First plane summed (pre-roll included): the first segment's.
    pub first: u64,
    /// One past the last plane summed: the last segment's. A CUT segment
    /// sums up to `t_drop − N` and its continuation from `t_drop + 1 − N`,
    /// so `first..last` is every plane the joined segments summed, once.
    pub last: u64,
    /// Plane the track opened.
    pub t_cross: u64,
    /// First of the two planes below T_hold.
    pub t_drop: u64,
    /// Anchor.
    pub anchor: (u16, u16),
    /// Segments joined.
    pub segments: u32,
}

/// Joins every CUT segment with the CONTINUATION segments that follow it in
/// the same slot; `records` come from a pipeline configured with `cfg`.
pub fn join_segments(records: &[BlinkRecord], cfg: &PipelineConfig) -> Vec<Joined> {
    let mut open: Vec<Option<usize>> = vec![None; 256];
    let mut out: Vec<Joined> = Vec::new();
    for r in records {
        let planes = record_planes(r, cfg);
        let (first, last) = (planes.start, planes.end);
        if r.has(flags::CONTINUATION) {
            if let Some(i) = open[r.slot as usize] {
                let j = &mut out[i];
                j.t_e = r.t_e;
                j.last = last;
                j.t_drop = r.t_drop;
                j.segments += 1;
                if !r.has(flags::CUT) {
                    open[r.slot as usize] = None;
                }
                continue;
            }
        }
        out.push(Joined {
            t_s: r.t_s,
            t_e: r.t_e,
            first,
            last,
            t_cross: r.t_cross,
            t_drop: r.t_drop,
            anchor: (r.anchor_x, r.anchor_y),
            segments: 1,
        });
        open[r.slot as usize] = r.has(flags::CUT).then_some(out.len() - 1);
    }
    out
}

/// How the records of one blink relate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SplitCounts {
    /// Record pairs (consecutive in t_cross) whose live ranges overlap: a
    /// second track opened while the first was on.
    pub concurrent: u32,
    /// Pairs one after the other: the first dropped and a new one opened.
    pub sequential: u32,
}

/// One true blink and what each scheme made of it.
#[derive(Debug, Clone, PartialEq)]
pub struct BlinkRow {
    /// True duration, ms.
    pub duration_ms: f64,
    /// Per association radius of [`BlinkDurationsResult::r_assoc`] (the
    /// field design's, then [`NARROW_R_ASSOC`]): records matched.
    pub records: [u32; 2],
    /// Per radius: duration from the first matched record (t_e − t_s), ms.
    pub est_ms: [Option<f64>; 2],
    /// Per radius: how the records relate.
    pub split: [SplitCounts; 2],
    /// Per radius: the largest Chebyshev distance between matched anchors, px.
    pub anchor_spread: [u32; 2],
    /// Per radius: t_cross of the second record − t_cross of the first, ms.
    pub second_delay_ms: [Option<f64>; 2],
    /// EMCCD: frames of the merged chain matched (0: missed).
    pub emccd_frames: u32,
}

/// The study's result.
#[derive(Debug, Clone)]
pub struct BlinkDurationsResult {
    /// Every true blink.
    pub blinks: Vec<BlinkRow>,
    /// Every smart record's estimated duration (the field design), ms, and
    /// whether it matched a blink.
    pub record_ms: Vec<(f64, bool)>,
    /// The smart scheme's pipeline (the field design).
    pub smart: PipelineConfig,
    /// The association radii compared: the field design's, then
    /// [`NARROW_R_ASSOC`].
    pub r_assoc: [u32; 2],
    /// N.
    pub n_window: u32,
    /// On-count at which the mean of H reaches T_open, planes.
    pub k_open: f64,
    /// On-count at which the mean of H reaches T_hold (Eq. 7):
    /// ≈ N·√V_off/(√V_off+√V_on), planes.
    pub k_hold: f64,
    /// Derived bias N − k_open − k_hold + 1, ms.
    pub derived_bias_ms: f64,
    /// EMCCD frame period, ms.
    pub emccd_period_ms: f64,
    /// Wall seconds: SPAD (simulation + 2 pipelines), EMCCD (simulation + fits).
    pub seconds: (f64, f64),
}

impl BlinkDurationsResult {
    /// Mean and standard deviation of (estimate − truth) over blinks with
    /// exactly one record at radius index `r`, ms; optionally corrected.
    pub fn bias(&self, r: usize, corrected: bool) -> Option<(f64, f64, usize)> {
        let d: Vec<f64> = self
            .blinks
            .iter()
            .filter(|b| b.records[r] == 1)
            .filter_map(|b| b.est_ms[r].map(|e| e - b.duration_ms))
            .map(|e| {
                if corrected {
                    e - self.derived_bias_ms
                } else {
                    e
                }
            })
            .collect();
        if d.len() < 2 {
            return None;
        }
        let n = d.len() as f64;
        let m = d.iter().sum::<f64>() / n;
        let sd = (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        Some((m, sd, d.len()))
    }

    /// Records per detected blink at radius index `r`, over blinks of true
    /// duration in `[lo, hi)` ms.
    pub fn records_per_blink(&self, r: usize, lo: f64, hi: f64) -> Option<f64> {
        let v: Vec<u32> = self
            .blinks
            .iter()
            .filter(|b| b.duration_ms >= lo && b.duration_ms < hi && b.records[r] > 0)
            .map(|b| b.records[r])
            .collect();
        (!v.is_empty()).then(|| v.iter().sum::<u32>() as f64 / v.len() as f64)
    }
}

fn block_blinks(seed: u64, n: usize) -> (Vec<(f64, f64, f64, f64)>, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = 0.0;
    let mut v = Vec::with_capacity(n);
    for _ in 0..n {
        let gap = 0.030 - 0.040 * (1.0 - rng.gen::<f64>()).ln();
        let d = -MEAN_ON_S * (1.0 - rng.gen::<f64>()).ln();
        let (u, w) = (rng.gen::<f64>(), rng.gen::<f64>());
        v.push((u, w, t + gap, t + gap + d));
        t += gap + d;
    }
    (v, t + 0.064)
}

fn explicit(v: &[(f64, f64, f64, f64)], s: &Setup) -> Vec<ExplicitBlink> {
    let span = s.field_nm() - 2.0 * s.margin_nm;
    v.iter()
        .enumerate()
        .map(|(i, &(u, w, a, b))| ExplicitBlink {
            emitter: i as u64,
            position: Position {
                x_nm: s.margin_nm + u * span,
                y_nm: s.margin_nm + w * span,
            },
            t_on_s: a,
            t_off_s: b,
            flux_factor: 1.0,
        })
        .collect()
}

/// Runs the study: `blinks` true blinks (default 1000, quick 400).
pub fn compute(
    seed: u64,
    quick: bool,
    blinks: Option<u32>,
) -> Result<BlinkDurationsResult, StudyError> {
    let n = blinks.unwrap_or(if quick { 400 } else { 1000 }) as usize;
    let spad = Setup::new(PresetName::Spcimager, 150)?;
    let (det, _, smart) = smart_config(&spad.preset, spad.field, None)?;
    let (_, _, narrow) = smart_config(&spad.preset, spad.field, Some(NARROW_R_ASSOC))?;
    let cfgs = [smart, narrow];
    let Camera::Spad(cam) = spad.preset.camera.clone() else {
        unreachable!("SPCIMAGER is a SPAD")
    };
    let mut em = Setup::new(PresetName::Emccd, 150)?;
    let em_cam = emccd_experiment(&mut em.preset)?;
    let period = cam.plane_period_s;
    let blocks = n.div_ceil(BLOCK);
    type Block = (Vec<BlinkRow>, Vec<(f64, bool)>, f64, f64);
    let out: Vec<Block> = (0..blocks)
        .into_par_iter()
        .map(|b| -> Result<Block, StudyError> {
            let m = BLOCK.min(n - b * BLOCK);
            let s = derive_seed(&[seed, key_hash("blink-durations"), b as u64]);
            let (v, end_s) = block_blinks(s, m);
            let t0 = Instant::now();
            let sb = explicit(&v, &spad);
            let scene = explicit_scene(&spad.preset, spad.field, spad.field, 1.0, sb.clone());
            let run = run_spad(
                &cam,
                &scene,
                derive_seed(&[s, 1]),
                (end_s / period).ceil() as u64,
                &cfgs,
                None,
            )?;
            let spad_s = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let eb = explicit(&v, &em);
            let escene = explicit_scene(&em.preset, em.field, em.field, 1.0, eb.clone());
            let frames_n = (end_s / em_cam.frame_period_s).ceil() as usize;
            let (frames, _) = run_emccd(&em_cam, &escene, derive_seed(&[s, 2]), frames_n)?;
            let (locs, _, failed) = localize_frames(
                &frames,
                em.field,
                em.pixel_nm,
                em.sigma_px,
                NoiseModel::Emccd,
                em_cam.frame_period_s,
                em_cam.exposure_s,
                true,
            )?;
            let truth: Vec<Truth> = eb
                .iter()
                .map(|x| Truth {
                    x_nm: x.position.x_nm,
                    y_nm: x.position.y_nm,
                    t_on_s: x.t_on_s,
                    t_off_s: x.t_off_s,
                })
                .collect();
            let lv: Vec<Loc> = locs.iter().map(TLoc::loc).collect();
            let a = crate::matching::assign(&truth, &lv, 53.3);
            let _ = outcome(
                &truth,
                &lv,
                53.3,
                (locs.len() + failed) as u32,
                failed as u32,
            );
            let mut em_frames = vec![0u32; m];
            for (l, k) in locs.iter().zip(&a) {
                if let Some(k) = k {
                    em_frames[*k] = em_frames[*k].max(l.frames);
                }
            }
            let em_s = t1.elapsed().as_secs_f64();
            // Smart: a joined record belongs to the blink whose on-time
            // overlaps its live planes [t_cross, t_drop] widened by N
            // (the window's delay) and whose pixel is within 2 px of its anchor.
            let joined: Vec<Vec<Joined>> = run
                .records
                .iter()
                .zip(&cfgs)
                .map(|(r, c)| join_segments(r, c))
                .collect();
            let mut rows: Vec<BlinkRow> = v
                .iter()
                .zip(&em_frames)
                .map(|(x, &ef)| BlinkRow {
                    duration_ms: (x.3 - x.2) * 1e3,
                    records: [0; 2],
                    est_ms: [None; 2],
                    split: [SplitCounts::default(); 2],
                    anchor_spread: [0; 2],
                    second_delay_ms: [None; 2],
                    emccd_frames: ef,
                })
                .collect();
            let mut record_ms = Vec::new();
            let nw = det.n_window as f64;
            for (ri, js) in joined.iter().enumerate() {
                let mut per: Vec<Vec<Joined>> = vec![Vec::new(); m];
                for j in js {
                    let t0 = (j.t_cross as f64 - nw) * period;
                    let t1 = (j.t_drop as f64 + 1.0) * period;
                    let hit = sb.iter().position(|x| {
                        let px = (x.position.x_nm / spad.pixel_nm).floor();
                        let py = (x.position.y_nm / spad.pixel_nm).floor();
                        t0 < x.t_off_s
                            && t1 > x.t_on_s
                            && (px - j.anchor.0 as f64).abs() <= 2.0
                            && (py - j.anchor.1 as f64).abs() <= 2.0
                    });
                    if ri == 0 {
                        record_ms.push(((j.t_e - j.t_s) as f64 * period * 1e3, hit.is_some()));
                    }
                    if let Some(k) = hit {
                        per[k].push(*j);
                    }
                }
                for (k, mut js) in per.into_iter().enumerate() {
                    js.sort_by_key(|j| j.t_cross);
                    let row = &mut rows[k];
                    row.records[ri] = js.len() as u32;
                    row.est_ms[ri] = js.first().map(|j| (j.t_e - j.t_s) as f64 * period * 1e3);
                    if js.len() > 1 {
                        row.second_delay_ms[ri] =
                            Some((js[1].t_cross - js[0].t_cross) as f64 * period * 1e3);
                    }
                    for w in js.windows(2) {
                        if w[1].t_cross <= w[0].t_drop {
                            row.split[ri].concurrent += 1;
                        } else {
                            row.split[ri].sequential += 1;
                        }
                    }
                    for a in &js {
                        for c in &js {
                            let d = (a.anchor.0 as i32 - c.anchor.0 as i32)
                                .abs()
                                .max((a.anchor.1 as i32 - c.anchor.1 as i32).abs());
                            row.anchor_spread[ri] = row.anchor_spread[ri].max(d as u32);
                        }
                    }
                }
            }
            Ok((rows, record_ms, spad_s, em_s))
        })
        .collect::<Result<_, _>>()?;
    let nw = det.n_window as f64;
    // The on-count at which the mean of H reaches an integer threshold.
    let k_at =
        |t: u32| (t as f64 * det.threshold_unit - nw * det.e_f_off) / (det.e_f_on - det.e_f_off);
    let (k_open, k_hold) = (k_at(cfgs[0].threshold_int), k_at(cfgs[0].threshold_hold));
    let mut res = BlinkDurationsResult {
        blinks: Vec::new(),
        record_ms: Vec::new(),
        r_assoc: [cfgs[0].r_assoc, cfgs[1].r_assoc],
        n_window: det.n_window,
        k_open,
        k_hold,
        derived_bias_ms: (nw - k_open - k_hold + 1.0) * period * 1e3,
        smart: cfgs[0].clone(),
        emccd_period_ms: em_cam.frame_period_s * 1e3,
        seconds: (0.0, 0.0),
    };
    for (rows, rec, a, b) in out {
        res.blinks.extend(rows);
        res.record_ms.extend(rec);
        res.seconds.0 += a;
        res.seconds.1 += b;
    }
    Ok(res)
}

fn f1(v: Option<f64>) -> String {
    v.map_or("—".into(), |x| format!("{x:.1}"))
}

/// Writes points.csv (one row per true blink), records.csv,
/// blink-durations.png and summary.md.
pub fn write(
    dir: &Path,
    r: &BlinkDurationsResult,
) -> Result<(Vec<PathBuf>, Vec<String>), StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io(dir, e))?;
    let (mut files, mut warnings) = (Vec::new(), Vec::new());
    // Unsuffixed: the smart scheme (the field design); `_r1`: r_assoc 1.
    let mut csv = String::from("duration_ms,records,est_ms,concurrent,sequential,anchor_spread,records_r1,est_ms_r1,concurrent_r1,sequential_r1,anchor_spread_r1,emccd_frames\n");
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.2}"));
    for b in &r.blinks {
        let _ = writeln!(
            csv,
            "{:.3},{},{},{},{},{},{},{},{},{},{},{}",
            b.duration_ms,
            b.records[0],
            o(b.est_ms[0]),
            b.split[0].concurrent,
            b.split[0].sequential,
            b.anchor_spread[0],
            b.records[1],
            o(b.est_ms[1]),
            b.split[1].concurrent,
            b.split[1].sequential,
            b.anchor_spread[1],
            b.emccd_frames
        );
    }
    let p = dir.join("points.csv");
    write_text(&p, &csv)?;
    files.push(p);
    let mut csv = String::from("est_ms,matched\n");
    for (e, m) in &r.record_ms {
        let _ = writeln!(csv, "{e:.2},{}", *m as u8);
    }
    let p = dir.join("records.csv");
    write_text(&p, &csv)?;
    files.push(p);
    let png = dir.join("blink-durations.png");
    match plot(&png, r) {
        Ok(()) => files.push(png),
        Err(e) => warnings.push(e.to_string()),
    }
    let p = dir.join("summary.md");
    write_text(&p, &markdown(r, &warnings))?;
    files.push(p);
    Ok((files, warnings))
}

fn markdown(r: &BlinkDurationsResult, warnings: &[String]) -> String {
    let mut m = String::new();
    let n = r.blinks.len();
    let _ = writeln!(m, "# Study `blink-durations`: estimated blink durations, smart aggregation and EMCCD against the truth (paper Fig. 5)\n\n![blink-durations](blink-durations.png)\n\n## Set-up\n");
    let _ = writeln!(m, "- **Scene**: {n} blinks, one molecule on at a time at a random position, durations Exp(mean {:.0} ms), gaps 30 ms + Exp(40 ms); study light (50,000 photons/s, 70,000 photons/s/µm²), 150×. SPCIMAGER 32×32, EMCCD 16×16 with 64 ms frames and 34 ms exposure; the same blinks for both.", MEAN_ON_S * 1e3);
    let c = &r.smart;
    let [ra, rn] = r.r_assoc;
    let _ = writeln!(m, "- **Smart aggregation**: the model's pipeline (fast engine) and packet path with the field design of the {f}×{f} field, as `smartagg aggregate` defaults to: N = {}, a track opens at T_open = {} (at most 1 false blink/s over the field from background alone) and holds down to T_hold = {} (the paper's Eq. 7 threshold), r_assoc = {ra} px (round(2σ)), L_min = {}, end_trim = {} (a blink sums [t_cross − N, t_drop − {}]); and the same with the paper's r_assoc = {rn} on the same bit-planes. Estimated duration of a record = (t_e − t_s)·0.1 ms with CUT/CONTINUATION segments joined.", c.n_window, c.threshold_int, c.threshold_hold, c.l_min, c.end_trim, c.end_trim, f = c.width);
    let _ = writeln!(m, "- **EMCCD**: ThunderSTORM detection and EMCCD MLE, localisations of consecutive frames within 40 nm merged; estimated duration = frames of the chain × {:.0} ms.", r.emccd_period_ms);
    let _ = writeln!(m, "- **Truth matching**: a smart record belongs to the blink whose on-time overlaps [t_cross − N, t_drop] and whose pixel is within 2 px (Chebyshev) of its anchor (one molecule at a time, so this is unambiguous); an EMCCD chain matches within 53.3 nm with overlapping exposure.\n");
    let det = |r_i: usize| r.blinks.iter().filter(|b| b.records[r_i] > 0).count();
    let em_det = r.blinks.iter().filter(|b| b.emccd_frames > 0).count();
    let matched = r.record_ms.iter().filter(|x| x.1).count();
    let _ = writeln!(m, "## Results\n\n| quantity | value |\n|---|---|");
    let _ = writeln!(
        m,
        "| blinks detected, smart (r_assoc {ra}) / r_assoc {rn} | {:.1} % / {:.1} % |",
        100.0 * det(0) as f64 / n as f64,
        100.0 * det(1) as f64 / n as f64
    );
    let _ = writeln!(
        m,
        "| blinks detected, EMCCD | {:.1} % |",
        100.0 * em_det as f64 / n as f64
    );
    let _ = writeln!(
        m,
        "| smart records matching no blink (FP) | {} of {} ({:.1} %) |",
        r.record_ms.len() - matched,
        r.record_ms.len(),
        100.0 * (r.record_ms.len() - matched) as f64 / r.record_ms.len().max(1) as f64
    );
    let _ = writeln!(
        m,
        "| N; on-counts at which the mean of H reaches T_open (k_open) and T_hold (k_hold ≈ N·√V_off/(√V_off+√V_on)) | {}; {:.1}, {:.1} planes |",
        r.n_window, r.k_open, r.k_hold
    );
    let _ = writeln!(
        m,
        "| derived bias of t_e − t_s: N − k_open − k_hold + 1 | {:.2} ms |",
        r.derived_bias_ms
    );
    for (i, ra) in r.r_assoc.iter().enumerate() {
        if let Some((mu, sd, k)) = r.bias(i, false) {
            let _ = writeln!(m, "| measured bias (estimate − truth), r_assoc {ra}, blinks with one record ({k}) | {mu:.2} ms (sd {sd:.2} ms) |");
        }
        if let Some((mu, sd, _)) = r.bias(i, true) {
            let _ = writeln!(
                m,
                "| after subtracting the derived bias, r_assoc {ra} | {mu:.2} ms (sd {sd:.2} ms) |"
            );
        }
    }
    let _ = writeln!(m, "| wall time: SPAD simulation + 2 pipelines; EMCCD simulation + fits (summed over workers) | {:.1} s; {:.1} s |\n", r.seconds.0, r.seconds.1);
    let _ = writeln!(m, "### Records per detected blink, and how a blink is split\n\nEach split column gives the smart scheme (r_assoc {ra}) / r_assoc {rn}.\n\n| true duration ms | blinks | records/blink r_assoc {ra} | r_assoc {rn} | split blinks | concurrent pairs | sequential pairs | median anchor spread of split blinks (px) | median delay of the 2nd track (ms) | EMCCD frames/blink |\n|---|---|---|---|---|---|---|---|---|---|");
    for (lo, hi) in [
        (0.0, 20.0),
        (20.0, 40.0),
        (40.0, 60.0),
        (60.0, 100.0),
        (100.0, 1e9),
    ] {
        let sel: Vec<&BlinkRow> = r
            .blinks
            .iter()
            .filter(|b| b.duration_ms >= lo && b.duration_ms < hi)
            .collect();
        let emf: Vec<f64> = sel
            .iter()
            .filter(|b| b.emccd_frames > 0)
            .map(|b| b.emccd_frames as f64)
            .collect();
        let per = |i: usize| {
            let split: Vec<&&BlinkRow> = sel.iter().filter(|b| b.records[i] > 1).collect();
            let conc: u32 = sel.iter().map(|b| b.split[i].concurrent).sum();
            let seq: u32 = sel.iter().map(|b| b.split[i].sequential).sum();
            let spread: Vec<f64> = split.iter().map(|b| b.anchor_spread[i] as f64).collect();
            let det = sel.iter().filter(|b| b.records[i] > 0).count();
            let delay: Vec<f64> = sel.iter().filter_map(|b| b.second_delay_ms[i]).collect();
            (
                format!("{} of {det}", split.len()),
                conc,
                seq,
                f1(median(&spread)),
                f1(median(&delay)),
            )
        };
        let (a, b) = (per(0), per(1));
        let _ = writeln!(
            m,
            "| {}–{} | {} | {} | {} | {} / {} | {} / {} | {} / {} | {} / {} | {} / {} | {} |",
            lo,
            if hi > 1e8 {
                "∞".to_string()
            } else {
                hi.to_string()
            },
            sel.len(),
            f1(r.records_per_blink(0, lo, hi)),
            f1(r.records_per_blink(1, lo, hi)),
            a.0,
            b.0,
            a.1,
            b.1,
            a.2,
            b.2,
            a.3,
            b.3,
            a.4,
            b.4,
            f1((!emf.is_empty()).then(|| emf.iter().sum::<f64>() / emf.len() as f64))
        );
    }
    let _ = writeln!(m, "\nA *concurrent* pair: the second track opened (t_cross) before the first dropped — a local maximum of H at or above T_open more than r_assoc from the first anchor while the blink was on; both tracks then stay on (each tests the 3×3 around its own anchor, which still sees the molecule) and each record sums the same planes into an ROI shifted by the anchor distance: duplicates, not shares, of the photons. A *sequential* pair: the first track dropped (two planes below T_hold) and a new one opened later in the same blink.\n");
    let _ = writeln!(
        m,
        "## Where this differs from the paper, and why\n\n{}",
        super::notes::with_source("blink-durations", super::notes::BLINK_DURATIONS)
    );
    for w in warnings {
        let _ = writeln!(m, "\n**Warning**: {w}");
    }
    m
}

/// Histogram of `v` as a density per true blink (`norm` blinks), so that
/// blinks an estimator misses show as a deficit.
fn hist(v: &[f64], width: f64, max: f64, norm: usize) -> Vec<(f64, f64)> {
    let bins = (max / width).ceil() as usize;
    let mut h = vec![0f64; bins];
    for &x in v {
        if x >= 0.0 && x < max {
            h[(x / width) as usize] += 1.0;
        }
    }
    let tot = norm.max(1) as f64;
    h.iter()
        .enumerate()
        .map(|(i, c)| (i as f64 * width, c / tot / width))
        .collect()
}

fn plot(path: &Path, r: &BlinkDurationsResult) -> Result<(), StudyError> {
    let root = BitMapBackend::new(path, (1400, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let panels = root.split_evenly((1, 2));
    let max = 200.0;
    let truth: Vec<f64> = r.blinks.iter().map(|b| b.duration_ms).collect();
    let raw: Vec<f64> = r.blinks.iter().filter_map(|b| b.est_ms[0]).collect();
    let nb = r.blinks.len();
    let corr: Vec<f64> = raw.iter().map(|x| x - r.derived_bias_ms).collect();
    let em: Vec<f64> = r
        .blinks
        .iter()
        .filter(|b| b.emccd_frames > 0)
        .map(|b| b.emccd_frames as f64 * r.emccd_period_ms - 1.0)
        .collect();
    let series: [(&str, Vec<(f64, f64)>); 3] = [
        ("true durations", hist(&truth, 10.0, max, nb)),
        (
            "smart: t_e − t_s, first record of each blink",
            hist(&raw, 10.0, max, nb),
        ),
        ("smart, derived bias subtracted", hist(&corr, 10.0, max, nb)),
    ];
    let ymax = series
        .iter()
        .flat_map(|s| s.1.iter().map(|p| p.1))
        .fold(0.0, f64::max)
        * 1.15;
    let mut chart = ChartBuilder::on(&panels[0])
        .caption(
            "SPCIMAGER smart aggregation (10 ms bins)",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..max, 0.0..ymax.max(1e-3))
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("blink duration (ms)")
        .y_desc("blinks per ms, per true blink")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (i, (name, h)) in series.iter().enumerate() {
        let col = if i == 0 { BLACK } else { colour(i) };
        let steps: Vec<(f64, f64)> = h
            .iter()
            .flat_map(|&(x, y)| [(x, y), (x + 10.0, y)])
            .collect();
        chart
            .draw_series(LineSeries::new(steps, col.stroke_width(2)))
            .map_err(|e| plot_err(path, e))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    let p = r.emccd_period_ms;
    let th = hist(&truth, p, max + p, nb);
    let eh = hist(&em, p, max + p, nb);
    let ymax = th.iter().chain(&eh).map(|x| x.1).fold(0.0, f64::max) * 1.15;
    let mut chart = ChartBuilder::on(&panels[1])
        .caption("EMCCD: consecutive 64 ms frames", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..(max + p), 0.0..ymax.max(1e-3))
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("blink duration (ms): frames × 64 ms")
        .y_desc("blinks per ms, per true blink")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (i, (name, h)) in [
        ("true durations", th),
        ("EMCCD frames × 64 ms (detected blinks)", eh),
    ]
    .into_iter()
    .enumerate()
    {
        let col = if i == 0 { BLACK } else { colour(3) };
        let steps: Vec<(f64, f64)> = h.iter().flat_map(|&(x, y)| [(x, y), (x + p, y)]).collect();
        chart
            .draw_series(LineSeries::new(steps, col.stroke_width(2)))
            .map_err(|e| plot_err(path, e))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
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
