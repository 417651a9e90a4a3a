//! The slots' words (see "Registers" in the tracker's doc), one 64-bit
//! register per slot and field group, and every write to them:
//! * `geo`: the anchor, the window's word columns and last row, and the
//!   counter bank ([`slot_word`] offsets); `win`: the window's two lane
//!   masks (the low word's at bit 0, the high word's at bit 32); `bnd`: the
//!   association window (x from 0, x to 10, y from 20, y to 30);
//! * `sh`: the ROI view, entry `parity·M + slot` ([`shadow`] offsets).
//!
//! The writes:
//! * **Walk** (the slot one-hot in `walk_slot`, one walk at a time):
//!   the end of a plane, and `emit` of a busy slot, give the slot its bank
//!   from now on (`next_bank`: a fresh one when it has just handed its bank
//!   to a Blink record); the end of a plane and of a drain plane write its
//!   ROI view entry for plane t + 1 (anchor, bank, `next_pre`, and
//!   `next_fresh` at the end of a real plane only); the stream end's
//!   `finish` clears the flags of its entry for plane t if the track ends
//!   `unconfirmed` (freed: it sums nothing more).
//! * **Opening** (`open`, the slot one-hot in `open_slot`): the opening
//!   candidate's `geo` fields, lane masks and association window; its ROI
//!   view entry for plane t (`open_view`, and `pre` if `open_pre`, t ≥ N);
//!   both keep the slot's bank.
//! * `restart`: every slot back to its first bank (slot i: bank i), every
//!   ROI view entry without flags. The other fields are read only after an
//!   opening or a walk has written them.
//!
//! A clock's writes apply in this order, each over the one before: the
//! walk, the opening, the restart. Each word is held through the mask of
//! its bits in use, so that synthesis sees the others constant, also where
//! no reader prunes them.

use super::layout::{shadow, slot_word, COORD_BITS};
use crate::config::MAX_SLOTS;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// The words of `m` slots and their writes. `BW`: bits of a counter bank.
#[derive(LogicBlock)]
pub struct SlotWords<const BW: usize> {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// Every slot back to its first bank, every ROI view entry cleared.
    pub restart: Signal<In, Bit>,
    /// The parity of plane t: the ROI view of t is at `parity·M + slot`.
    pub parity: Signal<In, Bit>,
    /// The walked slot, one-hot.
    pub walk_slot: Signal<In, Bits<MAX_SLOTS>>,
    /// The walk at the end of a plane writes the slot.
    pub end_of_plane: Signal<In, Bit>,
    /// The walk at the end of a drain plane writes the slot.
    pub drain: Signal<In, Bit>,
    /// The stream end's `finish` writes the slot.
    pub finish: Signal<In, Bit>,
    /// The last walk emits the slot's record.
    pub emit: Signal<In, Bit>,
    /// The walked slot was busy.
    pub was_busy: Signal<In, Bit>,
    /// Its bank from now on.
    pub next_bank: Signal<In, Bits<BW>>,
    /// Its anchor column.
    pub walk_ax: Signal<In, Bits<COORD_BITS>>,
    /// Its anchor row.
    pub walk_ay: Signal<In, Bits<COORD_BITS>>,
    /// Its ROI view of plane t + 1 sums the delayed plane.
    pub next_pre: Signal<In, Bit>,
    /// Plane t + 1 is the first of its segment.
    pub next_fresh: Signal<In, Bit>,
    /// The track `finish` ends is unconfirmed.
    pub unconfirmed: Signal<In, Bit>,
    /// A track opens.
    pub open: Signal<In, Bit>,
    /// The slot it opens in, one-hot.
    pub open_slot: Signal<In, Bits<MAX_SLOTS>>,
    /// Its `geo` fields (all but the bank).
    pub open_geo: Signal<In, Bits<64>>,
    /// Its lane masks.
    pub open_win: Signal<In, Bits<64>>,
    /// Its association window.
    pub open_bnd: Signal<In, Bits<64>>,
    /// Its ROI view entry for plane t (all but the bank and `pre`).
    pub open_view: Signal<In, Bits<64>>,
    /// Plane t ≥ N: the opened slot sums the delayed plane.
    pub open_pre: Signal<In, Bit>,
    /// Each slot's `geo` word.
    pub geo: Vec<Signal<Out, Bits<64>>>,
    /// Each slot's lane masks.
    pub win: Vec<Signal<Out, Bits<64>>>,
    /// Each slot's association window.
    pub bnd: Vec<Signal<Out, Bits<64>>>,
    /// The ROI view, entry `parity·M + slot`.
    pub sh: Vec<Signal<Out, Bits<64>>>,
    geo_r: Vec<DFF<Bits<64>>>,
    win_r: Vec<DFF<Bits<64>>>,
    bnd_r: Vec<DFF<Bits<64>>>,
    sv: Vec<DFF<Bits<64>>>,
    par1: Signal<Local, Bit>,
    /// `next_bank` at the bank's offset of `geo` and of a ROI view entry.
    bank_w: Signal<Local, Bits<64>>,
    /// The walked slot's ROI view entry for plane t + 1.
    view_next: Signal<Local, Bits<64>>,
    /// The bits of the walked slot's ROI view entry that `finish` keeps:
    /// all, but the flags if the track ends unconfirmed. (A value shifted
    /// into a wider word is a signal of its own: Verilog widens the
    /// operands of `~` before inverting them.)
    fin_keep: Signal<Local, Bits<64>>,
    /// `open_pre` at its offset.
    pre_w: Signal<Local, Bits<64>>,
    /// Slot i's first bank, i, at the bank's offset of `geo`.
    bank_init: Vec<Constant<Bits<64>>>,
    /// The bank's bits of `geo` and of a ROI view entry.
    bank_mask: Constant<Bits<64>>,
    /// The bits in use of a `geo` word, of a `win` word and of a ROI view
    /// entry; of `geo` without the bank.
    geo_used: Constant<Bits<64>>,
    win_used: Constant<Bits<64>>,
    sh_used: Constant<Bits<64>>,
    geo_keep: Constant<Bits<64>>,
    _m: usize,
}

