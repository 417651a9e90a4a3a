//! The on/off step at the end of a row (combinational; bit i: slot i): for
//! each slot active at the end of plane t − 1 (`active_before`), busy,
//! live, and whose 3×3 window has streamed with this row (`row_end`), the
//! model's rule (`model/PACKETS.md` §8) on whether the window is on:
//! * on after a dip: the dip is bridged (`bridge`: the dip ends, the
//!   bridge is counted);
//! * off, not in a dip: the first plane below (`dip_starts`);
//! * off in a dip: the second plane below, the blink ended at t − 1
//!   (`ends`: the slot is no longer live, its dip ends, and the walk
//!   settles its drop, `pend`).
//!
//! Nothing when not `enable`d (the decide stage has not reached the end of
//! a row), and nothing for slots past M. The three sets are disjoint.

use crate::config::MAX_SLOTS;
use rust_hdl::prelude::*;

/// The on/off step of every slot whose window ends with a row.
#[derive(LogicBlock)]
pub struct OnOffStep {
    /// The end of a row is decided.
    pub enable: Signal<In, Bit>,
    /// Slots active at the end of plane t − 1.
    pub active_before: Signal<In, Bits<MAX_SLOTS>>,
    /// Busy slots.
    pub busy: Signal<In, Bits<MAX_SLOTS>>,
    /// Live slots (the blink has not ended).
    pub live: Signal<In, Bits<MAX_SLOTS>>,
    /// Slots one plane below (in a dip).
    pub dip: Signal<In, Bits<MAX_SLOTS>>,
    /// Slots whose 3×3 window has streamed with this row.
    pub row_end: Signal<In, Bits<MAX_SLOTS>>,
    /// Slots whose 3×3 window has an above bit in this plane.
    pub on: Signal<In, Bits<MAX_SLOTS>>,
    /// On after a dip: the dip is bridged.
    pub bridge: Signal<Out, Bits<MAX_SLOTS>>,
    /// Off, not in a dip: a dip starts.
    pub dip_starts: Signal<Out, Bits<MAX_SLOTS>>,
    /// Off in a dip: the blink ended at t − 1.
    pub ends: Signal<Out, Bits<MAX_SLOTS>>,
    stepped: Signal<Local, Bits<MAX_SLOTS>>,
    slots: Constant<Bits<MAX_SLOTS>>,
}

impl OnOffStep {
    /// The step of `m` slots (at most [`MAX_SLOTS`]).
    pub fn new(m: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        OnOffStep {
            enable: Default::default(),
            active_before: Default::default(),
            busy: Default::default(),
            live: Default::default(),
            dip: Default::default(),
            row_end: Default::default(),
            on: Default::default(),
            bridge: Default::default(),
            dip_starts: Default::default(),
            ends: Default::default(),
            stepped: Default::default(),
            slots: Constant::new((u64::MAX >> (64 - m)).to_bits()),
        }
    }
}

impl Logic for OnOffStep {
    #[hdl_gen]
    fn update(&mut self) {
        self.stepped.next = 0.into();
        if self.enable.val() {
            self.stepped.next = self.active_before.val()
                & self.busy.val()
                & self.live.val()
                & self.row_end.val()
                & self.slots.val();
        }
        self.bridge.next = self.stepped.val() & self.on.val() & self.dip.val();
        self.dip_starts.next = self.stepped.val() & !self.on.val() & !self.dip.val();
        self.ends.next = self.stepped.val() & !self.on.val() & self.dip.val();
    }
}
