//! `smartagg bench aggregate`: golden and fast engines side by side on the
//! same simulated bit-planes, at typical SMLM density and a dense worst case.
//! Prints planes/s and Mpixel/s (wall clock) and planes per CPU-second (the
//! rate one free core would give: the machine may be shared), checks that the
//! bytes are identical, and gives the 1- vs T-thread speed-up. With
//! `--stream` it streams `--planes` planes through the fast engine and prints
//! the resident memory as it goes, to show that it stays flat.

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

/// Planes per time chunk of the parallel engine (as `smartagg aggregate`).
const CHUNK: usize = 512;

/// Arguments of `smartagg bench aggregate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Planes per measurement of the fast engine (with `--stream`: planes streamed).
    #[arg(long, default_value_t = 3000)]
    pub planes: u64,
    /// Planes for the (slow) golden engine.
    #[arg(long, default_value_t = 300)]
    pub golden_planes: usize,
    /// Worker threads of the multi-threaded run, 1..=1024 (default: all cores; more than the cores oversubscribe them, as asked).
    #[arg(long, value_parser = crate::setup::thread_count)]
    pub threads: Option<usize>,
    /// Field width (default: the sensor).
    #[arg(long)]
    pub width: Option<u32>,
    /// Field height (default: the sensor).
    #[arg(long)]
    pub height: Option<u32>,
    /// Random seed of the simulated scene.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Instead: stream `--planes` planes through the fast engine (`--threads`
    /// workers) and print the resident memory at intervals. The planes are a
    /// pool of simulated planes replayed cyclically, so the generator costs
    /// only a copy per plane and holds a fixed amount of memory.
    #[arg(long)]
    pub stream: bool,
    /// Planes simulated for the `--stream` pool.
    #[arg(long, default_value_t = 1024)]
    pub pool: usize,
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
        CHUNK,
        |r| out.push(r),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out)
}

/// A `/proc/self/status` field in MiB (VmRSS: resident now, VmHWM: peak).
fn status_mib(field: &str) -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// CPU seconds used by the whole process so far, all threads (user + system),
/// from `/proc/self/stat` in clock ticks of 1/100 s; `None` off Linux.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// The 1-minute load average, to judge how shared the machine was.
fn load_average() -> Option<String> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

/// Wall and CPU time of one measurement.
struct Timing {
    wall: Instant,
    cpu: Option<f64>,
}

impl Timing {
    fn start() -> Timing {
        Timing {
            wall: Instant::now(),
            cpu: cpu_seconds(),
        }
    }

