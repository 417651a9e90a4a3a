//! W1 and W2 of the tracker's walk pipeline
//! ([`WalkPipeline`](super::WalkPipeline)), one slot per clock each: W1
//! holds the slot the read stage has taken — its flags, anchor and bank
//! through [`SlotMux`](super::SlotMux), its word from
//! [`WalkMemory`](super::WalkMemory) —, and W2 what the walk does to it
//! ([`WalkStep`], of W1's slot and the walk's inputs as they are when W2
//! loads: the bundle [`WalkedSlot`]). The tracker acts on W2 and says when
//! it is `done` with it (the record pushed, the slot written); a stage
//! takes the one before it when it is empty or its slot moves on this
//! clock, so a walk that never waits goes at one slot a clock. A restart
//! empties both.

use super::layout::{AGE_BITS, COORD_BITS};
use super::walk_memory::WALK_WORD_BITS;
use super::WalkStep;
use crate::config::MAX_SLOTS;
use rust_hdl::prelude::*;

/// W2's slot, and what the walk does to it ([`WalkStep`]'s outputs of its
/// slot, registered): what the tracker acts on. `BW`: bits of a counter
/// bank.
#[derive(Clone, Debug, Default, LogicInterface)]
pub struct WalkedSlot<const BW: usize> {
    /// W2 holds a slot.
    pub valid: Signal<Out, Bit>,
    /// W2's slot, one-hot.
    pub sel: Signal<Out, Bits<MAX_SLOTS>>,
    /// Its index.
    pub slot: Signal<Out, Bits<8>>,
    /// It is the walk's last.
    pub last: Signal<Out, Bit>,
    /// Its busy flag (before the walk).
    pub was_busy: Signal<Out, Bit>,
    /// Bridged in this plane.
    pub bridge: Signal<Out, Bit>,
    /// Its anchor column.
    pub ax: Signal<Out, Bits<COORD_BITS>>,
    /// Its anchor row.
    pub ay: Signal<Out, Bits<COORD_BITS>>,
    /// Its counter bank.
    pub bank: Signal<Out, Bits<BW>>,
    /// The walk cuts it at L_max.
    pub cut: Signal<Out, Bit>,
    /// Freed unconfirmed.
    pub unconf: Signal<Out, Bit>,
    /// Completed: its Blink record is due.
    pub comp: Signal<Out, Bit>,
    /// The record's flag bits.
    pub flags: Signal<Out, Bits<8>>,
    /// The record's t_cross.
    pub tc: Signal<Out, Bits<48>>,
    /// The record's t_drop.
    pub td: Signal<Out, Bits<48>>,
    /// Busy in plane t + 1.
    pub n_busy: Signal<Out, Bit>,
    /// Live in plane t + 1.
    pub n_live: Signal<Out, Bit>,
    /// Its ROI view for t + 1: sum the delayed plane.
    pub n_pre: Signal<Out, Bit>,
    /// Its ROI view for t + 1: a segment's first plane.
    pub n_fresh: Signal<Out, Bit>,
    /// `finish` ends a live track.
    pub fin_end: Signal<Out, Bit>,
    /// `finish` ends it unconfirmed.
    pub fin_unconf: Signal<Out, Bit>,
}

