//! What a walk does to one slot (the W1 stage of the tracker's
//! [`WalkPipeline`](super::WalkPipeline); combinational,
//! [`WalkStages`](super::WalkStages) registers it in W2): a `pend` drop's
//! t_drop and confirmation, the cut at L_max, the unconfirmed free or the
//! completion, the Blink record's flags and planes, the slot's state for
//! plane t + 1 and its ROI view flags, and the word written back to the
//! walk memory. The stream end's `finish` and a drain plane's end use the
//! same step with their own write-back.
//!
//! **Ages instead of plane arithmetic.** Each slot keeps `age = t − t_cross`
//! ([`AGE_BITS`] bits; L_min, L_max and N are at most L_max,max, checked
//! when the tracker is generated): confirmation `t_drop − t_cross ≥ L_min`
//! (of a first segment; a continuation is always confirmed) is
//! `age ≥ L_min + 1` at the drop, the cut `t + 1 ≥ t_cross + L_max` is
//! `age ≥ L_max − 1`. A second per-slot age `dage = t − t_drop` (also
//! [`AGE_BITS`] bits; 1 at the plane `t_drop + 1` that sees the drop and
//! at the stream end, where `t_drop = p − 1` and `t = p`; at most 2N when
//! recorded at the stream end) gives the completion of a drop,
//! `t ≥ t_drop + N − end_trim`, as `dage ≥ N − end_trim`, and a dropped
//! segment's sums of plane t + 1, `dage + 1 ≤ N − end_trim`. The record's
//! planes are not stored either: `t_cross = t − age` (a continuation
//! starts at `age = −1`, which is 0 by the time it can be recorded) and
//! `t_drop = t − dage` (a cut: `t`); both ages advance with t. One
//! subtraction after the slot multiplexer, instead of two 48-bit registers
//! per slot.
//!
//! The walk's constants (L_min, L_min + 1, L_max − 1 and N − end_trim) are
//! registers of the walk pipeline.

use super::layout::AGE_BITS;
use super::walk_memory::WALK_WORD_BITS;
use rust_hdl::prelude::*;

/// Bit offsets of a slot's walk word (see
/// [`WALK_WORD_BITS`]): age, dage, and the
/// confirmation, continuation and truncation flags. `update` writes them
/// as literals where rust-hdl's `hdl_gen` needs a number.
pub mod walk_word {
    /// `age = t − t_cross` ([`AGE_BITS`](super::AGE_BITS) bits).
    pub const AGE: usize = 0;
    /// `dage = t − t_drop`.
    pub const DAGE: usize = 18;
    /// The segment is confirmed (lasted L_min planes, or continues a cut).
    pub const CONF: usize = 36;
    /// The segment continues a cut one.
    pub const CONT: usize = 37;
    /// The segment was ended by the stream end.
    pub const TRUNC: usize = 38;
}

const _: () = assert!(
    walk_word::DAGE == AGE_BITS
        && walk_word::CONF == 2 * AGE_BITS
        && walk_word::TRUNC + 1 == WALK_WORD_BITS
);

