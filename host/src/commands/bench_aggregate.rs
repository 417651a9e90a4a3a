//! `smartagg bench aggregate`: golden and fast engines side by side on the
//! same simulated bit-planes, at typical SMLM density and a dense worst case.
//! Prints planes/s and Mpixel/s, checks the bytes are identical, and (with
//! `--stream`) shows that memory stays flat over a long streamed run.

use crate::setup::{self, PipelineArgs};
use smartagg_model::config::PipelineConfig;
use smartagg_model::fast_engine::{fast_pipeline, run_parallel, FastFrontEnd};
use smartagg_model::packetiser::Packetiser;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::pipeline::FrontEnd;
use smartagg_model::pipeline::{run_with, Pipeline};
use smartagg_model::plane::BitPlane;
use smartagg_model::record::Record;
use smartagg_scene::scene::{Blinking, Layout, OnTime, Scene};
use smartagg_scene::spad::SpadSimulator;
use std::time::Instant;

/// Arguments of `smartagg bench aggregate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Planes per measurement (the golden engine runs on at most `--golden-planes`).
    #[arg(long, default_value_t = 3000)]
    pub planes: usize,
    /// Planes for the (slow) golden engine.
    #[arg(long, default_value_t = 300)]
    pub golden_planes: usize,
    /// Field width (default: the sensor).
    #[arg(long)]
    pub width: Option<u32>,
    /// Field height (default: the sensor).
    #[arg(long)]
    pub height: Option<u32>,
    /// Random seed of the simulated scene.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Instead: stream this many planes from the simulator through the fast
    /// engine (2 threads) and print the resident memory as it goes.
    #[arg(long)]
    pub stream: Option<u64>,
}

fn simulate(
    preset: &Preset,
    scene: &Scene,
    planes: usize,
    seed: u64,
) -> anyhow::Result<Vec<BitPlane>> {
    let Camera::Spad(cam) = &preset.camera else {
        anyhow::bail!("bench aggregate needs a bit-plane (SPAD) preset");
    };
    let mut sim = SpadSimulator::new(cam, scene, seed)?;
    Ok((0..planes).map(|_| sim.next_plane()).collect())
}

fn bytes_of(records: &[Record]) -> anyhow::Result<Vec<u8>> {
    Ok(smartagg_model::packetiser::encode_stream(records)?)
}

fn parallel(
    cfg: &PipelineConfig,
    planes: &[BitPlane],
    threads: usize,
) -> anyhow::Result<Vec<Record>> {
    let mut out = Vec::new();
    run_parallel::<std::convert::Infallible, _, _>(
        cfg.clone(),
        planes.iter().cloned().map(Ok),
        threads,
        1024,
        |r| out.push(r),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out)
}

