//! The Opal Kelly XEM6310 top: FrontPanel host interface, register map
//! ([`crate::registers`]), the pipeline with its DDR2 delay line, the replay
//! and mask pipes, the packet pipe-out and the sensor port.
//!
//! **Black boxes.** Opal Kelly's FrontPanel HDL (okHost, okWireIn, okWireOut,
//! okTriggerIn, okBTPipeIn, okBTPipeOut, okWireOR) and the Xilinx MIG DDR2
//! controller are proprietary or generated netlists, never a dependency:
//! [`OkHost`], [`OkEndpoint`], [`OkWireOr`] … ([`crate::frontpanel`]) and
//! [`MigDdr2`] ([`crate::mig_ddr2`]) instantiate them by name, and the
//! generated Verilog carries `(* blackbox *)` declarations of their ports
//! (written from Opal Kelly's public FrontPanel user's manual and Xilinx
//! UG388; stub bodies only drive outputs to 0 so that Verilator can lint the
//! design). To build a bitfile, add Opal Kelly's `okLibrary.v` and the `.ngc`
//! cores for the XEM6310, and the MIG-generated DDR2 controller named
//! `smartagg_mig` (configured as [`crate::mig_ddr2`] says); the declarations
//! must then be left out. The designs whose delay line is on chip park the
//! DDR2 pins instead ([`ParkedDdr2`]).
//!
//! **Clock.** Everything but the sensor port runs on the host-interface
//! clock `okClk` (100.8 MHz, period 9.92 ns); the MCB user port is clocked
//! by it too (its FIFOs cross into the memory clock).
//!
//! **Simulation.** [`XemCore`] is the whole design between the endpoints: its
//! ports are the endpoints' user sides (wire values, trigger pulses, pipe
//! strobes) and the MCB user port, so it is simulated against the model with
//! the behavioural MCB ([`crate::mcb_model::McbModel`]); FrontPanel's
//! host protocol itself is Opal Kelly's and is not modelled.
//!
//! **Replay** (`SOURCE_REPLAY`): the host sends whole planes in whole
//! blocks (a 320×240 plane is 600 blocks of 16 bytes); they go in at one
//! word every other clock, the sensor's duty cycle at P = 16 (a 320×240
//! plane in 96 µs: faster than real time), and wait while the back half
//! has no room (the pipeline's `ready`), so that no replayed scene, however
//! dense, overflows it; STOP takes effect
//! once every replayed word has gone in and the plane in progress is
//! complete.
//!
//! **Sensor port** (placeholder: the SPCImager's connector pin-out is not
//! published). `sensor_clk`, `sensor_valid`, `sensor_sop` and P data bits on
//! expansion connector JP2, 3.3 V LVCMOS (see `constraints/xem6310.ucf`);
//! the words cross into `okClk` through an asynchronous FIFO whose overflow
//! is a sticky status bit.

