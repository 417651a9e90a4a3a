//! A packet's prefix as `model/PACKETS.md` lays it out, a byte lane each
//! (combinational): the header — magic "SA", the format version, the type,
//! the sequence number, the payload length — and the record kind's fixed
//! payload, as [`smartagg_model::packet::encode_record`] writes them:
//! * StreamStart: the generation's constant bytes (field, association
//!   radius, slots, ROI side, kernel) with the runtime registers (N, T_int,
//!   L_min, L_max, plane period, masked pixels, T_hold, END_TRIM) in their
//!   places;
//! * Blink: slot, flags (with MASKED from the counter rows), anchor,
//!   t_cross, t_drop, t_s, t_e, planes summed, ROI side, then the count
//!   block's head (the base as a varint, and k);
//! * Dropped: plane, count, first column and row;
//! * StreamEnd: the six counters.
//!
//! Beside it, the Overflow packet's whole prefix: its header carries the
//! first lost number and length 8, its payload that number and the count.
//!
//! The lanes are computed only when `enable` (a packet starts), 0 on other
//! clocks: free in hardware, and a simulator skips the lanes' tree then.
//! The payload length comes in (a Blink's depends on its codes). Lanes past
//! a kind's prefix are 0.

use crate::bundles::{StreamSettings, TrackerTotals};
use crate::config::BackHalfConfig;
use crate::packetiser::HEAD_BYTES;
use crate::stream::lanes;
use rust_hdl::prelude::*;
use smartagg_model::packet::VERSION as PACKET_VERSION;

/// The prefixes of every record kind and of the Overflow packet. `NW`:
/// bits of N.
#[derive(LogicBlock)]
pub struct RecordPrefix<const NW: usize> {
    /// A packet starts: compute the lanes (else all 0).
    pub enable: Signal<In, Bit>,
    /// The record kind ([`crate::blink_tracker::record_kind`]).
    pub kind: Signal<In, Bits<2>>,
    /// The record's sequence number.
    pub seq: Signal<In, Bits<32>>,
    /// The record's payload length, bytes.
    pub payload_len: Signal<In, Bits<16>>,
    /// Blink: slot.
    pub slot: Signal<In, Bits<8>>,
    /// Blink: flags, without MASKED.
    pub flags: Signal<In, Bits<8>>,
    /// Blink: an ROI row holds a masked pixel (the MASKED flag).
    pub masked: Signal<In, Bit>,
    /// Blink: anchor column; Dropped: first column.
    pub ax: Signal<In, Bits<16>>,
    /// Blink: anchor row; Dropped: first row.
    pub ay: Signal<In, Bits<16>>,
    /// Blink: t_cross; Dropped: plane.
    pub t0: Signal<In, Bits<48>>,
    /// Blink: t_drop; Dropped: count (its low 32 bits).
    pub t1: Signal<In, Bits<48>>,
    /// Blink: t_s (two's complement, 48 bits).
    pub ts: Signal<In, Bits<48>>,
    /// Blink: t_e.
    pub te: Signal<In, Bits<48>>,
    /// Blink: planes summed.
    pub planes: Signal<In, Bits<32>>,
    /// Blink: the count block's head ([`super::CountBlockHead`]).
    pub head: Vec<Signal<In, Bits<8>>>,
    /// StreamStart: the stream's settings.
    pub settings: StreamSettings<NW>,
    /// StreamEnd: planes.
    pub c_planes: Signal<In, Bits<64>>,
    /// StreamEnd: the tracker's totals.
    pub totals: TrackerTotals,
    /// Overflow: the first lost sequence number.
    pub lost_first: Signal<In, Bits<32>>,
    /// Overflow: records lost.
    pub lost_count: Signal<In, Bits<32>>,
    /// The record's prefix.
    pub record: Vec<Signal<Out, Bits<8>>>,
    /// The Overflow packet's prefix.
    pub overflow: Vec<Signal<Out, Bits<8>>>,
    rec: Vec<Signal<Local, Bits<8>>>,
    ovf: Vec<Signal<Local, Bits<8>>>,
    type_code: Signal<Local, Bits<8>>,
    /// (Verilog cannot slice an expression: N widened into a signal first.)
    n16: Signal<Local, Bits<16>>,
    /// END_TRIM widened to its StreamStart field.
    trim32: Signal<Local, Bits<32>>,
    start_bytes: Vec<Constant<Bits<8>>>,
    /// The packet format version ([`PACKET_VERSION`]), every header's byte 2.
    version: Constant<Bits<8>>,
    roi_side: Constant<Bits<8>>,
    /// Lanes: bytes of the longest prefix.
    _pb: usize,
    /// Byte offsets in StreamStart of the plane period, masked pixels,
    /// T_hold and END_TRIM.
    _o_period: usize,
    _o_masked: usize,
    _o_hold: usize,
    _o_trim: usize,
}

