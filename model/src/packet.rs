//! The blink-ROI packet stream, format version 3: the byte contract between
//! the golden model's encoder, the gateware's packetiser and the host's
//! decoder. `model/PACKETS.md` is the full written definition (with the
//! checked-in test vectors of `model/tests/vectors/`); this summary and that
//! file must agree.
//!
//! # Framing
//!
//! Every record travels in one packet; all integers are little-endian.
//!
//! | bytes        | field                                                     |
//! |--------------|-----------------------------------------------------------|
//! | 0–1          | magic `0x53 0x41` ("SA"), [`MAGIC`]                       |
//! | 2            | format version, [`VERSION`] = 3 (1 and 2 are still read)  |
//! | 3            | record type, see [`record_type`]                          |
//! | 4–7          | sequence number, u32                                      |
//! | 8–9          | payload length `L`, u16, at most [`MAX_PAYLOAD`] = 4096   |
//! | 10 … 10+L−1  | payload                                                   |
//! | 10+L … 13+L  | CRC-32C (Castagnoli, [`crc32c`]) of bytes `0 .. 10+L`     |
//!
//! Future versions keep this framing (magic, version byte, 10-byte header,
//! length limit, trailing CRC-32C); they may change payloads and add types.
//!
//! # Payloads (offsets in bytes; u48/i48 are 6-byte little-endian, i48 in
//! two's complement)
//!
//! * `0x01` StreamStart, `41 + 2n` bytes: width u16 @0, height u16 @2,
//!   n_window u32 @4, threshold_int u32 @8, l_min u32 @12, l_max u32 @16,
//!   r_assoc u8 @20, slots u8 @21, roi_size u8 @22, kernel_shift u8 @23,
//!   kernel length `n` u8 @24, `n` kernel weights u16 @25, plane_period_ns
//!   u32 @25+2n, masked_pixels u32 @29+2n, threshold_hold u32 @33+2n,
//!   end_trim u32 @37+2n. A version-2 StreamStart has `37 + 2n` bytes and no
//!   end_trim (read as `None`: its segments summed by the version-2 rule,
//!   PACKETS.md §8.6); a version-1 one has `33 + 2n` bytes, no
//!   threshold_hold either, and is read with `threshold_hold = threshold_int`
//!   (the one-threshold rule). Every other payload is the same in all three
//!   versions.
//! * `0x02` Blink, `35 + block` bytes: slot u8 @0, flags u8 @1, anchor_x u16
//!   @2, anchor_y u16 @4, t_cross u48 @6, t_drop u48 @12, t_s i48 @18, t_e i48
//!   @24, planes_summed u32 @30, roi_size u8 @34 (odd, 1..=31), then the R×R
//!   counts as one [`crate::rice`] count block filling the rest of the
//!   payload.
//! * `0x03` Dropped, 14 bytes: plane u48 @0, count u32 @6, first_x u16 @10,
//!   first_y u16 @12.
//! * `0x04` StreamEnd, 48 bytes: planes, blinks, unconfirmed,
//!   dropped_candidates, bridged_dips, cut_segments, u64 each.
//! * `0x7F` Overflow, 8 bytes: first_seq u32 @0, count u32 @4 (≥ 1).
//!
//! The worst-case Blink payload (R = 31, any counts) is 35 + 3 971 = 4 006
//! bytes, so every record fits [`MAX_PAYLOAD`].
//!
//! # Sequence numbers and loss accounting
//!
//! The [`Encoder`] gives every record but Overflow the next sequence number
//! (wrapping u32), starting at 0 with StreamStart. An Overflow record, emitted
//! only by the gateware when it lost records (its record queue or its output
//! FIFO was full), carries in its header the sequence number of the first record lost (equal to its
//! `first_seq`) and consumes none. The [`Decoder`] expects sequence 0 first
//! and then reports every discontinuity as an [`Event::Gap`]: the records
//! announced by an Overflow record are lost on the device, every other missing
//! record is lost in transport (that includes packets dropped for a CRC error
//! or malformed payload). A sequence number that goes backwards (duplicated or
//! reordered packets; the transports are in-order, so this means a broken
//! transport) is a gap with `lost = 0`, counted in
//! [`LossStats::out_of_order`]; after reordering the transport loss is
//! over-counted, never under-counted. A StreamStart with sequence 0 where
//! another number was expected starts a new stream (concatenated captures)
//! without a gap.
//!
//! # Resynchronisation
//!
//! The decoder scans for the magic; a *plausible header* is magic, a non-zero
//! version and `L ≤ MAX_PAYLOAD`. It then waits for the whole frame and checks
//! the CRC: on a mismatch it counts a CRC error and moves on by **one** byte
//! (never by the claimed length, which may itself be corrupt). A CRC-valid
//! frame is always consumed whole: delivered, or skipped as malformed or as a
//! newer version. At [`Decoder::finish`], a plausible header whose frame runs
//! past the end is skipped one byte at a time as well, so a complete packet
//! behind a corrupted length is still found; the bytes from the first such
//! header to the end are the truncated tail.