use crate::bram::RamStyle;
use crate::config::{BackHalfConfig, GatewareError};
use crate::fifo::Fifo;
use crate::frontpanel::{EndpointKind, OkEndpoint, OkHost, OkWireOr};
use crate::mig_ddr2::{MigDdr2, ParkedDdr2};
use crate::pipeline::{Pipeline, PipelineDdr};
use crate::registers;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// Declares an XEM6310 core ([`XemCore`], [`XemCoreOnChip`]) around a
/// pipeline type with [`PipelineDdr`]'s ports: one text for both delay
/// lines, since rust-hdl's generated logic reads a sub-block's ports by name.
macro_rules! xem_core {
    ($(#[$attr:meta])* $core:ident, $pipe:ident) => {
$(#[$attr])*
#[derive(LogicBlock)]
pub struct $core<
    const P: usize,
    const PAW: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW2: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// okClk.
    pub clock: Signal<In, Clock>,
    /// Wire-ins 0x00 … 0x08.
    pub wire_in: Vec<Signal<In, Bits<32>>>,
    /// Trigger-in 0x40 (one-clock pulses).
    pub trigger: Signal<In, Bits<32>>,
    /// Pipe-in 0x80 (replay): write strobe.
    pub replay_write: Signal<In, Bit>,
    /// Pipe-in 0x80: data.
    pub replay_data: Signal<In, Bits<32>>,
    /// Pipe-in 0x80: a block can be written.
    pub replay_ready: Signal<Out, Bit>,
    /// Pipe-in 0x81 (mask): write strobe.
    pub mask_write: Signal<In, Bit>,
    /// Pipe-in 0x81: data.
    pub mask_data: Signal<In, Bits<32>>,
    /// Pipe-in 0x81: a block can be written.
    pub mask_ready: Signal<Out, Bit>,
    /// Pipe-out 0xA0: read strobe (data the next clock).
    pub out_read: Signal<In, Bit>,
    /// Pipe-out 0xA0: data.
    pub out_data: Signal<Out, Bits<32>>,
    /// Pipe-out 0xA0: a block can be read.
    pub out_ready: Signal<Out, Bit>,
    /// Sensor FIFO: no word.
    pub sensor_empty: Signal<In, Bit>,
    /// Sensor FIFO head: `sop` in bit P, pixels below.
    pub sensor_word: Signal<In, Bits<32>>,
    /// Sensor FIFO: take the word.
    pub sensor_read: Signal<Out, Bit>,
    /// Sensor FIFO overflowed (synchronised, sticky).
    pub sensor_overflow: Signal<In, Bit>,
    /// Wire-outs 0x20 … 0x27.
    pub wire_out: Vec<Signal<Out, Bits<32>>>,
    /// MCB: calibration done.
    pub calib_done: Signal<In, Bit>,
    /// MCB: command enable.
    pub cmd_en: Signal<Out, Bit>,
    /// MCB: instruction.
    pub cmd_instr: Signal<Out, Bits<3>>,
    /// MCB: burst length − 1.
    pub cmd_bl: Signal<Out, Bits<6>>,
    /// MCB: byte address.
    pub cmd_addr: Signal<Out, Bits<30>>,
    /// MCB: command FIFO full.
    pub cmd_full: Signal<In, Bit>,
    /// MCB: write enable.
    pub wr_en: Signal<Out, Bit>,
    /// MCB: write mask.
    pub wr_mask: Signal<Out, Bits<4>>,
    /// MCB: write data.
    pub wr_data: Signal<Out, Bits<32>>,
    /// MCB: write FIFO full.
    pub wr_full: Signal<In, Bit>,
    /// MCB: read enable.
    pub rd_en: Signal<Out, Bit>,
    /// MCB: read data.
    pub rd_data: Signal<In, Bits<32>>,
    /// MCB: read FIFO empty.
    pub rd_empty: Signal<In, Bit>,
    pipe: $pipe<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>,
    replay: Fifo<32, 9>,
    maskf: Fifo<32, 9>,
    owords: Fifo<32, 9>,
    src_replay: DFF<Bit>,
    stop_pend: DFF<Bit>,
    /// START taken, waiting for the mask pipe to drain into the mask and
    /// for the memory's calibration: a mask written just before START is
    /// the stream's whole mask, and a START before calibration is not lost.
    start_pend: DFF<Bit>,
    rphase: DFF<Bit>,
    rsub: DFF<Bits<8>>,
    rwidx: DFF<Bits<32>>,
    msub: DFF<Bits<8>>,
    maddr: DFF<Bits<CAW>>,
    pack: DFF<Bits<32>>,
    pbytes: DFF<Bits<8>>,
    total: DFF<Bits<8>>,
    avail: DFF<Bits<32>>,
    odata: DFF<Bits<32>>,
    rshift: Signal<Local, Bits<32>>,
    mshift: Signal<Local, Bits<32>>,
    take_byte: Signal<Local, Bit>,
    avail_base: Signal<Local, Bits<32>>,
    pad: Signal<Local, Bit>,
    byte32: Signal<Local, Bits<32>>,
    sop_bit: Constant<Bits<8>>,
    sub_last: Constant<Bits<8>>,
    log2p: Constant<Bits<8>>,
    last_widx: Constant<Bits<32>>,
    block_words: Constant<Bits<16>>,
    fifo_room: Constant<Bits<16>>,
    consts: Vec<Constant<Bits<32>>>,
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > $core<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The core of a configuration; errors if the type's widths differ or a
    /// plane is not whole 32-bit pipe words.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        let f = &cfg.front;
        if P > 31 || !(f.width * f.height).is_multiple_of(32) {
            return Err(GatewareError::Invalid {
                field: "width/height",
                value: format!("{}x{}", f.width, f.height),
                why: "a plane must be whole 32-bit pipe words, P < 32".into(),
            });
        }
        let c32 = |v: u64| Constant::new(v.to_bits());
        let words = (0..registers::wire_out::COUNT)
            .map(|i| match i as u8 + registers::wire_out::STATUS {
                registers::wire_out::VERSION => registers::version_word() as u64,
                registers::wire_out::GEOMETRY => f.width as u64 | (f.height as u64) << 16,
                registers::wire_out::GENERATION => {
                    f.kernel.len() as u64
                        | (f.kernel_shift as u64) << 8
                        | (cfg.roi_size as u64) << 16
                        | (cfg.slots as u64) << 24
                }
                registers::wire_out::KERNEL_CRC => registers::kernel_crc(&f.kernel) as u64,
                registers::wire_out::R_ASSOC => cfg.r_assoc as u64,
                registers::wire_out::MAX_N => f.n_max as u64,
                _ => 0,
            })
            .map(c32)
            .collect();
        let block = (registers::PIPE_BLOCK_BYTES / 4) as u64;
        Ok($core {
            clock: Default::default(),
            wire_in: lanes(registers::wire_in::COUNT),
            trigger: Default::default(),
            replay_write: Default::default(),
            replay_data: Default::default(),
            replay_ready: Default::default(),
            mask_write: Default::default(),
            mask_data: Default::default(),
            mask_ready: Default::default(),
            out_read: Default::default(),
            out_data: Default::default(),
            out_ready: Default::default(),
            sensor_empty: Default::default(),
            sensor_word: Default::default(),
            sensor_read: Default::default(),
            sensor_overflow: Default::default(),
            wire_out: lanes(registers::wire_out::COUNT),
            calib_done: Default::default(),
            cmd_en: Default::default(),
            cmd_instr: Default::default(),
            cmd_bl: Default::default(),
            cmd_addr: Default::default(),
            cmd_full: Default::default(),
            wr_en: Default::default(),
            wr_mask: Default::default(),
            wr_data: Default::default(),
            wr_full: Default::default(),
            rd_en: Default::default(),
            rd_data: Default::default(),
            rd_empty: Default::default(),
            pipe: $pipe::new(cfg)?,
            replay: Fifo::new(RamStyle::Block),
            maskf: Fifo::new(RamStyle::Block),
            owords: Fifo::new(RamStyle::Block),
            src_replay: Default::default(),
            stop_pend: Default::default(),
            start_pend: Default::default(),
            rphase: Default::default(),
            rsub: Default::default(),
            rwidx: Default::default(),
            msub: Default::default(),
            maddr: Default::default(),
            pack: Default::default(),
            pbytes: Default::default(),
            total: Default::default(),
            avail: Default::default(),
            odata: Default::default(),
            rshift: Default::default(),
            mshift: Default::default(),
            take_byte: Default::default(),
            avail_base: Default::default(),
            pad: Default::default(),
            byte32: Default::default(),
            sop_bit: Constant::new((P as u64).to_bits()),
            sub_last: Constant::new(((32 / P) as u64 - 1).to_bits()),
            log2p: Constant::new((P.trailing_zeros() as u64).to_bits()),
            last_widx: c32(f.words_per_plane() as u64 - 1),
            block_words: Constant::new(block.to_bits()),
            fifo_room: Constant::new(((1u64 << 9) - block).to_bits()),
            consts: words,
        })
    }
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic
    for $core<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, pipe, replay, maskf, owords);
        dff_setup!(
            self, clock, src_replay, stop_pend, start_pend, rphase, rsub, rwidx, msub, maddr, pack, pbytes,
            total, avail, odata
        );
        // ---- Registers and triggers.
        self.pipe.reg_mask_enable.next = self.wire_in[0].val().get_bit(1);
        self.pipe.reg_n.next = self.wire_in[1].val();
        self.pipe.reg_threshold.next = self.wire_in[2].val();
        self.pipe.reg_l_min.next = self.wire_in[3].val();
        self.pipe.reg_l_max.next = self.wire_in[4].val();
        self.pipe.reg_period.next = self.wire_in[5].val();
        self.pipe.reg_masked.next = self.wire_in[6].val();
        // wire_in::THRESHOLD_HOLD and END_TRIM (checked below the block).
        self.pipe.reg_threshold_hold.next = self.wire_in[7].val();
        self.pipe.reg_end_trim.next = self.wire_in[8].val();
        self.pipe.reset.next = self.trigger.val().get_bit(0);
        if self.trigger.val().get_bit(1) {
            self.start_pend.d.next = true;
        }
        self.pipe.start.next = self.start_pend.q.val()
            & !self.maskf.out_valid.val()
            & (self.maskf.count.val() == 0)
            & self.pipe.mem_ready.val();
        if self.pipe.start.val() | self.trigger.val().get_bit(0) {
            self.start_pend.d.next = false;
        }
        // STOP with replay: once every word the host sent has gone in.
        if self.trigger.val().get_bit(2) {
            self.stop_pend.d.next = true;
        }
        self.pipe.stop.next = self.stop_pend.q.val()
            & (!self.src_replay.q.val()
                | (!self.replay.out_valid.val() & (self.replay.count.val() == 0)));
        if self.pipe.stop.val() | self.trigger.val().get_bit(0) {
            self.stop_pend.d.next = false;
        }
        if self.trigger.val().get_bit(1) {
            self.src_replay.d.next = self.wire_in[0].val().get_bit(0);
            self.rsub.d.next = 0.into();
            self.rwidx.d.next = 0.into();
        }
        self.replay.restart.next = self.trigger.val().get_bit(0);
        self.maskf.restart.next = self.trigger.val().get_bit(0);
        self.owords.restart.next = self.trigger.val().get_bit(0) | self.trigger.val().get_bit(1);

        // ---- Replay pipe: 32 pixels per pipe word, 32/P stream words.
        self.replay.push.next = self.replay_write.val();
        self.replay.push_data.next = self.replay_data.val();
        self.replay_ready.next = self.replay.count.val() <= self.fifo_room.val();
        self.rshift.next = self.replay.out_data.val()
            >> (bit_cast::<32, 8>(self.rsub.q.val()) << self.log2p.val());
        self.replay.pop.next = false;
        self.sensor_read.next = false;
        self.pipe.in_valid.next = false;
        self.pipe.in_sop.next = false;
        self.pipe.in_live.next = 0.into();
        if self.src_replay.q.val() {
            // One word every other clock: the duty cycle the sensor has at
            // P = 16 (47.6 %), for which the back half and the DDR2 port are
            // sized; and only while the back half has room, so that a dense
            // replayed scene waits instead of overflowing it.
            self.rphase.d.next = !self.rphase.q.val();
            if self.replay.out_valid.val() & self.pipe.ready.val() & self.rphase.q.val() {
                self.pipe.in_valid.next = true;
                self.pipe.in_sop.next = self.rwidx.q.val() == 0;
                self.pipe.in_live.next = self.rshift.val().get_bits::<P>(0);
                self.rsub.d.next = self.rsub.q.val() + 1;
                if self.rsub.q.val() == self.sub_last.val() {
                    self.rsub.d.next = 0.into();
                    self.replay.pop.next = true;
                }
                self.rwidx.d.next = self.rwidx.q.val() + 1;
                if self.rwidx.q.val() == self.last_widx.val() {
                    self.rwidx.d.next = 0.into();
                }
            }
        } else {
            // The sensor streams whether or not a stream runs: take its words.
            self.sensor_read.next = !self.sensor_empty.val();
            self.pipe.in_valid.next = !self.sensor_empty.val() & self.pipe.accepting.val();
            self.pipe.in_sop.next = self.sensor_word.val().get_bit(self.sop_bit.val().index());
            self.pipe.in_live.next = self.sensor_word.val().get_bits::<P>(0);
        }

        // ---- Mask pipe, loaded while stopped: word by word from address 0 after RESET.
        self.maskf.push.next = self.mask_write.val();
        self.maskf.push_data.next = self.mask_data.val();
        self.mask_ready.next = self.maskf.count.val() <= self.fifo_room.val();
        self.mshift.next =
            self.maskf.out_data.val() >> (bit_cast::<32, 8>(self.msub.q.val()) << self.log2p.val());
        self.maskf.pop.next = false;
        // Mask words sent while a stream runs wait in the FIFO for its end.
        self.pipe.load.next = self.maskf.out_valid.val() & self.pipe.mask_loadable.val();
        self.pipe.load_address.next = self.maddr.q.val();
        self.pipe.load_data.next = self.mshift.val().get_bits::<P>(0);
        if self.maskf.out_valid.val() & self.pipe.mask_loadable.val() {
            self.maddr.d.next = self.maddr.q.val() + 1;
            self.msub.d.next = self.msub.q.val() + 1;
            if self.msub.q.val() == self.sub_last.val() {
                self.msub.d.next = 0.into();
                self.maskf.pop.next = true;
            }
        }
        if self.trigger.val().get_bit(0) {
            self.maddr.d.next = 0.into();
            self.msub.d.next = 0.into();
        }

        // ---- Packet bytes to 32-bit pipe words (byte k in bits 8k+7..8k);
        // at the stream's end, zero bytes up to a whole block.
        self.pad.next = self.pipe.ended.val()
            & !self.pipe.out_valid.val()
            & (self.pipe.out_count.val() == 0)
            & ((self.total.q.val() & 15) != 0);
        self.take_byte.next = (self.pipe.out_valid.val() | self.pad.val()) & self.owords.room.val();
        self.pipe.out_pop.next = self.take_byte.val() & self.pipe.out_valid.val();
        self.byte32.next = 0.into();
        if self.pipe.out_valid.val() {
            self.byte32.next = bit_cast::<32, 8>(self.pipe.out_data.val());
        }
        self.owords.push.next = false;
        self.owords.push_data.next = self.pack.q.val()
            | (self.byte32.val() << (bit_cast::<32, 8>(self.pbytes.q.val()) << 3));
        if self.take_byte.val() {
            self.total.d.next = self.total.q.val() + 1;
            self.pack.d.next = self.pack.q.val()
                | (self.byte32.val() << (bit_cast::<32, 8>(self.pbytes.q.val()) << 3));
            self.pbytes.d.next = self.pbytes.q.val() + 1;
            if self.pbytes.q.val() == 3 {
                self.owords.push.next = true;
                self.pack.d.next = 0.into();
                self.pbytes.d.next = 0.into();
            }
        }
        // Bytes of the stream not yet read by the host (padding excluded).
        // The host's read first, the byte taken this clock added last: the
        // pop (behind the output FIFO's room) meets one adder, not two.
        self.avail_base.next = self.avail.q.val();
        self.owords.pop.next = self.out_read.val();
        if self.out_read.val() {
            self.odata.d.next = self.owords.out_data.val();
            self.avail_base.next = 0.into();
            if self.avail.q.val() >= 4 {
                self.avail_base.next = self.avail.q.val() - 4;
            }
        }
        self.avail.d.next =
            self.avail_base.val() + bit_cast::<32, 1>(self.pipe.out_pop.val().into());
        if self.trigger.val().get_bit(0) | self.trigger.val().get_bit(1) {
            self.pack.d.next = 0.into();
            self.pbytes.d.next = 0.into();
            self.total.d.next = 0.into();
            self.avail.d.next = 0.into();
        }
        self.out_data.next = self.odata.q.val();
        self.out_ready.next = self.owords.count.val() >= self.block_words.val();

        // ---- Sensor, MCB.
        self.pipe.calib_done.next = self.calib_done.val();
        self.pipe.cmd_full.next = self.cmd_full.val();
        self.pipe.wr_full.next = self.wr_full.val();
        self.pipe.rd_data.next = self.rd_data.val();
        self.pipe.rd_empty.next = self.rd_empty.val();
        self.cmd_en.next = self.pipe.cmd_en.val();
        self.cmd_instr.next = self.pipe.cmd_instr.val();
        self.cmd_bl.next = self.pipe.cmd_bl.val();
        self.cmd_addr.next = self.pipe.cmd_addr.val();
        self.wr_en.next = self.pipe.wr_en.val();
        self.wr_mask.next = self.pipe.wr_mask.val();
        self.wr_data.next = self.pipe.wr_data.val();
        self.rd_en.next = self.pipe.rd_en.val();

        // ---- Wire-outs.
        self.wire_out[0].next = bit_cast::<32, 1>(self.pipe.running.val().into())
            | (bit_cast::<32, 1>(self.pipe.ended.val().into()) << 1)
            | (bit_cast::<32, 1>(self.pipe.overflowed.val().into()) << 2)
            | (bit_cast::<32, 1>(self.pipe.config_error.val().into()) << 3)
            | (bit_cast::<32, 1>(self.pipe.fault.val().into()) << 4)
            | (bit_cast::<32, 1>(self.pipe.mem_ready.val().into()) << 5)
            | (bit_cast::<32, 1>(self.pipe.framing_error.val().into()) << 6)
            | (bit_cast::<32, 1>(self.sensor_overflow.val().into()) << 7);
        self.wire_out[1].next = bit_cast::<32, 16>(self.pipe.out_count.val()) + self.avail.q.val();
        for i in 2..8 {
            self.wire_out[i].next = self.consts[i].val();
        }
    }
}

    };
}

