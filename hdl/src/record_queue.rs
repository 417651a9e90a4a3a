//! The record queue: the FIFO of record descriptors between the blink
//! tracker ([`crate::blink_tracker`]) and the packetiser
//! ([`crate::packetiser::Packetiser`]), at most Q records deep so that every
//! queued Blink holds one of the Q spare counter banks
//! ([`crate::bank_pool`]). A sub-block of the packetiser stage (stage 7;
//! its model twin is `model/src/packetiser.rs`).

use crate::bram::RamStyle;
use crate::bundles::RecordPush;
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::fifo::Fifo;
use rust_hdl::prelude::*;

/// The record queue between the tracker and the packetiser: descriptor
/// fields packed into one FIFO entry (`QW = 226 + BW` bits: kind 2, lost 32,
/// slot 8, flags 8, x 16, y 16, t0 48, t1 48, tag 48, bank BW), in
/// distributed RAM. `room` limits it to Q entries (the packetiser's current
/// record included), so that every queued Blink holds one of the Q spare
/// banks.
#[derive(LogicBlock)]
pub struct RecordQueue<const BW: usize, const QAW: usize, const QW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: empty.
    pub restart: Signal<In, Bit>,
    /// The descriptor pushed by the tracker, and the queue's room (fewer
    /// than Q records held).
    pub record: RecordPush<BW>,
    /// The head is valid.
    pub h_valid: Signal<Out, Bit>,
    /// Pop the head.
    pub h_pop: Signal<In, Bit>,
    /// Head kind.
    pub h_kind: Signal<Out, Bits<2>>,
    /// Head lost count.
    pub h_lost: Signal<Out, Bits<32>>,
    /// Head slot.
    pub h_slot: Signal<Out, Bits<8>>,
    /// Head flags.
    pub h_flags: Signal<Out, Bits<8>>,
    /// Head column.
    pub h_x: Signal<Out, Bits<16>>,
    /// Head row.
    pub h_y: Signal<Out, Bits<16>>,
    /// Head t0.
    pub h_t0: Signal<Out, Bits<48>>,
    /// Head t1.
    pub h_t1: Signal<Out, Bits<48>>,
    /// Head tag.
    pub h_tag: Signal<Out, Bits<48>>,
    /// Head bank.
    pub h_bank: Signal<Out, Bits<BW>>,
    /// A push was refused (never expected: the tracker checks `room`).
    pub overflow: Signal<Out, Bit>,
    /// Nothing queued, nothing in flight.
    pub empty: Signal<Out, Bit>,
    fifo: Fifo<QW, QAW>,
    /// `room` as a register: the tracker's walk reads it (its next value
    /// from the count and this clock's push and pop).
    room_r: DFF<Bit>,
    pushed: Signal<Local, Bit>,
    popped: Signal<Local, Bit>,
    depth: Constant<Bits<16>>,
    depth_m1: Constant<Bits<16>>,
}

impl<const BW: usize, const QAW: usize, const QW: usize> RecordQueue<BW, QAW, QW> {
    /// The queue of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        GatewareConfig::check_width("RecordQueue", "BW", BW, cfg.bank_bits())?;
        GatewareConfig::check_width("RecordQueue", "QAW", QAW, cfg.queue_log2)?;
        GatewareConfig::check_width("RecordQueue", "QW", QW, 226 + cfg.bank_bits())?;
        Ok(RecordQueue {
            clock: Default::default(),
            restart: Default::default(),
            record: Default::default(),
            h_valid: Default::default(),
            h_pop: Default::default(),
            h_kind: Default::default(),
            h_lost: Default::default(),
            h_slot: Default::default(),
            h_flags: Default::default(),
            h_x: Default::default(),
            h_y: Default::default(),
            h_t0: Default::default(),
            h_t1: Default::default(),
            h_tag: Default::default(),
            h_bank: Default::default(),
            overflow: Default::default(),
            empty: Default::default(),
            // Block RAM: a record is ~230 bits wide, 78 RAM64M (312 LUTs) of
            // LUT RAM for the SPCImager's 32 records, or four RAMB8s.
            fifo: Fifo::new(RamStyle::Block),
            room_r: Default::default(),
            pushed: Default::default(),
            popped: Default::default(),
            depth: Constant::new((cfg.queue_depth() as u64).to_bits()),
            depth_m1: Constant::new((cfg.queue_depth() as u64 - 1).to_bits()),
        })
    }
}

impl<const BW: usize, const QAW: usize, const QW: usize> Logic for RecordQueue<BW, QAW, QW> {
    #[hdl_gen]
    fn update(&mut self) {
        self.fifo.clock.next = self.clock.val();
        self.fifo.restart.next = self.restart.val();
        self.fifo.push.next = self.record.push.val();
        self.fifo.push_data.next = bit_cast::<QW, 2>(self.record.kind.val())
            | (bit_cast::<QW, 32>(self.record.lost.val()) << 2)
            | (bit_cast::<QW, 8>(self.record.slot.val()) << 34)
            | (bit_cast::<QW, 8>(self.record.flags.val()) << 42)
            | (bit_cast::<QW, 16>(self.record.ax.val()) << 50)
            | (bit_cast::<QW, 16>(self.record.ay.val()) << 66)
            | (bit_cast::<QW, 48>(self.record.t0.val()) << 82)
            | (bit_cast::<QW, 48>(self.record.t1.val()) << 130)
            | (bit_cast::<QW, 48>(self.record.tag.val()) << 178)
            | (bit_cast::<QW, BW>(self.record.bank.val()) << 226);
        self.fifo.pop.next = self.h_pop.val();
        // count' = count + pushed − popped < Q, from the count's compares
        // with constants and the two flags.
        self.room_r.clock.next = self.clock.val();
        self.pushed.next = self.record.push.val() & self.fifo.room.val();
        self.popped.next = self.h_pop.val() & self.fifo.out_valid.val();
        self.room_r.d.next = (self.fifo.count.val() < self.depth_m1.val())
            | ((self.fifo.count.val() == self.depth_m1.val())
                & !(self.pushed.val() & !self.popped.val()))
            | ((self.fifo.count.val() == self.depth.val())
                & self.popped.val()
                & !self.pushed.val());
        if self.restart.val() {
            self.room_r.d.next = true;
        }
        self.record.room.next = self.room_r.q.val();
        self.h_valid.next = self.fifo.out_valid.val();
        self.h_kind.next = self.fifo.out_data.val().get_bits::<2>(0);
        self.h_lost.next = self.fifo.out_data.val().get_bits::<32>(2);
        self.h_slot.next = self.fifo.out_data.val().get_bits::<8>(34);
        self.h_flags.next = self.fifo.out_data.val().get_bits::<8>(42);
        self.h_x.next = self.fifo.out_data.val().get_bits::<16>(50);
        self.h_y.next = self.fifo.out_data.val().get_bits::<16>(66);
        self.h_t0.next = self.fifo.out_data.val().get_bits::<48>(82);
        self.h_t1.next = self.fifo.out_data.val().get_bits::<48>(130);
        self.h_tag.next = self.fifo.out_data.val().get_bits::<48>(178);
        self.h_bank.next = self.fifo.out_data.val().get_bits::<BW>(226);
        self.overflow.next = self.fifo.overflow.val();
        self.empty.next = self.fifo.count.val() == 0;
    }
}
