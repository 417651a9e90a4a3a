//! The start of a row's sweep: the slots whose ROI covers raw row `ra` and
//! that sum this plane or start in it (`pre` or `fresh` in their view entry
//! of the plane's parity), bit i: slot i (combinational). The block reads
//! two fields of each entry, which the aggregator cuts from the view.
//!
//! Rows `ay − h … ay + h` cover `ra` iff `0 ≤ (ra + h) − ay ≤ 2h`: one
//! subtraction modulo 2^10 a slot, as a difference below zero wraps to at
//! least 2^10 − 511 > 2h (rows are below 512). Computed only when a row's
//! sweep starts (`enable`), which costs nothing in hardware and saves a
//! simulator the slots' comparisons on the other clocks.

use crate::blink_tracker::COORD_BITS;
use crate::config::MAX_SLOTS;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// The slots a row's sweep visits.
#[derive(LogicBlock)]
pub struct RowCover {
    /// The anchor row `ay` of each entry of the ROI view, `parity·M + slot`.
    pub anchor_rows: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// Each entry's `pre | fresh`: the slot sums this plane or starts in it.
    pub sums_or_starts: Vec<Signal<In, Bit>>,
    /// The plane's parity: which half of the view is read.
    pub parity: Signal<In, Bit>,
    /// `ra + h`: the last ROI row that covers row `ra`.
    pub row_hi: Signal<In, Bits<COORD_BITS>>,
    /// Compute (else `slots` is 0).
    pub enable: Signal<In, Bit>,
    /// Bit i: slot i's ROI covers the row and the slot sums or starts.
    pub slots: Signal<Out, Bits<MAX_SLOTS>>,
    in_roi: Vec<Signal<Local, Bit>>,
    /// `in_roi` packed.
    slot_set: Signal<Local, Bits<MAX_SLOTS>>,
    two_h: Constant<Bits<COORD_BITS>>,
    _m: usize,
}

impl RowCover {
    /// The block for `m` slots (at most [`MAX_SLOTS`]) and ROIs of half
    /// side `h`.
    pub fn new(m: usize, h: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        RowCover {
            anchor_rows: lanes(2 * m),
            sums_or_starts: lanes(2 * m),
            parity: Default::default(),
            row_hi: Default::default(),
            enable: Default::default(),
            slots: Default::default(),
            in_roi: lanes(m),
            slot_set: Default::default(),
            two_h: Constant::new((2 * h as u64).to_bits()),
            _m: m,
        }
    }
}

impl Logic for RowCover {
    #[hdl_gen]
    fn update(&mut self) {
        self.slot_set.next = 0.into();
        for i in 0..self._m {
            self.in_roi[i].next = false;
        }
        if self.enable.val() {
            for mm in self._m..(self._m + 1) {
                for i in 0..self._m {
                    if self.parity.val() {
                        self.in_roi[i].next = self.sums_or_starts[i + mm].val()
                            & ((self.row_hi.val() - self.anchor_rows[i + mm].val())
                                <= self.two_h.val());
                    } else {
                        self.in_roi[i].next = self.sums_or_starts[i].val()
                            & ((self.row_hi.val() - self.anchor_rows[i].val()) <= self.two_h.val());
                    }
                    self.slot_set.next = self.slot_set.val().replace_bit(i, self.in_roi[i].val());
                }
            }
        }
        self.slots.next = self.slot_set.val();
    }
}
