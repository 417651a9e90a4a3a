//! Records to bytes: the checks that every field fits its packet field
//! (before any byte is written), the payloads, the framing and CRC, and the
//! [`Encoder`] that numbers the records.

use super::{
    crc32c, roi_size_ok, type_of, PacketError, HEADER_LEN, MAGIC, MAX_KERNEL_LEN, MAX_PAYLOAD,
    VERSION,
};
use crate::record::{Record, MAX_PLANE};
use crate::rice;

const I48_MIN: i64 = -(1 << 47);
const I48_MAX: i64 = (1 << 47) - 1;

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
