//! `smartagg calibrate`: dark-count map, hot pixels and PRNU of a SPAD camera
//! from its own bit-plane recordings; offset, gain and read-noise maps of an
//! EMCCD or sCMOS camera from dark and flat stacks. Writes a calibration
//! directory (format in `calibration`'s docs) with a report beside it.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use smartagg_model::params::{Camera, PresetName};

use crate::setup;
use smartagg_calibration::frames::{calibrate_frames, FrameOptions, FrameSource, TiffStack};
use smartagg_calibration::spad::{calibrate_spad, Counted, CriterionSpec, SpadOptions};
use smartagg_calibration::{
    report, Calibration, FrameCalibration, FrameCamera, PlaneCounter, Provenance,
};

/// Which camera the recordings come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraArg {
    /// Binary SPAD camera: .spad bit-plane recordings (or raw packed planes).
    Spad,
    /// EMCCD: 16-bit TIFF frame stacks.
    Emccd,
    /// sCMOS: 16-bit TIFF frame stacks.
    Scmos,
}

/// Arguments of `smartagg calibrate`.
#[derive(clap::Args, Debug)]
#[command(mut_arg("preset", |a| a.help("Preset: for SPAD, sets N, T_int and the kernel of the hot-pixel criterion (default spcimager); for EMCCD/sCMOS, the gain used without a flat")))]
pub struct Args {
    /// Dark recording: .spad bit-planes (raw packed planes with --raw) for a
    /// SPAD camera, a 16-bit TIFF stack for EMCCD/sCMOS.
    #[arg(long)]
    pub dark: PathBuf,
    /// Uniformly lit flat recording or stack (PRNU; gain for frame cameras).
    #[arg(long)]
    pub flat: Option<PathBuf>,
    /// Output calibration directory (created; calibration files in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Camera kind (default: the preset's; else .tif/.tiff must say which, other files are SPAD).
    #[arg(long, value_enum)]
    pub camera: Option<CameraArg>,
    #[command(flatten)]
    pub preset: crate::setup::OptionalPresetArgs,
    /// Molecule flux for the preset's statistics, photons/s (default 50,000).
    #[arg(long)]
    pub flux: Option<f64>,
    /// Override the window N of the hot-pixel criterion (bit-planes).
    #[arg(long)]
    pub n_window: Option<u32>,
    /// Override the threshold T_int of the hot-pixel criterion.
    #[arg(long)]
    pub threshold_int: Option<u64>,
    /// Detected background light per pixel while imaging, Hz (default: the preset's).
    #[arg(long)]
    pub background_light_hz: Option<f64>,
    /// Relative DCR uncertainty wanted at the median DCR.
    #[arg(long, default_value_t = 0.05)]
    pub precision: f64,
    /// Accept a dark recording too short for --precision (with a warning).
    #[arg(long)]
    pub allow_short: bool,
    /// Use at most this many planes of each SPAD recording.
    #[arg(long)]
    pub max_planes: Option<u64>,
    /// A pixel responding to the flat with less than this fraction of the median is dead.
    #[arg(long, default_value_t = 0.1)]
    pub dead_below: f64,
    /// EMCCD: EM gain G, so that F² = 2 − 1/G (default F² = 2, the high-gain limit).
    #[arg(long)]
    pub em_gain: Option<f64>,
    #[command(flatten)]
    pub raw: setup::RawArgs,
    /// No progress line.
    #[arg(long)]
    pub quiet: bool,
}

fn preset_camera(name: &str) -> anyhow::Result<CameraArg> {
    Ok(match PresetName::parse(name)? {
        PresetName::Spcimager | PresetName::SpcimagerProjected | PresetName::Spad512s => {
            CameraArg::Spad
        }
        PresetName::Emccd => CameraArg::Emccd,
        PresetName::Scmos => CameraArg::Scmos,
    })
}

fn choose_camera(args: &Args) -> anyhow::Result<CameraArg> {
    let from_preset = args.preset.name.as_deref().map(preset_camera).transpose()?;
    Ok(match (args.camera, from_preset) {
        (Some(c), Some(p)) if c != p => bail!(
            "--camera {c:?} contradicts --preset {} (a {p:?} camera)",
            args.preset.name.as_deref().unwrap_or("")
        ),
        (Some(c), _) | (None, Some(c)) => c,
        (None, None) => {
            let ext = args
                .dark
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if matches!(ext.as_deref(), Some("tif" | "tiff")) {
                bail!(
                    "{} looks like a TIFF frame stack: say --camera emccd or --camera scmos",
                    args.dark.display()
                );
            }
            CameraArg::Spad
        }
    })
}

