//! The free list of the ROI aggregator's counter banks
//! ([`crate::roi_aggregator`]): a completed segment hands its bank to the
//! record queue and its slot takes a free one; the packetiser returns a
//! bank once it has sent the record's counts.

use crate::bram::RamStyle;
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::fifo::Fifo;
use rust_hdl::prelude::*;

/// The free list of counter banks. Slot i owns bank i from stream start;
/// banks M … M+Q−1 are handed out first, then the banks the packetiser
/// returned (a FIFO of Q entries: at most Q banks are ever outside the slots).
#[derive(LogicBlock)]
pub struct BankPool<const BW: usize, const QAW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: all spare banks free.
    pub restart: Signal<In, Bit>,
    /// A bank is available.
    pub valid: Signal<Out, Bit>,
    /// The bank.
    pub bank: Signal<Out, Bits<BW>>,
    /// Take it.
    pub pop: Signal<In, Bit>,
    /// Return a bank.
    pub ret: Signal<In, Bit>,
    /// The bank returned.
    pub ret_bank: Signal<In, Bits<BW>>,
    fresh: DFF<Bits<BW>>,
    left: DFF<Bits<16>>,
    /// `left ≠ 0`, as a register: `valid` then costs the tracker one LUT.
    any_left: DFF<Bit>,
    fifo: Fifo<BW, QAW>,
    first: Constant<Bits<BW>>,
    spare: Constant<Bits<16>>,
}

impl<const BW: usize, const QAW: usize> BankPool<BW, QAW> {
    /// The pool of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        GatewareConfig::check_width("BankPool", "BW", BW, cfg.bank_bits())?;
        GatewareConfig::check_width("BankPool", "QAW", QAW, cfg.queue_log2)?;
        Ok(BankPool {
            clock: Default::default(),
            restart: Default::default(),
            valid: Default::default(),
            bank: Default::default(),
            pop: Default::default(),
            ret: Default::default(),
            ret_bank: Default::default(),
            fresh: Default::default(),
            left: Default::default(),
            any_left: Default::default(),
            fifo: Fifo::new(RamStyle::Distributed),
            first: Constant::new((cfg.slots as u64).to_bits()),
            spare: Constant::new((cfg.queue_depth() as u64).to_bits()),
        })
    }
}

impl<const BW: usize, const QAW: usize> Logic for BankPool<BW, QAW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, fresh, left, any_left);
        self.fifo.clock.next = self.clock.val();
        self.fifo.restart.next = self.restart.val();
        self.fifo.push.next = self.ret.val();
        self.fifo.push_data.next = self.ret_bank.val();
        self.fifo.pop.next = false;
        if self.any_left.q.val() {
            self.valid.next = true;
            self.bank.next = self.fresh.q.val();
            if self.pop.val() {
                self.fresh.d.next = self.fresh.q.val() + 1;
                self.left.d.next = self.left.q.val() - 1;
                self.any_left.d.next = self.left.q.val() != 1;
            }
        } else {
            self.valid.next = self.fifo.out_valid.val();
            self.bank.next = self.fifo.out_data.val();
            self.fifo.pop.next = self.pop.val();
        }
        if self.restart.val() {
            self.fresh.d.next = self.first.val();
            self.left.d.next = self.spare.val();
            self.any_left.d.next = self.spare.val() != 0;
        }
    }
}
