//! `smartagg localize`: molecule positions from blink-ROI packets (`.rois`)
//! or from a TIFF stack of frames, written as a ThunderSTORM CSV table
//! (`--out x.csv`) or as Picasso HDF5 with its YAML sidecar (`--out
//! x.hdf5` or `.h5`; [`smartagg_localize::picasso`] says how the columns map).
//!
//! * **ROI packets** (from `smartagg aggregate` or `download`): each blink
//!   record is fitted where it is; position = ROI origin + fitted position,
//!   times the pixel size. `frame` is the 1-based blink index (the page of
//!   `--export-tiff`); the blink's timing follows in `t_start [plane]`,
//!   `t_end [plane]`, `planes`, and the record `flags`. Pixels off the sensor
//!   (EDGE records) are left out of the fit. With `--calibration` (a SPAD
//!   calibration directory) the fit uses the DCR map (as dark counts per
//!   plane), the PRNU map, and the hot pixels (ignored or interpolated).
//!   `--estimator spad-mle` uses the binomial likelihood with the record's
//!   on/off split, exact under pile-up. The camera (pixel size, PSF σ)
//!   comes from the stream's sidecar `FILE.rois.json`, which `aggregate` and
//!   `download` write beside it; `--preset` or `--pixel-nm` override it.
//! * **TIFF frames** (EMCCD, sCMOS, fixed-aggregation SPAD frames): B-spline
//!   wavelet filter, threshold 1.5 × noise, 8-neighbour maxima, fits,
//!   optional merging of consecutive frames within `--merge-nm` (the paper's
//!   40 nm). ADU are converted with `--offset-adu`, `--e-per-adu`,
//!   `--em-gain` (defaults from `--preset`) or per pixel from a frame
//!   calibration.
//!
//! A failed fit is kept and flagged in `fit_status` (0 = ok) unless
//! `--drop-failed`; either way the failures are counted and printed.

use crate::setup;
use crate::stream_info::StreamInfo;
use anyhow::{bail, Context};
use rayon::prelude::*;
use smartagg_calibration::{flags, AnyCalibration};
use smartagg_io::output::AtomicFile;
use smartagg_localize::export::{RoiLayout, RoiPage};
use smartagg_localize::frames::{localize_batch, Conversion, FramePipeline};
use smartagg_localize::merge::merge_consecutive;
use smartagg_localize::record_fit::{fit_record, RecordFitConfig};
use smartagg_localize::table::{LocTable, Localization};
use smartagg_localize::{Estimator, FitOptions, HotPixelMode, NoiseModel, SigmaMode};
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::record::{flags as rflags, BlinkRecord, Record, StreamStart};
use smartagg_model::record_check::{check_blink, is_empty_segment, RepeatFilter};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod frames;
mod stream;

use frames::localize_tiff;
use stream::localize_rois;

/// Estimator names on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum EstimatorArg {
    /// Poisson maximum likelihood (pixel-integrated Gaussian), as ThunderSTORM's MLE.
    Mle,
    /// SPAD binomial maximum likelihood (ROI packets, or SPAD frames with --planes).
    SpadMle,
    /// Unweighted least squares.
    Lsq,
    /// Background-subtracted centroid.
    Centroid,
}

impl EstimatorArg {
    fn estimator(self) -> Estimator {
        match self {
            EstimatorArg::Mle => Estimator::Mle,
            EstimatorArg::SpadMle => Estimator::SpadMle,
            EstimatorArg::Lsq => Estimator::Lsq,
            EstimatorArg::Centroid => Estimator::Centroid,
        }
    }
}

/// Noise model names on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoiseArg {
    /// Ideal photon counting.
    Poisson,
    /// EMCCD, excess noise F² = 2.
    Emccd,
    /// sCMOS, per-pixel read noise (Huang et al. 2013).
    Scmos,
}

/// Hot-pixel strategy on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum HotArg {
    /// Leave hot pixels out of the likelihood (the paper found this better).
    Ignore,
    /// Replace them by the mean of their valid 4-neighbours.
    Interpolate,
}