    /// (planes per wall second, planes per CPU-second).
    fn rates(&self, planes: usize) -> (f64, Option<f64>) {
        let wall = planes as f64 / self.wall.elapsed().as_secs_f64().max(1e-9);
        let cpu = match (self.cpu, cpu_seconds()) {
            (Some(a), Some(b)) if b > a => Some(planes as f64 / (b - a)),
            _ => None,
        };
        (wall, cpu)
    }
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
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = args.threads.unwrap_or(cores).max(1);
    println!(
        "load average at start: {} ({cores} cores)",
        load_average().unwrap_or_else(|| "unknown".into())
    );
    let typical = Scene::smlm(&preset).with_field(w, h);
    if args.stream {
        return stream(&preset, &typical, &cfg, &args, threads);
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
    let planes_n = usize::try_from(args.planes)?.max(args.golden_planes).max(1);
    println!(
        "{:<8} {:<20} {:>7} {:>10} {:>9} {:>11} {:>8} {:>8}",
        "scene", "engine", "planes", "planes/s", "Mpixel/s", "planes/CPUs", "vs gold", "bytes"
    );
    let mpix = |rate: f64| rate * (w as f64 * h as f64) / 1e6;
    for (name, scene) in [("typical", &typical), ("dense", &dense)] {
        let planes = simulate(&preset, scene, planes_n, args.seed)?;
        let on = scene.expected_on(&preset.camera).unwrap_or(0.0);
        let gp = &planes[..args.golden_planes.min(planes.len())];
        let t = Timing::start();
        let golden = run_with(Pipeline::new(cfg.clone())?, gp.iter().cloned())?;
        let (golden_rate, golden_cpu) = t.rates(gp.len());
        let golden_bytes = bytes_of(&golden)?;
        let row = |engine: &str, n: usize, (rate, cpu): (f64, Option<f64>), bytes: usize| {
            println!(
                "{:<8} {:<20} {:>7} {:>10.0} {:>9.1} {:>11} {:>7.1}x {:>8}",
                name,
                engine,
                n,
                rate,
                mpix(rate),
                cpu.map_or("-".into(), |c| format!("{c:.0}")),
                rate / golden_rate,
                bytes
            );
        };
        row(
            "golden",
            gp.len(),
            (golden_rate, golden_cpu),
            golden_bytes.len(),
        );
        // The fast engines on the golden planes: bytes must be identical.
        let fast_same = run_with(fast_pipeline(cfg.clone())?, gp.iter().cloned())?;
        let par_same = parallel(&cfg, gp, threads.max(2))?;
        if bytes_of(&fast_same)? != golden_bytes || bytes_of(&par_same)? != golden_bytes {
            anyhow::bail!(
                "the fast engine's bytes differ from the golden model's on the {name} scene"
            );
        }
        // Stages 1–4 alone, to show where the time goes (and what AVX2 adds).
        let zero = BitPlane::zeros(w as usize, h as usize);
        let n = cfg.n_window as usize;
        let simd = FastFrontEnd::new(&cfg).uses_avx2();
        for (label, portable) in [("stages 1-4", false), ("stages 1-4 portable", true)] {
            if portable && !simd {
                continue;
            }
            let t = Timing::start();
            let mut fe = FastFrontEnd::new(&cfg);
            if portable {
                fe = fe.portable();
            }
            for (i, p) in planes.iter().enumerate() {
                fe.push(p, if i >= n { &planes[i - n] } else { &zero });
            }
            let rates = t.rates(planes.len());
            let label = if simd && !portable {
                format!("{label} avx2")
            } else {
                label.to_string()
            };
            row(&label, planes.len(), rates, 0);
            if !portable {
                println!(
                    "{:<8} {} of {} planes filtered densely (more than 1/8 of the pixels changed)",
                    "",
                    fe.dense_planes(),
                    planes.len()
                );
            }
        }
        let t = Timing::start();
        let fast = run_with(fast_pipeline(cfg.clone())?, planes.iter().cloned())?;
        let single = t.rates(planes.len());
        row(
            "fast, 1 thread",
            planes.len(),
            single,
            bytes_of(&fast)?.len(),
        );
        // Chunked runs: x1 overlaps one worker with the reader and the
        // sequential back end; xT adds workers.
        let mut chunked = vec![(0, single.0)];
        for th in [1, threads]
            .into_iter()
            .collect::<std::collections::BTreeSet<_>>()
        {
            let t = Timing::start();
            let par = parallel(&cfg, &planes, th)?;
            let rates = t.rates(planes.len());
            if par != fast {
                anyhow::bail!("parallel run ({th} threads) differs from the single-threaded one");
            }
            row(
                &format!("fast, chunked x{th}"),
                planes.len(),
                rates,
                bytes_of(&par)?.len(),
            );
            chunked.push((th, rates.0));
        }
        if let Some(&(tn, many)) = chunked.last() {
            println!(
                "{:<8} speed-up, chunked x{tn} over the single-threaded fast engine (wall, same run): {:.2}x",
                "",
                many / single.0
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
            "{:<8} about {:.1} molecules on at a time; {} blinks; unconfirmed {}, dropped candidates {}; golden bytes identical: yes",
            "",
            on,
            blinks,
            end.as_ref().map_or(0, |e| e.unconfirmed),
            end.as_ref().map_or(0, |e| e.dropped_candidates)
        );
    }
    println!(
        "(real time for the SPCImager: 10,000 planes/s; planes/CPUs = planes per CPU-second of all threads; load average now {})",
        load_average().unwrap_or_else(|| "unknown".into())
    );
    Ok(())
}

fn stream(
    preset: &Preset,
    scene: &Scene,
    cfg: &PipelineConfig,
    args: &Args,
    threads: usize,
) -> anyhow::Result<()> {
    let planes = args.planes;
    let pool_len = args.pool.max(1);
    let t = Timing::start();
    let pool = simulate(preset, scene, pool_len, args.seed)?;
    println!(
        "pool of {pool_len} simulated planes in {:.1} s; streaming {planes} planes through the fast engine on {threads} threads (chunks of {CHUNK})",
        t.wall.elapsed().as_secs_f64()
    );
    let t = Timing::start();
    let report_every = (planes / 10).max(1);
    let mut done = 0u64;
    let mut records = 0u64;
    let mut bytes = 0usize;
    let mut packetiser = Packetiser::new();
    let mut buf = Vec::new();
    println!(
        "{:>10} {:>8} {:>10} {:>11} {:>8} {:>8}",
        "planes", "seconds", "planes/s", "planes/CPUs", "RSS MiB", "HWM MiB"
    );
    let mib = |f: &str| status_mib(f).map_or("-".into(), |v| format!("{v:.1}"));
    let src = std::iter::from_fn(|| {
        if done == planes {
            return None;
        }
        let plane = pool[(done % pool_len as u64) as usize].clone();
        done += 1;
        if done.is_multiple_of(report_every) {
            let (rate, cpu) = t.rates(done as usize);
            println!(
                "{:>10} {:>8.1} {:>10.0} {:>11} {:>8} {:>8}",
                done,
                t.wall.elapsed().as_secs_f64(),
                rate,
                cpu.map_or("-".into(), |c| format!("{c:.0}")),
                mib("VmRSS:"),
                mib("VmHWM:")
            );
        }
        Some(Ok::<_, std::convert::Infallible>(plane))
    });
    run_parallel(cfg.clone(), src, threads, CHUNK, |r| {
        records += 1;
        buf.clear();
        if packetiser.push(&r, &mut buf).is_ok() {
            bytes += buf.len();
        }
    })
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    println!(
        "{records} records, {bytes} bytes of packets; planes counted when read, so the rate includes the replay copy; load average now {}",
        load_average().unwrap_or_else(|| "unknown".into())
    );
    Ok(())
}
