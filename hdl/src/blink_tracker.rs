//! Stage 5 — blink tracking in M slots, exactly the rules of
//! [`smartagg_model::blink_tracker`] and of `model/PACKETS.md` §8
//! (association against the slot states at the end of the previous plane
//! plus tracks opened earlier in this plane, lowest free slot, Chebyshev
//! `r_assoc`, 3×3 on/off around the anchor, single-plane dip bridging,
//! `L_min` confirmation of a first segment — a continuation is always
//! confirmed —, cut at `L_max`, the summation ranges, completion of a
//! dropped segment (first or continuation) at `t_drop + N − end_trim`, of a
//! cut segment at the cut plane, stream end).
//!
//! **What a segment sums** (the model's `sums_delayed`, PACKETS.md §8.6):
//! only the delayed plane `B_{t−N}`, never the live one. At plane t a busy
//! slot sums it iff `t ≥ N`, `t ≥ t_cross` (a continuation's `t_cross` is
//! the plane after the cut) and the segment is live at t (its opening
//! plane and the plane after a cut included), or has ended by a drop with
//! `dage = t − t_drop ≤ N − end_trim`, or has been truncated by the stream
//! end (all N drain planes). The planes summed are thus
//! `[max(0, t_cross − N), last]` with `last = t_drop − end_trim` (dropped),
//! `t_drop − N` (cut: the continuation goes on from `t_drop + 1 − N`, one
//! accumulator per slot) or `t_drop` (truncated).
//!
//! **Input.** The words of the front half's output (above bits, `H ≥ T_hold`, and
//! candidate bits of P pixels, word column, row) through a FIFO, in raster
//! order; the pipeline pushes only the words with an above bit and the last
//! word of every row, which marks the row's end. Words of flush/drain planes
//! carry `flush`.
//!
//! **Order of work within a plane t** (the model was written so that this
//! order gives its results):
//! * every word ORs its above bits into each slot's 3×3 window around the
//!   anchor (two P-bit lane masks, computed once when the slot opens);
//! * candidates are associated one per clock in raster order (the lowest
//!   candidate lane of the word first) against the slots active at the end
//!   of t−1 or opened earlier in t; a new track opens in the lowest slot free
//!   at the end of t−1 and not yet taken, or the candidate is dropped;
//! * at the end of row `min(ay + 1, H − 1)` the slot's 3×3 window has
//!   streamed and its on/off step is applied (bridge, dip, or end of the
//!   blink at `t_drop = t − 1`, which only marks the slot `pend`) — in the
//!   model this happens first, but no association reads what it changes;
//! * after the last row, the *walk* (see "Walk pipeline"): one clock per
//!   slot in slot order, once the sweep has finished plane t − 1 (see
//!   `swept`): a `pend` drop's t_drop and confirmation, the cut at L_max,
//!   the unconfirmed free or the completion, the Blink record and its
//!   continuation, the counters, and the slot's state and ROI view for
//!   plane t + 1 (its sums of t + 1 follow from its state at the end of t:
//!   the on/off step of t + 1 changes none of them). Then the Dropped
//!   record and plane t + 1. The model decides all slots first and then
//!   emits in slot order; each slot's decision reads only that slot, so one
//!   slot at a time gives the same records. The stream end's `finish` and
//!   the drain planes' ends are walks too.
//!
//! **Pipeline** (so that no path between registers is deeper than a few
//! LUTs). A word goes through three registered stages, one item per clock:
//! * the *item* stage ([`ItemStage`]) takes the head word's lowest
//!   candidate lane not yet taken, or the word itself when it has none;
//! * the *compare* stage ([`CompareStage`]) compares it with every slot's
//!   association window (stored when the slot opened), 3×3 window and last
//!   row ([`SlotCompare`]), and computes what an opening would write
//!   ([`OpeningWindows`]); its doc gives the flow between the stages (the
//!   replay after an opening, the clock after the plane's last item);
//! * the *decide* stage acts on it in Run: the association against the
//!   current flags ([`Association`]), the opening or drop, the hits, the
//!   end-of-row step ([`OnOffStep`], in [`SlotFlags`]).
//!
//! A word's hits on a slot opened in this plane, or on a free one, may be
//! stale, and need not be right: only slots active at the end of t − 1 have
//! their on/off step, and the walk clears every slot's hits.
//!
//! **Walk pipeline** ([`WalkPipeline`]). A walk also runs in three
//! stages, one slot per clock: the read stage takes the slot's state, W1
//! computes what the walk does to it ([`WalkStep`]), and W2's slot waits
//! for the sweep and the bank ([`WalkGate`]) while the tracker pushes the
//! record and writes the slot.
//!
//! **Ages instead of plane arithmetic** ([`WalkStep`]). Each slot keeps its
//! ages `age = t − t_cross` and `dage = t − t_drop` ([`AGE_BITS`] bits)
//! instead of its planes: one subtraction after the slot multiplexer
//! instead of two 48-bit registers per slot.
//!
//! **ROI view (shadow).** For each plane t and slot, the tracker publishes
//! what the ROI aggregator needs — sum the delayed plane (`pre`, the
//! model's `sums_delayed`), first plane of the segment (`fresh`: its
//! opening plane or the plane after a cut; the counters and mask flags
//! start from zero, and the aggregator sweeps the ROI even without `pre`),
//! anchor and counter bank — in a table indexed by the parity of t. A
//! slot's entry for plane t is written by the walk at the end of t − 1, or
//! when the slot opens in t, before the aggregator (which follows
//! `plane`/`rows_done`) reads any ROI row of it; the stream end's `finish`
//! clears the flags of a track it ends unconfirmed. Entries of plane t stay
//! untouched while the tracker works on t+1, until the sweep has finished
//! plane t (the walk at the end of t + 1 writes the entries of t + 2 over
//! them).
//!
//! **Records** go to the record queue in the model's order, numbered later
//! by the packetiser: StreamStart, then per plane the completed segments in
//! slot order and one Dropped record, and at stream end the finished
//! segments and StreamEnd. A Blink record carries its counter bank; the slot
//! takes a fresh bank from the free list (and waits for one that is on its
//! way back: [`WalkGate`]). A record lost to a full queue is counted, never
//! silent ([`RecordPort`]).
//!
//! **Registers.** The slots' state is most of the tracker's flip-flops, and
//! a simulator such as Verilator copies every register on every clock
//! (those copies were 29 % of the full-field co-simulation's time with one
//! register per slot and field), so it is packed: one
//! [`MAX_SLOTS`](crate::config::MAX_SLOTS)-bit register per flag (bit i:
//! slot i; [`SlotFlags`]), and 64-bit words per slot and ROI view entry
//! ([`slot_word`], [`shadow`]; [`SlotWords`]). Synthesis maps the same
//! flip-flops either way. The walks and openings of one clock touch
//! different slots. The StreamEnd totals, the plane's drops and the bank
//! error are [`TrackerCounters`].
//!
//! **Stream end** (`stopping`, `planes_total = p`): after plane p−1 the
//! tracker does the model's `finish` (live tracks end at p−1, TRUNCATED),
//! follows the N drain planes (their ends are flush rows) so that the
//! aggregator completes the sums from the delay line (`B_{p−N} … B_{p−1}`:
//! a truncated segment sums every drain plane, a dropped one while
//! `dage ≤ N − end_trim`), emits the finished segments in slot order and
//! then StreamEnd.

