//! Port bundles (`#[derive(LogicInterface)]`): groups of ports that travel
//! together from block to block, declared once. A bundle is passed into a
//! sub-block whole (`link`); between siblings the parent assigns it field
//! by field in its own process: the bundles declare no `#[join]` mate, so
//! rust-hdl's `join` does not exist for them. (A join writes a process per
//! field in the Verilog, which Verilator evaluates on its own: joined, the
//! record bundle made the co-simulation 0.95× as fast.) Each side of a
//! connection has its own bundle, the same fields in the other direction.
//! In Verilog each field is a port named `bundle$field`.
//!
//! * [`StreamSettings`] / [`StreamSettingsOut`]: the runtime registers that
//!   [`crate::stream_control::StreamControl`] latches at START and the
//!   StreamStart record reports (`model/PACKETS.md` §3.1), from stream
//!   control through the back half to the packetiser's prefix;
//! * [`TrackerTotals`] / [`TrackerTotalsOut`]: the blink tracker's five
//!   StreamEnd totals (§3.4), from its counters to the packetiser's prefix;
//! * [`RecordPushOut`] / [`RecordPush`]: a record descriptor pushed by the
//!   blink tracker (from its record port) into the record queue, and the
//!   queue's room;
//! * [`RecordHead`]: the record at the head of the record queue, with the
//!   fields the finisher derives, as the packetiser takes it;
//! * [`RuntimeRegisters`]: the registers the host writes before START
//!   (`smartagg_model::registers`), from the XEM6310 core through the pipeline
//!   to stream control, which checks and latches them;
//! * [`McbPort`] / [`McbMemory`]: one MCB user port of the Spartan-6
//!   memory controller (Xilinx UG388), the delay line's side (from the
//!   DDR2 delay line through the pipeline and the XEM6310 core to the top,
//!   which wires it to the MIG core) and the memory's (the MIG core's
//!   wrapper [`crate::mig_ddr2::MigDdr2`], its parked stand-in and the
//!   behavioural model of the tests,
//!   [`crate::testbench::mcb_model::McbModel`]);
//! * [`PlaneWord`] / [`PlaneWordOut`]: a word of the bit-plane stream as
//!   stream control frames it (a source word, or a word of a drain or the
//!   flush plane), through the hot-pixel mask into the delay line;
//! * [`DelayedWord`] / [`DelayedWordOut`]: the delay line's word, `B_t`
//!   beside `B_{t−N}`, numbered, with its masked pixels, into the front
//!   half (the rolling count) and the back half (the ROI sums);
//! * [`CandidateWord`] / [`CandidateWordOut`]: the front half's word, its
//!   pixels above T_hold and its candidates, into the back half (the
//!   tracker's FIFO).
//!
//! A bundle that stays inside one stage is declared beside the block that
//! drives it: [`WalkedSlot`](crate::blink_tracker::WalkedSlot), the slot
//! the tracker's walk holds in W2 and what the walk does to it, from the
//! walk stages through the walk pipeline to the tracker.

use rust_hdl::prelude::*;

/// The stream's settings, latched at START (inputs). `NW`: bits of N.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct StreamSettings<const NW: usize> {
    /// N, the rolling window in planes.
    pub n_window: Signal<In, Bits<NW>>,
    /// T_int, the opening threshold.
    pub threshold: Signal<In, Bits<32>>,
    /// T_hold, the hold threshold.
    pub threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM (≤ N − 1, so NW bits hold it).
    pub end_trim: Signal<In, Bits<NW>>,
    /// L_min.
    pub l_min: Signal<In, Bits<32>>,
    /// L_max.
    pub l_max: Signal<In, Bits<32>>,
    /// The plane period, ns.
    pub plane_period: Signal<In, Bits<32>>,
    /// Masked pixels (0 without MASK_ENABLE).
    pub masked_pixels: Signal<In, Bits<32>>,
}

/// The stream's settings, latched at START (outputs of stream control).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct StreamSettingsOut<const NW: usize> {
    /// N.
    pub n_window: Signal<Out, Bits<NW>>,
    /// T_int.
    pub threshold: Signal<Out, Bits<32>>,
    /// T_hold.
    pub threshold_hold: Signal<Out, Bits<32>>,
    /// END_TRIM.
    pub end_trim: Signal<Out, Bits<NW>>,
    /// L_min.
    pub l_min: Signal<Out, Bits<32>>,
    /// L_max.
    pub l_max: Signal<Out, Bits<32>>,
    /// The plane period, ns.
    pub plane_period: Signal<Out, Bits<32>>,
    /// Masked pixels.
    pub masked_pixels: Signal<Out, Bits<32>>,
}

