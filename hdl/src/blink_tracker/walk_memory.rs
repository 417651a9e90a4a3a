//! The fields that only the tracker's walks read (ages, confirmation,
//! continuation, truncation: one [`WALK_WORD_BITS`]-bit word per slot),
//! in LUT RAM, so that the walk's read stage takes them without a
//! multiplexer over M registers (see [`WalkPipeline`](super::WalkPipeline)).
//!
//! The read stage's slot moves on by one slot a clock, or stays. The word
//! must be there in the clock the stage is at a slot, without the read
//! address waiting on whether it moves on (that decision is behind the W2
//! stage's back-pressure), so two copies are read a clock ahead: `mem` at
//! the stage's slot, `mem_next` at the slot after it; `adv` picks one. The
//! one exception is a single slot, where a walk's last step writes slot 0
//! in the clock the next walk issues its read of slot 0: the word written
//! is forwarded (`fwd`; for M > 1 synthesis removes the bypass).

use crate::bram::{Bram, RamStyle};
use rust_hdl::prelude::*;

/// Bits of a slot's walk word: 0–17 age, 18–35 dage, 36 conf, 37 cont,
/// 38 trunc.
pub const WALK_WORD_BITS: usize = 39;

/// The walks' per-slot words.
#[derive(LogicBlock)]
pub struct WalkMemory {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: the read stage goes to slot 0.
    pub restart: Signal<In, Bit>,
    /// The read stage's slot.
    pub slot: Signal<In, Bits<8>>,
    /// The read stage's slot on the next clock.
    pub slot_next: Signal<In, Bits<8>>,
    /// The read stage moves on to the next slot (0 after the last).
    pub advance: Signal<In, Bit>,
    /// The word of `slot`, read a clock ahead.
    pub word: Signal<Out, Bits<WALK_WORD_BITS>>,
    /// Write `write_data` to slot `write_slot`.
    pub write_enable: Signal<In, Bit>,
    /// The slot written.
    pub write_slot: Signal<In, Bits<8>>,
    /// Its word.
    pub write_data: Signal<In, Bits<WALK_WORD_BITS>>,
    mem: Bram<WALK_WORD_BITS, 8>,
    /// A copy of `mem` (written with it), read at the slot after `slot`:
    /// 39 × M bits of LUT RAM for a shallower path.
    mem_next: Bram<WALK_WORD_BITS, 8>,
    /// The read stage moved on a clock ago: the word is `mem_next`'s.
    adv: DFF<Bit>,
    /// The read is of the slot written a clock ago (one slot only).
    fwd: DFF<Bit>,
    /// The word written a clock ago.
    last: DFF<Bits<WALK_WORD_BITS>>,
    last_slot: Constant<Bits<8>>,
    one_slot: Constant<Bit>,
}

impl WalkMemory {
    /// The words of `m` slots (`1 ..= 256`; the tracker has checked it).
    pub fn new(m: usize) -> Self {
        WalkMemory {
            clock: Default::default(),
            restart: Default::default(),
            slot: Default::default(),
            slot_next: Default::default(),
            advance: Default::default(),
            word: Default::default(),
            write_enable: Default::default(),
            write_slot: Default::default(),
            write_data: Default::default(),
            mem: Bram::new(m, RamStyle::Distributed),
            mem_next: Bram::new(m, RamStyle::Distributed),
            adv: Default::default(),
            fwd: Default::default(),
            last: Default::default(),
            last_slot: Constant::new((m as u64 - 1).to_bits()),
            one_slot: Constant::new(m == 1),
        }
    }
}

impl Logic for WalkMemory {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, adv, fwd, last);
        self.mem.clock.next = self.clock.val();
        self.mem_next.clock.next = self.clock.val();
        self.mem.write_address.next = self.write_slot.val();
        self.mem.write_enable.next = self.write_enable.val();
        self.mem.write_data.next = self.write_data.val();
        self.mem_next.write_address.next = self.write_slot.val();
        self.mem_next.write_enable.next = self.write_enable.val();
        self.mem_next.write_data.next = self.write_data.val();

        self.word.next = self.mem.read_data.val();
        if self.adv.q.val() {
            self.word.next = self.mem_next.read_data.val();
        }
        if self.fwd.q.val() {
            self.word.next = self.last.q.val();
        }

        // Read the word of the slot the stage is at on the next clock: the
        // slot itself (or 0 at a restart) unless it moves on.
        self.mem.read_address.next = self.slot.val();
        if self.restart.val() {
            self.mem.read_address.next = 0.into();
        }
        self.mem_next.read_address.next = self.slot.val() + 1;
        if self.slot.val() == self.last_slot.val() {
            self.mem_next.read_address.next = 0.into();
        }
        self.adv.d.next = self.advance.val() & !self.restart.val();
        self.fwd.d.next = self.one_slot.val()
            & self.write_enable.val()
            & (self.slot_next.val() == self.write_slot.val());
        self.last.d.next = self.write_data.val();
    }
}
