//! `smartagg bench drift`: drift correction measured on a simulated nanoruler
//! acquisition (figures printed, nothing asserted).
//!
//! GATTA-PAINT 80G nanorulers seen by the SPCImager at 150× on a small field
//! are simulated twice with the same seed — without drift (the reference)
//! and with a smooth random stage drift of `--drift-nm` — aggregated by the
//! fast engine and localised (SPAD binomial MLE). Each localisation is
//! matched to the true blink it came from (overlapping in time, nearest to
//! where the blink was imaged, within 60 nm), which gives its emitter and
//! the true drift it was imaged with. The drifted table is then corrected by
//! RCC and by fiducials (the markers themselves keep blinking, so each is a
//! fiducial), and for each table the command prints:
//!
//! * residual drift RMS: `corr(t) − d_true` over the matched localisations,
//!   the mean removed (a correction is relative to the first segment), nm;
//!   uncorrected, that is the spread of the true drift itself;
//! * the median spread of a marker's localisations (RMS per axis about their
//!   mean) over markers with at least 5;
//! * the spacing of neighbouring markers of a ruler (true 80 nm): mean and
//!   standard deviation over the ruler pairs.

use anyhow::Context;
use rayon::prelude::*;
use smartagg_localize::drift::{self, DriftEstimate, DriftOptions, DriftPoint};
use smartagg_localize::{fit_binomial, FitOptions, SigmaMode, SpadRoi};
use smartagg_model::fast_engine::{default_chunk, run_parallel};
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::record::{BlinkRecord, Record};
use smartagg_model::record_check::summed_planes_by;
use smartagg_scene::{Blinking, DriftTrajectory, Layout, OnTime, Scene, SpadSimulator};
use std::time::Instant;

use crate::setup::{self, PipelineArgs};

/// Arguments of `smartagg bench drift`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Simulated acquisition, s (10,000 bit-planes per second).
    #[arg(long, default_value_t = 600.0)]
    pub seconds: f64,
    /// Field side, pixels (53.3 nm at 150x; the demo's field).
    #[arg(long, default_value_t = 48)]
    pub field: u32,
    /// Rulers per µm².
    #[arg(long, default_value_t = 2.0)]
    pub density: f64,
    /// Mean off-time of a marker, s.
    #[arg(long, default_value_t = 3.0)]
    pub mean_off_s: f64,
    /// Largest drift from the start over the acquisition, nm (smooth random trajectory).
    #[arg(long, default_value_t = 100.0)]
    pub drift_nm: f64,
    /// Time segments of the correction.
    #[arg(long, default_value_t = 10)]
    pub segments: usize,
    /// Random seed of the scene, the drift and the photons.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads of the aggregation (default: all cores).
    #[arg(long, value_parser = setup::thread_count)]
    pub threads: Option<usize>,
}

/// Localisations further than this from where the blink was imaged are false.
const MATCH_NM: f64 = 60.0;
/// Fewest localisations of a marker for its spread and position.
const MIN_PER_MARKER: usize = 5;
/// Markers per ruler (GATTA-PAINT 80G).
const MARKERS: usize = 3;

/// One matched localisation.
#[derive(Debug, Clone, Copy)]
struct Loc {
    /// Middle of the summed planes, in planes.
    t: f64,
    x: f64,
    y: f64,
    emitter: usize,
    /// The true drift the blink was imaged with, nm.
    drift: (f64, f64),
}

/// One simulated, aggregated and localised acquisition.
struct Run {
    locs: Vec<Loc>,
    /// Every successful localisation (matched or not), for the correction.
    points: Vec<DriftPoint>,
    emitters: usize,
    planes: u64,
    seconds: f64,
}