/// The tracker's StreamEnd totals, 64 bits each (inputs).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct TrackerTotals {
    /// Blink records emitted (lost ones included).
    pub blinks: Signal<In, Bits<64>>,
    /// Tracks that ended unconfirmed.
    pub unconfirmed: Signal<In, Bits<64>>,
    /// Candidates dropped for want of a slot.
    pub dropped: Signal<In, Bits<64>>,
    /// Single-plane dips bridged.
    pub bridged: Signal<In, Bits<64>>,
    /// Segments cut at L_max.
    pub cuts: Signal<In, Bits<64>>,
}

/// The tracker's StreamEnd totals (outputs of its counters).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct TrackerTotalsOut {
    /// Blink records emitted.
    pub blinks: Signal<Out, Bits<64>>,
    /// Tracks that ended unconfirmed.
    pub unconfirmed: Signal<Out, Bits<64>>,
    /// Candidates dropped.
    pub dropped: Signal<Out, Bits<64>>,
    /// Dips bridged.
    pub bridged: Signal<Out, Bits<64>>,
    /// Segments cut.
    pub cuts: Signal<Out, Bits<64>>,
}

/// The record at the head of the record queue, as the packetiser takes it
/// (inputs). `BW`: bank bits.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct RecordHead<const BW: usize> {
    /// A record is at the head of the queue (held until the packetiser
    /// pops it).
    pub valid: Signal<In, Bit>,
    /// Its kind ([`crate::blink_tracker::record_kind`]).
    pub kind: Signal<In, Bits<2>>,
    /// Records lost just before it.
    pub lost: Signal<In, Bits<32>>,
    /// Blink: slot.
    pub slot: Signal<In, Bits<8>>,
    /// Blink: flags (MASKED is added from the counter rows).
    pub flags: Signal<In, Bits<8>>,
    /// Blink: anchor column; Dropped: first column.
    pub ax: Signal<In, Bits<16>>,
    /// Blink: anchor row; Dropped: first row.
    pub ay: Signal<In, Bits<16>>,
    /// Blink: t_cross; Dropped: plane.
    pub t0: Signal<In, Bits<48>>,
    /// Blink: t_drop; Dropped: count.
    pub t1: Signal<In, Bits<48>>,
    /// Blink: t_s (two's complement, 48 bits).
    pub ts: Signal<In, Bits<48>>,
    /// Blink: t_e.
    pub te: Signal<In, Bits<48>>,
    /// Blink: planes summed.
    pub planes: Signal<In, Bits<32>>,
    /// Blink: counter bank.
    pub bank: Signal<In, Bits<BW>>,
    /// Blink: its counts are final.
    pub ready: Signal<In, Bit>,
}

/// A record descriptor pushed by the blink tracker into the record queue
/// (the tracker's side: the descriptor out, the queue's room in). `BW`:
/// bank bits.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct RecordPushOut<const BW: usize> {
    /// The queue accepts a push (it holds fewer than Q records).
    pub room: Signal<In, Bit>,
    /// Push the descriptor (only with `room`).
    pub push: Signal<Out, Bit>,
    /// Its kind ([`crate::blink_tracker::record_kind`]).
    pub kind: Signal<Out, Bits<2>>,
    /// Records lost (queue full) just before this one.
    pub lost: Signal<Out, Bits<32>>,
    /// Blink: slot.
    pub slot: Signal<Out, Bits<8>>,
    /// Blink: CUT, CONTINUATION, TRUNCATED flag bits.
    pub flags: Signal<Out, Bits<8>>,
    /// Blink: anchor column; Dropped: first column.
    pub ax: Signal<Out, Bits<16>>,
    /// Blink: anchor row; Dropped: first row.
    pub ay: Signal<Out, Bits<16>>,
    /// Blink: t_cross; Dropped: the plane.
    pub t0: Signal<Out, Bits<48>>,
    /// Blink: t_drop; Dropped: the count.
    pub t1: Signal<Out, Bits<48>>,
    /// Blink: its counts are final once the ROI aggregator has swept this
    /// plane.
    pub tag: Signal<Out, Bits<48>>,
    /// Blink: the counter bank holding its ROI.
    pub bank: Signal<Out, Bits<BW>>,
}

