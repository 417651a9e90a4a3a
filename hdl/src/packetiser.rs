//! Stage 7 — packetiser: records become the bytes of `model/PACKETS.md`
//! exactly as [`smartagg_model::packet::encode_record`] writes them — header
//! (magic, version, type, sequence number, length), payload with the ROI
//! counts as one Rice-coded count block, CRC-32C — one byte per clock into
//! the output FIFO.
//!
//! **A Blink.** Its counts are read from the record's counter bank three
//! times, one a clock ([`CountStreamer`]; ROI rows off the sensor read 0).
//! Pass 1 finds the minimum `base` and ORs the rows' mask flags into
//! MASKED. Pass 2 sums each Rice parameter's code lengths, and Choose scans
//! the totals for the fewest bits ([`RiceChoice`], [`RiceLengths`]; no k
//! above RCW can win: [`rice_candidates`]). Pass 3 makes the codes in the
//! [`CodePipeline`]'s three registered stages — A the offset from the base
//! (also pass 2's input), B its quotient by 2^k, C the code ([`RiceCode`])
//! — and packs them MSB first into bytes ([`BitPacker`]). The base and k enter
//! the prefix as [`CountBlockHead`]'s bytes; the header's length is known
//! after pass 2 ([`PacketLength`]); the room check for the whole packet is
//! a register (Decide acts on its second clock).
//!
//! **Every packet** is its prefix — header and fixed payload, a byte lane
//! each, laid out by record kind in [`RecordPrefix`] — loaded into [`PrefixBytes`] once
//! and read out a byte a clock ([`PrefixCursor`]: "this byte is the
//! prefix's last" is a register), then a Blink's codes, then the CRC-32C
//! ([`PacketCrc`], to which [`Crc32cStep`] adds a byte a clock).
//!
//! **Sequence numbers and overflow** ([`SequenceNumbers`]). Every record but Overflow takes the
//! next number (from `seq_init` at stream start). A record the tracker could
//! not queue (its record queue full) arrives as `record.lost` on the next one and
//! is numbered and announced like a record the output FIFO dropped. Before emitting a record
//! the packetiser checks that the output FIFO has room for the whole packet
//! (and for an Overflow packet if records were lost); if not, the record is
//! dropped whole and counted. The next record that fits is preceded by one
//! Overflow record (first lost number, count), whose header carries the first
//! lost number and consumes none — the gateware stream is the model's with
//! records missing and every gap announced exactly. StreamStart and
//! StreamEnd are never dropped: they wait for room (nothing else is in
//! flight then).
//!
//! Each sub-block is a file in `packetiser/` with its own test in
//! `tests/packetiser_blocks.rs` (the record prefix in
//! `tests/packetiser_prefix.rs`, against the model's encoder; the sequence
//! numbers and the packet's lengths in `tests/packetiser_numbers.rs`; the
//! prefix cursor and the packet CRC in `tests/packetiser_bytes.rs`); the
//! state machine is the packetiser's own. Its settings, totals and head
//! record come in bundles ([`crate::bundles`]).
//!
//! **Outputs without transients.** A sub-block assigns each output once an
//! evaluation (a value with a default and an override is built in a local
//! first). rust-hdl writes a block as one `always @(*)` process, and an
//! event-driven simulator (Icarus) wakes a signal's readers on every
//! change, even one the writing process overwrites before it ends. The
//! packetiser gives its sub-blocks commands with a default and an
//! override and reads their outputs back: had an output a default and an
//! override too, the two processes would wake each other forever without
//! simulated time passing (the 4-state test hung so in the bit packer's
//! Codes state). Verilator and rust-hdl's simulation settle such loops.

use crate::bundles::{RecordHead, StreamSettings, TrackerTotals};
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::stream::lanes;
use rust_hdl::prelude::*;

mod bit_packer;
mod code_pipeline;
mod count_block_head;
mod count_streamer;
mod crc32c_step;
mod packet_crc;
mod packet_length;
mod prefix_bytes;
mod prefix_cursor;
mod record_prefix;
mod rice_choice;
mod rice_code;
mod rice_lengths;
mod sequence_numbers;

