//! W2's gate: when the tracker acts on the slot that W2 of the walk holds
//! ([`WalkPipeline`](super::WalkPipeline)), and whether that makes a Blink
//! record. One write enable per walk, each for W2's `valid` slot in its
//! state:
//! * the end of a plane (`end_of_plane`) and of a drain plane (`drain`)
//!   wait until the sweep has finished plane t − 1 (`view_free`), whose
//!   ROI view the walk overwrites. The gate registers `view_free`: a clock
//!   old is soon enough, as t changes only at the end of a walk, two
//!   stages before W2 can act again;
//! * a Blink — a completed segment (`comp`) at the end of a plane, a busy
//!   slot (`was_busy`) in the stream end's `emit` — waits for its fresh
//!   bank when the record queue has `room` but the free list shows no bank
//!   (`bank_wait`). The bank of the record the packetiser has just finished
//!   is on its way back (the queue counts that record until it is popped,
//!   the free list shows the bank a few clocks later), so the walk waits
//!   for it rather than lose the record. Room in the queue means at most
//!   Q − 1 queued Blinks, so one of the Q spare banks is free or returning.
//!   With the queue full the Blink goes ahead and is lost (and counted:
//!   see [`RecordPort`](super::RecordPort));
//! * the stream end's `finish` never waits.
//!
//! The walk then writes the slot's flags and words, and its word goes back
//! to the walk memory (`write_back`), except in `emit`, the last walk.

use rust_hdl::prelude::*;

/// The write enables of W2's slot, its Blink, and the wait for a bank.
#[derive(LogicBlock, Default)]
pub struct WalkGate {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// The tracker is in the walk at the end of a plane.
    pub end_of_plane: Signal<In, Bit>,
    /// … in the stream end's `finish`.
    pub finish: Signal<In, Bit>,
    /// … in the walk at the end of a drain plane.
    pub drain: Signal<In, Bit>,
    /// … in the stream end's `emit` of the finished segments.
    pub emit: Signal<In, Bit>,
    /// The sweep has finished plane t − 1 (the tracker's `swept ≥ t`).
    pub view_free: Signal<In, Bit>,
    /// W2 holds a slot.
    pub valid: Signal<In, Bit>,
    /// W2's slot completes its segment at the end of this plane.
    pub comp: Signal<In, Bit>,
    /// W2's slot was busy when the walk read it.
    pub was_busy: Signal<In, Bit>,
    /// The record queue has room.
    pub room: Signal<In, Bit>,
    /// The free list shows a bank.
    pub fb_valid: Signal<In, Bit>,
    /// The end of a plane writes W2's slot.
    pub we_walk: Signal<Out, Bit>,
    /// `finish` writes W2's slot.
    pub we_fin: Signal<Out, Bit>,
    /// The end of a drain plane writes W2's slot.
    pub we_drain: Signal<Out, Bit>,
    /// `emit` writes W2's slot.
    pub we_emit: Signal<Out, Bit>,
    /// W2's slot makes a Blink record.
    pub blink: Signal<Out, Bit>,
    /// The walk holds a Blink for its bank this clock.
    pub bank_wait: Signal<Out, Bit>,
    /// W2's slot is done (any of the four writes).
    pub done: Signal<Out, Bit>,
    /// W2's word goes back to the walk memory.
    pub write_back: Signal<Out, Bit>,
    /// `view_free` a clock ago.
    vf: DFF<Bit>,
    /// W2's slot makes a Blink if it goes ahead.
    need_bank: Signal<Local, Bit>,
}

impl Logic for WalkGate {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, vf);
        self.vf.d.next = self.view_free.val();
        self.need_bank.next = self.valid.val()
            & ((self.end_of_plane.val() & self.vf.q.val() & self.comp.val())
                | (self.emit.val() & self.was_busy.val()));
        self.bank_wait.next = self.need_bank.val() & self.room.val() & !self.fb_valid.val();
        self.we_walk.next =
            self.valid.val() & self.end_of_plane.val() & self.vf.q.val() & !self.bank_wait.val();
        self.we_fin.next = self.valid.val() & self.finish.val();
        self.we_drain.next = self.valid.val() & self.drain.val() & self.vf.q.val();
        self.we_emit.next = self.valid.val() & self.emit.val() & !self.bank_wait.val();
        self.blink.next =
            (self.we_walk.val() & self.comp.val()) | (self.we_emit.val() & self.was_busy.val());
        self.done.next =
            self.we_walk.val() | self.we_fin.val() | self.we_drain.val() | self.we_emit.val();
        self.write_back.next = self.we_walk.val() | self.we_fin.val() | self.we_drain.val();
    }
}
