//! `smartagg bench frames`: the frame path end to end on a simulated TIFF
//! stack with one spot per frame (issue #37's stack by default: 20 000
//! frames of 9×9 pixels, σ = 1.5 px, 230 photons, 5.9 background photons
//! per pixel, the spot within ±1.5 px of the centre).
//!
//! Writes the stack (`spots.tif`) and its truth (`truth.csv`), then runs
//! `smartagg localize spots.tif --estimator mle` — the command itself, TIFF
//! decoding, detection, ROIs, fits and the CSV included — once per thread
//! count and pass, and prints spots/s (wall clock, median and best over
//! passes), the fraction of the spots found, and the RMSE over the
//! Cramér–Rao bound. Figures are printed, nothing asserted.

use crate::commands::localize;
use anyhow::Context;
use clap::Parser;
use smartagg_localize::stackbench::{score_stack, simulate_stack, StackScenario, StackScore};
use smartagg_localize::table::{CsvTable, Localization};
use smartagg_localize::FitStatus;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `smartagg bench frames`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Frames (one spot each).
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub frames: u64,
    /// Frame width and height, pixels.
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u64).range(1..=4096))]
    pub side: u64,
    /// PSF σ, pixels.
    #[arg(long, default_value_t = 1.5, value_parser = |s: &str| crate::setup::ranged(s, 0.3, 20.0, "px"))]
    pub sigma: f64,
    /// Photons per spot.
    #[arg(long, default_value_t = 230.0, value_parser = |s: &str| crate::setup::ranged(s, 1.0, 1e7, "photons"))]
    pub photons: f64,
    /// Background photons per pixel.
    #[arg(long, default_value_t = 5.9, value_parser = |s: &str| crate::setup::ranged(s, 0.0, 1e6, "photons"))]
    pub background: f64,
    /// Spot position uniform within ± this of the frame centre, pixels.
    #[arg(long, default_value_t = 1.5, value_parser = |s: &str| crate::setup::ranged(s, 0.0, 2048.0, "px"))]
    pub jitter: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Thread counts to run, comma separated (0: the default, all cores).
    #[arg(long, value_delimiter = ',', default_value = "1,0")]
    pub threads: Vec<usize>,
    /// Timed passes per thread count.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub repeats: u64,
    /// Fitting ROI side passed to localize (default: localize's own).
    #[arg(long)]
    pub roi: Option<usize>,
    /// Pixel size, nm (only scales the table).
    #[arg(long, default_value_t = 100.0, value_parser = |s: &str| crate::setup::ranged(s, 0.1, 1e6, "nm"))]
    pub pixel_nm: f64,
    /// Keep spots.tif, truth.csv and the tables in this directory (default:
    /// a temporary directory, removed at the end).
    #[arg(long)]
    pub dir: Option<PathBuf>,
}

/// `smartagg localize` as parsed from its command line.
#[derive(Parser)]
struct LocalizeCli {
    #[command(flatten)]
    args: localize::Args,
}

fn write_truth(
    path: &Path,
    truth: &[smartagg_localize::crlb::Emitter],
    pixel_nm: f64,
) -> anyhow::Result<()> {
    let mut w = std::io::BufWriter::new(smartagg_io::output::AtomicFile::create(path)?);
    writeln!(w, "frame,x_px,y_px,x_nm,y_nm,photons,background,sigma_px")?;
    for (i, e) in truth.iter().enumerate() {
        writeln!(
            w,
            "{},{:.6},{:.6},{:.4},{:.4},{},{},{}",
            i + 1,
            e.x,
            e.y,
            e.x * pixel_nm,
            e.y * pixel_nm,
            e.photons,
            e.background,
            e.sigma
        )?;
    }
    w.into_inner().map_err(|e| e.into_error())?.commit()?;
    Ok(())
}

