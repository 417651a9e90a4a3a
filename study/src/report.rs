//! What a person reads: the CSV of every point, the ratios, the timing, a
//! PNG plot and a Markdown summary with the paper's claims checked.

use crate::acquisition::Setup;
use crate::error::StudyError;
use crate::item::ItemResult;
use crate::spec::{LMin, Method, Plan, StudyName, FIXED_FRAME_PLANES, MERGE_RADIUS_NM, ROI_SIDE};
use crate::stats::{summarise, Estimate, Summary};
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Detection rate below which a curve is drawn dotted (the paper's 90 %).
pub const DOTTED_BELOW: f64 = 0.9;

/// A CSV text field, quoted (RFC 4180) when it holds a comma, quote or newline.
fn text(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v}"))
}

fn fmt1(v: Option<f64>) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.1}"))
}

fn fmt2(v: Option<f64>) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.2}"))
}

fn ci1(e: &Estimate) -> String {
    match (e.value, e.lo, e.hi) {
        (Some(v), Some(l), Some(h)) => format!("{v:.1} [{l:.1}, {h:.1}]"),
        (Some(v), _, _) => format!("{v:.1}"),
        _ => "–".into(),
    }
}

fn ci2(e: &Estimate) -> String {
    match (e.value, e.lo, e.hi) {
        (Some(v), Some(l), Some(h)) => format!("{v:.2} [{l:.2}, {h:.2}]"),
        (Some(v), _, _) => format!("{v:.2}"),
        _ => "–".into(),
    }
}

/// `points.csv`: every scheme at every point (deterministic: no timing).
pub fn points_csv(plan: &Plan, s: &Summary) -> String {
    let mut out = format!(
        "study,{},scheme,label,reference,blinks,detected,detection_rate,matches,detections,false_pos,false_pos_rate,failed_fits,rms_nm,rms_lo_nm,rms_hi_nm,bias_x_nm,bias_y_nm,match_radius_nm\n",
        plan.axis.column()
    );
    for p in &s.points {
        for (sc, st) in plan.schemes.iter().zip(&p.schemes) {
            let _ = writeln!(
                out,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                plan.study,
                p.x,
                text(&sc.id),
                text(&sc.label),
                sc.method.is_reference() as u8,
                st.blinks,
                st.detected,
                st.detection_rate(),
                st.matches,
                st.detections,
                st.false_pos,
                st.false_pos_rate(),
                st.failed_fits,
                opt(st.rms.value),
                opt(st.rms.lo),
                opt(st.rms.hi),
                opt(st.bias_x),
                opt(st.bias_y),
                plan.options.match_radius_nm
            );
        }
    }
    out
}

/// `ratios.csv`: every ratio at every point with its paired interval.
pub fn ratios_csv(plan: &Plan, s: &Summary) -> String {
    let mut out = format!(
        "study,{},ratio,numerator,denominator,denominator_point,value,lo,hi\n",
        plan.axis.column()
    );
    for p in &s.points {
        for (r, e) in plan.ratios.iter().zip(&p.ratios) {
            let _ = writeln!(
                out,
                "{},{},{},{},{},{},{},{},{}",
                plan.study,
                p.x,
                text(&r.label),
                text(&plan.schemes[r.num].id),
                text(&plan.schemes[r.den].id),
                r.den_point.map_or(p.x, |i| plan.points[i]),
                opt(e.value),
                opt(e.lo),
                opt(e.hi)
            );
        }
    }
    out
}

/// `timing.csv`: wall seconds per point and in total per stage.
pub fn timing_csv(plan: &Plan, s: &Summary) -> String {
    let mut out = format!("{},stage,count,seconds\n", plan.axis.column());
    for p in &s.points {
        let _ = writeln!(out, "{},all,,{}", p.x, p.seconds);
    }
    for t in &s.stages {
        let _ = writeln!(out, "all,{},{},{}", text(&t.stage), t.count, t.seconds);
    }
    out
}

