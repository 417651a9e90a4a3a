//! Stage 3 — threshold: a pixel is *above* a level `T` when `H ≥ T`, as in
//! [`smartagg_model::threshold::above`]. P comparators against a runtime
//! threshold register (HW bits; see
//! [`crate::config::GatewareConfig::threshold_register`]). The candidate
//! finder ([`crate::candidates`]) uses two: one against the open level T_int
//! (candidates) and one against the hold level T_hold (the tracker's on/off
//! bits).

use crate::stream::lanes;
use rust_hdl::prelude::*;

/// P comparators `H ≥ T` (combinational).
#[derive(LogicBlock)]
pub struct Threshold<const HW: usize> {
    /// H of P pixels.
    pub filtered: Vec<Signal<In, Bits<HW>>>,
    /// The level T (T_int or T_hold).
    pub threshold: Signal<In, Bits<HW>>,
    /// `H ≥ T` per pixel.
    pub above: Vec<Signal<Out, Bit>>,
    _p: usize,
}

impl<const HW: usize> Threshold<HW> {
    /// Comparators for `p` pixels.
    pub fn new(p: usize) -> Self {
        Threshold {
            filtered: lanes(p),
            threshold: Default::default(),
            above: lanes(p),
            _p: p,
        }
    }
}

impl<const HW: usize> Logic for Threshold<HW> {
    #[hdl_gen]
    fn update(&mut self) {
        for i in 0..self._p {
            self.above[i].next = self.filtered[i].val() >= self.threshold.val();
        }
    }
}