/// A record descriptor pushed into the record queue (the queue's side).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct RecordPush<const BW: usize> {
    /// Fewer than Q records held.
    pub room: Signal<Out, Bit>,
    /// Push the descriptor.
    pub push: Signal<In, Bit>,
    /// Kind.
    pub kind: Signal<In, Bits<2>>,
    /// Records lost before it.
    pub lost: Signal<In, Bits<32>>,
    /// Slot.
    pub slot: Signal<In, Bits<8>>,
    /// Tracker flags.
    pub flags: Signal<In, Bits<8>>,
    /// Column.
    pub ax: Signal<In, Bits<16>>,
    /// Row.
    pub ay: Signal<In, Bits<16>>,
    /// t_cross / plane.
    pub t0: Signal<In, Bits<48>>,
    /// t_drop / count.
    pub t1: Signal<In, Bits<48>>,
    /// Plane after whose sweep the counts are final.
    pub tag: Signal<In, Bits<48>>,
    /// Bank.
    pub bank: Signal<In, Bits<BW>>,
}

/// The runtime registers as the host wrote them (inputs), checked and
/// latched by stream control at START.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct RuntimeRegisters {
    /// N.
    pub n: Signal<In, Bits<32>>,
    /// T_int.
    pub threshold: Signal<In, Bits<32>>,
    /// T_hold.
    pub threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM.
    pub end_trim: Signal<In, Bits<32>>,
    /// L_min.
    pub l_min: Signal<In, Bits<32>>,
    /// L_max.
    pub l_max: Signal<In, Bits<32>>,
    /// The plane period, ns.
    pub period: Signal<In, Bits<32>>,
    /// The masked-pixel count.
    pub masked: Signal<In, Bits<32>>,
    /// MASK_ENABLE.
    pub mask_enable: Signal<In, Bit>,
}

/// One 32-bit bidirectional MCB user port (Xilinx UG388), the side that
/// issues the commands: the DDR2 delay line's, and every block between it
/// and the top. The port's clock is the block's.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct McbPort {
    /// The memory has calibrated.
    pub calib_done: Signal<In, Bit>,
    /// Command enable.
    pub cmd_en: Signal<Out, Bit>,
    /// Instruction: 000 write, 001 read.
    pub cmd_instr: Signal<Out, Bits<3>>,
    /// Burst length − 1.
    pub cmd_bl: Signal<Out, Bits<6>>,
    /// Byte address.
    pub cmd_addr: Signal<Out, Bits<30>>,
    /// Command FIFO full.
    pub cmd_full: Signal<In, Bit>,
    /// Write data enable.
    pub wr_en: Signal<Out, Bit>,
    /// Write byte mask (0: write every byte).
    pub wr_mask: Signal<Out, Bits<4>>,
    /// Write data.
    pub wr_data: Signal<Out, Bits<32>>,
    /// Write data FIFO full.
    pub wr_full: Signal<In, Bit>,
    /// Take a read word.
    pub rd_en: Signal<Out, Bit>,
    /// The head read word.
    pub rd_data: Signal<In, Bits<32>>,
    /// No read word.
    pub rd_empty: Signal<In, Bit>,
}

/// One MCB user port, the memory's side (the same fields as [`McbPort`],
/// the other way).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct McbMemory {
    /// Calibration done.
    pub calib_done: Signal<Out, Bit>,
    /// Command enable.
    pub cmd_en: Signal<In, Bit>,
    /// Instruction.
    pub cmd_instr: Signal<In, Bits<3>>,
    /// Burst length − 1.
    pub cmd_bl: Signal<In, Bits<6>>,
    /// Byte address.
    pub cmd_addr: Signal<In, Bits<30>>,
    /// Command FIFO full.
    pub cmd_full: Signal<Out, Bit>,
    /// Write data enable.
    pub wr_en: Signal<In, Bit>,
    /// Write byte mask.
    pub wr_mask: Signal<In, Bits<4>>,
    /// Write data.
    pub wr_data: Signal<In, Bits<32>>,
    /// Write data FIFO full.
    pub wr_full: Signal<Out, Bit>,
    /// Take a read word.
    pub rd_en: Signal<In, Bit>,
    /// The head read word.
    pub rd_data: Signal<Out, Bits<32>>,
    /// No read word.
    pub rd_empty: Signal<Out, Bit>,
}