mod association;
mod compare_stage;
mod counters;
mod item_stage;
mod layout;
mod on_off_step;
mod opening;
mod record_port;
mod sequencer;
mod slot_compare;
mod slot_flags;
mod slot_mux;
mod slot_words;
mod walk_gate;
mod walk_memory;
mod walk_pipeline;
mod walk_stages;
mod walk_step;

pub use association::Association;
pub use compare_stage::CompareStage;
pub use counters::TrackerCounters;
pub use item_stage::ItemStage;
pub use layout::{shadow, slot_word, AGE_BITS, COORD_BITS, MAX_FIELD};
pub use on_off_step::OnOffStep;
pub use opening::OpeningWindows;
pub use record_port::{record_kind, RecordPort};
pub use sequencer::{Sequencer, TrackerState};
pub use slot_compare::SlotCompare;
pub use slot_flags::SlotFlags;
pub use slot_mux::SlotMux;
pub use slot_words::SlotWords;
pub use walk_gate::WalkGate;
pub use walk_memory::{WalkMemory, WALK_WORD_BITS};
pub use walk_pipeline::WalkPipeline;
pub use walk_stages::{WalkStages, WalkedSlot};
pub use walk_step::{walk_word, WalkStep};

use crate::bundles::{RecordPushOut, TrackerTotalsOut};
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// The M-slot blink tracker. `P`: pixels per word; `NW`: bits of N;
/// `BW`: bits of a counter-bank index.
#[derive(LogicBlock)]
pub struct BlinkTracker<const P: usize, const NW: usize, const BW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: all slots free, plane 0, StreamStart first.
    pub restart: Signal<In, Bit>,
    /// With `restart`: a stream starts (push StreamStart); without, the
    /// tracker is only cleared (RESET).
    pub emit_start: Signal<In, Bit>,
    /// N register.
    pub n_window: Signal<In, Bits<NW>>,
    /// END_TRIM register (≤ N − 1): a dropped segment sums while
    /// `dage ≤ N − end_trim`.
    pub end_trim: Signal<In, Bits<NW>>,
    /// L_min register (≥ 1).
    pub l_min: Signal<In, Bits<32>>,
    /// L_max register (≥ max(L_min, N)).
    pub l_max: Signal<In, Bits<32>>,
    /// No real plane after `planes_total` will come.
    pub stopping: Signal<In, Bit>,
    /// Number of real planes p of the stream (valid with `stopping`).
    pub planes_total: Signal<In, Bits<48>>,
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
    /// It belongs to a flush or drain plane.
    pub in_flush: Signal<In, Bit>,
    /// Pop the head word.
    pub in_pop: Signal<Out, Bit>,
    /// Planes the ROI aggregator has swept completely (its `planes_done`).
    /// The end of plane t writes the ROI view of plane t + 1 over that of
    /// plane t − 1, so it waits until this reaches t: however far the
    /// sweep falls behind, it never reads a view that is not its plane's
    /// (the tracker's input FIFO then fills, and a source that can wait
    /// holds back; one that cannot overflows it, which is a FAULT).
    pub swept: Signal<In, Bits<48>>,
    /// Plane t being tracked.
    pub plane: Signal<Out, Bits<48>>,
    /// Rows of plane t fully processed (H once the plane's rows are done).
    pub rows_done: Signal<Out, Bits<16>>,
    /// StreamEnd has been pushed.
    pub done: Signal<Out, Bit>,
    /// ROI view, index `parity·M + slot`: one word per entry, fields at
    /// [`shadow`]'s offsets (sum the delayed plane, fresh, anchor, counter
    /// bank).
    pub sh: Vec<Signal<Out, Bits<64>>>,
    /// The record descriptor pushed into the record queue, and its room.
    pub record: RecordPushOut<BW>,
    /// A free bank is available.
    pub fb_valid: Signal<In, Bit>,
    /// The free bank.
    pub fb_bank: Signal<In, Bits<BW>>,
    /// Take the free bank.
    pub fb_pop: Signal<Out, Bit>,
    /// The StreamEnd totals.
    pub totals: TrackerTotalsOut,
    /// A Blink waited 16 clocks for a free bank while the record queue had
    /// room (sticky; never expected: it means a bank went missing).
    pub bank_error: Signal<Out, Bit>,
    /// The state, the plane t and its rows done.
    seq: Sequencer<NW>,
    /// The records asked for by the states, and the lost-record count.
    port: RecordPort<BW>,
    /// The StreamEnd totals, the plane's drops and the bank error.
    counters: TrackerCounters,
    // Per slot, packed (see "Registers" in the module doc).
    /// The slots' flags and their writes.
    flags: SlotFlags,
    /// The slots' words (anchor, window rows and bank; lane masks;
    /// association window) and ROI view, and their writes.
    words: SlotWords<BW>,
    /// The item stage (see "Pipeline" in the module doc): one candidate
    /// lane of the head word, or the word itself when it has none.
    items: ItemStage<P>,
    /// The compare stage: the item against every slot, and what an opening
    /// by its candidate writes, registered for the decide stage.
    compare: CompareStage<P>,
    /// The decide stage's absorption, opening or drop of a candidate.
    association: Association,
    /// The walks: the read stage, W1 and W2.
    walks: WalkPipeline<BW>,
    /// When W2's slot is written, and its Blink.
    gate: WalkGate,
    /// The walk holds a Blink this clock: the record queue has room but the
    /// free list shows no bank yet (observed by the tests).
    pub bank_wait: Signal<Local, Bit>,
    /// The walked slot's bank from now on.
    n_bank: Signal<Local, Bits<BW>>,
    _m: usize,
}

