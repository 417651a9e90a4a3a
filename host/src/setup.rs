//! Shared command-line plumbing: pipeline parameters from a preset (with
//! overrides), recording input, progress bars.

use anyhow::{bail, Context};
use smartagg_model::config::PipelineConfig;
use smartagg_model::params::{Preset, PresetName};
use smartagg_model::recording::{BitOrder, RecordingReader};
use smartagg_model::stats::{self, Detection, DetectionInputs};
use std::io::Read;

/// How tracks are opened and held on to.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DetectionMode {
    /// For the whole field: the open threshold keeps background-only false
    /// blinks within --false-blinks-per-s over the sensor, a track is held
    /// on at the paper's 3σ threshold, association within 2σ of the PSF,
    /// L_min = 1 (model/src/field_design.rs).
    #[default]
    Field,
    /// The paper's literal scheme: one per-pixel 3σ threshold, L_min = 1,
    /// r_assoc = 1 (right for one molecule in a 32×32 ROI).
    Paper,
}

/// `--preset` and `--objective`: a camera preset and the objective it is
/// used with, default SPCImager at 150x. Every command that takes a preset
/// flattens this (or [`OptionalPresetArgs`]); a command whose presets are
/// fewer, or whose preset is required, says so with `mut_arg("preset", ..)`.
#[derive(clap::Args, Debug, Clone, PartialEq, Eq)]
pub struct PresetArgs {
    /// Camera preset: spcimager, spcimager-projected, spad512s, emccd, scmos.
    #[arg(
        id = "preset",
        long = "preset",
        value_name = "PRESET",
        default_value = "spcimager"
    )]
    pub name: String,
    /// Objective magnification: 150 or 60.
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
}

impl Default for PresetArgs {
    /// The command-line defaults: SPCImager at 150x.
    fn default() -> PresetArgs {
        PresetArgs {
            name: "spcimager".into(),
            objective: 150,
        }
    }
}

/// [`PresetArgs`] for commands where the preset is optional (it then comes
/// from the input, or is not needed).
#[derive(clap::Args, Debug, Clone, PartialEq, Eq)]
pub struct OptionalPresetArgs {
    /// Camera preset: spcimager, spcimager-projected, spad512s, emccd, scmos.
    #[arg(id = "preset", long = "preset", value_name = "PRESET")]
    pub name: Option<String>,
    /// Objective magnification of the preset: 150 or 60.
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
}

/// How the pipeline is parametrised: a preset and objective give N, the
/// thresholds and the kernel through the statistics; any of them can be
/// overridden.
#[derive(clap::Args, Debug, Clone)]
#[command(mut_arg("preset", |a| a.help("Camera preset whose statistics set N, T and the kernel (spcimager, spcimager-projected, spad512s)")))]
pub struct PipelineArgs {
    // `--preset` (whose statistics set N, T and the kernel) and `--objective`.
    #[command(flatten)]
    pub preset: PresetArgs,
    /// Molecule flux, photons/s reaching the sensor (default: the study's 50,000).
    #[arg(long)]
    pub flux: Option<f64>,
    /// Override the rolling window N (bit-planes).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub n_window: Option<u32>,
    /// Detection design: `field` (default) or the paper's literal `paper`.
    #[arg(long, value_enum, default_value_t = DetectionMode::Field)]
    pub detection: DetectionMode,
    /// Budget of background-only false blinks per second over the whole
    /// field, for `--detection field`.
    #[arg(long, default_value_t = smartagg_model::field_design::DEFAULT_FALSE_BLINKS_PER_S)]
    pub false_blinks_per_s: f64,
    /// Override the integer threshold T_int that opens a track.
    #[arg(long)]
    pub threshold_int: Option<u32>,
    /// Override the integer threshold T_hold that holds a track on (≤ T_int).
    #[arg(long)]
    pub threshold_hold: Option<u32>,
    /// Planes left out at the end of a blink's sum: a blink that ends sums
    /// the bit-planes [t_cross − N, t_drop − END_TRIM] (0 ..= N − 1);
    /// default: ⌊N/2⌋ with `--detection field` (to the blink's estimated
    /// end), 0 with `paper` (the paper's sum, to t_drop).
    #[arg(long)]
    pub end_trim: Option<u32>,
    /// Planes a track must stay on to be confirmed (default 1, both designs).
    #[arg(long)]
    pub l_min: Option<u32>,
    /// Planes after which a long blink is cut into a new segment (default: one second of bit-planes with `--detection field`, 10,000 for the SPCImager; 10,000 with `paper`).
    #[arg(long)]
    pub l_max: Option<u32>,
    /// Tracking slots M.
    #[arg(long, default_value_t = smartagg_model::config::DEFAULT_SLOTS)]
    pub slots: usize,
    /// ROI side R (odd); default: the kernel size.
    #[arg(long)]
    pub roi: Option<usize>,
    /// Association radius, pixels (Chebyshev); default: round(2σ) of the
    /// PSF with `--detection field`, 1 with `paper`.
    #[arg(long)]
    pub r_assoc: Option<u32>,
    /// Calibration folder (`smartagg calibrate`): its hot pixels, judged
    /// against this run's N and T_hold (a hot pixel at the hold level would keep a track on), are masked (read as 0).
    #[arg(long)]
    pub calibration: Option<std::path::PathBuf>,
}

