//! `smartagg study`: the paper's simulation study (Fig. 4 and Fig. 8) and
//! beyond, on the scene simulator, the real pipeline and the localisers.
//! The work is in the `smartagg-study` crate; this is the command line.

use anyhow::{bail, Context};
use smartagg_study::sensor::SensorCalibration;
use smartagg_study::spec::LMin;
use smartagg_study::{run, Plan, Shard, StudyName, StudyOptions};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Studies: smart-vs-fixed, future-spad, cameras, objective, hot-pixels, localizers, \
nanoruler, emccd-frames, blink-durations, detection (the experiment of the paper's section 4.1 and \
the detection statistics of section 3; one job each, no shards), \
all (every study into OUT/NAME). `smartagg study merge --out OUT SHARD_DIR...` merges the outputs \
of `--shard I/N` runs (e.g. a Slurm job array) into exactly what one run would have written."
)]
pub struct Args {
    /// Study to run (or `merge`, or `all`).
    pub name: String,
    /// With `merge`: the shard output directories.
    pub dirs: Vec<PathBuf>,
    /// Output directory (CSV, PNG, Markdown summary and raw per-blink results).
    #[arg(long)]
    pub out: PathBuf,
    /// Blinks simulated per point (per configuration).
    #[arg(long, default_value_t = smartagg_study::spec::DEFAULT_BLINKS)]
    pub blinks_per_point: u32,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Fewer points (20, 50, 100 ms; 0, 5, 10, 20 % hot pixels).
    #[arg(long)]
    pub quick: bool,
    /// Run only shard I of N (`I/N`); merge the shards with `smartagg study merge`.
    #[arg(long)]
    pub shard: Option<String>,
    /// Comma-separated x values instead of the defaults (blink ms, or hot-pixel %).
    #[arg(long, value_delimiter = ',')]
    pub points: Option<Vec<f64>>,
    /// Blinks per work item (one continuous recording per configuration).
    #[arg(long, default_value_t = smartagg_study::spec::DEFAULT_BLOCK)]
    pub block: u32,
    /// Bootstrap resamples for the 95 % intervals.
    #[arg(long, default_value_t = smartagg_study::spec::DEFAULT_BOOTSTRAP)]
    pub bootstrap: u32,
    /// Pipeline confirmation length of the smart scheme: planes, or `design`
    /// (the field design's L_min, 1: its open threshold controls the false
    /// blinks).
    #[arg(long, default_value = "design")]
    pub l_min: String,
    /// Pipeline association radius, pixels (default: the model's).
    #[arg(long)]
    pub r_assoc: Option<u32>,
    /// Frame detection threshold, in std of the first wavelet level.
    #[arg(long, default_value_t = 1.5)]
    pub frame_threshold: f64,
    /// Fix the PSF width in every fit instead of fitting it.
    #[arg(long)]
    pub fixed_sigma: bool,
    /// Localisations further than this from the truth are false, nm.
    #[arg(long, default_value_t = smartagg_study::spec::DEFAULT_MATCH_RADIUS_NM)]
    pub match_radius: f64,
    /// Worker threads (default: all cores; more than the cores are capped, with a note).
    #[arg(long, value_parser = crate::setup::thread_count)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// SPAD calibration folder (`smartagg calibrate`): the SPCIMAGER
    /// configurations simulate its measured DCR, hot pixels and PRNU (a crop
    /// per work item) instead of the preset's synthetic maps, and mask its
    /// hot pixels. Not for the hot-pixels study or the experiment studies.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
}

fn options(a: &Args, calibration: Option<&SensorCalibration>) -> anyhow::Result<StudyOptions> {
    Ok(StudyOptions {
        blinks_per_point: a.blinks_per_point,
        seed: a.seed,
        quick: a.quick,
        block: a.block,
        bootstrap: a.bootstrap,
        fit_sigma: !a.fixed_sigma,
        match_radius_nm: a.match_radius,
        points: a.points.clone(),
        l_min: LMin::parse(&a.l_min)?,
        r_assoc: a.r_assoc,
        frame_threshold: a.frame_threshold,
        calibration: calibration.cloned(),
    })
}

fn bar(quiet: bool, label: &str) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(0);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} work items, eta {eta} {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb.set_message(label.to_string());
    pb
}