impl HotArg {
    /// The library's strategy of this name.
    fn mode(self) -> HotPixelMode {
        match self {
            HotArg::Ignore => HotPixelMode::Ignore,
            HotArg::Interpolate => HotPixelMode::Interpolate,
        }
    }
}

/// Layout of `--export-tiff`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutArg {
    /// One R×R page per ROI (a page → origin table goes to PATH.origins.csv).
    Compact,
    /// One sensor-sized page per ROI, the ROI at its place.
    Sensor,
}

/// Arguments of `smartagg localize`.
#[derive(clap::Args, Debug)]
#[command(mut_arg("preset", |a| a.help("Camera preset (spcimager, spcimager-projected, spad512s, emccd, scmos): pixel size, PSF σ, ADU conversion, noise model")))]
#[command(mut_arg("objective", |a| a.help("Objective magnification of the preset (150 or 60)")))]
pub struct Args {
    /// Blink-ROI packet stream (.rois) or TIFF stack of frames (.tif).
    pub input: PathBuf,
    /// Output table, format from the extension: .csv (ThunderSTORM), .hdf5 or .h5 (Picasso, with its .yaml sidecar beside it).
    #[arg(long)]
    pub out: PathBuf,
    /// Estimator.
    #[arg(long, value_enum, default_value_t = EstimatorArg::Mle)]
    pub estimator: EstimatorArg,
    /// Sample-plane pixel size, nm [default: from --preset, else from the stream's sidecar FILE.rois.json].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 0.1, 1e6, "nm"))]
    pub pixel_nm: Option<f64>,
    #[command(flatten)]
    pub preset: crate::setup::OptionalPresetArgs,
    /// PSF σ in camera pixels (initial value when fitted) [default: the preset's, else the stream sidecar's, else 1.6 as ThunderSTORM].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 0.05, 100.0, "camera pixels"))]
    pub sigma: Option<f64>,
    /// Keep σ fixed instead of fitting it.
    #[arg(long)]
    pub fixed_sigma: bool,
    /// Noise model for the likelihood and the uncertainty [default: from the preset, else poisson].
    #[arg(long, value_enum)]
    pub noise: Option<NoiseArg>,
    /// Camera or calibration directory (from `smartagg calibrate`): SPAD DCR/PRNU/hot maps, or frame offset/gain/read-noise maps.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// What to do with hot pixels of the calibration.
    #[arg(long, value_enum, default_value_t = HotArg::Ignore)]
    pub hot_pixels: HotArg,
    /// Leave failed fits out of the table (they are counted either way).
    #[arg(long)]
    pub drop_failed: bool,
    /// Worker threads (default: all cores; more than the cores are capped, with a note).
    #[arg(long, value_parser = setup::thread_count)]
    pub threads: Option<usize>,
    /// Frames: camera bias, ADU [default: from the preset, else 0].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, -1e9, 1e9, "ADU"))]
    pub offset_adu: Option<f64>,
    /// Frames: electrons per ADU [default: from the preset, else 1].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 1e-6, 1e6, "e-/ADU"))]
    pub e_per_adu: Option<f64>,
    /// Frames: EM gain [default: from the preset, else 1].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 1.0, 1e5, "(EM gain)"))]
    pub em_gain: Option<f64>,
    /// Frames: sCMOS read noise, e⁻ rms [default: from the preset].
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 0.0, 1e4, "e- rms"))]
    pub read_noise_e: Option<f64>,
    /// Frames: fitting ROI side, odd [default: 2⌈3σ⌉+1, at least 7]; frames smaller than it are fitted with the largest odd side that fits (said once).
    #[arg(long)]
    pub roi: Option<usize>,
    /// Frames: detection threshold in units of the wavelet noise std.
    #[arg(long, default_value_t = 1.5, value_parser = |s: &str| setup::ranged(s, 1e-3, 1e3, "noise std"))]
    pub threshold: f64,
    /// Frames: bit-planes per SPAD frame (for --estimator spad-mle on frames).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub planes: Option<u32>,
    /// Frames: merge localisations of consecutive frames within this distance, nm (the paper: 40).
    #[arg(long, allow_negative_numbers = true, value_parser = |s: &str| setup::ranged(s, 1e-3, 1e6, "nm"))]
    pub merge_nm: Option<f64>,
    /// Frames: frames a merged track may skip.
    #[arg(long, default_value_t = 0)]
    pub merge_gap: u64,
    /// ROI packets: localise what arrived of a stream that is not whole
    /// (losses, no StreamEnd, repeated or impossible records), with warnings,
    /// instead of stopping.
    #[arg(long)]
    pub allow_loss: bool,
    /// ROI packets: also write the ROIs as a TIFF stack (for ThunderSTORM).
    #[arg(long)]
    pub export_tiff: Option<PathBuf>,
    /// Layout of --export-tiff.
    #[arg(long, value_enum, default_value_t = LayoutArg::Compact)]
    pub export_layout: LayoutArg,
}