/// A statement of the paper checked against this run.
#[derive(Debug, Clone, PartialEq)]
pub struct Claim {
    /// What the paper says.
    pub paper: String,
    /// The rule applied here.
    pub rule: String,
    /// What this run measured.
    pub measured: String,
    /// Whether the rule holds on this run.
    pub holds: bool,
}

fn ratio_at<'a>(plan: &Plan, s: &'a Summary, label: &str) -> Vec<(f64, &'a Estimate)> {
    let Some(r) = plan.ratios.iter().position(|r| r.label == label) else {
        return Vec::new();
    };
    s.points.iter().map(|p| (p.x, &p.ratios[r])).collect()
}

fn list(v: &[(f64, &Estimate)]) -> String {
    v.iter()
        .map(|(x, e)| format!("{x}: {}", ci2(e)))
        .collect::<Vec<_>>()
        .join("; ")
}

/// The paper's claims for this study, evaluated on `s`.
pub fn claims(plan: &Plan, s: &Summary) -> Vec<Claim> {
    let mut out = Vec::new();
    match plan.study {
        StudyName::SmartVsFixed => {
            let r = ratio_at(plan, s, "fixed / smart");
            let long: Vec<_> = r.iter().filter(|(x, _)| *x >= 50.0).copied().collect();
            out.push(Claim {
                paper:
                    "smart aggregation beats fixed aggregation, up to about 2x for longer blinks"
                        .into(),
                rule:
                    "RMS(fixed)/RMS(smart): lower 95 % bound above 1.3 at every duration >= 50 ms"
                        .into(),
                measured: format!("ratio [95 % CI] per ms: {}", list(&r)),
                holds: !long.is_empty() && long.iter().all(|(_, e)| e.lo.is_some_and(|l| l > 1.3)),
            });
        }
        StudyName::FutureSpad => {
            let r = ratio_at(plan, s, "current / projected (smart)");
            out.push(Claim {
                paper: "the projected SPAD roughly halves the error".into(),
                rule:
                    "RMS(current)/RMS(projected), smart: 95 % CI within [1.5, 3] at every duration"
                        .into(),
                measured: format!("ratio per ms: {}", list(&r)),
                holds: !r.is_empty()
                    && r.iter().all(|(_, e)| {
                        e.lo.is_some_and(|l| l >= 1.5) && e.hi.is_some_and(|h| h <= 3.0)
                    }),
            });
        }
        StudyName::Cameras => {
            for label in [
                "EMCCD merged / projected smart",
                "sCMOS merged / projected smart",
            ] {
                let r = ratio_at(plan, s, label);
                let ok = r
                    .iter()
                    .filter(|(_, e)| e.value.is_some_and(|v| (2.0 / 3.0..=1.5).contains(&v)))
                    .count();
                out.push(Claim {
                    paper: "the projected SPAD with smart aggregation is comparable to EMCCD/sCMOS over most blink durations".into(),
                    rule: format!("{label}: within [2/3, 3/2] at more than half of the durations"),
                    measured: format!("{ok} of {}: {}", r.len(), list(&r)),
                    holds: 2 * ok > r.len(),
                });
            }
        }
        StudyName::Objective => {
            let r = ratio_at(plan, s, "SPCIMAGER 150x / 60x");
            let long: Vec<_> = r.iter().filter(|(x, _)| *x >= 50.0).copied().collect();
            out.push(Claim {
                paper: "60x reduces the current SPAD's error by about 20 % for longer blinks".into(),
                rule: "RMS(150x)/RMS(60x), SPCIMAGER smart: above 1 (lower bound > 1) at every duration >= 50 ms".into(),
                measured: format!("ratio per ms: {}", list(&r)),
                holds: !long.is_empty() && long.iter().all(|(_, e)| e.lo.is_some_and(|l| l > 1.0)),
            });
            let r = ratio_at(plan, s, "projected 150x / 60x");
            let long: Vec<_> = r.iter().filter(|(x, _)| *x >= 50.0).copied().collect();
            out.push(Claim {
                paper: "60x has negligible effect on the projected SPAD".into(),
                rule: "RMS(150x)/RMS(60x), projected smart: within [0.9, 1.1] at every duration >= 50 ms".into(),
                measured: format!("ratio per ms: {}", list(&r)),
                holds: !long.is_empty()
                    && long
                        .iter()
                        .all(|(_, e)| e.value.is_some_and(|v| (0.9..=1.1).contains(&v))),
            });
        }
        StudyName::HotPixels => {
            for obj in ["150x", "60x"] {
                let r = ratio_at(plan, s, &format!("{obj} ignore / 0 % hot"));
                let low: Vec<_> = r
                    .iter()
                    .filter(|(x, _)| *x > 0.0 && *x < 10.0)
                    .copied()
                    .collect();
                out.push(Claim {
                    paper: "fewer than about 10 % hot pixels barely affect the error".into(),
                    rule: format!("{obj}, ignored: RMS(f)/RMS(0 %) below 1.15 for 0 < f < 10 %"),
                    measured: format!("ratio per %: {}", list(&r)),
                    holds: !low.is_empty()
                        && low.iter().all(|(_, e)| e.value.is_some_and(|v| v < 1.15)),
                });
                let r = ratio_at(plan, s, &format!("{obj} interpolate / ignore"));
                let hot: Vec<_> = r.iter().filter(|(x, _)| *x > 0.0).copied().collect();
                let better = hot
                    .iter()
                    .filter(|(_, e)| e.value.is_some_and(|v| v >= 1.0))
                    .count();
                out.push(Claim {
                    paper: "ignoring hot pixels beats interpolating them".into(),
                    rule: format!(
                        "{obj}: RMS(interpolate)/RMS(ignore) >= 1 at every hot-pixel fraction > 0"
                    ),
                    measured: format!("{better} of {}: {}", hot.len(), list(&r)),
                    holds: !hot.is_empty() && better == hot.len(),
                });
            }
        }
        StudyName::Localizers => {}
    }
    out
}

