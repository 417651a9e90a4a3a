//! The decide stage's association of a candidate (the model's
//! `BlinkTracker::associate`, `model/PACKETS.md` §8.2), bit i for slot i:
//! * **absorbed** by a busy slot whose association window holds it
//!   (`near`) and whose track was active at the end of plane t − 1
//!   (`active_before`) or has opened in this plane (`opened`);
//! * otherwise it **opens** a track in the lowest free slot, free at the
//!   end of t − 1 (`free_before`) and not opened since;
//! * with none free, it is **dropped**.
//!
//! The lowest free slot (`open_slot`, one-hot) and whether there is one are
//! registers of the previous clock's flags, which keeps the priority
//! encoder off the decide stage's path. It is right for every decision the
//! tracker makes: after an opening the next candidate is replayed (one
//! clock, no decision), and after a walk comes WalkEnd.

use crate::config::MAX_SLOTS;
use rust_hdl::prelude::*;

/// Absorb, open in the lowest free slot, or drop.
#[derive(LogicBlock, Default)]
pub struct Association {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// A candidate is decided this clock.
    pub candidate: Signal<In, Bit>,
    /// The candidate is in the slot's association window.
    pub near: Signal<In, Bits<MAX_SLOTS>>,
    /// The slot holds a segment.
    pub busy: Signal<In, Bits<MAX_SLOTS>>,
    /// Busy and live at the end of plane t − 1.
    pub active_before: Signal<In, Bits<MAX_SLOTS>>,
    /// Free at the end of plane t − 1.
    pub free_before: Signal<In, Bits<MAX_SLOTS>>,
    /// Opened in this plane.
    pub opened: Signal<In, Bits<MAX_SLOTS>>,
    /// The candidate opens a track in `open_slot`.
    pub open: Signal<Out, Bit>,
    /// The lowest free slot, one-hot (of the previous clock's flags).
    pub open_slot: Signal<Out, Bits<MAX_SLOTS>>,
    /// The candidate is dropped.
    pub drop: Signal<Out, Bit>,
    /// The lowest free slot, one-hot, and whether there is one.
    lowest: DFF<Bits<MAX_SLOTS>>,
    any_free: DFF<Bit>,
    free_now: Signal<Local, Bits<MAX_SLOTS>>,
    absorbed: Signal<Local, Bit>,
}

impl Logic for Association {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, lowest, any_free);
        self.free_now.next = self.free_before.val() & !self.opened.val();
        // x & −x: the lowest set bit.
        self.lowest.d.next = self.free_now.val() & (!self.free_now.val() + 1);
        self.any_free.d.next = self.free_now.val().any();
        self.absorbed.next =
            (self.busy.val() & (self.active_before.val() | self.opened.val()) & self.near.val())
                .any();
        self.open.next = self.candidate.val() & !self.absorbed.val() & self.any_free.q.val();
        self.drop.next = self.candidate.val() & !self.absorbed.val() & !self.any_free.q.val();
        self.open_slot.next = self.lowest.q.val();
    }
}
