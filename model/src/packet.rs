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

mod decode;
mod decoder;
mod encode;

pub use decode::{decode_frame, decode_payload, Packet};
pub use decoder::{decode_all, DecodedStream, Decoder, Event, LossStats, SkipReason};
pub use encode::{encode_record, Encoder};

use crate::record::{Record, MAX_PLANE};
use crate::rice::RiceError;
use crc::{Crc, Table, CRC_32_ISCSI};
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

fn roi_size_ok(r: u8) -> bool {
    r % 2 == 1 && r <= MAX_ROI_SIZE
}
