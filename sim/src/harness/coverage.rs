//! Coverage counters: what the model's records of a case exercised, and
//! what the gateware delivered (its packets decoded: record kinds, flags,
//! sequence wraps).

use super::{Case, Framed};
use crate::verilator::Counters;
use smartagg_model::record::{flags, Record};

/// Coverage of what the cases exercised (summed over cases).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Coverage {
    /// Cases run.
    pub cases: u64,
    /// Bit-planes streamed.
    pub planes: u64,
    /// Packets compared (model records).
    pub packets: u64,
    /// Confirmed blinks (Blink records).
    pub confirmed_blinks: u64,
    /// Single-plane dips bridged.
    pub bridged_dips: u64,
    /// Tracks shorter than L_min (unconfirmed).
    pub unconfirmed_tracks: u64,
    /// Candidates dropped for want of a free slot.
    pub slot_exhaustion: u64,
    /// Cases whose output FIFO overflowed.
    pub output_fifo_full: u64,
    /// Records lost to output overflow, all announced.
    pub records_lost: u64,
    /// DDR2 refreshes that collided with waiting commands.
    pub refresh_collisions: u64,
    /// Blink ROIs touching the field's edge.
    pub edge_rois: u64,
    /// Segments cut at L_max.
    pub cut_segments: u64,
    /// Blinks truncated by the stream end.
    pub truncated_blinks: u64,
    /// Blinks that summed no plane (a first segment that ended before its
    /// first plane left the window).
    pub empty_blinks: u64,
    /// StreamStart records the gateware delivered (its bytes decoded, as
    /// are all the counters from here to [`Coverage::seq_wraps`]).
    pub start_records: u64,
    /// Blink records delivered.
    pub blink_records: u64,
    /// Dropped records delivered.
    pub dropped_records: u64,
    /// Overflow records delivered.
    pub overflow_records: u64,
    /// StreamEnd records delivered.
    pub end_records: u64,
    /// Delivered Blinks flagged EDGE.
    pub flag_edge: u64,
    /// Delivered Blinks flagged MASKED.
    pub flag_masked: u64,
    /// Delivered Blinks flagged TRUNCATED.
    pub flag_truncated: u64,
    /// Delivered Blinks flagged CONTINUATION.
    pub flag_continuation: u64,
    /// Delivered Blinks flagged PREROLL_CLIPPED.
    pub flag_preroll_clipped: u64,
    /// Delivered Blinks cut at L_max (flag CUT).
    pub lmax_cuts: u64,
    /// Delivered empty segments (no plane summed) that were cut at L_max
    /// and continued: the empty segment of a continued blink. (A
    /// CONTINUATION segment itself always sums a plane under the version-3
    /// rule, PACKETS.md §8.6; [`Coverage::empty_continuations`] counts any.)
    pub empty_continued: u64,
    /// Delivered CONTINUATION segments that summed no plane (0 under the
    /// version-3 rule).
    pub empty_continuations: u64,
    /// Delivered continuations of a cut at the stream's last plane
    /// (CONTINUATION | TRUNCATED, `t_drop = t_cross − 1`).
    pub continued_at_last_plane: u64,
    /// Times the delivered sequence numbers (Overflow ranges included)
    /// wrapped from 2³² − 1 to 0.
    pub seq_wraps: u64,
    /// Clock cycles simulated.
    pub cycles: u64,
    /// Clock cycles from START to the end of the stream (of [`Coverage::cycles`]).
    pub stream_cycles: u64,
    /// Wall time simulating, seconds.
    pub seconds: f64,
    /// Calls into the Verilated model and its evaluations.
    pub driver: Counters,
}