pub use bit_packer::BitPacker;
pub use code_pipeline::CodePipeline;
pub use count_block_head::{CountBlockHead, HEAD_BYTES};
pub use count_streamer::CountStreamer;
pub use crc32c_step::Crc32cStep;
pub use packet_crc::PacketCrc;
pub use packet_length::PacketLength;
pub use prefix_bytes::PrefixBytes;
pub use prefix_cursor::PrefixCursor;
pub use record_prefix::RecordPrefix;
pub use rice_choice::{rice_candidates, RiceChoice};
pub use rice_code::RiceCode;
pub use rice_lengths::RiceLengths;
pub use sequence_numbers::SequenceNumbers;

/// Packetiser states.
#[derive(Copy, Clone, Debug, PartialEq, LogicState)]
pub enum PacketState {
    /// Waiting for a record.
    Idle,
    /// Blink: waiting until its counts are final.
    Wait,
    /// Blink pass 1: minimum and mask flag.
    Pass1,
    /// Blink pass 2: code lengths for every k.
    Pass2,
    /// Blink: the best k.
    Choose,
    /// Room check: emit or drop.
    Decide,
    /// Header and payload bytes of the Overflow packet.
    Ovf,
    /// Header and fixed payload bytes of the record.
    Emit,
    /// Blink pass 3: the codes.
    Codes,
    /// The four CRC bytes.
    Crc,
    /// Return the bank, next sequence number.
    Finish,
}

/// The packetiser. `R` counts per ROI row come from the counter memory.
/// `RCW`: count bits; `CAW`: counter address bits; `BW`: bank bits; `NW`:
/// bits of N; `PW`: bits of the assembled header and fixed payload
/// (`8 ×` [`BackHalfConfig::prefix_bytes`]).
#[derive(LogicBlock)]
pub struct Packetiser<
    const RCW: usize,
    const CAW: usize,
    const BW: usize,
    const NW: usize,
    const PW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: sequence number `seq_init` next, nothing pending.
    pub restart: Signal<In, Bit>,
    /// First sequence number (0 in the pipeline; the vectors start later).
    pub seq_init: Signal<In, Bits<32>>,
    /// The stream's settings (StreamStart).
    pub settings: StreamSettings<NW>,
    /// StreamEnd: planes.
    pub c_planes: Signal<In, Bits<64>>,
    /// StreamEnd: the tracker's totals.
    pub totals: TrackerTotals,
    /// The record at the head of the queue (held until `r_pop`).
    pub record: RecordHead<BW>,
    /// Done with the head record.
    pub r_pop: Signal<Out, Bit>,
    /// Counter row read request.
    pub rd_req: Signal<Out, Bit>,
    /// Counter row address.
    pub rd_addr: Signal<Out, Bits<CAW>>,
    /// The request is taken; the row follows next clock.
    pub rd_grant: Signal<In, Bit>,
    /// The counts of the row.
    pub rd_counts: Vec<Signal<In, Bits<RCW>>>,
    /// The row's mask flag.
    pub rd_masked: Signal<In, Bit>,
    /// Return a bank to the free list.
    pub fb_ret: Signal<Out, Bit>,
    /// The bank returned.
    pub fb_ret_bank: Signal<Out, Bits<BW>>,
    /// Free bytes in the output FIFO.
    pub fifo_free: Signal<In, Bits<16>>,
    /// A byte is emitted.
    pub out_valid: Signal<Out, Bit>,
    /// The byte.
    pub out_byte: Signal<Out, Bits<8>>,
    /// Nothing in flight and no record waiting.
    pub idle: Signal<Out, Bit>,
    /// Records were lost since stream start (sticky; Overflow records tell how many).
    pub overflowed: Signal<Out, Bit>,
    state: DFF<PacketState>,
    /// The next sequence number and the records lost, pending announcement.
    seqs: SequenceNumbers,
    in_ovf: DFF<Bit>,
    /// The ROI's counts, one a clock.
    counts: CountStreamer<RCW, CAW, BW>,
    base: DFF<Bits<RCW>>,
    masked: DFF<Bit>,
    /// Pass 2 and Choose: the k with the fewest code bits.
    choice: RiceChoice<RCW>,
    // Emission.
    /// The header and fixed payload of the record and of an Overflow packet.
    record_prefix: RecordPrefix<NW>,
    /// The packet's prefix bytes, loaded once a packet (see `prefix_load`)
    /// and read out a byte a clock.
    prefix: PrefixBytes,
    /// Pass 3 (and pass 2's offsets): counts to Rice codes.
    code_stages: CodePipeline<RCW>,
    /// The count block's base (LEB128) and k, for the prefix.
    head: CountBlockHead<RCW>,
    /// The prefix's byte of this clock, and whether it is the last.
    cursor: PrefixCursor,
    /// `record.planes` a clock late: the finisher's arithmetic ends in a register.
    /// It is read when a Blink's prefix loads (Decide's second clock on, or
    /// Crc after an Overflow), when the head record has been the same for
    /// clocks (it changes only after Finish's pop).
    planes_r: DFF<Bits<32>>,
    /// The packet's CRC-32C: its bytes added, then its own four.
    crc: PacketCrc,
    /// Pass 3: codes in, bytes out.
    packer: BitPacker,
    /// The packet's lengths by kind and the registered room check.
    lengths: PacketLength,
    // Combinational.
    is_blink: Signal<Local, Bit>,
    take: Signal<Local, Bit>,
    /// A packet starts: the prefix registers load (the Overflow packet's
    /// prefix, of 18 bytes, if `prefix_ovf`, else the record's), the cursor
    /// is at its first byte, the CRC register all ones.
    prefix_load: Signal<Local, Bit>,
    prefix_ovf: Signal<Local, Bit>,
    the_byte: Signal<Local, Bits<8>>,
    /// A state that sends bytes.
    emitting: Signal<Local, Bit>,
    bk: Signal<Local, Bits<8>>,
    in_codes: Signal<Local, Bit>,
    in_pass2: Signal<Local, Bit>,
    // Constants.
    /// Covers every k scanned ([`rice_candidates`]; a power of two minus one).
    k_mask: Constant<Bits<8>>,
    all_ones: Constant<Bits<RCW>>,
    /// ROI side R.
    _r: usize,
    /// Bytes of the assembled header and fixed payload (PW / 8).
    _pb: usize,
}

