//! The download loop, the same for every source: read a chunk, append it to
//! the output file at once, feed the incremental decoder, count blinks and
//! losses, report progress; stop at the end of the source, at the device's
//! StreamEnd record, at a time limit, or when the source stalls.
//!
//! Nothing is lost silently: the raw bytes reach the file before they are
//! decoded (a decoding problem can always be re-examined from the file), and
//! every gap, CRC failure, malformed or newer-version packet, device-side
//! overflow and truncated tail ends up in [`DownloadReport`] with exact counts.

use super::{Chunk, PacketSource, TransportError};
use smartagg_model::packet::{newer_version_message, Decoder, Event, LossStats};
use smartagg_model::record::{Record, StreamEnd, StreamStart};
use smartagg_model::record_check::RepeatFilter;
use std::fmt;
use std::io::Write;
use std::time::{Duration, Instant};

/// Longest single wait inside a read, so time limits and progress stay live.
const POLL: Duration = Duration::from_millis(100);

/// How the download loop behaves.
#[derive(Debug, Clone)]
pub struct DownloadOptions {
    /// A source that delivers no byte for this long has stalled: the download
    /// ends with [`DownloadError::Stalled`]. A device that was asked to stop
    /// must also finish its stream within this time (at least one second).
    pub stall_timeout: Duration,
    /// Ask the source to stop after this long (`--seconds`).
    pub max_duration: Option<Duration>,
    /// Bytes asked for per read (a multiple of every USB packet size).
    pub chunk_size: usize,
    /// The StreamStart record the configured device must send; any other is
    /// reported in [`DownloadReport::start_mismatch`].
    pub expected_start: Option<StreamStart>,
    /// Shortest interval between two progress reports.
    pub progress_interval: Duration,
}

impl Default for DownloadOptions {
    fn default() -> Self {
        DownloadOptions {
            stall_timeout: Duration::from_secs(5),
            max_duration: None,
            chunk_size: 1 << 16,
            expected_start: None,
            progress_interval: Duration::from_millis(200),
        }
    }
}

/// Counters for the progress line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Progress {
    /// Bytes received and written.
    pub bytes: u64,
    /// Packets delivered.
    pub packets: u64,
    /// Blink records delivered.
    pub blinks: u64,
    /// Records lost so far (in transport and on the device).
    pub records_lost: u64,
    /// Bytes that formed no valid packet so far.
    pub bytes_skipped: u64,
    /// Time since the start.
    pub elapsed: Duration,
}

impl Progress {
    /// Blinks per second so far.
    pub fn blinks_per_s(&self) -> f64 {
        self.blinks as f64 / self.elapsed.as_secs_f64().max(1e-3)
    }

    /// Megabytes (10⁶ bytes) per second so far.
    pub fn mb_per_s(&self) -> f64 {
        self.bytes as f64 / 1e6 / self.elapsed.as_secs_f64().max(1e-3)
    }
}

impl fmt::Display for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} blinks ({:.0}/s), {:.2} MB ({:.2} MB/s), lost: {} records, {} bytes skipped",
            self.blinks,
            self.blinks_per_s(),
            self.bytes as f64 / 1e6,
            self.mb_per_s(),
            self.records_lost,
            self.bytes_skipped
        )
    }
}

/// Receives what the download loop sees (for live localisation, tests and
/// the progress line). Both methods do nothing by default.
pub trait DownloadObserver {
    /// Every decoder event, in stream order.
    fn event(&mut self, _event: &Event) {}
    /// Counters, at most every [`DownloadOptions::progress_interval`] and once at the end.
    fn progress(&mut self, _progress: &Progress) {}
}

/// Why the download ended without an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// The device sent its StreamEnd record.
    StreamEnd,
    /// The source had no more bytes (end of file).
    SourceEnd,
}

/// Most gap descriptions kept for the summary (the counts are always exact).
const MAX_GAP_NOTES: usize = 20;

