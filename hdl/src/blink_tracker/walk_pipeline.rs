//! The tracker's walk pipeline: at the end of a plane, at the stream end
//! and at the end of each drain plane, every slot in slot order, one slot
//! per clock in each of three stages.
//! * The *read* stage takes slot `walk`'s flags, anchor and bank through
//!   one multiplexer ([`SlotMux`]) and its word from [`WalkMemory`] (the
//!   fields only the walks read: ages, confirmation, continuation,
//!   truncation), into W1.
//! * W1 ([`WalkStep`](super::WalkStep)) computes what the walk does (the
//!   comparisons with L_min, L_max and N − end_trim, the cut, the
//!   completion, the record's planes, the slot's next state and words)
//!   into W2 (W1 and W2 are [`WalkStages`]).
//! * The tracker waits with W2's slot for the sweep and the bank, pushes
//!   the record, writes the slot's flags and words, and says so (`done`);
//!   the word goes back to the walk memory (`write_back`).
//!
//! W2 writes slot k while the read stage reads k + 1 or k + 2, and a walk
//! starts reading (`start`) once the previous writer of its slots is done
//! (the decide stage, or the previous walk's W2), so no stage reads a slot
//! that an earlier one has yet to write; the one exception, with a single
//! slot, is the word written as the next walk's read of it is issued
//! ([`WalkMemory`] forwards it).
//!
//! The walk's constants (N − end_trim, `N − end_trim = 1`, L_min,
//! L_min + 1, L_max − 1) are registered from the tracker's runtime
//! registers, which are written long before a walk; the walk compares
//! ages with them (see "Ages instead of plane arithmetic" in
//! [`WalkStep`](super::WalkStep)'s doc).

use super::layout::{slot_word, AGE_BITS, COORD_BITS};
use super::{SlotMux, WalkMemory, WalkStages, WalkedSlot};
use crate::config::MAX_SLOTS;
use crate::stream::lanes;
use rust_hdl::prelude::*;

// The read stage slices the anchor and bank out of a slot's `geo` word at
// these offsets, written as literals (`hdl_gen` takes no path constant).
const _: () =
    assert!(slot_word::AX == 0 && slot_word::AY == COORD_BITS && slot_word::BANK == 2 * COORD_BITS);

/// The walk pipeline of M slots. `BW`: bits of a counter bank.
#[derive(LogicBlock)]
pub struct WalkPipeline<const BW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: no walk, every stage empty.
    pub restart: Signal<In, Bit>,
    /// A walk starts: the read stage reads from slot 0 on the next clock.
    pub start: Signal<In, Bit>,
    /// N (the tracker's register, in [`AGE_BITS`] bits).
    pub n: Signal<In, Bits<AGE_BITS>>,
    /// END_TRIM.
    pub end_trim: Signal<In, Bits<AGE_BITS>>,
    /// L_min.
    pub l_min: Signal<In, Bits<AGE_BITS>>,
    /// L_max.
    pub l_max: Signal<In, Bits<AGE_BITS>>,
    /// The slots' busy flags (bit i: slot i).
    pub busy: Signal<In, Bits<MAX_SLOTS>>,
    /// Their live flags.
    pub live: Signal<In, Bits<MAX_SLOTS>>,
    /// Their dip flags.
    pub dip: Signal<In, Bits<MAX_SLOTS>>,
    /// The drops the walk has yet to settle.
    pub pend: Signal<In, Bits<MAX_SLOTS>>,
    /// The slots opened in this plane.
    pub opened: Signal<In, Bits<MAX_SLOTS>>,
    /// The bridges of this plane.
    pub bridges: Signal<In, Bits<MAX_SLOTS>>,
    /// Each slot's `geo` word (anchor and bank at [`slot_word`](super::slot_word)'s offsets).
    pub slot_geo: Vec<Signal<In, Bits<64>>>,
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
    /// The tracker is done with W2's slot this clock.
    pub done: Signal<In, Bit>,
    /// With `done`: W2's word goes back to the walk memory.
    pub write_back: Signal<In, Bit>,
    /// W2's slot and what the walk does to it.
    pub w2: WalkedSlot<BW>,
    /// The read stage's slot; 0 whenever no walk reads (a walk ends, and a
    /// restart leaves it, at 0), so that a walk starts without writing it
    /// and the walk memory's read address does not wait on `start`.
    walk: DFF<Bits<8>>,
    /// The read stage is on (`walk` is its slot).
    on: DFF<Bit>,
    /// The read stage's multiplexer: the walked slot's state.
    read: SlotMux<BW>,
    /// The fields that only the walks read, read a clock ahead.
    memory: WalkMemory,
    /// W1 and W2.
    stages: WalkStages<BW>,
    /// The walk's constants (see the module doc).
    n_mc: DFF<Bits<AGE_BITS>>,
    mc_one: DFF<Bit>,
    lmin: DFF<Bits<AGE_BITS>>,
    lmin_p1: DFF<Bits<AGE_BITS>>,
    lmax_m1: DFF<Bits<AGE_BITS>>,
    last_slot: Constant<Bits<8>>,
    _m: usize,
}