use crate::record::{
    BlinkRecord, DroppedRecord, OverflowRecord, Record, StreamEnd, StreamStart, MAX_PLANE,
};
use crate::rice::{self, RiceError};
use crc::{Crc, Table, CRC_32_ISCSI};
use std::collections::VecDeque;
use std::fmt;
use thiserror::Error;

/// First two bytes of every packet: "SA".
pub const MAGIC: [u8; 2] = [0x53, 0x41];
/// Format version this crate writes (and the newest it reads).
pub const VERSION: u8 = 3;
/// Oldest format version this crate reads: version 1, whose StreamStart has
/// no hold threshold.
pub const OLDEST_VERSION: u8 = 1;
/// Largest payload length a packet may declare, bytes.
pub const MAX_PAYLOAD: usize = 4096;
/// Header length, bytes.
pub const HEADER_LEN: usize = 10;
/// CRC length, bytes.
pub const CRC_LEN: usize = 4;
/// Largest packet, bytes.
pub const MAX_PACKET: usize = HEADER_LEN + MAX_PAYLOAD + CRC_LEN;
/// Fixed part of a Blink payload before the count block, bytes.
pub const BLINK_FIXED_LEN: usize = 35;
/// Largest ROI side R.
pub const MAX_ROI_SIZE: u8 = 31;
/// Longest kernel a StreamStart can carry (its length is one byte).
pub const MAX_KERNEL_LEN: usize = 255;
/// Most bytes of unconsumed input a [`Decoder`] holds.
pub const DECODER_BUFFER: usize = 2 * MAX_PACKET;

/// Record type codes (header byte 3).
pub mod record_type {
    /// [`crate::record::Record::Start`].
    pub const STREAM_START: u8 = 0x01;
    /// [`crate::record::Record::Blink`].
    pub const BLINK: u8 = 0x02;
    /// [`crate::record::Record::Dropped`].
    pub const DROPPED: u8 = 0x03;
    /// [`crate::record::Record::End`].
    pub const STREAM_END: u8 = 0x04;
    /// [`crate::record::Record::Overflow`].
    pub const OVERFLOW: u8 = 0x7F;
}

const I48_MIN: i64 = -(1 << 47);
const I48_MAX: i64 = (1 << 47) - 1;

static CRC32C: Crc<u32, Table<16>> = Crc::<u32, Table<16>>::new(&CRC_32_ISCSI);

/// CRC-32C (Castagnoli; reflected, init and xorout `0xFFFF_FFFF`) of `bytes`.
pub fn crc32c(bytes: &[u8]) -> u32 {
    CRC32C.checksum(bytes)
}

/// The message the host prints for a stream of a newer format version.
pub fn newer_version_message(version: u8) -> String {
    format!("stream format version {version} is newer than this smartagg supports ({VERSION})")
}

/// The type code of a record.
pub fn type_of(record: &Record) -> u8 {
    match record {
        Record::Start(_) => record_type::STREAM_START,
        Record::Blink(_) => record_type::BLINK,
        Record::Dropped(_) => record_type::DROPPED,
        Record::End(_) => record_type::STREAM_END,
        Record::Overflow(_) => record_type::OVERFLOW,
    }
}

