//! The slots' flags (bit i: slot i), one [`MAX_SLOTS`]-bit register per
//! flag (see "Registers" in the tracker's doc), and every write to them:
//! * `busy`: the slot holds a segment (it may have ended and wait for its
//!   completion); `live`: its blink has not ended; `dip`: one plane below;
//!   `pend`: ended at t − 1, the walk has yet to settle the drop;
//!   `opened`: opened in this plane; `bridges`: a dip bridged in this
//!   plane; `active_before` and `free_before`: busy and live, and free, at
//!   the end of plane t − 1 (what association reads); and the slots whose
//!   3×3 window has an above bit in this plane (`hit`, kept inside).
//! * **Decide** (`decide`): the decided word's hits (`hits`) join the
//!   plane's; at the end of a row (`step`), the on/off step of the slots
//!   whose window has streamed with it ([`OnOffStep`]) on those hits: a
//!   bridge ends the dip and is kept in `bridges`, a first plane below
//!   starts a dip, a second one ends the blink (not live, no dip, `pend`).
//! * **Opening** (`open`, the slot one-hot in `open_slot`): busy, live,
//!   opened, no dip.
//! * **Walk** (the slot one-hot in `walk_slot`), one of three at a time:
//!   * the end of a plane (`end_of_plane`): busy and live as the walk step
//!     decides (`next_busy`, `next_live`), the drop settled, the bridge
//!     counted, the dip ended by a `cut`, the association state at the end
//!     of plane t (active: busy and live; free: not busy), neither opened
//!     nor hit;
//!   * the stream end's `finish`: no longer opened; a track that `ends`
//!     there is neither live nor in a dip, and is freed if it was
//!     `unconfirmed`;
//!   * `emit`: a busy slot whose record is emitted is freed.
//! * `restart`: every slot free and idle (the dips stay: only a live slot's
//!   is read, and an opening clears it).
//!
//! A clock's writes apply in this order, each over the one before: the
//! walk, the opening, the on/off step, the restart. (The tracker never
//! walks and decides in one clock; the order makes the block's rule whole.)
//! The flags of slots past M change only at the restart. The walk and the
//! opening write bit by bit, slot by slot: the same logic written with
//! whole-word masks mapped to about 1 % more LUTs out of context
//! (`hdl/RESOURCES.md`, 2026-11-29 evening).

use super::on_off_step::OnOffStep;
use crate::config::MAX_SLOTS;
use rust_hdl::prelude::*;

/// The flags of `m` slots and their writes.
#[derive(LogicBlock)]
pub struct SlotFlags {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// Every slot free and idle.
    pub restart: Signal<In, Bit>,
    /// The decide stage decides a word (its hits join the plane's).
    pub decide: Signal<In, Bit>,
    /// The decided word's hits on each slot's 3×3 window.
    pub hits: Signal<In, Bits<MAX_SLOTS>>,
    /// The decided word ends its row: the on/off step.
    pub step: Signal<In, Bit>,
    /// Slots whose 3×3 window has streamed with the decided row.
    pub row_end: Signal<In, Bits<MAX_SLOTS>>,
    /// A track opens.
    pub open: Signal<In, Bit>,
    /// The slot it opens in, one-hot.
    pub open_slot: Signal<In, Bits<MAX_SLOTS>>,
    /// The walked slot, one-hot.
    pub walk_slot: Signal<In, Bits<MAX_SLOTS>>,
    /// The walk at the end of a plane writes the slot.
    pub end_of_plane: Signal<In, Bit>,
    /// The stream end's `finish` writes the slot.
    pub finish: Signal<In, Bit>,
    /// The last walk emits the slot's record.
    pub emit: Signal<In, Bit>,
    /// The walked slot was busy.
    pub was_busy: Signal<In, Bit>,
    /// Its busy flag after the walk at the end of a plane.
    pub next_busy: Signal<In, Bit>,
    /// Its live flag after the walk at the end of a plane.
    pub next_live: Signal<In, Bit>,
    /// The walk cuts its segment at L_max.
    pub cut: Signal<In, Bit>,
    /// `finish` ends its track.
    pub ends: Signal<In, Bit>,
    /// The track `finish` ends is unconfirmed.
    pub unconfirmed: Signal<In, Bit>,
    /// Busy slots.
    pub busy: Signal<Out, Bits<MAX_SLOTS>>,
    /// Live slots.
    pub live: Signal<Out, Bits<MAX_SLOTS>>,
    /// Slots in a dip.
    pub dip: Signal<Out, Bits<MAX_SLOTS>>,
    /// Slots whose drop the walk has yet to settle.
    pub pend: Signal<Out, Bits<MAX_SLOTS>>,
    /// Slots opened in this plane.
    pub opened: Signal<Out, Bits<MAX_SLOTS>>,
    /// Slots with a dip bridged in this plane.
    pub bridges: Signal<Out, Bits<MAX_SLOTS>>,
    /// Slots busy and live at the end of plane t − 1.
    pub active_before: Signal<Out, Bits<MAX_SLOTS>>,
    /// Slots free at the end of plane t − 1.
    pub free_before: Signal<Out, Bits<MAX_SLOTS>>,
    busy_r: DFF<Bits<MAX_SLOTS>>,
    live_r: DFF<Bits<MAX_SLOTS>>,
    dip_r: DFF<Bits<MAX_SLOTS>>,
    pend_r: DFF<Bits<MAX_SLOTS>>,
    aprev_r: DFF<Bits<MAX_SLOTS>>,
    fprev_r: DFF<Bits<MAX_SLOTS>>,
    opened_r: DFF<Bits<MAX_SLOTS>>,
    hit_r: DFF<Bits<MAX_SLOTS>>,
    bridge_r: DFF<Bits<MAX_SLOTS>>,
    on_off: OnOffStep,
    // What the clock's writes make of each flag so far (`d` at the end).
    busy_nx: Signal<Local, Bits<MAX_SLOTS>>,
    live_nx: Signal<Local, Bits<MAX_SLOTS>>,
    dip_nx: Signal<Local, Bits<MAX_SLOTS>>,
    pend_nx: Signal<Local, Bits<MAX_SLOTS>>,
    aprev_nx: Signal<Local, Bits<MAX_SLOTS>>,
    fprev_nx: Signal<Local, Bits<MAX_SLOTS>>,
    opened_nx: Signal<Local, Bits<MAX_SLOTS>>,
    hit_nx: Signal<Local, Bits<MAX_SLOTS>>,
    bridge_nx: Signal<Local, Bits<MAX_SLOTS>>,
    /// The plane's hits with the decided word's.
    on_v: Signal<Local, Bits<MAX_SLOTS>>,
    slots: Constant<Bits<MAX_SLOTS>>,
    _m: usize,
}