impl<const P: usize, const NW: usize, const BW: usize> BlinkTracker<P, NW, BW> {
    /// The tracker of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        let f = &cfg.front;
        GatewareConfig::check_width("BlinkTracker", "P", P, f.pixels_per_clock)?;
        GatewareConfig::check_width("BlinkTracker", "NW", NW, f.count_bits())?;
        GatewareConfig::check_width("BlinkTracker", "BW", BW, cfg.bank_bits())?;
        layout::fits(cfg, P, BW)?;
        let m = cfg.slots;
        Ok(BlinkTracker {
            clock: Default::default(),
            restart: Default::default(),
            emit_start: Default::default(),
            n_window: Default::default(),
            end_trim: Default::default(),
            l_min: Default::default(),
            l_max: Default::default(),
            stopping: Default::default(),
            planes_total: Default::default(),
            in_valid: Default::default(),
            in_above: Default::default(),
            in_cand: Default::default(),
            in_x: Default::default(),
            in_y: Default::default(),
            in_flush: Default::default(),
            in_pop: Default::default(),
            swept: Default::default(),
            plane: Default::default(),
            rows_done: Default::default(),
            done: Default::default(),
            sh: lanes(2 * m),
            record: Default::default(),
            fb_valid: Default::default(),
            fb_bank: Default::default(),
            fb_pop: Default::default(),
            totals: Default::default(),
            bank_error: Default::default(),
            seq: Default::default(),
            port: Default::default(),
            counters: Default::default(),
            flags: SlotFlags::new(m),
            words: SlotWords::new(m, P),
            association: Default::default(),
            walks: WalkPipeline::new(m),
            gate: Default::default(),
            items: ItemStage::new(cfg),
            compare: CompareStage::new(cfg),
            bank_wait: Default::default(),
            n_bank: Default::default(),
            _m: m,
        })
    }
}