fn simulate(args: &Args, drift: Option<&DriftTrajectory>) -> anyhow::Result<Run> {
    let preset = Preset::new(PresetName::Spcimager, 150)?;
    let Camera::Spad(cam) = &preset.camera else {
        unreachable!("the SPCImager preset is a SPAD camera")
    };
    let scene = Scene {
        layout: Layout::gatta_paint_80g(args.density),
        blinking: Blinking::Independent {
            on: OnTime::Exponential { mean_s: 0.030 },
            mean_off_s: args.mean_off_s,
        },
        ..Scene::nanorulers(&preset).with_field(args.field, args.field)
    };
    let planes = (args.seconds / cam.plane_period_s).round() as u64;
    let cfg = setup::pipeline_config(&PipelineArgs::default(), args.field, args.field, 100_000)?;
    let mut sim = SpadSimulator::new(cam, &scene, args.seed)?;
    if let Some(d) = drift {
        sim.set_drift(d.clone());
    }
    let t = Instant::now();
    let threads = args.threads.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        setup::cap_threads,
    );
    let mut records: Vec<BlinkRecord> = Vec::new();
    {
        let sim = &mut sim;
        let source = (0..planes).map(|_| Ok::<_, std::convert::Infallible>(sim.next_plane()));
        run_parallel(
            cfg.clone(),
            source,
            threads,
            default_chunk(cfg.n_window),
            |r| {
                if let Record::Blink(b) = r {
                    records.push(b);
                }
            },
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let seconds = t.elapsed().as_secs_f64();
    let opts = FitOptions::new(SigmaMode::Fitted {
        initial: preset.sigma_px(),
    });
    let pixel_nm = preset.pixel_nm();
    let fits: Vec<Option<(f64, f64, std::ops::Range<u64>)>> = records
        .par_iter()
        .map(|rec| {
            let roi = SpadRoi::from_record(rec, None).ok()?;
            let fit = fit_binomial(&roi, &opts);
            let (x, y) = (
                (rec.roi_x0() as f64 + fit.x) * pixel_nm,
                (rec.roi_y0() as f64 + fit.y) * pixel_nm,
            );
            (fit.status.is_ok() && x.is_finite() && y.is_finite()).then(|| {
                (
                    x,
                    y,
                    summed_planes_by(rec, cfg.n_window, Some(cfg.end_trim)),
                )
            })
        })
        .collect();
    let truth = sim.truth();
    let period = cam.plane_period_s;
    let mut locs = Vec::new();
    let mut points = Vec::new();
    for (x, y, planes_summed) in fits.into_iter().flatten() {
        let t = 0.5 * (planes_summed.start + planes_summed.end) as f64;
        points.push(DriftPoint {
            t,
            x_nm: x,
            y_nm: y,
        });
        let (t0, t1) = (
            planes_summed.start as f64 * period,
            planes_summed.end as f64 * period,
        );
        let best = truth
            .iter()
            .filter(|b| b.t_on_s < t1 && b.t_off_s > t0)
            .map(|b| {
                let (ix, iy) = b.imaged_nm();
                (b, (ix - x).hypot(iy - y))
            })
            .filter(|&(_, d)| d <= MATCH_NM)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((b, _)) = best {
            locs.push(Loc {
                t,
                x,
                y,
                emitter: b.emitter as usize,
                drift: (b.drift_x_nm, b.drift_y_nm),
            });
        }
    }
    Ok(Run {
        locs,
        points,
        emitters: sim.emitters().len(),
        planes,
        seconds,
    })
}

/// The figures of one table under one correction.
struct Figures {
    drift_rms_nm: f64,
    marker_spread_nm: f64,
    markers: usize,
    spacing_mean_nm: f64,
    spacing_sd_nm: f64,
    spacings: usize,
}

fn figures(run: &Run, corr: &dyn Fn(f64) -> (f64, f64)) -> Figures {
    let n = run.locs.len().max(1) as f64;
    let res: Vec<(f64, f64)> = run
        .locs
        .iter()
        .map(|l| {
            let c = corr(l.t);
            (c.0 - l.drift.0, c.1 - l.drift.1)
        })
        .collect();
    let (mx, my) = res
        .iter()
        .fold((0.0, 0.0), |a, r| (a.0 + r.0 / n, a.1 + r.1 / n));
    let drift_rms_nm = (res
        .iter()
        .map(|r| (r.0 - mx).powi(2) + (r.1 - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let mut per: Vec<Vec<(f64, f64)>> = vec![Vec::new(); run.emitters];
    for l in &run.locs {
        let c = corr(l.t);
        if let Some(v) = per.get_mut(l.emitter) {
            v.push((l.x - c.0, l.y - c.1));
        }
    }
    let stats: Vec<Option<((f64, f64), f64)>> = per
        .iter()
        .map(|pts| {
            (pts.len() >= MIN_PER_MARKER).then(|| {
                let k = pts.len() as f64;
                let m = pts
                    .iter()
                    .fold((0.0, 0.0), |a, p| (a.0 + p.0 / k, a.1 + p.1 / k));
                let s = (pts
                    .iter()
                    .map(|p| (p.0 - m.0).powi(2) + (p.1 - m.1).powi(2))
                    .sum::<f64>()
                    / (2.0 * k))
                    .sqrt();
                (m, s)
            })
        })
        .collect();
    let mut spreads: Vec<f64> = stats.iter().flatten().map(|s| s.1).collect();
    spreads.sort_by(f64::total_cmp);
    let mut spacings = Vec::new();
    for ruler in stats.chunks(MARKERS) {
        for w in ruler.windows(2) {
            if let (Some(a), Some(b)) = (w[0], w[1]) {
                spacings.push((a.0 .0 - b.0 .0).hypot(a.0 .1 - b.0 .1));
            }
        }
    }
    let k = spacings.len().max(1) as f64;
    let mean = spacings.iter().sum::<f64>() / k;
    let sd = (spacings.iter().map(|s| (s - mean).powi(2)).sum::<f64>()
        / (spacings.len().max(2) - 1) as f64)
        .sqrt();
    Figures {
        drift_rms_nm,
        marker_spread_nm: spreads.get(spreads.len() / 2).copied().unwrap_or(f64::NAN),
        markers: spreads.len(),
        spacing_mean_nm: mean,
        spacing_sd_nm: sd,
        spacings: spacings.len(),
    }
}

fn at(e: &DriftEstimate) -> impl Fn(f64) -> (f64, f64) + '_ {
    move |t| e.at(t)
}

/// A figure to one decimal, or "–" where there was nothing to measure.
fn nm(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.1} nm")
    } else {
        "–".into()
    }
}

fn row(name: &str, f: &Figures) -> String {
    let (mean, sd) = if f.spacings > 0 {
        (nm(f.spacing_mean_nm), nm(f.spacing_sd_nm))
    } else {
        ("–".into(), "–".into())
    };
    format!(
        "| {name} | {} | {} ({} markers) | {mean} ± {sd} ({} pairs) |",
        nm(f.drift_rms_nm),
        nm(f.marker_spread_nm),
        f.markers,
        f.spacings
    )
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.seconds.is_finite() && (1.0..=36_000.0).contains(&args.seconds),
        "--seconds must be 1 ..= 36000"
    );
    anyhow::ensure!(
        (8..=320).contains(&args.field),
        "--field must be 8 ..= 320 pixels"
    );
    let trajectory = DriftTrajectory::random(args.drift_nm, args.seconds, args.seed)
        .map_err(|e| anyhow::anyhow!("--drift-nm: {e}"))?;
    let opts = DriftOptions {
        segments: args.segments,
        ..DriftOptions::default()
    };
    opts.validate().context("--segments")?;
    eprintln!(
        "smartagg bench drift: nanorulers ({} per µm²), SPCImager 150x, {}x{} pixels, {} s, drift {} nm, seed {}",
        args.density, args.field, args.field, args.seconds, args.drift_nm, args.seed
    );
    let still = simulate(&args, None)?;
    eprintln!(
        "  no drift: {} planes simulated and aggregated in {:.1} s ({:.0} planes/s), {} localisations, {} matched",
        still.planes,
        still.seconds,
        still.planes as f64 / still.seconds.max(1e-9),
        still.points.len(),
        still.locs.len()
    );
    let moved = simulate(&args, Some(&trajectory))?;
    eprintln!(
        "  drift: {} planes in {:.1} s, {} localisations, {} matched",
        moved.planes,
        moved.seconds,
        moved.points.len(),
        moved.locs.len()
    );
    let t = Instant::now();
    let rcc = drift::rcc(&moved.points, &opts).context("RCC")?;
    let rcc_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let fid = drift::fiducials(&moved.points, &opts);
    let fid_s = t.elapsed().as_secs_f64();
    let zero = |_: f64| (0.0, 0.0);
    println!(
        "| table | residual drift RMS | median marker spread | neighbour spacing (true 80 nm) |"
    );
    println!("|---|---|---|---|");
    println!("{}", row("no drift (reference)", &figures(&still, &zero)));
    println!(
        "{}",
        row(
            &format!("{} nm drift, uncorrected", args.drift_nm),
            &figures(&moved, &zero)
        )
    );
    println!(
        "{}",
        row(
            &format!("RCC, {} segments", rcc.segments.len()),
            &figures(&moved, &at(&rcc))
        )
    );
    match &fid {
        Ok(f) => println!(
            "{}",
            row(
                &format!("fiducials, {} segments", f.segments.len()),
                &figures(&moved, &at(f))
            )
        ),
        Err(e) => println!("| fiducials | {e} | | |"),
    }
    println!(
        "\nRCC: {} of {} pairs kept, residual {:.2} nm, bins {:.1} nm, {:.2} s. Fiducials: {}, {:.2} s.",
        rcc.used,
        rcc.total,
        rcc.residual_rms_nm,
        rcc.bin_nm,
        rcc_s,
        match &fid {
            Ok(f) => format!("{} of {} spots followed", f.used, f.total),
            Err(_) => "none".into(),
        },
        fid_s
    );
    Ok(())
}
