//! The tracker's compare stage (see "Pipeline" in [`super`]'s doc): the
//! item of the item stage against every slot ([`SlotCompare`]) and what an
//! opening by its candidate would write ([`OpeningWindows`]), registered
//! with the item for the decide stage, one item per clock.
//!
//! The flow between the three stages is the stage's too:
//! * the decide stage takes the stage's item (`go`) in Run unless it is
//!   replayed;
//! * the stage takes the item stage's item (`take`) when it is empty or
//!   its item is decided, except in the clock that decides the plane's last
//!   item (an item that ends the field's last row): that item may open a
//!   track, and the next plane's words must be compared with the opened
//!   slot's window, so the stage takes them a clock later;
//! * a candidate taken in the clock of an opening was compared without the
//!   opened slot's window: it is compared again (`replay`, one clock, the
//!   comparisons only) before it is decided.

use super::layout::{slot_word, COORD_BITS};
use super::{OpeningWindows, SlotCompare};
use crate::config::{BackHalfConfig, MAX_SLOTS};
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// The compare stage of the blink tracker. `P`: pixels per word.
#[derive(LogicBlock)]
pub struct CompareStage<const P: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: the stage is empty, no replay.
    pub restart: Signal<In, Bit>,
    /// The tracker is in Run: the decide stage takes items.
    pub run: Signal<In, Bit>,
    /// The decide stage opens a track this clock.
    pub open: Signal<In, Bit>,
    /// The item stage holds an item.
    pub item_valid: Signal<In, Bit>,
    /// It is a candidate.
    pub item_cand: Signal<In, Bit>,
    /// It is its word's last item.
    pub item_last: Signal<In, Bit>,
    /// Its word ends its row.
    pub item_eor: Signal<In, Bit>,
    /// Its row is the field's last.
    pub item_lastrow: Signal<In, Bit>,
    /// The candidate's column (pixels).
    pub item_cx: Signal<In, Bits<COORD_BITS>>,
    /// Its row (the word's).
    pub item_cy: Signal<In, Bits<COORD_BITS>>,
    /// The word's column (words).
    pub item_word_col: Signal<In, Bits<COORD_BITS>>,
    /// Its row − 1 (0 on row 0).
    pub item_row_m1: Signal<In, Bits<COORD_BITS>>,
    /// Its row + 1.
    pub item_row_p1: Signal<In, Bits<COORD_BITS>>,
    /// Its above bits.
    pub item_above: Signal<In, Bits<P>>,
    /// Each slot's `geo` word ([`slot_word`](super::slot_word)).
    pub slot_geo: Vec<Signal<In, Bits<64>>>,
    /// Each slot's lane masks (low word at bit 0, high word at bit 32).
    pub slot_win: Vec<Signal<In, Bits<64>>>,
    /// Each slot's association window (x from at bit 0, x to at 10, y
    /// from at 20, y to at 30).
    pub slot_bnd: Vec<Signal<In, Bits<64>>>,
    /// The stage takes the item stage's item this clock.
    pub take: Signal<Out, Bit>,
    /// The decide stage takes the stage's item this clock.
    pub go: Signal<Out, Bit>,
    /// `go` with a candidate: it is associated this clock.
    pub candidate: Signal<Out, Bit>,
    /// `go` with the last item of a word that ends its row: the on/off step
    /// of the slots whose window ends there.
    pub step: Signal<Out, Bit>,
    /// The stage's item is on the field's last row.
    pub lastrow: Signal<Out, Bit>,
    /// Its candidate's column.
    pub cx: Signal<Out, Bits<COORD_BITS>>,
    /// Its row.
    pub cy: Signal<Out, Bits<COORD_BITS>>,
    /// Bit i: the candidate is in slot i's association window.
    pub near: Signal<Out, Bits<MAX_SLOTS>>,
    /// Bit i: the word hits slot i's 3×3 window.
    pub hits: Signal<Out, Bits<MAX_SLOTS>>,
    /// Bit i: the word's row ends slot i's window.
    pub row_end: Signal<Out, Bits<MAX_SLOTS>>,
    /// What an opening by the candidate writes: the `geo` word without
    /// its bank, the lane masks, the ROI view entry without its bank, the
    /// association window.
    pub open_geo: Signal<Out, Bits<64>>,
    /// See `open_geo`.
    pub open_win: Signal<Out, Bits<64>>,
    /// See `open_geo`.
    pub open_view: Signal<Out, Bits<64>>,
    /// See `open_geo`.
    pub open_bnd: Signal<Out, Bits<64>>,
    slots: SlotCompare<P>,
    opening: OpeningWindows<P>,
    valid: DFF<Bit>,
    cand: DFF<Bit>,
    last: DFF<Bit>,
    eor: DFF<Bit>,
    r_lastrow: DFF<Bit>,
    r_cx: DFF<Bits<COORD_BITS>>,
    r_cy: DFF<Bits<COORD_BITS>>,
    r_near: DFF<Bits<MAX_SLOTS>>,
    r_hits: DFF<Bits<MAX_SLOTS>>,
    r_row_end: DFF<Bits<MAX_SLOTS>>,
    r_geo: DFF<Bits<64>>,
    r_win: DFF<Bits<64>>,
    r_view: DFF<Bits<64>>,
    r_bnd: DFF<Bits<64>>,
    /// The item was compared before the opening of the previous clock:
    /// compare it again rather than decide it.
    replay: DFF<Bit>,
    /// The decide stage takes the plane's last item.
    end_item: Signal<Local, Bit>,
    /// The candidate compared: the item's, or the one replayed.
    s_cx: Signal<Local, Bits<COORD_BITS>>,
    s_cy: Signal<Local, Bits<COORD_BITS>>,
    _m: usize,
}

