//! `smartagg aggregate`: a bit-plane recording in, blink-ROI packets out.

use crate::setup::{self, PipelineArgs};
use crate::stream_info::StreamInfo;
use anyhow::Context;
use smartagg_io::output::AtomicFile;
use smartagg_model::config::PipelineConfig;
use smartagg_model::fast_engine::{default_chunk, fast_pipeline, run_parallel, SourcePlane};
use smartagg_model::packet::Encoder;
use smartagg_model::pipeline::{FrontEnd, Pipeline};
use smartagg_model::record::Record;
use smartagg_model::recording::{PlaneFile, RecordingError, RecordingReader};
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::PathBuf;
use std::time::Instant;

/// Which implementation computes the aggregation (the bytes are identical).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// The golden reference model: clear, slow.
    Golden,
    /// Incremental filtering, time-chunked over `--threads` cores.
    Fast,
}

/// Arguments of `smartagg aggregate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Bit-plane recording (.spad, or raw packed planes with --raw).
    pub recording: PathBuf,
    /// Output packet stream (.rois).
    #[arg(long)]
    pub out: PathBuf,
    /// Engine; both give byte-identical output.
    #[arg(long, value_enum, default_value_t = Engine::Fast)]
    pub engine: Engine,
    /// Worker threads of the fast engine (default: all cores; more than the cores are capped, with a note).
    #[arg(long, value_parser = setup::thread_count)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    #[command(flatten)]
    pub raw: setup::RawArgs,
    /// No progress line.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let file = std::fs::File::open(&args.recording)
        .with_context(|| format!("opening recording {}", args.recording.display()))?;
    // A second handle for the workers' reads at an index.
    let file_at = file
        .try_clone()
        .with_context(|| format!("opening recording {}", args.recording.display()))?;
    let reader = setup::open_recording(BufReader::with_capacity(1 << 20, file), &args.raw)
        .with_context(|| format!("reading {}", args.recording.display()))?;
    let header = *reader.header();
    let cfg = setup::pipeline_config(
        &args.pipeline,
        header.width,
        header.height,
        header.plane_period_ns,
    )?;
    let preset = setup::detection(
        &args.pipeline.preset.name,
        args.pipeline.preset.objective,
        args.pipeline.flux,
    )?
    .0;
    smartagg_io::output::refuse_overwriting(&args.out, &[&args.recording])?;
    let info = StreamInfo::new(&preset, header.width, header.height, "aggregate");
    smartagg_io::output::refuse_overwriting(&StreamInfo::path_for(&args.out), &[&args.recording])?;
    // Written beside the target and renamed into place only when complete:
    // a failure leaves no partial stream (and never touches the recording).
    let mut out = BufWriter::new(AtomicFile::create(&args.out)?);
    eprintln!("{}", setup::describe(&cfg));

    let planes_total =
        (header.planes != smartagg_model::recording::PLANES_UNKNOWN).then_some(header.planes);
    let progress = setup::progress(planes_total, args.quiet);
    let started = Instant::now();
    let mut summary = Summary::default();
    let mut encoder = Encoder::new();
    let mut buf = Vec::new();
    let mut write_record = |r: Record, summary: &mut Summary| -> anyhow::Result<()> {
        summary.count(&r);
        buf.clear();
        encoder.push(&r, &mut buf)?;
        summary.bytes_out += buf.len() as u64;
        out.write_all(&buf)?;
        Ok(())
    };

    match args.engine {
        Engine::Golden => {
            let p = Pipeline::new(cfg.clone())?;
            stream_through(p, reader, &progress, &mut summary, &mut write_record)?;
        }
        Engine::Fast if args.threads == Some(1) => {
            let p = fast_pipeline(cfg.clone())?;
            stream_through(p, reader, &progress, &mut summary, &mut write_record)?;
        }
        Engine::Fast => {
            let threads = args.threads.map_or_else(
                || std::thread::available_parallelism().map_or(1, |n| n.get()),
                setup::cap_threads,
            );
            let pb = progress.clone();
            // A regular file: each worker reads its own chunk's planes; a
            // pipe or a device: the reader reads them all.
            let at = PlaneFile::of(file_at, &reader)
                .with_context(|| format!("reading {}", args.recording.display()))?;
            match &at {
                Some(at) => {
                    let planes = at.planes().inspect(move |_| pb.inc(1));
                    run_fast(&cfg, planes, threads, &mut summary, &mut write_record)?
                }
                None => {
                    let planes = reader.inspect(move |_| pb.inc(1));
                    run_fast(&cfg, planes, threads, &mut summary, &mut write_record)?
                }
            }
        }
    }
    let out = out
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", args.out.display()))?;
    out.commit()?;
    let sidecar = info.write_beside(&args.out)?;
    progress.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    let raw_bytes =
        summary.planes * smartagg_model::recording::plane_bytes(header.width, header.height) as u64;
    println!(
        "{} planes in {:.2} s ({:.0} planes/s, {:.1} Mpixel/s); {} blinks, {} unconfirmed tracks, {} candidates dropped (no free slot), {} segments cut at L_max",
        summary.planes,
        secs,
        summary.planes as f64 / secs.max(1e-9),
        summary.planes as f64 * (header.width as f64 * header.height as f64) / secs.max(1e-9) / 1e6,
        summary.blinks,
        summary.unconfirmed,
        summary.dropped,
        summary.cut
    );
    println!(
        "{} bytes of packets written to {} for {} bytes of bit-planes ({:.0}x smaller)",
        summary.bytes_out,
        args.out.display(),
        raw_bytes,
        raw_bytes as f64 / summary.bytes_out.max(1) as f64
    );
    println!(
        "camera {} {}x ({:.1} nm pixels) recorded in {} for localize",
        info.camera,
        info.objective,
        info.pixel_nm,
        sidecar.display()
    );
    Ok(())
}

