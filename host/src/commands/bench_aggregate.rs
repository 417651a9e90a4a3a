//! `smartagg bench aggregate`: golden and fast engines side by side on the
//! same simulated bit-planes, at typical SMLM density and a dense worst case.
//! Prints planes/s and Gpixel/s (wall clock) and planes per CPU-second (the
//! rate one free core would give: the machine may be shared), checks that the
//! bytes are identical, times stages 1–4 and 5–7 alone, and runs the chunked
//! engine's scaling curve (1, 2, 4, … threads) with the speed-up over one
//! thread; then the same for the SPAD512S class camera. With
//! `--stream` it streams `--planes` planes through the fast engine and prints
//! the resident memory as it goes, to show that it stays flat.

use crate::setup::{self, PipelineArgs};
use smartagg_model::config::PipelineConfig;
use smartagg_model::fast_engine::{
    default_chunk, fast_pipeline, run_parallel, sum_parts, FastFrontEnd, FrontResults, Isa,
    READER_THREAD, SUMS_THREAD, TRACKER_THREAD, WORKER_THREAD,
};
use smartagg_model::packetiser::Packetiser;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::pipeline::FrontEnd;
use smartagg_model::pipeline::{run_with, Pipeline};
use smartagg_model::plane::BitPlane;
use smartagg_model::record::Record;
use smartagg_scene::scene::{Blinking, Layout, OnTime, Scene};
use smartagg_scene::spad::SpadSimulator;
use std::collections::BTreeMap;
use std::time::Instant;

/// Arguments of `smartagg bench aggregate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Planes per measurement of the fast engine (with `--stream`: planes streamed), ≥ 1.
    #[arg(long, default_value_t = 3000, value_parser = clap::value_parser!(u64).range(1..))]
    pub planes: u64,
    /// Planes for the (slow) golden engine, ≥ 1 (its rate is every other engine's reference).
    #[arg(long, default_value_t = 300, value_parser = clap::value_parser!(u32).range(1..))]
    pub golden_planes: u32,
    /// Most worker threads: the scaling curve runs 1, 2, 4, … up to this, 1..=1024 (default: all cores; more than the cores oversubscribe them, as asked). With `--stream`: the workers.
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
    /// pool of simulated planes replayed cyclically and lent, so the
    /// generator costs a copy per plane in the workers and holds a fixed
    /// amount of memory.
    #[arg(long)]
    pub stream: bool,
    /// Planes simulated for the `--stream` pool, ≥ 1.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    pub pool: u32,
    /// Scenes to measure, comma-separated (default: all three). With
    /// `--stream`: the first of `typical` and `dense` given.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "typical,dense,spad512s"
    )]
    pub scene: Vec<BenchScene>,
}

/// A scene of `smartagg bench aggregate`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchScene {
    /// The preset's field at typical SMLM density.
    Typical,
    /// The preset's field at 500 molecules/µm², 30 ms blinks: a worst case.
    Dense,
    /// The SPAD512S class camera's whole field at typical SMLM density
    /// (skipped when the preset is the SPAD512S: `typical` is that).
    Spad512s,
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

/// The chunked engine on `len` planes: `planes` over and over, lent (the
/// worker that takes a chunk copies its planes; a decoder's planes, given
/// away, are copied by the reader: `smartagg_model::fast_engine::SourcePlane`).
fn parallel(
    cfg: &PipelineConfig,
    planes: &[BitPlane],
    len: usize,
    threads: usize,
) -> anyhow::Result<Vec<Record>> {
    let mut out = Vec::new();
    run_parallel::<std::convert::Infallible, _, _, _>(
        cfg.clone(),
        planes.iter().cycle().take(len).map(Ok),
        threads,
        default_chunk(cfg.n_window),
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
    Some(stat_ticks(&s)? as f64 / 100.0)
}

/// User + system clock ticks (1/100 s, the kernel's USER_HZ) of a process's
/// or thread's `stat` line.
fn stat_ticks(stat: &str) -> Option<u64> {
    // Fields after the command name, which is in parentheses and may hold spaces.
    let f: Vec<&str> = stat
        .get(stat.rfind(')')? + 2..)?
        .split_whitespace()
        .collect();
    Some(f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?)
}

/// CPU ticks (1/100 s, the kernel's USER_HZ) used so far by each live thread
/// of this process, user + system: thread id → (name, ticks); `None` off
/// Linux. A thread that ends while it is read is left out.
fn thread_ticks() -> Option<BTreeMap<u32, (String, u64)>> {
    let mut out = BTreeMap::new();
    for entry in std::fs::read_dir("/proc/self/task").ok()?.flatten() {
        let dir = entry.path();
        let Some(tid) = dir
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.parse().ok())
        else {
            continue;
        };
        let (Ok(stat), Ok(comm)) = (
            std::fs::read_to_string(dir.join("stat")),
            std::fs::read_to_string(dir.join("comm")),
        ) else {
            continue;
        };
        if let Some(ticks) = stat_ticks(&stat) {
            out.insert(tid, (comm.trim().to_string(), ticks));
        }
    }
    Some(out)
}

