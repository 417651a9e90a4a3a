//! `smartagg inspect`: what a packet stream (.rois) holds, decoded by the
//! host's decoder ([`smartagg_model::packet::Decoder`]).
//!
//! With `--json` it prints the decoded stream in the JSON form of
//! `model/PACKETS.md` §9 — one object per event (record, gap, skipped run),
//! then a summary of the loss accounting — the same bytes as the second
//! decoder `tools/rois.py` prints (`host/tests/python_decoder.rs` checks it).
//! Without, a short summary for a person.

use anyhow::Context;
use smartagg_model::packet::{newer_version_message, Decoder, Event, LossStats, SkipReason};
use smartagg_model::record::{flags, Record};
use std::fmt::Write as _;
use std::io::{BufWriter, Read, Write};
use std::path::PathBuf;

/// Arguments of `smartagg inspect`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The packet stream (.rois).
    pub input: PathBuf,
    /// One JSON object per line: every record, gap and skipped run in stream
    /// order, then a summary of the losses (model/PACKETS.md §9; the output
    /// of tools/rois.py, byte for byte).
    #[arg(long)]
    pub json: bool,
}

/// One JSON object of PACKETS.md §9, keys in the order they are added.
struct Obj(String);

impl Obj {
    fn new(kind: &str) -> Obj {
        Obj(format!("{{\"type\":\"{kind}\""))
    }
    fn int(mut self, key: &str, v: impl std::fmt::Display) -> Obj {
        let _ = write!(self.0, ",\"{key}\":{v}");
        self
    }
    /// An integer, or `null` when absent.
    fn opt(self, key: &str, v: Option<impl std::fmt::Display>) -> Obj {
        match v {
            Some(v) => self.int(key, v),
            None => self.int(key, "null"),
        }
    }
    fn word(mut self, key: &str, v: &str) -> Obj {
        let _ = write!(self.0, ",\"{key}\":\"{v}\"");
        self
    }
    fn bool(self, key: &str, v: bool) -> Obj {
        self.int(key, v)
    }
    fn ints<T: std::fmt::Display>(mut self, key: &str, vs: impl IntoIterator<Item = T>) -> Obj {
        let _ = write!(self.0, ",\"{key}\":[");
        for (i, v) in vs.into_iter().enumerate() {
            if i > 0 {
                self.0.push(',');
            }
            let _ = write!(self.0, "{v}");
        }
        self.0.push(']');
        self
    }
    fn done(mut self) -> String {
        self.0.push('}');
        self.0
    }
}

/// The JSON line (without newline) of one decoder event.
pub fn event_json(e: &Event) -> String {
    match e {
        Event::Packet(p) => {
            let seq = p.seq;
            match &p.record {
                Record::Start(s) => Obj::new("stream_start")
                    .int("seq", seq)
                    .int("width", s.width)
                    .int("height", s.height)
                    .int("n_window", s.n_window)
                    .int("threshold_int", s.threshold_int)
                    .int("threshold_hold", s.threshold_hold)
                    .opt("end_trim", s.end_trim)
                    .int("l_min", s.l_min)
                    .int("l_max", s.l_max)
                    .int("r_assoc", s.r_assoc)
                    .int("slots", s.slots)
                    .int("roi_size", s.roi_size)
                    .int("kernel_shift", s.kernel_shift)
                    .ints("kernel", &s.kernel)
                    .int("plane_period_ns", s.plane_period_ns)
                    .int("masked_pixels", s.masked_pixels)
                    .done(),
                Record::Blink(b) => Obj::new("blink")
                    .int("seq", seq)
                    .int("slot", b.slot)
                    .int("flags", b.flags)
                    .int("anchor_x", b.anchor_x)
                    .int("anchor_y", b.anchor_y)
                    .int("t_cross", b.t_cross)
                    .int("t_drop", b.t_drop)
                    .int("t_s", b.t_s)
                    .int("t_e", b.t_e)
                    .int("planes_summed", b.planes_summed)
                    .int("roi_size", b.roi_size)
                    .ints("counts", &b.counts)
                    .done(),
                Record::Dropped(d) => Obj::new("dropped")
                    .int("seq", seq)
                    .int("plane", d.plane)
                    .int("count", d.count)
                    .int("first_x", d.first_x)
                    .int("first_y", d.first_y)
                    .done(),
                Record::End(e) => Obj::new("stream_end")
                    .int("seq", seq)
                    .int("planes", e.planes)
                    .int("blinks", e.blinks)
                    .int("unconfirmed", e.unconfirmed)
                    .int("dropped_candidates", e.dropped_candidates)
                    .int("bridged_dips", e.bridged_dips)
                    .int("cut_segments", e.cut_segments)
                    .done(),
                Record::Overflow(o) => Obj::new("overflow")
                    .int("seq", seq)
                    .int("first_seq", o.first_seq)
                    .int("count", o.count)
                    .done(),
            }
        }
        Event::Gap {
            expected,
            got,
            lost,
            on_device,
        } => Obj::new("gap")
            .int("expected", expected)
            .int("got", got)
            .int("lost", lost)
            .bool("on_device", *on_device)
            .done(),
        Event::Skipped { bytes, reason } => {
            let o = Obj::new("skipped").int("bytes", bytes);
            match reason {
                SkipReason::Corrupt => o.word("reason", "corrupt"),
                SkipReason::Malformed(_) => o.word("reason", "malformed"),
                SkipReason::NewerVersion(v) => o.word("reason", "newer_version").int("version", v),
                SkipReason::Truncated => o.word("reason", "truncated"),
            }
            .done()
        }
    }
}