/// The optics and camera settings resolved from the arguments.
struct Setup {
    pixel_nm: f64,
    sigma_px: f64,
    opts: FitOptions,
    preset: Option<Preset>,
    /// The stream's sidecar, when it gave the camera.
    sidecar: Option<StreamInfo>,
}

fn setup(args: &Args) -> anyhow::Result<Setup> {
    let mut preset = match &args.preset.name {
        Some(name) => Some(Preset::new(
            PresetName::parse(name)?,
            args.preset.objective,
        )?),
        None => None,
    };
    // A stream from `aggregate` or `download` says its camera in a sidecar;
    // the command line wins over it.
    let mut sidecar = None;
    if args.preset.name.is_none() && args.pixel_nm.is_none() && !is_tiff(&args.input)? {
        if let Some((info, path)) = StreamInfo::read_beside(&args.input)? {
            eprintln!(
                "camera from {}: {} {}x, {:.2} nm pixels, PSF sigma {:.3} px",
                path.display(),
                info.camera,
                info.objective,
                info.pixel_nm,
                info.psf_sigma_px
            );
            preset = info.preset();
            sidecar = Some(info);
        }
    }
    let pixel_nm = match (args.pixel_nm, &preset, &sidecar) {
        (Some(p), _, _) => p,
        (None, _, Some(info)) => info.pixel_nm,
        (None, Some(p), None) => p.pixel_nm(),
        (None, None, None) => bail!(
            "give the pixel size with --pixel-nm, or a camera with --preset (a stream written by `smartagg aggregate` or `download` says its camera in {}, which is missing)",
            StreamInfo::path_for(&args.input).display()
        ),
    };
    if !(pixel_nm.is_finite() && pixel_nm > 0.0) {
        bail!("--pixel-nm must be a positive number of nanometres, got {pixel_nm}");
    }
    let sigma_px = args.sigma.unwrap_or_else(|| match (&sidecar, &preset) {
        (Some(info), _) => info.psf_sigma_px,
        (None, Some(p)) => p.sigma_px(),
        (None, None) => 1.6,
    });
    let noise = match args.noise {
        Some(NoiseArg::Poisson) => NoiseModel::Poisson,
        Some(NoiseArg::Emccd) => NoiseModel::Emccd,
        Some(NoiseArg::Scmos) => NoiseModel::Scmos,
        None => match preset.as_ref().map(|p| &p.camera) {
            Some(Camera::Emccd(_)) => NoiseModel::Emccd,
            Some(Camera::Scmos(_)) => NoiseModel::Scmos,
            _ => NoiseModel::Poisson,
        },
    };
    let mut opts = FitOptions::new(if args.fixed_sigma {
        SigmaMode::Fixed(sigma_px)
    } else {
        SigmaMode::Fitted { initial: sigma_px }
    });
    opts.noise = noise;
    opts.validate().context("fit options")?;
    Ok(Setup {
        pixel_nm,
        sigma_px,
        opts,
        preset,
        sidecar,
    })
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let threads = args.threads.map(setup::cap_threads);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .context("starting the worker threads")?;
    pool.install(|| run_in_pool(args))
}

