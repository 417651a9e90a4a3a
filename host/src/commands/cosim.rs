//! `smartagg cosim`: the generated gateware (Verilog, verilated) against the
//! golden model on a simulated scene: prints match or the first mismatch
//! (stage, bit-plane, VCD), packets compared, clocks per bit-plane and
//! simulated clock cycles per second.

use anyhow::{bail, Context};
use smartagg_model::params::PresetName;
use smartagg_sim::designs::{Config, DesignSpec, REDUCED};
use smartagg_sim::harness::{threshold_at_quantile, Case, Cosim, Source};
use smartagg_sim::scene::{generate, SceneSpec};
use std::path::PathBuf;

/// Arguments of `smartagg cosim`.
#[derive(clap::Args, Debug)]
#[command(mut_arg("preset", |a| a.help("Camera preset (spcimager, spcimager-projected)")))]
#[command(mut_arg("objective", |a| a.help("Objective magnification (150 or 60)")))]
pub struct Args {
    #[command(flatten)]
    pub preset: crate::setup::PresetArgs,
    /// Bit-planes to stream.
    #[arg(long, default_value_t = 500)]
    pub planes: usize,
    /// Scene and host-stall seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Field width: any multiple of 16 from 32 up to the sensor's (320);
    /// the design is generated and verilated for the field on demand, and
    /// cached (default 64, with height 32).
    #[arg(long, requires = "height")]
    pub width: Option<usize>,
    /// Field height: from the ROI side + 1 up to the sensor's (240).
    #[arg(long, requires = "width")]
    pub height: Option<usize>,
    /// Rolling window N (default: the configuration's N_max, at most 108).
    #[arg(long)]
    pub n: Option<u32>,
    /// Feed the planes through the sensor port instead of the replay pipe-in.
    #[arg(long)]
    pub sensor: bool,
    /// Clocks between sensor-port words (with --sensor): 2 is the sensor's
    /// duty cycle at P = 16, 1 the full rate the pipeline must sustain.
    #[arg(long, default_value_t = 2, requires = "sensor")]
    pub sensor_interval: u32,
    /// Write a VCD of the whole run to this file (debug build, slow).
    #[arg(long)]
    pub vcd: Option<PathBuf>,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let name = PresetName::parse(&args.preset.name)?;
    let config = Config::for_preset(name, args.preset.objective)?;
    let (w, h) = match (args.width, args.height) {
        (Some(w), Some(h)) => (w, h),
        _ => REDUCED,
    };
    let spec = DesignSpec::new(config, w, h)?;
    if args.planes == 0 {
        bail!("--planes must be at least 1");
    }
    if args.sensor && !spec.xem() {
        bail!("--sensor: {} on {w}x{h} is simulated without the XEM6310 core; its input is the pipeline's word port", config.name());
    }
    if args.sensor_interval == 0 {
        bail!("--sensor-interval must be at least 1 clock");
    }
    let n = args.n.unwrap_or(spec.n_max().min(108));
    if n == 0 || n > spec.n_max() {
        bail!(
            "--n {n}: must be 1..={} for {} on {w}x{h}",
            spec.n_max(),
            config.name()
        );
    }
    eprintln!(
        "{} on {w}x{h}: generating and verilating (cached by the Verilog's hash)...",
        config.name()
    );
    let t = std::time::Instant::now();
    let mut c = Cosim::new(spec.clone()).context("building the co-simulation")?;
    let b = c.build();
    eprintln!(
        "design ready in {:.1} s ({}, {}, {})",
        t.elapsed().as_secs_f64(),
        b.dir.display(),
        if b.fresh {
            "verilated now"
        } else {
            "from the cache"
        },
        match (&b.training_error, b.profiled) {
            (Some(why), _) => format!("not profile-guided: its training run failed: {why}"),
            (None, true) => "profile-guided".to_string(),
            (None, false) => "not profile-guided".to_string(),
        }
    );
    let hot = vec![(w / 3, h / 2)];
    let planes = generate(
        &SceneSpec {
            hot: hot.clone(),
            hot_rate: 0.3,
            ..SceneSpec::sparse(w, h, args.planes)
        },
        args.seed,
    );
    let mut case = Case {
        n,
        threshold: 1,
        threshold_hold: None,
        // The field design's choice: sum to the estimated end t_e.
        end_trim: n / 2,
        l_min: 3,
        l_max: n + 100,
        planes,
        hot,
        mask_enable: true,
        source: if args.sensor {
            Source::Sensor
        } else {
            Source::Replay
        },
        input_stall: 10,
        read_stall: 20,
        hold_reads: false,
        seed: args.seed,
    };
    case.threshold = threshold_at_quantile(&c.model_config(&case)?, &case.planes, 0.995);
    // Hysteresis: tracks open at the 99.5th percentile of H and hold down to the 98th.
    case.threshold_hold = Some(
        threshold_at_quantile(&c.model_config(&case)?, &case.planes, 0.98).min(case.threshold),
    );
    c.set_sensor_interval(args.sensor_interval);
    if let Some(path) = &args.vcd {
        c.trace_whole_run(path.clone());
    }
    match c.check(&case)? {
        Ok(cov) => {
            println!(
                "match: {} packets compared byte for byte over {} bit-planes (N {n}, T_int {}, END_TRIM {}, L_min {}, L_max {})",
                cov.packets, cov.planes, case.threshold, case.end_trim, case.l_min, case.l_max
            );
            if cov.records_lost > 0 {
                println!(
                    "  output FIFO overflowed: {} records missing, every one announced by Overflow records",
                    cov.records_lost
                );
            }
            println!("  {cov}");
            let source = if args.sensor {
                format!(
                    "sensor port, a word every {} clock(s)",
                    args.sensor_interval
                )
            } else if spec.xem() {
                "replay pipe-in, block-throttled, a word every other clock at most".to_string()
            } else {
                "the pipeline core's word port, a word on every clock it is ready".to_string()
            };
            println!(
                "  {:.0} clocks per bit-plane from START to the stream's end ({} words of P = {} pixels; {source}); {:.3} M simulated clock cycles/s ({} clocks in {:.2} s)",
                cov.clocks_per_plane(),
                w * h / smartagg_sim::designs::P,
                smartagg_sim::designs::P,
                cov.mcycles_per_second(),
                cov.cycles,
                cov.seconds
            );
            if let Some(p) = &args.vcd {
                println!("  VCD: {}", p.display());
            }
            Ok(())
        }
        Err(m) => bail!("{m}"),
    }
}
