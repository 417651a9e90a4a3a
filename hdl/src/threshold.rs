//! Stage 3 — threshold: a pixel is *above* when `H ≥ T_int`, as in
//! [`smartagg_model::threshold::above`]. P comparators against the runtime
//! T_int register (HW bits; see [`crate::config::GatewareConfig::threshold_register`]).

use crate::stream::lanes;
use rust_hdl::prelude::*;

/// P comparators `H ≥ T_int` (combinational).
#[derive(LogicBlock)]
pub struct Threshold<const HW: usize> {
    /// H of P pixels.
    pub filtered: Vec<Signal<In, Bits<HW>>>,
    /// T_int.
    pub threshold: Signal<In, Bits<HW>>,
    /// `H ≥ T_int` per pixel.
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