fn run_one(
    a: &Args,
    study: StudyName,
    out: &std::path::Path,
    calibration: Option<&SensorCalibration>,
) -> anyhow::Result<()> {
    let plan = Plan::new(study, options(a, calibration)?)?;
    let shard = match &a.shard {
        Some(s) => Shard::parse(s)?,
        None => Shard::ALL,
    };
    let pb = bar(a.quiet, study.as_str());
    let t0 = Instant::now();
    let progress = |done: usize, total: usize| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    };
    let w =
        run::run_to_dir(&plan, shard, out, &progress).with_context(|| format!("study {study}"))?;
    pb.finish_and_clear();
    eprintln!(
        "study {study}{}: {} points x {} blinks in {:.1} s wall; wrote {}",
        if shard.count > 1 {
            format!(" shard {shard}")
        } else {
            String::new()
        },
        plan.points.len(),
        plan.options.blinks_per_point,
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    for warn in &w.warnings {
        eprintln!("smartagg: warning: {warn}");
    }
    Ok(())
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(t) = a.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(crate::setup::cap_threads(t))
            .build_global()
            .context("setting up the worker threads")?;
    }
    match a.name.as_str() {
        "merge" => {
            if a.dirs.is_empty() {
                bail!("`smartagg study merge --out OUT DIR...` needs the shard directories");
            }
            let t0 = Instant::now();
            let (plan, w) = run::merge_to_dir(&a.dirs, &a.out)?;
            eprintln!(
                "merged {} shard director{} of study {} in {:.1} s; wrote {}",
                a.dirs.len(),
                if a.dirs.len() == 1 { "y" } else { "ies" },
                plan.study,
                t0.elapsed().as_secs_f64(),
                a.out.display()
            );
            for warn in &w.warnings {
                eprintln!("smartagg: warning: {warn}");
            }
            Ok(())
        }
        "all" => {
            if !a.dirs.is_empty() {
                bail!("unexpected arguments after `all`: {:?}", a.dirs);
            }
            let cal = a
                .calibration
                .as_deref()
                .map(SensorCalibration::load)
                .transpose()?;
            for s in StudyName::ALL {
                if cal.is_some() && s == StudyName::HotPixels {
                    eprintln!(
                        "study hot-pixels skipped: it sweeps synthetic hot-pixel fractions, the calibrated sensor has its own"
                    );
                    continue;
                }
                run_one(&a, s, &a.out.join(s.as_str()), cal.as_ref())?;
            }
            Ok(())
        }
        name if smartagg_study::experiment::Experiment::parse(name).is_some() => {
            if !a.dirs.is_empty() {
                bail!("unexpected arguments after the study name: {:?}", a.dirs);
            }
            if a.shard.is_some() {
                bail!("study {name} runs as one job: --shard is not supported");
            }
            if a.calibration.is_some() {
                bail!("study {name} simulates its own cameras: --calibration applies to smart-vs-fixed, future-spad, cameras, objective and localizers");
            }
            let exp =
                smartagg_study::experiment::Experiment::parse(name).context("experiment study")?;
            let t0 = Instant::now();
            let o = smartagg_study::experiment::ExperimentOptions {
                seed: a.seed,
                quick: a.quick,
                blinks_per_point: (a.blinks_per_point != smartagg_study::spec::DEFAULT_BLINKS)
                    .then_some(a.blinks_per_point),
            };
            let (_, warnings) = smartagg_study::experiment::run(exp, &o, &a.out)
                .with_context(|| format!("study {name}"))?;
            eprintln!(
                "study {name}: {:.1} s wall; wrote {}",
                t0.elapsed().as_secs_f64(),
                a.out.display()
            );
            for w in &warnings {
                eprintln!("smartagg: warning: {w}");
            }
            Ok(())
        }
        name => {
            if !a.dirs.is_empty() {
                bail!(
                    "unexpected arguments after the study name: {:?} (only `merge` takes directories)",
                    a.dirs
                );
            }
            let cal = a
                .calibration
                .as_deref()
                .map(SensorCalibration::load)
                .transpose()?;
            run_one(&a, StudyName::parse(name)?, &a.out, cal.as_ref())
        }
    }
}