impl PipelineArgs {
    /// The options given that change the pipeline's configuration (all but
    /// the camera), by their command-line names.
    pub fn configuration_options(&self) -> Vec<&'static str> {
        let d = PipelineArgs::default();
        let mut given = Vec::new();
        let mut note = |set: bool, name: &'static str| {
            if set {
                given.push(name);
            }
        };
        note(self.flux.is_some(), "--flux");
        note(self.n_window.is_some(), "--n-window");
        note(self.detection != d.detection, "--detection");
        note(
            self.false_blinks_per_s != d.false_blinks_per_s,
            "--false-blinks-per-s",
        );
        note(self.threshold_int.is_some(), "--threshold-int");
        note(self.threshold_hold.is_some(), "--threshold-hold");
        note(self.end_trim.is_some(), "--end-trim");
        note(self.l_min.is_some(), "--l-min");
        note(self.l_max.is_some(), "--l-max");
        note(self.slots != d.slots, "--slots");
        note(self.roi.is_some(), "--roi");
        note(self.r_assoc.is_some(), "--r-assoc");
        note(self.calibration.is_some(), "--calibration");
        given
    }
}

impl Default for PipelineArgs {
    /// The command-line defaults: SPCImager at 150x, the field design.
    fn default() -> PipelineArgs {
        PipelineArgs {
            preset: PresetArgs::default(),
            flux: None,
            n_window: None,
            detection: DetectionMode::Field,
            false_blinks_per_s: smartagg_model::field_design::DEFAULT_FALSE_BLINKS_PER_S,
            threshold_int: None,
            threshold_hold: None,
            end_trim: None,
            l_min: None,
            l_max: None,
            slots: smartagg_model::config::DEFAULT_SLOTS,
            roi: None,
            r_assoc: None,
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
    let (_, det) = detection(&args.preset.name, args.preset.objective, args.flux)?;
    // Another window moves the paper's Eq. 7 threshold (and so the design) with it.
    let det = match args.n_window {
        Some(n) => det.at_window(n),
        None => det,
    };
    let n = det.n_window;
    let t32 = |t: u64| u32::try_from(t).context("the derived threshold does not fit 32 bits");
    // The paper's scheme: one threshold, L_min 1, r_assoc 1, end_trim 0.
    let mut cfg = PipelineConfig::new(
        width as usize,
        height as usize,
        n,
        det.kernel_weights.clone(),
        det.kernel_shift,
        t32(det.threshold_int)?,
    );
    if args.detection == DetectionMode::Field {
        if plane_period_ns == 0 {
            bail!("the recording's plane period is 0 ns");
        }
        let d = smartagg_model::field_design::design(
            &det,
            width,
            height,
            1e9 / plane_period_ns as f64,
            args.false_blinks_per_s,
        )?;
        eprintln!("{}", describe_design(&d));
        d.apply(&mut cfg)?;
    }
    if let Some(t) = args.threshold_int {
        cfg.threshold_int = t;
        // An open level given alone holds at the same level unless that
        // would put the hold level above it.
        cfg.threshold_hold = cfg.threshold_hold.min(t);
    }
    if let Some(t) = args.threshold_hold {
        cfg.threshold_hold = t;
    }
    if let Some(c) = args.end_trim {
        cfg.end_trim = c;
    }
    if cfg.end_trim >= n {
        bail!(
            "--end-trim {} planes must be below the window N = {n}: a blink's last summed plane must have left the window when its end is seen",
            cfg.end_trim
        );
    }
    if let Some(l) = args.l_min {
        cfg.l_min = l;
    }
    let l_max = args.l_max.unwrap_or(cfg.l_max);
    if l_max < n.max(cfg.l_min) {
        bail!(
            "--l-max {} planes is shorter than the window N = {n} (and L_min = {}): a blink is cut into segments of L_max planes, give at least {}",
            l_max,
            cfg.l_min,
            n.max(cfg.l_min)
        );
    }
    cfg.l_max = l_max;
    cfg.slots = args.slots;
    if let Some(r) = args.r_assoc {
        cfg.r_assoc = r;
    }
    if let Some(r) = args.roi {
        cfg.roi_size = r;
    }
    cfg.plane_period_ns = u32::try_from(plane_period_ns).map_err(|_| {
        anyhow::anyhow!(
            "the plane period is {plane_period_ns} ns; the stream records at most {} ns (4.29 s)",
            u32::MAX
        )
    })?;
    if let Some(path) = &args.calibration {
        let cal = smartagg_calibration::Calibration::load(path)?;
        anyhow::ensure!(
            (cal.width, cal.height) == (width, height),
            "calibration {} is for {}x{} pixels, the recording has {}x{}",
            path.display(),
            cal.width,
            cal.height,
            width,
            height
        );
        // A hot pixel at the hold level would keep a neighbouring track on.
        let hold = cfg.threshold_hold;
        let criterion = cal.hot_criterion.with_threshold(n, hold as u64)?;
        let mask = cal.hot_mask_for(&criterion);
        eprintln!(
            "calibration {}: {} hot pixels masked (dark counts alone would reach T_hold = {hold} with N = {n})",
            path.display(),
            mask.count()
        );
        cfg.hot_mask = Some(mask);
    }
    cfg.validate()?;
    Ok(cfg)
}

/// What a field design chose and predicts, in a microscopist's words.
pub fn describe_design(d: &smartagg_model::field_design::FieldDesign) -> String {
    let ms = |p: u32| p as f64 / d.plane_rate_hz * 1e3;
    let shortest = match d.shortest_blink_planes {
        Some(p) => format!(
            "blinks of {:.1} ms or longer are detected with ≥ 90 % probability (predicted)",
            ms(p)
        ),
        None => "warning: at this budget no blink reaches 90 % predicted detection: the light is too weak; raise --false-blinks-per-s or use a longer window".into(),
    };
    format!(
        "detection: a track opens at T_int = {} ({:.1} sd above background: at most {:.3} false blinks/s over the {}x{} field from background alone, budget {}/s) and stays on down to T_hold = {} (the paper's 3-sigma level); a blink's ROI sums the planes from N before the crossing to its estimated end, t_drop - {}; {shortest}",
        d.threshold_open,
        d.open_sigmas,
        d.predicted_false_blinks_per_s,
        d.width,
        d.height,
        d.budget_per_s,
        d.threshold_hold,
        d.end_trim,
    )
}

/// One line describing a configuration.
pub fn describe(cfg: &PipelineConfig) -> String {
    format!(
        "pipeline: {}x{} pixels, window N = {} planes, T_int = {} (open), T_hold = {}, end_trim = {}, kernel {:?} (sum 2^{}), L_min = {}, L_max = {}, r_assoc = {}, {} slots, ROI {}x{}",
        cfg.width,
        cfg.height,
        cfg.n_window,
        cfg.threshold_int,
        cfg.threshold_hold,
        cfg.end_trim,
        cfg.kernel,
        cfg.kernel_shift,
        cfg.l_min,
        cfg.l_max,
        cfg.r_assoc,
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

/// A number within `lo..=hi` (finite), for clap's `value_parser`; the error
/// names the range and the unit.
pub fn ranged(s: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number ({unit})"))?;
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{s} is outside {}..={} {unit}", num(lo), num(hi)))
    }
}

/// A number as a person writes it: plain in 0.001..1e7, else in e-notation.
pub fn num(v: f64) -> String {
    if v == 0.0 || (1e-3..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Most worker threads an option may ask for.
pub const MAX_THREADS: usize = 1024;

/// A worker-thread count for clap's `value_parser`: 1..=[`MAX_THREADS`].
pub fn thread_count(s: &str) -> Result<usize, String> {
    let v: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a whole number of threads"))?;
    if (1..=MAX_THREADS).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{s} threads: give 1 to {MAX_THREADS}"))
    }
}

/// `threads` capped at the machine's cores, with a note when it was more.
pub fn cap_threads(threads: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if threads > cores {
        eprintln!(
            "note: {threads} threads asked for, this machine has {cores} cores: using {cores}"
        );
        cores
    } else {
        threads
    }
}
