//! The records the pipeline emits: what a packet carries once decoded.
//!
//! The byte layout and the meaning of every field are defined in
//! `model/PACKETS.md` (§3, and §8 for which records exist and when); the
//! docs here summarise them. Plane indices count bit-planes from 0 at
//! stream start and are carried in 48 bits on the wire (890 years at 10 kHz).

use serde::{Deserialize, Serialize};

/// Largest plane index the packet format can carry (2⁴⁸ − 1).
pub const MAX_PLANE: u64 = (1 << 48) - 1;

/// Flag bits of a [`BlinkRecord`].
pub mod flags {
    /// Part of the ROI lies outside the sensor; those pixels count 0.
    pub const EDGE: u8 = 1 << 0;
    /// The ROI contains at least one masked (hot) pixel; those pixels count 0.
    pub const MASKED: u8 = 1 << 1;
    /// The blink was still on after `L_max` planes: this segment was cut and
    /// the next record of the same slot continues it.
    pub const CUT: u8 = 1 << 2;
    /// This segment continues a cut one: its summed planes start where the
    /// cut segment's ended (`t_cross − N`, PACKETS.md §8.6).
    pub const CONTINUATION: u8 = 1 << 3;
    /// The stream ended while the segment was live; `t_drop` is the last
    /// plane of the stream (with CONTINUATION, possibly `t_cross − 1`: the
    /// continuation of a cut at the last plane).
    pub const TRUNCATED: u8 = 1 << 4;
    /// `t_cross < N`: the first window, `t_cross − N …`, was clipped at plane 0.
    pub const PREROLL_CLIPPED: u8 = 1 << 5;
}

/// Parameters the pipeline ran with, sent first in every stream so the host
/// can interpret everything after it without any other file.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct StreamStart {
    /// Sensor width, pixels.
    pub width: u16,
    /// Sensor height, pixels.
    pub height: u16,
    /// Rolling window N, bit-planes.
    pub n_window: u32,
    /// Integer threshold T_int on H (kernel units, see [`crate::kernel`])
    /// that opens a track.
    pub threshold_int: u32,
    /// Integer threshold T_hold that holds an open track on (≤ T_int; equal
    /// to it for the one-threshold rule and in version-1 streams).
    pub threshold_hold: u32,
    /// Planes between a dropped segment's last summed plane and its `t_drop`
    /// ([`crate::config::PipelineConfig::end_trim`]); `None` in a version-1
    /// or 2 stream, whose segments summed the live range and a first
    /// segment's pre-roll (PACKETS.md §8.6).
    pub end_trim: Option<u32>,
    /// Planes a track must stay on to be confirmed (L_min).
    pub l_min: u32,
    /// Planes after which an on track is cut and restarted (L_max).
    pub l_max: u32,
    /// Association radius (Chebyshev, pixels).
    pub r_assoc: u8,
    /// Number of tracking slots M.
    pub slots: u8,
    /// ROI side R (odd), pixels.
    pub roi_size: u8,
    /// Kernel scale exponent a: the 1-D kernel sums to 2^a.
    pub kernel_shift: u8,
    /// The 1-D integer kernel k1 (odd length, symmetric).
    pub kernel: Vec<u16>,
    /// Bit-plane period, ns.
    pub plane_period_ns: u32,
    /// Number of masked (hot) pixels.
    pub masked_pixels: u32,
}

/// One confirmed blink (or one segment of a blink longer than L_max).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct BlinkRecord {
    /// Tracking slot that followed the blink.
    pub slot: u8,
    /// Flag bits, see [`flags`].
    pub flags: u8,
    /// Anchor column (the candidate that opened the track).
    pub anchor_x: u16,
    /// Anchor row.
    pub anchor_y: u16,
    /// First live plane: the plane at which the track opened (threshold
    /// crossed), or the plane after the cut for a continuation.
    pub t_cross: u64,
    /// Last live plane: the first of the two consecutive planes below
    /// T_hold, the cut plane (CUT), or the last plane of the stream
    /// (TRUNCATED). `t_cross − 1` for the continuation of a cut at the
    /// last plane (CONTINUATION | TRUNCATED).
    pub t_drop: u64,
    /// Estimated start of the blink: `t_cross − ⌊N/2⌋` (mid-window), or
    /// `t_cross` for a continuation segment. May be negative near stream start.
    pub t_s: i64,
    /// Estimated end of the blink: `t_drop − ⌊N/2⌋`, or `t_drop` for a cut or
    /// truncated segment. May be below `t_s`: a continuation that ends within
    /// ⌊N/2⌋ planes of its `t_cross`, and an empty segment.
    pub t_e: i64,
    /// Number of bit-planes summed into the ROI: the length of
    /// `[max(0, t_cross − N), last]`, `last = t_drop − end_trim` after a drop,
    /// `t_drop − N` after a cut, `t_drop` when truncated (0: an empty
    /// segment; see [`crate::record_check::summed_planes`], which also
    /// knows the rule of version-1 and 2 streams).
    pub planes_summed: u32,
    /// ROI side R; `counts` has R×R entries.
    pub roi_size: u8,
    /// Photon-detection counts, row-major, top-left pixel at
    /// (`anchor_x − R/2`, `anchor_y − R/2`).
    pub counts: Vec<u32>,
}

impl BlinkRecord {
    /// Column of the ROI's left edge (may be negative at the sensor edge).
    pub fn roi_x0(&self) -> i32 {
        self.anchor_x as i32 - (self.roi_size / 2) as i32
    }

    /// Row of the ROI's top edge (may be negative at the sensor edge).
    pub fn roi_y0(&self) -> i32 {
        self.anchor_y as i32 - (self.roi_size / 2) as i32
    }

    /// Whether a flag bit is set.
    pub fn has(&self, flag: u8) -> bool {
        self.flags & flag != 0
    }
}

/// Candidates that found no free tracking slot during one plane.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DroppedRecord {
    /// The plane.
    pub plane: u64,
    /// How many candidates were dropped in it.
    pub count: u32,
    /// Column of the first dropped candidate (raster order).
    pub first_x: u16,
    /// Row of the first dropped candidate.
    pub first_y: u16,
}

/// Totals sent when the stream is stopped.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct StreamEnd {
    /// Bit-planes processed.
    pub planes: u64,
    /// Blink records produced (segments included; records the device then
    /// lost included).
    pub blinks: u64,
    /// First segments that ended unconfirmed (before L_min planes) and
    /// emitted nothing.
    pub unconfirmed: u64,
    /// Candidates dropped for want of a free slot.
    pub dropped_candidates: u64,
    /// Single planes below threshold bridged inside a track.
    pub bridged_dips: u64,
    /// Segments cut at L_max.
    pub cut_segments: u64,
}

/// Emitted by the gateware only: records it numbered but lost, because its
/// record queue or its output FIFO was full. It carries no sequence number of
/// its own (see [`crate::packet`] and `model/PACKETS.md` §5).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct OverflowRecord {
    /// Sequence number of the first record lost.
    pub first_seq: u32,
    /// Number of consecutive records lost.
    pub count: u32,
}

/// Any record of the stream.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Record {
    /// Parameters, first in every stream.
    Start(StreamStart),
    /// One confirmed blink.
    Blink(BlinkRecord),
    /// Candidates dropped in one plane.
    Dropped(DroppedRecord),
    /// Totals at stream end.
    End(StreamEnd),
    /// Records lost on the device (record queue or output FIFO).
    Overflow(OverflowRecord),
}
