//! The streaming [`Decoder`]: resynchronisation on the magic, sequence
//! numbers and loss accounting ([`LossStats`]), in bounded memory.

use super::{
    crc32c, decode_payload, Packet, PayloadError, CRC_LEN, DECODER_BUFFER, HEADER_LEN, MAGIC,
    MAX_PAYLOAD, VERSION,
};
use crate::record::Record;
use std::collections::VecDeque;
use std::fmt;

/// What the decoder has seen so far. Every input byte ends up in exactly one
/// of: a delivered packet, `bytes_skipped`, `truncated_tail_bytes`, or the
/// decoder's buffer (until [`Decoder::finish`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LossStats {
    /// Packets delivered (Overflow packets included).
    pub packets_ok: u64,
    /// Bytes fed to the decoder.
    pub bytes_in: u64,
    /// Plausible headers whose CRC did not match (each skipped by one byte).
    pub crc_errors: u64,
    /// CRC-valid frames of a version this crate reads (1 or 2) whose payload
    /// is invalid (skipped whole).
    pub malformed: u64,
    /// Bytes not delivered: noise, corrupted frames, malformed and
    /// newer-version frames (the truncated tail is counted apart).
    pub bytes_skipped: u64,
    /// Records missing from the sequence, not announced by an Overflow record.
    pub lost_in_transport: u64,
    /// Records the device announced lost (Overflow records: its record queue
    /// or its output FIFO was full).
    pub lost_on_device: u64,
    /// CRC-valid frames of a format version newer than [`VERSION`] (skipped).
    pub newer_version: u64,
    /// Bytes of an incomplete packet at the end of the stream.
    pub truncated_tail_bytes: u64,
    /// Packets whose sequence number went backwards (duplicated or reordered).
    pub out_of_order: u64,
}

impl LossStats {
    /// True when any record or byte was not delivered (skipped bytes, CRC
    /// errors, malformed or newer-version frames, lost records, a truncated
    /// tail). Duplicates and reordering alone are not loss.
    pub fn any_loss(&self) -> bool {
        self.crc_errors
            + self.malformed
            + self.bytes_skipped
            + self.lost_in_transport
            + self.lost_on_device
            + self.newer_version
            + self.truncated_tail_bytes
            > 0
    }
}

impl fmt::Display for LossStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} packets decoded from {} bytes",
            self.packets_ok, self.bytes_in
        )?;
        if !self.any_loss() && self.out_of_order == 0 {
            return write!(f, "; nothing lost.");
        }
        let mut parts = Vec::new();
        if self.lost_in_transport > 0 {
            parts.push(format!(
                "{} records lost in transport",
                self.lost_in_transport
            ));
        }
        if self.lost_on_device > 0 {
            parts.push(format!(
                "{} records lost on the device (announced by Overflow records)",
                self.lost_on_device
            ));
        }
        if self.crc_errors > 0 {
            parts.push(format!("{} CRC errors", self.crc_errors));
        }
        if self.malformed > 0 {
            parts.push(format!("{} malformed packets", self.malformed));
        }
        if self.newer_version > 0 {
            parts.push(format!(
                "{} packets of a format version newer than {VERSION} skipped",
                self.newer_version
            ));
        }
        if self.bytes_skipped > 0 {
            parts.push(format!("{} bytes skipped", self.bytes_skipped));
        }
        if self.truncated_tail_bytes > 0 {
            parts.push(format!(
                "{} bytes of a truncated packet at the end",
                self.truncated_tail_bytes
            ));
        }
        if self.out_of_order > 0 {
            parts.push(format!(
                "{} packets out of order (duplicated or reordered)",
                self.out_of_order
            ));
        }
        write!(f, "; {}.", parts.join(", "))
    }
}

/// Why bytes were skipped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SkipReason {
    /// Bytes that form no CRC-valid frame: noise, corrupted packets, or the
    /// middle of a packet where the capture started.
    Corrupt,
    /// A CRC-valid frame whose payload is invalid.
    Malformed(PayloadError),
    /// A CRC-valid frame of a newer format version (see
    /// [`newer_version_message`](super::newer_version_message)).
    NewerVersion(u8),
    /// An incomplete packet at the end of the stream.
    Truncated,
}

/// What the decoder reports, in stream order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// A valid packet.
    Packet(Packet),
    /// Records `expected .. got` (wrapping) are missing: `lost` of them, on
    /// the device (announced by an Overflow record) or in transport. `lost =
    /// 0` means the sequence went backwards (`got` before `expected`).
    Gap {
        /// First missing sequence number.
        expected: u32,
        /// Sequence number after the missing ones.
        got: u32,
        /// Number of missing records.
        lost: u32,
        /// Whether an Overflow record announced them.
        on_device: bool,
    },
    /// `bytes` consecutive bytes were skipped.
    Skipped {
        /// Number of bytes.
        bytes: u64,
        /// Why.
        reason: SkipReason,
    },
}