xem_core!(
    /// Everything between the FrontPanel endpoints and the MCB user port, on
    /// `okClk`: register decoding, replay and mask pipes, the pipeline, the
    /// packet pipe-out and the status wire-outs. Type parameters: those of
    /// [`PipelineDdr`].
    XemCore,
    PipelineDdr
);

xem_core!(
    /// [`XemCore`] around the pipeline with the block-RAM delay line
    /// ([`Pipeline`]): the same endpoints, registers and pipes; its MCB user
    /// port stays idle and `MEM_READY` is always set.
    XemCoreOnChip,
    Pipeline
);

/// [`XemCore`] of [`crate::pipeline::test_back_config`]`(4, 3, 1)` (the
/// parameters of [`crate::pipeline::TestPipelineDdr`]).
pub type TestXemCore = XemCore<4, 6, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11>;

/// [`XemCoreOnChip`] of the same configuration (the parameters of
/// [`crate::pipeline::TestPipeline`]).
pub type TestXemCoreOnChip =
    XemCoreOnChip<4, 8, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11>;

// The core's wire-in indices are literals (an `#[hdl_gen]` body indexes
// with them): they are the register map's addresses.
const _: () = assert!(
    registers::wire_in::N_WINDOW == 1
        && registers::wire_in::THRESHOLD_INT == 2
        && registers::wire_in::L_MIN == 3
        && registers::wire_in::L_MAX == 4
        && registers::wire_in::PLANE_PERIOD_NS == 5
        && registers::wire_in::MASKED_PIXELS == 6
        && registers::wire_in::THRESHOLD_HOLD == 7
        && registers::wire_in::END_TRIM == 8
        && registers::wire_in::COUNT == 9
);