/// Format of the output table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum OutFormat {
    /// ThunderSTORM CSV.
    Csv,
    /// Picasso HDF5 and its YAML sidecar.
    Picasso,
}

/// The output format from the extension of `--out`.
fn out_format(out: &Path) -> anyhow::Result<OutFormat> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "csv" => Ok(OutFormat::Csv),
        "hdf5" | "h5" => Ok(OutFormat::Picasso),
        _ => bail!(
            "--out {}: the format comes from the extension: .csv (ThunderSTORM) or .hdf5/.h5 (Picasso)",
            out.display()
        ),
    }
}

/// Size and time extent of what was localised, for Picasso's metadata.
struct Extent {
    width: u32,
    height: u32,
    frames: u64,
    data_type: String,
    /// Rows are blink records (else frames of a stack).
    blinks: bool,
}

fn run_in_pool(args: Args) -> anyhow::Result<()> {
    let s = setup(&args)?;
    smartagg_io::output::refuse_overwriting(&args.out, &[&args.input])?;
    let format = out_format(&args.out)?;
    if format == OutFormat::Picasso {
        let yaml = smartagg_localize::picasso::sidecar_path(&args.out);
        smartagg_io::output::refuse_overwriting(&yaml, &[&args.input])?;
        if args.export_tiff.as_ref() == Some(&yaml) {
            bail!("--export-tiff is {}, the sidecar of --out", yaml.display());
        }
    }
    if let Some(tiff) = &args.export_tiff {
        smartagg_io::output::refuse_overwriting(tiff, &[&args.input])?;
        if tiff == &args.out {
            bail!(
                "--export-tiff and --out are the same file, {}",
                tiff.display()
            );
        }
    }
    let started = Instant::now();
    let (mut table, fits, extent) = if is_tiff(&args.input)? {
        localize_tiff(&args, &s)?
    } else {
        localize_rois(&args, &s)?
    };
    let seconds = started.elapsed().as_secs_f64();
    let mut counts: BTreeMap<&'static str, usize> = BTreeMap::new();
    for r in &table.rows {
        *counts.entry(r.status.name()).or_default() += 1;
    }
    let failed = table.failures();
    if args.drop_failed {
        table.rows.retain(|r| r.status.is_ok());
    }
    let written = Instant::now();
    match format {
        OutFormat::Csv => {
            let mut w = std::io::BufWriter::new(AtomicFile::create(&args.out)?);
            table
                .write_csv(&mut w)
                .with_context(|| format!("writing {}", args.out.display()))?;
            w.into_inner()
                .map_err(|e| e.into_error())
                .with_context(|| format!("writing {}", args.out.display()))?
                .commit()?;
        }
        OutFormat::Picasso => {
            let meta = smartagg_localize::picasso::PicassoMeta {
                width: extent.width,
                height: extent.height,
                frames: extent.frames,
                pixel_nm: s.pixel_nm,
                input: args.input.display().to_string(),
                data_type: extent.data_type,
                estimator: format!("{:?}", args.estimator).to_lowercase(),
                blinks: extent.blinks,
                generated_by: format!("smartagg v{} localize", env!("CARGO_PKG_VERSION")),
            };
            smartagg_localize::picasso::write(&args.out, &table, &meta)?;
            if failed > 0 && !args.drop_failed {
                eprintln!(
                    "note: Picasso draws every row: its {failed} failed fits are flagged in the fit_status column (filter fit_status = 0 in Picasso Filter, or localize with --drop-failed)"
                );
            }
        }
    }
    let write_s = written.elapsed().as_secs_f64();
    let summary: Vec<String> = counts.iter().map(|(k, v)| format!("{k} {v}")).collect();
    println!(
        "{} localisations written to {}{} in {:.3} s ({}); {} failed fits {}; {} fits in {:.2} s ({:.0} fits/s)",
        table.rows.len(),
        args.out.display(),
        if format == OutFormat::Picasso {
            format!(
                " and {}",
                smartagg_localize::picasso::sidecar_path(&args.out).display()
            )
        } else {
            String::new()
        },
        write_s,
        summary.join(", "),
        failed,
        if args.drop_failed {
            "dropped"
        } else {
            "kept, flagged in fit_status"
        },
        fits,
        seconds,
        fits as f64 / seconds.max(1e-9)
    );
    Ok(())
}

