//! The packet's prefix — header and fixed payload — held in byte registers
//! that load once a packet (one clock enable, see [`EnableRegs`]) and are
//! read out a byte a clock: byte `index` through a binary tree of 2:1 byte
//! multiplexers, node i of the heap layout selecting between 2i and 2i + 1
//! by one bit of the index (the leaves are the bytes; past the last byte
//! they read 0). A byte-lane tree, not one wide vector shifted by the
//! index: the same multiplexers without the wide shifts that dominated the
//! packetiser's simulation.
//!
//! `selected` is 0 unless `read`: the tree is computed only while bytes go out,
//! which a simulator then skips on every other clock.

use crate::stream::{lanes, EnableRegs};
use rust_hdl::prelude::*;

/// The prefix registers and their read-out.
#[derive(LogicBlock)]
pub struct PrefixBytes {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Take every `d` at this clock's edge.
    pub load: Signal<In, Bit>,
    /// The bytes to load.
    pub d: Vec<Signal<In, Bits<8>>>,
    /// Bytes are read out this clock.
    pub read: Signal<In, Bit>,
    /// The byte read (0 .. the number of bytes).
    pub index: Signal<In, Bits<16>>,
    /// Byte `index` of the registers if `read`, else 0.
    pub selected: Signal<Out, Bits<8>>,
    regs: EnableRegs<Bits<8>>,
    /// The tree's nodes in heap layout (node 0 unused; leaves from `_leaves`).
    sel_tree: Vec<Signal<Local, Bits<8>>>,
    /// The index bit node i selects by.
    tree_bit: Vec<Constant<Bits<8>>>,
    _bytes: usize,
    /// Leaves of the tree: the power of two at or above `_bytes`.
    _leaves: usize,
}

impl PrefixBytes {
    /// `bytes` byte registers (at least 1).
    pub fn new(bytes: usize) -> Self {
        let leaves = bytes.max(1).next_power_of_two();
        let levels = leaves.trailing_zeros();
        PrefixBytes {
            clock: Default::default(),
            load: Default::default(),
            d: lanes(bytes),
            read: Default::default(),
            index: Default::default(),
            selected: Default::default(),
            regs: EnableRegs::new(bytes),
            sel_tree: lanes(2 * leaves),
            // Node i (depth ⌊log2 i⌋ below the root) selects by bit
            // log2(leaves) − 1 − depth of the index (node 0 is unused).
            tree_bit: (0..leaves)
                .map(|i: usize| {
                    let depth = if i == 0 { 0 } else { i.ilog2() };
                    Constant::new((levels.saturating_sub(1 + depth) as u64).to_bits())
                })
                .collect(),
            _bytes: bytes,
            _leaves: leaves,
        }
    }
}

impl Logic for PrefixBytes {
    #[hdl_gen]
    fn update(&mut self) {
        self.regs.clock.next = self.clock.val();
        // The registers hold between packets without a copy a clock (a
        // clock enable): their next value exists only when they load.
        self.regs.enable.next = self.load.val();
        for j in 0..self._bytes {
            self.regs.d[j].next = 0.into();
            if self.load.val() {
                self.regs.d[j].next = self.d[j].val();
            }
        }
        for j in 0..(2 * self._leaves) {
            self.sel_tree[j].next = 0.into();
        }
        if self.read.val() {
            // (rust-hdl's Verilog indexes with loop variables only.)
            for lv in self._leaves..(self._leaves + 1) {
                for j in 0..self._bytes {
                    self.sel_tree[lv + j].next = self.regs.q[j].val();
                }
            }
            // Deepest nodes first (i = leaves − k), so that the process
            // assigns every node before it reads it.
            for lv in self._leaves..(self._leaves + 1) {
                for k in 1..self._leaves {
                    self.sel_tree[lv - k].next = self.sel_tree[2 * (lv - k)].val();
                    if self
                        .index
                        .val()
                        .get_bit(self.tree_bit[lv - k].val().index())
                    {
                        self.sel_tree[lv - k].next = self.sel_tree[2 * (lv - k) + 1].val();
                    }
                }
            }
        }
        // (Assigned once, outside the branch: see [`super`], outputs
        // without transients.)
        self.selected.next = self.sel_tree[1].val();
    }
}
