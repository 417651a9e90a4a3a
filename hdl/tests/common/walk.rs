//! What the tracker's walk step makes of a slot, read from the block that
//! computes it (`WalkStep`) or from W2, which holds it (`WalkedSlot`).

use smartagg_hdl::blink_tracker::{WalkStep, WalkedSlot};

/// The walk step's outputs for one slot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOut {
    pub cut: bool,
    pub unconf: bool,
    pub comp: bool,
    pub flags: u64,
    pub tc: u64,
    pub td: u64,
    pub n_busy: bool,
    pub n_live: bool,
    pub n_pre: bool,
    pub n_fresh: bool,
    pub fin_end: bool,
    pub fin_unconf: bool,
    /// The word written back to the walk memory.
    pub word: u64,
}

impl StepOut {
    /// The outputs of a settled walk step.
    pub fn of_step(o: &WalkStep) -> Self {
        StepOut {
            cut: o.cut.val(),
            unconf: o.unconf.val(),
            comp: o.comp.val(),
            flags: o.flags.val().to_u64(),
            tc: o.tc.val().to_u64(),
            td: o.td.val().to_u64(),
            n_busy: o.n_busy.val(),
            n_live: o.n_live.val(),
            n_pre: o.n_pre.val(),
            n_fresh: o.n_fresh.val(),
            fin_end: o.fin_end.val(),
            fin_unconf: o.fin_unconf.val(),
            word: o.word_next.val().to_u64(),
        }
    }

    /// What W2 holds, with `word` the word it writes back (the walk
    /// stages' `word`; the walk pipeline keeps it inside).
    pub fn of_w2<const BW: usize>(w: &WalkedSlot<BW>, word: u64) -> Self {
        StepOut {
            cut: w.cut.val(),
            unconf: w.unconf.val(),
            comp: w.comp.val(),
            flags: w.flags.val().to_u64(),
            tc: w.tc.val().to_u64(),
            td: w.td.val().to_u64(),
            n_busy: w.n_busy.val(),
            n_live: w.n_live.val(),
            n_pre: w.n_pre.val(),
            n_fresh: w.n_fresh.val(),
            fin_end: w.fin_end.val(),
            fin_unconf: w.fin_unconf.val(),
            word,
        }
    }
}