/// True for a TIFF (by magic number; a missing file is an error).
fn is_tiff(path: &Path) -> anyhow::Result<bool> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let mut magic = [0u8; 4];
    let n = f.read(&mut magic)?;
    Ok(n == 4
        && (magic == *b"II*\0" || magic == *b"MM\0*" || magic == *b"II+\0" || magic == *b"MM\0+"))
}

#[cfg(test)]
mod tests {
    use super::stream::*;
    use super::*;
    use smartagg_localize::FitStatus;
    use smartagg_model::packet::Encoder;

    fn record(i: u16, x: u16, y: u16, counts: Vec<u32>) -> BlinkRecord {
        BlinkRecord {
            slot: 0,
            flags: 0,
            anchor_x: x,
            anchor_y: y,
            t_cross: 1000 + i as u64 * 10,
            t_drop: 1500 + i as u64 * 10,
            t_s: 946 + i as i64 * 10,
            t_e: 1446 + i as i64 * 10,
            planes_summed: 609,
            roi_size: 9,
            counts,
        }
    }

    fn start() -> StreamStart {
        StreamStart {
            width: 64,
            height: 48,
            n_window: 108,
            threshold_int: 100,
            threshold_hold: 100,
            end_trim: Some(0),
            l_min: 1,
            l_max: 10_000,
            r_assoc: 1,
            slots: 8,
            roi_size: 9,
            kernel_shift: 4,
            kernel: vec![1, 4, 6, 4, 1],
            plane_period_ns: 100_000,
            masked_pixels: 0,
        }
    }

    /// A blink ROI centred at (4.5 + dx, 4.5) in ROI pixels, from the
    /// expected image (no noise), in counts.
    fn blink(dx: f64) -> Vec<u32> {
        let em = smartagg_localize::crlb::Emitter {
            x: 4.5 + dx,
            y: 4.5,
            sigma: 1.5,
            photons: 2000.0,
            background: 7.0,
        };
        smartagg_localize::synth::expected_roi(9, &em, None)
            .into_iter()
            .map(|v| v.round() as u32)
            .collect()
    }

    fn args(input: &Path, out: &Path) -> Args {
        Args {
            input: input.to_path_buf(),
            out: out.to_path_buf(),
            estimator: EstimatorArg::SpadMle,
            pixel_nm: Some(50.0),
            preset: crate::setup::OptionalPresetArgs {
                name: None,
                objective: 150,
            },
            sigma: Some(1.5),
            fixed_sigma: false,
            noise: None,
            calibration: None,
            hot_pixels: HotArg::Ignore,
            drop_failed: false,
            threads: None,
            offset_adu: None,
            e_per_adu: None,
            em_gain: None,
            read_noise_e: None,
            roi: None,
            threshold: 1.5,
            planes: None,
            merge_nm: None,
            merge_gap: 0,
            export_tiff: None,
            export_layout: LayoutArg::Compact,
            allow_loss: false,
        }
    }

    #[test]
    fn packet_stream_to_table_and_tiff() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("blinks.rois");
        let mut enc = Encoder::new();
        let mut bytes = Vec::new();
        enc.push(&Record::Start(start()), &mut bytes).unwrap();
        enc.push(&Record::Blink(record(0, 20, 30, blink(0.3))), &mut bytes)
            .unwrap();
        let mut edge = record(1, 2, 10, blink(-0.2));
        edge.flags = rflags::EDGE;
        enc.push(&Record::Blink(edge), &mut bytes).unwrap();
        enc.push(&Record::Blink(record(2, 40, 20, vec![0; 81])), &mut bytes)
            .unwrap();
        enc.push(&Record::End(end(3)), &mut bytes).unwrap();
        std::fs::write(&input, &bytes).unwrap();

        let content = read_stream(&input).unwrap();
        assert_eq!(content.start.unwrap().width, 64);
        assert_eq!(content.rois.len(), 3);
        assert!(content.problems.is_empty(), "{:?}", content.problems);