impl SlotFlags {
    /// The flags of `m` slots (at most [`MAX_SLOTS`]).
    pub fn new(m: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        SlotFlags {
            clock: Default::default(),
            restart: Default::default(),
            decide: Default::default(),
            hits: Default::default(),
            step: Default::default(),
            row_end: Default::default(),
            open: Default::default(),
            open_slot: Default::default(),
            walk_slot: Default::default(),
            end_of_plane: Default::default(),
            finish: Default::default(),
            emit: Default::default(),
            was_busy: Default::default(),
            next_busy: Default::default(),
            next_live: Default::default(),
            cut: Default::default(),
            ends: Default::default(),
            unconfirmed: Default::default(),
            busy: Default::default(),
            live: Default::default(),
            dip: Default::default(),
            pend: Default::default(),
            opened: Default::default(),
            bridges: Default::default(),
            active_before: Default::default(),
            free_before: Default::default(),
            busy_r: Default::default(),
            live_r: Default::default(),
            dip_r: Default::default(),
            pend_r: Default::default(),
            aprev_r: Default::default(),
            fprev_r: Default::default(),
            opened_r: Default::default(),
            hit_r: Default::default(),
            bridge_r: Default::default(),
            on_off: OnOffStep::new(m),
            busy_nx: Default::default(),
            live_nx: Default::default(),
            dip_nx: Default::default(),
            pend_nx: Default::default(),
            aprev_nx: Default::default(),
            fprev_nx: Default::default(),
            opened_nx: Default::default(),
            hit_nx: Default::default(),
            bridge_nx: Default::default(),
            on_v: Default::default(),
            slots: Constant::new((u64::MAX >> (64 - m)).to_bits()),
            _m: m,
        }
    }
}

