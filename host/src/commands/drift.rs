//! `smartagg drift`: estimate and remove stage drift from a localisation
//! table (the algorithm is `smartagg_localize::drift`).
//!
//! The table is split into `--segments` time segments (or segments of
//! `--segment-s` seconds, with `--frame-s`); the drift of each is estimated
//! by redundant cross-correlation (`--method rcc`, the default) or from
//! fiducials (`--method fiducials`: spots present in every segment), then
//! interpolated linearly to each localisation's time and subtracted.
//!
//! Time is the middle of `t_start [plane]`/`t_end [plane]` (our blink-ROI
//! tables; `t_s`/`t_e` of the demo's) or else `frame`. Only localisations
//! whose fit succeeded (`fit_status` 0, where there is one) enter the
//! estimate; every row is corrected.
//!
//! Outputs, all written beside their targets and renamed into place once
//! everything is computed, never over the input:
//! * `--out`: the table itself with `x [nm]` and `y [nm]` corrected; every
//!   other byte as it was;
//! * `--trajectory` (default `OUT` with `.drift.csv`): one row per segment,
//!   `segment,t_start,t_end,t_mean,t_mean_s,localisations,dx_nm,dy_nm`
//!   (time in the table's unit; `t_mean_s` in seconds with `--frame-s`,
//!   else empty), the drift relative to the first segment;
//! * `--plot` (default `OUT` with `.drift.png`): the trajectory, dx and dy
//!   against time (skipped with a warning where no font is available).

use anyhow::{bail, Context};
use smartagg_localize::drift::{self, DriftOptions, DriftPoint};
use smartagg_localize::table::CsvTable;
use std::path::{Path, PathBuf};

use smartagg_io::output::{refuse_overwriting, AtomicFile};
use std::io::Write as _;

/// How the drift is estimated.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Redundant cross-correlation of the segments' images (Wang et al. 2014).
    Rcc,
    /// Spots present in every segment (beads, persistent markers).
    Fiducials,
}

/// Arguments of `smartagg drift`.
#[derive(clap::Args, Debug)]
pub struct Args {
    // A help attribute, not a doc comment: rustdoc would read "[nm]" as a link.
    #[arg(
        help = "Localisation table (ThunderSTORM CSV with \"x [nm]\", \"y [nm]\" and a time column)"
    )]
    pub table: PathBuf,
    /// Corrected table (same columns).
    #[arg(long)]
    pub out: PathBuf,
    /// Estimation method.
    #[arg(long, value_enum, default_value_t = Method::Rcc)]
    pub method: Method,
    /// Number of time segments [default: 10].
    #[arg(long, conflicts_with = "segment_s")]
    pub segments: Option<usize>,
    /// Segment duration, s (needs --frame-s).
    #[arg(long, requires = "frame_s", allow_negative_numbers = true)]
    pub segment_s: Option<f64>,
    /// Seconds per unit of the table's time column (1e-4 for SPCImager bit-planes).
    #[arg(long, allow_negative_numbers = true)]
    pub frame_s: Option<f64>,
    /// RCC image pixel (histogram bin), nm [default: 15, coarser if the field needs it].
    #[arg(long, allow_negative_numbers = true)]
    pub pixel_nm: Option<f64>,
    /// Largest drift between two segments searched for, nm.
    #[arg(long, default_value_t = 500.0, allow_negative_numbers = true)]
    pub max_drift_nm: f64,
    /// RCC: drop pairs whose residual exceeds this, nm.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    pub reject_nm: f64,
    /// Fiducials: radius of a spot, nm (also the largest step followed between segments).
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub fiducial_radius_nm: f64,
    /// Fiducials: localisations a spot needs in every segment.
    #[arg(long, default_value_t = 5)]
    pub fiducial_min: usize,
    /// Trajectory CSV [default: OUT with extension .drift.csv].
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// Trajectory plot (PNG) [default: OUT with extension .drift.png].
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

