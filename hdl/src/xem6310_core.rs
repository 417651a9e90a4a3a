//! The XEM6310 core: the whole design between the FrontPanel endpoints of
//! the top ([`crate::xem6310`]) — the register map ([`crate::registers`]),
//! the pipeline with its delay line, the replay and mask pipes and the
//! packet pipe-out.
//!
//! **Simulation.** [`XemCore`] is the unit the co-simulation drives: its
//! ports are the endpoints' user sides (wire values, trigger pulses, pipe
//! strobes) and the MCB user port, so it is simulated against the model with
//! the behavioural MCB ([`crate::testbench::mcb_model::McbModel`]); FrontPanel's
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

use crate::bram::RamStyle;
use crate::bundles::McbPort;
use crate::config::{BackHalfConfig, GatewareError};
use crate::fifo::Fifo;
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
    /// The MCB user port of the DDR2 (idle with the block-RAM delay line).
    pub mcb: McbPort,
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
            mcb: Default::default(),
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
        self.pipe.regs.mask_enable.next = self.wire_in[0].val().get_bit(1);
        self.pipe.regs.n.next = self.wire_in[1].val();
        self.pipe.regs.threshold.next = self.wire_in[2].val();
        self.pipe.regs.l_min.next = self.wire_in[3].val();
        self.pipe.regs.l_max.next = self.wire_in[4].val();
        self.pipe.regs.period.next = self.wire_in[5].val();
        self.pipe.regs.masked.next = self.wire_in[6].val();
        // wire_in::THRESHOLD_HOLD and END_TRIM (checked below the block).
        self.pipe.regs.threshold_hold.next = self.wire_in[7].val();
        self.pipe.regs.end_trim.next = self.wire_in[8].val();
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
        McbPort::link(&mut self.mcb, &mut self.pipe.mcb);

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