impl<const RCW: usize, const CAW: usize, const BW: usize, const NW: usize, const PW: usize>
    Packetiser<RCW, CAW, BW, NW, PW>
{
    /// The packetiser of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        let f = &cfg.front;
        GatewareConfig::check_width("Packetiser", "RCW", RCW, cfg.roi_count_bits())?;
        GatewareConfig::check_width("Packetiser", "CAW", CAW, cfg.counter_addr_bits())?;
        GatewareConfig::check_width("Packetiser", "BW", BW, cfg.bank_bits())?;
        GatewareConfig::check_width("Packetiser", "NW", NW, f.count_bits())?;
        GatewareConfig::check_width("Packetiser", "PW", PW, 8 * cfg.prefix_bytes())?;
        let r = cfg.roi_size;
        let kn = rice_candidates(RCW);
        let c8 = |v: u64| Constant::new(v.to_bits());
        Ok(Packetiser {
            clock: Default::default(),
            restart: Default::default(),
            seq_init: Default::default(),
            settings: Default::default(),
            c_planes: Default::default(),
            totals: Default::default(),
            record: Default::default(),
            r_pop: Default::default(),
            rd_req: Default::default(),
            rd_addr: Default::default(),
            rd_grant: Default::default(),
            rd_counts: lanes(r),
            rd_masked: Default::default(),
            fb_ret: Default::default(),
            fb_ret_bank: Default::default(),
            fifo_free: Default::default(),
            out_valid: Default::default(),
            out_byte: Default::default(),
            idle: Default::default(),
            overflowed: Default::default(),
            state: Default::default(),
            seqs: Default::default(),
            in_ovf: Default::default(),
            counts: CountStreamer::new(cfg),
            base: Default::default(),
            masked: Default::default(),
            choice: RiceChoice::new(kn, r),
            record_prefix: RecordPrefix::new(cfg),
            prefix: PrefixBytes::new(PW / 8),
            code_stages: Default::default(),
            head: Default::default(),
            cursor: Default::default(),
            planes_r: Default::default(),
            crc: Default::default(),
            packer: Default::default(),
            lengths: PacketLength::new(cfg.stream_start_bytes()),
            is_blink: Default::default(),
            take: Default::default(),
            prefix_load: Default::default(),
            prefix_ovf: Default::default(),
            the_byte: Default::default(),
            emitting: Default::default(),
            bk: Default::default(),
            in_codes: Default::default(),
            in_pass2: Default::default(),
            k_mask: c8(kn.next_power_of_two() as u64 - 1),
            all_ones: Constant::new(Bits::<RCW>::mask()),
            _r: r,
            _pb: PW / 8,
        })
    }
}

