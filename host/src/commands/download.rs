//! `smartagg download`: receive the blink-ROI packet stream from a board, a
//! recorded file or the co-simulated gateware, write it to a `.rois` file as
//! it arrives (beside the output, renamed into place when the download ends;
//! a download that receives nothing leaves an earlier output as it was), and
//! report what was lost.
//!
//! Exit status: 0 when the stream arrived whole (nothing lost or skipped,
//! closed by its stream-end record); otherwise an error (status 2) that names
//! every loss, while all bytes received stay in the output file. With
//! `--allow-loss` an incomplete stream only prints warnings and exits 0. An
//! empty source, a stream with no valid packet (e.g. only packets of a newer
//! format version), a stalled or failing source are errors either way.

use crate::setup::{self, PipelineArgs};
use crate::stream_info::StreamInfo;
use anyhow::{bail, Context};
use smartagg_io::output::AtomicFile;
use smartagg_model::params::{Preset, PresetName};
use smartagg_transport::download::{
    download, DownloadObserver, DownloadOptions, DownloadReport, Progress,
};
use smartagg_transport::file::FileSource;
use smartagg_transport::frontpanel::{FrontPanelOptions, FrontPanelSource};
use smartagg_transport::usb::{self, UsbOptions, UsbSource};
use smartagg_transport::{cosim, DeviceConfig, PacketSource, SourceSpec};
use std::path::{Path, PathBuf};
use std::time::Duration;

fn parse_hex_u16(s: &str) -> Result<u16, String> {
    let digits = s
        .strip_prefix("0x")
        .or_else(|| s.strip_prefix("0X"))
        .unwrap_or(s);
    u16::from_str_radix(digits, 16)
        .map_err(|_| format!("`{s}` is not a hexadecimal 16-bit id (e.g. 151f or 0x151f)"))
}

fn parse_hex_u8(s: &str) -> Result<u8, String> {
    let digits = s
        .strip_prefix("0x")
        .or_else(|| s.strip_prefix("0X"))
        .unwrap_or(s);
    u8::from_str_radix(digits, 16)
        .map_err(|_| format!("`{s}` is not a hexadecimal endpoint address (e.g. 0x81)"))
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v < 1e9 => Ok(v),
        _ => Err(format!("`{s}` is not a positive number of seconds")),
    }
}

/// Arguments of `smartagg download`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where the stream comes from: frontpanel (stock XEM6310, needs Opal
    /// Kelly's FrontPanel SDK), usb (bulk-endpoint firmware), file:PATH (a
    /// recorded .rois stream or a named pipe), cosim:PRESET (co-simulated gateware).
    #[arg(long, default_value = "frontpanel")]
    pub source: String,
    /// Output packet stream (.rois): the bytes go to a file beside it as they
    /// arrive, which takes its name when the download ends (an earlier file
    /// of that name stays as it was if nothing arrived).
    #[arg(long)]
    pub out: PathBuf,
    /// USB vendor id, hexadecimal (usb source).
    #[arg(long, value_parser = parse_hex_u16, default_value = "151f")]
    pub vid: u16,
    /// USB product id, hexadecimal (usb source; the default is a placeholder).
    #[arg(long, value_parser = parse_hex_u16, default_value = "5341")]
    pub pid: u16,
    /// Bulk IN endpoint of the stream, hexadecimal (usb source).
    #[arg(long, value_parser = parse_hex_u8, default_value = "0x81")]
    pub endpoint: u8,
    /// USB interface to claim (usb source).
    #[arg(long, default_value_t = usb::DEFAULT_INTERFACE)]
    pub interface: u8,
    /// Board serial number (frontpanel source; default: the first board).
    #[arg(long)]
    pub serial: Option<String>,
    /// Bitfile to load into the FPGA before streaming (frontpanel source).
    #[arg(long)]
    pub bitfile: Option<PathBuf>,
    /// Give up when the source sends nothing for this many seconds. A device
    /// sends packets only when molecules blink: set this above the longest
    /// quiet period the sample can have.
    #[arg(long, value_parser = parse_seconds, default_value = "5")]
    pub timeout: f64,
    /// Stop the device after this many seconds (it then finishes its stream).
    #[arg(long, value_parser = parse_seconds)]
    pub seconds: Option<f64>,
    /// Deliver a file source at this many MB/s, as a device would.
    #[arg(long)]
    pub rate_mbps: Option<f64>,
    /// Exit 0 with warnings when records were lost or the stream is incomplete.
    #[arg(long)]
    pub allow_loss: bool,
    /// The device configuration (N, T_int, kernel, L_min, L_max) comes from this preset.
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// No progress line.
    #[arg(long)]
    pub quiet: bool,
}