/// A record that cannot be encoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PacketError {
    /// A plane index above 2⁴⁸ − 1.
    #[error("{field} = {value} does not fit in 48 bits (max {MAX_PLANE})")]
    PlaneOutOfRange {
        /// Field name.
        field: &'static str,
        /// The value.
        value: u64,
    },
    /// A signed plane estimate outside −2⁴⁷ ..= 2⁴⁷ − 1.
    #[error("{field} = {value} does not fit in a signed 48-bit field")]
    SignedOutOfRange {
        /// Field name.
        field: &'static str,
        /// The value.
        value: i64,
    },
    /// An ROI side that is even, zero or above 31.
    #[error("ROI side {0} is not odd and in 1..=31")]
    BadRoiSize(u8),
    /// A Blink whose counts are not R×R.
    #[error("blink has {got} counts, ROI side {roi_size} needs {expected}")]
    CountsLength {
        /// ROI side.
        roi_size: u8,
        /// R×R.
        expected: usize,
        /// Counts present.
        got: usize,
    },
    /// A StreamStart read from a version-1 or 2 stream (no `end_trim`): its
    /// records were summed by the earlier rule, which version 3 cannot say.
    #[error("a stream-start without end_trim (from a version-1 or 2 stream) cannot be written as version {VERSION}")]
    NoEndTrim,
    /// A kernel longer than 255 weights.
    #[error("kernel has {0} weights, at most 255 fit a stream-start packet")]
    KernelTooLong(usize),
    /// An Overflow record whose header seq would differ from `first_seq`.
    #[error("overflow record must carry seq = first_seq ({first_seq}), got {seq}")]
    OverflowSeq {
        /// Requested header sequence number.
        seq: u32,
        /// The record's first lost sequence number.
        first_seq: u32,
    },
    /// An Overflow record announcing no lost record.
    #[error("overflow record with count 0")]
    OverflowEmpty,
}

/// A CRC-valid frame of a version this crate reads whose payload is not a
/// valid record.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PayloadError {
    /// A record type this version does not define.
    #[error("unknown record type 0x{0:02X}")]
    UnknownType(u8),
    /// A payload of the wrong length for its type.
    #[error("{record} payload is {got} bytes, expected {expected}")]
    Length {
        /// Record type name.
        record: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// A payload too short to hold its type's fixed fields.
    #[error("{record} payload is {got} bytes, shorter than its {min} fixed bytes")]
    TooShort {
        /// Record type name.
        record: &'static str,
        /// Minimum length.
        min: usize,
        /// Actual length.
        got: usize,
    },
    /// An ROI side that is even, zero or above 31.
    #[error("ROI side {0} is not odd and in 1..=31")]
    BadRoiSize(u8),
    /// The count block of a Blink is invalid.
    #[error("blink counts: {0}")]
    Counts(#[from] RiceError),
    /// An Overflow record whose header seq differs from its `first_seq`.
    #[error("overflow record header seq {seq} differs from first_seq {first_seq}")]
    OverflowSeq {
        /// Header sequence number.
        seq: u32,
        /// Payload first_seq.
        first_seq: u32,
    },
    /// An Overflow record with count 0.
    #[error("overflow record with count 0")]
    OverflowEmpty,
}

/// Why a single frame given to [`decode_frame`] was rejected.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    /// Fewer bytes than a header and CRC.
    #[error("frame of {0} bytes is shorter than the 14-byte minimum")]
    TooShort(usize),
    /// The first two bytes are not "SA".
    #[error("bad magic {0:02X?}, expected 53 41")]
    BadMagic([u8; 2]),
    /// Version byte 0.
    #[error("version byte 0 is invalid")]
    VersionZero,
    /// A version newer than [`VERSION`].
    #[error("{}", newer_version_message(*.0))]
    NewerVersion(u8),
    /// A declared payload length above [`MAX_PAYLOAD`].
    #[error("declared payload length {0} exceeds {MAX_PAYLOAD}")]
    PayloadTooLong(usize),
    /// The declared length does not match the frame's size.
    #[error("declared payload length {declared} but the frame holds {actual}")]
    LengthMismatch {
        /// From the header.
        declared: usize,
        /// From the slice.
        actual: usize,
    },
    /// The CRC does not match.
    #[error("CRC mismatch: stored 0x{stored:08X}, computed 0x{computed:08X}")]
    Crc {
        /// CRC in the frame.
        stored: u32,
        /// CRC of the bytes.
        computed: u32,
    },
    /// The payload is invalid.
    #[error("malformed payload: {0}")]
    Malformed(#[from] PayloadError),
}

fn check_plane(field: &'static str, value: u64) -> Result<(), PacketError> {
    if value > MAX_PLANE {
        return Err(PacketError::PlaneOutOfRange { field, value });
    }
    Ok(())
}

fn check_i48(field: &'static str, value: i64) -> Result<(), PacketError> {
    if !(I48_MIN..=I48_MAX).contains(&value) {
        return Err(PacketError::SignedOutOfRange { field, value });
    }
    Ok(())
}

fn roi_size_ok(r: u8) -> bool {
    r % 2 == 1 && r <= MAX_ROI_SIZE
}

fn put_u48(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes()[..6]);
}