/// The fast engine on `threads` workers, `write` taking every record until
/// one fails.
fn run_fast<P, I>(
    cfg: &PipelineConfig,
    planes: I,
    threads: usize,
    summary: &mut Summary,
    write: &mut impl FnMut(Record, &mut Summary) -> anyhow::Result<()>,
) -> anyhow::Result<()>
where
    P: SourcePlane<RecordingError>,
    I: Iterator<Item = Result<P, RecordingError>> + Send,
{
    let mut failed: Option<anyhow::Error> = None;
    run_parallel(
        cfg.clone(),
        planes,
        threads,
        default_chunk(cfg.n_window),
        |r| {
            if failed.is_none() {
                if let Err(e) = write(r, summary) {
                    failed = Some(e);
                }
            }
        },
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    failed.map_or(Ok(()), Err)
}

fn stream_through<F: FrontEnd, R: Read>(
    mut p: Pipeline<F>,
    reader: RecordingReader<R>,
    progress: &indicatif::ProgressBar,
    summary: &mut Summary,
    write: &mut impl FnMut(Record, &mut Summary) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    write(p.start_record(), summary)?;
    for plane in reader {
        for r in p.push_plane(&plane?)? {
            write(r, summary)?;
        }
        progress.inc(1);
    }
    for r in p.finish() {
        write(r, summary)?;
    }
    Ok(())
}

/// Totals printed at the end.
#[derive(Default, Debug)]
struct Summary {
    planes: u64,
    blinks: u64,
    unconfirmed: u64,
    dropped: u64,
    cut: u64,
    bytes_out: u64,
}

impl Summary {
    fn count(&mut self, r: &Record) {
        match r {
            Record::Blink(_) => self.blinks += 1,
            Record::End(e) => {
                self.planes = e.planes;
                self.unconfirmed = e.unconfirmed;
                self.dropped = e.dropped_candidates;
                self.cut = e.cut_segments;
            }
            _ => {}
        }
    }
}