impl<const NW: usize> RecordPrefix<NW> {
    /// The prefixes of a configuration, [`BackHalfConfig::prefix_bytes`]
    /// lanes.
    pub fn new(cfg: &BackHalfConfig) -> Self {
        let pb = cfg.prefix_bytes();
        let f = &cfg.front;
        let k = f.kernel.len();
        // The constant bytes of StreamStart: header (seq and the registers
        // are added at run time) and the generation parameters.
        let mut sb = vec![0u8; cfg.stream_start_bytes()];
        let start_payload = sb.len() - 10;
        sb[..4].copy_from_slice(&[0x53, 0x41, PACKET_VERSION, 0x01]);
        sb[8..10].copy_from_slice(&(start_payload as u16).to_le_bytes());
        sb[10..12].copy_from_slice(&(f.width as u16).to_le_bytes());
        sb[12..14].copy_from_slice(&(f.height as u16).to_le_bytes());
        sb[30] = cfg.r_assoc as u8;
        sb[31] = cfg.slots as u8;
        sb[32] = cfg.roi_size as u8;
        sb[33] = f.kernel_shift;
        sb[34] = k as u8;
        for (i, w) in f.kernel.iter().enumerate() {
            sb[35 + 2 * i..37 + 2 * i].copy_from_slice(&(*w as u16).to_le_bytes());
        }
        let c8 = |v: u64| Constant::new(v.to_bits());
        RecordPrefix {
            enable: Default::default(),
            kind: Default::default(),
            seq: Default::default(),
            payload_len: Default::default(),
            slot: Default::default(),
            flags: Default::default(),
            masked: Default::default(),
            ax: Default::default(),
            ay: Default::default(),
            t0: Default::default(),
            t1: Default::default(),
            ts: Default::default(),
            te: Default::default(),
            planes: Default::default(),
            head: lanes(HEAD_BYTES),
            settings: Default::default(),
            c_planes: Default::default(),
            totals: Default::default(),
            lost_first: Default::default(),
            lost_count: Default::default(),
            record: lanes(pb),
            overflow: lanes(pb),
            rec: lanes(pb),
            ovf: lanes(pb),
            type_code: Default::default(),
            n16: Default::default(),
            trim32: Default::default(),
            start_bytes: (0..pb)
                .map(|j| c8(sb.get(j).copied().unwrap_or(0) as u64))
                .collect(),
            version: c8(PACKET_VERSION as u64),
            roi_side: c8(cfg.roi_size as u64),
            _pb: pb,
            _o_period: 35 + 2 * k,
            _o_masked: 39 + 2 * k,
            _o_hold: 43 + 2 * k,
            _o_trim: 47 + 2 * k,
        }
    }
}