/// Checks that every field of `record` is representable, before any byte is written.
fn validate(record: &Record, seq: u32) -> Result<(), PacketError> {
    match record {
        Record::Start(s) => {
            if !roi_size_ok(s.roi_size) {
                return Err(PacketError::BadRoiSize(s.roi_size));
            }
            if s.kernel.len() > MAX_KERNEL_LEN {
                return Err(PacketError::KernelTooLong(s.kernel.len()));
            }
            if s.end_trim.is_none() {
                return Err(PacketError::NoEndTrim);
            }
        }
        Record::Blink(b) => {
            if !roi_size_ok(b.roi_size) {
                return Err(PacketError::BadRoiSize(b.roi_size));
            }
            let expected = b.roi_size as usize * b.roi_size as usize;
            if b.counts.len() != expected {
                return Err(PacketError::CountsLength {
                    roi_size: b.roi_size,
                    expected,
                    got: b.counts.len(),
                });
            }
            check_plane("t_cross", b.t_cross)?;
            check_plane("t_drop", b.t_drop)?;
            check_i48("t_s", b.t_s)?;
            check_i48("t_e", b.t_e)?;
        }
        Record::Dropped(d) => check_plane("plane", d.plane)?,
        Record::End(_) => {}
        Record::Overflow(o) => {
            if o.count == 0 {
                return Err(PacketError::OverflowEmpty);
            }
            if seq != o.first_seq {
                return Err(PacketError::OverflowSeq {
                    seq,
                    first_seq: o.first_seq,
                });
            }
        }
    }
    Ok(())
}

fn write_payload(record: &Record, out: &mut Vec<u8>) {
    match record {
        Record::Start(s) => {
            out.extend_from_slice(&s.width.to_le_bytes());
            out.extend_from_slice(&s.height.to_le_bytes());
            out.extend_from_slice(&s.n_window.to_le_bytes());
            out.extend_from_slice(&s.threshold_int.to_le_bytes());
            out.extend_from_slice(&s.l_min.to_le_bytes());
            out.extend_from_slice(&s.l_max.to_le_bytes());
            out.extend_from_slice(&[
                s.r_assoc,
                s.slots,
                s.roi_size,
                s.kernel_shift,
                s.kernel.len() as u8,
            ]);
            for w in &s.kernel {
                out.extend_from_slice(&w.to_le_bytes());
            }
            out.extend_from_slice(&s.plane_period_ns.to_le_bytes());
            out.extend_from_slice(&s.masked_pixels.to_le_bytes());
            out.extend_from_slice(&s.threshold_hold.to_le_bytes());
            // `validate` refuses a StreamStart without end_trim.
            out.extend_from_slice(&s.end_trim.unwrap_or(0).to_le_bytes());
        }
        Record::Blink(b) => {
            out.extend_from_slice(&[b.slot, b.flags]);
            out.extend_from_slice(&b.anchor_x.to_le_bytes());
            out.extend_from_slice(&b.anchor_y.to_le_bytes());
            put_u48(out, b.t_cross);
            put_u48(out, b.t_drop);
            // Two's complement: the low 6 bytes of the i64.
            put_u48(out, b.t_s as u64);
            put_u48(out, b.t_e as u64);
            out.extend_from_slice(&b.planes_summed.to_le_bytes());
            out.push(b.roi_size);
            rice::encode_counts(&b.counts, out);
        }
        Record::Dropped(d) => {
            put_u48(out, d.plane);
            out.extend_from_slice(&d.count.to_le_bytes());
            out.extend_from_slice(&d.first_x.to_le_bytes());
            out.extend_from_slice(&d.first_y.to_le_bytes());
        }
        Record::End(e) => {
            for v in [
                e.planes,
                e.blinks,
                e.unconfirmed,
                e.dropped_candidates,
                e.bridged_dips,
                e.cut_segments,
            ] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        Record::Overflow(o) => {
            out.extend_from_slice(&o.first_seq.to_le_bytes());
            out.extend_from_slice(&o.count.to_le_bytes());
        }
    }
}

/// Appends the packet of `record` with sequence number `seq` to `out`.
///
/// For an Overflow record `seq` must equal its `first_seq`. On error nothing
/// is appended.
pub fn encode_record(record: &Record, seq: u32, out: &mut Vec<u8>) -> Result<(), PacketError> {
    validate(record, seq)?;
    let start = out.len();
    out.extend_from_slice(&MAGIC);
    out.push(VERSION);
    out.push(type_of(record));
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&[0, 0]);
    write_payload(record, out);
    let len = out.len() - start - HEADER_LEN;
    // Validation bounds every payload (worst case 4006 bytes, see module docs).
    debug_assert!(len <= MAX_PAYLOAD);
    out[start + 8..start + 10].copy_from_slice(&(len as u16).to_le_bytes());
    let crc = crc32c(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(())
}

/// Assigns sequence numbers and encodes records, as the model's packetiser does.
#[derive(Debug, Clone, Default)]
pub struct Encoder {
    next_seq: u32,
}

impl Encoder {
    /// An encoder whose first record gets sequence number 0.
    pub fn new() -> Self {
        Encoder { next_seq: 0 }
    }

    /// An encoder whose next record gets sequence number `seq` (tests of
    /// wrap-around and of streams joined mid-way).
    pub fn starting_at(seq: u32) -> Self {
        Encoder { next_seq: seq }
    }

    /// The sequence number the next non-Overflow record will get.
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }

    /// Encodes `record` onto `out`. Every record but Overflow takes the next
    /// sequence number; Overflow is written with its own `first_seq` and
    /// takes none. A record that fails to encode takes no sequence number and
    /// appends nothing.
    pub fn push(&mut self, record: &Record, out: &mut Vec<u8>) -> Result<(), PacketError> {
        match record {
            Record::Overflow(o) => encode_record(record, o.first_seq, out),
            _ => {
                encode_record(record, self.next_seq, out)?;
                self.next_seq = self.next_seq.wrapping_add(1);
                Ok(())
            }
        }
    }
}

