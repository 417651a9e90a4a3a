//! Bytes to records: one payload ([`decode_payload`]) and one complete
//! frame ([`decode_frame`]), with every length and field checked.

use super::{
    crc32c, record_type, roi_size_ok, FrameError, PayloadError, BLINK_FIXED_LEN, CRC_LEN,
    HEADER_LEN, MAGIC, MAX_PAYLOAD, VERSION,
};
use crate::record::{BlinkRecord, DroppedRecord, OverflowRecord, Record, StreamEnd, StreamStart};
use crate::rice;

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
