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
use plotters::prelude::*;
use smartagg_localize::drift::{self, DriftEstimate, DriftOptions, DriftPoint};
use smartagg_localize::table::{format_decimal, CsvTable};
use std::fmt::Write as _;
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

/// The time column(s) of a table: a (start, end) pair or one column.
fn time_columns(t: &CsvTable) -> Option<(usize, usize, String)> {
    for (a, b) in [
        ("t_start [plane]", "t_end [plane]"),
        ("t_s [plane]", "t_e [plane]"),
    ] {
        if let (Some(i), Some(j)) = (t.column(&[a]), t.column(&[b])) {
            return Some((i, j, "plane".into()));
        }
    }
    t.column(&["frame"]).map(|i| (i, i, "frame".into()))
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
    let col = |name: &str| {
        table.column(&[name]).with_context(|| {
            format!(
                "{} has no column \"{name}\" (columns: {})",
                args.table.display(),
                table.columns.join(", ")
            )
        })
    };
    let (cx, cy) = (col("x [nm]")?, col("y [nm]")?);
    let (ta, tb, unit) = time_columns(&table).with_context(|| {
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

    let corrected = rewrite(&text, &table, cx, cy, |r| est.at(time(r)))
        .with_context(|| format!("rewriting {}", args.table.display()))?;
    let csv = trajectory_csv(&est, args.frame_s);
    let png = plot_png(&est, args.frame_s, &unit);

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

/// The input's bytes with x and y of every data row replaced by `x − dx`,
/// `y − dy`; every other byte kept. Rows are found as `CsvTable::read`
/// finds them (the first non-blank line is the header, blank lines skipped).
fn rewrite(
    text: &[u8],
    table: &CsvTable,
    cx: usize,
    cy: usize,
    drift_at: impl Fn(&[f64]) -> (f64, f64),
) -> anyhow::Result<Vec<u8>> {
    let text = std::str::from_utf8(text).context("not UTF-8 text")?;
    let mut out = String::with_capacity(text.len() + text.len() / 8);
    let mut header_seen = false;
    let mut rows = table.rows.iter();
    for line in text.split_inclusive('\n') {
        let content = line.trim_end_matches(['\n', '\r']);
        let ending = &line[content.len()..];
        if content.trim_start_matches('\u{feff}').trim().is_empty() || !header_seen {
            header_seen |= !content.trim_start_matches('\u{feff}').trim().is_empty();
            out.push_str(line);
            continue;
        }
        let r = rows.next().context("more rows than the table read")?;
        let (dx, dy) = drift_at(r);
        let mut fields: Vec<String> = content.split(',').map(str::to_string).collect();
        let keep_space = |old: &str, new: String| {
            // Keep any padding around the number.
            let lead = &old[..old.len() - old.trim_start().len()];
            let trail = &old[old.trim_end().len()..];
            format!("{lead}{new}{trail}")
        };
        fields[cx] = keep_space(&fields[cx], format_decimal(r[cx] - dx, 3));
        fields[cy] = keep_space(&fields[cy], format_decimal(r[cy] - dy, 3));
        out.push_str(&fields.join(","));
        out.push_str(ending);
    }
    if rows.next().is_some() {
        bail!("fewer rows than the table read");
    }
    Ok(out.into_bytes())
}

/// The trajectory as CSV, one row per segment.
fn trajectory_csv(est: &DriftEstimate, frame_s: Option<f64>) -> String {
    let mut s = String::from("segment,t_start,t_end,t_mean,t_mean_s,localisations,dx_nm,dy_nm\n");
    for (k, g) in est.segments.iter().enumerate() {
        let secs = frame_s.map_or(String::new(), |f| format_decimal(g.t_mean * f, 6));
        let _ = writeln!(
            s,
            "{},{},{},{},{secs},{},{},{}",
            k + 1,
            format_decimal(g.t_start, 3),
            format_decimal(g.t_end, 3),
            format_decimal(g.t_mean, 3),
            g.count,
            format_decimal(g.dx_nm, 3),
            format_decimal(g.dy_nm, 3)
        );
    }
    s
}

/// The trajectory drawn as PNG bytes.
fn plot_png(est: &DriftEstimate, frame_s: Option<f64>, unit: &str) -> Result<Vec<u8>, String> {
    let (w, h) = (900u32, 520u32);
    let scale = frame_s.unwrap_or(1.0);
    let x_desc = if frame_s.is_some() {
        "time (s)".to_string()
    } else {
        format!("time ({unit})")
    };
    let pts = |f: fn(&drift::SegmentDrift) -> f64| -> Vec<(f64, f64)> {
        est.segments
            .iter()
            .map(|g| (g.t_mean * scale, f(g)))
            .collect()
    };
    let (xs, ys) = (pts(|g| g.dx_nm), pts(|g| g.dy_nm));
    let t0 = est.segments.first().map_or(0.0, |g| g.t_start * scale);
    let t1 = est
        .segments
        .last()
        .map_or(1.0, |g| g.t_end * scale)
        .max(t0 + 1e-9);
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for &(_, v) in xs.iter().chain(&ys) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let pad = ((hi - lo) * 0.1).max(5.0);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption("Estimated stage drift", ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(t0..t1, (lo - pad)..(hi + pad))
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("drift (nm)")
            .draw()
            .map_err(|e| e.to_string())?;
        for (series, colour, name) in [(&xs, BLUE, "dx"), (&ys, RED, "dy")] {
            chart
                .draw_series(LineSeries::new(
                    series.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            chart
                .draw_series(series.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| e.to_string())?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header().map_err(|e| e.to_string())?;
        wr.write_image_data(&buf).map_err(|e| e.to_string())?;
    }
    Ok(png_bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rewriting_changes_x_and_y_only() {
        let text = "\u{feff}\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"q\"\r\n\r\n1,3,100.5,200,7.125\r\n2,4, 10 ,20,8\n";
        let t = CsvTable::read(text.as_bytes()).unwrap();
        let out = rewrite(text.as_bytes(), &t, 2, 3, |r| (r[1], -1.0)).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "\u{feff}\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"q\"\r\n\r\n1,3,97.5,201,7.125\r\n2,4, 6 ,21,8\n"
        );
    }
}
