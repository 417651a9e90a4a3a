//! `detection`: does the paper's choice of N and T (Eq. 5–7) give ≈ 99 %
//! detection, and at what false-alarm rate? And what does N trade: time
//! resolution against localisation precision.
//!
//! **Part A — per window.** The SPCIMAGER at 150× with uniform maps (η and
//! the median DCR everywhere, no hot pixels: the model's assumptions) looks
//! at four molecules on throughout, each centred on a pixel centre, and at
//! a background-only field. For every plane the filtered value
//! `F = Σ K_int·B` (the pipeline's integer kernel) is computed at each
//! molecule's pixel and at every interior background pixel, and the rolling
//! sum `H` over N planes is compared with `T_int`. Measured: the detection
//! probability (molecule windows with `H ≥ T_int`) and the false-alarm
//! probability per pixel-plane; beside them the model's exact values
//! (`false_alarm::detection_probability`, `false_alarm::tail_probability`)
//! and the Gaussian approximation of Eq. 5/7. N runs over ¼ … 2× the derived
//! N, T over `N·E(F_off) + z·√(N·Var F_off)` for z = 2 … 4 (z = 3 is Eq. 7).
//! Windows overlap (every plane starts one), so the intervals use the
//! number of independent windows (planes / N).
//!
//! Part A measures the paper's own threshold rule (Eq. 5–7), so it keeps it:
//! no pipeline, the windowed sums compared with `T_int` directly.
//!
//! **Part B — N against precision.** The pipeline (fast engine) with the
//! field design at several N (as `smartagg aggregate --n-window N` makes it:
//! Eq. 7's threshold at that N as T_hold, T_open for 1 false blink/s over
//! the field, r_assoc = round(2σ), L_min 1, end_trim ⌊N/2⌋) on the same
//! bit-planes of one-at-a-time blinks of exponential duration (mean
//! 30 ms): detection, records per blink, RMS error (Poisson MLE), and the
//! time resolution N·τ.

use super::common::*;
use crate::acquisition::{field_design_config, Setup};
use crate::error::StudyError;
use crate::matching::{outcome, Loc, Truth};
use crate::stats::{resample_indices, rms_estimate, Estimate};
use crate::timeline::{derive_seed, key_hash};
use plotters::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use smartagg_model::config::PipelineConfig;
use smartagg_model::false_alarm::{detection_probability, tail_probability};
use smartagg_model::params::{Camera, PresetName};
use smartagg_model::stats::{normal_sf, Detection};
use smartagg_scene::{ExplicitBlink, Position, SpadSimulator};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Multiples of the derived N in part A.
pub const N_FACTORS: [f64; 6] = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0];
/// Threshold offsets z (in √(N·Var F_off)) in part A; 3 is Eq. 7.
pub const Z: [f64; 5] = [2.0, 2.5, 3.0, 3.5, 4.0];
/// Multiples of the derived N in part B.
pub const N_FACTORS_B: [f64; 4] = [0.25, 0.5, 1.0, 2.0];

/// One (N, T) point of part A.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowPoint {
    /// Window, planes.
    pub n: u32,
    /// Threshold offset z.
    pub z: f64,
    /// Integer threshold.
    pub t_int: u64,
    /// Measured detection probability.
    pub p_det: f64,
    /// Its 95 % interval (independent windows).
    pub p_det_ci: (f64, f64),
    /// Exact detection probability (model).
    pub p_det_exact: f64,
    /// Gaussian detection probability (Eq. 5).
    pub p_det_gauss: f64,
    /// Measured false-alarm probability per pixel-plane.
    pub p_fa: f64,
    /// Its 95 % interval.
    pub p_fa_ci: (f64, f64),
    /// Exact false-alarm probability (model).
    pub p_fa_exact: f64,
    /// Gaussian false-alarm probability.
    pub p_fa_gauss: f64,
}

/// One N of part B.
#[derive(Debug, Clone, PartialEq)]
pub struct PrecisionPoint {
    /// Window, planes.
    pub n: u32,
    /// Open threshold T_open (the pipeline's T_int).
    pub t_int: u32,
    /// Hold threshold T_hold (Eq. 7 at this N).
    pub t_hold: u32,
    /// Confirmation length, planes.
    pub l_min: u32,
    /// Blinks simulated.
    pub blinks: usize,
    /// Blinks with a matched localisation.
    pub detected: usize,
    /// Matched localisations.
    pub matches: u64,
    /// Records.
    pub records: u64,
    /// Records without a match.
    pub false_pos: u64,
    /// RMS error.
    pub rms: Estimate,
    /// Wall time of this pipeline and its fits, s.
    pub seconds: f64,
}