/// One slot's walk step.
#[derive(LogicBlock, Default)]
pub struct WalkStep {
    /// The end of a real plane (the tracker's `Walk`).
    pub end_of_plane: Signal<In, Bit>,
    /// The stream end's `finish`.
    pub finish: Signal<In, Bit>,
    /// The end of a drain plane: the slot only ages.
    pub drain: Signal<In, Bit>,
    /// The slot holds a track.
    pub busy: Signal<In, Bit>,
    /// Its segment is live (not yet dropped).
    pub live: Signal<In, Bit>,
    /// Its blink is in a single-plane dip.
    pub dip: Signal<In, Bit>,
    /// Its blink ended in this plane (at t_drop = t − 1).
    pub pend: Signal<In, Bit>,
    /// The slot opened in this plane (its word is a previous track's).
    pub opened: Signal<In, Bit>,
    /// The slot's walk word.
    pub word: Signal<In, Bits<39>>,
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
    /// The segment is cut at L_max (it completes, and goes on as a
    /// continuation).
    pub cut: Signal<Out, Bit>,
    /// The segment ended unconfirmed: the slot is freed without a record.
    pub unconf: Signal<Out, Bit>,
    /// The segment completes: its Blink record is due.
    pub comp: Signal<Out, Bit>,
    /// The record's flag bits (CUT 0x04, CONTINUATION 0x08, TRUNCATED 0x10).
    pub flags: Signal<Out, Bits<8>>,
    /// The record's t_cross.
    pub tc: Signal<Out, Bits<48>>,
    /// The record's t_drop (the cut plane for a cut).
    pub td: Signal<Out, Bits<48>>,
    /// The slot holds a track in plane t + 1.
    pub n_busy: Signal<Out, Bit>,
    /// Its segment is live in plane t + 1.
    pub n_live: Signal<Out, Bit>,
    /// Its ROI view for plane t + 1: sum the delayed plane.
    pub n_pre: Signal<Out, Bit>,
    /// Its ROI view for plane t + 1: first plane of a segment (after a cut).
    pub n_fresh: Signal<Out, Bit>,
    /// `finish` ends a live track.
    pub fin_end: Signal<Out, Bit>,
    /// `finish` ends it unconfirmed.
    pub fin_unconf: Signal<Out, Bit>,
    /// The word the walk writes back.
    pub word_next: Signal<Out, Bits<39>>,
    w_age: Signal<Local, Bits<AGE_BITS>>,
    w_dage: Signal<Local, Bits<AGE_BITS>>,
    w_conf: Signal<Local, Bit>,
    w_cont: Signal<Local, Bit>,
    w_trunc: Signal<Local, Bit>,
    ge_lmin: Signal<Local, Bit>,
    ge_lmin1: Signal<Local, Bit>,
    ge_lmax1: Signal<Local, Bit>,
    ge_nc: Signal<Local, Bit>,
    w_conf1: Signal<Local, Bit>,
    w_dage1: Signal<Local, Bits<AGE_BITS>>,
    w_fconf: Signal<Local, Bit>,
    n_cont: Signal<Local, Bit>,
    n_age: Signal<Local, Bits<AGE_BITS>>,
    n_dage: Signal<Local, Bits<AGE_BITS>>,
    wr_age: Signal<Local, Bits<AGE_BITS>>,
    wr_dage: Signal<Local, Bits<AGE_BITS>>,
    wr_conf: Signal<Local, Bit>,
    wr_cont: Signal<Local, Bit>,
    wr_trunc: Signal<Local, Bit>,
}