/// Writes the final outputs of a study (points.csv, ratios.csv, timing.csv,
/// NAME.png, summary.md) to `dir`; returns the files written. A plot that
/// cannot be drawn (no font, say) is reported in the summary and returned
/// as a warning rather than losing the tables.
pub fn finalize(
    dir: &Path,
    plan: &Plan,
    items: &[ItemResult],
    provenance: &str,
) -> Result<(Vec<PathBuf>, Vec<String>), StudyError> {
    std::fs::create_dir_all(dir).map_err(|e| StudyError::io(dir, e))?;
    let summary = summarise(plan, items);
    let setups = crate::run::setups(plan)?;
    let mut written = Vec::new();
    let mut warnings = Vec::new();
    for (name, text) in [
        ("points.csv", points_csv(plan, &summary)),
        ("ratios.csv", ratios_csv(plan, &summary)),
        ("timing.csv", timing_csv(plan, &summary)),
    ] {
        let p = dir.join(name);
        crate::experiment::common::write_text(&p, &text)?;
        written.push(p);
    }
    let png = dir.join(format!("{}.png", plan.study));
    match plot(&png, plan, &summary) {
        Ok(()) => written.push(png.clone()),
        Err(e) => warnings.push(e.to_string()),
    }
    let md = markdown(plan, &summary, &setups, provenance, &png, &warnings);
    let p = dir.join("summary.md");
    crate::experiment::common::write_text(&p, &md)?;
    written.push(p);
    Ok((written, warnings))
}

