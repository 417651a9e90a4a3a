//! The tracker's item stage (see "Pipeline" in [`super`]'s doc): the
//! head word of the input FIFO, one item per clock. An item is one
//! candidate lane of the word, the lowest not yet taken (`done_mask`), or
//! the word itself when it has none; the word is popped with its last item.
//! Flush and drain words are not taken (the tracker pops those itself).
//!
//! Besides the item's coordinates the stage registers what the compare
//! stage needs of the word: the rows `y − 1 ..= y + 1` that see it (its
//! above bits OR into the 3×3 windows anchored there), whether it ends its
//! row and whether that row is the field's last.

use super::layout::COORD_BITS;
use crate::config::BackHalfConfig;
use rust_hdl::prelude::*;

/// The item stage of the blink tracker. `P`: pixels per word.
#[derive(LogicBlock)]
pub struct ItemStage<const P: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: no item, no lane taken.
    pub restart: Signal<In, Bit>,
    /// A word is at the head of the input FIFO.
    pub in_valid: Signal<In, Bit>,
    /// Its above-threshold bits.
    pub in_above: Signal<In, Bits<P>>,
    /// Its candidate bits.
    pub in_cand: Signal<In, Bits<P>>,
    /// Its word column.
    pub in_x: Signal<In, Bits<16>>,
    /// Its row.
    pub in_y: Signal<In, Bits<16>>,
    /// It belongs to a flush or drain plane (not taken).
    pub in_flush: Signal<In, Bit>,
    /// The compare stage takes the item this clock (the stage may then
    /// take the next).
    pub take: Signal<In, Bit>,
    /// Pop the head word: its last item is taken.
    pub pop: Signal<Out, Bit>,
    /// The head word is the last of its row.
    pub head_eor: Signal<Out, Bit>,
    /// The head word's row is the field's last.
    pub head_lastrow: Signal<Out, Bit>,
    /// The stage holds an item.
    pub valid: Signal<Out, Bit>,
    /// The item is a candidate (else a word without one).
    pub cand: Signal<Out, Bit>,
    /// The item is its word's last.
    pub last: Signal<Out, Bit>,
    /// Its word is the last of its row.
    pub eor: Signal<Out, Bit>,
    /// Its row is the field's last.
    pub lastrow: Signal<Out, Bit>,
    /// The candidate's column (pixels).
    pub cx: Signal<Out, Bits<COORD_BITS>>,
    /// Its row.
    pub yc: Signal<Out, Bits<COORD_BITS>>,
    /// Its word column.
    pub xc: Signal<Out, Bits<COORD_BITS>>,
    /// The first and last rows that see the word: `max(y − 1, 0)`, `y + 1`.
    pub ym1: Signal<Out, Bits<COORD_BITS>>,
    /// See `ym1`.
    pub yp1: Signal<Out, Bits<COORD_BITS>>,
    /// The word's above-threshold bits.
    pub above: Signal<Out, Bits<P>>,
    done_mask: DFF<Bits<P>>,
    x_valid: DFF<Bit>,
    x_cand: DFF<Bit>,
    x_last: DFF<Bit>,
    x_eor: DFF<Bit>,
    x_lastrow: DFF<Bit>,
    x_cx: DFF<Bits<COORD_BITS>>,
    x_yc: DFF<Bits<COORD_BITS>>,
    x_xc: DFF<Bits<COORD_BITS>>,
    x_ym1: DFF<Bits<COORD_BITS>>,
    x_yp1: DFF<Bits<COORD_BITS>>,
    x_above: DFF<Bits<P>>,
    x_ready: Signal<Local, Bit>,
    x_take: Signal<Local, Bit>,
    rem: Signal<Local, Bits<P>>,
    low: Signal<Local, Bits<P>>,
    has_cand: Signal<Local, Bit>,
    more: Signal<Local, Bit>,
    /// Some lane below the one being looked at is a candidate.
    seen: Signal<Local, Bit>,
    in_xc: Signal<Local, Bits<COORD_BITS>>,
    /// The head word's row, narrowed to the tracker's coordinates.
    head_row: Signal<Local, Bits<COORD_BITS>>,
    lane: Signal<Local, Bits<COORD_BITS>>,
    lane_id: Vec<Constant<Bits<COORD_BITS>>>,
    log2p: Constant<Bits<8>>,
    last_row: Constant<Bits<COORD_BITS>>,
    last_word: Constant<Bits<16>>,
}

