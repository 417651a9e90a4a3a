//! Passes 2 and Choose of a Blink's count block: the Rice parameter k with
//! the fewest code bits ([`smartagg_model::rice::choose`]: the smallest k
//! on ties), from one length accumulator per k scanned.
//!
//! Pass 2 gives an offset a clock: stage L registers its code lengths for
//! every k ([`RiceLengths`], less the 1 + k of every code) before the
//! accumulators add them, so that the escape tests and the adders are not
//! in series (synthesis lets the logic on either side of a carry chain take
//! the whole depth). The accumulators start at R² (k + 1), 16 bits suffice
//! for R ≤ 31. Choose then scans one k a clock: the accumulators shift
//! down a lane a clock, so the total of the k scanned is always lane 0 (a
//! register, not a multiplexer by k).
//!
//! The owner's commands: `clear` (before pass 2), `offset_valid` with each
//! offset of pass 2, `start_scan` (after it), `step` (a clock of Choose; `last`
//! says the clock scans the last k).

use super::rice_lengths::RiceLengths;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// Rice parameters worth a length accumulator for counts of `rcw` bits:
/// 0 ..= `rcw` (at most the model's 0 ..= 31). An offset from the base is
/// below 2^rcw, so for every k ≥ rcw each code is 1 + k bits and the total
/// grows with k: k = rcw beats every larger k, and the model's choice
/// ([`smartagg_model::rice::choose`], smallest k on ties) is always in
/// 0 ..= rcw.
pub fn rice_candidates(rcw: usize) -> usize {
    (rcw + 1).min(smartagg_model::rice::MAX_K as usize + 1)
}

/// The length accumulators and the scan. `RCW`: count bits.
#[derive(LogicBlock)]
pub struct RiceChoice<const RCW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: no offset in stage L.
    pub restart: Signal<In, Bit>,
    /// Start the totals at R² (k + 1).
    pub clear: Signal<In, Bit>,
    /// An offset of pass 2.
    pub offset: Signal<In, Bits<RCW>>,
    /// `offset` is one (added two clocks later).
    pub offset_valid: Signal<In, Bit>,
    /// Start the scan.
    pub start_scan: Signal<In, Bit>,
    /// Scan the next k.
    pub step: Signal<In, Bit>,
    /// This clock scans the last k.
    pub last: Signal<Out, Bit>,
    /// The best k so far (the chosen one after the last step).
    pub k: Signal<Out, Bits<8>>,
    /// Bytes of the best k's codes, ⌈bits / 8⌉.
    pub code_bytes: Signal<Out, Bits<16>>,
    lengths: RiceLengths<RCW>,
    /// Stage L: an offset's lengths are in `lq`.
    lv: DFF<Bit>,
    lq: Vec<DFF<Bits<16>>>,
    acc: Vec<DFF<Bits<16>>>,
    best: DFF<Bits<16>>,
    best_bytes: DFF<Bits<16>>,
    bestk: DFF<Bits<8>>,
    scan: DFF<Bits<8>>,
    /// The total of the k scanned.
    acc_j: Signal<Local, Bits<16>>,
    /// R² (k + 1): the 1 + k bits of every code, where the totals start.
    acc0: Vec<Constant<Bits<16>>>,
    /// The largest k scanned.
    k_last: Constant<Bits<8>>,
    _kn: usize,
}

impl<const RCW: usize> RiceChoice<RCW> {
    /// Accumulators for k = 0 .. `kn` (1 ..= 32) and ROIs of side `r`.
    pub fn new(kn: usize, r: usize) -> Self {
        RiceChoice {
            clock: Default::default(),
            restart: Default::default(),
            clear: Default::default(),
            offset: Default::default(),
            offset_valid: Default::default(),
            start_scan: Default::default(),
            step: Default::default(),
            last: Default::default(),
            k: Default::default(),
            code_bytes: Default::default(),
            lengths: RiceLengths::new(kn),
            lv: Default::default(),
            lq: lanes(kn),
            acc: lanes(kn),
            best: Default::default(),
            best_bytes: Default::default(),
            bestk: Default::default(),
            scan: Default::default(),
            acc_j: Default::default(),
            acc0: (0..kn)
                .map(|k| Constant::new(((r * r * (k + 1)) as u64).to_bits()))
                .collect(),
            k_last: Constant::new((kn as u64 - 1).to_bits()),
            _kn: kn,
        }
    }
}

impl<const RCW: usize> Logic for RiceChoice<RCW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, lv, best, best_bytes, bestk, scan);
        for k in 0..self._kn {
            self.acc[k].clock.next = self.clock.val();
            self.acc[k].d.next = self.acc[k].q.val();
            self.lq[k].clock.next = self.clock.val();
            self.lq[k].d.next = self.lengths.extra[k].val();
        }
        self.lengths.offset.next = self.offset.val();
        self.lv.d.next = self.offset_valid.val();
        self.acc_j.next = self.acc[0].q.val();
        self.last.next = self.scan.q.val() == self.k_last.val();
        self.k.next = self.bestk.q.val();
        self.code_bytes.next = self.best_bytes.q.val();
        if self.clear.val() {
            for k in 0..self._kn {
                self.acc[k].d.next = self.acc0[k].val();
            }
        }
        if self.lv.q.val() {
            for k in 0..self._kn {
                self.acc[k].d.next = self.acc[k].q.val() + self.lq[k].q.val();
            }
        }
        if self.start_scan.val() {
            self.best.d.next = 0xFFFF.into();
            self.best_bytes.d.next = 0.into();
            self.bestk.d.next = 0.into();
            self.scan.d.next = 0.into();
        }
        if self.step.val() {
            for k in 0..(self._kn - 1) {
                self.acc[k].d.next = self.acc[k + 1].q.val();
            }
            if self.acc_j.val() < self.best.q.val() {
                self.best.d.next = self.acc_j.val();
                self.best_bytes.d.next = (self.acc_j.val() + 7) >> 3;
                self.bestk.d.next = self.scan.q.val();
            }
            self.scan.d.next = self.scan.q.val() + 1;
        }
        if self.restart.val() {
            self.lv.d.next = false;
        }
    }
}