/// The study's result.
#[derive(Debug, Clone)]
pub struct DetectionResult {
    /// Derived N.
    pub n0: u32,
    /// Derived T_int.
    pub t0: u64,
    /// Part A.
    pub windows: Vec<WindowPoint>,
    /// Planes of part A (molecule field), and background planes.
    pub planes: (u64, u64),
    /// Part B.
    pub precision: Vec<PrecisionPoint>,
    /// Recording length of part B, s.
    pub acquisition_s: f64,
    /// Wall time of part A (simulation + measurement + exact statistics), s.
    pub seconds_a: f64,
    /// Mean and variance of F per plane, background pixels: measured, model.
    pub f_off: ((f64, f64), (f64, f64)),
    /// The same at the molecules' pixels.
    pub f_on: ((f64, f64), (f64, f64)),
}

impl DetectionResult {
    /// The part-A point at the derived N and z = 3.
    pub fn derived(&self) -> Option<&WindowPoint> {
        self.windows
            .iter()
            .find(|w| w.n == self.n0 && (w.z - 3.0).abs() < 1e-9)
    }
}

fn threshold(det: &Detection, n: u32, z: f64) -> u64 {
    let t = n as f64 * det.e_f_off + z * (n as f64 * det.var_f_off).sqrt();
    ((t / det.threshold_unit).ceil() as u64).max(1)
}

/// F per plane at each of `pixels` (centre coordinates) of a `side` field.
fn filtered_series(
    sim: &mut SpadSimulator,
    side: usize,
    planes: u64,
    k1: &[u32],
    pixels: &[(usize, usize)],
) -> Vec<Vec<u64>> {
    let h = k1.len() / 2;
    let mut out = vec![Vec::with_capacity(planes as usize); pixels.len()];
    let mut row = vec![0u64; side * side];
    for _ in 0..planes {
        let plane = sim.next_plane();
        let bits: Vec<u8> = (0..side * side)
            .map(|i| plane.get(i % side, i / side) as u8)
            .collect();
        // Horizontal pass.
        for y in 0..side {
            for x in h..side - h {
                let mut s = 0u64;
                for (k, &w) in k1.iter().enumerate() {
                    s += w as u64 * bits[y * side + x + k - h] as u64;
                }
                row[y * side + x] = s;
            }
        }
        for (p, &(x, y)) in pixels.iter().enumerate() {
            let mut s = 0u64;
            for (k, &w) in k1.iter().enumerate() {
                s += w as u64 * row[(y + k - h) * side + x];
            }
            out[p].push(s);
        }
    }
    out
}

/// Fraction of windows of `n` planes (every start) with `Σ F ≥ t`, over
/// all series.
fn window_fraction(prefix: &[Vec<u64>], n: usize, t: u64) -> (u64, u64) {
    let (mut hit, mut tot) = (0u64, 0u64);
    for p in prefix {
        for e in n..p.len() {
            tot += 1;
            if p[e] - p[e - n] >= t {
                hit += 1;
            }
        }
    }
    (hit, tot)
}