fn provenance(args: &Args) -> Provenance {
    Provenance {
        dark: args.dark.display().to_string(),
        flat: args.flat.as_ref().map(|f| f.display().to_string()),
        preset: None,
        objective: None,
        command: Some(std::env::args().collect::<Vec<_>>().join(" ")),
        created_by: format!("smartagg {}", env!("CARGO_PKG_VERSION")),
        created_unix_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .ok()
            .map(|d| d.as_secs()),
        notes: Vec::new(),
    }
}

/// Reads a SPAD recording into per-pixel counts.
fn count_planes(path: &Path, what: &str, args: &Args) -> anyhow::Result<Counted> {
    let file =
        std::fs::File::open(path).with_context(|| format!("opening {what} {}", path.display()))?;
    let mut reader = setup::open_recording(BufReader::with_capacity(1 << 20, file), &args.raw)
        .with_context(|| format!("reading {what} {}", path.display()))?;
    let h = *reader.header();
    let limit = args.max_planes.unwrap_or(u64::MAX);
    let total =
        (h.planes != smartagg_model::recording::PLANES_UNKNOWN).then(|| h.planes.min(limit));
    let progress = setup::progress(total, args.quiet);
    progress.set_message(what.to_string());
    let mut counter = PlaneCounter::new(h.width, h.height);
    while counter.planes() < limit {
        match reader
            .read_plane()
            .with_context(|| format!("reading {what} {}", path.display()))?
        {
            Some(p) => counter.push(&p)?,
            None => break,
        }
        progress.inc(1);
    }
    progress.finish_and_clear();
    Ok(Counted {
        counts: counter.finish(),
        tau_s: h.exposure_ns as f64 * 1e-9,
        plane_period_s: h.plane_period_ns as f64 * 1e-9,
    })
}

fn run_spad(args: &Args) -> anyhow::Result<()> {
    let preset_name = args
        .preset
        .name
        .clone()
        .unwrap_or_else(|| "spcimager".into());
    let (preset, det) = setup::detection(&preset_name, args.preset.objective, args.flux)?;
    let Camera::Spad(cam) = &preset.camera else {
        bail!("preset {preset_name} is not a SPAD camera");
    };
    let mut prov = provenance(args);
    prov.preset = Some(preset_name.clone());
    prov.objective = Some(args.preset.objective);
    let n_window = args.n_window.unwrap_or(det.n_window);
    let threshold_int = args.threshold_int.unwrap_or(det.threshold_int);
    let light = args
        .background_light_hz
        .unwrap_or((det.background_rate_hz - cam.dcr_median_hz).max(0.0));
    let mut source = format!(
        "preset {preset_name}, {}x objective, flux {} photons/s: N = {}, T_int = {}",
        args.preset.objective, det.flux_hz, det.n_window, det.threshold_int
    );
    if args.n_window.is_some() || args.threshold_int.is_some() {
        source.push_str(&format!(
            "; used N = {n_window}, T_int = {threshold_int} (overridden)"
        ));
    }
    let spec = CriterionSpec {
        n_window,
        threshold_int,
        kernel: det.kernel(),
        background_light_hz: light,
        source,
    };
    let dark = count_planes(&args.dark, "dark recording", args)?;
    let flat = match &args.flat {
        Some(f) => Some(count_planes(f, "flat recording", args)?),
        None => None,
    };
    if (dark.tau_s / cam.exposure_s - 1.0).abs() > 0.01 {
        prov.notes.push(format!(
            "the dark recording's exposure ({:.3} µs) differs from the preset's ({:.3} µs): N and T_int were derived for the preset's",
            dark.tau_s * 1e6,
            cam.exposure_s * 1e6
        ));
    }
    let options = SpadOptions {
        precision: args.precision,
        allow_short: args.allow_short,
        dead_below: args.dead_below,
    };
    let cal = calibrate_spad(&dark, flat.as_ref(), &spec, &options, prov)?;
    cal.save(&args.out)?;
    let files = report::write_spad_report(&cal, &args.out)?;
    // Read back what was written: the file is what the pipeline will use.
    let back = Calibration::load(&args.out)?;
    if back.hot_mask().count() != cal.dark.hot_pixels {
        bail!(
            "the calibration written to {} does not read back with the same hot pixels",
            args.out.display()
        );
    }
    let d = &cal.dark;
    println!(
        "{}x{} pixels, {} dark bit-planes: median DCR {:.4} Hz, DRNU {:.3} % ({:.3} % measured), {} hot pixels ({:.3} %) above {}, {} saturated, {} without counts",
        cal.width,
        cal.height,
        cal.planes,
        d.median_dcr_hz,
        100.0 * d.drnu,
        100.0 * d.drnu_measured,
        d.hot_pixels,
        100.0 * d.hot_fraction,
        cal.hot_criterion
            .dcr_critical_hz
            .map_or("no reachable DCR".to_string(), |c| format!("{c:.4} Hz")),
        d.saturated_pixels,
        d.no_count_pixels
    );
    println!(
        "precision at the median DCR: {} reached, {:.2} % requested, {}{} planes needed",
        d.precision_achieved
            .map_or("none".to_string(), |a| format!("{:.3} %", 100.0 * a)),
        100.0 * d.precision_requested,
        if d.planes_needed_is_bound {
            "at least "
        } else {
            ""
        },
        d.planes_needed
    );
    if let Some(f) = &cal.flat {
        println!(
            "flat: {} bit-planes, PRNU spread {:.3} % ({:.3} % measured, {:.3} % per-pixel noise), {} dead pixels",
            f.planes,
            100.0 * f.prnu_spread,
            100.0 * f.prnu_spread_measured,
            100.0 * f.prnu_noise,
            f.dead_pixels
        );
    }
    finish(&args.out, &cal.provenance.notes, &files)
}