fn beside(out: &Path, ext: &str) -> PathBuf {
    out.with_extension(ext)
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Every option and output path is checked before anything is read.
    let trajectory = args
        .trajectory
        .clone()
        .unwrap_or_else(|| beside(&args.out, "drift.csv"));
    let plot = args
        .plot
        .clone()
        .unwrap_or_else(|| beside(&args.out, "drift.png"));
    for (o, name) in [
        (&args.out, "--out"),
        (&trajectory, "--trajectory"),
        (&plot, "--plot"),
    ] {
        refuse_overwriting(o, &[&args.table]).with_context(|| name.to_string())?;
    }
    if args.out == trajectory || args.out == plot || trajectory == plot {
        bail!("--out, --trajectory and --plot must be three different files");
    }
    if let Some(f) = args.frame_s {
        if !(f.is_finite() && f > 0.0 && f <= 1e6) {
            bail!("invalid parameter `--frame-s` = {f}: must be a positive number of seconds");
        }
    }
    if let Some(s) = args.segment_s {
        if !(s.is_finite() && s > 0.0) {
            bail!("invalid parameter `--segment-s` = {s}: must be a positive number of seconds");
        }
    }
    let mut opts = DriftOptions {
        segments: args.segments.unwrap_or(10),
        bin_nm: args.pixel_nm,
        max_drift_nm: args.max_drift_nm,
        reject_nm: args.reject_nm,
        fiducial_radius_nm: args.fiducial_radius_nm,
        fiducial_min: args.fiducial_min,
    };
    opts.validate()?;

    let text =
        std::fs::read(&args.table).with_context(|| format!("reading {}", args.table.display()))?;
    let table =
        CsvTable::read(&text[..]).with_context(|| format!("reading {}", args.table.display()))?;
    let col = |names: &'static [&'static str]| {
        table
            .require(names)
            .map_err(|m| anyhow::anyhow!("{} {m}", args.table.display()))
    };
    let (cx, cy) = (col(&["x [nm]"])?, col(&["y [nm]"])?);
    let (ta, tb, unit) = drift::time_columns(&table).with_context(|| {
        format!(
            "{} has no time column (\"t_start [plane]\" and \"t_end [plane]\", or \"frame\")",
            args.table.display()
        )
    })?;
    let status = table.column(&["fit_status"]);
    for (n, r) in table.rows.iter().enumerate() {
        if let Some(c) = r.iter().position(|v| !v.is_finite()) {
            bail!(
                "{}: data row {} has a non-finite value in column \"{}\": fix or remove it first",
                args.table.display(),
                n + 1,
                table.columns[c]
            );
        }
    }
    let time = |r: &[f64]| 0.5 * (r[ta] + r[tb]);
    let points: Vec<DriftPoint> = table
        .rows
        .iter()
        .filter(|r| status.is_none_or(|c| r[c] == 0.0))
        .map(|r| DriftPoint {
            t: time(r),
            x_nm: r[cx],
            y_nm: r[cy],
        })
        .collect();
    if let Some(s) = args.segment_s {
        let frame_s = args
            .frame_s
            .expect("clap requires --frame-s with --segment-s");
        let (lo, hi) = points
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.t), b.max(p.t)));
        let span_s = (hi - lo).max(0.0) * frame_s;
        opts.segments =
            ((span_s / s).round() as usize).clamp(drift::MIN_SEGMENTS, drift::MAX_SEGMENTS);
    }
    let est = match args.method {
        Method::Rcc => drift::rcc(&points, &opts),
        Method::Fiducials => drift::fiducials(&points, &opts),
    }
    .with_context(|| {
        let m = format!("{:?}", args.method).to_lowercase();
        format!("{}: drift correction ({m})", args.table.display())
    })?;

    let corrected = table
        .rewrite_xy(&text, cx, cy, |r| est.at(time(r)))
        .with_context(|| format!("rewriting {}", args.table.display()))?;
    let csv = est.trajectory_csv(args.frame_s);
    let png = smartagg_localize::figure::drift_png(&est, args.frame_s, &unit);

    // All files are started before any is renamed into place: a folder
    // that does not exist stops the run with nothing written.
    let mut files = vec![
        (AtomicFile::create(&args.out)?, corrected, &args.out),
        (
            AtomicFile::create(&trajectory)?,
            csv.into_bytes(),
            &trajectory,
        ),
    ];
    match png {
        Ok(bytes) => files.push((AtomicFile::create(&plot)?, bytes, &plot)),
        Err(e) => eprintln!("smartagg: warning: no plot written ({e})"),
    }
    for (f, bytes, path) in &mut files {
        f.write_all(bytes)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    for (f, _, _) in files {
        f.commit()?;
    }
    let last = est.segments.last().expect("at least two segments");
    match args.method {
        Method::Rcc => println!(
            "RCC: {} segments, {} of {} pairs kept (residual RMS {:.2} nm), bins of {:.1} nm",
            est.segments.len(),
            est.used,
            est.total,
            est.residual_rms_nm,
            est.bin_nm
        ),
        Method::Fiducials => println!(
            "fiducials: {} segments, {} of {} spots followed through every segment (spread {:.2} nm)",
            est.segments.len(),
            est.used,
            est.total,
            est.residual_rms_nm
        ),
    }
    println!(
        "drift of the last segment: {:.1}, {:.1} nm; {} localisations used of {}; wrote {}, {}, {}",
        last.dx_nm,
        last.dy_nm,
        points.len(),
        table.rows.len(),
        args.out.display(),
        trajectory.display(),
        plot.display()
    );
    Ok(())
}