        let out = dir.path().join("locs.csv");
        let mut a = args(&input, &out);
        a.export_tiff = Some(dir.path().join("rois.tif"));
        run(a).unwrap();
        let t = smartagg_localize::table::CsvTable::read(std::io::BufReader::new(
            std::fs::File::open(&out).unwrap(),
        ))
        .unwrap();
        assert_eq!(t.rows.len(), 3, "the zero-photon ROI is kept, flagged");
        let (x, st) = (
            t.column(&["x [nm]"]).unwrap(),
            t.column(&["fit_status"]).unwrap(),
        );
        // First blink: anchor 20 → ROI origin 16; 16 + 4.5 + 0.3 px at 50 nm.
        assert!(
            (t.rows[0][x] - (16.0 + 4.8) * 50.0).abs() < 3.0,
            "{}",
            t.rows[0][x]
        );
        assert_eq!(t.rows[0][st], 0.0);
        // Second: origin x = −2, two columns off the sensor ignored.
        assert!(
            (t.rows[1][x] - (-2.0 + 4.3) * 50.0).abs() < 5.0,
            "{}",
            t.rows[1][x]
        );
        assert_eq!(t.rows[2][st], FitStatus::NoSignal.code() as f64);
        let ts = t.column(&["t_start [plane]"]).unwrap();
        assert_eq!(t.rows[0][ts], 946.0);
        // The ROI stack opens as three 9×9 pages.
        let pages: Vec<_> = smartagg_io::stack::open_stack(&dir.path().join("rois.tif"))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(pages.len(), 3);
        assert_eq!(pages[0].data.len(), 81);
        assert!(dir.path().join("rois.tif.origins.csv").exists());