impl<const P: usize> CompareStage<P> {
    /// The compare stage of a configuration (its slots, field, P and
    /// `r_assoc`; the tracker has checked them).
    pub fn new(cfg: &BackHalfConfig) -> Self {
        let m = cfg.slots;
        CompareStage {
            clock: Default::default(),
            restart: Default::default(),
            run: Default::default(),
            open: Default::default(),
            item_valid: Default::default(),
            item_cand: Default::default(),
            item_last: Default::default(),
            item_eor: Default::default(),
            item_lastrow: Default::default(),
            item_cx: Default::default(),
            item_cy: Default::default(),
            item_word_col: Default::default(),
            item_row_m1: Default::default(),
            item_row_p1: Default::default(),
            item_above: Default::default(),
            slot_geo: lanes(m),
            slot_win: lanes(m),
            slot_bnd: lanes(m),
            take: Default::default(),
            go: Default::default(),
            candidate: Default::default(),
            step: Default::default(),
            lastrow: Default::default(),
            cx: Default::default(),
            cy: Default::default(),
            near: Default::default(),
            hits: Default::default(),
            row_end: Default::default(),
            open_geo: Default::default(),
            open_win: Default::default(),
            open_view: Default::default(),
            open_bnd: Default::default(),
            slots: SlotCompare::new(m),
            opening: OpeningWindows::new(cfg),
            valid: Default::default(),
            cand: Default::default(),
            last: Default::default(),
            eor: Default::default(),
            r_lastrow: Default::default(),
            r_cx: Default::default(),
            r_cy: Default::default(),
            r_near: Default::default(),
            r_hits: Default::default(),
            r_row_end: Default::default(),
            r_geo: Default::default(),
            r_win: Default::default(),
            r_view: Default::default(),
            r_bnd: Default::default(),
            replay: Default::default(),
            end_item: Default::default(),
            s_cx: Default::default(),
            s_cy: Default::default(),
            _m: m,
        }
    }
}

// The offsets that `update` slices at as literals (hdl_gen needs numbers).
const _: () = assert!(
    slot_word::AY == 10
        && slot_word::WL == 34
        && slot_word::WH == 44
        && slot_word::FROW == 54
        && COORD_BITS == 10
);