impl<const BW: usize> SlotWords<BW> {
    /// The words of `m` slots (at most [`MAX_SLOTS`]) whose lane masks are
    /// `p` bits (at most 32); banks of `BW` ≤ [`slot_word::BANK_BITS_MAX`]
    /// bits.
    pub fn new(m: usize, p: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        assert!((1..=32).contains(&p), "{p}-bit lane masks");
        assert!(BW <= slot_word::BANK_BITS_MAX, "{BW}-bit banks");
        let ones = |n: usize| if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        let bank_bits = ones(BW) << slot_word::BANK;
        let geo_used = !((ones(slot_word::BANK_BITS_MAX) << slot_word::BANK) & !bank_bits);
        let win_used = ones(p) | (ones(p) << 32);
        let sh_used = ones(shadow::BANK + BW) | (1u64 << shadow::PRE) | (1u64 << shadow::FRESH);
        SlotWords {
            clock: Default::default(),
            restart: Default::default(),
            parity: Default::default(),
            walk_slot: Default::default(),
            end_of_plane: Default::default(),
            drain: Default::default(),
            finish: Default::default(),
            emit: Default::default(),
            was_busy: Default::default(),
            next_bank: Default::default(),
            walk_ax: Default::default(),
            walk_ay: Default::default(),
            next_pre: Default::default(),
            next_fresh: Default::default(),
            unconfirmed: Default::default(),
            open: Default::default(),
            open_slot: Default::default(),
            open_geo: Default::default(),
            open_win: Default::default(),
            open_bnd: Default::default(),
            open_view: Default::default(),
            open_pre: Default::default(),
            geo: lanes(m),
            win: lanes(m),
            bnd: lanes(m),
            sh: lanes(2 * m),
            geo_r: lanes(m),
            win_r: lanes(m),
            bnd_r: lanes(m),
            sv: lanes(2 * m),
            par1: Default::default(),
            bank_w: Default::default(),
            view_next: Default::default(),
            fin_keep: Default::default(),
            pre_w: Default::default(),
            bank_init: (0..m)
                .map(|i| Constant::new(((i as u64) << slot_word::BANK).to_bits()))
                .collect(),
            bank_mask: Constant::new(bank_bits.to_bits()),
            geo_used: Constant::new(geo_used.to_bits()),
            win_used: Constant::new(win_used.to_bits()),
            sh_used: Constant::new(sh_used.to_bits()),
            geo_keep: Constant::new((geo_used & !bank_bits).to_bits()),
            _m: m,
        }
    }
}

