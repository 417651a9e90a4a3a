//! Sequence numbers and the records lost (`model/PACKETS.md` §5,
//! "Sequence numbers and overflow"): every record but Overflow takes the next number,
//! from `seq_init` at stream start. A record lost before the packetiser
//! (the tracker's record queue was full: `lost` on the next record taken)
//! or dropped by it (no room in the output FIFO) consumes its number and
//! is counted as pending; the first pending number is kept. The Overflow
//! packet that announces them (first lost number, count) takes no number,
//! and once it is out nothing is pending.
//!
//! Commands, one a clock at most (the packetiser's states):
//! * `take`: a record is taken (Idle); the `lost` before it consume their
//!   numbers and, if any, are pending;
//! * `dropped`: the record is dropped (Decide without room): one more pending
//!   (its number is consumed by `advance`);
//! * `announced`: the Overflow packet is out;
//! * `advance`: the record is done (Finish): the next number.
//!
//! `overflowed` is sticky from the first loss to the next stream start.

use rust_hdl::prelude::*;

/// The next sequence number and the pending lost records.
#[derive(LogicBlock, Default)]
pub struct SequenceNumbers {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: next number `seq_init`, nothing pending.
    pub restart: Signal<In, Bit>,
    /// First sequence number of the stream.
    pub seq_init: Signal<In, Bits<32>>,
    /// A record is taken.
    pub take: Signal<In, Bit>,
    /// Records lost just before the record taken.
    pub lost: Signal<In, Bits<32>>,
    /// The record is dropped.
    pub dropped: Signal<In, Bit>,
    /// The Overflow packet is out.
    pub announced: Signal<In, Bit>,
    /// The record is done.
    pub advance: Signal<In, Bit>,
    /// The record's sequence number.
    pub seq: Signal<Out, Bits<32>>,
    /// The first pending lost number.
    pub lost_first: Signal<Out, Bits<32>>,
    /// Lost records pending (0: none).
    pub lost_count: Signal<Out, Bits<32>>,
    /// Records are pending: an Overflow packet goes first.
    pub pending: Signal<Out, Bit>,
    /// Records were lost since stream start.
    pub overflowed: Signal<Out, Bit>,
    seq_ctr: DFF<Bits<32>>,
    pend_first: DFF<Bits<32>>,
    pend_cnt: DFF<Bits<32>>,
    ovf_flag: DFF<Bit>,
}

impl Logic for SequenceNumbers {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, seq_ctr, pend_first, pend_cnt, ovf_flag);
        if self.take.val() {
            if self.lost.val() != 0 {
                self.ovf_flag.d.next = true;
                if self.pend_cnt.q.val() == 0 {
                    self.pend_first.d.next = self.seq_ctr.q.val();
                }
                self.pend_cnt.d.next = self.pend_cnt.q.val() + self.lost.val();
            }
            self.seq_ctr.d.next = self.seq_ctr.q.val() + self.lost.val();
        }
        if self.dropped.val() {
            self.ovf_flag.d.next = true;
            if self.pend_cnt.q.val() == 0 {
                self.pend_first.d.next = self.seq_ctr.q.val();
            }
            self.pend_cnt.d.next = self.pend_cnt.q.val() + 1;
        }
        if self.announced.val() {
            self.pend_cnt.d.next = 0.into();
        }
        if self.advance.val() {
            self.seq_ctr.d.next = self.seq_ctr.q.val() + 1;
        }
        if self.restart.val() {
            self.seq_ctr.d.next = self.seq_init.val();
            self.pend_cnt.d.next = 0.into();
            self.ovf_flag.d.next = false;
        }
        self.seq.next = self.seq_ctr.q.val();
        self.lost_first.next = self.pend_first.q.val();
        self.lost_count.next = self.pend_cnt.q.val();
        self.pending.next = self.pend_cnt.q.val() != 0;
        self.overflowed.next = self.ovf_flag.q.val();
    }
}