/// Everything the download saw.
#[derive(Debug, Clone, Default)]
pub struct DownloadReport {
    /// Where the bytes came from.
    pub source: String,
    /// Bytes received and written to the output.
    pub bytes: u64,
    /// Blink records delivered.
    pub blinks: u64,
    /// StreamStart records delivered (more than one: concatenated captures).
    pub streams: u64,
    /// The last StreamEnd record delivered.
    pub stream_end: Option<StreamEnd>,
    /// The sensor (width, height) of the first StreamStart delivered.
    pub sensor: Option<(u32, u32)>,
    /// Packets that repeat an earlier one (same sequence number, same
    /// record): kept in the output as received, counted here.
    pub duplicates: u64,
    /// Blink records delivered once (duplicates left out).
    pub unique_blinks: u64,
    /// Blinks the StreamEnd records (each counted once) say were sent.
    pub claimed_blinks: u64,
    /// The decoder's exact loss accounting.
    pub stats: LossStats,
    /// Highest newer format version met, if any.
    pub newer_version: Option<u8>,
    /// The first few gaps, described (`records 5..7 lost in transport`).
    pub gap_notes: Vec<String>,
    /// Gaps not described in `gap_notes`.
    pub more_gaps: u64,
    /// How the download ended (`None` when it failed).
    pub ending: Option<Ending>,
    /// The last packet delivered was a StreamEnd record.
    pub ended_with_stream_end: bool,
    /// Set when a device's StreamStart differs from the configuration sent.
    pub start_mismatch: Option<String>,
    /// Wall time.
    pub elapsed: Duration,
}

impl DownloadReport {
    /// True when the stream arrived whole: something was received, nothing
    /// was lost or skipped, the last stream was closed by its StreamEnd record
    /// and the device ran the requested configuration.
    pub fn complete(&self) -> bool {
        self.problems().is_empty()
    }

    /// One sentence per problem, for loud warnings (empty when complete).
    pub fn problems(&self) -> Vec<String> {
        let mut p = Vec::new();
        if self.bytes == 0 {
            p.push(format!("no data: {} delivered 0 bytes", self.source));
            return p;
        }
        if let Some(v) = self.newer_version {
            p.push(format!(
                "{}: {} packets could not be read; update smartagg",
                newer_version_message(v),
                self.stats.newer_version
            ));
        }
        if self.stats.packets_ok == 0 {
            p.push(format!(
                "no valid packet in {} bytes: this is not a smartagg packet stream, or it is corrupt throughout",
                self.bytes
            ));
        }
        if self.stats.any_loss() || self.stats.out_of_order > 0 {
            p.push(format!("losses: {}", self.stats));
        }
        if self.stats.truncated_tail_bytes > 0 {
            p.push(format!(
                "the stream is truncated: it ends inside a packet ({} bytes of an incomplete packet at the end)",
                self.stats.truncated_tail_bytes
            ));
        }
        if self.stats.packets_ok > 0 && !self.ended_with_stream_end {
            p.push(
                "the stream has no stream-end record after its last packet: the capture is incomplete (records after the last packet cannot be counted)"
                    .to_string(),
            );
        }
        if self.duplicates > 0 {
            p.push(format!(
                "{} packets repeat earlier ones (same sequence number and record: a duplicated transfer, or a capture concatenated with itself); they are kept as received, and `smartagg localize` drops them",
                self.duplicates
            ));
        } else if self.ended_with_stream_end
            && !self.stats.any_loss()
            && self.claimed_blinks != self.unique_blinks
        {
            p.push(format!(
                "the stream-end records count {} blinks but {} arrived",
                self.claimed_blinks, self.unique_blinks
            ));
        }
        if let Some(m) = &self.start_mismatch {
            p.push(m.clone());
        }
        p
    }
}

/// Why a download failed. The bytes received before the failure are in the
/// output file; the message says how many and where.
#[derive(Debug)]
pub enum DownloadError {
    /// No byte for longer than the stall timeout.
    Stalled {
        /// The timeout.
        waited: Duration,
        /// The source.
        source: String,
        /// Bytes received before.
        bytes: u64,
        /// Output name.
        out: String,
    },
    /// A device asked to stop did not send its StreamEnd record in time.
    NoStreamEnd {
        /// How long we waited after the stop request.
        waited: Duration,
        /// The source.
        source: String,
        /// Bytes received.
        bytes: u64,
        /// Output name.
        out: String,
    },
    /// The source failed.
    Source {
        /// The source.
        source: String,
        /// Bytes received before.
        bytes: u64,
        /// Output name.
        out: String,
        /// What went wrong.
        error: TransportError,
    },
    /// Writing the output failed.
    Write {
        /// Output name.
        out: String,
        /// Bytes written before.
        bytes: u64,
        /// The error.
        error: std::io::Error,
    },
}

