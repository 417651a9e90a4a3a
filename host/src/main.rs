//! `smartagg`: smart aggregation of SPAD bit-planes for single-molecule
//! localisation microscopy (dSTORM/PALM).

use clap::{Parser, Subcommand};

mod commands;
mod setup;
mod stream_info;

/// Smart aggregation of binary SPAD bit-planes for single-molecule localisation.
///
/// A SPAD camera records one bit per pixel every 100 µs. smartagg finds when
/// each molecule blinks on (spatial Gaussian filter, rolling sum over N
/// bit-planes, a threshold derived from photon statistics), sums only the
/// bit-planes of that blink into one small image (ROI) per blink, and localises
/// the molecule in it. Presets: spcimager, spcimager-projected, spad512s, emccd, scmos.
#[derive(Parser, Debug)]
#[command(name = "smartagg", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The whole chain on an embedded scene: nanorulers, SPCImager 150x, simulate, aggregate, decode, localise, report.
    Demo(commands::demo::Args),
    /// List the camera presets (Table 1 of the paper) and the study's scene defaults.
    Presets(commands::presets::Args),
    /// Derive the window N, threshold T and filter kernel for a camera and molecule.
    Params(commands::params::Args),
    /// Run smart aggregation on a bit-plane recording (.spad) and write blink-ROI packets (.rois).
    Aggregate(commands::aggregate::Args),
    /// Simulate blinking molecules seen by a camera: bit-planes (.spad) or frames (.tif) plus ground truth.
    Simulate(commands::simulate::Args),
    /// Localise molecules in blink-ROI packets (.rois) or a TIFF frame stack; ThunderSTORM CSV out.
    Localize(commands::localize::Args),
    /// Co-simulate the generated gateware (Verilator) against the golden model on a simulated scene.
    Cosim(commands::cosim::Args),
    /// Receive the blink-ROI packet stream from a board, a file or the co-simulation into a .rois file.
    Download(commands::download::Args),
    /// What a blink-ROI packet stream (.rois) holds: a summary, or every record as JSON lines (--json).
    Inspect(commands::inspect::Args),
    /// Estimate and remove stage drift from a localisation table (RCC or fiducials); trajectory CSV and plot.
    Drift(commands::drift::Args),
    /// Render a localisation table as a super-resolution image (normalised Gaussians).
    Render(commands::render::Args),
    /// Calibrate a camera from its own recordings: DCR map, hot pixels, PRNU (SPAD); offset, gain, read noise (EMCCD, sCMOS).
    Calibrate(commands::calibrate::Args),
    /// Reproduce the paper's simulation study (Fig. 4, Fig. 8) and beyond: CSV, PNG, Markdown.
    Study(commands::study::Args),
    /// Measure speed and accuracy (figures printed, nothing asserted).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Gateware: generate a preset's Verilog, UCF and ISE script; report its Spartan-6 resources.
    #[command(subcommand)]
    Hdl(commands::hdl::Command),
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// Bit-plane generation speed of the camera simulator (planes/s).
    Simulate(commands::bench_simulate::Args),
    /// Fits/s, RMSE and Cramér–Rao ratio of every estimator on simulated ROIs.
    Localize(commands::bench_localize::Args),
    /// The frame path end to end (TIFF to CSV) on a simulated one-spot-per-frame stack: spots/s, found, RMSE/CRLB.
    Frames(commands::bench_frames::Args),
    /// Planes/s of the golden and fast aggregation engines side by side.
    Aggregate(commands::bench_aggregate::Args),
    /// Drift correction on a simulated nanoruler acquisition: residual drift, marker spread, ruler spacing.
    Drift(commands::bench_drift::Args),
    /// Blinks made by background alone against L_min: measured, beside the analytic bound.
    FalseBlinks(commands::bench_false_blinks::Args),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(a) => commands::demo::run(a),
        Command::Presets(a) => commands::presets::run(a),
        Command::Params(a) => commands::params::run(a),
        Command::Aggregate(a) => commands::aggregate::run(a),
        Command::Simulate(a) => commands::simulate::run(a),
        Command::Localize(a) => commands::localize::run(a),
        Command::Render(a) => commands::render::run(a),
        Command::Drift(a) => commands::drift::run(a),
        Command::Calibrate(a) => commands::calibrate::run(a),
        Command::Download(a) => commands::download::run(a),
        Command::Inspect(a) => commands::inspect::run(a),
        Command::Cosim(a) => commands::cosim::run(a),
        Command::Study(a) => commands::study::run(a),
        Command::Hdl(c) => commands::hdl::run(c),
        Command::Bench(BenchCommand::Simulate(a)) => commands::bench_simulate::run(a),
        Command::Bench(BenchCommand::Localize(a)) => commands::bench_localize::run(a),
        Command::Bench(BenchCommand::Frames(a)) => commands::bench_frames::run(a),
        Command::Bench(BenchCommand::Aggregate(a)) => commands::bench_aggregate::run(a),
        Command::Bench(BenchCommand::Drift(a)) => commands::bench_drift::run(a),
        Command::Bench(BenchCommand::FalseBlinks(a)) => commands::bench_false_blinks::run(a),
    };
    if let Err(e) = result {
        eprintln!("smartagg: error: {e:#}");
        std::process::exit(2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;
    use proptest::prelude::*;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    /// Every subcommand path and every long option of the CLI.
    fn vocabulary() -> (Vec<Vec<String>>, Vec<String>) {
        fn walk(
            cmd: &clap::Command,
            path: Vec<String>,
            paths: &mut Vec<Vec<String>>,
            opts: &mut Vec<String>,
        ) {
            for a in cmd.get_arguments() {
                if let Some(l) = a.get_long() {
                    opts.push(format!("--{l}"));
                }
            }
            paths.push(path.clone());
            for sub in cmd.get_subcommands() {
                let mut p = path.clone();
                p.push(sub.get_name().to_string());
                walk(sub, p, paths, opts);
            }
        }
        let (mut paths, mut opts) = (Vec::new(), Vec::new());
        walk(&Cli::command(), Vec::new(), &mut paths, &mut opts);
        opts.sort();
        opts.dedup();
        (paths, opts)
    }

    const VALUES: [&str; 16] = [
        "0",
        "-1",
        "1",
        "nan",
        "inf",
        "-inf",
        "1e308",
        "1e-320",
        "18446744073709551616",
        "4294967296",
        "",
        "x",
        "0x",
        "file:",
        "cosim:",
        "320x240",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Any mix of subcommands, options and hostile values is parsed or
        /// refused with a message; the argument layer never panics.
        #[test]
        fn the_argument_layer_never_panics(
            path in any::<prop::sample::Index>(),
            args in prop::collection::vec((any::<prop::sample::Index>(), any::<prop::sample::Index>(), any::<bool>()), 0..8),
        ) {
            let (paths, opts) = vocabulary();
            let mut argv = vec!["smartagg".to_string()];
            argv.extend(path.get(&paths).iter().cloned());
            for (o, v, with_value) in args {
                argv.push(o.get(&opts).clone());
                if with_value {
                    argv.push(v.get(&VALUES).to_string());
                }
            }
            if let Err(e) = Cli::try_parse_from(&argv) {
                prop_assert!(!e.to_string().is_empty());
            }
        }
    }
}
