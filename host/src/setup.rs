//! Shared command-line plumbing: pipeline parameters from a preset (with
//! overrides), recording input, progress bars.

use anyhow::{bail, Context};
use smartagg_model::config::PipelineConfig;
use smartagg_model::params::{Preset, PresetName};
use smartagg_model::recording::{BitOrder, RecordingReader};
use smartagg_model::stats::{self, Detection, DetectionInputs};
use std::io::Read;

/// How the pipeline is parametrised: a preset and objective give N, T_int and
/// the kernel through the paper's statistics; any of them can be overridden.
#[derive(clap::Args, Debug, Clone)]
pub struct PipelineArgs {
    /// Camera preset whose statistics set N, T and the kernel (spcimager, spcimager-projected).
    #[arg(long, default_value = "spcimager")]
    pub preset: String,
    /// Objective magnification: 150 or 60.
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
    /// Molecule flux, photons/s reaching the sensor (default: the study's 50,000).
    #[arg(long)]
    pub flux: Option<f64>,
    /// Override the rolling window N (bit-planes).
    #[arg(long)]
    pub n_window: Option<u32>,
    /// Override the integer threshold T_int.
    #[arg(long)]
    pub threshold_int: Option<u32>,
    /// Planes a track must stay on to be confirmed (1 reproduces the paper).
    #[arg(long, default_value_t = 1)]
    pub l_min: u32,
    /// Planes after which a long blink is cut into a new segment.
    #[arg(long, default_value_t = smartagg_model::config::DEFAULT_L_MAX)]
    pub l_max: u32,
    /// Tracking slots M.
    #[arg(long, default_value_t = smartagg_model::config::DEFAULT_SLOTS)]
    pub slots: usize,
    /// ROI side R (odd); default: the kernel size.
    #[arg(long)]
    pub roi: Option<usize>,
    /// Association radius, pixels (Chebyshev).
    #[arg(long, default_value_t = 1)]
    pub r_assoc: u32,
    /// Calibration folder (`smartagg calibrate`): its hot pixels, judged
    /// against this run's N and T_int, are masked (read as 0).
    #[arg(long)]
    pub calibration: Option<std::path::PathBuf>,
}

impl Default for PipelineArgs {
    /// The command-line defaults: SPCImager at 150x, the paper's L_min = 1.
    fn default() -> PipelineArgs {
        PipelineArgs {
            preset: "spcimager".into(),
            objective: 150,
            flux: None,
            n_window: None,
            threshold_int: None,
            l_min: 1,
            l_max: smartagg_model::config::DEFAULT_L_MAX,
            slots: smartagg_model::config::DEFAULT_SLOTS,
            roi: None,
            r_assoc: 1,
            calibration: None,
        }
    }
}

/// Options for headerless recordings.
#[derive(clap::Args, Debug, Clone)]
pub struct RawArgs {
    /// The recording is raw packed planes without a .spad header (give --width and --height).
    #[arg(long)]
    pub raw: bool,
    /// Width of raw planes, pixels.
    #[arg(long, requires = "raw")]
    pub width: Option<u32>,
    /// Height of raw planes, pixels.
    #[arg(long, requires = "raw")]
    pub height: Option<u32>,
    /// Bit order of raw planes: lsb (pixel i at bit i%8) or msb.
    #[arg(long, default_value = "lsb", requires = "raw")]
    pub bit_order: String,
    /// Plane period of raw planes, ns.
    #[arg(long, default_value_t = 100_000, requires = "raw")]
    pub plane_period_ns: u64,
}

/// Opens a `.spad` recording, or raw packed planes with `--raw`.
pub fn open_recording<R: Read>(r: R, raw: &RawArgs) -> anyhow::Result<RecordingReader<R>> {
    if !raw.raw {
        return Ok(RecordingReader::open(r)?);
    }
    let (Some(w), Some(h)) = (raw.width, raw.height) else {
        bail!("--raw needs --width and --height");
    };
    let order = match raw.bit_order.as_str() {
        "lsb" => BitOrder::LsbFirst,
        "msb" => BitOrder::MsbFirst,
        other => bail!("--bit-order must be lsb or msb, not `{other}`"),
    };
    Ok(RecordingReader::open_raw(
        r,
        w,
        h,
        order,
        raw.plane_period_ns,
    )?)
}

/// The paper's statistics for a preset, objective and flux.
pub fn detection(
    preset: &str,
    objective: u32,
    flux: Option<f64>,
) -> anyhow::Result<(Preset, Detection)> {
    let preset = Preset::new(PresetName::parse(preset)?, objective)?;
    let inputs = DetectionInputs::from_preset(&preset, flux)?;
    let det = stats::derive(&inputs)?;
    Ok((preset, det))
}

/// A validated pipeline configuration for a `width × height` sensor.
pub fn pipeline_config(
    args: &PipelineArgs,
    width: u32,
    height: u32,
    plane_period_ns: u64,
) -> anyhow::Result<PipelineConfig> {
    let (_, det) = detection(&args.preset, args.objective, args.flux)?;
    let n = args.n_window.unwrap_or(det.n_window);
    let threshold = match args.threshold_int {
        Some(t) => t,
        None => u32::try_from(det.threshold_int)
            .context("the derived threshold does not fit 32 bits")?,
    };
    let mut cfg = PipelineConfig::new(
        width as usize,
        height as usize,
        n,
        det.kernel_weights.clone(),
        det.kernel_shift,
        threshold,
    );
    cfg.l_min = args.l_min;
    cfg.l_max = args.l_max.max(n);
    cfg.slots = args.slots;
    cfg.r_assoc = args.r_assoc;
    if let Some(r) = args.roi {
        cfg.roi_size = r;
    }
    cfg.plane_period_ns = u32::try_from(plane_period_ns).context("plane period above 4.29 s")?;
    if let Some(path) = &args.calibration {
        let cal = crate::calibration::Calibration::load(path)?;
        anyhow::ensure!(
            (cal.width, cal.height) == (width, height),
            "calibration {} is for {}x{} pixels, the recording has {}x{}",
            path.display(),
            cal.width,
            cal.height,
            width,
            height
        );
        let criterion = cal.hot_criterion.with_threshold(n, threshold as u64)?;
        let mask = cal.hot_mask_for(&criterion);
        eprintln!(
            "calibration {}: {} hot pixels masked (dark counts alone would reach T_int = {threshold} with N = {n})",
            path.display(),
            mask.count()
        );
        cfg.hot_mask = Some(mask);
    }
    cfg.validate()?;
    Ok(cfg)
}

/// One line describing a configuration.
pub fn describe(cfg: &PipelineConfig) -> String {
    format!(
        "pipeline: {}x{} pixels, window N = {} planes, T_int = {}, kernel {:?} (sum 2^{}), L_min = {}, L_max = {}, {} slots, ROI {}x{}",
        cfg.width,
        cfg.height,
        cfg.n_window,
        cfg.threshold_int,
        cfg.kernel,
        cfg.kernel_shift,
        cfg.l_min,
        cfg.l_max,
        cfg.slots,
        cfg.roi_size,
        cfg.roi_size
    )
}

/// A progress bar on stderr (hidden with `quiet` or when stderr is not a terminal).
pub fn progress(total: Option<u64>, quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = match total {
        Some(n) => indicatif::ProgressBar::new(n),
        None => indicatif::ProgressBar::new_spinner(),
    };
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} planes ({per_sec}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb
}