impl fmt::Display for DownloadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DownloadError::Stalled {
                waited,
                source,
                bytes,
                out,
            } => write!(
                f,
                "no data for {:.1} s from {source}; {bytes} bytes received so far are in {out}",
                waited.as_secs_f64()
            ),
            DownloadError::NoStreamEnd {
                waited,
                source,
                bytes,
                out,
            } => write!(
                f,
                "{source} did not finish its stream (no stream-end record) within {:.1} s of the stop request; {bytes} bytes received so far are in {out}",
                waited.as_secs_f64()
            ),
            DownloadError::Source {
                source,
                bytes,
                out,
                error,
            } => write!(
                f,
                "{source}: {error}; {bytes} bytes received so far are in {out}"
            ),
            DownloadError::Write { out, bytes, error } => write!(
                f,
                "writing {out} failed after {bytes} bytes: {error}"
            ),
        }
    }
}

impl std::error::Error for DownloadError {}

/// A failed download: the error and what was received before it.
#[derive(Debug)]
pub struct DownloadFailure {
    /// What went wrong.
    pub error: DownloadError,
    /// Counts up to the failure (the decoder was finished on the bytes received).
    pub report: Box<DownloadReport>,
}

impl fmt::Display for DownloadFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.error.fmt(f)
    }
}

impl std::error::Error for DownloadFailure {}

/// Decoder plus bookkeeping.
struct State<'a> {
    decoder: Decoder,
    report: DownloadReport,
    last_was_end: bool,
    repeats: RepeatFilter,
    expected_start: Option<&'a StreamStart>,
    t0: Instant,
    last_progress: Instant,
    progress_interval: Duration,
}

impl State<'_> {
    fn drain(&mut self, observer: &mut dyn DownloadObserver) {
        while let Some(e) = self.decoder.next_event() {
            self.account(&e);
            observer.event(&e);
        }
    }

    fn finish(&mut self, observer: &mut dyn DownloadObserver) {
        for e in self.decoder.finish() {
            self.account(&e);
            observer.event(&e);
        }
        self.report.stats = self.decoder.stats().clone();
        self.report.newer_version = self.decoder.newer_version_seen();
        self.report.elapsed = self.t0.elapsed();
        self.report.ended_with_stream_end = self.last_was_end;
        observer.progress(&self.progress());
    }

    fn account(&mut self, e: &Event) {
        match e {
            Event::Packet(p) => {
                self.last_was_end = matches!(p.record, Record::End(_));
                if self.repeats.is_repeat(p.seq, &p.record) {
                    self.report.duplicates += 1;
                } else {
                    match &p.record {
                        Record::Blink(_) => self.report.unique_blinks += 1,
                        Record::End(end) => {
                            self.report.claimed_blinks =
                                self.report.claimed_blinks.saturating_add(end.blinks)
                        }
                        _ => {}
                    }
                }
                match &p.record {
                    Record::Blink(_) => self.report.blinks += 1,
                    Record::Start(s) => {
                        self.report.streams += 1;
                        self.report
                            .sensor
                            .get_or_insert((s.width.into(), s.height.into()));
                        if let Some(want) = self.expected_start {
                            if s != want && self.report.start_mismatch.is_none() {
                                self.report.start_mismatch = Some(start_mismatch(want, s));
                            }
                        }
                    }
                    Record::End(end) => self.report.stream_end = Some(end.clone()),
                    _ => {}
                }
            }
            Event::Gap {
                expected,
                got,
                lost,
                on_device,
            } => {
                if self.report.gap_notes.len() < MAX_GAP_NOTES {
                    let note = if *lost == 0 {
                        format!("sequence number went back from {expected} to {got} (duplicated or reordered packet)")
                    } else if *on_device {
                        format!("records {expected}..{got} ({lost}) lost on the device (output FIFO overflow)")
                    } else {
                        format!("records {expected}..{got} ({lost}) lost in transport")
                    };
                    self.report.gap_notes.push(note);
                } else {
                    self.report.more_gaps += 1;
                }
            }
            Event::Skipped { .. } => {}
        }
    }

    fn progress(&self) -> Progress {
        let s = self.decoder.stats();
        Progress {
            bytes: s.bytes_in,
            packets: s.packets_ok,
            blinks: self.report.blinks,
            records_lost: s.lost_in_transport + s.lost_on_device,
            bytes_skipped: s.bytes_skipped,
            elapsed: self.t0.elapsed(),
        }
    }

    fn maybe_progress(&mut self, observer: &mut dyn DownloadObserver) {
        if self.last_progress.elapsed() >= self.progress_interval {
            self.last_progress = Instant::now();
            observer.progress(&self.progress());
        }
    }
}

