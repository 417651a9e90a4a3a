//! SV of the sweep: one entry of the tracker's ROI view, through a binary
//! multiplexer of 2:1 steps, one per index bit (combinational). Grouped in
//! pairs the steps map to 4:1 multiplexers, a LUT each; the AND-OR over a
//! one-hot select it replaces made the SPCImager 150× aggregator 2,890
//! rather than 2,159 LUTs (`cargo run -p smartagg-hdl --release --example
//! resources -- agg150`, `abc-d7`, with the aggregator's subtraction for
//! the slots' rows).
//!
//! Level 0 holds the 64 entries at `parity·32 + slot` (absent slots read
//! 0); levels 1 … 5 halve it by bits 0 … 4 of the index, and bit 5 picks
//! the root. Computed only for a valid index: nothing in hardware, and a
//! simulator skips the 127 words on the other clocks.

use crate::config::MAX_SLOTS;
use crate::stream::lanes;
use rust_hdl::prelude::*;

// Literal offsets below (32 = MAX_SLOTS), for hdl_gen.
const _: () = assert!(MAX_SLOTS == 32);

/// One entry of the ROI view.
#[derive(LogicBlock)]
pub struct ViewMux {
    /// The view's entries, `parity·M + slot` (the tracker's layout).
    pub entries: Vec<Signal<In, Bits<64>>>,
    /// Read an entry (else `entry` is 0).
    pub valid: Signal<In, Bit>,
    /// The entry: bit 5 the plane's parity, bits 0–4 the slot.
    pub index: Signal<In, Bits<6>>,
    /// The entry read (0 for a slot ≥ M).
    pub entry: Signal<Out, Bits<64>>,
    vm0: Vec<Signal<Local, Bits<64>>>,
    vm1: Vec<Signal<Local, Bits<64>>>,
    vm2: Vec<Signal<Local, Bits<64>>>,
    vm3: Vec<Signal<Local, Bits<64>>>,
    vm4: Vec<Signal<Local, Bits<64>>>,
    vm5: Vec<Signal<Local, Bits<64>>>,
    root: Signal<Local, Bits<64>>,
    _m: usize,
}

impl ViewMux {
    /// The multiplexer of a view of `m` slots (at most [`MAX_SLOTS`]).
    pub fn new(m: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        ViewMux {
            entries: lanes(2 * m),
            valid: Default::default(),
            index: Default::default(),
            entry: Default::default(),
            vm0: lanes(2 * MAX_SLOTS),
            vm1: lanes(MAX_SLOTS),
            vm2: lanes(MAX_SLOTS / 2),
            vm3: lanes(MAX_SLOTS / 4),
            vm4: lanes(MAX_SLOTS / 8),
            vm5: lanes(MAX_SLOTS / 16),
            root: Default::default(),
            _m: m,
        }
    }
}

impl Logic for ViewMux {
    #[hdl_gen]
    fn update(&mut self) {
        for n in 0..64 {
            self.vm0[n].next = 0.into();
        }
        for n in 0..32 {
            self.vm1[n].next = 0.into();
        }
        for n in 0..16 {
            self.vm2[n].next = 0.into();
        }
        for n in 0..8 {
            self.vm3[n].next = 0.into();
        }
        for n in 0..4 {
            self.vm4[n].next = 0.into();
        }
        for n in 0..2 {
            self.vm5[n].next = 0.into();
        }
        if self.valid.val() {
            for mm in self._m..(self._m + 1) {
                for i in 0..self._m {
                    self.vm0[i].next = self.entries[i].val();
                    self.vm0[i + 32].next = self.entries[i + mm].val();
                }
            }
            for n in 0..32 {
                self.vm1[n].next = self.vm0[2 * n].val();
                if self.index.val().get_bit(0) {
                    self.vm1[n].next = self.vm0[2 * n + 1].val();
                }
            }
            for n in 0..16 {
                self.vm2[n].next = self.vm1[2 * n].val();
                if self.index.val().get_bit(1) {
                    self.vm2[n].next = self.vm1[2 * n + 1].val();
                }
            }
            for n in 0..8 {
                self.vm3[n].next = self.vm2[2 * n].val();
                if self.index.val().get_bit(2) {
                    self.vm3[n].next = self.vm2[2 * n + 1].val();
                }
            }
            for n in 0..4 {
                self.vm4[n].next = self.vm3[2 * n].val();
                if self.index.val().get_bit(3) {
                    self.vm4[n].next = self.vm3[2 * n + 1].val();
                }
            }
            for n in 0..2 {
                self.vm5[n].next = self.vm4[2 * n].val();
                if self.index.val().get_bit(4) {
                    self.vm5[n].next = self.vm4[2 * n + 1].val();
                }
            }
        }
        self.root.next = self.vm5[0].val();
        if self.index.val().get_bit(5) {
            self.root.next = self.vm5[1].val();
        }
        self.entry.next = self.root.val();
    }
}