/// The walk's W1 and W2 stages. `BW`: bits of a counter bank.
#[derive(LogicBlock, Default)]
pub struct WalkStages<const BW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Both stages empty.
    pub restart: Signal<In, Bit>,
    /// The read stage holds a slot (it moves into W1 with `take`).
    pub offer: Signal<In, Bit>,
    /// The read stage's slot, one-hot.
    pub s_sel: Signal<In, Bits<MAX_SLOTS>>,
    /// Its index.
    pub s_slot: Signal<In, Bits<8>>,
    /// It is the walk's last.
    pub s_last: Signal<In, Bit>,
    /// Its busy flag.
    pub s_busy: Signal<In, Bit>,
    /// Its live flag.
    pub s_live: Signal<In, Bit>,
    /// Its dip flag.
    pub s_dip: Signal<In, Bit>,
    /// Its `pend` flag.
    pub s_pend: Signal<In, Bit>,
    /// Opened in this plane.
    pub s_opened: Signal<In, Bit>,
    /// Bridged in this plane.
    pub s_bridge: Signal<In, Bit>,
    /// Its anchor column.
    pub s_ax: Signal<In, Bits<COORD_BITS>>,
    /// Its anchor row.
    pub s_ay: Signal<In, Bits<COORD_BITS>>,
    /// Its counter bank.
    pub s_bank: Signal<In, Bits<BW>>,
    /// Its walk word.
    pub s_word: Signal<In, Bits<WALK_WORD_BITS>>,
    /// The walk ends a real plane.
    pub end_of_plane: Signal<In, Bit>,
    /// The walk is the stream end's `finish`.
    pub finish: Signal<In, Bit>,
    /// The walk ends a drain plane.
    pub drain: Signal<In, Bit>,
    /// The plane t.
    pub t: Signal<In, Bits<48>>,
    /// `t + 1 ≥ N`.
    pub t1_ge_n: Signal<In, Bit>,
    /// L_min.
    pub lmin: Signal<In, Bits<AGE_BITS>>,
    /// L_min + 1.
    pub lmin_p1: Signal<In, Bits<AGE_BITS>>,
    /// L_max − 1.
    pub lmax_m1: Signal<In, Bits<AGE_BITS>>,
    /// N − end_trim.
    pub n_mc: Signal<In, Bits<AGE_BITS>>,
    /// N − end_trim = 1.
    pub mc_one: Signal<In, Bit>,
    /// The tracker is done with W2's slot this clock.
    pub done: Signal<In, Bit>,
    /// The read stage's slot moves into W1 this clock.
    pub take: Signal<Out, Bit>,
    /// W2's slot and what the walk does to it.
    pub w2: WalkedSlot<BW>,
    /// The word the walk writes back.
    pub word: Signal<Out, Bits<WALK_WORD_BITS>>,
    /// What the walk does to W1's slot.
    step: WalkStep,
    w1_valid: DFF<Bit>,
    w1_sel: DFF<Bits<MAX_SLOTS>>,
    w1_slot: DFF<Bits<8>>,
    w1_last: DFF<Bit>,
    w1_busy: DFF<Bit>,
    w1_live: DFF<Bit>,
    w1_dip: DFF<Bit>,
    w1_pend: DFF<Bit>,
    w1_opened: DFF<Bit>,
    w1_bridge: DFF<Bit>,
    w1_ax: DFF<Bits<COORD_BITS>>,
    w1_ay: DFF<Bits<COORD_BITS>>,
    w1_bank: DFF<Bits<BW>>,
    w1_word: DFF<Bits<WALK_WORD_BITS>>,
    w2_valid: DFF<Bit>,
    w2_sel: DFF<Bits<MAX_SLOTS>>,
    w2_slot: DFF<Bits<8>>,
    w2_last: DFF<Bit>,
    w2_busy: DFF<Bit>,
    w2_bridge: DFF<Bit>,
    w2_ax: DFF<Bits<COORD_BITS>>,
    w2_ay: DFF<Bits<COORD_BITS>>,
    w2_bank: DFF<Bits<BW>>,
    w2_cut: DFF<Bit>,
    w2_unconf: DFF<Bit>,
    w2_comp: DFF<Bit>,
    w2_flags: DFF<Bits<8>>,
    w2_tc: DFF<Bits<48>>,
    w2_td: DFF<Bits<48>>,
    w2_n_busy: DFF<Bit>,
    w2_n_live: DFF<Bit>,
    w2_n_pre: DFF<Bit>,
    w2_n_fresh: DFF<Bit>,
    w2_fin_end: DFF<Bit>,
    w2_fin_unconf: DFF<Bit>,
    w2_word: DFF<Bits<WALK_WORD_BITS>>,
    w1_ready: Signal<Local, Bit>,
    w2_ready: Signal<Local, Bit>,
    take_v: Signal<Local, Bit>,
}