/// Runs the study.
pub fn compute(seed: u64, quick: bool, blinks: Option<u32>) -> Result<DetectionResult, StudyError> {
    let setup = Setup::new(PresetName::Spcimager, 150)?;
    let (det, _, _) = smart_config(&setup.preset, setup.field, None)?;
    let Camera::Spad(cam) = setup.preset.camera.clone() else {
        unreachable!("SPCIMAGER is a SPAD")
    };
    let t_a = Instant::now();
    let (mol_planes, bg_planes) = if quick {
        (400_000, 60_000)
    } else {
        (2_000_000, 200_000)
    };
    let k1 = det.kernel_weights.clone();
    let h = k1.len() / 2;
    let px = setup.pixel_nm;
    // Four molecules 17 px apart, on pixel centres.
    let side_m = 34usize;
    let centres = [(8usize, 8usize), (25, 8), (8, 25), (25, 25)];
    let mol_blinks: Vec<ExplicitBlink> = centres
        .iter()
        .enumerate()
        .map(|(i, &(x, y))| ExplicitBlink {
            emitter: i as u64,
            position: Position {
                x_nm: (x as f64 + 0.5) * px,
                y_nm: (y as f64 + 0.5) * px,
            },
            t_on_s: -1.0,
            t_off_s: 1e6,
            flux_factor: 1.0,
        })
        .collect();
    let side_b = 24usize;
    let bg_pixels: Vec<(usize, usize)> = (h..side_b - h)
        .flat_map(|y| (h..side_b - h).map(move |x| (x, y)))
        .collect();
    let (mol, bg) = rayon::join(
        || -> Result<Vec<Vec<u64>>, StudyError> {
            let scene =
                explicit_scene(&setup.preset, side_m as u32, side_m as u32, 1.0, mol_blinks);
            let maps = smartagg_scene::uniform_maps(&cam, side_m as u32, side_m as u32);
            let mut sim = SpadSimulator::with_maps(
                &cam,
                &scene,
                maps,
                derive_seed(&[seed, key_hash("det-mol")]),
            )?;
            Ok(filtered_series(&mut sim, side_m, mol_planes, &k1, &centres))
        },
        || -> Result<Vec<Vec<u64>>, StudyError> {
            let scene =
                explicit_scene(&setup.preset, side_b as u32, side_b as u32, 1.0, Vec::new());
            let maps = smartagg_scene::uniform_maps(&cam, side_b as u32, side_b as u32);
            let mut sim = SpadSimulator::with_maps(
                &cam,
                &scene,
                maps,
                derive_seed(&[seed, key_hash("det-bg")]),
            )?;
            Ok(filtered_series(
                &mut sim, side_b, bg_planes, &k1, &bg_pixels,
            ))
        },
    );
    let prefix = |v: Vec<Vec<u64>>| -> Vec<Vec<u64>> {
        v.into_iter()
            .map(|s| {
                let mut p = Vec::with_capacity(s.len() + 1);
                p.push(0u64);
                let mut acc = 0u64;
                for x in s {
                    acc += x;
                    p.push(acc);
                }
                p
            })
            .collect()
    };
    let (mol, bg) = (mol?, bg?);
    let moments = |v: &[Vec<u64>]| {
        let (mut s, mut s2, mut n) = (0.0f64, 0.0f64, 0.0f64);
        for x in v.iter().flatten() {
            let x = *x as f64 * det.threshold_unit;
            s += x;
            s2 += x * x;
            n += 1.0;
        }
        let m = s / n.max(1.0);
        (m, (s2 / n.max(1.0) - m * m).max(0.0))
    };
    let f_off = (moments(&bg), (det.e_f_off, det.var_f_off));
    let f_on = (moments(&mol), (det.e_f_on, det.var_f_on));
    let (mol, bg) = (prefix(mol), prefix(bg));
    let grid: Vec<(u32, f64)> = N_FACTORS
        .iter()
        .flat_map(|&f| {
            let n = ((det.n_window as f64 * f).round() as u32).max(1);
            Z.iter().map(move |&z| (n, z))
        })
        .collect();
    let windows: Vec<WindowPoint> = grid
        .par_iter()
        .map(|&(n, z)| -> Result<WindowPoint, StudyError> {
            let t_int = threshold(&det, n, z);
            let (dh, dt) = window_fraction(&mol, n as usize, t_int);
            let (fh, ft) = window_fraction(&bg, n as usize, t_int);
            // Independent windows: one per N planes per series.
            let d_eff = dt as f64 / n as f64;
            let f_eff = ft as f64 / n as f64;
            let p_det = dh as f64 / dt.max(1) as f64;
            let p_fa = fh as f64 / ft.max(1) as f64;
            let mut d2 = det.clone();
            d2.n_window = n;
            d2.threshold_int = t_int;
            let exact_det = detection_probability(&d2).map_err(|e| StudyError::Option {
                name: "detection",
                why: e.to_string(),
            })?;
            let exact_fa = tail_probability(&det.kernel(), n, det.p_off, t_int).map_err(|e| {
                StudyError::Option {
                    name: "false alarm",
                    why: e.to_string(),
                }
            })?;
            let tn = t_int as f64 * det.threshold_unit;
            let nf = n as f64;
            Ok(WindowPoint {
                n,
                z,
                t_int,
                p_det,
                p_det_ci: wilson(p_det * d_eff, d_eff),
                p_det_exact: exact_det.detection,
                p_det_gauss: normal_sf((tn - nf * det.e_f_on) / (nf * det.var_f_on).sqrt()),
                p_fa,
                p_fa_ci: wilson(p_fa * f_eff, f_eff),
                p_fa_exact: exact_fa.p,
                p_fa_gauss: normal_sf((tn - nf * det.e_f_off) / (nf * det.var_f_off).sqrt()),
            })
        })
        .collect::<Result<_, _>>()?;
    let seconds_a = t_a.elapsed().as_secs_f64();

    // Part B.
    let n_b = blinks.unwrap_or(if quick { 200 } else { 500 }) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(&[seed, key_hash("det-blinks")]));
    let span = setup.field_nm() - 2.0 * setup.margin_nm;
    let mut t = 0.0;
    let mut bl = Vec::new();
    for i in 0..n_b {
        let gap = 0.030 - 0.040 * (1.0 - rng.gen::<f64>()).ln();
        let d = -0.030 * (1.0 - rng.gen::<f64>()).ln();
        bl.push(ExplicitBlink {
            emitter: i as u64,
            position: Position {
                x_nm: setup.margin_nm + rng.gen::<f64>() * span,
                y_nm: setup.margin_nm + rng.gen::<f64>() * span,
            },
            t_on_s: t + gap,
            t_off_s: t + gap + d,
            flux_factor: 1.0,
        });
        t += gap + d;
    }
    let end_s = t + 0.05;
    let truth: Vec<Truth> = bl
        .iter()
        .map(|b| Truth {
            x_nm: b.position.x_nm,
            y_nm: b.position.y_nm,
            t_on_s: b.t_on_s,
            t_off_s: b.t_off_s,
        })
        .collect();
    let cfgs: Vec<PipelineConfig> = N_FACTORS_B
        .iter()
        .map(|&f| {
            let n = ((det.n_window as f64 * f).round() as u32).max(1);
            field_design_config(
                &det.at_window(n),
                setup.field,
                setup.field,
                cam.plane_period_s,
            )
            .map(|(_, cfg)| cfg)
        })
        .collect::<Result<_, _>>()?;
    let scene = explicit_scene(&setup.preset, setup.field, setup.field, 1.0, bl);
    let planes = (end_s / cam.plane_period_s).ceil() as u64;
    // One recording per N (same seed: the same bit-planes), in parallel.
    let precision: Vec<PrecisionPoint> = cfgs
        .par_iter()
        .map(|cfg| -> Result<PrecisionPoint, StudyError> {
            let a = Instant::now();
            let run = run_spad(
                &cam,
                &scene,
                derive_seed(&[seed, key_hash("det-planes")]),
                planes,
                std::slice::from_ref(cfg),
                None,
            )?;
            let recs = &run.records[0];
            let (locs, _, failed) = fit_records(
                recs,
                cfg,
                setup.field,
                setup.pixel_nm,
                setup.sigma_px,
                cam.plane_period_s,
            );
            let lv: Vec<Loc> = locs.iter().map(TLoc::loc).collect();
            let o = outcome(&truth, &lv, 53.3, recs.len() as u32, failed as u32);
            let idx = resample_indices(seed, truth.len(), crate::spec::DEFAULT_BOOTSTRAP as usize);
            Ok(PrecisionPoint {
                n: cfg.n_window,
                t_int: cfg.threshold_int,
                t_hold: cfg.threshold_hold,
                l_min: cfg.l_min,
                blinks: truth.len(),
                detected: o.blinks.iter().filter(|b| b.matches > 0).count(),
                matches: o.blinks.iter().map(|b| b.matches as u64).sum(),
                records: recs.len() as u64,
                false_pos: o.false_pos as u64,
                rms: rms_estimate(&o.blinks, &idx),
                seconds: a.elapsed().as_secs_f64() - run.simulate_s,
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(DetectionResult {
        n0: det.n_window,
        t0: det.threshold_int,
        windows,
        planes: (mol_planes, bg_planes),
        precision,
        acquisition_s: end_s,
        seconds_a,
        f_off,
        f_on,
    })
}

fn e(v: f64) -> String {
    format!("{v:.3e}")
}

fn f1(v: Option<f64>) -> String {
    v.map_or("—".into(), |x| format!("{x:.1}"))
}

/// Writes points.csv (part A), precision.csv (part B), detection.png and summary.md.
pub fn write(dir: &Path, r: &DetectionResult) -> Result<(Vec<PathBuf>, Vec<String>), StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io(dir, e))?;
    let (mut files, mut warnings) = (Vec::new(), Vec::new());
    let mut csv = String::from("n,z,t_int,p_det,p_det_lo,p_det_hi,p_det_exact,p_det_gauss,p_fa,p_fa_lo,p_fa_hi,p_fa_exact,p_fa_gauss\n");
    for w in &r.windows {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            w.n,
            w.z,
            w.t_int,
            w.p_det,
            w.p_det_ci.0,
            w.p_det_ci.1,
            w.p_det_exact,
            w.p_det_gauss,
            w.p_fa,
            w.p_fa_ci.0,
            w.p_fa_ci.1,
            w.p_fa_exact,
            w.p_fa_gauss
        );
    }
    let p = dir.join("points.csv");
    write_text(&p, &csv)?;
    files.push(p);
    let mut csv = String::from("n,t_open,t_hold,l_min,blinks,detected,matches,records,false_pos,rms_nm,rms_lo_nm,rms_hi_nm,seconds\n");
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.3}"));
    for p in &r.precision {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{:.2}",
            p.n,
            p.t_int,
            p.t_hold,
            p.l_min,
            p.blinks,
            p.detected,
            p.matches,
            p.records,
            p.false_pos,
            o(p.rms.value),
            o(p.rms.lo),
            o(p.rms.hi),
            p.seconds
        );
    }
    let p = dir.join("precision.csv");
    write_text(&p, &csv)?;
    files.push(p);
    let png = dir.join("detection.png");
    match plot(&png, r) {
        Ok(()) => files.push(png),
        Err(e) => warnings.push(e.to_string()),
    }
    let mut m = String::new();
    let _ = writeln!(m, "# Study `detection`: detection and false-alarm probabilities against N and T, and localisation error against N (paper §3, Eq. 5–7)\n\n![detection](detection.png)\n\n## Set-up\n");
    let _ = writeln!(m, "- **Part A (per window)**: SPCIMAGER 150×, study light, uniform maps (η and median DCR everywhere, no hot pixels — the model's assumptions). Four molecules on throughout, each centred on a pixel centre ({} planes); a background-only 24×24 field ({} planes, 256 interior pixels). F = Σ K_int·B with the pipeline's integer kernel at each molecule's pixel and every interior background pixel; H = rolling sum over N planes; a window detects when H ≥ T_int. Derived: N = {}, T_int = {} (the paper's Eq. 7 threshold, the rule this part tests; the field design holds tracks at it and opens them at a higher T_open, part B). T for other (N, z): ⌈(N·E F_off + z·√(N·Var F_off))/2^−2a⌉ (z = 3 is Eq. 7). Every plane starts a window; the 95 % intervals (Wilson) count planes/N independent windows per series.", r.planes.0, r.planes.1, r.n0, r.t0);
    let _ = writeln!(m, "- **Exact** = the model's lattice computation (`false_alarm::detection_probability`, `false_alarm::tail_probability`); **Gaussian** = Eq. 5/7's normal approximation of H.");
    let _ = writeln!(m, "- **Part B (N against precision)**: one molecule at a time on the SPCIMAGER 32×32 field, exponential blink durations (mean 30 ms), gaps 30 ms + Exp(40 ms), {:.1} s of bit-planes; the pipeline (fast engine, packet path) with the field design at each N, as `smartagg aggregate --n-window N` makes it (T_hold = Eq. 7's threshold at that N, T_open the lowest threshold at which background alone opens at most 1 false blink/s over the 32×32 field, r_assoc = round(2σ), L_min = 1, end_trim = ⌊N/2⌋), on the same bit-planes; every record fitted (Poisson MLE, σ fitted). **Truth matching**: within 53.3 nm of a blink whose on-time overlaps the record's summed planes; nearest wins; unmatched records are false positives.\n", r.acquisition_s);
    if let Some(d) = r.derived() {
        let holds = d.p_det_ci.1 >= 0.99 && d.p_det >= 0.985;
        let _ = writeln!(m, "## Does Eq. 5's ≈ 99 % hold?\n\n**{}**: at the derived N = {} and T_int = {}, the measured detection probability of a molecule on for the whole window is **{:.4}** [95 %: {:.4}, {:.4}] (exact {:.4}, Gaussian {:.4}). The measured false-alarm probability per pixel-plane is **{}** [{}, {}]: exact {} and Gaussian {} — the Gaussian approximation misses the background tail by a factor {:.2} (the sum of few-photon Bernoulli counts is right-skewed), and the model's exact statistics predict the measurement.\n",
            if holds { "Yes" } else { "No" },
            d.n, d.t_int, d.p_det, d.p_det_ci.0, d.p_det_ci.1, d.p_det_exact, d.p_det_gauss,
            e(d.p_fa), e(d.p_fa_ci.0), e(d.p_fa_ci.1), e(d.p_fa_exact), e(d.p_fa_gauss),
            d.p_fa_exact / d.p_fa_gauss.max(1e-300));
    }
    let _ = writeln!(m, "Per-plane moments of F (normalised units), measured vs model: background mean {:.5} vs {:.5}, variance {:.5} vs {:.5}; molecule pixel mean {:.5} vs {:.5}, variance {:.5} vs {:.5}.\n", r.f_off.0 .0, r.f_off.1 .0, r.f_off.0 .1, r.f_off.1 .1, r.f_on.0 .0, r.f_on.1 .0, r.f_on.0 .1, r.f_on.1 .1);
    let _ = writeln!(m, "## Part A: every (N, T)\n\n| N | z | T_int | P(detect) measured [95 %] | exact | Gaussian | P(false alarm)/pixel-plane measured [95 %] | exact | Gaussian | exact/Gaussian |\n|---|---|---|---|---|---|---|---|---|---|");
    for w in &r.windows {
        let _ = writeln!(
            m,
            "| {} | {} | {} | {:.4} [{:.4}, {:.4}] | {:.4} | {:.4} | {} [{}, {}] | {} | {} | {:.2} |",
            w.n, w.z, w.t_int, w.p_det, w.p_det_ci.0, w.p_det_ci.1, w.p_det_exact, w.p_det_gauss,
            e(w.p_fa), e(w.p_fa_ci.0), e(w.p_fa_ci.1), e(w.p_fa_exact), e(w.p_fa_gauss),
            w.p_fa_exact / w.p_fa_gauss.max(1e-300)
        );
    }
    let _ = writeln!(
        m,
        "\nTime: part A took {:.1} s wall (simulation, filtering, exact statistics).\n",
        r.seconds_a
    );
    let _ = writeln!(m, "## Part B: localisation error against N\n\n| N | window ms | T_open | T_hold | L_min (ms) | detection | FP | records/blink | RMS nm [95 % CI] | localisations per s of acquisition | time s |\n|---|---|---|---|---|---|---|---|---|---|---|");
    for p in &r.precision {
        let _ = writeln!(
            m,
            "| {} | {:.1} | {} | {} | {} ({:.1}) | {:.1} % | {:.1} % | {:.2} | {} [{}, {}] | {:.1} | {:.1} |",
            p.n,
            p.n as f64 * 0.1,
            p.t_int,
            p.t_hold,
            p.l_min,
            p.l_min as f64 * 0.1,
            100.0 * p.detected as f64 / p.blinks.max(1) as f64,
            100.0 * p.false_pos as f64 / p.records.max(1) as f64,
            p.matches as f64 / p.detected.max(1) as f64,
            f1(p.rms.value),
            f1(p.rms.lo),
            f1(p.rms.hi),
            p.matches as f64 / r.acquisition_s,
            p.seconds
        );
    }
    let _ = writeln!(m, "\nTime: wall seconds of the pipeline, packet path and fits for that N (the simulation is shared).\n\n## Where this differs from the paper, and why\n\n{}", super::notes::with_source("detection", super::notes::DETECTION));
    for w in &warnings {
        let _ = writeln!(m, "\n**Warning**: {w}");
    }
    let p = dir.join("summary.md");
    write_text(&p, &m)?;
    files.push(p);
    Ok((files, warnings))
}