fn describe_setups(plan: &Plan, setups: &[Setup]) -> String {
    let mut s = String::new();
    for (ci, (c, st)) in plan.configs.iter().zip(setups).enumerate() {
        let _ = write!(
            s,
            "- **{}**: field {}x{} px of {:.1} nm, PSF sigma {:.3} px, background {:.1} Hz/px detected",
            c.label,
            st.field,
            st.field,
            st.pixel_nm,
            st.sigma_px,
            st.preset.background_rate_hz()
        );
        let uses = |f: fn(Method) -> bool| {
            plan.schemes
                .iter()
                .any(|sc| sc.config == ci && f(sc.method))
        };
        let smart = uses(|m| {
            matches!(
                m,
                Method::Smart | Method::SmartSpadMle | Method::Estimator(_)
            )
        });
        if let (true, Some((det, cfg)), Some(d)) = (smart, &st.spad, &st.design) {
            let over = |v: u32, design: u32| {
                if v == design {
                    String::new()
                } else {
                    format!(" (overridden; the design's is {design})")
                }
            };
            let _ = write!(
                s,
                "; smart: the field design of this {}x{} field at {} planes/s (as `smartagg aggregate` defaults to, with the study's fitted ROI size; false-blink budget {}/s over the field): N = {} planes, T_open = T_int = {} ({:.2} sd of background H above its mean; background alone opens at most {:.3} false blinks/s, predicted), T_hold = {} (Eq. 7's T = {:.4}, {:.2} sd), end_trim = {} (a blink sums the planes [t_cross − N, t_drop − {}], to its estimated end), kernel {:?} (sum 2^{}), L_min = {}{}, r_assoc = {}{}, {} slots, ROI {}x{}",
                d.width,
                d.height,
                d.plane_rate_hz,
                d.budget_per_s,
                cfg.n_window,
                cfg.threshold_int,
                d.open_sigmas,
                d.predicted_false_blinks_per_s,
                cfg.threshold_hold,
                det.threshold,
                d.hold_sigmas,
                cfg.end_trim,
                cfg.end_trim,
                cfg.kernel,
                cfg.kernel_shift,
                cfg.l_min,
                over(cfg.l_min, d.l_min),
                cfg.r_assoc,
                over(cfg.r_assoc, d.r_assoc),
                cfg.slots,
                cfg.roi_size,
                cfg.roi_size
            );
        }
        if let (true, Some(p)) = (uses(|m| m == Method::SmartPaper), &st.paper) {
            let _ = write!(
                s,
                "; the paper's scheme: one threshold T_int = {} (opens and holds), end_trim = {} (a blink sums [t_cross − N, t_drop]), L_min = {}, r_assoc = {}, the same N, kernel, slots and ROI",
                p.threshold_int, p.end_trim, p.l_min, p.r_assoc
            );
        }
        s.push('\n');
    }
    if let Some(cal) = &plan.options.calibration {
        let _ = writeln!(
            s,
            "- **Calibrated sensor**: the SPCIMAGER configurations simulate the maps of `{}` (`smartagg calibrate`) instead of the preset's synthetic ones: each work item takes a field-sized crop at an offset drawn from its seed; dark counts are the measured DCR of each pixel, detection efficiency PDE x fill factor x the measured PRNU; pixels whose dark counts alone would reach the configuration's hold level (the calibration's criterion at its N and T_hold, the paper's Eq. 7 threshold: such a pixel would keep a neighbouring track on, as `smartagg aggregate --calibration` judges it) are masked in the smart pipelines, left out of the record fits and handled by the fixed-frame hot-pixel curves. The other cameras are not the calibrated one and keep their synthetic maps.",
            cal.id
        );
    }
    s
}

