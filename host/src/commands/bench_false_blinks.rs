//! `smartagg bench false-blinks`: how many blinks does background alone make,
//! as a function of the confirmation length L_min? Measured by running the
//! fast engine on simulated background-only bit-planes, beside the model's
//! analytic upper bound — the figures a user needs to choose L_min for a field.

use crate::setup::{self, PipelineArgs};
use smartagg_model::false_alarm::{BackgroundProcess, Neighbourhood};
use smartagg_model::fast_engine::fast_pipeline;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::record::Record;
use smartagg_scene::scene::{Layout, Scene};
use smartagg_scene::spad::SpadSimulator;
use std::time::Instant;

/// Arguments of `smartagg bench false-blinks`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Field width, pixels.
    #[arg(long, default_value_t = 64)]
    pub width: u32,
    /// Field height, pixels.
    #[arg(long, default_value_t = 64)]
    pub height: u32,
    /// Seconds of background-only bit-planes to simulate.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs the measurement.
pub fn run(args: Args) -> anyhow::Result<()> {
    let preset = Preset::new(
        PresetName::parse(&args.pipeline.preset.name)?,
        args.pipeline.preset.objective,
    )?;
    let Camera::Spad(cam) = &preset.camera else {
        anyhow::bail!("false blinks apply to bit-plane (SPAD) presets");
    };
    let (_, det) = setup::detection(
        &args.pipeline.preset.name,
        args.pipeline.preset.objective,
        args.pipeline.flux,
    )?;
    let mut cfg = setup::pipeline_config(&args.pipeline, args.width, args.height, 100_000)?;
    // Every background track is confirmed and counted; 255 slots so that slot
    // exhaustion does not hide any.
    cfg.l_min = 1;
    cfg.slots = 255;
    println!("{}", setup::describe(&cfg));
    let mut scene = Scene::smlm(&preset).with_field(args.width, args.height);
    scene.layout = Layout::Random {
        density_per_um2: 0.0,
    };
    let mut sim = SpadSimulator::new(cam, &scene, args.seed)?;
    let planes = (args.seconds / cam.plane_period_s).round().max(1.0) as u64;
    let mut p = fast_pipeline(cfg.clone())?;
    let mut durations = Vec::new();
    let mut dropped = 0;
    let t = Instant::now();
    for _ in 0..planes {
        for r in p.push_plane(&sim.next_plane())? {
            if let Record::Blink(b) = r {
                if !b.has(smartagg_model::record::flags::CONTINUATION) {
                    durations.push(b.t_drop - b.t_cross);
                }
            }
        }
    }
    for r in p.finish() {
        if let Record::End(e) = r {
            dropped = e.dropped_candidates;
        }
    }
    let secs = planes as f64 * cam.plane_period_s;
    println!(
        "{planes} background-only planes ({secs:.1} s of acquisition) in {:.1} s; {} candidates dropped (no slot)",
        t.elapsed().as_secs_f64(),
        dropped
    );
    let bp = BackgroundProcess::new(
        &det.kernel(),
        cfg.n_window,
        det.p_off,
        cfg.threshold_int as u64,
    )?;
    let field = args.width as f64 * args.height as f64;
    let rate = 1.0 / cam.plane_period_s;
    println!(
        "{:>7} {:>14} {:>16} {:>22}",
        "L_min", "false blinks", "measured per s", "bound per s (1 pixel)"
    );
    let mut l = 1u32;
    while l <= 4 * cfg.n_window {
        let n = durations.iter().filter(|&&d| d >= l as u64).count();
        let bound = bp
            .false_blink_bound(l, Neighbourhood::Pixel)
            .map(|b| format!("{:.3e}", b.per_pixel_plane * field * rate))
            .unwrap_or_else(|e| format!("({e})"));
        println!("{l:>7} {n:>14} {:>16.3} {bound:>22}", n as f64 / secs);
        l = if l < 10 { l + 9 } else { l + 10 };
    }
    println!("(a measured 0 means fewer than 1 in {secs:.1} s; the bound is an upper bound on single-pixel excursions)");
    Ok(())
}