fn finish(out: &Path, notes: &[String], files: &report::ReportFiles) -> anyhow::Result<()> {
    for n in notes.iter().chain(&files.warnings) {
        eprintln!("smartagg: warning: {n}");
    }
    println!(
        "calibration written to {} (report: {})",
        out.display(),
        out.join("report.md").display()
    );
    Ok(())
}

fn run_frames(args: &Args, camera: FrameCamera) -> anyhow::Result<()> {
    if args.raw.raw || args.max_planes.is_some() {
        bail!(
            "--raw and --max-planes apply to SPAD bit-plane recordings, not to {} frame stacks",
            camera.as_str()
        );
    }
    let mut prov = provenance(args);
    let fallback_gain = match &args.preset.name {
        Some(p) => {
            let preset =
                smartagg_model::params::Preset::new(PresetName::parse(p)?, args.preset.objective)?;
            prov.preset = Some(p.clone());
            match &preset.camera {
                Camera::Emccd(c) => Some((c.em_gain / c.e_per_adu, format!("preset {p}"))),
                Camera::Scmos(c) => Some((1.0 / c.e_per_adu, format!("preset {p}"))),
                Camera::Spad(_) => None,
            }
        }
        None => None,
    };
    let excess_noise_f2 = match args.em_gain {
        Some(g) if g.is_finite() && g >= 1.0 => 2.0 - 1.0 / g,
        Some(g) => bail!("--em-gain {g} must be at least 1"),
        None => 2.0,
    };
    let options = FrameOptions {
        camera,
        excess_noise_f2,
        dead_below: args.dead_below,
        fallback_gain,
    };
    let dark = TiffStack {
        path: args.dark.clone(),
    };
    let flat = args.flat.as_ref().map(|p| TiffStack { path: p.clone() });
    let cal = calibrate_frames(
        &dark,
        flat.as_ref().map(|f| f as &dyn FrameSource),
        &options,
        prov,
    )?;
    cal.save(&args.out)?;
    let files = report::write_frame_report(&cal, &args.out)?;
    let back = FrameCalibration::load(&args.out)?;
    if back.flags != cal.flags {
        bail!(
            "the calibration written to {} does not read back with the same flags",
            args.out.display()
        );
    }
    let s = &cal.summary;
    println!(
        "{} {}x{} pixels, {} dark frames: offset {:.3} ADU, read noise {:.4} ADU{}, gain {}",
        camera.as_str(),
        cal.width,
        cal.height,
        s.dark_frames,
        s.offset_median_adu,
        s.read_noise_median_adu,
        s.read_noise_median_e
            .map_or(String::new(), |e| format!(" ({e:.4} e-)")),
        match (s.gain_adu_per_e, s.gain_sd_adu_per_e) {
            (Some(g), Some(sd)) => format!("{g:.5} ± {sd:.5} ADU/e- ({})", s.gain_source),
            (Some(g), None) => format!("{g:.5} ADU/e- ({})", s.gain_source),
            _ => "unknown".into(),
        }
    );
    println!(
        "flagged: {} hot, {} noisy, {} dead, {} saturated, {} unmeasured",
        s.hot_pixels, s.noisy_pixels, s.dead_pixels, s.saturated_pixels, s.unmeasured_pixels
    );
    finish(&args.out, &cal.provenance.notes, &files)
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    match choose_camera(&args)? {
        CameraArg::Spad => run_spad(&args),
        CameraArg::Emccd => run_frames(&args, FrameCamera::Emccd),
        CameraArg::Scmos => run_frames(&args, FrameCamera::Scmos),
    }
}