/// The JSON line (without newline) of the final loss accounting.
pub fn summary_json(s: &LossStats) -> String {
    Obj::new("summary")
        .int("packets_ok", s.packets_ok)
        .int("bytes_in", s.bytes_in)
        .int("crc_errors", s.crc_errors)
        .int("malformed", s.malformed)
        .int("bytes_skipped", s.bytes_skipped)
        .int("lost_in_transport", s.lost_in_transport)
        .int("lost_on_device", s.lost_on_device)
        .int("newer_version", s.newer_version)
        .int("truncated_tail_bytes", s.truncated_tail_bytes)
        .int("out_of_order", s.out_of_order)
        .done()
}

/// Record counts for the human summary.
#[derive(Default)]
struct Tally {
    starts: u64,
    blinks: u64,
    cut: u64,
    continuations: u64,
    truncated: u64,
    dropped: u64,
    dropped_candidates: u64,
    ends: u64,
    overflows: u64,
    first_start: Option<smartagg_model::record::StreamStart>,
    last_end: Option<smartagg_model::record::StreamEnd>,
}

impl Tally {
    fn add(&mut self, e: &Event) {
        let Event::Packet(p) = e else { return };
        match &p.record {
            Record::Start(s) => {
                self.starts += 1;
                self.first_start.get_or_insert_with(|| s.clone());
            }
            Record::Blink(b) => {
                self.blinks += 1;
                self.cut += b.has(flags::CUT) as u64;
                self.continuations += b.has(flags::CONTINUATION) as u64;
                self.truncated += b.has(flags::TRUNCATED) as u64;
            }
            Record::Dropped(d) => {
                self.dropped += 1;
                self.dropped_candidates += d.count as u64;
            }
            Record::End(e) => {
                self.ends += 1;
                self.last_end = Some(e.clone());
            }
            Record::Overflow(_) => self.overflows += 1,
        }
    }
}

/// Decodes the stream and prints it.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut file = std::fs::File::open(&args.input)
        .with_context(|| format!("cannot open {}", args.input.display()))?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut dec = Decoder::new();
    let mut tally = Tally::default();
    let mut buf = vec![0u8; 1 << 16];
    let mut handle = |e: Event, out: &mut BufWriter<_>| -> std::io::Result<()> {
        if args.json {
            writeln!(out, "{}", event_json(&e))?;
        }
        tally.add(&e);
        Ok(())
    };
    loop {
        let n = file
            .read(&mut buf)
            .with_context(|| format!("cannot read {}", args.input.display()))?;
        if n == 0 {
            break;
        }
        dec.feed(&buf[..n]);
        while let Some(e) = dec.next_event() {
            handle(e, &mut out)?;
        }
    }
    for e in dec.finish() {
        handle(e, &mut out)?;
    }
    let stats = dec.stats().clone();
    if args.json {
        writeln!(out, "{}", summary_json(&stats))?;
        out.flush()?;
        if let Some(v) = dec.newer_version_seen() {
            eprintln!("{}", newer_version_message(v));
        }
        return Ok(());
    }
    writeln!(out, "{}: {} bytes", args.input.display(), stats.bytes_in)?;
    if let Some(s) = &tally.first_start {
        writeln!(
            out,
            "parameters: {}x{} pixels, N = {}, T_int = {}, T_hold = {}, {}, L_min = {}, L_max = {}, {} slots, r_assoc = {}, {}x{} ROIs, {} ns planes, {} masked pixels",
            s.width,
            s.height,
            s.n_window,
            s.threshold_int,
            s.threshold_hold,
            match s.end_trim {
                Some(c) => format!("end_trim = {c}"),
                None => "no end_trim (a version-1 or 2 stream: segments sum to t_drop)".into(),
            },
            s.l_min,
            s.l_max,
            s.slots,
            s.r_assoc,
            s.roi_size,
            s.roi_size,
            s.plane_period_ns,
            s.masked_pixels
        )?;
    }
    writeln!(
        out,
        "records: {} StreamStart, {} Blink ({} cut, {} continuations, {} truncated), {} Dropped ({} candidates), {} StreamEnd, {} Overflow",
        tally.starts,
        tally.blinks,
        tally.cut,
        tally.continuations,
        tally.truncated,
        tally.dropped,
        tally.dropped_candidates,
        tally.ends,
        tally.overflows
    )?;
    match &tally.last_end {
        Some(e) => writeln!(
            out,
            "stream end: {} planes, {} blinks, {} unconfirmed, {} candidates dropped, {} dips bridged, {} cuts",
            e.planes, e.blinks, e.unconfirmed, e.dropped_candidates, e.bridged_dips, e.cut_segments
        )?,
        None => writeln!(out, "no StreamEnd record: the stream was cut short")?,
    }
    writeln!(out, "{stats}")?;
    if let Some(v) = dec.newer_version_seen() {
        writeln!(out, "{}", newer_version_message(v))?;
    }
    out.flush()?;
    Ok(())
}