fn plot(path: &Path, r: &DetectionResult) -> Result<(), StudyError> {
    let root = BitMapBackend::new(path, (1500, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let panels = root.split_evenly((1, 3));
    let z3: Vec<&WindowPoint> = r
        .windows
        .iter()
        .filter(|w| (w.z - 3.0).abs() < 1e-9)
        .collect();
    let nmax = r.windows.iter().map(|w| w.n).max().unwrap_or(1) as f64 * 1.05;
    // Miss probability (log) against N at z = 3.
    let lg = |p: f64| p.max(1e-7).log10();
    for (k, (title, ylab)) in [
        (
            "Miss probability 1 − P(detect), z = 3 (Eq. 7)",
            "log10 P(miss)",
        ),
        (
            "False alarms per pixel-plane, z = 3",
            "log10 P(false alarm)",
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let mut chart = ChartBuilder::on(&panels[k])
            .caption(title, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(0.0..nmax, -7.0..0.0)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("window N (planes)")
            .y_desc(ylab)
            .draw()
            .map_err(|e| plot_err(path, e))?;
        type Get = fn(&WindowPoint) -> f64;
        let series: [(&str, Get, RGBColor); 3] = if k == 0 {
            [
                ("measured", |w| 1.0 - w.p_det, colour(0)),
                ("exact (model)", |w| 1.0 - w.p_det_exact, colour(1)),
                ("Gaussian (Eq. 5)", |w| 1.0 - w.p_det_gauss, colour(2)),
            ]
        } else {
            [
                ("measured", |w| w.p_fa, colour(0)),
                ("exact (model)", |w| w.p_fa_exact, colour(1)),
                ("Gaussian (Eq. 7)", |w| w.p_fa_gauss, colour(2)),
            ]
        };
        for (name, get, col) in series {
            chart
                .draw_series(LineSeries::new(
                    z3.iter().map(|w| (w.n as f64, lg(get(w)))),
                    col.stroke_width(2),
                ))
                .map_err(|e| plot_err(path, e))?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2))
                });
            chart
                .draw_series(
                    z3.iter()
                        .map(|w| Circle::new((w.n as f64, lg(get(w))), 4, col.filled())),
                )
                .map_err(|e| plot_err(path, e))?;
        }
        if k == 0 {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(0.0, -2.0), (nmax, -2.0)],
                    BLACK.stroke_width(1),
                )))
                .map_err(|e| plot_err(path, e))?
                .label("1 % miss (Eq. 5's 99 %)")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(1))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| plot_err(path, e))?;
    }
    let ymax = r
        .precision
        .iter()
        .filter_map(|p| p.rms.hi.or(p.rms.value))
        .fold(0.0, f64::max)
        .max(1.0)
        * 1.15;
    let mut chart = ChartBuilder::on(&panels[2])
        .caption(
            "Part B: RMS error and detection against N",
            ("sans-serif", 17),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .right_y_label_area_size(55)
        .build_cartesian_2d(0.0..nmax, 0.0..ymax)
        .map_err(|e| plot_err(path, e))?
        .set_secondary_coord(0.0..nmax, 0.0..100.0);
    chart
        .configure_mesh()
        .x_desc("window N (planes; × 0.1 ms)")
        .y_desc("RMS error (nm)")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_secondary_axes()
        .y_desc("blinks detected (%)")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    let c0 = colour(0);
    chart
        .draw_series(LineSeries::new(
            r.precision
                .iter()
                .filter_map(|p| p.rms.value.map(|v| (p.n as f64, v))),
            c0.stroke_width(2),
        ))
        .map_err(|e| plot_err(path, e))?
        .label("RMS error")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c0.stroke_width(2)));
    for p in &r.precision {
        if let (Some(lo), Some(hi)) = (p.rms.lo, p.rms.hi) {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(p.n as f64, lo), (p.n as f64, hi)],
                    c0.stroke_width(1),
                )))
                .map_err(|e| plot_err(path, e))?;
        }
    }
    let c1 = colour(1);
    chart
        .draw_secondary_series(LineSeries::new(
            r.precision.iter().map(|p| {
                (
                    p.n as f64,
                    100.0 * p.detected as f64 / p.blinks.max(1) as f64,
                )
            }),
            c1.stroke_width(2),
        ))
        .map_err(|e| plot_err(path, e))?
        .label("detection (right axis)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c1.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}