        // Dropping failed fits leaves two rows.
        let mut a = args(&input, &out);
        a.drop_failed = true;
        a.estimator = EstimatorArg::Mle;
        run(a).unwrap();
        let t = smartagg_localize::table::CsvTable::read(std::io::BufReader::new(
            std::fs::File::open(&out).unwrap(),
        ))
        .unwrap();
        assert_eq!(t.rows.len(), 2);
    }

    fn end(blinks: u64) -> smartagg_model::record::StreamEnd {
        smartagg_model::record::StreamEnd {
            planes: 4000,
            blinks,
            unconfirmed: 0,
            dropped_candidates: 0,
            bridged_dips: 0,
            cut_segments: 0,
        }
    }

    fn encode(records: &[Record]) -> Vec<u8> {
        let mut enc = Encoder::new();
        let mut bytes = Vec::new();
        for r in records {
            enc.push(r, &mut bytes).unwrap();
        }
        bytes
    }

    #[test]
    fn a_stream_that_is_not_whole_is_refused_unless_losses_are_allowed() {
        let dir = tempfile::tempdir().unwrap();
        let good = |i: u16| Record::Blink(record(i, 20 + i, 30, blink(0.1)));
        let whole = encode(&[
            Record::Start(start()),
            good(0),
            good(1),
            Record::End(end(2)),
        ]);
        let mut impossible = record(2, 20, 30, blink(0.1));
        impossible.planes_summed = 0;
        let mut off_sensor = record(3, 20, 30, blink(0.1));
        off_sensor.anchor_x = 64;
        let cases: Vec<(&str, Vec<u8>, &str, usize)> = vec![
            (
                "no end",
                encode(&[Record::Start(start()), good(0), good(1)]),
                "no StreamEnd record",
                2,
            ),
            (
                "twice",
                [whole.clone(), whole.clone()].concat(),
                "2 repeated packets",
                2,
            ),
            (
                "lying end",
                encode(&[
                    Record::Start(start()),
                    good(0),
                    good(1),
                    Record::End(end(u64::MAX)),
                ]),
                "count 18446744073709551615 blinks but 2 arrived",
                2,
            ),
            (
                "impossible",
                encode(&[
                    Record::Start(start()),
                    good(0),
                    Record::Blink(impossible),
                    Record::Blink(off_sensor),
                    good(1),
                    Record::End(end(4)),
                ]),
                "2 blink records that the stream's configuration cannot produce were rejected",
                2,
            ),
            (
                "no start",
                encode(&[good(0), good(1), Record::End(end(2))]),
                "no StreamStart",
                2,
            ),
        ];
        for (name, bytes, want, kept) in cases {
            let input = dir.path().join(format!("{name}.rois"));
            std::fs::write(&input, &bytes).unwrap();
            let out = dir.path().join(format!("{name}.csv"));
            let e = format!("{:#}", run(args(&input, &out)).unwrap_err());
            assert!(e.contains(want), "{name}: {e}");
            assert!(e.contains("--allow-loss"), "{name}: {e}");
            assert!(!out.exists(), "{name}: no table from a refused stream");
            let mut a = args(&input, &out);
            a.allow_loss = true;
            run(a).unwrap();
            let t = smartagg_localize::table::CsvTable::read(std::io::BufReader::new(
                std::fs::File::open(&out).unwrap(),
            ))
            .unwrap();
            assert_eq!(t.rows.len(), kept, "{name}");
        }
        // A whole stream goes through without --allow-loss.
        let input = dir.path().join("whole.rois");
        std::fs::write(&input, &whole).unwrap();
        run(args(&input, &dir.path().join("whole.csv"))).unwrap();
        // A device is not a recorded stream.
        let e = run(args(Path::new("/dev/zero"), &dir.path().join("z.csv")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }

    #[test]
    fn bad_inputs_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let junk = dir.path().join("junk.rois");
        std::fs::write(&junk, b"this is not a packet stream at all").unwrap();
        let e = run(args(&junk, &dir.path().join("o.csv")))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("neither a blink-ROI packet stream nor a TIFF"),
            "{e}"
        );
        let e = run(args(
            &dir.path().join("missing.rois"),
            &dir.path().join("o.csv"),
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("missing.rois"), "{e}");
        let mut a = args(&junk, &dir.path().join("o.csv"));
        a.pixel_nm = None;
        let e = format!("{:#}", run(a).unwrap_err());
        assert!(e.contains("--pixel-nm"), "{e}");
    }

    #[test]
    fn tiff_frames_with_merging() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (32usize, 32usize);
        // One molecule on in frames 1–3, another in frame 3 only; ADU with
        // offset 100 and 2 e⁻/ADU.
        let frames: Vec<Vec<u32>> = (0..4)
            .map(|f| {
                let mut em = Vec::new();
                if f < 3 {
                    em.push((10.4, 12.6, 3000.0));
                }
                if f == 2 {
                    em.push((22.5, 20.5, 3000.0));
                }
                smartagg_localize::synth::expected_frame(w, h, &em, 1.3, 8.0)
                    .into_iter()
                    .map(|v| (v / 2.0 + 100.0).round() as u32)
                    .collect()
            })
            .collect();
        let input = dir.path().join("frames.tif");
        smartagg_io::stack::write_stack(smartagg_io::stack::create(&input).unwrap(), w, h, &frames)
            .unwrap();
        let out = dir.path().join("f.csv");
        let mut a = args(&input, &out);
        a.estimator = EstimatorArg::Mle;
        a.pixel_nm = Some(100.0);
        a.sigma = Some(1.3);
        a.offset_adu = Some(100.0);
        a.e_per_adu = Some(2.0);
        a.merge_nm = Some(40.0);
        run(a).unwrap();
        let t = smartagg_localize::table::CsvTable::read(std::io::BufReader::new(
            std::fs::File::open(&out).unwrap(),
        ))
        .unwrap();
        let det = t.column(&["detections"]).unwrap();
        let st = t.column(&["fit_status"]).unwrap();
        let ok: Vec<_> = t.rows.iter().filter(|r| r[st] == 0.0).collect();
        assert_eq!(ok.len(), 2, "{:?}", t.rows);
        assert!(ok.iter().any(|r| r[det] == 3.0));
        assert!(ok.iter().any(|r| r[det] == 1.0));
    }
}
