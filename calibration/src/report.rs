//! The report a person reads: Markdown summary, histogram PNG and pixel CSVs,
//! written beside the maps in the calibration directory.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::estimate::LN_20;
use super::frames::{FrameCalibration, FrameCamera};
use super::{flags, Calibration, CalibrationError};

/// Files the report wrote, and anything that could not be drawn.
#[derive(Debug, Clone, Default)]
pub struct ReportFiles {
    /// Files written.
    pub written: Vec<PathBuf>,
    /// Parts left out, with the reason (e.g. a PNG that could not be drawn).
    pub warnings: Vec<String>,
}

fn write_file(path: &Path, text: &str) -> Result<(), CalibrationError> {
    smartagg_io::output::write_atomic(path, text.as_bytes())
        .map_err(|e| CalibrationError::invalid("report", chain(&e)))
}

/// An error and its causes, `: `-separated (as anyhow's `{:#}`).
fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cause = c.source();
    }
    s
}

/// Log-spaced histogram of the positive values: (lower edge, upper edge, count).
fn log_bins(values: &[f64], bins: usize) -> Vec<(f64, f64, u32)> {
    let pos: Vec<f64> = values.iter().copied().filter(|&v| v > 0.0).collect();
    let (Some(lo), Some(hi)) = (
        pos.iter().copied().reduce(f64::min),
        pos.iter().copied().reduce(f64::max),
    ) else {
        return Vec::new();
    };
    let (lo, hi) = (lo / 1.2, hi * 1.2);
    let (llo, lhi) = (lo.ln(), hi.ln());
    let step = (lhi - llo) / bins as f64;
    let mut out: Vec<(f64, f64, u32)> = (0..bins)
        .map(|b| {
            (
                (llo + b as f64 * step).exp(),
                (llo + (b + 1) as f64 * step).exp(),
                0,
            )
        })
        .collect();
    for v in pos {
        let b = (((v.ln() - llo) / step) as usize).min(bins - 1);
        out[b].2 += 1;
    }
    out
}

/// A tick label on a log axis: plain numbers from 0.01 to 99,999, else
/// scientific.
fn tick(v: f64) -> String {
    if (0.01..100_000.0).contains(&v) {
        let digits = if v >= 10.0 {
            0
        } else if v >= 1.0 {
            1
        } else {
            2
        };
        format!("{v:.digits$}")
    } else {
        format!("{v:.1e}")
    }
}

/// A vertical marker on a histogram.
struct Marker {
    x: f64,
    label: String,
    colour: RGBColor,
}