/// One decoded packet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Header sequence number (for Overflow: the first lost record's).
    pub seq: u32,
    /// The record.
    pub record: Record,
}

/// Little-endian field reader over a payload whose length was checked.
struct Fields<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Fields<'a> {
    fn take(&mut self, n: usize) -> &'a [u8] {
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        s
    }
    fn u8(&mut self) -> u8 {
        self.take(1)[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take(2).try_into().expect("2 bytes"))
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4).try_into().expect("4 bytes"))
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take(8).try_into().expect("8 bytes"))
    }
    fn u48(&mut self) -> u64 {
        let mut b = [0u8; 8];
        b[..6].copy_from_slice(self.take(6));
        u64::from_le_bytes(b)
    }
    fn i48(&mut self) -> i64 {
        // Sign-extend from bit 47.
        ((self.u48() << 16) as i64) >> 16
    }
}

fn exact_len(record: &'static str, payload: &[u8], expected: usize) -> Result<(), PayloadError> {
    if payload.len() != expected {
        return Err(PayloadError::Length {
            record,
            expected,
            got: payload.len(),
        });
    }
    Ok(())
}

/// Decodes the payload of a frame of format `version` (1, 2 or 3), type `kind`
/// and header `seq`.
pub fn decode_payload(
    version: u8,
    kind: u8,
    seq: u32,
    payload: &[u8],
) -> Result<Record, PayloadError> {
    match kind {
        record_type::STREAM_START => {
            // Version 2 appends threshold_hold (u32) to version 1's fields,
            // version 3 end_trim (u32) to version 2's.
            let fixed: usize = match version {
                1 => 33,
                2 => 37,
                _ => 41,
            };
            if payload.len() < fixed {
                return Err(PayloadError::TooShort {
                    record: "stream-start",
                    min: fixed,
                    got: payload.len(),
                });
            }
            let n = payload[24] as usize;
            exact_len("stream-start", payload, fixed + 2 * n)?;
            let mut f = Fields {
                bytes: payload,
                pos: 0,
            };
            let width = f.u16();
            let height = f.u16();
            let n_window = f.u32();
            let threshold_int = f.u32();
            let l_min = f.u32();
            let l_max = f.u32();
            let r_assoc = f.u8();
            let slots = f.u8();
            let roi_size = f.u8();
            let kernel_shift = f.u8();
            f.u8();
            let kernel = (0..n).map(|_| f.u16()).collect();
            let plane_period_ns = f.u32();
            let masked_pixels = f.u32();
            let threshold_hold = if version >= 2 { f.u32() } else { threshold_int };
            let end_trim = (version >= 3).then(|| f.u32());
            if !roi_size_ok(roi_size) {
                return Err(PayloadError::BadRoiSize(roi_size));
            }
            Ok(Record::Start(StreamStart {
                width,
                height,
                n_window,
                threshold_int,
                threshold_hold,
                end_trim,
                l_min,
                l_max,
                r_assoc,
                slots,
                roi_size,
                kernel_shift,
                kernel,
                plane_period_ns,
                masked_pixels,
            }))
        }
        record_type::BLINK => {
            if payload.len() < BLINK_FIXED_LEN {
                return Err(PayloadError::TooShort {
                    record: "blink",
                    min: BLINK_FIXED_LEN,
                    got: payload.len(),
                });
            }
            let mut f = Fields {
                bytes: payload,
                pos: 0,
            };
            let slot = f.u8();
            let flags = f.u8();
            let anchor_x = f.u16();
            let anchor_y = f.u16();
            let t_cross = f.u48();
            let t_drop = f.u48();
            let t_s = f.i48();
            let t_e = f.i48();
            let planes_summed = f.u32();
            let roi_size = f.u8();
            if !roi_size_ok(roi_size) {
                return Err(PayloadError::BadRoiSize(roi_size));
            }
            let n = roi_size as usize * roi_size as usize;
            let counts = rice::decode_counts(&payload[BLINK_FIXED_LEN..], n)?;
            Ok(Record::Blink(BlinkRecord {
                slot,
                flags,
                anchor_x,
                anchor_y,
                t_cross,
                t_drop,
                t_s,
                t_e,
                planes_summed,
                roi_size,
                counts,
            }))
        }
        record_type::DROPPED => {
            exact_len("dropped", payload, 14)?;
            let mut f = Fields {
                bytes: payload,
                pos: 0,
            };
            Ok(Record::Dropped(DroppedRecord {
                plane: f.u48(),
                count: f.u32(),
                first_x: f.u16(),
                first_y: f.u16(),
            }))
        }
        record_type::STREAM_END => {
            exact_len("stream-end", payload, 48)?;
            let mut f = Fields {
                bytes: payload,
                pos: 0,
            };
            Ok(Record::End(StreamEnd {
                planes: f.u64(),
                blinks: f.u64(),
                unconfirmed: f.u64(),
                dropped_candidates: f.u64(),
                bridged_dips: f.u64(),
                cut_segments: f.u64(),
            }))
        }
        record_type::OVERFLOW => {
            exact_len("overflow", payload, 8)?;
            let mut f = Fields {
                bytes: payload,
                pos: 0,
            };
            let first_seq = f.u32();
            let count = f.u32();
            if count == 0 {
                return Err(PayloadError::OverflowEmpty);
            }
            if seq != first_seq {
                return Err(PayloadError::OverflowSeq { seq, first_seq });
            }
            Ok(Record::Overflow(OverflowRecord { first_seq, count }))
        }
        other => Err(PayloadError::UnknownType(other)),
    }
}