impl<const BW: usize> Logic for WalkStages<BW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self,
            clock,
            w1_valid,
            w1_sel,
            w1_slot,
            w1_last,
            w1_busy,
            w1_live,
            w1_dip,
            w1_pend,
            w1_opened,
            w1_bridge,
            w1_ax,
            w1_ay,
            w1_bank,
            w1_word,
            w2_valid,
            w2_sel,
            w2_slot,
            w2_last,
            w2_busy,
            w2_bridge,
            w2_ax,
            w2_ay,
            w2_bank,
            w2_cut,
            w2_unconf,
            w2_comp,
            w2_flags,
            w2_tc,
            w2_td,
            w2_n_busy,
            w2_n_live,
            w2_n_pre,
            w2_n_fresh,
            w2_fin_end,
            w2_fin_unconf,
            w2_word
        );
        self.w2_ready.next = !self.w2_valid.q.val() | self.done.val();
        self.w1_ready.next = !self.w1_valid.q.val() | self.w2_ready.val();
        self.take_v.next = self.offer.val() & self.w1_ready.val();
        // W1: the read stage's slot.
        self.w1_valid.d.next = self.w1_valid.q.val() & !self.w2_ready.val();
        if self.take_v.val() {
            self.w1_valid.d.next = true;
            self.w1_sel.d.next = self.s_sel.val();
            self.w1_slot.d.next = self.s_slot.val();
            self.w1_last.d.next = self.s_last.val();
            self.w1_busy.d.next = self.s_busy.val();
            self.w1_live.d.next = self.s_live.val();
            self.w1_dip.d.next = self.s_dip.val();
            self.w1_pend.d.next = self.s_pend.val();
            self.w1_opened.d.next = self.s_opened.val();
            self.w1_bridge.d.next = self.s_bridge.val();
            self.w1_ax.d.next = self.s_ax.val();
            self.w1_ay.d.next = self.s_ay.val();
            self.w1_bank.d.next = self.s_bank.val();
            self.w1_word.d.next = self.s_word.val();
        }
        // W2: what the walk does to W1's slot.
        self.step.end_of_plane.next = self.end_of_plane.val();
        self.step.finish.next = self.finish.val();
        self.step.drain.next = self.drain.val();
        self.step.busy.next = self.w1_busy.q.val();
        self.step.live.next = self.w1_live.q.val();
        self.step.dip.next = self.w1_dip.q.val();
        self.step.pend.next = self.w1_pend.q.val();
        self.step.opened.next = self.w1_opened.q.val();
        self.step.word.next = self.w1_word.q.val();
        self.step.t.next = self.t.val();
        self.step.t1_ge_n.next = self.t1_ge_n.val();
        self.step.lmin.next = self.lmin.val();
        self.step.lmin_p1.next = self.lmin_p1.val();
        self.step.lmax_m1.next = self.lmax_m1.val();
        self.step.n_mc.next = self.n_mc.val();
        self.step.mc_one.next = self.mc_one.val();
        self.w2_valid.d.next = self.w2_valid.q.val() & !self.w2_ready.val();
        if self.w2_ready.val() {
            self.w2_valid.d.next = self.w1_valid.q.val();
            self.w2_sel.d.next = self.w1_sel.q.val();
            self.w2_slot.d.next = self.w1_slot.q.val();
            self.w2_last.d.next = self.w1_last.q.val();
            self.w2_busy.d.next = self.w1_busy.q.val();
            self.w2_bridge.d.next = self.w1_bridge.q.val();
            self.w2_ax.d.next = self.w1_ax.q.val();
            self.w2_ay.d.next = self.w1_ay.q.val();
            self.w2_bank.d.next = self.w1_bank.q.val();
            self.w2_cut.d.next = self.step.cut.val();
            self.w2_unconf.d.next = self.step.unconf.val();
            self.w2_comp.d.next = self.step.comp.val();
            self.w2_flags.d.next = self.step.flags.val();
            self.w2_tc.d.next = self.step.tc.val();
            self.w2_td.d.next = self.step.td.val();
            self.w2_n_busy.d.next = self.step.n_busy.val();
            self.w2_n_live.d.next = self.step.n_live.val();
            self.w2_n_pre.d.next = self.step.n_pre.val();
            self.w2_n_fresh.d.next = self.step.n_fresh.val();
            self.w2_fin_end.d.next = self.step.fin_end.val();
            self.w2_fin_unconf.d.next = self.step.fin_unconf.val();
            self.w2_word.d.next = self.step.word_next.val();
        }
        if self.restart.val() {
            self.w1_valid.d.next = false;
            self.w2_valid.d.next = false;
        }
        self.take.next = self.take_v.val();
        self.w2.valid.next = self.w2_valid.q.val();
        self.w2.sel.next = self.w2_sel.q.val();
        self.w2.slot.next = self.w2_slot.q.val();
        self.w2.last.next = self.w2_last.q.val();
        self.w2.was_busy.next = self.w2_busy.q.val();
        self.w2.bridge.next = self.w2_bridge.q.val();
        self.w2.ax.next = self.w2_ax.q.val();
        self.w2.ay.next = self.w2_ay.q.val();
        self.w2.bank.next = self.w2_bank.q.val();
        self.w2.cut.next = self.w2_cut.q.val();
        self.w2.unconf.next = self.w2_unconf.q.val();
        self.w2.comp.next = self.w2_comp.q.val();
        self.w2.flags.next = self.w2_flags.q.val();
        self.w2.tc.next = self.w2_tc.q.val();
        self.w2.td.next = self.w2_td.q.val();
        self.w2.n_busy.next = self.w2_n_busy.q.val();
        self.w2.n_live.next = self.w2_n_live.q.val();
        self.w2.n_pre.next = self.w2_n_pre.q.val();
        self.w2.n_fresh.next = self.w2_n_fresh.q.val();
        self.w2.fin_end.next = self.w2_fin_end.q.val();
        self.w2.fin_unconf.next = self.w2_fin_unconf.q.val();
        self.word.next = self.w2_word.q.val();
    }
}
