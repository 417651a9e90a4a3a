//! `smartagg bench simulate`: bit-plane generation speed of the SPAD
//! simulator on one thread (figures printed, nothing asserted).

use std::time::Instant;

use anyhow::bail;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::recording::{pack_plane, BitOrder};
use smartagg_scene::bench::{bench_spad, SpadBench};
use smartagg_scene::{Layout, Scene, SpadSimulator};

/// Arguments.
#[derive(clap::Args, Debug)]
#[command(mut_arg("preset", |a| a.help("SPAD preset: spcimager, spcimager-projected or spad512s")))]
#[command(mut_arg("objective", |a| a.help("Objective magnification (150 or 60)")))]
pub struct Args {
    #[command(flatten)]
    pub preset: crate::setup::PresetArgs,
    /// Bit-planes per case.
    #[arg(long, default_value_t = 20_000)]
    pub planes: u64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

fn line(name: &str, b: &SpadBench, plane_period_s: f64) {
    let cpu = b
        .planes_per_cpu_s()
        .map_or_else(|| "n/a".to_string(), |v| format!("{v:.0}"));
    println!(
        "{name:<38} {:>9} {:>9.0} {:>10} {:>9.1} {:>8.2}x {:>8.3} % {:>7.1}",
        format!("{}x{}", b.width, b.height),
        b.planes_per_s(),
        cpu,
        b.mpixel_per_s(),
        b.planes_per_s() * plane_period_s,
        100.0 * b.ones_fraction,
        b.mean_on
    );
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let name = PresetName::parse(&a.preset.name)?;
    let p = Preset::new(name, a.preset.objective)?;
    let Camera::Spad(cam) = &p.camera else {
        bail!("`bench simulate` measures the SPAD bit-plane simulator: use --preset spcimager, spcimager-projected or spad512s");
    };
    if a.planes == 0 {
        bail!("invalid parameter `--planes` = 0");
    }
    let typical = Scene::smlm(&p);
    let mut dense = Scene::smlm(&p);
    if let Layout::Random { density_per_um2 } = &mut dense.layout {
        *density_per_um2 *= 10.0;
    }
    let study = Scene::study(&p, 0.03);
    println!(
        "SPAD simulator, preset {name} at {}x, {} planes per case, one thread (camera rate {:.0} planes/s)",
        a.preset.objective,
        a.planes,
        1.0 / cam.plane_period_s
    );
    println!(
        "{:<38} {:>9} {:>9} {:>10} {:>9} {:>9} {:>10} {:>7}",
        "case", "field", "planes/s", "/CPU-s", "Mpixel/s", "realtime", "ones", "mol. on"
    );
    let cases = [
        ("typical SMLM (50 /um^2, 30 ms / 30 s)", &typical),
        ("dense SMLM (10x emitters)", &dense),
        ("study field, one molecule at a time", &study),
    ];
    for (label, sc) in cases {
        let b = bench_spad(cam, sc, a.planes, a.seed)?;
        line(label, &b, cam.plane_period_s);
    }
    // Simulation plus packing into the container's byte layout (what
    // `smartagg simulate` does before the disk).
    let mut sim = SpadSimulator::new(cam, &typical, a.seed)?;
    let mut buf = Vec::with_capacity(16 << 10);
    let t = Instant::now();
    for _ in 0..a.planes {
        buf.clear();
        pack_plane(&sim.next_plane(), BitOrder::LsbFirst, &mut buf);
    }
    let s = t.elapsed().as_secs_f64().max(1e-9);
    println!(
        "typical SMLM + packing to .spad bytes: {:.0} planes/s ({:.0} MB/s of packed planes)",
        a.planes as f64 / s,
        a.planes as f64 * buf.len() as f64 / s / 1e6
    );
    println!(
        "planes/s and Mpixel/s are wall-clock (realtime = planes/s ÷ camera rate); /CPU-s divides by \
         the thread's CPU time instead, which is what counts on a shared machine"
    );
    Ok(())
}