/// A word of the bit-plane stream as stream control frames it (inputs of
/// the hot-pixel mask and the delay line). `P`: pixels per word.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct PlaneWord<const P: usize> {
    /// A word is present.
    pub valid: Signal<In, Bit>,
    /// First word of a plane.
    pub sop: Signal<In, Bit>,
    /// Word of a flush plane (not stored in the delay line).
    pub flush: Signal<In, Bit>,
    /// Word of a drain plane (its live bits are 0).
    pub drain: Signal<In, Bit>,
    /// `B_t`, pixel i of the word in bit i.
    pub live: Signal<In, Bits<P>>,
}

/// A word of the bit-plane stream (outputs of stream control and of the
/// hot-pixel mask).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct PlaneWordOut<const P: usize> {
    /// A word is present.
    pub valid: Signal<Out, Bit>,
    /// First word of a plane.
    pub sop: Signal<Out, Bit>,
    /// Word of a flush plane.
    pub flush: Signal<Out, Bit>,
    /// Word of a drain plane.
    pub drain: Signal<Out, Bit>,
    /// `B_t`.
    pub live: Signal<Out, Bits<P>>,
}

/// A word out of the delay line: the live word `B_t` beside the word of
/// the same pixels N planes ago, `B_{t−N}`, numbered (inputs of the front
/// half, for the rolling count, and of the back half, for the ROI sums).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct DelayedWord<const P: usize> {
    /// A word is present.
    pub valid: Signal<In, Bit>,
    /// Word of a flush plane (or of a drain plane: see `drain`).
    pub flush: Signal<In, Bit>,
    /// Word of a drain plane: flush for the rolling count, a plane for the
    /// ROI sums (its `B_{t−N}` still leaves open sums).
    pub drain: Signal<In, Bit>,
    /// Word column (pixel i of the word is at x·P + i).
    pub x: Signal<In, Bits<16>>,
    /// Row.
    pub y: Signal<In, Bits<16>>,
    /// Word index within the plane.
    pub idx: Signal<In, Bits<32>>,
    /// `B_t`.
    pub live: Signal<In, Bits<P>>,
    /// `B_{t−N}` (zero for t < N and for flush words).
    pub delayed: Signal<In, Bits<P>>,
    /// The bits carried along with the word: its masked pixels.
    pub side: Signal<In, Bits<P>>,
}

/// A word out of the delay line (outputs of [`crate::delay_line::DelayLine`]
/// and [`crate::delay_line_ddr::DelayLineDdr`]).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct DelayedWordOut<const P: usize> {
    /// A word is present.
    pub valid: Signal<Out, Bit>,
    /// Word of a flush or drain plane.
    pub flush: Signal<Out, Bit>,
    /// Word of a drain plane.
    pub drain: Signal<Out, Bit>,
    /// Word column.
    pub x: Signal<Out, Bits<16>>,
    /// Row.
    pub y: Signal<Out, Bits<16>>,
    /// Word index within the plane.
    pub idx: Signal<Out, Bits<32>>,
    /// `B_t`.
    pub live: Signal<Out, Bits<P>>,
    /// `B_{t−N}`.
    pub delayed: Signal<Out, Bits<P>>,
    /// Masked pixels.
    pub side: Signal<Out, Bits<P>>,
}

/// A word of the front half's result: which pixels are above T_hold and
/// which are candidates (H ≥ T_int and a maximum of their 3×3
/// neighbourhood, [`crate::candidates`]), pixel i in bit i
/// (inputs of the back half).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct CandidateWord<const P: usize> {
    /// A word is present.
    pub valid: Signal<In, Bit>,
    /// Word of a flush plane.
    pub flush: Signal<In, Bit>,
    /// Word column.
    pub x: Signal<In, Bits<16>>,
    /// Row.
    pub y: Signal<In, Bits<16>>,
    /// `H ≥ T_hold` per pixel.
    pub above: Signal<In, Bits<P>>,
    /// Candidate per pixel.
    pub candidate: Signal<In, Bits<P>>,
}

/// A word of the front half's result (outputs of
/// [`crate::front_half::FrontHalf`]).
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct CandidateWordOut<const P: usize> {
    /// A word is present.
    pub valid: Signal<Out, Bit>,
    /// Word of a flush plane.
    pub flush: Signal<Out, Bit>,
    /// Word column.
    pub x: Signal<Out, Bits<16>>,
    /// Row.
    pub y: Signal<Out, Bits<16>>,
    /// `H ≥ T_hold` per pixel.
    pub above: Signal<Out, Bits<P>>,
    /// Candidate per pixel.
    pub candidate: Signal<Out, Bits<P>>,
}