fn rss_mib() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Runs the benchmark.
pub fn run(args: Args) -> anyhow::Result<()> {
    let preset = Preset::new(
        PresetName::parse(&args.pipeline.preset)?,
        args.pipeline.objective,
    )?;
    let (sw, sh) = preset.camera.size();
    let (w, h) = (args.width.unwrap_or(sw), args.height.unwrap_or(sh));
    let cfg = setup::pipeline_config(&args.pipeline, w, h, 100_000)?;
    println!("{}", setup::describe(&cfg));
    let typical = Scene::smlm(&preset).with_field(w, h);
    if let Some(n) = args.stream {
        return stream(&preset, &typical, &cfg, n, args.seed);
    }
    let dense = Scene {
        layout: Layout::Random {
            density_per_um2: 500.0,
        },
        blinking: Blinking::Independent {
            on: OnTime::Exponential { mean_s: 0.030 },
            mean_off_s: 3.0,
        },
        ..typical.clone()
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "{:<10} {:<22} {:>8} {:>12} {:>11} {:>8} {:>10}",
        "scene", "engine", "planes", "planes/s", "Mpixel/s", "vs gold", "bytes"
    );
    for (name, scene) in [("typical", &typical), ("dense", &dense)] {
        let planes = simulate(
            &preset,
            scene,
            args.planes.max(args.golden_planes),
            args.seed,
        )?;
        let on = scene.expected_on(&preset.camera).unwrap_or(0.0);
        let gp = &planes[..args.golden_planes.min(planes.len())];
        let t = Instant::now();
        let golden = run_with(Pipeline::new(cfg.clone())?, gp.iter().cloned())?;
        let golden_rate = gp.len() as f64 / t.elapsed().as_secs_f64();
        let golden_bytes = bytes_of(&golden)?;
        let row = |engine: &str, n: usize, rate: f64, bytes: usize| {
            println!(
                "{:<10} {:<22} {:>8} {:>12.0} {:>11.1} {:>7.1}x {:>10}",
                name,
                engine,
                n,
                rate,
                rate * (w as f64 * h as f64) / 1e6,
                rate / golden_rate,
                bytes
            );
        };
        row("golden", gp.len(), golden_rate, golden_bytes.len());
        // The fast engines on the golden planes: bytes must be identical.
        let fast_same = run_with(fast_pipeline(cfg.clone())?, gp.iter().cloned())?;
        let par_same = parallel(&cfg, gp, cores)?;
        if bytes_of(&fast_same)? != golden_bytes || bytes_of(&par_same)? != golden_bytes {
            anyhow::bail!(
                "the fast engine's bytes differ from the golden model's on the {name} scene"
            );
        }
        // Stages 1–4 alone, to show where the time goes.
        let t = Instant::now();
        let mut fe = FastFrontEnd::new(&cfg);
        let zero = BitPlane::zeros(w as usize, h as usize);
        let n = cfg.n_window as usize;
        for (i, p) in planes.iter().enumerate() {
            fe.push(p, if i >= n { &planes[i - n] } else { &zero });
        }
        row(
            "stages 1-4 only",
            planes.len(),
            planes.len() as f64 / t.elapsed().as_secs_f64(),
            0,
        );
        let t = Instant::now();
        let fast = run_with(fast_pipeline(cfg.clone())?, planes.iter().cloned())?;
        row(
            "fast, 1 thread",
            planes.len(),
            planes.len() as f64 / t.elapsed().as_secs_f64(),
            bytes_of(&fast)?.len(),
        );
        for threads in [1, 2, cores]
            .into_iter()
            .collect::<std::collections::BTreeSet<_>>()
        {
            let t = Instant::now();
            let par = parallel(&cfg, &planes, threads)?;
            let rate = planes.len() as f64 / t.elapsed().as_secs_f64();
            if par != fast {
                anyhow::bail!(
                    "parallel run ({threads} threads) differs from the single-threaded one"
                );
            }
            row(
                &format!("fast, chunked x{threads}"),
                planes.len(),
                rate,
                bytes_of(&par)?.len(),
            );
        }
        let blinks = fast
            .iter()
            .filter(|r| matches!(r, Record::Blink(_)))
            .count();
        let end = fast.iter().rev().find_map(|r| match r {
            Record::End(e) => Some(e.clone()),
            _ => None,
        });
        println!(
            "{:<10} about {:.1} molecules on at a time; {} blinks, {:?}; golden bytes identical: yes",
            "", on, blinks, end.map(|e| (e.unconfirmed, e.dropped_candidates))
        );
    }
    println!("(real time for the SPCImager: 10,000 planes/s; {cores} cores available)");
    Ok(())
}

fn stream(
    preset: &Preset,
    scene: &Scene,
    cfg: &PipelineConfig,
    planes: u64,
    seed: u64,
) -> anyhow::Result<()> {
    let Camera::Spad(cam) = &preset.camera else {
        anyhow::bail!("bench aggregate needs a bit-plane (SPAD) preset");
    };
    let mut sim = SpadSimulator::new(cam, scene, seed)?;
    let t = Instant::now();
    let report_every = (planes / 10).max(1);
    let mut done = 0u64;
    let mut records = 0u64;
    let mut bytes = 0usize;
    let mut packetiser = Packetiser::new();
    let mut buf = Vec::new();
    println!(
        "{:>12} {:>10} {:>12} {:>10}",
        "planes", "seconds", "planes/s", "RSS MiB"
    );
    let src = std::iter::from_fn(|| {
        if done == planes {
            return None;
        }
        done += 1;
        if done.is_multiple_of(report_every) {
            let s = t.elapsed().as_secs_f64();
            println!(
                "{:>12} {:>10.1} {:>12.0} {:>10.1}",
                done,
                s,
                done as f64 / s,
                rss_mib().unwrap_or(f64::NAN)
            );
        }
        Some(Ok::<_, std::convert::Infallible>(sim.next_plane()))
    });
    run_parallel(cfg.clone(), src, 2, 1024, |r| {
        records += 1;
        buf.clear();
        if packetiser.push(&r, &mut buf).is_ok() {
            bytes += buf.len();
        }
    })
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    println!("{records} records, {bytes} bytes; simulation and aggregation together (simulator included in the rate)");
    Ok(())
}