impl<const BW: usize> Logic for SlotWords<BW> {
    #[hdl_gen]
    fn update(&mut self) {
        for i in 0..self._m {
            self.geo_r[i].clock.next = self.clock.val();
            self.win_r[i].clock.next = self.clock.val();
            self.bnd_r[i].clock.next = self.clock.val();
            self.bnd_r[i].d.next = self.bnd_r[i].q.val();
            self.geo_r[i].d.next = self.geo_r[i].q.val() & self.geo_used.val();
            self.win_r[i].d.next = self.win_r[i].q.val() & self.win_used.val();
        }
        for q in 0..(2 * self._m) {
            self.sv[q].clock.next = self.clock.val();
            self.sv[q].d.next = self.sv[q].q.val() & self.sh_used.val();
        }
        self.par1.next = !self.parity.val();
        self.bank_w.next = bit_cast::<64, BW>(self.next_bank.val()) << 20;
        self.view_next.next = bit_cast::<64, 10>(self.walk_ax.val())
            | (bit_cast::<64, 10>(self.walk_ay.val()) << 10)
            | self.bank_w.val()
            | (bit_cast::<64, 1>(self.next_pre.val().into()) << 62)
            | (bit_cast::<64, 1>((self.next_fresh.val() & self.end_of_plane.val()).into()) << 63);
        self.fin_keep.next = self.sh_used.val();
        if self.unconfirmed.val() {
            self.fin_keep.next = self.fin_keep.val().replace_bit(62, false);
            self.fin_keep.next = self.fin_keep.val().replace_bit(63, false);
        }
        self.pre_w.next = bit_cast::<64, 1>(self.open_pre.val().into()) << 62;

        // ---- The walked slot (`mm` is M: an index expression needs a
        // loop variable). Inside a test of any walk's write, which each
        // write implies: the co-simulation then skips the M slots on the
        // clocks without one, most of them; the logic is the same.
        if self.end_of_plane.val() | self.drain.val() | self.finish.val() | self.emit.val() {
            for mm in self._m..(self._m + 1) {
                for i in 0..self._m {
                    if self.walk_slot.val().get_bit(i)
                        & (self.end_of_plane.val() | (self.emit.val() & self.was_busy.val()))
                    {
                        self.geo_r[i].d.next =
                            (self.geo_r[i].q.val() & self.geo_keep.val()) | self.bank_w.val();
                    }
                    if self.walk_slot.val().get_bit(i) & self.finish.val() {
                        if self.parity.val() {
                            self.sv[i + mm].d.next = self.sv[i + mm].q.val() & self.fin_keep.val();
                        } else {
                            self.sv[i].d.next = self.sv[i].q.val() & self.fin_keep.val();
                        }
                    }
                    if self.walk_slot.val().get_bit(i)
                        & (self.end_of_plane.val() | self.drain.val())
                    {
                        if self.par1.val() {
                            self.sv[i + mm].d.next = self.view_next.val();
                        } else {
                            self.sv[i].d.next = self.view_next.val();
                        }
                    }
                }
            }
        }

        // ---- The opening. (Not inside a test of `open`: with one, yosys
        // finds eight bits of each slot's `geo` constant and ABC maps the
        // tops 0.6-1.5 % larger, here and on 2026-11-29; the loop costs the
        // co-simulation about 3 % of its instructions.)
        for mm in self._m..(self._m + 1) {
            for i in 0..self._m {
                if self.open.val() & self.open_slot.val().get_bit(i) {
                    self.geo_r[i].d.next =
                        (self.geo_r[i].q.val() & self.bank_mask.val()) | self.open_geo.val();
                    self.win_r[i].d.next = self.open_win.val();
                    self.bnd_r[i].d.next = self.open_bnd.val();
                    if self.parity.val() {
                        self.sv[i + mm].d.next = (self.geo_r[i].q.val() & self.bank_mask.val())
                            | self.open_view.val()
                            | self.pre_w.val();
                    } else {
                        self.sv[i].d.next = (self.geo_r[i].q.val() & self.bank_mask.val())
                            | self.open_view.val()
                            | self.pre_w.val();
                    }
                }
            }
        }

        if self.restart.val() {
            for i in 0..self._m {
                self.geo_r[i].d.next = self.bank_init[i].val();
            }
            for q in 0..(2 * self._m) {
                self.sv[q].d.next = 0.into();
            }
        }

        for i in 0..self._m {
            self.geo[i].next = self.geo_r[i].q.val();
            self.win[i].next = self.win_r[i].q.val();
            self.bnd[i].next = self.bnd_r[i].q.val();
        }
        for q in 0..(2 * self._m) {
            self.sh[q].next = self.sv[q].q.val();
        }
    }
}