/// Decodes exactly one complete frame of a version this crate reads (no
/// bytes before or after).
pub fn decode_frame(frame: &[u8]) -> Result<Packet, FrameError> {
    if frame.len() < HEADER_LEN + CRC_LEN {
        return Err(FrameError::TooShort(frame.len()));
    }
    if frame[..2] != MAGIC {
        return Err(FrameError::BadMagic([frame[0], frame[1]]));
    }
    match frame[2] {
        0 => return Err(FrameError::VersionZero),
        v if v > VERSION => return Err(FrameError::NewerVersion(v)),
        _ => {}
    }
    let declared = u16::from_le_bytes([frame[8], frame[9]]) as usize;
    if declared > MAX_PAYLOAD {
        return Err(FrameError::PayloadTooLong(declared));
    }
    let actual = frame.len() - HEADER_LEN - CRC_LEN;
    if declared != actual {
        return Err(FrameError::LengthMismatch { declared, actual });
    }
    let body = &frame[..HEADER_LEN + declared];
    let stored = u32::from_le_bytes(frame[HEADER_LEN + declared..].try_into().expect("4 bytes"));
    let computed = crc32c(body);
    if stored != computed {
        return Err(FrameError::Crc { stored, computed });
    }
    let seq = u32::from_le_bytes(frame[4..8].try_into().expect("4 bytes"));
    let record = decode_payload(
        frame[2],
        frame[3],
        seq,
        &frame[HEADER_LEN..HEADER_LEN + declared],
    )?;
    Ok(Packet { seq, record })
}

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
    /// [`newer_version_message`]).
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

    /// Highest newer format version seen, if any (for [`newer_version_message`]).
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