fn markdown(
    plan: &Plan,
    s: &Summary,
    setups: &[Setup],
    provenance: &str,
    png: &Path,
    warnings: &[String],
) -> String {
    let o = &plan.options;
    let mut m = String::new();
    let _ = writeln!(m, "# `{}` — {}\n", plan.study, plan.study.title());
    let _ = writeln!(m, "{provenance}\n");
    let _ = writeln!(
        m,
        "{} blinks per point in work items of {} (seed {}, {} bootstrap resamples{}); smart scheme: the field design{}{}; frame threshold {}; sigma {}.\n",
        o.blinks_per_point,
        o.block,
        o.seed,
        o.bootstrap,
        if o.quick { ", --quick" } else { "" },
        match o.l_min {
            LMin::Design => String::new(),
            LMin::Planes(l) => format!(", L_min {l} (override)"),
        },
        o.r_assoc
            .map_or(String::new(), |r| format!(", r_assoc {r} (override)")),
        o.frame_threshold,
        if o.fit_sigma {
            "fitted (ThunderSTORM's default)"
        } else {
            "fixed to the optics' value"
        }
    );
    if warnings.is_empty() {
        let _ = writeln!(
            m,
            "![{}]({})\n",
            plan.study,
            png.file_name()
                .map_or(String::new(), |f| f.to_string_lossy().into_owned())
        );
    } else {
        for w in warnings {
            let _ = writeln!(m, "**The plot could not be drawn:** {w}\n");
        }
    }
    let _ = writeln!(m, "## Set-up\n");
    m.push_str(&describe_setups(plan, setups));
    let _ = writeln!(m);
    m.push_str(METHOD_TEXT);
    let _ = writeln!(
        m,
        "- **Truth matching**: a localisation matches a blink if it is within {} nm of the true position and its time interval (summed bit-planes, frame exposure, or merged frames) overlaps the blink's on-time; nearest blink wins; unmatched localisations are false positives; a blink without a match is missed. Every match counts in the RMS (several per blink for frames).",
        o.match_radius_nm
    );
    let _ = writeln!(
        m,
        "- **Fixed SPAD frames**: consecutive {FIXED_FRAME_PLANES}-plane sums of the same bit-planes; EMCCD/sCMOS: 50 ms frames; merging joins localisations of consecutive frames within {MERGE_RADIUS_NM} nm. Fitted ROIs are {ROI_SIDE}x{ROI_SIDE}.\n"
    );
    let _ = writeln!(m, "## Results\n");
    if plan.study == StudyName::Localizers {
        localizer_table(&mut m, plan, s);
    } else {
        let _ = writeln!(
            m,
            "RMS error in nm with its 95 % bootstrap interval; detection = blinks matched / blinks (curves are dotted below {:.0} %); FP = detections (smart records or frame candidates) without a matched localisation / detections; locs/blink = matched localisations per detected blink; time = wall seconds spent on the whole point (all schemes).\n",
            DOTTED_BELOW * 100.0
        );
        let _ = writeln!(
            m,
            "| {} | scheme | RMS nm [95 % CI] | detection | FP | locs/blink | bias x, y nm | time s |",
            plan.axis.label()
        );
        let _ = writeln!(m, "|---|---|---|---|---|---|---|---|");
        for p in &s.points {
            for (sc, st) in plan.schemes.iter().zip(&p.schemes) {
                let _ = writeln!(
                    m,
                    "| {} | {} | {} | {:.1} % | {:.1} % | {} | {}, {} | {:.1} |",
                    p.x,
                    sc.label,
                    ci1(&st.rms),
                    100.0 * st.detection_rate(),
                    100.0 * st.false_pos_rate(),
                    if st.detected > 0 {
                        format!("{:.2}", st.matches as f64 / st.detected as f64)
                    } else {
                        "–".into()
                    },
                    fmt1(st.bias_x),
                    fmt1(st.bias_y),
                    p.seconds
                );
            }
        }
    }
    let _ = writeln!(m, "\n## Ratios (paired bootstrap over the same blinks)\n");
    let _ = writeln!(m, "| {} | ratio | value [95 % CI] |", plan.axis.label());
    let _ = writeln!(m, "|---|---|---|");
    for p in &s.points {
        for (r, e) in plan.ratios.iter().zip(&p.ratios) {
            let _ = writeln!(m, "| {} | {} | {} |", p.x, r.label, ci2(e));
        }
    }
    let cl = claims(plan, s);
    if !cl.is_empty() {
        let _ = writeln!(m, "\n## The paper's claims on this run\n");
        for c in &cl {
            let _ = writeln!(
                m,
                "- **{}** — paper: {}. Rule: {}. Measured: {}.",
                if c.holds { "holds" } else { "does not hold" },
                c.paper,
                c.rule,
                c.measured
            );
        }
    }
    let _ = writeln!(m, "\n## Where this differs from the paper, and why\n");
    m.push_str(&crate::notes::notes(plan.study));
    let _ = writeln!(m, "\n## Time\n");
    let total: f64 = s.points.iter().map(|p| p.seconds).sum();
    let _ = writeln!(
        m,
        "{total:.1} s of worker time in total (summed over threads; wall time is about this divided by the cores). Per stage:\n"
    );
    let _ = writeln!(m, "| stage | units | seconds | units/s |");
    let _ = writeln!(m, "|---|---|---|---|");
    for t in &s.stages {
        let _ = writeln!(
            m,
            "| {} | {} | {:.2} | {:.0} |",
            t.stage,
            t.count,
            t.seconds,
            if t.seconds > 0.0 {
                t.count as f64 / t.seconds
            } else {
                0.0
            }
        );
    }
    m
}