fn start_mismatch(want: &StreamStart, got: &StreamStart) -> String {
    let mut d = Vec::new();
    macro_rules! cmp {
        ($($f:ident),*) => {$(
            if want.$f != got.$f {
                d.push(format!("{} {:?} (requested {:?})", stringify!($f), got.$f, want.$f));
            }
        )*};
    }
    cmp!(
        width,
        height,
        n_window,
        threshold_int,
        threshold_hold,
        l_min,
        l_max,
        r_assoc,
        slots,
        roi_size,
        kernel_shift,
        kernel,
        plane_period_ns,
        masked_pixels
    );
    format!(
        "the device streams with another configuration than requested: {}",
        d.join(", ")
    )
}

/// Runs the download: starts `source`, writes every byte to `out` as it
/// arrives (flushed per chunk), decodes, and ends as the module docs say.
/// `out_name` names the output in messages. The caller configures a device
/// source before (see [`PacketSource::configure`]).
pub fn download(
    source: &mut dyn PacketSource,
    out: &mut dyn Write,
    out_name: &str,
    opts: &DownloadOptions,
    observer: &mut dyn DownloadObserver,
) -> Result<DownloadReport, DownloadFailure> {
    let t0 = Instant::now();
    let mut st = State {
        decoder: Decoder::new(),
        report: DownloadReport {
            source: source.describe(),
            ..Default::default()
        },
        last_was_end: false,
        repeats: RepeatFilter::default(),
        expected_start: opts.expected_start.as_ref(),
        t0,
        last_progress: t0,
        progress_interval: opts.progress_interval,
    };
    let source_name = source.describe();
    let is_device = source.is_device();
    let mut buf = vec![0u8; opts.chunk_size.max(1)];
    // Builds the failure after finishing the decoder on what arrived.
    macro_rules! fail {
        ($make:expr) => {{
            st.finish(observer);
            let bytes = st.report.bytes;
            #[allow(clippy::redundant_closure_call)]
            let error = ($make)(bytes);
            return Err(DownloadFailure {
                error,
                report: Box::new(st.report),
            });
        }};
    }
    if let Err(error) = source.start() {
        fail!(|bytes| DownloadError::Source {
            source: source_name.clone(),
            bytes,
            out: out_name.to_string(),
            error,
        });
    }
    let mut last_data = Instant::now();
    let mut stop_requested: Option<Instant> = None;
    let drain_limit = opts.stall_timeout.max(Duration::from_secs(1));
    let ending = loop {
        let now = Instant::now();
        if stop_requested.is_none() && opts.max_duration.is_some_and(|d| now - t0 >= d) {
            if let Err(error) = source.stop() {
                fail!(|bytes| DownloadError::Source {
                    source: source_name.clone(),
                    bytes,
                    out: out_name.to_string(),
                    error,
                });
            }
            stop_requested = Some(now);
        }
        if let Some(t) = stop_requested {
            if is_device && now - t >= drain_limit {
                fail!(|bytes| DownloadError::NoStreamEnd {
                    waited: drain_limit,
                    source: source_name.clone(),
                    bytes,
                    out: out_name.to_string(),
                });
            }
        }
        let quiet_for = now - last_data;
        if quiet_for >= opts.stall_timeout {
            fail!(|bytes| DownloadError::Stalled {
                waited: opts.stall_timeout,
                source: source_name.clone(),
                bytes,
                out: out_name.to_string(),
            });
        }
        let mut wait = (opts.stall_timeout - quiet_for).min(POLL);
        if let (None, Some(d)) = (stop_requested, opts.max_duration) {
            wait = wait.min(d.saturating_sub(now - t0));
        }
        match source.read(&mut buf, wait) {
            // A source breaking the contract with Data(0) is idle, not alive.
            Ok(Chunk::Data(0)) | Ok(Chunk::Idle) => {}
            Ok(Chunk::Data(n)) => {
                let n = n.min(buf.len());
                let bytes = &buf[..n];
                // Disk first: the raw stream survives whatever decoding finds.
                if let Err(error) = out.write_all(bytes).and_then(|_| out.flush()) {
                    fail!(|b| DownloadError::Write {
                        out: out_name.to_string(),
                        bytes: b,
                        error,
                    });
                }
                st.report.bytes += n as u64;
                last_data = Instant::now();
                st.decoder.feed(bytes);
                st.drain(observer);
                if is_device && st.last_was_end {
                    break Ending::StreamEnd;
                }
            }
            Ok(Chunk::End) => break Ending::SourceEnd,
            Err(error) => fail!(|bytes| DownloadError::Source {
                source: source_name.clone(),
                bytes,
                out: out_name.to_string(),
                error,
            }),
        }
        st.maybe_progress(observer);
    };
    st.finish(observer);
    st.report.ending = Some(ending);
    Ok(st.report)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::DeviceConfig;
    use smartagg_model::packet::{Encoder, Packet};
    use smartagg_model::record::{BlinkRecord, DroppedRecord};
    use std::collections::VecDeque;

    /// One step of a scripted source.
    #[derive(Debug, Clone)]
    pub(crate) enum Step {
        Data(Vec<u8>),
        Idle,
        End,
    }

    /// A source that plays a script; after the script it is idle forever
    /// (a stalled device) unless the script ends with `End`. On `stop`, a
    /// device appends `on_stop` to the script.
    pub(crate) struct ScriptSource {
        pub steps: VecDeque<Step>,
        pub device: bool,
        pub on_stop: Vec<Step>,
        pub stops: usize,
        pub fail_after_script: Option<TransportError>,
        /// After the script, send this byte every millisecond forever.
        pub babble: Option<u8>,
    }

    impl ScriptSource {
        pub(crate) fn new(steps: Vec<Step>, device: bool) -> Self {
            ScriptSource {
                steps: steps.into(),
                device,
                on_stop: Vec::new(),
                stops: 0,
                fail_after_script: None,
                babble: None,
            }
        }
    }

    impl PacketSource for ScriptSource {
        fn describe(&self) -> String {
            "script".into()
        }
        fn is_device(&self) -> bool {
            self.device
        }
        fn configure(&mut self, _: &DeviceConfig) -> Result<(), TransportError> {
            Ok(())
        }
        fn start(&mut self) -> Result<(), TransportError> {
            Ok(())
        }
        fn read(&mut self, buf: &mut [u8], wait: Duration) -> Result<Chunk, TransportError> {
            match self.steps.pop_front() {
                Some(Step::Data(mut d)) => {
                    let n = d.len().min(buf.len());
                    buf[..n].copy_from_slice(&d[..n]);
                    if n < d.len() {
                        self.steps.push_front(Step::Data(d.split_off(n)));
                    }
                    Ok(Chunk::Data(n))
                }
                Some(Step::Idle) => Ok(Chunk::Idle),
                Some(Step::End) => {
                    self.steps.push_front(Step::End);
                    Ok(Chunk::End)
                }
                None => {
                    if let Some(e) = self.fail_after_script.take() {
                        return Err(e);
                    }
                    if let (Some(b), false) = (self.babble, buf.is_empty()) {
                        std::thread::sleep(Duration::from_millis(1));
                        buf[0] = b;
                        return Ok(Chunk::Data(1));
                    }
                    std::thread::sleep(wait);
                    Ok(Chunk::Idle)
                }
            }
        }
        fn stop(&mut self) -> Result<(), TransportError> {
            self.stops += 1;
            self.steps.extend(self.on_stop.drain(..));
            Ok(())
        }
    }

    /// Collects every delivered packet.
    #[derive(Default)]
    pub(crate) struct Collect {
        pub packets: Vec<Packet>,
        pub progress_calls: usize,
    }

    impl DownloadObserver for Collect {
        fn event(&mut self, e: &Event) {
            if let Event::Packet(p) = e {
                self.packets.push(p.clone());
            }
        }
        fn progress(&mut self, _: &Progress) {
            self.progress_calls += 1;
        }
    }

    fn start_record() -> StreamStart {
        smartagg_model::config::PipelineConfig::new(16, 12, 10, vec![1, 2, 1], 2, 20).stream_start()
    }

    fn blink(i: u64) -> Record {
        Record::Blink(BlinkRecord {
            slot: (i % 4) as u8,
            flags: 0,
            anchor_x: 3,
            anchor_y: 4,
            t_cross: 100 + i,
            t_drop: 120 + i,
            t_s: 95 + i as i64,
            t_e: 115 + i as i64,
            planes_summed: 30,
            roi_size: 3,
            counts: vec![1, 2, 1, 2, 9, 2, 1, 2, (i % 7) as u32],
        })
    }

    /// Start, `n` blinks, a dropped record, end: encoded packet by packet.
    fn packets(n: u64) -> Vec<Vec<u8>> {
        let mut enc = Encoder::new();
        let mut records = vec![Record::Start(start_record())];
        records.extend((0..n).map(blink));
        records.push(Record::Dropped(DroppedRecord {
            plane: 130,
            count: 2,
            first_x: 1,
            first_y: 1,
        }));
        records.push(Record::End(StreamEnd {
            planes: 200,
            blinks: n,
            ..Default::default()
        }));
        records
            .iter()
            .map(|r| {
                let mut b = Vec::new();
                enc.push(r, &mut b).unwrap();
                b
            })
            .collect()
    }

    fn opts(stall_ms: u64) -> DownloadOptions {
        DownloadOptions {
            stall_timeout: Duration::from_millis(stall_ms),
            ..Default::default()
        }
    }

    #[test]
    fn a_whole_stream_is_written_byte_for_byte_and_reported_complete() {
        let p = packets(5);
        let bytes = p.concat();
        // Split at awkward places, with idle reads between.
        let steps = vec![
            Step::Data(bytes[..7].to_vec()),
            Step::Idle,
            Step::Data(bytes[7..100].to_vec()),
            Step::Data(bytes[100..].to_vec()),
            Step::End,
        ];
        let mut src = ScriptSource::new(steps, false);
        let mut out = Vec::new();
        let mut obs = Collect::default();
        let r = download(&mut src, &mut out, "out.rois", &opts(1000), &mut obs).unwrap();
        assert_eq!(out, bytes);
        assert_eq!(r.bytes, bytes.len() as u64);
        assert_eq!((r.blinks, r.streams, r.stats.packets_ok), (5, 1, 8));
        assert_eq!(obs.packets.len(), 8);
        assert_eq!(r.ending, Some(Ending::SourceEnd));
        assert!(r.complete(), "{:?}", r.problems());
        assert_eq!(r.stream_end.as_ref().map(|e| e.planes), Some(200));
        assert!(obs.progress_calls >= 1, "a final progress report");
    }

    #[test]
    fn a_stalled_source_ends_with_the_timeout_message_and_keeps_the_bytes() {
        let p = packets(3);
        let sent = [p[0].clone(), p[1].clone(), p[2][..5].to_vec()].concat();
        for device in [false, true] {
            let steps = vec![
                Step::Data(sent[..30].to_vec()),
                Step::Data(sent[30..].to_vec()),
            ];
            let mut src = ScriptSource::new(steps, device);
            let mut out = Vec::new();
            let t0 = Instant::now();
            let f = download(
                &mut src,
                &mut out,
                "run.rois",
                &opts(200),
                &mut Collect::default(),
            )
            .unwrap_err();
            let waited = t0.elapsed();
            assert!(matches!(f.error, DownloadError::Stalled { .. }));
            assert_eq!(
                f.to_string(),
                format!(
                    "no data for 0.2 s from script; {} bytes received so far are in run.rois",
                    sent.len()
                )
            );
            assert!(waited >= Duration::from_millis(200), "{waited:?}");
            assert_eq!(out, sent, "every byte received is on disk");
            // The partial report was finished on what arrived.
            assert_eq!(f.report.stats.packets_ok, 2);
            assert_eq!(f.report.stats.truncated_tail_bytes, 5);
            assert_eq!(f.report.ending, None);
        }
    }

    #[test]
    fn a_device_stops_at_the_time_limit_and_the_loop_ends_at_its_stream_end() {
        let p = packets(40);
        let (body, end) = p.split_at(p.len() - 1);
        // The device streams blinks slowly until stopped, then sends the rest and its end.
        let mut steps = Vec::new();
        for pk in body[..20].iter() {
            steps.push(Step::Data(pk.clone()));
            steps.push(Step::Idle);
        }
        let mut src = ScriptSource::new(steps, true);
        src.on_stop = body[20..]
            .iter()
            .chain(end)
            .map(|b| Step::Data(b.clone()))
            .chain([Step::Data(vec![0xEE; 3])]) // never read: the loop ends at StreamEnd
            .collect();
        let mut o = opts(2000);
        o.max_duration = Some(Duration::from_millis(50));
        o.expected_start = Some(start_record());
        let mut out = Vec::new();
        let r = download(&mut src, &mut out, "o", &o, &mut Collect::default()).unwrap();
        assert_eq!(src.stops, 1);
        assert_eq!(r.ending, Some(Ending::StreamEnd));
        assert_eq!(out, p.concat());
        assert!(r.complete(), "{:?}", r.problems());
        assert_eq!(r.blinks, 40);
    }

    #[test]
    fn a_device_that_ignores_stop_is_an_error_after_the_drain_limit() {
        let p = packets(1);
        let mut src = ScriptSource::new(vec![Step::Data(p[0].clone())], true);
        src.babble = Some(0);
        let mut o = opts(100);
        o.max_duration = Some(Duration::from_millis(10));
        let f = download(
            &mut src,
            &mut Vec::new(),
            "o.rois",
            &o,
            &mut Collect::default(),
        )
        .unwrap_err();
        let msg = f.to_string();
        assert!(msg.starts_with("script did not finish its stream (no stream-end record) within 1.0 s of the stop request;"), "{msg}");
        assert!(
            msg.ends_with("bytes received so far are in o.rois"),
            "{msg}"
        );
    }

    #[test]
    fn a_device_streaming_another_configuration_is_reported() {
        let p = packets(1);
        let mut src = ScriptSource::new(vec![Step::Data(p.concat())], true);
        let mut want = start_record();
        want.n_window = 99;
        want.threshold_int = 7;
        let mut o = opts(500);
        o.expected_start = Some(want);
        let r = download(&mut src, &mut Vec::new(), "o", &o, &mut Collect::default()).unwrap();
        assert!(!r.complete());
        let m = r.start_mismatch.unwrap();
        assert!(m.contains("n_window 10 (requested 99)"), "{m}");
        assert!(m.contains("threshold_int 20 (requested 7)"), "{m}");
        assert!(!m.contains("kernel"), "{m}");
    }

    #[test]
    fn a_failing_source_names_the_bytes_kept() {
        let p = packets(2);
        let mut src = ScriptSource::new(vec![Step::Data(p[0].clone())], true);
        src.fail_after_script = Some(TransportError::Disconnected {
            device: "USB bus 001 device 004: 151f:5341".into(),
        });
        let mut out = Vec::new();
        let f = download(
            &mut src,
            &mut out,
            "x.rois",
            &opts(1000),
            &mut Collect::default(),
        )
        .unwrap_err();
        assert_eq!(
            f.to_string(),
            format!(
                "script: USB bus 001 device 004: 151f:5341 disappeared (unplugged or reset); {} bytes received so far are in x.rois",
                p[0].len()
            )
        );
        assert_eq!(out, p[0]);
        assert_eq!(f.report.stats.packets_ok, 1);
    }

    /// A writer that fails once it holds `limit` bytes.
    struct FullDisk {
        got: Vec<u8>,
        limit: usize,
    }
    impl Write for FullDisk {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            if self.got.len() + b.len() > self.limit {
                return Err(std::io::Error::other("no space left on device"));
            }
            self.got.extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_write_failure_stops_the_download_with_the_count_written() {
        let p = packets(2);
        let steps = p.iter().map(|b| Step::Data(b.clone())).collect();
        let mut src = ScriptSource::new(steps, false);
        let mut out = FullDisk {
            got: Vec::new(),
            limit: p[0].len() + 3,
        };
        let f = download(
            &mut src,
            &mut out,
            "d.rois",
            &opts(1000),
            &mut Collect::default(),
        )
        .unwrap_err();
        assert_eq!(
            f.to_string(),
            format!(
                "writing d.rois failed after {} bytes: no space left on device",
                p[0].len()
            )
        );
        // Bytes that could not be written were not decoded either.
        assert_eq!(f.report.stats.bytes_in, p[0].len() as u64);
    }

    #[test]
    fn concatenated_captures_in_a_file_are_read_to_the_end() {
        let one = packets(2).concat();
        let two = [one.clone(), one.clone()].concat();
        let mut src = ScriptSource::new(vec![Step::Data(two.clone()), Step::End], false);
        let r = download(
            &mut src,
            &mut Vec::new(),
            "o",
            &opts(500),
            &mut Collect::default(),
        )
        .unwrap();
        assert_eq!((r.streams, r.blinks), (2, 4));
        // The same capture twice: its Blink and Dropped packets repeat.
        assert_eq!(r.duplicates, 3);
        assert!(r.problems()[0].contains("3 packets repeat earlier ones"));
        // Two different captures of one configuration are whole.
        let mut enc = Encoder::new();
        let mut other = Vec::new();
        for rec in [
            Record::Start(start_record()),
            blink(10),
            blink(11),
            Record::End(StreamEnd {
                planes: 200,
                blinks: 2,
                ..Default::default()
            }),
        ] {
            enc.push(&rec, &mut other).unwrap();
        }
        let mut src = ScriptSource::new(vec![Step::Data([one, other].concat()), Step::End], false);
        let r = download(
            &mut src,
            &mut Vec::new(),
            "o",
            &opts(500),
            &mut Collect::default(),
        )
        .unwrap();
        assert_eq!((r.streams, r.blinks, r.duplicates), (2, 4, 0));
        assert!(r.complete(), "{:?}", r.problems());
    }

    #[test]
    fn empty_and_garbage_sources_are_problems_not_silence() {
        let mut src = ScriptSource::new(vec![Step::End], false);
        let r = download(
            &mut src,
            &mut Vec::new(),
            "o",
            &opts(500),
            &mut Collect::default(),
        )
        .unwrap();
        assert_eq!(
            r.problems(),
            vec!["no data: script delivered 0 bytes".to_string()]
        );
        let mut src = ScriptSource::new(vec![Step::Data(vec![7u8; 300]), Step::End], false);
        let r = download(
            &mut src,
            &mut Vec::new(),
            "o",
            &opts(500),
            &mut Collect::default(),
        )
        .unwrap();
        let p = r.problems().join("\n");
        assert!(p.contains("no valid packet in 300 bytes"), "{p}");
        assert!(p.contains("300 bytes skipped"), "{p}");
    }

    #[test]
    fn losses_are_described_with_their_sequence_numbers() {
        let p = packets(6);
        // Packets 2 and 3 missing (transport), plus a device overflow record.
        let mut bytes = [p[0].clone(), p[1].clone(), p[4].clone()].concat();
        let mut ovf = Vec::new();
        Encoder::new()
            .push(
                &Record::Overflow(smartagg_model::record::OverflowRecord {
                    first_seq: 5,
                    count: 2,
                }),
                &mut ovf,
            )
            .unwrap();
        bytes.extend_from_slice(&ovf);
        bytes.extend(p[7..].concat());
        let mut src = ScriptSource::new(vec![Step::Data(bytes), Step::End], false);
        let r = download(
            &mut src,
            &mut Vec::new(),
            "o",
            &opts(500),
            &mut Collect::default(),
        )
        .unwrap();
        assert_eq!(r.stats.lost_in_transport, 2);
        assert_eq!(r.stats.lost_on_device, 2);
        assert_eq!(
            r.gap_notes,
            [
                "records 2..4 (2) lost in transport",
                "records 5..7 (2) lost on the device (output FIFO overflow)"
            ]
        );
        let problems = r.problems().join("\n");
        assert!(
            problems.contains("2 records lost in transport"),
            "{problems}"
        );
        assert!(!problems.contains("truncated"), "{problems}");
    }
}