impl<const BW: usize> WalkPipeline<BW> {
    /// The walk pipeline of `m` slots (at most [`MAX_SLOTS`]; the tracker
    /// has checked it).
    pub fn new(m: usize) -> Self {
        WalkPipeline {
            clock: Default::default(),
            restart: Default::default(),
            start: Default::default(),
            n: Default::default(),
            end_trim: Default::default(),
            l_min: Default::default(),
            l_max: Default::default(),
            busy: Default::default(),
            live: Default::default(),
            dip: Default::default(),
            pend: Default::default(),
            opened: Default::default(),
            bridges: Default::default(),
            slot_geo: lanes(m),
            end_of_plane: Default::default(),
            finish: Default::default(),
            drain: Default::default(),
            t: Default::default(),
            t1_ge_n: Default::default(),
            done: Default::default(),
            write_back: Default::default(),
            w2: Default::default(),
            walk: Default::default(),
            on: Default::default(),
            read: SlotMux::new(m),
            memory: WalkMemory::new(m),
            stages: Default::default(),
            n_mc: Default::default(),
            mc_one: Default::default(),
            lmin: Default::default(),
            lmin_p1: Default::default(),
            lmax_m1: Default::default(),
            last_slot: Constant::new((m as u64 - 1).to_bits()),
            _m: m,
        }
    }
}

impl<const BW: usize> Logic for WalkPipeline<BW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, walk, on, n_mc, mc_one, lmin, lmin_p1, lmax_m1);
        self.memory.clock.next = self.clock.val();
        self.stages.clock.next = self.clock.val();

        // The walk's constants.
        self.n_mc.d.next = self.n.val() - self.end_trim.val();
        self.mc_one.d.next = self.n.val() == self.end_trim.val() + 1;
        self.lmin.d.next = self.l_min.val();
        self.lmin_p1.d.next = self.l_min.val() + 1;
        self.lmax_m1.d.next = self.l_max.val() - 1;

        // Read stage: the slot's state through one multiplexer; the fields
        // only the walks read come from its word in `memory`, read a clock
        // ahead (at `walk.d`).
        self.read.slot.next = self.walk.q.val();
        self.read.enable.next = self.on.q.val();
        self.read.busy.next = self.busy.val();
        self.read.live.next = self.live.val();
        self.read.dip.next = self.dip.val();
        self.read.pend.next = self.pend.val();
        self.read.opened.next = self.opened.val();
        self.read.bridges.next = self.bridges.val();
        for i in 0..self._m {
            self.read.anchor_cols[i].next = self.slot_geo[i].val().get_bits::<10>(0);
            self.read.anchor_rows[i].next = self.slot_geo[i].val().get_bits::<10>(10);
            self.read.banks[i].next = self.slot_geo[i].val().get_bits::<BW>(20);
        }
        self.stages.restart.next = self.restart.val();
        self.stages.offer.next = self.on.q.val();
        self.stages.s_sel.next = self.read.selected.val();
        self.stages.s_slot.next = self.walk.q.val();
        self.stages.s_last.next = self.walk.q.val() == self.last_slot.val();
        self.stages.s_busy.next = self.read.s_busy.val();
        self.stages.s_live.next = self.read.s_live.val();
        self.stages.s_dip.next = self.read.s_dip.val();
        self.stages.s_pend.next = self.read.s_pend.val();
        self.stages.s_opened.next = self.read.s_opened.val();
        self.stages.s_bridge.next = self.read.s_bridge.val();
        self.stages.s_ax.next = self.read.s_ax.val();
        self.stages.s_ay.next = self.read.s_ay.val();
        self.stages.s_bank.next = self.read.s_bank.val();
        self.stages.s_word.next = self.memory.word.val();
        if self.stages.take.val() {
            self.walk.d.next = self.walk.q.val() + 1;
            if self.walk.q.val() == self.last_slot.val() {
                self.on.d.next = false;
                self.walk.d.next = 0.into();
            }
        }
        if self.start.val() {
            self.on.d.next = true;
        }
        if self.restart.val() {
            self.on.d.next = false;
            self.walk.d.next = 0.into();
        }

        // W1 into W2 ([`WalkStep`](super::WalkStep)), and W2's slot done.
        self.stages.end_of_plane.next = self.end_of_plane.val();
        self.stages.finish.next = self.finish.val();
        self.stages.drain.next = self.drain.val();
        self.stages.t.next = self.t.val();
        self.stages.t1_ge_n.next = self.t1_ge_n.val();
        self.stages.lmin.next = self.lmin.q.val();
        self.stages.lmin_p1.next = self.lmin_p1.q.val();
        self.stages.lmax_m1.next = self.lmax_m1.q.val();
        self.stages.n_mc.next = self.n_mc.q.val();
        self.stages.mc_one.next = self.mc_one.q.val();
        self.stages.done.next = self.done.val();

        // The walk memory: read at the slot the read stage is at on the next
        // clock, written with W2's word.
        self.memory.restart.next = self.restart.val();
        self.memory.slot.next = self.walk.q.val();
        self.memory.slot_next.next = self.walk.d.val();
        self.memory.advance.next = self.stages.take.val();
        self.memory.write_slot.next = self.w2.slot.val();
        self.memory.write_enable.next = self.write_back.val();
        self.memory.write_data.next = self.stages.word.val();

        WalkedSlot::<BW>::link(&mut self.w2, &mut self.stages.w2);
    }
}