/// The progress line.
struct Bar(indicatif::ProgressBar);

impl DownloadObserver for Bar {
    fn progress(&mut self, p: &Progress) {
        self.0.set_message(p.to_string());
        self.0.tick();
    }
}

fn open_source(args: &Args, spec: &SourceSpec) -> anyhow::Result<Box<dyn PacketSource>> {
    if args.rate_mbps.is_some() && !matches!(spec, SourceSpec::File(_)) {
        bail!("--rate-mbps applies to file sources only");
    }
    Ok(match spec {
        SourceSpec::File(path) => {
            let mut src = FileSource::open(path)?;
            if let Some(rate) = args.rate_mbps {
                src = src.with_rate(rate)?;
            }
            Box::new(src)
        }
        SourceSpec::Usb => Box::new(UsbSource::open(&UsbOptions {
            vid: args.vid,
            pid: args.pid,
            interface: args.interface,
            endpoint: args.endpoint,
        })?),
        SourceSpec::FrontPanel => Box::new(FrontPanelSource::open(&FrontPanelOptions {
            serial: args.serial.clone(),
            bitfile: args.bitfile.clone(),
        })?),
        SourceSpec::Cosim(preset) => cosim::open(preset)?,
    })
}

/// The configuration the device gets: the preset's statistics for its full sensor.
fn device_config(args: &PipelineArgs) -> anyhow::Result<DeviceConfig> {
    let (preset, _) = setup::detection(&args.preset.name, args.preset.objective, args.flux)?;
    let (width, height) = preset.camera.size();
    let period_ns = (preset.period_s() * 1e9).round() as u64;
    let cfg = setup::pipeline_config(args, width, height, period_ns)?;
    eprintln!("{}", setup::describe(&cfg));
    Ok(DeviceConfig::from_pipeline(&cfg)?)
}

/// Writes the stream's sidecar (camera, objective, pixel size) when bytes
/// arrived: the sensor is the stream's own, else the preset camera's.
fn write_sidecar(args: &Args, preset: &Preset, r: &DownloadReport) -> anyhow::Result<()> {
    if r.bytes == 0 {
        return Ok(());
    }
    let (w, h) = r.sensor.unwrap_or_else(|| preset.camera.size());
    let path = StreamInfo::new(preset, w, h, "download").write_beside(&args.out)?;
    println!(
        "camera {} {}x recorded in {} for localize",
        preset.name,
        args.pipeline.preset.objective,
        path.display()
    );
    Ok(())
}

