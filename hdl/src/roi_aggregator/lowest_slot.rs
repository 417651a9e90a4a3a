//! S0 of the sweep: the lowest slot of a set (bit i: slot i), its index
//! and the set without it (combinational).
//!
//! `taken` (bit i: a slot below i is in the set) is a prefix OR in five
//! doubling steps: a tree a few LUTs deep, where the chain
//! `taken[i + 1] = taken[i] | set[i]` was 32 ORs deep and `set & (!set + 1)`
//! a 32-bit carry chain. The index's bit b is the OR of the one-hot bits
//! whose slot has bit b.

use crate::config::MAX_SLOTS;
use rust_hdl::prelude::*;

// The index is five bits and the masks below are 32 bits wide.
const _: () = assert!(MAX_SLOTS == 32);

/// The lowest slot of a set.
#[derive(LogicBlock)]
pub struct LowestSlot {
    /// The set (bit i: slot i).
    pub slots: Signal<In, Bits<MAX_SLOTS>>,
    /// The lowest slot's index (0 for an empty set).
    pub index: Signal<Out, Bits<5>>,
    /// The set without its lowest slot.
    pub rest: Signal<Out, Bits<MAX_SLOTS>>,
    /// The set is not empty.
    pub any: Signal<Out, Bit>,
    /// Prefix ORs of the set over 2, 4, 8, 16 slots.
    pre1: Signal<Local, Bits<MAX_SLOTS>>,
    pre2: Signal<Local, Bits<MAX_SLOTS>>,
    pre4: Signal<Local, Bits<MAX_SLOTS>>,
    pre8: Signal<Local, Bits<MAX_SLOTS>>,
    /// Bit i: a slot below i is in the set.
    taken: Signal<Local, Bits<MAX_SLOTS>>,
    /// The lowest slot, one-hot.
    lowest: Signal<Local, Bits<MAX_SLOTS>>,
    idx: Signal<Local, Bits<5>>,
    /// Masks of the slots whose index has bit b set, b = 0 … 4.
    idx_b0: Constant<Bits<MAX_SLOTS>>,
    idx_b1: Constant<Bits<MAX_SLOTS>>,
    idx_b2: Constant<Bits<MAX_SLOTS>>,
    idx_b3: Constant<Bits<MAX_SLOTS>>,
    idx_b4: Constant<Bits<MAX_SLOTS>>,
}

impl Default for LowestSlot {
    fn default() -> Self {
        Self::new()
    }
}

impl LowestSlot {
    /// The block (its widths are fixed by [`MAX_SLOTS`]).
    pub fn new() -> Self {
        LowestSlot {
            slots: Default::default(),
            index: Default::default(),
            rest: Default::default(),
            any: Default::default(),
            pre1: Default::default(),
            pre2: Default::default(),
            pre4: Default::default(),
            pre8: Default::default(),
            taken: Default::default(),
            lowest: Default::default(),
            idx: Default::default(),
            idx_b0: Constant::new(0xAAAA_AAAAu64.to_bits()),
            idx_b1: Constant::new(0xCCCC_CCCCu64.to_bits()),
            idx_b2: Constant::new(0xF0F0_F0F0u64.to_bits()),
            idx_b3: Constant::new(0xFF00_FF00u64.to_bits()),
            idx_b4: Constant::new(0xFFFF_0000u64.to_bits()),
        }
    }
}

impl Logic for LowestSlot {
    #[hdl_gen]
    fn update(&mut self) {
        self.pre1.next = self.slots.val() | (self.slots.val() << 1);
        self.pre2.next = self.pre1.val() | (self.pre1.val() << 2);
        self.pre4.next = self.pre2.val() | (self.pre2.val() << 4);
        self.pre8.next = self.pre4.val() | (self.pre4.val() << 8);
        self.taken.next = (self.pre8.val() | (self.pre8.val() << 16)) << 1;
        self.lowest.next = self.slots.val() & !self.taken.val();
        self.idx.next = 0.into();
        self.idx.next = self
            .idx
            .val()
            .replace_bit(0, (self.lowest.val() & self.idx_b0.val()).any());
        self.idx.next = self
            .idx
            .val()
            .replace_bit(1, (self.lowest.val() & self.idx_b1.val()).any());
        self.idx.next = self
            .idx
            .val()
            .replace_bit(2, (self.lowest.val() & self.idx_b2.val()).any());
        self.idx.next = self
            .idx
            .val()
            .replace_bit(3, (self.lowest.val() & self.idx_b3.val()).any());
        self.idx.next = self
            .idx
            .val()
            .replace_bit(4, (self.lowest.val() & self.idx_b4.val()).any());
        // (Each output assigned once: see "Outputs without transients" in
        // the packetiser.)
        self.index.next = self.idx.val();
        self.rest.next = self.slots.val() & self.taken.val();
        self.any.next = self.slots.val().any();
    }
}