impl Logic for WalkStep {
    #[hdl_gen]
    fn update(&mut self) {
        // A slot opened in this plane has not been walked since: its word
        // is a previous track's, and the opening's values (age 0,
        // unconfirmed, no continuation, not truncated) stand in for it (so
        // that the opening needs no second write port; `dage` means nothing
        // until the drop).
        self.w_age.next = self.word.val().get_bits::<18>(0);
        self.w_dage.next = self.word.val().get_bits::<18>(18);
        self.w_conf.next = self.word.val().get_bit(36);
        self.w_cont.next = self.word.val().get_bit(37);
        self.w_trunc.next = self.word.val().get_bit(38);
        if self.opened.val() {
            self.w_age.next = 0.into();
            self.w_conf.next = false;
            self.w_cont.next = false;
            self.w_trunc.next = false;
        }
        self.ge_lmin.next = self.w_age.val() >= self.lmin.val();
        self.ge_lmin1.next = self.w_age.val() >= self.lmin_p1.val();
        self.ge_lmax1.next = self.w_age.val() >= self.lmax_m1.val();
        // A blink that ended in this plane (its on/off step found the second
        // plane below: `pend`) ended at t_drop = t − 1, confirmed if it lasted
        // L_min planes.
        self.w_conf1.next = self.w_conf.val();
        self.w_dage1.next = self.w_dage.val();
        if self.pend.val() {
            self.w_conf1.next = self.w_cont.val() | self.ge_lmin1.val();
            self.w_dage1.next = 1.into();
        }
        // A dropped segment's last plane, t_drop − end_trim, leaves the
        // window (is summed) at plane t_drop + N − end_trim: `dage1 ≥ N −
        // end_trim` (dage1 = t − t_drop in this plane: 1 for a `pend` drop,
        // compared through a register rather than behind the multiplexer).
        self.ge_nc.next = self.w_dage.val() >= self.n_mc.val();
        if self.pend.val() {
            self.ge_nc.next = self.mc_one.val();
        }
        // Cut at L_max; an ended track unconfirmed is freed, a confirmed one
        // completes once it has summed its last plane.
        self.cut.next = self.busy.val() & self.live.val() & !self.dip.val() & self.ge_lmax1.val();
        self.unconf.next = self.busy.val() & !self.live.val() & !self.w_conf1.val();
        self.comp.next = self.cut.val()
            | (self.busy.val() & !self.live.val() & self.w_conf1.val() & self.ge_nc.val());
        // The model's `finish`: a live track is confirmed if it lasted L_min planes.
        self.w_fconf.next = self.w_cont.val()
            | (!self.dip.val() & self.ge_lmin.val())
            | (self.dip.val() & self.ge_lmin1.val());
        self.fin_end.next = self.busy.val() & self.live.val();
        self.fin_unconf.next = self.busy.val() & self.live.val() & !self.w_fconf.val();
        // Record flag bits (model `flags`).
        self.flags.next = 0.into();
        if self.cut.val() {
            self.flags.next = self.flags.val() | 4;
        }
        if self.w_cont.val() {
            self.flags.next = self.flags.val() | 8;
        }
        if self.w_trunc.val() {
            self.flags.next = self.flags.val() | 16;
        }
        self.tc.next = self.t.val() - bit_cast::<48, 18>(self.w_age.val());
        self.td.next = self.t.val() - bit_cast::<48, 18>(self.w_dage1.val());
        if self.cut.val() {
            self.td.next = self.t.val();
        }
        // The slot after the walk, ages advanced to plane t + 1: a cut blink
        // goes on as a continuation from t + 1 (age 0 at t + 1); a
        // completed or unconfirmed one frees the slot.
        self.n_busy.next = self.busy.val() & !self.unconf.val();
        if self.comp.val() & !self.cut.val() {
            self.n_busy.next = false;
        }
        self.n_live.next = self.live.val() | self.cut.val();
        self.n_cont.next = self.w_cont.val() | self.cut.val();
        self.n_age.next = self.w_age.val() + 1;
        self.n_dage.next = self.w_dage1.val() + 1;
        if self.cut.val() {
            self.n_age.next = 0.into();
            self.n_dage.next = 1.into();
        }
        // A drain plane ends no track: the slot only ages.
        if self.drain.val() {
            self.n_busy.next = self.busy.val();
        }
        // Its ROI view for plane t + 1 (≥ t_cross of a busy slot's
        // segment): sum B_{t+1−N} if t + 1 ≥ N and the segment is live, or
        // truncated by the stream end (every drain plane), or dropped with
        // dage(t + 1) = dage1 + 1 ≤ N − end_trim (at the end of a real
        // plane a dropped segment still busy has not completed, so this
        // holds; in a drain plane it may not). The first plane of a
        // segment after a cut (the opening writes its own).
        self.n_pre.next = self.n_busy.val()
            & self.t1_ge_n.val()
            & (self.n_live.val() | self.w_trunc.val() | !self.ge_nc.val());
        self.n_fresh.next = self.n_busy.val() & self.cut.val();
        // What the walk writes back to the slot's word: the end of a plane
        // its next state, the stream end's `finish` the end of a live track
        // (at t − 1 = p − 1, truncated), a drain plane's end the ages.
        self.wr_age.next = self.n_age.val();
        self.wr_dage.next = self.n_dage.val();
        self.wr_conf.next = self.w_conf.val();
        self.wr_cont.next = self.w_cont.val();
        self.wr_trunc.next = self.w_trunc.val();
        if self.end_of_plane.val() {
            self.wr_conf.next = self.w_conf1.val() | self.cut.val();
            self.wr_cont.next = self.n_cont.val();
            if self.cut.val() {
                self.wr_trunc.next = false;
            }
        }
        if self.finish.val() {
            self.wr_age.next = self.w_age.val();
            self.wr_dage.next = self.w_dage.val();
            if self.busy.val() & self.live.val() {
                self.wr_dage.next = 1.into();
                self.wr_trunc.next = true;
                self.wr_conf.next = self.w_fconf.val();
            }
        }
        self.word_next.next = bit_cast::<39, 18>(self.wr_age.val())
            | (bit_cast::<39, 18>(self.wr_dage.val()) << 18)
            | (bit_cast::<39, 1>(self.wr_conf.val().into()) << 36)
            | (bit_cast::<39, 1>(self.wr_cont.val().into()) << 37)
            | (bit_cast::<39, 1>(self.wr_trunc.val().into()) << 38);
    }
}