impl<const P: usize> ItemStage<P> {
    /// The item stage of a configuration (its field and P; the tracker has
    /// checked them).
    pub fn new(cfg: &BackHalfConfig) -> Self {
        let f = &cfg.front;
        let cc = |v: u64| Constant::new(v.to_bits());
        ItemStage {
            clock: Default::default(),
            restart: Default::default(),
            in_valid: Default::default(),
            in_above: Default::default(),
            in_cand: Default::default(),
            in_x: Default::default(),
            in_y: Default::default(),
            in_flush: Default::default(),
            take: Default::default(),
            pop: Default::default(),
            head_eor: Default::default(),
            head_lastrow: Default::default(),
            valid: Default::default(),
            cand: Default::default(),
            last: Default::default(),
            eor: Default::default(),
            lastrow: Default::default(),
            cx: Default::default(),
            yc: Default::default(),
            xc: Default::default(),
            ym1: Default::default(),
            yp1: Default::default(),
            above: Default::default(),
            done_mask: Default::default(),
            x_valid: Default::default(),
            x_cand: Default::default(),
            x_last: Default::default(),
            x_eor: Default::default(),
            x_lastrow: Default::default(),
            x_cx: Default::default(),
            x_yc: Default::default(),
            x_xc: Default::default(),
            x_ym1: Default::default(),
            x_yp1: Default::default(),
            x_above: Default::default(),
            x_ready: Default::default(),
            x_take: Default::default(),
            rem: Default::default(),
            low: Default::default(),
            has_cand: Default::default(),
            more: Default::default(),
            seen: Default::default(),
            in_xc: Default::default(),
            head_row: Default::default(),
            lane: Default::default(),
            lane_id: (0..P).map(|j| cc(j as u64)).collect(),
            log2p: Constant::new((cfg.log2_p() as u64).to_bits()),
            last_row: cc(f.height as u64 - 1),
            last_word: Constant::new((f.words_per_row() as u64 - 1).to_bits()),
        }
    }
}

impl<const P: usize> Logic for ItemStage<P> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, done_mask, x_valid, x_cand, x_last, x_eor, x_lastrow, x_cx, x_yc, x_xc,
            x_ym1, x_yp1, x_above
        );
        self.x_ready.next = !self.x_valid.q.val() | self.take.val();
        self.x_take.next = self.x_ready.val() & self.in_valid.val() & !self.in_flush.val();

        // Candidate lanes, lowest first.
        self.rem.next = self.in_cand.val() & !self.done_mask.q.val();
        self.low.next = self.rem.val() & (!self.rem.val() + 1);
        self.has_cand.next = self.rem.val().any();
        // At least two candidate lanes left, as plain logic rather than
        // `rem & (rem − 1)`: no carry chain, so the mapping can flatten it
        // (the head word's pop waits on it).
        self.more.next = false;
        self.seen.next = false;
        for j in 0..P {
            if self.rem.val().get_bit(j) {
                if self.seen.val() {
                    self.more.next = true;
                }
                self.seen.next = true;
            }
        }
        self.lane.next = 0.into();
        for j in 0..P {
            if self.low.val().get_bit(j) {
                self.lane.next = self.lane_id[j].val();
            }
        }
        self.in_xc.next = bit_cast::<10, 16>(self.in_x.val());
        self.head_row.next = bit_cast::<10, 16>(self.in_y.val());
        self.head_eor.next = self.in_x.val() == self.last_word.val();
        self.head_lastrow.next = self.head_row.val() == self.last_row.val();

        self.pop.next = false;
        self.x_valid.d.next = self.x_valid.q.val() & !self.take.val();
        if self.x_take.val() {
            self.x_valid.d.next = true;
            self.x_cand.d.next = self.has_cand.val();
            self.x_last.d.next = !self.more.val();
            self.x_eor.d.next = self.head_eor.val();
            self.x_lastrow.d.next = self.head_lastrow.val();
            self.x_cx.d.next = (self.in_xc.val() << self.log2p.val()) | self.lane.val();
            self.x_yc.d.next = self.head_row.val();
            self.x_xc.d.next = self.in_xc.val();
            // Rows y − 1 .. y + 1 see the word.
            self.x_ym1.d.next = 0.into();
            if self.head_row.val() != 0 {
                self.x_ym1.d.next = self.head_row.val() - 1;
            }
            self.x_yp1.d.next = self.head_row.val() + 1;
            self.x_above.d.next = self.in_above.val();
            if self.more.val() {
                self.done_mask.d.next = self.done_mask.q.val() | self.low.val();
            } else {
                self.pop.next = true;
                self.done_mask.d.next = 0.into();
            }
        }
        if self.restart.val() {
            self.done_mask.d.next = 0.into();
            self.x_valid.d.next = false;
        }

        self.valid.next = self.x_valid.q.val();
        self.cand.next = self.x_cand.q.val();
        self.last.next = self.x_last.q.val();
        self.eor.next = self.x_eor.q.val();
        self.lastrow.next = self.x_lastrow.q.val();
        self.cx.next = self.x_cx.q.val();
        self.yc.next = self.x_yc.q.val();
        self.xc.next = self.x_xc.q.val();
        self.ym1.next = self.x_ym1.q.val();
        self.yp1.next = self.x_yp1.q.val();
        self.above.next = self.x_above.q.val();
    }
}