fn localizer_table(m: &mut String, plan: &Plan, s: &Summary) {
    let _ = writeln!(
        m,
        "Every estimator on the same smart-aggregated ROIs. CRLB ratio = RMS / sqrt(mean Cramér–Rao bound of the blinks' ideal aggregation). Fit speed from the wall time of each estimator's loop over the records it fitted, over the whole study; point time = wall seconds spent on the whole point (simulation, pipeline, every estimator). Truth matching as for every study: within the match radius and overlapping in time.\n"
    );
    let _ = writeln!(
        m,
        "| {} | estimator | RMS nm [95 % CI] | bias x, y nm | RMS / CRLB [95 % CI] | detection | FP | fits/s | µs/fit | point time s |",
        plan.axis.label()
    );
    let _ = writeln!(m, "|---|---|---|---|---|---|---|---|---|---|");
    for p in &s.points {
        for (i, (sc, st)) in plan.schemes.iter().zip(&p.schemes).enumerate() {
            let ratio = plan
                .ratios
                .iter()
                .position(|r| r.num == i)
                .map(|r| ci2(&p.ratios[r]))
                .unwrap_or_else(|| "1".into());
            let stage = format!("fit {}", sc.id);
            let speed = s.stages.iter().find(|t| t.stage == stage);
            let (fps, us) = match speed {
                Some(t) if t.seconds > 0.0 && t.count > 0 => (
                    format!("{:.0}", t.count as f64 / t.seconds),
                    format!("{:.1}", 1e6 * t.seconds / t.count as f64),
                ),
                _ => ("–".into(), "–".into()),
            };
            let _ = writeln!(
                m,
                "| {} | {} | {} | {}, {} | {} | {:.1} % | {:.1} % | {} | {} | {:.1} |",
                p.x,
                sc.method.as_str(),
                ci1(&st.rms),
                fmt2(st.bias_x),
                fmt2(st.bias_y),
                ratio,
                100.0 * st.detection_rate(),
                100.0 * st.false_pos_rate(),
                fps,
                us,
                p.seconds
            );
        }
    }
}

const METHOD_TEXT: &str = "- **Scene** (paper §4): one molecule on at a time at a random position (3 sigma from the edges) in the camera's study field, 50,000 photons/s, 70,000 background photons/s/um^2, every blink exactly the point's duration, gaps of 10 ms + Exp(40 ms). Every configuration of a point sees the same blinks (same times, same relative positions) as explicit blinks of the scene simulator, each camera with its own photon noise; each work item is one continuous recording per configuration.
- **Smart aggregation**: the model's pipeline (its fast engine, proven byte-identical to the golden pipeline by the model's tests) on the simulated bit-planes with the **field design** of each configuration's study field, as `smartagg aggregate` defaults to on a recording of that size and plane rate (`model::field_design`): N and the kernel from the paper's statistics; a track opens where H reaches T_open, the lowest threshold at which background alone opens at most 1 false blink/s over the field, and stays on while H stays at or above T_hold, the paper's Eq. 7 threshold; candidates within r_assoc = round(2 sigma) of a live track belong to it; L_min = 1; a blink sums the bit-planes from N before its crossing to its estimated end, t_drop − end_trim with end_trim = floor(N/2). `--l-min` and `--r-assoc` override the design's L_min and r_assoc. `smart (paper's scheme)` is the paper's literal scheme on the same bit-planes: one threshold T (Eq. 7) that opens and holds, L_min = 1, r_assoc = 1, each blink summed to t_drop (end_trim 0). Records go through the packetiser and the packet decoder (any loss is an error); each ROI is fitted with the Poisson MLE (and the SPAD binomial MLE with the record's on/off split where shown). Records whose summed planes and ROI cannot reach any blink are false positives whatever their fit and are not fitted.
- **Frame detection** (fixed SPAD frames, EMCCD, sCMOS, hot-pixel frames): B-spline wavelet (ThunderSTORM's default), 8-neighbour local maxima of the second wavelet level above the frame threshold times the std of the first; Poisson MLE of a 9x9 ROI (EMCCD: F^2 = 2 in the bound; sCMOS: per-pixel read variance). Hot pixels (known map) are interpolated for detection, then ignored or interpolated in the fit.
- **CRLB reference** (dashed): per blink, the SPAD binomial Cramér–Rao bound at its true position for an ideal aggregation of exactly its on-planes (no off-plane), in a 9x9 ROI centred on its pixel, sigma fixed or fitted as the fits; the curve is sqrt(mean(var_x + var_y)).
";

/// Colour of configuration `c`.
fn colour(c: usize) -> RGBColor {
    const C: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
    ];
    C[c % C.len()]
}