impl<const NW: usize> Logic for RecordPrefix<NW> {
    #[hdl_gen]
    fn update(&mut self) {
        for j in 0..self._pb {
            self.rec[j].next = 0.into();
            self.ovf[j].next = 0.into();
        }
        self.type_code.next = 1.into();
        match self.kind.val().index() {
            1 => {
                self.type_code.next = 2.into();
            }
            2 => {
                self.type_code.next = 3.into();
            }
            3 => {
                self.type_code.next = 4.into();
            }
            _ => {}
        }
        self.n16.next = bit_cast::<16, NW>(self.settings.n_window.val());
        self.trim32.next = bit_cast::<32, NW>(self.settings.end_trim.val());
        if self.enable.val() {
            // Header: magic "SA", version, type, sequence number, length.
            self.rec[0].next = 0x53.into();
            self.rec[1].next = 0x41.into();
            self.rec[2].next = self.version.val();
            self.rec[3].next = self.type_code.val();
            for b in 0..4 {
                self.rec[4 + b].next = self.seq.val().get_bits::<8>(8 * b);
            }
            for b in 0..2 {
                self.rec[8 + b].next = self.payload_len.val().get_bits::<8>(8 * b);
            }
            match self.kind.val().index() {
                1 => {
                    self.rec[10].next = self.slot.val();
                    self.rec[11].next =
                        self.flags.val() | (bit_cast::<8, 1>(self.masked.val().into()) << 1);
                    for b in 0..2 {
                        self.rec[12 + b].next = self.ax.val().get_bits::<8>(8 * b);
                        self.rec[14 + b].next = self.ay.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..6 {
                        self.rec[16 + b].next = self.t0.val().get_bits::<8>(8 * b);
                        self.rec[22 + b].next = self.t1.val().get_bits::<8>(8 * b);
                        self.rec[28 + b].next = self.ts.val().get_bits::<8>(8 * b);
                        self.rec[34 + b].next = self.te.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..4 {
                        self.rec[40 + b].next = self.planes.val().get_bits::<8>(8 * b);
                    }
                    self.rec[44].next = self.roi_side.val();
                    for b in 0..HEAD_BYTES {
                        self.rec[45 + b].next = self.head[b].val();
                    }
                }
                2 => {
                    for b in 0..6 {
                        self.rec[10 + b].next = self.t0.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..4 {
                        self.rec[16 + b].next = self.t1.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..2 {
                        self.rec[20 + b].next = self.ax.val().get_bits::<8>(8 * b);
                        self.rec[22 + b].next = self.ay.val().get_bits::<8>(8 * b);
                    }
                }
                3 => {
                    for b in 0..8 {
                        self.rec[10 + b].next = self.c_planes.val().get_bits::<8>(8 * b);
                        self.rec[18 + b].next = self.totals.blinks.val().get_bits::<8>(8 * b);
                        self.rec[26 + b].next = self.totals.unconfirmed.val().get_bits::<8>(8 * b);
                        self.rec[34 + b].next = self.totals.dropped.val().get_bits::<8>(8 * b);
                        self.rec[42 + b].next = self.totals.bridged.val().get_bits::<8>(8 * b);
                        self.rec[50 + b].next = self.totals.cuts.val().get_bits::<8>(8 * b);
                    }
                }
                _ => {
                    // StreamStart: the generation's constant bytes (field,
                    // kernel) with the runtime registers in their zero bytes.
                    for j in 10..self._pb {
                        self.rec[j].next = self.start_bytes[j].val();
                    }
                    for b in 0..2 {
                        self.rec[14 + b].next = self.n16.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..4 {
                        self.rec[18 + b].next = self.settings.threshold.val().get_bits::<8>(8 * b);
                        self.rec[22 + b].next = self.settings.l_min.val().get_bits::<8>(8 * b);
                        self.rec[26 + b].next = self.settings.l_max.val().get_bits::<8>(8 * b);
                    }
                    for o in self._o_period..(self._o_period + 1) {
                        for b in 0..4 {
                            self.rec[o + b].next =
                                self.settings.plane_period.val().get_bits::<8>(8 * b);
                        }
                    }
                    for o in self._o_masked..(self._o_masked + 1) {
                        for b in 0..4 {
                            self.rec[o + b].next =
                                self.settings.masked_pixels.val().get_bits::<8>(8 * b);
                        }
                    }
                    for o in self._o_hold..(self._o_hold + 1) {
                        for b in 0..4 {
                            self.rec[o + b].next =
                                self.settings.threshold_hold.val().get_bits::<8>(8 * b);
                        }
                    }
                    for o in self._o_trim..(self._o_trim + 1) {
                        for b in 0..4 {
                            self.rec[o + b].next = self.trim32.val().get_bits::<8>(8 * b);
                        }
                    }
                }
            }
            // Overflow: header (type 0x7F, the first lost number), length
            // 8, first lost number and count.
            self.ovf[0].next = 0x53.into();
            self.ovf[1].next = 0x41.into();
            self.ovf[2].next = self.version.val();
            self.ovf[3].next = 0x7F.into();
            self.ovf[8].next = 8.into();
            for b in 0..4 {
                self.ovf[4 + b].next = self.lost_first.val().get_bits::<8>(8 * b);
                self.ovf[10 + b].next = self.lost_first.val().get_bits::<8>(8 * b);
                self.ovf[14 + b].next = self.lost_count.val().get_bits::<8>(8 * b);
            }
        }
        for j in 0..self._pb {
            self.record[j].next = self.rec[j].val();
            self.overflow[j].next = self.ovf[j].val();
        }
    }
}