/// Reads a localize table back as localisations (the columns the score uses).
fn read_table(path: &Path) -> anyhow::Result<Vec<Localization>> {
    let f = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let t = CsvTable::read(std::io::BufReader::new(f))?;
    let col = |name: &str| {
        t.column(&[name])
            .with_context(|| format!("no {name} column"))
    };
    let (cf, cx, cy, cs) = (
        col("frame")?,
        col("x [nm]")?,
        col("y [nm]")?,
        col("fit_status")?,
    );
    Ok(t.rows
        .iter()
        .map(|r| Localization {
            frame: r[cf] as u64,
            x_nm: r[cx],
            y_nm: r[cy],
            sigma_nm: 0.0,
            intensity: 0.0,
            offset: 0.0,
            bkgstd: 0.0,
            uncertainty_nm: 0.0,
            status: FitStatus::from_code(r[cs] as u8).unwrap_or(FitStatus::Singular),
            detections: 1,
            extra: vec![],
        })
        .collect())
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let side = args.side as usize;
    let sc = StackScenario {
        width: side,
        height: side,
        sigma: args.sigma,
        photons: args.photons,
        background: args.background,
        jitter: args.jitter,
        count: args.frames as usize,
        seed: args.seed,
    };
    let tmp;
    let dir = match &args.dir {
        Some(d) => {
            std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
            d.clone()
        }
        None => {
            tmp = tempfile::tempdir().context("creating a temporary directory")?;
            tmp.path().to_path_buf()
        }
    };
    let (pages, truth) = simulate_stack(&sc);
    let stack = dir.join("spots.tif");
    {
        let mut buf = std::io::Cursor::new(Vec::new());
        smartagg_io::stack::write_stack(&mut buf, side, side, &pages)?;
        let mut w = smartagg_io::output::AtomicFile::create(&stack)?;
        w.write_all(buf.get_ref())?;
        w.commit()?;
    }
    write_truth(&dir.join("truth.csv"), &truth, args.pixel_nm)?;
    println!(
        "smartagg bench frames: {} frames of {side}x{side}, sigma {} px, {} photons, {} background/px, spot within ±{} px of the centre (seed {}); {} cores, load average {}",
        sc.count,
        sc.sigma,
        sc.photons,
        sc.background,
        sc.jitter,
        sc.seed,
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        std::fs::read_to_string("/proc/loadavg")
            .ok()
            .and_then(|s| s.split_whitespace().next().map(str::to_string))
            .unwrap_or_else(|| "?".into())
    );
    println!(
        "  {:>7} {:>12} {:>12} {:>8} {:>9} {:>7} {:>9} {:>9} {:>7}",
        "threads",
        "spots/s med",
        "spots/s max",
        "found",
        "spurious",
        "failed",
        "RMSE px",
        "CRLB px",
        "ratio"
    );
    for &threads in &args.threads {
        let out = dir.join(format!("locs-{threads}.csv"));
        let mut rates = Vec::new();
        let mut score: Option<StackScore> = None;
        for _ in 0..args.repeats {
            let _ = std::fs::remove_file(&out);
            let mut cli = vec![
                "localize".to_string(),
                stack.display().to_string(),
                "--out".into(),
                out.display().to_string(),
                "--estimator".into(),
                "mle".into(),
                "--pixel-nm".into(),
                args.pixel_nm.to_string(),
                "--sigma".into(),
                args.sigma.to_string(),
            ];
            if threads > 0 {
                cli.extend(["--threads".into(), threads.to_string()]);
            }
            if let Some(r) = args.roi {
                cli.extend(["--roi".into(), r.to_string()]);
            }
            let parsed = LocalizeCli::try_parse_from(&cli)?;
            let t0 = Instant::now();
            localize::run(parsed.args)?;
            rates.push(sc.count as f64 / t0.elapsed().as_secs_f64().max(1e-12));
            if score.is_none() {
                let rows = read_table(&out)?;
                score = Some(score_stack(&rows, &truth, side, side, args.pixel_nm, 2.0));
            }
        }
        rates.sort_by(|a, b| a.total_cmp(b));
        let s = score.expect("at least one pass");
        println!(
            "  {:>7} {:>12.0} {:>12.0} {:>7.2}% {:>9} {:>7} {:>9.4} {:>9.4} {:>7.3}",
            if threads == 0 {
                format!("{}*", rayon::current_num_threads())
            } else {
                threads.to_string()
            },
            rates[rates.len() / 2],
            rates[rates.len() - 1],
            100.0 * s.recall(),
            s.spurious,
            s.failed,
            s.rmse,
            s.crlb,
            s.ratio()
        );
    }
    println!("  (* the default thread count; spots/s = frames / wall-clock seconds of the whole localize command; found = an ok fit within 2 px; RMSE per axis over the found spots; CRLB of the Poisson model with sigma fitted over the frame)");
    if args.dir.is_some() {
        println!("  stack, truth and tables in {}", dir.display());
    }
    Ok(())
}