/// Outcome of looking at the unconsumed input's first byte.
enum Step {
    /// More input is needed to decide.
    NeedMore,
    /// Skip this many bytes as noise; `tail` marks a plausible but incomplete
    /// header at the end of the stream, `crc_error` a complete plausible
    /// frame whose CRC failed.
    Skip {
        bytes: usize,
        tail: bool,
        crc_error: bool,
    },
    /// A CRC-valid frame of this length.
    Frame(usize),
}

/// Incremental, resynchronising stream decoder with bounded memory.
///
/// Feed bytes in chunks of any size; the events are the same for every
/// chunking. The decoder holds at most [`DECODER_BUFFER`] bytes of input
/// (decoded events wait in a queue until taken with [`Decoder::next_event`]).
///
/// Event order: noise before a CRC-valid frame is reported as one
/// [`Event::Skipped`] (reason [`SkipReason::Corrupt`]) when that frame is
/// found, so it is never split by chunk boundaries; then come the frame's
/// [`Event::Gap`]s (transport gap first, then the device gap of an Overflow
/// record), then its [`Event::Packet`], or a `Skipped` event for a malformed
/// or newer-version frame. [`Decoder::finish`] reports the last noise run and
/// the truncated tail.
#[derive(Debug, Clone)]
pub struct Decoder {
    buf: Vec<u8>,
    start: usize,
    events: VecDeque<Event>,
    stats: LossStats,
    expected: u32,
    /// Bytes of the current run of skipped noise (not yet reported).
    run: u64,
    /// Offset in the run of the first plausible-but-incomplete header at EOF.
    run_tail_from: Option<u64>,
    newest_version: Option<u8>,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// A decoder expecting sequence number 0 first.
    pub fn new() -> Self {
        Decoder {
            buf: Vec::with_capacity(DECODER_BUFFER),
            start: 0,
            events: VecDeque::new(),
            stats: LossStats::default(),
            expected: 0,
            run: 0,
            run_tail_from: None,
            newest_version: None,
        }
    }

    /// Adds input. Complete packets are decoded at once and queued as events.
    pub fn feed(&mut self, mut bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        while !bytes.is_empty() {
            if self.start > 0 && self.buf.len() + bytes.len() > DECODER_BUFFER {
                self.buf.drain(..self.start);
                self.start = 0;
            }
            // After parsing, less than one packet stays unconsumed, so there
            // is always room for more than one packet.
            let n = (DECODER_BUFFER - self.buf.len()).min(bytes.len());
            self.buf.extend_from_slice(&bytes[..n]);
            bytes = &bytes[n..];
            self.parse(false);
        }
    }

    /// The next event, if any is ready.
    pub fn next_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// Ends the stream: decodes what can still be decoded, reports the
    /// incomplete tail as truncated, and returns every pending event.
    pub fn finish(&mut self) -> Vec<Event> {
        self.parse(true);
        self.flush_run();
        self.buf.clear();
        self.start = 0;
        self.events.drain(..).collect()
    }

    /// Counters so far.
    pub fn stats(&self) -> &LossStats {
        &self.stats
    }

    /// Highest newer format version seen, if any (for
    /// [`newer_version_message`](super::newer_version_message)).
    pub fn newer_version_seen(&self) -> Option<u8> {
        self.newest_version
    }

    /// Bytes of input currently held (at most [`DECODER_BUFFER`]).
    pub fn buffered(&self) -> usize {
        self.buf.len() - self.start
    }

    /// Decides what the unconsumed input `avail` (non-empty) starts with,
    /// looking at no more bytes than needed, so that the decision does not
    /// depend on how the input was split into chunks.
    fn step(avail: &[u8], eof: bool) -> Step {
        const NOISE: Step = Step::Skip {
            bytes: 1,
            tail: false,
            crc_error: false,
        };
        if avail[0] != MAGIC[0] {
            let bytes = avail
                .iter()
                .position(|&b| b == MAGIC[0])
                .unwrap_or(avail.len());
            return Step::Skip {
                bytes,
                tail: false,
                crc_error: false,
            };
        }
        // At EOF a plausible header that cannot be completed is the
        // truncated tail; before EOF, wait for more bytes.
        let short = if eof {
            Step::Skip {
                bytes: 1,
                tail: true,
                crc_error: false,
            }
        } else {
            Step::NeedMore
        };
        if avail.len() < 2 {
            return short;
        }
        if avail[1] != MAGIC[1] {
            return NOISE;
        }
        if avail.len() < 3 {
            return short;
        }
        if avail[2] == 0 {
            return NOISE;
        }
        if avail.len() < HEADER_LEN {
            return short;
        }
        let len = u16::from_le_bytes([avail[8], avail[9]]) as usize;
        if len > MAX_PAYLOAD {
            return NOISE;
        }
        let total = HEADER_LEN + len + CRC_LEN;
        if avail.len() < total {
            return short;
        }
        let stored =
            u32::from_le_bytes(avail[HEADER_LEN + len..total].try_into().expect("4 bytes"));
        if crc32c(&avail[..HEADER_LEN + len]) != stored {
            // Move on by one byte: the length may be the corrupted field.
            return Step::Skip {
                bytes: 1,
                tail: false,
                crc_error: true,
            };
        }
        Step::Frame(total)
    }

