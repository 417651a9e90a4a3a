//! The tracker's record port: the record descriptor it pushes into the
//! record queue (`model/PACKETS.md` §3, §8.7), one at a time, each asked for
//! by a state of the tracker:
//! * StreamStart (`stream_start`), pushed once the queue has room (the tracker
//!   waits for it);
//! * a Blink (`blink`), the slot that W2 of the walk holds: pushed if the
//!   queue has room and the free list shows a bank (the slot takes that
//!   bank: `fb_pop`), otherwise lost. Its tag, the plane whose sweep makes
//!   its counts final, is t, or t − 1 for the stream end's segments
//!   (`emit`: t has gone one past the last drain plane);
//! * the plane's Dropped record (`walk_end` with a nonzero `plane_drops`),
//!   pushed if the queue has room, otherwise lost;
//! * StreamEnd (`stream_end`), pushed once the queue has room.
//!
//! Every record carries `lost`, the records lost since the previous one
//! pushed (the packetiser reports them in an Overflow record ahead of it):
//! a lost Blink or Dropped record adds one, a pushed Blink, Dropped or
//! StreamEnd starts it over, and so does `restart`. (StreamStart is the
//! stream's first record: its count is the restart's zero.)

use super::layout::COORD_BITS;
use crate::bundles::RecordPushOut;
use rust_hdl::prelude::*;

/// Kinds of the record descriptors the tracker pushes (see [`crate::packetiser`]).
pub mod record_kind {
    /// StreamStart.
    pub const START: u64 = 0;
    /// Blink.
    pub const BLINK: u64 = 1;
    /// Dropped.
    pub const DROPPED: u64 = 2;
    /// StreamEnd.
    pub const END: u64 = 3;
}

/// The record descriptor the tracker asks for, and the lost-record count.
/// `BW`: bits of a counter-bank index.
#[derive(LogicBlock, Default)]
pub struct RecordPort<const BW: usize> {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: no record lost.
    pub restart: Signal<In, Bit>,
    /// The descriptor, and the queue's room.
    pub record: RecordPushOut<BW>,
    /// A free counter bank is shown.
    pub fb_valid: Signal<In, Bit>,
    /// The Blink is pushed with the free bank: the slot takes it.
    pub fb_pop: Signal<Out, Bit>,
    /// The plane t being tracked.
    pub t: Signal<In, Bits<48>>,
    /// Push StreamStart (waits for room).
    pub stream_start: Signal<In, Bit>,
    /// Push the walked slot's Blink (or lose it).
    pub blink: Signal<In, Bit>,
    /// The Blink is one of the stream end's segments: tag t − 1.
    pub emit: Signal<In, Bit>,
    /// Its slot.
    pub slot: Signal<In, Bits<8>>,
    /// Its flags.
    pub flags: Signal<In, Bits<8>>,
    /// Its anchor column.
    pub ax: Signal<In, Bits<COORD_BITS>>,
    /// Its anchor row.
    pub ay: Signal<In, Bits<COORD_BITS>>,
    /// Its t_cross.
    pub t_cross: Signal<In, Bits<48>>,
    /// Its t_drop.
    pub t_drop: Signal<In, Bits<48>>,
    /// Its counter bank.
    pub bank: Signal<In, Bits<BW>>,
    /// The end of plane t: push its Dropped record if it dropped candidates
    /// (or lose it).
    pub walk_end: Signal<In, Bit>,
    /// Candidates dropped in plane t.
    pub plane_drops: Signal<In, Bits<32>>,
    /// The column of the first.
    pub first_x: Signal<In, Bits<COORD_BITS>>,
    /// Its row.
    pub first_y: Signal<In, Bits<COORD_BITS>>,
    /// Push StreamEnd (waits for room).
    pub stream_end: Signal<In, Bit>,
    /// Records lost since the last one pushed.
    lost: DFF<Bits<32>>,
    /// The Dropped record is asked for.
    dropped: Signal<Local, Bit>,
}

impl<const BW: usize> Logic for RecordPort<BW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, lost);
        self.dropped.next = self.walk_end.val() & (self.plane_drops.val() != 0);
        self.record.push.next = false;
        self.record.kind.next = 0.into(); // record_kind::START
        self.record.lost.next = self.lost.q.val();
        self.record.slot.next = 0.into();
        self.record.flags.next = 0.into();
        self.record.ax.next = 0.into();
        self.record.ay.next = 0.into();
        self.record.t0.next = 0.into();
        self.record.t1.next = 0.into();
        self.record.bank.next = 0.into();
        self.record.tag.next = self.t.val();
        self.fb_pop.next = false;
        if self.stream_start.val() & self.record.room.val() {
            self.record.push.next = true;
        }
        if self.blink.val() {
            self.record.kind.next = 1.into(); // record_kind::BLINK
            self.record.slot.next = self.slot.val();
            self.record.flags.next = self.flags.val();
            self.record.ax.next = bit_cast::<16, COORD_BITS>(self.ax.val());
            self.record.ay.next = bit_cast::<16, COORD_BITS>(self.ay.val());
            self.record.t0.next = self.t_cross.val();
            self.record.t1.next = self.t_drop.val();
            self.record.bank.next = self.bank.val();
            if self.emit.val() {
                self.record.tag.next = self.t.val() - 1;
            }
            if self.record.room.val() & self.fb_valid.val() {
                self.record.push.next = true;
                self.lost.d.next = 0.into();
                self.fb_pop.next = true;
            } else {
                self.lost.d.next = self.lost.q.val() + 1;
            }
        }
        if self.dropped.val() {
            self.record.kind.next = 2.into(); // record_kind::DROPPED
            self.record.ax.next = bit_cast::<16, COORD_BITS>(self.first_x.val());
            self.record.ay.next = bit_cast::<16, COORD_BITS>(self.first_y.val());
            self.record.t0.next = self.t.val();
            self.record.t1.next = bit_cast::<48, 32>(self.plane_drops.val());
            if self.record.room.val() {
                self.record.push.next = true;
                self.lost.d.next = 0.into();
            } else {
                self.lost.d.next = self.lost.q.val() + 1;
            }
        }
        if self.stream_end.val() & self.record.room.val() {
            self.record.push.next = true;
            self.record.kind.next = 3.into(); // record_kind::END
            self.lost.d.next = 0.into();
        }
        if self.restart.val() {
            self.lost.d.next = 0.into();
        }
    }
}