// Match guards do not translate to Verilog, so the ifs stay inside the arms.
#[allow(clippy::collapsible_match)]
impl<const RCW: usize, const CAW: usize, const BW: usize, const NW: usize, const PW: usize> Logic
    for Packetiser<RCW, CAW, BW, NW, PW>
{
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, state, in_ovf, base, masked, planes_r);
        self.prefix.clock.next = self.clock.val();
        self.cursor.clock.next = self.clock.val();
        self.cursor.step.next = false;
        self.crc.clock.next = self.clock.val();
        self.crc.add.next = false;
        self.crc.tail.next = false;
        self.packer.clock.next = self.clock.val();
        self.packer.start.next = false;
        self.packer.send.next = false;
        self.packer.append.next = false;
        self.packer.pad.next = false;
        self.packer.code.next = self.code_stages.code.val();
        self.packer.len.next = self.code_stages.len.val();
        self.head.clock.next = self.clock.val();
        self.prefix_load.next = false;
        self.prefix_ovf.next = false;
        self.is_blink.next = self.record.kind.val() == 1;
        self.planes_r.d.next = self.record.planes.val();

        // ---- Count streamer: one ROI row at a time from the counter bank.
        self.counts.clock.next = self.clock.val();
        self.counts.restart.next = self.restart.val();
        self.counts.start.next = false;
        self.counts.bank.next = self.record.bank.val();
        self.counts.anchor_row.next = self.record.ay.val();
        self.rd_req.next = self.counts.rd_req.val();
        self.rd_addr.next = self.counts.rd_addr.val();
        self.counts.rd_grant.next = self.rd_grant.val();
        for dx in 0..self._r {
            self.counts.rd_counts[dx].next = self.rd_counts[dx].val();
        }
        self.counts.rd_masked.next = self.rd_masked.val();
        // The code pipeline ([`CodePipeline`]): the offsets from the base
        // (pass 2's input too), then the codes the bit packer appends.
        self.bk.next = self.choice.k.val() & self.k_mask.val();
        self.in_codes.next = self.state.q.val() == PacketState::Codes;
        self.in_pass2.next = self.state.q.val() == PacketState::Pass2;
        self.code_stages.clock.next = self.clock.val();
        self.code_stages.restart.next = self.restart.val();
        self.code_stages.pass2.next = self.in_pass2.val();
        self.code_stages.codes.next = self.in_codes.val();
        self.code_stages.count.next = self.counts.count.val();
        self.code_stages.count_valid.next = self.counts.valid.val();
        self.code_stages.base.next = self.base.q.val();
        self.code_stages.k.next = self.bk.val();
        self.code_stages.code_taken.next = self.in_codes.val() & !self.packer.full.val();
        // `take` (set below by the pass that consumes) advances the streamer.
        self.take.next = false;
        match self.state.q.val() {
            PacketState::Pass1 => {
                self.take.next = true;
            }
            PacketState::Pass2 => {
                self.take.next = true;
            }
            PacketState::Codes => {
                self.take.next = self.code_stages.ready.val();
            }
            _ => {}
        }
        self.counts.take.next = self.take.val();
        if (self.state.q.val() == PacketState::Pass1) & self.counts.masked_row.val() {
            self.masked.d.next = true;
        }

        // ---- The code lengths for every k, of the offsets in stage A.
        self.choice.clock.next = self.clock.val();
        self.choice.restart.next = self.restart.val();
        self.choice.clear.next = false;
        self.choice.start_scan.next = false;
        self.choice.step.next = false;
        self.choice.offset.next = self.code_stages.a_offset.val();
        self.choice.offset_valid.next = self.code_stages.a_valid.val() & self.in_pass2.val();

        // ---- Count block head in the prefix: base as LEB128, then k.
        self.head.base.next = self.base.q.val();
        self.head.k.next = self.choice.k.val();

        // ---- Sequence numbers and losses: commands set by the states below.
        self.seqs.clock.next = self.clock.val();
        self.seqs.restart.next = self.restart.val();
        self.seqs.seq_init.next = self.seq_init.val();
        self.seqs.take.next = false;
        self.seqs.lost.next = self.record.lost.val();
        self.seqs.dropped.next = false;
        self.seqs.announced.next = false;
        self.seqs.advance.next = false;

        // ---- The packet's lengths by kind; the room check is registered
        // (Decide acts from its second clock: `lengths.ready`).
        self.lengths.clock.next = self.clock.val();
        self.lengths.kind.next = self.record.kind.val();
        self.lengths.varint_len.next = self.head.varint_len.val();
        self.lengths.code_bytes.next = self.choice.code_bytes.val();
        self.lengths.pending.next = self.seqs.pending.val();
        self.lengths.fifo_free.next = self.fifo_free.val();
        self.lengths.decide.next = self.state.q.val() == PacketState::Decide;
        // ---- The prefixes, read only when a packet starts (Decide, and Crc
        // after an Overflow packet), and computed only then.
        self.record_prefix.enable.next =
            (self.state.q.val() == PacketState::Decide) | (self.state.q.val() == PacketState::Crc);
        self.record_prefix.kind.next = self.record.kind.val();
        self.record_prefix.seq.next = self.seqs.seq.val();
        self.record_prefix.payload_len.next = self.lengths.payload_len.val();
        self.record_prefix.slot.next = self.record.slot.val();
        self.record_prefix.flags.next = self.record.flags.val();
        self.record_prefix.masked.next = self.masked.q.val();
        self.record_prefix.ax.next = self.record.ax.val();
        self.record_prefix.ay.next = self.record.ay.val();
        self.record_prefix.t0.next = self.record.t0.val();
        self.record_prefix.t1.next = self.record.t1.val();
        self.record_prefix.ts.next = self.record.ts.val();
        self.record_prefix.te.next = self.record.te.val();
        self.record_prefix.planes.next = self.planes_r.q.val();
        for b in 0..HEAD_BYTES {
            self.record_prefix.head[b].next = self.head.bytes[b].val();
        }
        StreamSettings::<NW>::link(&mut self.settings, &mut self.record_prefix.settings);
        self.record_prefix.c_planes.next = self.c_planes.val();
        TrackerTotals::link(&mut self.totals, &mut self.record_prefix.totals);
        self.record_prefix.lost_first.next = self.seqs.lost_first.val();
        self.record_prefix.lost_count.next = self.seqs.lost_count.val();

        // ---- The byte of this clock and the CRC.
        // Read only while bytes go out (Ovf, Emit, Codes), and computed only
        // then: free in hardware, and a simulator skips the prefix's tree on
        // the other clocks.
        self.emitting.next = (self.state.q.val() == PacketState::Ovf)
            | (self.state.q.val() == PacketState::Emit)
            | (self.state.q.val() == PacketState::Codes);
        self.prefix.read.next = self.emitting.val();
        self.prefix.index.next = self.cursor.index.val();
        self.the_byte.next = self.prefix.selected.val();
        if self.state.q.val() == PacketState::Codes {
            self.the_byte.next = self.packer.next_byte.val();
        }
        self.crc.data.next = self.the_byte.val();

        self.out_valid.next = false;
        self.out_byte.next = self.the_byte.val();
        self.r_pop.next = false;
        self.fb_ret.next = false;
        self.fb_ret_bank.next = self.record.bank.val();

        match self.state.q.val() {
            PacketState::Idle => {
                if self.record.valid.val() {
                    self.seqs.take.next = true;
                    if self.is_blink.val() {
                        self.state.d.next = PacketState::Wait;
                    } else {
                        self.state.d.next = PacketState::Decide;
                    }
                }
            }
            PacketState::Wait => {
                if self.record.ready.val() {
                    self.base.d.next = self.all_ones.val();
                    self.masked.d.next = false;
                    self.counts.start.next = true;
                    self.state.d.next = PacketState::Pass1;
                }
            }
            PacketState::Pass1 => {
                if self.counts.valid.val() & (self.counts.count.val() < self.base.q.val()) {
                    self.base.d.next = self.counts.count.val();
                }
                if !self.counts.active.val() {
                    self.choice.clear.next = true;
                    self.counts.start.next = true;
                    self.state.d.next = PacketState::Pass2;
                }
            }
            PacketState::Pass2 => {
                // (The last offset is in stage A on the clock the streamer
                // stops, in stage L on the next, and is added on the clock
                // that leaves Pass2.)
                if !self.counts.active.val() & !self.code_stages.a_valid.val() {
                    self.choice.start_scan.next = true;
                    self.state.d.next = PacketState::Choose;
                }
            }
            PacketState::Choose => {
                self.choice.step.next = true;
                if self.choice.last.val() {
                    self.state.d.next = PacketState::Decide;
                }
            }
            PacketState::Decide => {
                if self.lengths.ready.val() & self.lengths.room.val() {
                    self.prefix_load.next = true;
                    if self.seqs.pending.val() {
                        self.prefix_ovf.next = true;
                        self.in_ovf.d.next = true;
                        self.state.d.next = PacketState::Ovf;
                    } else {
                        self.in_ovf.d.next = false;
                        self.state.d.next = PacketState::Emit;
                    }
                } else if self.lengths.ready.val()
                    & ((self.record.kind.val() == 1) | (self.record.kind.val() == 2))
                {
                    // No room for the whole packet: drop the record, count it.
                    self.seqs.dropped.next = true;
                    self.state.d.next = PacketState::Finish;
                }
            }
            PacketState::Ovf => {
                self.out_valid.next = true;
                self.crc.add.next = true;
                self.cursor.step.next = true;
                if self.cursor.last.val() {
                    self.state.d.next = PacketState::Crc;
                }
            }
            PacketState::Emit => {
                self.out_valid.next = true;
                self.crc.add.next = true;
                self.cursor.step.next = true;
                if self.cursor.last.val() {
                    if self.is_blink.val() {
                        self.packer.start.next = true;
                        self.counts.start.next = true;
                        self.state.d.next = PacketState::Codes;
                    } else {
                        self.state.d.next = PacketState::Crc;
                    }
                }
            }
            PacketState::Codes => {
                if self.packer.full.val() {
                    self.out_valid.next = true;
                    self.crc.add.next = true;
                    self.packer.send.next = true;
                } else if self.code_stages.c_valid.val() {
                    self.packer.append.next = true;
                } else if !self.counts.active.val()
                    & !self.code_stages.a_valid.val()
                    & !self.code_stages.b_valid.val()
                {
                    if !self.packer.empty.val() {
                        self.out_valid.next = true;
                        self.crc.add.next = true;
                        self.packer.pad.next = true;
                    } else {
                        self.state.d.next = PacketState::Crc;
                    }
                }
            }
            PacketState::Crc => {
                self.out_valid.next = true;
                self.out_byte.next = self.crc.tail_byte.val();
                self.crc.tail.next = true;
                if self.crc.tail_last.val() {
                    if self.in_ovf.q.val() {
                        // The Overflow packet is out: now the record.
                        self.seqs.announced.next = true;
                        self.in_ovf.d.next = false;
                        self.prefix_load.next = true;
                        self.state.d.next = PacketState::Emit;
                    } else {
                        self.state.d.next = PacketState::Finish;
                    }
                }
            }
            PacketState::Finish => {
                self.r_pop.next = true;
                self.fb_ret.next = self.is_blink.val();
                self.seqs.advance.next = true;
                self.state.d.next = PacketState::Idle;
            }
            _ => {}
        }

        if self.restart.val() {
            self.state.d.next = PacketState::Idle;
        }
        self.prefix.load.next = self.prefix_load.val();
        self.cursor.start.next = self.prefix_load.val();
        self.cursor.rest.next = self.lengths.prefix_rest.val();
        if self.prefix_ovf.val() {
            self.cursor.rest.next = 17.into();
        }
        self.crc.start.next = self.prefix_load.val();
        for j in 0..self._pb {
            self.prefix.d[j].next = self.record_prefix.record[j].val();
            if self.prefix_ovf.val() {
                self.prefix.d[j].next = self.record_prefix.overflow[j].val();
            }
        }
        self.idle.next = (self.state.q.val() == PacketState::Idle) & !self.record.valid.val();
        self.overflowed.next = self.seqs.overflowed.val();
    }
}