/// Colour of a scheme: by configuration, or by method when one configuration
/// carries several curves of the same kind.
fn scheme_colour(plan: &Plan, i: usize) -> RGBColor {
    let s = &plan.schemes[i];
    if plan.configs.len() == 1 {
        return colour(i);
    }
    let base = colour(s.config);
    match s.method {
        Method::Smart | Method::Frames | Method::HotIgnore => base,
        Method::SmartCrlb => RGBColor(base.0 / 2, base.1 / 2, base.2 / 2),
        _ => RGBColor(
            (base.0 as u16 / 2 + 110) as u8,
            (base.1 as u16 / 2 + 110) as u8,
            (base.2 as u16 / 2 + 110) as u8,
        ),
    }
}

/// Marker of a method: 0 circle, 1 triangle, 2 cross.
fn marker(m: Method) -> u8 {
    match m {
        Method::SmartSpadMle | Method::FramesMerged | Method::HotInterpolate => 1,
        Method::SmartPaper => 2,
        Method::Estimator(e) => (e as u8) % 3,
        _ => 0,
    }
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Plot {
        path: path.to_path_buf(),
        why: e.to_string(),
    }
}

/// Draws RMS error against x for every scheme: solid where the detection
/// rate is at least 90 %, dotted below, error bars for the 95 % intervals,
/// reference (CRLB) curves dashed.
pub fn plot(path: &Path, plan: &Plan, s: &Summary) -> Result<(), StudyError> {
    let xs: Vec<f64> = s.points.iter().map(|p| p.x).collect();
    let (xmin, xmax) = xs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let pad = ((xmax - xmin) * 0.05).max(1.0);
    let ymax_values = s
        .points
        .iter()
        .flat_map(|p| p.schemes.iter().filter_map(|st| st.rms.value))
        .fold(0.0f64, f64::max);
    let ymax = if ymax_values > 0.0 {
        ymax_values * 1.25
    } else {
        10.0
    };
    let root = BitMapBackend::new(path, (1100, 740)).into_drawing_area();
    let (plot_area, foot) = root.split_vertically(705);
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let mut chart = ChartBuilder::on(&plot_area)
        .caption(plan.study.title(), ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(65)
        .build_cartesian_2d((xmin - pad)..(xmax + pad), 0.0..ymax)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(plan.axis.label())
        .y_desc("RMS localisation error (nm)")
        .axis_desc_style(("sans-serif", 18))
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (i, sc) in plan.schemes.iter().enumerate() {
        let col = scheme_colour(plan, i);
        let style = col.stroke_width(2);
        // (x, RMS, detection rate, CI low, CI high)
        type Pt = (f64, Option<f64>, f64, Option<f64>, Option<f64>);
        let pts: Vec<Pt> = s
            .points
            .iter()
            .map(|p| {
                let st = &p.schemes[i];
                (p.x, st.rms.value, st.detection_rate(), st.rms.lo, st.rms.hi)
            })
            .collect();
        for w in pts.windows(2) {
            let (Some(y0), Some(y1)) = (w[0].1, w[1].1) else {
                continue;
            };
            let seg = vec![(w[0].0, y0.min(ymax)), (w[1].0, y1.min(ymax))];
            let low = w[0].2 < DOTTED_BELOW || w[1].2 < DOTTED_BELOW;
            if sc.method.is_reference() {
                chart
                    .draw_series(DashedLineSeries::new(seg, 10, 6, style))
                    .map_err(|e| plot_err(path, e))?;
            } else if low {
                chart
                    .draw_series(DashedLineSeries::new(seg, 2, 5, style))
                    .map_err(|e| plot_err(path, e))?;
            } else {
                chart
                    .draw_series(LineSeries::new(seg, style))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
        if !sc.method.is_reference() {
            for &(x, y, _, lo, hi) in &pts {
                if let (Some(lo), Some(hi)) = (lo, hi) {
                    let (lo, hi) = (lo.min(ymax), hi.min(ymax));
                    let cap = pad * 0.15;
                    chart
                        .draw_series(std::iter::once(PathElement::new(
                            vec![(x, lo), (x, hi)],
                            col.stroke_width(1),
                        )))
                        .map_err(|e| plot_err(path, e))?;
                    for yy in [lo, hi] {
                        chart
                            .draw_series(std::iter::once(PathElement::new(
                                vec![(x - cap, yy), (x + cap, yy)],
                                col.stroke_width(1),
                            )))
                            .map_err(|e| plot_err(path, e))?;
                    }
                }
                if let Some(y) = y {
                    let at = (x, y.min(ymax));
                    let drawn = match marker(sc.method) {
                        1 => chart.draw_series(std::iter::once(TriangleMarker::new(
                            at,
                            6,
                            col.filled(),
                        ))),
                        2 => chart.draw_series(std::iter::once(Cross::new(
                            at,
                            5,
                            col.stroke_width(2),
                        ))),
                        _ => chart.draw_series(std::iter::once(Circle::new(at, 4, col.filled()))),
                    };
                    drawn.map_err(|e| plot_err(path, e))?;
                }
            }
        }
        let reference = sc.method.is_reference();
        let mk = marker(sc.method);
        chart
            .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
            .map_err(|e| plot_err(path, e))?
            .label(sc.label.clone())
            .legend(move |(x, y)| {
                let style = col.stroke_width(2);
                let (seg1, seg2) = if reference {
                    (vec![(0, 0), (7, 0)], vec![(13, 0), (20, 0)])
                } else {
                    (vec![(0, 0), (20, 0)], vec![(20, 0), (20, 0)])
                };
                let shape: Vec<(i32, i32)> = match (reference, mk) {
                    (true, _) => Vec::new(),
                    (false, 1) => vec![(10, -5), (15, 4), (5, 4)],
                    (false, 2) => vec![
                        (8, -5),
                        (12, -5),
                        (12, -2),
                        (15, -2),
                        (15, 2),
                        (12, 2),
                        (12, 5),
                        (8, 5),
                        (8, 2),
                        (5, 2),
                        (5, -2),
                        (8, -2),
                    ],
                    _ => vec![
                        (8, -4),
                        (12, -4),
                        (14, -2),
                        (14, 2),
                        (12, 4),
                        (8, 4),
                        (6, 2),
                        (6, -2),
                    ],
                };
                EmptyElement::at((x, y))
                    + PathElement::new(seg1, style)
                    + PathElement::new(seg2, style)
                    + Polygon::new(shape, col.filled())
            });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    foot.draw(&Text::new(
        format!(
            "dotted segments: detection rate below {:.0} %;  dashed: Cramér–Rao bound;  bars: 95 % bootstrap CI;  localisations beyond {} nm of the truth are false",
            DOTTED_BELOW * 100.0,
            plan.options.match_radius_nm
        ),
        (70, 8),
        ("sans-serif", 14),
    ))
    .map_err(|e| plot_err(path, e))?;
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_text_is_quoted_only_when_needed() {
        assert_eq!(text("fixed / smart"), "fixed / smart");
        assert_eq!(text("a,b"), "\"a,b\"");
        assert_eq!(text("say \"hi\", twice"), "\"say \"\"hi\"\", twice\"");
    }
}
