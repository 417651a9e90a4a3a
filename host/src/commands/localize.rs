//! `smartagg localize`: molecule positions from blink-ROI packets (`.rois`)
//! or from a TIFF stack of frames, written as a ThunderSTORM CSV table
//! (`--out x.csv`) or as Picasso HDF5 with its YAML sidecar (`--out
//! x.hdf5` or `.h5`; [`crate::picasso`] says how the columns map).
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

use crate::calibration::{flags, AnyCalibration};
use crate::output::AtomicFile;
use crate::setup;
use crate::stream_info::StreamInfo;
use anyhow::{bail, Context};
use rayon::prelude::*;
use smartagg_localize::frames::{localize_batch, Conversion, FramePipeline};
use smartagg_localize::merge::merge_consecutive;
use smartagg_localize::spad::{fit_binomial, SpadRoi};
use smartagg_localize::table::{LocTable, Localization};
use smartagg_localize::tiffio::{self, RoiLayout, RoiPage};
use smartagg_localize::{
    fit_roi, Estimator, FitOptions, FitStatus, HotPixelMode, NoiseModel, PixelMaps, RoiView,
    SigmaMode,
};
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::record::{flags as rflags, BlinkRecord, Record, StreamStart};
use smartagg_model::record_check::{check_blink, is_empty_segment, RepeatFilter};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    /// Camera preset (spcimager, spcimager-projected, spad512s, emccd, scmos): pixel size, PSF σ, ADU conversion, noise model.
    #[arg(long)]
    pub preset: Option<String>,
    /// Objective magnification of the preset (150 or 60).
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
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
    let mut preset = match &args.preset {
        Some(name) => Some(Preset::new(PresetName::parse(name)?, args.objective)?),
        None => None,
    };
    // A stream from `aggregate` or `download` says its camera in a sidecar;
    // the command line wins over it.
    let mut sidecar = None;
    if args.preset.is_none() && args.pixel_nm.is_none() && !is_tiff(&args.input)? {
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
    crate::output::refuse_overwriting(&args.out, &[&args.input])?;
    let format = out_format(&args.out)?;
    if format == OutFormat::Picasso {
        let yaml = crate::picasso::sidecar_path(&args.out);
        crate::output::refuse_overwriting(&yaml, &[&args.input])?;
        if args.export_tiff.as_ref() == Some(&yaml) {
            bail!("--export-tiff is {}, the sidecar of --out", yaml.display());
        }
    }
    if let Some(tiff) = &args.export_tiff {
        crate::output::refuse_overwriting(tiff, &[&args.input])?;
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
            let meta = crate::picasso::PicassoMeta {
                width: extent.width,
                height: extent.height,
                frames: extent.frames,
                pixel_nm: s.pixel_nm,
                input: args.input.display().to_string(),
                data_type: extent.data_type,
                estimator: format!("{:?}", args.estimator).to_lowercase(),
                blinks: extent.blinks,
            };
            crate::picasso::write(&args.out, &table, &meta)?;
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
                crate::picasso::sidecar_path(&args.out).display()
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

/// numpy's name of a TIFF's sample type (first page), as Picasso's movie
/// loaders write it in `Data Type`; "unknown" if the tags do not say.
fn tiff_data_type(path: &Path) -> String {
    use tiff::tags::Tag;
    let Ok(mut d) = std::fs::File::open(path)
        .map_err(|_| ())
        .and_then(|f| tiff::decoder::Decoder::new(std::io::BufReader::new(f)).map_err(|_| ()))
    else {
        return "unknown".into();
    };
    let bits = match d.colortype() {
        Ok(tiff::ColorType::Gray(b)) => b,
        _ => return "unknown".into(),
    };
    // SampleFormat: 1 unsigned (the default), 2 signed, 3 IEEE float.
    let kind = match d.find_tag_unsigned::<u16>(Tag::SampleFormat) {
        Ok(Some(2)) => "int",
        Ok(Some(3)) => "float",
        _ => "uint",
    };
    format!("{kind}{bits}")
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

/// What a packet stream delivered, checked: its first StreamStart, the
/// blink records worth fitting, and every reason the stream is not whole.
pub struct StreamContent {
    /// The first StreamStart (it describes the stream).
    pub start: Option<StreamStart>,
    /// Blink records, in stream order, without duplicates, implausible
    /// records or empty segments.
    pub rois: Vec<BlinkRecord>,
    /// Sentences, one per problem (empty: the stream arrived whole).
    pub problems: Vec<String>,
    /// Empty segments (continuations cut on their last plane): nothing to fit.
    pub empty_segments: usize,
    /// Bit-planes of the stream, from its last StreamEnd.
    pub planes: Option<u64>,
}

/// Reads and checks a packet stream: prints the decoder's loss accounting,
/// drops repeated packets (same sequence number, same record), rejects
/// records the stream's configuration cannot produce
/// (`smartagg_model::record_check`), and cross-checks the StreamEnd totals.
pub fn read_stream(path: &Path) -> anyhow::Result<StreamContent> {
    let meta = std::fs::metadata(path).with_context(|| format!("reading {}", path.display()))?;
    if !meta.is_file() {
        bail!(
            "{} is not a regular file: localize reads a recorded stream (`smartagg download` records a live one)",
            path.display()
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let decoded = smartagg_model::packet::decode_all(&bytes);
    eprintln!("{}: {}", path.display(), decoded.stats);
    let mut problems = Vec::new();
    if decoded.stats.any_loss() {
        problems.push(format!("the decoder lost data: {}", decoded.stats));
    }
    let mut start: Option<StreamStart> = None;
    let mut ends: Vec<smartagg_model::record::StreamEnd> = Vec::new();
    let mut repeats = RepeatFilter::default();
    let (mut received, mut empty_segments) = (0u64, 0usize);
    let (mut rejected, mut examples) = (0usize, Vec::new());
    let mut blinks = Vec::new();
    for p in decoded.packets {
        // A packet repeated by the transport (or a capture concatenated with
        // itself) has the same sequence number and the same record.
        if repeats.is_repeat(p.seq, &p.record) {
            continue;
        }
        match p.record {
            Record::Start(s) if start.is_none() => start = Some(s),
            Record::Blink(b) => {
                received += 1;
                blinks.push(b);
            }
            Record::End(e) => ends.push(e),
            _ => {}
        }
    }
    if blinks.is_empty() && decoded.stats.packets_ok == 0 {
        bail!(
            "{} holds no packets: it is neither a blink-ROI packet stream nor a TIFF",
            path.display()
        );
    }
    let duplicates = repeats.repeats();
    if duplicates > 0 {
        problems.push(format!(
            "{duplicates} repeated packets (same sequence number and content) dropped"
        ));
    }
    let planes = ends.last().map(|e| e.planes);
    let mut rois = Vec::with_capacity(blinks.len());
    match &start {
        None => {
            problems.push(
                "no StreamStart record: the records cannot be checked against the stream's configuration"
                    .into(),
            );
            for b in blinks {
                if is_empty_segment(&b) {
                    empty_segments += 1;
                } else {
                    rois.push(b);
                }
            }
        }
        Some(st) => {
            for b in blinks {
                // Only a single stream's plane count bounds its records.
                let bound = if ends.len() == 1 { planes } else { None };
                match check_blink(&b, st, bound) {
                    Err(e) => {
                        rejected += 1;
                        if examples.len() < 3 {
                            examples.push(format!(
                                "slot {} at ({}, {}), t_cross {}: {e}",
                                b.slot, b.anchor_x, b.anchor_y, b.t_cross
                            ));
                        }
                    }
                    Ok(()) if is_empty_segment(&b) => empty_segments += 1,
                    Ok(()) => rois.push(b),
                }
            }
        }
    }
    if rejected > 0 {
        problems.push(format!(
            "{rejected} blink records that the stream's configuration cannot produce were rejected, not fitted (e.g. {})",
            examples.join("; ")
        ));
    }
    if ends.is_empty() {
        problems.push("no StreamEnd record: the stream was cut short".into());
    } else if !decoded.stats.any_loss() && duplicates == 0 {
        let claimed: u64 = ends.iter().map(|e| e.blinks).fold(0, u64::saturating_add);
        if claimed != received {
            problems.push(format!(
                "the StreamEnd records count {claimed} blinks but {received} arrived"
            ));
        }
    }
    Ok(StreamContent {
        start,
        rois,
        problems,
        empty_segments,
        planes,
    })
}

/// Sensor-sized SPAD maps from a calibration: dark counts per plane, PRNU,
/// hot pixels.
struct SpadMaps {
    width: usize,
    height: usize,
    dark_per_plane: Vec<f64>,
    gain: Option<Vec<f64>>,
    hot: Vec<bool>,
}

fn localize_rois(args: &Args, s: &Setup) -> anyhow::Result<(LocTable, usize, Extent)> {
    let StreamContent {
        start,
        rois,
        problems,
        empty_segments,
        planes,
    } = read_stream(&args.input)?;
    if !problems.is_empty() {
        if !args.allow_loss || rois.is_empty() {
            let mut msg = format!(
                "{} is not a whole stream:\n  - {}",
                args.input.display(),
                problems.join("\n  - ")
            );
            msg += if rois.is_empty() {
                "\nnothing left to localise"
            } else {
                "\n(--allow-loss localises the records that arrived)"
            };
            bail!(msg);
        }
        for p in &problems {
            eprintln!("smartagg: WARNING: {p}");
        }
    }
    if empty_segments > 0 {
        eprintln!("{empty_segments} empty segments (a continuation cut on its last plane sums no plane): nothing to fit");
    }
    if let (Some(st), Some(info)) = (&start, &s.sidecar) {
        if (u32::from(st.width), u32::from(st.height)) != (info.width, info.height) {
            bail!(
                "the stream's sensor is {}x{} but its sidecar {} says {}x{}: give the camera with --preset or --pixel-nm",
                st.width,
                st.height,
                StreamInfo::path_for(&args.input).display(),
                info.width,
                info.height
            );
        }
    }
    let est = args.estimator.estimator();
    let maps = match &args.calibration {
        None => None,
        Some(dir) => match AnyCalibration::load(dir)
            .with_context(|| format!("loading calibration {}", dir.display()))?
        {
            AnyCalibration::Spad(c) => {
                let tau = start
                    .as_ref()
                    .map(|st| st.plane_period_ns as f64 * 1e-9)
                    .unwrap_or(c.tau_s);
                Some(SpadMaps {
                    width: c.width as usize,
                    height: c.height as usize,
                    dark_per_plane: c.dcr_hz.iter().map(|r| r * tau).collect(),
                    gain: c.prnu.clone(),
                    hot: c.flags.iter().map(|f| f & flags::HOT != 0).collect(),
                })
            }
            AnyCalibration::Frame(_) => bail!(
                "{} is a frame-camera calibration; blink-ROI packets need a SPAD calibration",
                dir.display()
            ),
        },
    };
    if let (Some(st), Some(m)) = (&start, &maps) {
        if (st.width as usize, st.height as usize) != (m.width, m.height) {
            bail!(
                "the calibration is {}x{} pixels but the stream's sensor is {}x{}",
                m.width,
                m.height,
                st.width,
                st.height
            );
        }
    }
    let sensor = start
        .as_ref()
        .map(|st| (st.width as usize, st.height as usize));
    if sensor.is_none() {
        eprintln!("warning: no stream-start record: pixels off the right or bottom sensor edge cannot be told apart");
    }
    let masked = rois.iter().filter(|r| r.has(rflags::MASKED)).count();
    if masked > 0 && maps.is_none() {
        eprintln!(
            "warning: {masked} ROIs contain pixels masked by the pipeline (they read 0); give --calibration to leave them out of the fit"
        );
    }
    let hot_mode = match args.hot_pixels {
        HotArg::Ignore => HotPixelMode::Ignore,
        HotArg::Interpolate => HotPixelMode::Interpolate,
    };
    let rows: Vec<Localization> = rois
        .par_iter()
        .enumerate()
        .map(|(i, rec)| fit_record(rec, i as u64 + 1, est, s, sensor, maps.as_ref(), hot_mode))
        .collect();
    if let Some(path) = &args.export_tiff {
        export_tiff(path, &rois, args.export_layout, sensor)?;
    }
    let n = rows.len();
    // The sensor: the stream's, else its sidecar's, else what the ROIs reach.
    let (width, height) = match (&start, &s.sidecar) {
        (Some(st), _) => (u32::from(st.width), u32::from(st.height)),
        (None, Some(info)) => (info.width, info.height),
        (None, None) => rois.iter().fold((1, 1), |(w, h), r| {
            let side = i64::from(r.roi_size);
            (
                w.max((i64::from(r.roi_x0()) + side).clamp(1, u32::MAX as i64) as u32),
                h.max((i64::from(r.roi_y0()) + side).clamp(1, u32::MAX as i64) as u32),
            )
        }),
    };
    // Picasso's frame of a blink is its start plane: the time axis is planes.
    let last = rois.iter().map(|r| r.t_e.max(r.t_s)).max().unwrap_or(0);
    let extent = Extent {
        width,
        height,
        frames: planes.unwrap_or(0).max(last.max(0) as u64 + 1),
        data_type: "uint32".into(),
        blinks: true,
    };
    Ok((
        LocTable {
            extra_columns: vec![
                "t_start [plane]".into(),
                "t_end [plane]".into(),
                "planes".into(),
                "flags".into(),
            ],
            merged: false,
            rows,
        },
        n,
        extent,
    ))
}

/// Fits one blink record.
fn fit_record(
    rec: &BlinkRecord,
    frame: u64,
    est: Estimator,
    s: &Setup,
    sensor: Option<(usize, usize)>,
    maps: Option<&SpadMaps>,
    hot_mode: HotPixelMode,
) -> Localization {
    let side = rec.roi_size as usize;
    let (x0, y0) = (rec.roi_x0(), rec.roi_y0());
    let extra = vec![
        rec.t_s as f64,
        rec.t_e as f64,
        rec.planes_summed as f64,
        rec.flags as f64,
    ];
    let bad_shape =
        side == 0 || side > smartagg_localize::psf::MAX_SIDE || rec.counts.len() != side * side;
    if bad_shape {
        let mut l = Localization::from_fit(
            &smartagg_localize::Fit::failed(side.max(1), s.sigma_px, FitStatus::InconsistentCounts),
            x0 as f64,
            y0 as f64,
            s.pixel_nm,
            frame,
        );
        l.extra = extra;
        return l;
    }
    // Per-ROI maps: pixels off the sensor ignored; calibration maps cut out.
    let mut pm = PixelMaps::uniform(side);
    let mut hot = vec![false; side * side];
    let planes = rec.planes_summed as f64;
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            let (x, y) = (x0 + i as i32, y0 + j as i32);
            let off =
                x < 0 || y < 0 || sensor.is_some_and(|(w, h)| x as usize >= w || y as usize >= h);
            if off {
                pm.ignore[k] = true;
                continue;
            }
            if let Some(m) = maps {
                let (xu, yu) = (x as usize, y as usize);
                if xu < m.width && yu < m.height {
                    let q = yu * m.width + xu;
                    pm.dark[k] = m.dark_per_plane[q];
                    if let Some(g) = &m.gain {
                        // A dead pixel (response 0) is left out rather than
                        // given an impossible gain.
                        if g[q] > 0.0 {
                            pm.gain[k] = g[q];
                        } else {
                            pm.ignore[k] = true;
                        }
                    }
                    hot[k] = m.hot[q];
                }
            }
        }
    }
    let mut data: Vec<f64> = rec.counts.iter().map(|&c| c as f64).collect();
    if maps.is_some() {
        // Shapes agree by construction.
        let _ = smartagg_localize::roi::apply_hot_pixels(&mut data, &hot, hot_mode, &mut pm);
    }
    let fit = if est == Estimator::SpadMle {
        let counts: Vec<u32> = if maps.is_some() && hot_mode == HotPixelMode::Interpolate {
            data.iter().map(|&v| v.round().max(0.0) as u32).collect()
        } else {
            rec.counts.clone()
        };
        let (n_on, n_off) = smartagg_localize::spad::on_off_split(rec);
        let roi = SpadRoi {
            side,
            counts: &counts,
            n_on,
            n_off,
            maps: Some(&pm),
        };
        fit_binomial(&roi, &s.opts)
    } else {
        // Frame estimators see totals: dark counts over all planes summed.
        for d in pm.dark.iter_mut() {
            *d *= planes;
        }
        let opts = FitOptions {
            noise: NoiseModel::Poisson,
            ..s.opts
        };
        fit_roi(
            est,
            &RoiView {
                side,
                data: &data,
                maps: Some(&pm),
            },
            &opts,
        )
    };
    let mut l = Localization::from_fit(&fit, x0 as f64, y0 as f64, s.pixel_nm, frame);
    l.extra = extra;
    l
}

fn export_tiff(
    path: &Path,
    rois: &[BlinkRecord],
    layout: LayoutArg,
    sensor: Option<(usize, usize)>,
) -> anyhow::Result<()> {
    let pages: Vec<RoiPage> = rois
        .iter()
        .map(|r| RoiPage {
            x0: r.roi_x0(),
            y0: r.roi_y0(),
            side: r.roi_size as usize,
            counts: &r.counts,
        })
        .collect();
    let layout = match layout {
        LayoutArg::Compact => RoiLayout::Compact,
        LayoutArg::Sensor => {
            let Some((width, height)) = sensor else {
                bail!("--export-layout sensor needs the stream-start record (sensor size), which this stream lacks");
            };
            // One sensor-sized page per blink, built in memory.
            const MAX_BYTES: u64 = 2 << 30;
            let bytes = (width * height) as u64 * 4 * pages.len() as u64;
            if bytes > MAX_BYTES {
                bail!(
                    "--export-layout sensor would build {} sensor-sized pages of {width}x{height} pixels ({:.1} GiB, the limit is 2 GiB): use --export-layout compact",
                    pages.len(),
                    bytes as f64 / (1u64 << 30) as f64
                );
            }
            RoiLayout::Sensor { width, height }
        }
    };
    let (w, h, data) = tiffio::roi_pages(&pages, layout);
    let mut out = std::io::BufWriter::new(AtomicFile::create(path)?);
    let bits16 = tiffio::write_stack(&mut out, w, h, &data)
        .with_context(|| format!("writing {}", path.display()))?;
    out.into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", path.display()))?
        .commit()?;
    if layout == RoiLayout::Compact {
        let origins = PathBuf::from(format!("{}.origins.csv", path.display()));
        let mut f = std::io::BufWriter::new(AtomicFile::create(&origins)?);
        writeln!(
            f,
            "\"page\",\"x0 [px]\",\"y0 [px]\",\"t_start [plane]\",\"t_end [plane]\",\"planes\""
        )?;
        for (i, r) in rois.iter().enumerate() {
            writeln!(
                f,
                "{},{},{},{},{},{}",
                i + 1,
                r.roi_x0(),
                r.roi_y0(),
                r.t_s,
                r.t_e,
                r.planes_summed
            )?;
        }
        f.into_inner()
            .map_err(|e| e.into_error())
            .with_context(|| format!("writing {}", origins.display()))?
            .commit()?;
        eprintln!(
            "{} ROIs written to {} ({}x{}, {}); page origins in {}",
            rois.len(),
            path.display(),
            w,
            h,
            if bits16 { "16-bit" } else { "32-bit float" },
            origins.display()
        );
    } else {
        eprintln!(
            "{} sensor-sized pages written to {}",
            rois.len(),
            path.display()
        );
    }
    Ok(())
}

fn localize_tiff(args: &Args, s: &Setup) -> anyhow::Result<(LocTable, usize, Extent)> {
    let est = args.estimator.estimator();
    if args.export_tiff.is_some() {
        bail!("--export-tiff applies to blink-ROI packet input");
    }
    // ADU conversion: options, else the preset, else identity.
    let (p_off, p_epa, p_gain, p_read) = match s.preset.as_ref().map(|p| &p.camera) {
        Some(Camera::Emccd(c)) => (c.offset_adu, c.e_per_adu, c.em_gain, c.read_noise_e),
        Some(Camera::Scmos(c)) => (c.offset_adu, c.e_per_adu, 1.0, c.read_noise_e),
        _ => (0.0, 1.0, 1.0, 0.0),
    };
    let conversion = Conversion {
        offset_adu: args.offset_adu.unwrap_or(p_off),
        e_per_adu: args.e_per_adu.unwrap_or(p_epa),
        em_gain: args.em_gain.unwrap_or(p_gain),
    };
    conversion.validate()?;
    let read_noise = args.read_noise_e.unwrap_or(p_read);
    let calibration = match &args.calibration {
        None => None,
        Some(dir) => match AnyCalibration::load(dir)
            .with_context(|| format!("loading calibration {}", dir.display()))?
        {
            AnyCalibration::Frame(f) => Some(f),
            AnyCalibration::Spad(_) => bail!(
                "{} is a SPAD calibration; frames need an EMCCD or sCMOS calibration",
                dir.display()
            ),
        },
    };
    let roi = args.roi.unwrap_or_else(|| {
        let r = 2 * (3.0 * s.sigma_px).ceil() as usize + 1;
        r.clamp(7, 21)
    });
    let stack = tiffio::open_stack(&args.input)?;
    let mut size = (0, 0);
    let mut rows = Vec::new();
    let mut frames = 0u64;
    let mut candidates = 0usize;
    let mut pipeline: Option<FramePipeline> = None;
    // A reader thread decodes batches of frames while the pool fits the
    // previous batch (decoding is a good part of a small frame's cost).
    let (tx, rx) = std::sync::mpsc::sync_channel::<anyhow::Result<Vec<_>>>(2);
    std::thread::scope(|scope| -> anyhow::Result<()> {
        scope.spawn(move || {
            let mut batch = Vec::with_capacity(FRAME_BATCH);
            let mut no = 0u64;
            for frame in stack {
                no += 1;
                match frame {
                    Ok(f) => batch.push((no, f)),
                    Err(e) => {
                        let _ = tx.send(Err(e.into()));
                        return;
                    }
                }
                if batch.len() == FRAME_BATCH
                    && tx
                        .send(Ok(std::mem::replace(
                            &mut batch,
                            Vec::with_capacity(FRAME_BATCH),
                        )))
                        .is_err()
                {
                    return;
                }
            }
            if !batch.is_empty() {
                let _ = tx.send(Ok(batch));
            }
        });
        for batch in rx {
            let mut batch = batch?;
            frames += batch.len() as u64;
            let first = &batch[0].1;
            if pipeline.is_none() {
                size = (first.width, first.height);
                let p = frame_pipeline(
                    args,
                    s,
                    est,
                    conversion,
                    read_noise,
                    roi,
                    calibration.as_ref(),
                    first,
                )?;
                let used = p.roi_for(first.width, first.height);
                if used != roi {
                    eprintln!(
                        "frames are {}x{} pixels: fitting {used}x{used} ROIs instead of {roi}x{roi}",
                        first.width, first.height
                    );
                }
                pipeline = Some(p);
            }
            let p = pipeline.as_ref().expect("set above");
            if let Some(c) = &calibration {
                for (_, frame) in batch.iter_mut() {
                    calibrate_frame(c, conversion, frame)?;
                }
            }
            candidates += localize_batch(p, &batch, &mut rows)?;
        }
        Ok(())
    })?;
    if pipeline.is_none() {
        bail!("{} holds no frames", args.input.display());
    }
    let fits = rows.len();
    eprintln!("{frames} frames, {candidates} candidates above threshold");
    let mut table = LocTable {
        extra_columns: vec![],
        merged: false,
        rows,
    };
    if let Some(d) = args.merge_nm {
        if !(d.is_finite() && d > 0.0) {
            bail!("--merge-nm must be a positive distance in nm, got {d}");
        }
        let (merged, st) = merge_consecutive(&table.rows, d, args.merge_gap);
        eprintln!(
            "merging within {d} nm over consecutive frames: {} → {} localisations ({} tracks of two or more; {} failed fits not merged)",
            st.input, st.output, st.merged_tracks, st.passed_failed
        );
        table.rows = merged;
        table.merged = true;
    }
    let extent = Extent {
        width: size.0.min(u32::MAX as usize) as u32,
        height: size.1.min(u32::MAX as usize) as u32,
        frames,
        data_type: tiff_data_type(&args.input),
        blinks: false,
    };
    Ok((table, fits, extent))
}

/// Frames per batch handed from the reader to the workers.
const FRAME_BATCH: usize = 1024;

/// Per-pixel conversion of a frame with a frame calibration:
/// (ADU − offset) / (ADU per electron).
fn calibrate_frame(
    c: &crate::calibration::FrameCalibration,
    conversion: Conversion,
    frame: &mut smartagg_localize::tiffio::Frame,
) -> anyhow::Result<()> {
    if (c.width as usize, c.height as usize) != (frame.width, frame.height) {
        bail!(
            "the calibration is {}x{} pixels but the frames are {}x{}",
            c.width,
            c.height,
            frame.width,
            frame.height
        );
    }
    for (k, v) in frame.data.iter_mut().enumerate() {
        let gain = c
            .gain_adu_per_e
            .as_ref()
            .map_or(1.0 / (conversion.e_per_adu / conversion.em_gain), |g| g[k]);
        *v = (*v - c.offset_adu[k]) / gain.max(1e-12);
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn frame_pipeline(
    args: &Args,
    s: &Setup,
    est: Estimator,
    conversion: Conversion,
    read_noise: f64,
    roi: usize,
    calibration: Option<&crate::calibration::FrameCalibration>,
    first: &smartagg_localize::tiffio::Frame,
) -> anyhow::Result<FramePipeline> {
    let n = first.width * first.height;
    let scmos = s.opts.noise == NoiseModel::Scmos;
    let read_var = if scmos {
        Some(match calibration.and_then(|c| c.read_noise_e.as_ref()) {
            Some(m) => m.iter().map(|r| r * r).collect(),
            None => vec![read_noise * read_noise; n],
        })
    } else {
        None
    };
    let hot = calibration.map(|c| {
        let mode = match args.hot_pixels {
            HotArg::Ignore => HotPixelMode::Ignore,
            HotArg::Interpolate => HotPixelMode::Interpolate,
        };
        (c.flags.iter().map(|f| f & flags::HOT != 0).collect(), mode)
    });
    let p = FramePipeline {
        // With a calibration the host converts per pixel.
        conversion: if calibration.is_some() {
            Conversion::IDENTITY
        } else {
            conversion
        },
        roi_side: roi,
        threshold_factor: args.threshold,
        estimator: est,
        fit: s.opts,
        pixel_nm: s.pixel_nm,
        read_var,
        hot,
        spad_planes: args.planes,
    };
    p.validate(first.width, first.height)?;
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
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
            preset: None,
            objective: 150,
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
        let pages: Vec<_> = tiffio::open_stack(&dir.path().join("rois.tif"))
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
        tiffio::write_stack(tiffio::create(&input).unwrap(), w, h, &frames).unwrap();
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