impl<const P: usize> Logic for CompareStage<P> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, valid, cand, last, eor, r_lastrow, r_cx, r_cy, r_near, r_hits, r_row_end,
            r_geo, r_win, r_view, r_bnd, replay
        );

        // ---- Flow.
        self.go.next = self.run.val() & self.valid.q.val() & !self.replay.q.val();
        self.candidate.next = self.go.val() & self.cand.q.val();
        self.step.next = self.go.val() & self.last.q.val() & self.eor.q.val();
        self.end_item.next = self.step.val() & self.r_lastrow.q.val();
        self.take.next =
            !self.replay.q.val() & (!self.valid.q.val() | self.run.val()) & !self.end_item.val();

        // ---- What an opening by the item writes.
        self.opening.cx.next = self.item_cx.val();
        self.opening.cy.next = self.item_cy.val();
        self.opening.lastrow.next = self.item_lastrow.val();

        // ---- Every slot against the item, or against the candidate replayed.
        self.s_cx.next = self.item_cx.val();
        self.s_cy.next = self.item_cy.val();
        if self.replay.q.val() {
            self.s_cx.next = self.r_cx.q.val();
            self.s_cy.next = self.r_cy.q.val();
        }
        for i in 0..self._m {
            self.slots.bounds[i].next = self.slot_bnd[i].val().get_bits::<40>(0);
            self.slots.anchor_rows[i].next = self.slot_geo[i].val().get_bits::<10>(10);
            self.slots.low_cols[i].next = self.slot_geo[i].val().get_bits::<10>(34);
            self.slots.high_cols[i].next = self.slot_geo[i].val().get_bits::<10>(44);
            self.slots.end_rows[i].next = self.slot_geo[i].val().get_bits::<10>(54);
            self.slots.low_lanes[i].next = self.slot_win[i].val().get_bits::<P>(0);
            self.slots.high_lanes[i].next = self.slot_win[i].val().get_bits::<P>(32);
        }
        self.slots.cx.next = self.s_cx.val();
        self.slots.cy.next = self.s_cy.val();
        self.slots.word_col.next = self.item_word_col.val();
        self.slots.row.next = self.item_cy.val();
        self.slots.row_m1.next = self.item_row_m1.val();
        self.slots.row_p1.next = self.item_row_p1.val();
        self.slots.above.next = self.item_above.val();
        self.slots.enable.next = self.replay.q.val() | (self.take.val() & self.item_valid.val());

        // ---- The registers.
        if self.replay.q.val() {
            self.r_near.d.next = self.slots.near.val();
        }
        if self.end_item.val() {
            self.valid.d.next = false;
        }
        if self.take.val() {
            self.valid.d.next = self.item_valid.val();
            self.cand.d.next = self.item_cand.val();
            self.last.d.next = self.item_last.val();
            self.eor.d.next = self.item_eor.val();
            self.r_lastrow.d.next = self.item_lastrow.val();
            self.r_cx.d.next = self.item_cx.val();
            self.r_cy.d.next = self.item_cy.val();
            self.r_near.d.next = self.slots.near.val();
            self.r_hits.d.next = self.slots.hits.val();
            self.r_row_end.d.next = self.slots.row_end.val();
            self.r_geo.d.next = self.opening.geo.val();
            self.r_win.d.next = self.opening.win.val();
            self.r_view.d.next = self.opening.sh.val();
            self.r_bnd.d.next = self.opening.bnd.val();
        }
        self.replay.d.next =
            self.open.val() & self.item_valid.val() & self.item_cand.val() & self.take.val();
        if self.restart.val() {
            self.valid.d.next = false;
            self.replay.d.next = false;
        }

        self.lastrow.next = self.r_lastrow.q.val();
        self.cx.next = self.r_cx.q.val();
        self.cy.next = self.r_cy.q.val();
        self.near.next = self.r_near.q.val();
        self.hits.next = self.r_hits.q.val();
        self.row_end.next = self.r_row_end.q.val();
        self.open_geo.next = self.r_geo.q.val();
        self.open_win.next = self.r_win.q.val();
        self.open_view.next = self.r_view.q.val();
        self.open_bnd.next = self.r_bnd.q.val();
    }
}
