//! The compare stage's comparisons (combinational; the tracker registers
//! them with the item): per slot (bit i: slot i),
//! * `near`: the candidate `(cx, cy)` falls in the slot's association
//!   window, the bounds stored when the slot opened (the opening
//!   candidate's own window, [`OpeningWindows`](super::OpeningWindows));
//! * `hits`: the word hits the slot's 3×3 window — the anchor row is
//!   within one of the word's row, and the word is one of the window's two
//!   words with an above bit in that word's lane mask;
//! * `row_end`: the word's row is the one at whose end the window has
//!   streamed (its on/off step, [`OnOffStep`](super::OnOffStep)).
//!
//! Computed only when the stage loads (`enable`; else all 0): in hardware
//! it costs nothing, and in a simulator the slots' comparators are most of
//! the tracker's time while most clocks bring no word. The candidate is
//! the item's, or the one replayed; the word is always the item's.

use super::layout::COORD_BITS;
use crate::config::MAX_SLOTS;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// Every slot against the compare stage's item. `P`: pixels per word.
#[derive(LogicBlock)]
pub struct SlotCompare<const P: usize> {
    /// Each slot's association window: x from at bit 0, x to at 10, y from
    /// at 20, y to at 30 (inclusive).
    pub bounds: Vec<Signal<In, Bits<40>>>,
    /// Each slot's anchor row.
    pub anchor_rows: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// Each slot's window: the word column of its low word.
    pub low_cols: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// The word column of its high word.
    pub high_cols: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// The lanes of the low word in the window.
    pub low_lanes: Vec<Signal<In, Bits<P>>>,
    /// The lanes of the high word in the window.
    pub high_lanes: Vec<Signal<In, Bits<P>>>,
    /// The row at whose end the window has streamed.
    pub end_rows: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// The candidate's column.
    pub cx: Signal<In, Bits<COORD_BITS>>,
    /// The candidate's row.
    pub cy: Signal<In, Bits<COORD_BITS>>,
    /// The word's column (words).
    pub word_col: Signal<In, Bits<COORD_BITS>>,
    /// The word's row.
    pub row: Signal<In, Bits<COORD_BITS>>,
    /// Its row − 1 (0 on row 0) and + 1: the anchor rows whose window it
    /// may hit.
    pub row_m1: Signal<In, Bits<COORD_BITS>>,
    /// See `row_m1`.
    pub row_p1: Signal<In, Bits<COORD_BITS>>,
    /// The word's above bits.
    pub above: Signal<In, Bits<P>>,
    /// Compare (else every output is 0).
    pub enable: Signal<In, Bit>,
    /// Bit i: the candidate is in slot i's association window.
    pub near: Signal<Out, Bits<MAX_SLOTS>>,
    /// Bit i: the word hits slot i's 3×3 window.
    pub hits: Signal<Out, Bits<MAX_SLOTS>>,
    /// Bit i: the word's row ends slot i's window.
    pub row_end: Signal<Out, Bits<MAX_SLOTS>>,
    near_v: Signal<Local, Bits<MAX_SLOTS>>,
    hits_v: Signal<Local, Bits<MAX_SLOTS>>,
    row_end_v: Signal<Local, Bits<MAX_SLOTS>>,
    _m: usize,
}

impl<const P: usize> SlotCompare<P> {
    /// The comparisons of `m` slots (at most [`MAX_SLOTS`]).
    pub fn new(m: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        SlotCompare {
            bounds: lanes(m),
            anchor_rows: lanes(m),
            low_cols: lanes(m),
            high_cols: lanes(m),
            low_lanes: lanes(m),
            high_lanes: lanes(m),
            end_rows: lanes(m),
            cx: Default::default(),
            cy: Default::default(),
            word_col: Default::default(),
            row: Default::default(),
            row_m1: Default::default(),
            row_p1: Default::default(),
            above: Default::default(),
            enable: Default::default(),
            near: Default::default(),
            hits: Default::default(),
            row_end: Default::default(),
            near_v: Default::default(),
            hits_v: Default::default(),
            row_end_v: Default::default(),
            _m: m,
        }
    }
}

impl<const P: usize> Logic for SlotCompare<P> {
    #[hdl_gen]
    fn update(&mut self) {
        self.near_v.next = 0.into();
        self.hits_v.next = 0.into();
        self.row_end_v.next = 0.into();
        if self.enable.val() {
            for i in 0..self._m {
                self.near_v.next = self.near_v.val().replace_bit(
                    i,
                    (self.cx.val() >= self.bounds[i].val().get_bits::<10>(0))
                        & (self.cx.val() <= self.bounds[i].val().get_bits::<10>(10))
                        & (self.cy.val() >= self.bounds[i].val().get_bits::<10>(20))
                        & (self.cy.val() <= self.bounds[i].val().get_bits::<10>(30)),
                );
                self.hits_v.next = self.hits_v.val().replace_bit(
                    i,
                    (self.anchor_rows[i].val() >= self.row_m1.val())
                        & (self.anchor_rows[i].val() <= self.row_p1.val())
                        & (((self.word_col.val() == self.low_cols[i].val())
                            & (self.above.val() & self.low_lanes[i].val()).any())
                            | ((self.word_col.val() == self.high_cols[i].val())
                                & (self.above.val() & self.high_lanes[i].val()).any())),
                );
                self.row_end_v.next = self
                    .row_end_v
                    .val()
                    .replace_bit(i, self.end_rows[i].val() == self.row.val());
            }
        }
        self.near.next = self.near_v.val();
        self.hits.next = self.hits_v.val();
        self.row_end.next = self.row_end_v.val();
    }
}