fn histogram_png(
    path: &Path,
    title: &str,
    x_label: &str,
    values: &[f64],
    markers: &[Marker],
) -> Result<(), String> {
    let bins = log_bins(values, 60);
    if bins.is_empty() {
        return Err("no positive value to draw".into());
    }
    let (lo, hi) = (bins[0].0, bins[bins.len() - 1].1);
    let top = bins.iter().map(|b| b.2).max().unwrap_or(1) + 1;
    let root = BitMapBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d((lo..hi).log_scale(), 0u32..top)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("pixels")
        .x_label_formatter(&|v| tick(*v))
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(
            bins.iter()
                .map(|&(a, b, c)| Rectangle::new([(a, 0), (b, c)], BLUE.mix(0.6).filled())),
        )
        .map_err(|e| e.to_string())?;
    for m in markers.iter().filter(|m| m.x > lo && m.x < hi) {
        let colour = m.colour;
        chart
            .draw_series(LineSeries::new(
                vec![(m.x, 0), (m.x, top)],
                colour.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label(m.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    }
    if !markers.is_empty() {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

fn pct(x: f64) -> String {
    format!("{:.3} %", 100.0 * x)
}

/// Writes `report.md`, `dcr_histogram.png`, `hot_pixels.csv` and
/// `flagged_pixels.csv` of a SPAD calibration into `dir`.
pub fn write_spad_report(c: &Calibration, dir: &Path) -> Result<ReportFiles, CalibrationError> {
    let mut files = ReportFiles::default();
    let w = c.width as usize;
    let n = c.pixels();
    let d = &c.dark;
    let hc = &c.hot_criterion;

    // CSVs.
    let mut hot_csv = String::from("x,y,dcr_hz,dcr_sd_hz,flags\n");
    let mut all_csv = String::from("x,y,dcr_hz,dcr_sd_hz,prnu,prnu_sd,flags\n");
    for i in 0..n {
        let f = c.flags[i];
        if f == 0 {
            continue;
        }
        let (x, y) = (i % w, i / w);
        if f & flags::HOT != 0 {
            let _ = writeln!(
                hot_csv,
                "{x},{y},{:.6e},{:.6e},{}",
                c.dcr_hz[i],
                c.dcr_sd_hz[i],
                flags::names(f)
            );
        }
        let (p, ps) = match (&c.prnu, &c.prnu_sd) {
            (Some(p), Some(s)) => (format!("{:.6}", p[i]), format!("{:.6}", s[i])),
            _ => (String::new(), String::new()),
        };
        let _ = writeln!(
            all_csv,
            "{x},{y},{:.6e},{:.6e},{p},{ps},{}",
            c.dcr_hz[i],
            c.dcr_sd_hz[i],
            flags::names(f)
        );
    }
    for (name, text) in [
        ("hot_pixels.csv", &hot_csv),
        ("flagged_pixels.csv", &all_csv),
    ] {
        let p = dir.join(name);
        write_file(&p, text)?;
        files.written.push(p);
    }

    // Histogram.
    let png = dir.join("dcr_histogram.png");
    let mut markers = vec![Marker {
        x: d.median_dcr_hz,
        label: format!("median {:.4} Hz", d.median_dcr_hz),
        colour: BLACK,
    }];
    if let Some(crit) = hc.dcr_critical_hz {
        markers.push(Marker {
            x: crit,
            label: format!("hot above {crit:.4} Hz"),
            colour: RED,
        });
    }
    let zeros = c.dcr_hz.iter().filter(|&&v| v <= 0.0).count();
    let png_ok = match histogram_png(
        &png,
        &format!(
            "Dark-count rate, {}x{} pixels, {} bit-planes",
            c.width, c.height, c.planes
        ),
        "dark-count rate (Hz, log scale)",
        &c.dcr_hz,
        &markers,
    ) {
        Ok(()) => {
            files.written.push(png.clone());
            true
        }
        Err(e) => {
            files
                .warnings
                .push(format!("DCR histogram {} not drawn: {e}", png.display()));
            false
        }
    };

    // Markdown.
    let mut md = String::new();
    let _ = writeln!(md, "# SPAD calibration: {}x{} pixels\n", c.width, c.height);
    let _ = writeln!(md, "| | |\n|---|---|");
    let _ = writeln!(
        md,
        "| dark recording | `{}`: {} bit-planes of {:.3} µs exposure ({:.3} s at {:.4} µs per plane) |",
        c.provenance.dark,
        c.planes,
        c.tau_s * 1e6,
        c.planes as f64 * c.plane_period_s,
        c.plane_period_s * 1e6
    );
    if let (Some(f), Some(fs)) = (&c.provenance.flat, &c.flat) {
        let _ = writeln!(
            md,
            "| flat recording | `{f}`: {} bit-planes of {:.3} µs exposure |",
            fs.planes,
            fs.tau_s * 1e6
        );
    }
    if let Some(p) = &c.provenance.preset {
        let obj = c
            .provenance
            .objective
            .map_or(String::new(), |o| format!(", {o}x objective"));
        let _ = writeln!(md, "| preset | {p}{obj} |");
    }
    let _ = writeln!(md, "| made by | {} |", c.provenance.created_by);
    if let Some(cmd) = &c.provenance.command {
        let _ = writeln!(md, "| command | `{cmd}` |");
    }

    let _ = writeln!(md, "\n## Dark-count rate\n");
    let _ = writeln!(md, "Per pixel: `DCR = −ln(1 − k/n)/τ` (k ones in n planes, pile-up corrected), uncertainty `√(p/(n(1−p)))/τ` (delta method).\n");
    let _ = writeln!(md, "| figure | value |\n|---|---|");
    let _ = writeln!(
        md,
        "| median DCR (all pixels) | {:.4} Hz |",
        d.median_dcr_hz
    );
    let _ = writeln!(
        md,
        "| mean DCR (neither hot nor saturated) | {:.4} Hz |",
        d.mean_dcr_hz
    );
    let _ = writeln!(
        md,
        "| DRNU measured (1.4826·MAD/median, neither hot nor saturated) | {} |",
        pct(d.drnu_measured)
    );
    let _ = writeln!(md, "| DRNU with counting noise removed | {} |", pct(d.drnu));
    let _ = writeln!(
        md,
        "| median per-pixel uncertainty / median DCR | {} |",
        pct(d.dcr_relative_sd_median)
    );
    let _ = writeln!(
        md,
        "| pixels with no dark count | {} (rate 0; below {:.4} Hz at 95 %) |",
        d.no_count_pixels,
        LN_20 / (c.planes as f64 * c.tau_s)
    );
    let _ = writeln!(
        md,
        "| saturated pixels (1 in every plane) | {} (finite lower estimate ln(2n)/τ = {:.4e} Hz) |",
        d.saturated_pixels,
        (2.0 * c.planes as f64).ln() / c.tau_s
    );

    let _ = writeln!(md, "\n### Precision\n");
    let achieved = d
        .precision_achieved
        .map_or("not stated (no count at the median pixel)".to_string(), pct);
    let bound = if d.planes_needed_is_bound {
        "at least "
    } else {
        ""
    };
    let _ = writeln!(
        md,
        "Requested relative DCR uncertainty at the median DCR: {}; reached: {}. Planes needed: {bound}{} ({bound}{:.2} s); recorded: {}.",
        pct(d.precision_requested),
        achieved,
        d.planes_needed,
        d.planes_needed as f64 * c.plane_period_s,
        c.planes
    );
    if d.planes_needed > c.planes || d.planes_needed_is_bound {
        let _ = writeln!(md, "\n**The recording is too short for the requested precision** (accepted with --allow-short).");
    }
    if png_ok {
        let _ = writeln!(md, "\n![DCR histogram](dcr_histogram.png)\n");
        if zeros > 0 {
            let _ = writeln!(md, "({zeros} pixels with DCR 0 are not on the log axis.)");
        }
    }

    let _ = writeln!(md, "\n## Hot pixels\n");
    let _ = writeln!(
        md,
        "Criterion (docs/DESIGN.md §3 stage 0): a pixel is hot when its own dark counts alone make the expected filtered sum reach the threshold, `N·(K_c·p_pix + (ΣK − K_c)·p_bg) ≥ T_int`, the other pixels at the median DCR plus the imaging background light.\n"
    );
    let _ = writeln!(md, "| | |\n|---|---|");
    let _ = writeln!(md, "| source | {} |", hc.source);
    let _ = writeln!(
        md,
        "| N, T_int | {} planes, {} |",
        hc.n_window, hc.threshold_int
    );
    let _ = writeln!(
        md,
        "| kernel k1 (sum 2^{}) | {:?}; K_c = {}, ΣK = {} |",
        hc.kernel_shift, hc.kernel_weights, hc.kernel_centre_weight, hc.kernel_sum
    );
    let _ = writeln!(
        md,
        "| background light per pixel | {:.4} Hz |",
        hc.background_light_hz
    );
    let _ = writeln!(md, "| neighbours' DCR | {:.4} Hz |", hc.neighbour_dcr_hz);
    match hc.dcr_critical_hz {
        Some(crit) => {
            let _ = writeln!(
                md,
                "| critical DCR | **{crit:.4} Hz** ({:.1}× the median) |",
                crit / d.median_dcr_hz.max(f64::MIN_POSITIVE)
            );
        }
        None => {
            let _ = writeln!(md, "| critical DCR | none: no rate crosses T_int alone |");
        }
    }
    let _ = writeln!(
        md,
        "| hot pixels | **{} of {} ({})** |",
        d.hot_pixels,
        n,
        pct(d.hot_fraction)
    );
    let _ = writeln!(
        md,
        "| within 3 sd of the critical DCR (call uncertain) | {} |",
        d.ambiguous_pixels
    );
    let _ = writeln!(
        md,
        "| expected H at the median pixel | {:.0} (T_int = {}) |",
        hc.expected_h(d.median_dcr_hz),
        hc.threshold_int
    );
    // How the mask follows the threshold: what other registers would mask.
    let _ = writeln!(md, "\nIf the pipeline runs with another threshold (same N and kernel):\n\n| T_int | critical DCR (Hz) | hot pixels |\n|---|---|---|");
    for f in [0.8, 0.9, 1.0, 1.1, 1.25, 1.5] {
        let t = ((hc.threshold_int as f64 * f).round() as u64).max(1);
        match hc.with_threshold(hc.n_window, t) {
            Ok(other) => {
                let crit = other
                    .dcr_critical_hz
                    .map_or("none reachable".to_string(), |c| format!("{c:.4}"));
                let _ = writeln!(
                    md,
                    "| {t} ({f:.2}×) | {crit} | {} |",
                    c.hot_mask_for(&other).count()
                );
            }
            Err(_) => {
                let _ = writeln!(
                    md,
                    "| {t} ({f:.2}×) | reached by the background alone | all |"
                );
            }
        }
    }
    let mut hot: Vec<usize> = (0..n).filter(|&i| c.flags[i] & flags::HOT != 0).collect();
    hot.sort_by(|&a, &b| c.dcr_hz[b].total_cmp(&c.dcr_hz[a]));
    if !hot.is_empty() {
        let _ = writeln!(md, "\nHottest pixels (all in `hot_pixels.csv`):\n\n| x | y | DCR (Hz) | sd (Hz) | flags |\n|---|---|---|---|---|");
        for &i in hot.iter().take(40) {
            let _ = writeln!(
                md,
                "| {} | {} | {:.4e} | {:.3e} | {} |",
                i % w,
                i / w,
                c.dcr_hz[i],
                c.dcr_sd_hz[i],
                flags::names(c.flags[i])
            );
        }
        if hot.len() > 40 {
            let _ = writeln!(md, "\n… and {} more.", hot.len() - 40);
        }
    }

    if let Some(fs) = &c.flat {
        let _ = writeln!(md, "\n## PRNU (flat recording)\n");
        let _ = writeln!(md, "Per pixel: photon response = flat rate − DCR (both pile-up corrected), divided by the mean response of the normalising pixels; uncertainty `√(sd_flat² + sd_dark²)/mean`.\n");
        let _ = writeln!(md, "| figure | value |\n|---|---|");
        let _ = writeln!(
            md,
            "| median detection rate in the flat | {:.4} Hz |",
            fs.median_rate_hz
        );
        let _ = writeln!(
            md,
            "| mean photon response (PRNU = 1) | {:.4} Hz over {} pixels |",
            fs.mean_response_hz, fs.normalising_pixels
        );
        let _ = writeln!(
            md,
            "| PRNU spread measured (std) | {} (robust {}) |",
            pct(fs.prnu_spread_measured),
            pct(fs.prnu_spread_robust)
        );
        let _ = writeln!(
            md,
            "| per-pixel PRNU uncertainty (RMS) | {} |",
            pct(fs.prnu_noise)
        );
        let _ = writeln!(
            md,
            "| PRNU spread with counting noise removed | **{}** |",
            pct(fs.prnu_spread)
        );
        let _ = writeln!(
            md,
            "| dead pixels (response < {} of the median) | {} |",
            pct(fs.dead_below),
            fs.dead_pixels
        );
        let _ = writeln!(
            md,
            "| pixels saturated in the flat | {} |",
            fs.flat_saturated_pixels
        );
        if fs.prnu_noise > fs.prnu_spread_measured * 0.5 {
            let _ = writeln!(md, "\nThe per-pixel uncertainty is not small against the spread: record a longer flat to resolve the PRNU pixel by pixel.");
        }
    }

    notes(&mut md, &c.provenance.notes, &files.warnings);
    let p = dir.join("report.md");
    write_file(&p, &md)?;
    files.written.push(p);
    Ok(files)
}

fn notes(md: &mut String, notes: &[String], warnings: &[String]) {
    if notes.is_empty() && warnings.is_empty() {
        return;
    }
    let _ = writeln!(md, "\n## Notes\n");
    for n in notes.iter().chain(warnings) {
        let _ = writeln!(md, "- {n}");
    }
}

/// Writes `report.md`, `read_noise_histogram.png` and `flagged_pixels.csv`
/// of a frame-camera calibration into `dir`.
pub fn write_frame_report(
    c: &FrameCalibration,
    dir: &Path,
) -> Result<ReportFiles, CalibrationError> {
    let mut files = ReportFiles::default();
    let w = c.width as usize;
    let n = c.pixels();
    let s = &c.summary;
    let mut csv = String::from("x,y,offset_adu,read_noise_adu,gain_adu_per_e,prnu,flags\n");
    for i in 0..n {
        let f = c.flags[i];
        if f == 0 {
            continue;
        }
        let g = c
            .gain_adu_per_e
            .as_ref()
            .map_or(String::new(), |g| format!("{:.6}", g[i]));
        let p = c
            .prnu
            .as_ref()
            .map_or(String::new(), |p| format!("{:.6}", p[i]));
        let _ = writeln!(
            csv,
            "{},{},{:.4},{:.4},{g},{p},{}",
            i % w,
            i / w,
            c.offset_adu[i],
            c.read_noise_adu[i],
            flags::names(f)
        );
    }
    let p = dir.join("flagged_pixels.csv");
    write_file(&p, &csv)?;
    files.written.push(p);

    let png = dir.join("read_noise_histogram.png");
    let markers = [Marker {
        x: s.read_noise_median_adu,
        label: format!("median {:.4} ADU", s.read_noise_median_adu),
        colour: BLACK,
    }];
    let png_ok = match histogram_png(
        &png,
        &format!(
            "Read noise, {}x{} pixels, {} dark frames",
            c.width, c.height, s.dark_frames
        ),
        "read noise (ADU rms, log scale)",
        &c.read_noise_adu,
        &markers,
    ) {
        Ok(()) => {
            files.written.push(png.clone());
            true
        }
        Err(e) => {
            files.warnings.push(format!(
                "read-noise histogram {} not drawn: {e}",
                png.display()
            ));
            false
        }
    };

    let name = match c.camera {
        FrameCamera::Emccd => "EMCCD",
        FrameCamera::Scmos => "sCMOS",
    };
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# {name} calibration: {}x{} pixels\n",
        c.width, c.height
    );
    let _ = writeln!(md, "| | |\n|---|---|");
    let _ = writeln!(
        md,
        "| dark stack | `{}`: {} frames |",
        c.provenance.dark, s.dark_frames
    );
    if let (Some(f), Some(k)) = (&c.provenance.flat, s.flat_frames) {
        let _ = writeln!(md, "| flat stack | `{f}`: {k} frames |");
    }
    let _ = writeln!(md, "| made by | {} |", c.provenance.created_by);
    if let Some(cmd) = &c.provenance.command {
        let _ = writeln!(md, "| command | `{cmd}` |");
    }
    let _ = writeln!(md, "\n## Results\n\n| figure | value |\n|---|---|");
    let _ = writeln!(
        md,
        "| median offset (mean of dark frames) | {:.4} ADU |",
        s.offset_median_adu
    );
    let _ = writeln!(
        md,
        "| median read noise | {:.4} ADU rms |",
        s.read_noise_median_adu
    );
    if let Some(e) = s.read_noise_median_e {
        let referred = if c.camera == FrameCamera::Emccd {
            " (input-referred)"
        } else {
            ""
        };
        let _ = writeln!(md, "| median read noise | {e:.4} e⁻ rms{referred} |");
    }
    match (s.gain_adu_per_e, s.gain_sd_adu_per_e) {
        (Some(g), Some(sd)) => {
            let _ = writeln!(
                md,
                "| gain ({}) | {g:.5} ± {sd:.5} ADU/e⁻ ({:.5} e⁻/ADU) |",
                s.gain_source,
                1.0 / g
            );
        }
        (Some(g), None) => {
            let _ = writeln!(md, "| gain ({}) | {g:.5} ADU/e⁻ |", s.gain_source);
        }
        _ => {
            let _ = writeln!(md, "| gain | not known (no flat stack, no preset) |");
        }
    }
    if c.camera == FrameCamera::Emccd {
        let _ = writeln!(
            md,
            "| excess-noise factor F² used | {:.5} (photon transfer: Δvar = F²·g·Δmean) |",
            s.excess_noise_f2
        );
        let _ = writeln!(
            md,
            "| dark values rejected as clock-induced-charge spikes | {} |",
            s.rejected_dark_values
        );
    }
    if let Some(gs) = s.gain_spread {
        let _ = writeln!(
            md,
            "| per-pixel gain spread (noise removed) | {} |",
            pct(gs)
        );
    }
    if let Some(m) = s.flat_signal_mean_adu {
        let _ = writeln!(md, "| mean flat signal above dark | {m:.3} ADU |");
    }
    if let (Some(ps), Some(pn)) = (s.prnu_spread, s.prnu_noise) {
        let _ = writeln!(
            md,
            "| PRNU spread (noise removed) | {} (per-pixel uncertainty {}) |",
            pct(ps),
            pct(pn)
        );
    }
    let _ = writeln!(
        md,
        "| clipped values (0 or 65535 ADU) | dark {}, flat {} |",
        s.clipped_dark_values, s.clipped_flat_values
    );
    let _ = writeln!(
        md,
        "| flagged pixels | hot {}, noisy {}, dead {}, saturated {}, unmeasured {} (all in `flagged_pixels.csv`) |",
        s.hot_pixels, s.noisy_pixels, s.dead_pixels, s.saturated_pixels, s.unmeasured_pixels
    );
    if png_ok {
        let _ = writeln!(md, "\n![read-noise histogram](read_noise_histogram.png)");
    }
    notes(&mut md, &c.provenance.notes, &files.warnings);
    let p = dir.join("report.md");
    write_file(&p, &md)?;
    files.written.push(p);
    Ok(files)
}