impl<const P: usize, const NW: usize, const BW: usize> Logic for BlinkTracker<P, NW, BW> {
    #[hdl_gen]
    fn update(&mut self) {
        self.seq.clock.next = self.clock.val();
        self.walks.clock.next = self.clock.val();
        self.gate.clock.next = self.clock.val();
        self.items.clock.next = self.clock.val();
        self.compare.clock.next = self.clock.val();
        self.flags.clock.next = self.clock.val();
        self.words.clock.next = self.clock.val();
        self.counters.clock.next = self.clock.val();
        self.port.clock.next = self.clock.val();
        self.association.clock.next = self.clock.val();
        for q in 0..(2 * self._m) {
            self.sh[q].next = self.words.sh[q].val();
        }

        // ---- The state, the plane t and its rows ([`Sequencer`]).
        self.seq.restart.next = self.restart.val();
        self.seq.emit_start.next = self.emit_start.val();
        self.seq.n_window.next = self.n_window.val();
        self.seq.stopping.next = self.stopping.val();
        self.seq.planes_total.next = self.planes_total.val();
        self.seq.room.next = self.record.room.val();
        self.seq.step.next = self.compare.step.val();
        self.seq.lastrow.next = self.compare.lastrow.val();
        self.seq.row.next = self.compare.cy.val();
        self.seq.walked.next = self.gate.done.val() & self.walks.w2.last.val();
        self.seq.in_valid.next = self.in_valid.val();
        self.seq.in_flush.next = self.in_flush.val();
        self.seq.in_y.next = self.in_y.val();
        self.seq.head_eor.next = self.items.head_eor.val();
        self.seq.head_lastrow.next = self.items.head_lastrow.val();

        // ---- Item stage: the head word's next item, taken by the compare
        // stage ([`CompareStage`], which also gives the flow between the
        // three stages; see "Pipeline" in the module doc). (When the sequencer
        // is `finishing`, both stages are empty: they take only real words, and
        // every real plane is done.)
        self.items.restart.next = self.restart.val();
        self.items.in_valid.next = self.in_valid.val();
        self.items.in_above.next = self.in_above.val();
        self.items.in_cand.next = self.in_cand.val();
        self.items.in_x.next = self.in_x.val();
        self.items.in_y.next = self.in_y.val();
        self.items.in_flush.next = self.in_flush.val();
        self.items.take.next = self.compare.take.val();
        self.in_pop.next = self.items.pop.val() | self.seq.drain_pop.val();

        // ---- Compare stage: the item against every slot's words, and what
        // an opening by it writes.
        self.compare.restart.next = self.restart.val();
        self.compare.run.next = self.seq.run.val();
        self.compare.open.next = self.association.open.val();
        self.compare.item_valid.next = self.items.valid.val();
        self.compare.item_cand.next = self.items.cand.val();
        self.compare.item_last.next = self.items.last.val();
        self.compare.item_eor.next = self.items.eor.val();
        self.compare.item_lastrow.next = self.items.lastrow.val();
        self.compare.item_cx.next = self.items.cx.val();
        self.compare.item_cy.next = self.items.yc.val();
        self.compare.item_word_col.next = self.items.xc.val();
        self.compare.item_row_m1.next = self.items.ym1.val();
        self.compare.item_row_p1.next = self.items.yp1.val();
        self.compare.item_above.next = self.items.above.val();
        for i in 0..self._m {
            self.compare.slot_geo[i].next = self.words.geo[i].val();
            self.compare.slot_win[i].next = self.words.win[i].val();
            self.compare.slot_bnd[i].next = self.words.bnd[i].val();
        }

        // ---- Decide stage: the item against the slots as they are now
        // ([`Association`]: absorb, open in the lowest free slot, or drop).
        self.association.candidate.next = self.compare.candidate.val();
        self.association.near.next = self.compare.near.val();
        self.association.busy.next = self.flags.busy.val();
        self.association.active_before.next = self.flags.active_before.val();
        self.association.free_before.next = self.flags.free_before.val();
        self.association.opened.next = self.flags.opened.val();

        // ---- The walks ([`WalkPipeline`]): the read stage takes the next
        // slot into W1, W1 decides what the walk does to it into W2, and W2
        // does it, one slot per clock each.
        // W2's step ([`WalkGate`]): the end of a plane waits until the sweep
        // has finished plane t − 1, whose ROI view it overwrites (see
        // `swept`); a Blink waits for its fresh bank.
        self.gate.end_of_plane.next = self.seq.walk.val();
        self.gate.finish.next = self.seq.finish.val();
        self.gate.drain.next = self.seq.drain_walk.val();
        self.gate.emit.next = self.seq.emit.val();
        self.gate.view_free.next = self.swept.val() >= self.seq.t.val();
        self.gate.valid.next = self.walks.w2.valid.val();
        self.gate.comp.next = self.walks.w2.comp.val();
        self.gate.was_busy.next = self.walks.w2.was_busy.val();
        self.gate.room.next = self.record.room.val();
        self.gate.fb_valid.next = self.fb_valid.val();
        self.bank_wait.next = self.gate.bank_wait.val();
        self.walks.restart.next = self.restart.val();
        self.walks.start.next = self.seq.start_walk.val();
        self.walks.done.next = self.gate.done.val();
        self.walks.write_back.next = self.gate.write_back.val();
        // The walks' constants, in the ages' width.
        self.walks.n.next = bit_cast::<18, NW>(self.n_window.val());
        self.walks.end_trim.next = bit_cast::<18, NW>(self.end_trim.val());
        self.walks.l_min.next = bit_cast::<18, 32>(self.l_min.val());
        self.walks.l_max.next = bit_cast::<18, 32>(self.l_max.val());
        // The read stage's slot, through one multiplexer.
        self.walks.busy.next = self.flags.busy.val();
        self.walks.live.next = self.flags.live.val();
        self.walks.dip.next = self.flags.dip.val();
        self.walks.pend.next = self.flags.pend.val();
        self.walks.opened.next = self.flags.opened.val();
        self.walks.bridges.next = self.flags.bridges.val();
        for i in 0..self._m {
            self.walks.slot_geo[i].next = self.words.geo[i].val();
        }
        // W1 into W2: what the walk makes of the slot.
        self.walks.end_of_plane.next = self.seq.walk.val();
        self.walks.finish.next = self.seq.finish.val();
        self.walks.drain.next = self.seq.drain_walk.val();
        self.walks.t.next = self.seq.t.val();
        self.walks.t1_ge_n.next = self.seq.t1_ge_n.val();

        // ---- The records ([`RecordPort`]): W2's Blink, the plane's Dropped
        // record, StreamStart and StreamEnd, each in its state.
        RecordPushOut::<BW>::link(&mut self.record, &mut self.port.record);
        self.port.restart.next = self.restart.val();
        self.port.fb_valid.next = self.fb_valid.val();
        self.fb_pop.next = self.port.fb_pop.val();
        self.port.t.next = self.seq.t.val();
        self.port.stream_start.next = self.seq.stream_start.val();
        self.port.blink.next = self.gate.blink.val();
        self.port.emit.next = self.seq.emit.val();
        self.port.slot.next = self.walks.w2.slot.val();
        self.port.flags.next = self.walks.w2.flags.val();
        self.port.ax.next = self.walks.w2.ax.val();
        self.port.ay.next = self.walks.w2.ay.val();
        self.port.t_cross.next = self.walks.w2.tc.val();
        self.port.t_drop.next = self.walks.w2.td.val();
        self.port.bank.next = self.walks.w2.bank.val();
        self.port.walk_end.next = self.seq.walk_end.val();
        self.port.plane_drops.next = self.counters.plane_drops.val();
        self.port.first_x.next = self.counters.first_x.val();
        self.port.first_y.next = self.counters.first_y.val();
        self.port.stream_end.next = self.seq.stream_end.val();
        self.counters.blink.next = self.gate.blink.val();
        // The walk's events (W2's slot, as it is written).
        self.counters.bridge.next = self.gate.we_walk.val() & self.walks.w2.bridge.val();
        self.counters.cut.next = self.gate.we_walk.val() & self.walks.w2.cut.val();
        self.counters.unconfirmed_end.next = (self.gate.we_walk.val() & self.walks.w2.unconf.val())
            | (self.gate.we_fin.val() & self.walks.w2.fin_unconf.val());
        self.counters.plane_end.next = self.seq.walk_end.val();

        // The walked slot's bank from now on (and in its ROI view for plane
        // t + 1): a fresh one if it has just handed its bank to a Blink record.
        self.n_bank.next = self.walks.w2.bank.val();
        if self.fb_pop.val() {
            self.n_bank.next = self.fb_bank.val();
        }

        self.counters.restart.next = self.restart.val();
        self.counters.bank_wait.next = self.bank_wait.val();
        self.counters.drop.next = self.association.drop.val();
        self.counters.drop_x.next = self.compare.cx.val();
        self.counters.drop_y.next = self.compare.cy.val();

        // ---- The slots' words ([`SlotWords`]): the walked slot's bank and
        // its ROI view for plane t + 1 (or, in `finish`, the flags of its
        // view of t cleared if its track ends unconfirmed); an opening.
        self.words.restart.next = self.restart.val();
        self.words.parity.next = self.seq.t.val().get_bit(0);
        self.words.walk_slot.next = self.walks.w2.sel.val();
        self.words.end_of_plane.next = self.gate.we_walk.val();
        self.words.drain.next = self.gate.we_drain.val();
        self.words.finish.next = self.gate.we_fin.val();
        self.words.emit.next = self.gate.we_emit.val();
        self.words.was_busy.next = self.walks.w2.was_busy.val();
        self.words.next_bank.next = self.n_bank.val();
        self.words.walk_ax.next = self.walks.w2.ax.val();
        self.words.walk_ay.next = self.walks.w2.ay.val();
        self.words.next_pre.next = self.walks.w2.n_pre.val();
        self.words.next_fresh.next = self.walks.w2.n_fresh.val();
        self.words.unconfirmed.next = self.walks.w2.fin_unconf.val();
        self.words.open.next = self.association.open.val();
        self.words.open_slot.next = self.association.open_slot.val();
        self.words.open_geo.next = self.compare.open_geo.val();
        self.words.open_win.next = self.compare.open_win.val();
        self.words.open_bnd.next = self.compare.open_bnd.val();
        self.words.open_view.next = self.compare.open_view.val();
        self.words.open_pre.next = self.seq.t_ge_n.val();

        // ---- The slots' flags ([`SlotFlags`]): the decided word's hits and,
        // at the end of a row, the on/off step of the slots whose 3x3 window
        // has streamed (an end of the blink at t − 1 only marks the slot
        // `pend`: the walk settles its t_drop and confirmation, and its view
        // of plane t stays, as it sums B_{t−N} at dage = 1 ≤ N − end_trim);
        // the opening; the walked slot.
        self.flags.restart.next = self.restart.val();
        self.flags.decide.next = self.compare.go.val() & !self.seq.finishing.val();
        self.flags.hits.next = self.compare.hits.val();
        self.flags.step.next = self.compare.step.val();
        self.flags.row_end.next = self.compare.row_end.val();
        self.flags.open.next = self.association.open.val();
        self.flags.open_slot.next = self.association.open_slot.val();
        self.flags.walk_slot.next = self.walks.w2.sel.val();
        self.flags.end_of_plane.next = self.gate.we_walk.val();
        self.flags.finish.next = self.gate.we_fin.val();
        self.flags.emit.next = self.gate.we_emit.val();
        self.flags.was_busy.next = self.walks.w2.was_busy.val();
        self.flags.next_busy.next = self.walks.w2.n_busy.val();
        self.flags.next_live.next = self.walks.w2.n_live.val();
        self.flags.cut.next = self.walks.w2.cut.val();
        self.flags.ends.next = self.walks.w2.fin_end.val();
        self.flags.unconfirmed.next = self.walks.w2.fin_unconf.val();

        self.plane.next = self.seq.t.val();
        self.rows_done.next = self.seq.rows.val();
        self.done.next = self.seq.done.val();
        TrackerTotalsOut::link(&mut self.totals, &mut self.counters.totals);
        self.bank_error.next = self.counters.bank_error.val();
    }
}