/// Depth (address bits) of the sensor port's clock-crossing FIFO.
pub const SENSOR_FIFO_BITS: usize = 5;

/// Declares an XEM6310 top ([`Xem6310Top`], [`Xem6310TopOnChip`]) around a
/// core type ([`XemCore`], [`XemCoreOnChip`]) and a DDR2 block ([`MigDdr2`],
/// [`ParkedDdr2`]): the same pins, endpoints and sensor port, so one
/// `constraints/xem6310.ucf` places both.
macro_rules! xem_top {
    ($(#[$attr:meta])* $top:ident, $core:ident, $mem:ident) => {
$(#[$attr])*
#[allow(non_snake_case)]
#[derive(LogicBlock)]
pub struct $top<
    const P: usize,
    const PAW: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW2: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// FrontPanel host interface.
    pub okUH: Signal<In, Bits<5>>,
    /// FrontPanel host interface.
    pub okHU: Signal<Out, Bits<3>>,
    /// FrontPanel host interface.
    pub okUHU: Signal<InOut, Bits<32>>,
    /// FrontPanel host interface.
    pub okAA: Signal<InOut, Bit>,
    /// 100 MHz system clock (LVDS), for the MIG.
    pub sys_clkp: Signal<In, Bit>,
    /// 100 MHz system clock (LVDS), for the MIG.
    pub sys_clkn: Signal<In, Bit>,
    /// LEDs, active low: running, ended, overflowed, config error, fault, memory ready.
    pub led: Signal<Out, Bits<8>>,
    /// DDR2 data.
    pub ddr2_dq: Signal<InOut, Bits<16>>,
    /// DDR2 address.
    pub ddr2_a: Signal<Out, Bits<13>>,
    /// DDR2 bank.
    pub ddr2_ba: Signal<Out, Bits<3>>,
    /// DDR2 RAS#.
    pub ddr2_ras_n: Signal<Out, Bit>,
    /// DDR2 CAS#.
    pub ddr2_cas_n: Signal<Out, Bit>,
    /// DDR2 WE#.
    pub ddr2_we_n: Signal<Out, Bit>,
    /// DDR2 ODT.
    pub ddr2_odt: Signal<Out, Bit>,
    /// DDR2 CKE.
    pub ddr2_cke: Signal<Out, Bit>,
    /// DDR2 lower data mask.
    pub ddr2_dm: Signal<Out, Bit>,
    /// DDR2 upper data mask.
    pub ddr2_udm: Signal<Out, Bit>,
    /// DDR2 lower strobe.
    pub ddr2_dqs: Signal<InOut, Bit>,
    /// DDR2 lower strobe, negative.
    pub ddr2_dqs_n: Signal<InOut, Bit>,
    /// DDR2 upper strobe.
    pub ddr2_udqs: Signal<InOut, Bit>,
    /// DDR2 upper strobe, negative.
    pub ddr2_udqs_n: Signal<InOut, Bit>,
    /// DDR2 clock.
    pub ddr2_ck: Signal<Out, Bit>,
    /// DDR2 clock, negative.
    pub ddr2_ck_n: Signal<Out, Bit>,
    /// DDR2 chip select (held low).
    pub ddr2_cs_n: Signal<Out, Bit>,
    /// MCB calibration resistor.
    pub ddr2_rzq: Signal<InOut, Bit>,
    /// MCB calibration pin.
    pub ddr2_zio: Signal<InOut, Bit>,
    /// Sensor port (placeholder pins): word clock.
    pub sensor_clk: Signal<In, Clock>,
    /// Sensor port: a word this clock.
    pub sensor_valid: Signal<In, Bit>,
    /// Sensor port: first word of a plane.
    pub sensor_sop: Signal<In, Bit>,
    /// Sensor port: P pixels.
    pub sensor_data: Signal<In, Bits<P>>,
    host: OkHost,
    wire_or: OkWireOr<715>,
    wi0: OkEndpoint,
    wi1: OkEndpoint,
    wi2: OkEndpoint,
    wi3: OkEndpoint,
    wi4: OkEndpoint,
    wi5: OkEndpoint,
    wi6: OkEndpoint,
    wi7: OkEndpoint,
    wi8: OkEndpoint,
    wo0: OkEndpoint,
    wo1: OkEndpoint,
    wo2: OkEndpoint,
    wo3: OkEndpoint,
    wo4: OkEndpoint,
    wo5: OkEndpoint,
    wo6: OkEndpoint,
    wo7: OkEndpoint,
    ti40: OkEndpoint,
    pi80: OkEndpoint,
    pi81: OkEndpoint,
    poa0: OkEndpoint,
    mig: $mem,
    sensor_fifo: AsynchronousFIFO<Bits<32>, SENSOR_FIFO_BITS, 6, 1>,
    sensor_sync: BitSynchronizer,
    core: $core<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>,
    sop_shift: Constant<Bits<8>>,
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > $top<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The top of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        use registers::{pipe, trigger, wire_in, wire_out};
        use EndpointKind::*;
        let wi = |a: u8| OkEndpoint::new(WireIn, wire_in::CONTROL + a);
        let wo = |a: u8| OkEndpoint::new(WireOut, wire_out::STATUS + a);
        Ok($top {
            okUH: Default::default(),
            okHU: Default::default(),
            okUHU: Default::default(),
            okAA: Default::default(),
            sys_clkp: Default::default(),
            sys_clkn: Default::default(),
            led: Default::default(),
            ddr2_dq: Default::default(),
            ddr2_a: Default::default(),
            ddr2_ba: Default::default(),
            ddr2_ras_n: Default::default(),
            ddr2_cas_n: Default::default(),
            ddr2_we_n: Default::default(),
            ddr2_odt: Default::default(),
            ddr2_cke: Default::default(),
            ddr2_dm: Default::default(),
            ddr2_udm: Default::default(),
            ddr2_dqs: Default::default(),
            ddr2_dqs_n: Default::default(),
            ddr2_udqs: Default::default(),
            ddr2_udqs_n: Default::default(),
            ddr2_ck: Default::default(),
            ddr2_ck_n: Default::default(),
            ddr2_cs_n: Default::default(),
            ddr2_rzq: Default::default(),
            ddr2_zio: Default::default(),
            sensor_clk: Default::default(),
            sensor_valid: Default::default(),
            sensor_sop: Default::default(),
            sensor_data: Default::default(),
            host: Default::default(),
            wire_or: Default::default(),
            wi0: wi(0),
            wi1: wi(1),
            wi2: wi(2),
            wi3: wi(3),
            wi4: wi(4),
            wi5: wi(5),
            wi6: wi(6),
            wi7: wi(7),
            wi8: wi(8),
            wo0: wo(0),
            wo1: wo(1),
            wo2: wo(2),
            wo3: wo(3),
            wo4: wo(4),
            wo5: wo(5),
            wo6: wo(6),
            wo7: wo(7),
            ti40: OkEndpoint::new(TriggerIn, trigger::CONTROL),
            pi80: OkEndpoint::new(BtPipeIn, pipe::REPLAY_IN),
            pi81: OkEndpoint::new(BtPipeIn, pipe::MASK_IN),
            poa0: OkEndpoint::new(BtPipeOut, pipe::STREAM_OUT),
            mig: Default::default(),
            sensor_fifo: Default::default(),
            sensor_sync: Default::default(),
            core: $core::new(cfg)?,
            sop_shift: Constant::new((P as u64).to_bits()),
        })
    }
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic
    for $top<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        // Host interface and its clock.
        self.host.ok_uh.next = self.okUH.val();
        self.okHU.next = self.host.ok_hu.val();
        Signal::<InOut, Bits<32>>::link(&mut self.okUHU, &mut self.host.ok_uhu);
        Signal::<InOut, Bit>::link(&mut self.okAA, &mut self.host.ok_aa);
        self.host.ok_eh.next = self.wire_or.ok_eh.val();
        self.core.clock.next = self.host.ok_clk.val();
        self.ti40.ep_clk.next = self.host.ok_clk.val();
        self.wi0.ok_he.next = self.host.ok_he.val();
        self.wi1.ok_he.next = self.host.ok_he.val();
        self.wi2.ok_he.next = self.host.ok_he.val();
        self.wi3.ok_he.next = self.host.ok_he.val();
        self.wi4.ok_he.next = self.host.ok_he.val();
        self.wi5.ok_he.next = self.host.ok_he.val();
        self.wi6.ok_he.next = self.host.ok_he.val();
        self.wi7.ok_he.next = self.host.ok_he.val();
        self.wi8.ok_he.next = self.host.ok_he.val();
        self.wo0.ok_he.next = self.host.ok_he.val();
        self.wo1.ok_he.next = self.host.ok_he.val();
        self.wo2.ok_he.next = self.host.ok_he.val();
        self.wo3.ok_he.next = self.host.ok_he.val();
        self.wo4.ok_he.next = self.host.ok_he.val();
        self.wo5.ok_he.next = self.host.ok_he.val();
        self.wo6.ok_he.next = self.host.ok_he.val();
        self.wo7.ok_he.next = self.host.ok_he.val();
        self.ti40.ok_he.next = self.host.ok_he.val();
        self.pi80.ok_he.next = self.host.ok_he.val();
        self.pi81.ok_he.next = self.host.ok_he.val();
        self.poa0.ok_he.next = self.host.ok_he.val();
        // The endpoints that answer the host, one 65-bit bus each.
        self.wire_or.ok_ehx.next = bit_cast::<715, 65>(self.wo0.ok_eh.val())
            | (bit_cast::<715, 65>(self.wo1.ok_eh.val()) << 65)
            | (bit_cast::<715, 65>(self.wo2.ok_eh.val()) << 130)
            | (bit_cast::<715, 65>(self.wo3.ok_eh.val()) << 195)
            | (bit_cast::<715, 65>(self.wo4.ok_eh.val()) << 260)
            | (bit_cast::<715, 65>(self.wo5.ok_eh.val()) << 325)
            | (bit_cast::<715, 65>(self.wo6.ok_eh.val()) << 390)
            | (bit_cast::<715, 65>(self.wo7.ok_eh.val()) << 455)
            | (bit_cast::<715, 65>(self.pi80.ok_eh.val()) << 520)
            | (bit_cast::<715, 65>(self.pi81.ok_eh.val()) << 585)
            | (bit_cast::<715, 65>(self.poa0.ok_eh.val()) << 650);
        // Unused endpoint inputs.
        self.wi0.ep_datain.next = 0.into();
        self.wi1.ep_datain.next = 0.into();
        self.wi2.ep_datain.next = 0.into();
        self.wi3.ep_datain.next = 0.into();
        self.wi4.ep_datain.next = 0.into();
        self.wi5.ep_datain.next = 0.into();
        self.wi6.ep_datain.next = 0.into();
        self.wi7.ep_datain.next = 0.into();
        self.wi8.ep_datain.next = 0.into();
        self.ti40.ep_datain.next = 0.into();
        self.pi80.ep_datain.next = 0.into();
        self.pi81.ep_datain.next = 0.into();
        self.wi0.ep_ready.next = false;
        self.wi1.ep_ready.next = false;
        self.wi2.ep_ready.next = false;
        self.wi3.ep_ready.next = false;
        self.wi4.ep_ready.next = false;
        self.wi5.ep_ready.next = false;
        self.wi6.ep_ready.next = false;
        self.wi7.ep_ready.next = false;
        self.wi8.ep_ready.next = false;
        self.wo0.ep_ready.next = false;
        self.wo1.ep_ready.next = false;
        self.wo2.ep_ready.next = false;
        self.wo3.ep_ready.next = false;
        self.wo4.ep_ready.next = false;
        self.wo5.ep_ready.next = false;
        self.wo6.ep_ready.next = false;
        self.wo7.ep_ready.next = false;
        self.ti40.ep_ready.next = false;
        self.wi0.ep_clk.next = self.host.ok_clk.val();
        self.wi1.ep_clk.next = self.host.ok_clk.val();
        self.wi2.ep_clk.next = self.host.ok_clk.val();
        self.wi3.ep_clk.next = self.host.ok_clk.val();
        self.wi4.ep_clk.next = self.host.ok_clk.val();
        self.wi5.ep_clk.next = self.host.ok_clk.val();
        self.wi6.ep_clk.next = self.host.ok_clk.val();
        self.wi7.ep_clk.next = self.host.ok_clk.val();
        self.wi8.ep_clk.next = self.host.ok_clk.val();
        self.wo0.ep_clk.next = self.host.ok_clk.val();
        self.wo1.ep_clk.next = self.host.ok_clk.val();
        self.wo2.ep_clk.next = self.host.ok_clk.val();
        self.wo3.ep_clk.next = self.host.ok_clk.val();
        self.wo4.ep_clk.next = self.host.ok_clk.val();
        self.wo5.ep_clk.next = self.host.ok_clk.val();
        self.wo6.ep_clk.next = self.host.ok_clk.val();
        self.wo7.ep_clk.next = self.host.ok_clk.val();
        self.pi80.ep_clk.next = self.host.ok_clk.val();
        self.pi81.ep_clk.next = self.host.ok_clk.val();
        self.poa0.ep_clk.next = self.host.ok_clk.val();

        // Registers, triggers, pipes.
        self.core.wire_in[0].next = self.wi0.ep_dataout.val();
        self.core.wire_in[1].next = self.wi1.ep_dataout.val();
        self.core.wire_in[2].next = self.wi2.ep_dataout.val();
        self.core.wire_in[3].next = self.wi3.ep_dataout.val();
        self.core.wire_in[4].next = self.wi4.ep_dataout.val();
        self.core.wire_in[5].next = self.wi5.ep_dataout.val();
        self.core.wire_in[6].next = self.wi6.ep_dataout.val();
        self.core.wire_in[7].next = self.wi7.ep_dataout.val();
        self.core.wire_in[8].next = self.wi8.ep_dataout.val();
        self.core.trigger.next = self.ti40.ep_dataout.val();
        self.wo0.ep_datain.next = self.core.wire_out[0].val();
        self.wo1.ep_datain.next = self.core.wire_out[1].val();
        self.wo2.ep_datain.next = self.core.wire_out[2].val();
        self.wo3.ep_datain.next = self.core.wire_out[3].val();
        self.wo4.ep_datain.next = self.core.wire_out[4].val();
        self.wo5.ep_datain.next = self.core.wire_out[5].val();
        self.wo6.ep_datain.next = self.core.wire_out[6].val();
        self.wo7.ep_datain.next = self.core.wire_out[7].val();
        self.core.replay_write.next = self.pi80.ep_strobe.val();
        self.core.replay_data.next = self.pi80.ep_dataout.val();
        self.pi80.ep_ready.next = self.core.replay_ready.val();
        self.core.mask_write.next = self.pi81.ep_strobe.val();
        self.core.mask_data.next = self.pi81.ep_dataout.val();
        self.pi81.ep_ready.next = self.core.mask_ready.val();
        self.core.out_read.next = self.poa0.ep_strobe.val();
        self.poa0.ep_datain.next = self.core.out_data.val();
        self.poa0.ep_ready.next = self.core.out_ready.val();

        // Sensor port: into okClk through the asynchronous FIFO.
        self.sensor_fifo.write_clock.next = self.sensor_clk.val();
        self.sensor_fifo.read_clock.next = self.host.ok_clk.val();
        self.sensor_fifo.write.next = self.sensor_valid.val() & !self.sensor_fifo.full.val();
        self.sensor_fifo.data_in.next = bit_cast::<32, P>(self.sensor_data.val())
            | (bit_cast::<32, 1>(self.sensor_sop.val().into()) << self.sop_shift.val());
        self.sensor_fifo.read.next = self.core.sensor_read.val();
        self.core.sensor_empty.next = self.sensor_fifo.empty.val();
        self.core.sensor_word.next = self.sensor_fifo.data_out.val();
        self.sensor_sync.clock.next = self.host.ok_clk.val();
        self.sensor_sync.sig_in.next = self.sensor_fifo.overflow.val();
        self.core.sensor_overflow.next = self.sensor_sync.sig_out.val();

        // DDR2 through the MIG.
        self.mig.sys_clk_p.next = self.sys_clkp.val();
        self.mig.sys_clk_n.next = self.sys_clkn.val();
        self.mig.sys_rst.next = false;
        self.mig.port_clk.next = self.host.ok_clk.val();
        self.core.calib_done.next = self.mig.calib_done.val();
        self.mig.cmd_en.next = self.core.cmd_en.val();
        self.mig.cmd_instr.next = self.core.cmd_instr.val();
        self.mig.cmd_bl.next = self.core.cmd_bl.val();
        self.mig.cmd_addr.next = self.core.cmd_addr.val();
        self.core.cmd_full.next = self.mig.cmd_full.val();
        self.mig.wr_en.next = self.core.wr_en.val();
        self.mig.wr_mask.next = self.core.wr_mask.val();
        self.mig.wr_data.next = self.core.wr_data.val();
        self.core.wr_full.next = self.mig.wr_full.val();
        self.mig.rd_en.next = self.core.rd_en.val();
        self.core.rd_data.next = self.mig.rd_data.val();
        self.core.rd_empty.next = self.mig.rd_empty.val();
        Signal::<InOut, Bits<16>>::link(&mut self.ddr2_dq, &mut self.mig.dq);
        Signal::<InOut, Bit>::link(&mut self.ddr2_dqs, &mut self.mig.dqs);
        Signal::<InOut, Bit>::link(&mut self.ddr2_dqs_n, &mut self.mig.dqs_n);
        Signal::<InOut, Bit>::link(&mut self.ddr2_udqs, &mut self.mig.udqs);
        Signal::<InOut, Bit>::link(&mut self.ddr2_udqs_n, &mut self.mig.udqs_n);
        Signal::<InOut, Bit>::link(&mut self.ddr2_rzq, &mut self.mig.rzq);
        Signal::<InOut, Bit>::link(&mut self.ddr2_zio, &mut self.mig.zio);
        self.ddr2_a.next = self.mig.a.val();
        self.ddr2_ba.next = self.mig.ba.val();
        self.ddr2_ras_n.next = self.mig.ras_n.val();
        self.ddr2_cas_n.next = self.mig.cas_n.val();
        self.ddr2_we_n.next = self.mig.we_n.val();
        self.ddr2_odt.next = self.mig.odt.val();
        self.ddr2_cke.next = self.mig.cke.val();
        self.ddr2_dm.next = self.mig.dm.val();
        self.ddr2_udm.next = self.mig.udm.val();
        self.ddr2_ck.next = self.mig.ck.val();
        self.ddr2_ck_n.next = self.mig.ck_n.val();
        self.ddr2_cs_n.next = false;

        // LEDs (active low): the status bits 0..5.
        self.led.next = !self.core.wire_out[0].val().get_bits::<8>(0);
    }
}

    };
}

xem_top!(
    /// The XEM6310 top: pins, FrontPanel endpoints, MIG, sensor port, core.
    /// Port names are the pin names of `constraints/xem6310.ucf`.
    Xem6310Top,
    XemCore,
    MigDdr2
);

xem_top!(
    /// The XEM6310 top of a design whose delay line is on chip (block RAM):
    /// [`Xem6310Top`]'s pins and endpoints around [`XemCoreOnChip`], with
    /// the DDR2 parked ([`ParkedDdr2`]). Port names are the pin names of
    /// `constraints/xem6310.ucf`.
    Xem6310TopOnChip,
    XemCoreOnChip,
    ParkedDdr2
);

/// A small XEM6310 top ([`crate::pipeline::test_back_config`]) for lint.
pub type TestXem = Xem6310Top<4, 6, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11>;