impl Coverage {
    /// Adds another's counts.
    pub fn add(&mut self, o: &Coverage) {
        self.cases += o.cases;
        self.planes += o.planes;
        self.packets += o.packets;
        self.confirmed_blinks += o.confirmed_blinks;
        self.bridged_dips += o.bridged_dips;
        self.unconfirmed_tracks += o.unconfirmed_tracks;
        self.slot_exhaustion += o.slot_exhaustion;
        self.output_fifo_full += o.output_fifo_full;
        self.records_lost += o.records_lost;
        self.refresh_collisions += o.refresh_collisions;
        self.edge_rois += o.edge_rois;
        self.cut_segments += o.cut_segments;
        self.truncated_blinks += o.truncated_blinks;
        self.empty_blinks += o.empty_blinks;
        self.start_records += o.start_records;
        self.blink_records += o.blink_records;
        self.dropped_records += o.dropped_records;
        self.overflow_records += o.overflow_records;
        self.end_records += o.end_records;
        self.flag_edge += o.flag_edge;
        self.flag_masked += o.flag_masked;
        self.flag_truncated += o.flag_truncated;
        self.flag_continuation += o.flag_continuation;
        self.flag_preroll_clipped += o.flag_preroll_clipped;
        self.lmax_cuts += o.lmax_cuts;
        self.empty_continued += o.empty_continued;
        self.empty_continuations += o.empty_continuations;
        self.continued_at_last_plane += o.continued_at_last_plane;
        self.seq_wraps += o.seq_wraps;
        self.cycles += o.cycles;
        self.stream_cycles += o.stream_cycles;
        self.seconds += o.seconds;
        self.driver.add(&o.driver);
    }
}

impl Coverage {
    /// Clocks per bit-plane from START to the stream's end (W·H/P when the
    /// source and the pipeline sustain a word of P pixels every clock).
    pub fn clocks_per_plane(&self) -> f64 {
        self.stream_cycles as f64 / self.planes.max(1) as f64
    }

    /// Simulated clock cycles per wall-clock second, millions.
    pub fn mcycles_per_second(&self) -> f64 {
        self.cycles as f64 / self.seconds.max(1e-9) / 1e6
    }
}

impl std::fmt::Display for Coverage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cases {} planes {} packets {} | confirmed blinks {} bridged dips {} unconfirmed tracks {} \
             slot exhaustion {} output FIFO full {} (records lost {}) DDR2 refresh collisions {} edge ROIs {} \
             cuts {} truncated {} empty {} | delivered: StreamStart {} Blink {} Dropped {} Overflow {} StreamEnd {}; \
             EDGE {} MASKED {} TRUNCATED {} CONTINUATION {} PREROLL_CLIPPED {} L_max cuts {} empty continued {} \
             empty continuations {} continued at the last plane {} sequence wraps {} | {} cycles in {:.2} s ({:.2} M cycles/s; per clock {:.2} shim calls, {:.2} evals, {:.2} input-combinational passes)",
            self.cases,
            self.planes,
            self.packets,
            self.confirmed_blinks,
            self.bridged_dips,
            self.unconfirmed_tracks,
            self.slot_exhaustion,
            self.output_fifo_full,
            self.records_lost,
            self.refresh_collisions,
            self.edge_rois,
            self.cut_segments,
            self.truncated_blinks,
            self.empty_blinks,
            self.start_records,
            self.blink_records,
            self.dropped_records,
            self.overflow_records,
            self.end_records,
            self.flag_edge,
            self.flag_masked,
            self.flag_truncated,
            self.flag_continuation,
            self.flag_preroll_clipped,
            self.lmax_cuts,
            self.empty_continued,
            self.empty_continuations,
            self.continued_at_last_plane,
            self.seq_wraps,
            self.cycles,
            self.seconds,
            self.cycles as f64 / self.seconds.max(1e-9) / 1e6,
            self.driver.ffi_calls as f64 / self.cycles.max(1) as f64,
            self.driver.evals as f64 / self.cycles.max(1) as f64,
            self.driver.ico_evals as f64 / self.cycles.max(1) as f64,
        )
    }
}

/// Counters of the model's records for a case.
pub(super) fn coverage_of(records: &[Record], case: &Case) -> Coverage {
    let mut c = Coverage {
        cases: 1,
        planes: case.planes.len() as u64,
        packets: records.len() as u64,
        ..Default::default()
    };
    for r in records {
        match r {
            Record::Blink(b) => {
                c.confirmed_blinks += 1;
                if b.flags & flags::EDGE != 0 {
                    c.edge_rois += 1;
                }
                if b.flags & flags::TRUNCATED != 0 {
                    c.truncated_blinks += 1;
                }
                if b.planes_summed == 0 {
                    c.empty_blinks += 1;
                }
            }
            Record::End(e) => {
                c.bridged_dips += e.bridged_dips;
                c.unconfirmed_tracks += e.unconfirmed;
                c.slot_exhaustion += e.dropped_candidates;
                c.cut_segments += e.cut_segments;
            }
            _ => {}
        }
    }
    c
}