    fn parse(&mut self, eof: bool) {
        while self.start < self.buf.len() {
            let avail = &self.buf[self.start..];
            match Self::step(avail, eof) {
                Step::NeedMore => break,
                Step::Skip {
                    bytes,
                    tail,
                    crc_error,
                } => {
                    if crc_error {
                        self.stats.crc_errors += 1;
                    }
                    if tail && self.run_tail_from.is_none() {
                        self.run_tail_from = Some(self.run);
                    }
                    self.run += bytes as u64;
                    self.start += bytes;
                }
                Step::Frame(total) => {
                    let frame = &self.buf[self.start..self.start + total];
                    let version = frame[2];
                    let kind = frame[3];
                    let seq = u32::from_le_bytes(frame[4..8].try_into().expect("4 bytes"));
                    let decoded = if version > VERSION {
                        Err(SkipReason::NewerVersion(version))
                    } else {
                        decode_payload(version, kind, seq, &frame[HEADER_LEN..total - CRC_LEN])
                            .map_err(SkipReason::Malformed)
                    };
                    self.start += total;
                    // A complete frame ends the noise run, even one that
                    // started at a header cut off by EOF.
                    self.run_tail_from = None;
                    self.flush_run();
                    match decoded {
                        Ok(record) => self.deliver(seq, record),
                        Err(reason) => {
                            match reason {
                                SkipReason::NewerVersion(v) => {
                                    self.stats.newer_version += 1;
                                    self.newest_version =
                                        Some(self.newest_version.map_or(v, |n| n.max(v)));
                                }
                                _ => self.stats.malformed += 1,
                            }
                            self.stats.bytes_skipped += total as u64;
                            self.events.push_back(Event::Skipped {
                                bytes: total as u64,
                                reason,
                            });
                        }
                    }
                }
            }
        }
    }

    /// Reports the current noise run, splitting off the truncated tail.
    fn flush_run(&mut self) {
        if self.run == 0 {
            return;
        }
        let tail_from = self.run_tail_from.take().unwrap_or(self.run);
        if tail_from > 0 {
            self.stats.bytes_skipped += tail_from;
            self.events.push_back(Event::Skipped {
                bytes: tail_from,
                reason: SkipReason::Corrupt,
            });
        }
        let tail = self.run - tail_from;
        if tail > 0 {
            self.stats.truncated_tail_bytes += tail;
            self.events.push_back(Event::Skipped {
                bytes: tail,
                reason: SkipReason::Truncated,
            });
        }
        self.run = 0;
    }

    /// Accounts for sequence numbers `seq` onwards being present.
    fn advance_to(&mut self, seq: u32) {
        let d = seq.wrapping_sub(self.expected);
        if d == 0 {
            return;
        }
        if d < 1 << 31 {
            self.stats.lost_in_transport += d as u64;
            self.events.push_back(Event::Gap {
                expected: self.expected,
                got: seq,
                lost: d,
                on_device: false,
            });
        } else {
            self.stats.out_of_order += 1;
            self.events.push_back(Event::Gap {
                expected: self.expected,
                got: seq,
                lost: 0,
                on_device: false,
            });
        }
    }

    fn deliver(&mut self, seq: u32, record: Record) {
        match &record {
            Record::Overflow(o) => {
                self.advance_to(o.first_seq);
                let got = o.first_seq.wrapping_add(o.count);
                self.stats.lost_on_device += o.count as u64;
                self.events.push_back(Event::Gap {
                    expected: o.first_seq,
                    got,
                    lost: o.count,
                    on_device: true,
                });
                self.expected = got;
            }
            // A new stream (concatenated captures): not a gap.
            Record::Start(_) if seq == 0 => self.expected = 1,
            _ => {
                self.advance_to(seq);
                self.expected = seq.wrapping_add(1);
            }
        }
        self.stats.packets_ok += 1;
        self.events.push_back(Event::Packet(Packet { seq, record }));
    }
}

/// All packets of a complete stream and the decoder's counters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodedStream {
    /// Delivered packets, in stream order.
    pub packets: Vec<Packet>,
    /// Loss accounting.
    pub stats: LossStats,
}

/// Decodes a complete stream held in memory.
pub fn decode_all(bytes: &[u8]) -> DecodedStream {
    let mut d = Decoder::new();
    d.feed(bytes);
    let mut packets = Vec::new();
    while let Some(e) = d.next_event() {
        if let Event::Packet(p) = e {
            packets.push(p);
        }
    }
    for e in d.finish() {
        if let Event::Packet(p) = e {
            packets.push(p);
        }
    }
    DecodedStream {
        packets,
        stats: d.stats.clone(),
    }
}
