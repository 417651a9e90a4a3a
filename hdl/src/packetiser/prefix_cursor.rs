//! The read-out of a packet's prefix ([`super::PrefixBytes`]): the index of
//! the byte that goes out this clock, and whether it is the prefix's last
//! (a register, so that the packetiser's Ovf and Emit states decide
//! without a compare).
//!
//! `start` starts a prefix whose first byte goes out next clock, with
//! `rest` bytes after it; `step` sends this clock's byte. `start` wins over
//! `step`. A prefix has two bytes or more (every one of `model/PACKETS.md`
//! has 18 or more), so its first byte is never its last.

use rust_hdl::prelude::*;

/// The prefix's byte index and last-byte flag.
#[derive(LogicBlock, Default)]
pub struct PrefixCursor {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// A prefix starts: its first byte goes out next clock.
    pub start: Signal<In, Bit>,
    /// With `start`: the prefix's bytes after its first (1 or more).
    pub rest: Signal<In, Bits<16>>,
    /// The byte `index` goes out this clock.
    pub step: Signal<In, Bit>,
    /// The byte of this clock (0 first).
    pub index: Signal<Out, Bits<16>>,
    /// The byte of this clock is the prefix's last.
    pub last: Signal<Out, Bit>,
    idx: DFF<Bits<16>>,
    /// Bytes after the one of this clock (down-counted).
    left: DFF<Bits<16>>,
    is_last: DFF<Bit>,
}

impl Logic for PrefixCursor {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, idx, left, is_last);
        if self.step.val() {
            self.idx.d.next = self.idx.q.val() + 1;
            self.left.d.next = self.left.q.val() - 1;
            self.is_last.d.next = self.left.q.val() == 1;
        }
        if self.start.val() {
            self.idx.d.next = 0.into();
            self.left.d.next = self.rest.val();
            self.is_last.d.next = false;
        }
        self.index.next = self.idx.q.val();
        self.last.next = self.is_last.q.val();
    }
}