/// Each role's CPU between two [`thread_ticks`] `seconds` apart, in percent
/// of one core: `reader/tracker/sums/records/workers` (the busiest thread of
/// ROI sums; the records are made in this, the calling, thread; the workers
/// as their lowest–highest), `-` for a role with no thread. Where the planes/s stop growing with the threads, the role at
/// 100 % is the one that holds them back.
fn role_cpu(
    before: &BTreeMap<u32, (String, u64)>,
    after: &BTreeMap<u32, (String, u64)>,
    seconds: f64,
) -> String {
    let pid = std::process::id();
    let (mut reader, mut tracker, mut sums, mut records, mut workers) =
        (None, None, None::<f64>, None, Vec::new());
    for (tid, (name, t1)) in after {
        // A thread born in the interval used all its ticks in it.
        let t0 = before.get(tid).map_or(0, |(_, t)| *t);
        let pct = t1.saturating_sub(t0) as f64 / seconds.max(1e-9);
        match name.as_str() {
            READER_THREAD => reader = Some(pct),
            TRACKER_THREAD => tracker = Some(pct),
            WORKER_THREAD => workers.push(pct),
            SUMS_THREAD => sums = Some(sums.map_or(pct, |s| s.max(pct))),
            _ if *tid == pid => records = Some(pct),
            _ => {}
        }
    }
    let one = |p: Option<f64>| p.map_or("-".to_string(), |p| format!("{p:.0}"));
    let w = match workers.iter().copied().reduce(f64::min) {
        Some(lo) => {
            let hi = workers.iter().copied().fold(lo, f64::max);
            format!("{lo:.0}-{hi:.0}")
        }
        None => "-".into(),
    };
    format!(
        "{}/{}/{}/{}/{w}",
        one(reader),
        one(tracker),
        one(sums),
        one(records)
    )
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

/// The thread counts of the scaling curve: 1, 2, 4, … up to `max`, and
/// `max` itself.
fn thread_curve(max: usize) -> Vec<usize> {
    let mut t: Vec<usize> = std::iter::successors(Some(1usize), |&t| t.checked_mul(2))
        .take_while(|&t| t < max)
        .collect();
    t.push(max.max(1));
    t
}

/// One preset's field, configured as `aggregate` would be.
struct Case {
    preset: Preset,
    cfg: PipelineConfig,
    width: u32,
    height: u32,
}

impl Case {
    fn new(
        pipeline: &PipelineArgs,
        width: Option<u32>,
        height: Option<u32>,
    ) -> anyhow::Result<Case> {
        let preset = Preset::new(
            PresetName::parse(&pipeline.preset.name)?,
            pipeline.preset.objective,
        )?;
        let (sw, sh) = preset.camera.size();
        let (width, height) = (width.unwrap_or(sw), height.unwrap_or(sh));
        let period_ns = (preset.period_s() * 1e9).round() as u64;
        let cfg = setup::pipeline_config(pipeline, width, height, period_ns)?;
        Ok(Case {
            preset,
            cfg,
            width,
            height,
        })
    }

    fn typical(&self) -> Scene {
        Scene::smlm(&self.preset).with_field(self.width, self.height)
    }
}

/// Runs the benchmark.
pub fn run(args: Args) -> anyhow::Result<()> {
    let case = Case::new(&args.pipeline, args.width, args.height)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = args.threads.unwrap_or(cores).max(1);
    println!(
        "load average at start: {} ({cores} cores)",
        load_average().unwrap_or_else(|| "unknown".into())
    );
    println!("{}", setup::describe(&case.cfg));
    let typical = case.typical();
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
    if args.stream {
        let (name, scene) = match args.scene.iter().find(|s| **s != BenchScene::Spad512s) {
            Some(BenchScene::Dense) => ("dense", &dense),
            Some(_) => ("typical", &typical),
            None => anyhow::bail!(
                "--stream streams the preset's typical or dense scene; for the SPAD512S give --preset spad512s"
            ),
        };
        return stream(&case.preset, name, scene, &case.cfg, &args, threads);
    }
    let golden_planes = args.golden_planes as usize;
    let planes_n = usize::try_from(args.planes)?.max(golden_planes);
    header();
    if args.scene.contains(&BenchScene::Typical) {
        measure(&case, "typical", &typical, planes_n, &args, threads)?;
    }
    if args.scene.contains(&BenchScene::Dense) {
        measure(&case, "dense", &dense, planes_n, &args, threads)?;
    }
    // The SPAD512S class camera in the same run (the camera this engine must
    // one day keep up with in real time), on its whole field, unless it was
    // the preset measured above.
    if case.preset.name != PresetName::Spad512s && args.scene.contains(&BenchScene::Spad512s) {
        // 32 slots (the SPCImager gateware's) drop most candidates of the
        // ~160 molecules on at once over its field: give the software engine
        // room for them (5 sd above the mean number on, plus 16 for
        // background tracks; at most the stream's 255).
        let mut spad = Case::new(
            &PipelineArgs {
                preset: setup::PresetArgs {
                    name: PresetName::Spad512s.as_str().into(),
                    ..Default::default()
                },
                ..Default::default()
            },
            None,
            None,
        )?;
        let on = spad
            .typical()
            .expected_on(&spad.preset.camera)
            .unwrap_or(0.0);
        spad.cfg.slots = ((on + 5.0 * on.sqrt()).ceil() as usize + 16).clamp(spad.cfg.slots, 255);
        spad.cfg.validate()?;
        println!();
        println!("{}", setup::describe(&spad.cfg));
        header();
        measure(&spad, "spad512s", &spad.typical(), planes_n, &args, threads)?;
    }
    println!(
        "(real time: 10,000 planes/s for the SPCImager, 100,000 for the SPAD512S; planes/CPUs = planes per CPU-second of all threads; vs 1 thr = over the single-threaded fast engine in the same run; load average now {})",
        load_average().unwrap_or_else(|| "unknown".into())
    );
    Ok(())
}

fn header() {
    println!(
        "{:<8} {:<20} {:>7} {:>10} {:>9} {:>11} {:>8} {:>8} {:>8}",
        "scene",
        "engine",
        "planes",
        "planes/s",
        "Gpixel/s",
        "planes/CPUs",
        "vs gold",
        "vs 1 thr",
        "bytes"
    );
}

/// Every engine on one scene: golden, stages 1–4 alone, stages 5–7 alone,
/// the fast engine on one thread, and the chunked engine's scaling curve.
fn measure(
    case: &Case,
    name: &str,
    scene: &Scene,
    planes_n: usize,
    args: &Args,
    threads: usize,
) -> anyhow::Result<()> {
    let cfg = &case.cfg;
    let (w, h) = (case.width, case.height);
    let planes = simulate(&case.preset, scene, planes_n, args.seed)?;
    let on = scene.expected_on(&case.preset.camera).unwrap_or(0.0);
    let gp = &planes[..(args.golden_planes as usize).min(planes.len())];
    let t = Timing::start();
    let golden = run_with(Pipeline::new(cfg.clone())?, gp.iter())?;
    let (golden_rate, golden_cpu) = t.rates(gp.len());
    let golden_bytes = bytes_of(&golden)?;
    let gpix = |rate: f64| rate * (w as f64 * h as f64) / 1e9;
    let mut single_rate: Option<f64> = None;
    let row = |engine: &str,
               n: usize,
               (rate, cpu): (f64, Option<f64>),
               bytes: usize,
               single: Option<f64>| {
        println!(
            "{:<8} {:<20} {:>7} {:>10.0} {:>9.3} {:>11} {:>7.1}x {:>8} {:>8}",
            name,
            engine,
            n,
            rate,
            gpix(rate),
            cpu.map_or("-".into(), |c| format!("{c:.0}")),
            rate / golden_rate,
            single.map_or("-".into(), |s| format!("{:.2}x", rate / s)),
            bytes
        );
    };
    row(
        "golden",
        gp.len(),
        (golden_rate, golden_cpu),
        golden_bytes.len(),
        None,
    );
    // The fast engines on the golden planes: bytes must be identical.
    let fast_same = run_with(fast_pipeline(cfg.clone())?, gp.iter())?;
    let par_same = parallel(cfg, gp, gp.len(), threads.max(2))?;
    if bytes_of(&fast_same)? != golden_bytes || bytes_of(&par_same)? != golden_bytes {
        anyhow::bail!("the fast engine's bytes differ from the golden model's on the {name} scene");
    }
    // Stages 1–4 alone, to show where the time goes (and what each
    // instruction set adds): the build the engine runs first, then the slower ones.
    let zero = BitPlane::zeros(w as usize, h as usize);
    let n = cfg.n_window as usize;
    let best = Isa::detect();
    for isa in best.up_to().collect::<Vec<_>>().into_iter().rev() {
        let t = Timing::start();
        let mut fe = FastFrontEnd::new(cfg).with_isa(isa);
        for (i, p) in planes.iter().enumerate() {
            fe.push(p, if i >= n { &planes[i - n] } else { &zero });
        }
        let rates = t.rates(planes.len());
        row(
            &format!("stages 1-4 {}", isa.as_str()),
            planes.len(),
            rates,
            0,
            None,
        );
        if isa == best {
            println!(
                "{:<8} {:.0} pixels changed a plane (the bit entering the window is not the one \
                 leaving it: each adds ±K around it); {} of {} planes filtered densely (more \
                 than 1/8 of the pixels changed)",
                "",
                fe.changed_pixels() as f64 / planes.len().max(1) as f64,
                fe.dense_planes(),
                planes.len()
            );
        }
    }
    let t = Timing::start();
    let fast = run_with(fast_pipeline(cfg.clone())?, planes.iter())?;
    let single = t.rates(planes.len());
    single_rate.get_or_insert(single.0);
    row(
        "fast, 1 thread",
        planes.len(),
        single,
        bytes_of(&fast)?.len(),
        single_rate,
    );
    // Stages 5–7 alone (the back end of the chunked engine, in its threads
    // for the most workers: the part that the workers do not share): the
    // ceiling of the curve.
    let fronts = FrontResults::compute(cfg, &planes);
    let t = Timing::start();
    let back = fronts.replay_back_end(threads)?;
    let rates = t.rates(planes.len());
    if back != fast {
        anyhow::bail!("stages 5-7 replayed alone differ from the fast engine on the {name} scene");
    }
    let label = format!("stages 5-7, {} thr", sum_parts(threads) + 2);
    row(&label, planes.len(), rates, 0, single_rate);
    // The scaling curve: one worker overlaps the reader and the back end;
    // more workers share the chunks. A run must be long beside the chunks
    // in flight (3·threads + 1), or the curve measures the stream's start,
    // where every chunk's planes are memory touched for the first time, and
    // its end, where workers wait for the last chunks: the simulated planes
    // are streamed again from the start until the most workers' run has
    // had four times the chunks it holds in flight.
    let chunk = default_chunk(cfg.n_window);
    let len = planes.len().max(4 * (3 * threads + 1) * chunk);
    if len > planes.len() {
        println!(
            "{:<8} the curve streams {len} planes: the {} simulated, repeated ({} chunks of {chunk} for {threads} threads)",
            "",
            planes.len(),
            len.div_ceil(chunk)
        );
    }
    let mut first: Option<Vec<Record>> = None;
    for th in thread_curve(threads) {
        let t = Timing::start();
        let par = parallel(cfg, &planes, len, th)?;
        let rates = t.rates(len);
        // The same planes as the single-threaded engine's, or the first
        // run's of the repeated stream.
        let want = if len == planes.len() {
            &fast
        } else {
            first.get_or_insert_with(|| par.clone())
        };
        if &par != want {
            anyhow::bail!("parallel run ({th} threads) differs from the single-threaded one");
        }
        row(
            &format!("fast, chunked x{th}"),
            len,
            rates,
            bytes_of(&par)?.len(),
            single_rate,
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
        "{:<8} about {:.1} molecules on at a time; {} blinks; unconfirmed {}, dropped candidates {}; golden bytes identical: yes; chunks of {} planes",
        "",
        on,
        blinks,
        end.as_ref().map_or(0, |e| e.unconfirmed),
        end.as_ref().map_or(0, |e| e.dropped_candidates),
        default_chunk(cfg.n_window)
    );
    Ok(())
}

fn stream(
    preset: &Preset,
    name: &str,
    scene: &Scene,
    cfg: &PipelineConfig,
    args: &Args,
    threads: usize,
) -> anyhow::Result<()> {
    let planes = args.planes;
    let pool_len = args.pool as usize;
    let t = Timing::start();
    let pool = simulate(preset, scene, pool_len, args.seed)?;
    println!(
        "pool of {pool_len} simulated planes of the {name} scene in {:.1} s; streaming {planes} planes through the fast engine on {threads} threads (chunks of {})",
        t.wall.elapsed().as_secs_f64(),
        default_chunk(cfg.n_window)
    );
    let t = Timing::start();
    let report_every = (planes / 10).max(1);
    let mut done = 0u64;
    let mut records = 0u64;
    let mut bytes = 0usize;
    let mut packetiser = Packetiser::new();
    let mut buf = Vec::new();
    println!(
        "{:>10} {:>8} {:>10} {:>11} {:>8} {:>8}  CPU % since the last row: reader/tracker/sums/records/workers",
        "planes", "seconds", "planes/s", "planes/CPUs", "RSS MiB", "HWM MiB"
    );
    let mut last = (Instant::now(), thread_ticks());
    let mib = |f: &str| status_mib(f).map_or("-".into(), |v| format!("{v:.1}"));
    let src = std::iter::from_fn(|| {
        if done == planes {
            return None;
        }
        let plane = &pool[(done % pool_len as u64) as usize];
        done += 1;
        if done.is_multiple_of(report_every) {
            let (rate, cpu) = t.rates(done as usize);
            let now = (Instant::now(), thread_ticks());
            let roles = match (&last.1, &now.1) {
                (Some(a), Some(b)) => role_cpu(a, b, (now.0 - last.0).as_secs_f64()),
                _ => "-".into(),
            };
            last = now;
            println!(
                "{:>10} {:>8.1} {:>10.0} {:>11} {:>8} {:>8}  {roles}",
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
    let stats = run_parallel(
        cfg.clone(),
        src,
        threads,
        default_chunk(cfg.n_window),
        |r| {
            records += 1;
            buf.clear();
            if packetiser.push(&r, &mut buf).is_ok() {
                bytes += buf.len();
            }
        },
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    // The rows above count a plane when the reader takes it, up to
    // (3·threads + 1) chunks before its records: the rate of a run that is
    // short beside that (the SPAD512S's chunks are 1,009 planes) reads high.
    // This one counts them all through.
    let (rate, cpu) = t.rates(planes as usize);
    println!(
        "all {planes} planes through the engine in {:.2} s: {rate:.0} planes/s, {} planes/CPU-s ({:.3} Gpixel/s); {records} records, {bytes} bytes of packets; the tracker's 3×3 tests: {}, {:.1} % answered ahead by the workers; the rows above count planes when read (the rate includes the replay copy, and the chunks in flight until the end); load average now {}",
        t.wall.elapsed().as_secs_f64(),
        cpu.map_or("-".into(), |c| format!("{c:.0}")),
        rate * (cfg.width * cfg.height) as f64 * 1e-9,
        stats.tracker_tests,
        100.0 * stats.answered_ahead as f64 / stats.tracker_tests.max(1) as f64,
        load_average().unwrap_or_else(|| "unknown".into())
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ticks(threads: &[(u32, &str, u64)]) -> BTreeMap<u32, (String, u64)> {
        threads
            .iter()
            .map(|&(tid, name, t)| (tid, (name.to_string(), t)))
            .collect()
    }

    #[test]
    fn role_cpu_names_each_role_and_dashes_a_missing_one() {
        let pid = std::process::id();
        let before = ticks(&[
            (pid, "smartagg", 100),
            (pid + 1, READER_THREAD, 10),
            (pid + 2, WORKER_THREAD, 0),
            (pid + 3, WORKER_THREAD, 5),
        ]);
        // The tracker is born in the interval (all its ticks count); a
        // thread of no role is left out.
        let after = ticks(&[
            (pid, "smartagg", 150),
            (pid + 1, READER_THREAD, 110),
            (pid + 2, WORKER_THREAD, 20),
            (pid + 3, WORKER_THREAD, 85),
            (pid + 4, TRACKER_THREAD, 30),
            (pid + 5, "other", 999),
            (pid + 6, SUMS_THREAD, 40),
            (pid + 7, SUMS_THREAD, 60),
        ]);
        // The busiest thread of sums.
        assert_eq!(role_cpu(&before, &after, 1.0), "100/30/60/50/20-80");
        assert_eq!(role_cpu(&before, &after, 2.0), "50/15/30/25/10-40");
        assert_eq!(role_cpu(&before, &before, 1.0), "0/-/-/0/0-0");
        let alone = ticks(&[(pid, "smartagg", 7)]);
        assert_eq!(role_cpu(&alone, &alone, 1.0), "-/-/-/0/-");
    }
}