fn print_summary(r: &DownloadReport, out: &Path) {
    let secs = r.elapsed.as_secs_f64().max(1e-9);
    println!(
        "{} bytes from {} written to {} in {:.2} s ({:.2} MB/s); {} packets, {} blinks ({:.0} blinks/s), {} stream(s)",
        r.bytes,
        r.source,
        out.display(),
        secs,
        r.bytes as f64 / 1e6 / secs,
        r.stats.packets_ok,
        r.blinks,
        r.blinks as f64 / secs,
        r.streams
    );
    if let Some(end) = &r.stream_end {
        println!(
            "device totals: {} planes, {} blinks, {} unconfirmed tracks, {} candidates dropped (no free slot), {} segments cut at L_max",
            end.planes, end.blinks, end.unconfirmed, end.dropped_candidates, end.cut_segments
        );
    }
    if r.bytes > 0 {
        println!("{}", r.stats);
    }
    for note in &r.gap_notes {
        println!("  {note}");
    }
    if r.more_gaps > 0 {
        println!("  ... and {} more gaps", r.more_gaps);
    }
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let spec: SourceSpec = args.source.parse()?;
    let preset = Preset::new(
        PresetName::parse(&args.pipeline.preset.name)?,
        args.pipeline.preset.objective,
    )?;
    if let SourceSpec::File(input) = &spec {
        let ignored = args.pipeline.configuration_options();
        if !ignored.is_empty() {
            bail!(
                "{} configure a device; a file source replays a recorded stream as it is (only --preset and --objective, which name the camera for localize, apply)",
                ignored.join(", ")
            );
        }
        for out in [args.out.clone(), StreamInfo::path_for(&args.out)] {
            if smartagg_io::output::same_file(input, &out) {
                bail!(
                    "--out {} is the input file itself: writing it would destroy the recording",
                    out.display()
                );
            }
        }
    }
    let mut source = open_source(&args, &spec)?;
    let mut opts = DownloadOptions {
        stall_timeout: Duration::from_secs_f64(args.timeout),
        max_duration: args.seconds.map(Duration::from_secs_f64),
        ..Default::default()
    };
    if source.is_device() {
        let cfg = device_config(&args.pipeline)?;
        source
            .configure(&cfg)
            .with_context(|| format!("configuring {}", source.describe()))?;
        opts.expected_start = Some(cfg.expected_start());
    }
    // The bytes go to a file beside the output as they arrive; it becomes
    // the output when the download ends, whatever was lost, unless nothing
    // arrived (then an earlier file of that name is left as it was).
    let mut out = AtomicFile::create(&args.out)?;
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        let pb = indicatif::ProgressBar::new_spinner();
        pb.set_style(
            indicatif::ProgressStyle::with_template("{elapsed_precise} {spinner} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        pb
    };
    let mut observer = Bar(bar.clone());
    let out_name = args.out.display().to_string();
    let result = download(source.as_mut(), &mut out, &out_name, &opts, &mut observer);
    bar.finish_and_clear();
    let received = match &result {
        Ok(r) => r.bytes,
        Err(f) => f.report.bytes,
    };
    if received > 0 {
        out.commit()?;
    } else {
        drop(out);
    }
    // What localize needs to know about the stream, beside every byte kept.
    let report = match result {
        Ok(r) => r,
        Err(failure) => {
            print_summary(&failure.report, &args.out);
            write_sidecar(&args, &preset, &failure.report)?;
            return Err(failure.error.into());
        }
    };
    write_sidecar(&args, &preset, &report)?;
    print_summary(&report, &args.out);
    if report.complete() {
        return Ok(());
    }
    let problems = report.problems();
    let fatal = report.bytes == 0 || report.stats.packets_ok == 0;
    if fatal || !args.allow_loss {
        let mut msg = format!(
            "the download is incomplete:\n  - {}",
            problems.join("\n  - ")
        );
        if report.bytes > 0 {
            msg += &format!(
                "\nall {} bytes received are in {}",
                report.bytes,
                args.out.display()
            );
        }
        if !fatal {
            msg += " (--allow-loss accepts an incomplete stream)";
        }
        bail!(msg);
    }
    for p in problems {
        eprintln!("smartagg: WARNING: {p}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_hexadecimal_with_or_without_prefix() {
        assert_eq!(parse_hex_u16("151f"), Ok(0x151f));
        assert_eq!(parse_hex_u16("0x151F"), Ok(0x151f));
        assert!(parse_hex_u16("0x1_0000").is_err());
        assert!(parse_hex_u16("xyz")
            .unwrap_err()
            .contains("`xyz` is not a hexadecimal"));
        assert_eq!(parse_hex_u8("0x81"), Ok(0x81));
        assert_eq!(parse_hex_u8("82"), Ok(0x82));
        assert!(parse_hex_u8("0x181").is_err());
        assert_eq!(parse_seconds("0.2"), Ok(0.2));
        for bad in ["0", "-1", "nan", "inf", "x"] {
            assert!(parse_seconds(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn device_config_follows_the_preset() {
        let args = PipelineArgs {
            n_window: Some(40),
            threshold_int: None,
            l_min: Some(2),
            l_max: Some(500),
            slots: 16,
            ..PipelineArgs::default()
        };
        let cfg = device_config(&args).unwrap();
        assert_eq!((cfg.width, cfg.height), (320, 240));
        assert_eq!(cfg.registers.n_window, 40);
        assert_eq!(
            (cfg.registers.l_min, cfg.registers.l_max, cfg.slots),
            (2, 500, 16)
        );
        assert_eq!(cfg.registers.plane_period_ns, 100_000);
        assert_eq!(
            cfg.kernel.iter().map(|&w| w as u64).sum::<u64>(),
            1 << cfg.kernel_shift
        );
    }
}