impl Logic for SlotFlags {
    #[hdl_gen]
    fn update(&mut self) {
        clock!(
            self, clock, busy_r, live_r, dip_r, pend_r, aprev_r, fprev_r, opened_r, hit_r, bridge_r
        );
        self.busy_nx.next = self.busy_r.q.val();
        self.live_nx.next = self.live_r.q.val();
        self.dip_nx.next = self.dip_r.q.val();
        self.pend_nx.next = self.pend_r.q.val();
        self.aprev_nx.next = self.aprev_r.q.val();
        self.fprev_nx.next = self.fprev_r.q.val();
        self.opened_nx.next = self.opened_r.q.val();
        self.hit_nx.next = self.hit_r.q.val();
        self.bridge_nx.next = self.bridge_r.q.val();

        // ---- Decide: the word's hits join the plane's.
        self.on_v.next = self.hit_r.q.val() | self.hits.val();
        if self.decide.val() {
            self.hit_nx.next = self.on_v.val();
        }

        // ---- The walked slot, then the opening (bit by bit: each write
        // replaces its bit of the flag as assigned so far).
        // Each loop inside a test that its writes imply: the co-simulation
        // skips the M slots on the clocks without a walk or an opening.
        if self.end_of_plane.val() | self.finish.val() | self.emit.val() {
            for i in 0..self._m {
                if self.walk_slot.val().get_bit(i) & self.end_of_plane.val() {
                    self.busy_nx.next = self.busy_nx.val().replace_bit(i, self.next_busy.val());
                    self.live_nx.next = self.live_nx.val().replace_bit(i, self.next_live.val());
                    self.pend_nx.next = self.pend_nx.val().replace_bit(i, false);
                    self.bridge_nx.next = self.bridge_nx.val().replace_bit(i, false);
                    if self.cut.val() {
                        self.dip_nx.next = self.dip_nx.val().replace_bit(i, false);
                    }
                    // Association state at the end of plane t.
                    self.aprev_nx.next = self
                        .aprev_nx
                        .val()
                        .replace_bit(i, self.next_busy.val() & self.next_live.val());
                    self.fprev_nx.next = self.fprev_nx.val().replace_bit(i, !self.next_busy.val());
                    self.opened_nx.next = self.opened_nx.val().replace_bit(i, false);
                    self.hit_nx.next = self.hit_nx.val().replace_bit(i, false);
                }
                // (`opened` too, so that the drain walks and Emit read the word
                // `finish` writes.)
                if self.walk_slot.val().get_bit(i) & self.finish.val() {
                    self.opened_nx.next = self.opened_nx.val().replace_bit(i, false);
                }
                if self.walk_slot.val().get_bit(i) & self.finish.val() & self.ends.val() {
                    self.live_nx.next = self.live_nx.val().replace_bit(i, false);
                    self.dip_nx.next = self.dip_nx.val().replace_bit(i, false);
                    if self.unconfirmed.val() {
                        self.busy_nx.next = self.busy_nx.val().replace_bit(i, false);
                    }
                }
                if self.walk_slot.val().get_bit(i) & self.emit.val() & self.was_busy.val() {
                    self.busy_nx.next = self.busy_nx.val().replace_bit(i, false);
                }
            }
        }
        if self.open.val() {
            for i in 0..self._m {
                if self.open.val() & self.open_slot.val().get_bit(i) {
                    self.busy_nx.next = self.busy_nx.val().replace_bit(i, true);
                    self.live_nx.next = self.live_nx.val().replace_bit(i, true);
                    self.dip_nx.next = self.dip_nx.val().replace_bit(i, false);
                    self.opened_nx.next = self.opened_nx.val().replace_bit(i, true);
                }
            }
        }

        // ---- The on/off step at the end of a row.
        self.on_off.enable.next = self.step.val();
        self.on_off.active_before.next = self.aprev_r.q.val();
        self.on_off.busy.next = self.busy_r.q.val();
        self.on_off.live.next = self.live_r.q.val();
        self.on_off.dip.next = self.dip_r.q.val();
        self.on_off.row_end.next = self.row_end.val();
        self.on_off.on.next = self.on_v.val();
        self.dip_nx.next = (self.dip_nx.val()
            & !(self.on_off.bridge.val() | self.on_off.ends.val()))
            | self.on_off.dip_starts.val();
        self.bridge_nx.next = self.bridge_nx.val() | self.on_off.bridge.val();
        self.live_nx.next = self.live_nx.val() & !self.on_off.ends.val();
        self.pend_nx.next = self.pend_nx.val() | self.on_off.ends.val();

        if self.restart.val() {
            self.busy_nx.next = 0.into();
            self.live_nx.next = 0.into();
            self.aprev_nx.next = 0.into();
            self.fprev_nx.next = self.slots.val();
            self.opened_nx.next = 0.into();
            self.hit_nx.next = 0.into();
            self.pend_nx.next = 0.into();
            self.bridge_nx.next = 0.into();
        }

        self.busy_r.d.next = self.busy_nx.val();
        self.live_r.d.next = self.live_nx.val();
        self.dip_r.d.next = self.dip_nx.val();
        self.pend_r.d.next = self.pend_nx.val();
        self.aprev_r.d.next = self.aprev_nx.val();
        self.fprev_r.d.next = self.fprev_nx.val();
        self.opened_r.d.next = self.opened_nx.val();
        self.hit_r.d.next = self.hit_nx.val();
        self.bridge_r.d.next = self.bridge_nx.val();

        self.busy.next = self.busy_r.q.val();
        self.live.next = self.live_r.q.val();
        self.dip.next = self.dip_r.q.val();
        self.pend.next = self.pend_r.q.val();
        self.opened.next = self.opened_r.q.val();
        self.bridges.next = self.bridge_r.q.val();
        self.active_before.next = self.aprev_r.q.val();
        self.free_before.next = self.fprev_r.q.val();
    }
}