/// Counters of what the gateware delivered: its packets (split and decoded
/// by [`split_packets`]; the `delivered` fields of [`Coverage`]).
pub(super) fn delivered_coverage(packets: &[Framed]) -> Coverage {
    let mut c = Coverage::default();
    // Sequence numbers unwrapped: each packet's number (an Overflow's
    // range) follows the previous one's end.
    let (mut first, mut end) = (None::<u64>, 0u64);
    for p in packets {
        let len = match &p.record {
            Record::Overflow(o) => o.count as u64,
            _ => 1,
        };
        let at = match first {
            None => {
                first = Some(p.seq as u64);
                p.seq as u64
            }
            Some(_) => end + (p.seq.wrapping_sub(end as u32)) as u64,
        };
        end = at + len;
        match &p.record {
            Record::Start(_) => c.start_records += 1,
            Record::Dropped(_) => c.dropped_records += 1,
            Record::Overflow(_) => c.overflow_records += 1,
            Record::End(_) => c.end_records += 1,
            Record::Blink(b) => {
                c.blink_records += 1;
                let has = |f: u8| (b.flags & f != 0) as u64;
                c.flag_edge += has(flags::EDGE);
                c.flag_masked += has(flags::MASKED);
                c.flag_truncated += has(flags::TRUNCATED);
                c.flag_continuation += has(flags::CONTINUATION);
                c.flag_preroll_clipped += has(flags::PREROLL_CLIPPED);
                c.lmax_cuts += has(flags::CUT);
                let empty = (b.planes_summed == 0) as u64;
                c.empty_continued += empty * has(flags::CUT);
                c.empty_continuations += empty * has(flags::CONTINUATION);
                if b.has(flags::CONTINUATION)
                    && b.has(flags::TRUNCATED)
                    && b.t_drop + 1 == b.t_cross
                {
                    c.continued_at_last_plane += 1;
                }
            }
        }
    }
    if let Some(f) = first {
        c.seq_wraps = (end.max(f + 1) - 1) / (1 << 32) - f / (1 << 32);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::compare::tests::{encode_stream, stream};
    use crate::harness::split_packets;
    use smartagg_model::packet::{encode_record, Encoder};
    use smartagg_model::record::OverflowRecord;

    #[test]
    fn delivered_coverage_counts_records_flags_and_wraps() {
        let (records, _) = stream();
        let mut bytes = Vec::new();
        let mut enc = Encoder::starting_at(u32::MAX - 2);
        for r in &records {
            enc.push(r, &mut bytes).unwrap();
        }
        let packets = split_packets(&bytes).unwrap();
        let c = delivered_coverage(&packets);
        assert_eq!((c.start_records, c.end_records, c.seq_wraps), (1, 1, 1));
        assert_eq!(
            c.blink_records as usize,
            records
                .iter()
                .filter(|r| matches!(r, Record::Blink(_)))
                .count()
        );
        let plain = delivered_coverage(&split_packets(&want_of(&records)).unwrap());
        assert_eq!(plain.seq_wraps, 0);
        // An Overflow whose range crosses the wrap.
        let mut ovf = Vec::new();
        encode_record(&records[0], u32::MAX - 1, &mut ovf).unwrap();
        let o = Record::Overflow(OverflowRecord {
            first_seq: u32::MAX,
            count: 3,
        });
        encode_record(&o, u32::MAX, &mut ovf).unwrap();
        encode_record(records.last().unwrap(), 2, &mut ovf).unwrap();
        let c = delivered_coverage(&split_packets(&ovf).unwrap());
        assert_eq!((c.overflow_records, c.seq_wraps), (1, 1));
    }

    fn want_of(records: &[Record]) -> Vec<u8> {
        encode_stream(records)
    }
}
