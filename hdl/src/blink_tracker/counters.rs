//! The tracker's counts (`model/PACKETS.md` §3.3–3.4):
//! * the StreamEnd totals, 64 bits each, one event a clock at most: Blink
//!   records emitted (lost ones included), tracks that ended unconfirmed,
//!   candidates dropped for want of a slot, single-plane dips bridged and
//!   segments cut at L_max;
//! * the plane's Dropped record: the candidates dropped in it (32 bits)
//!   and the position of the first, cleared by `plane_end` (the record is
//!   taken). The tracker never drops a candidate in the clock that ends a
//!   plane (a drop is decided in Run, the plane ends in WalkEnd); were
//!   they to come together, the drop would win and the count go on from
//!   the plane's;
//! * the bank error: sticky once a Blink has waited 16 clocks in a row for
//!   a free counter bank while the record queue had room (never expected:
//!   it means a bank went missing).
//!
//! `restart` zeroes the totals, the plane's count and the error (the run
//! of waits goes on counting: it starts over at the first clock without a
//! wait).

use super::layout::COORD_BITS;
use crate::bundles::TrackerTotalsOut;
use rust_hdl::prelude::*;

/// The tracker's event counters, the plane's drops and the bank error.
#[derive(LogicBlock, Default)]
pub struct TrackerCounters {
    /// The clock.
    pub clock: Signal<In, Clock>,
    /// Zero the totals, the plane's count and the error.
    pub restart: Signal<In, Bit>,
    /// A Blink record is emitted (pushed or lost).
    pub blink: Signal<In, Bit>,
    /// A track ends unconfirmed.
    pub unconfirmed_end: Signal<In, Bit>,
    /// A dip is bridged.
    pub bridge: Signal<In, Bit>,
    /// A segment is cut at L_max.
    pub cut: Signal<In, Bit>,
    /// A candidate is dropped.
    pub drop: Signal<In, Bit>,
    /// Its column.
    pub drop_x: Signal<In, Bits<COORD_BITS>>,
    /// Its row.
    pub drop_y: Signal<In, Bits<COORD_BITS>>,
    /// The plane's Dropped record is taken: its count starts over.
    pub plane_end: Signal<In, Bit>,
    /// A Blink waits for a free bank while the record queue has room.
    pub bank_wait: Signal<In, Bit>,
    /// The StreamEnd totals.
    pub totals: TrackerTotalsOut,
    /// Candidates dropped in this plane.
    pub plane_drops: Signal<Out, Bits<32>>,
    /// The column of the plane's first dropped candidate.
    pub first_x: Signal<Out, Bits<COORD_BITS>>,
    /// Its row.
    pub first_y: Signal<Out, Bits<COORD_BITS>>,
    /// A Blink waited 16 clocks or more for a bank (sticky).
    pub bank_error: Signal<Out, Bit>,
    c_blinks: DFF<Bits<64>>,
    c_unconf: DFF<Bits<64>>,
    c_dropped: DFF<Bits<64>>,
    c_bridged: DFF<Bits<64>>,
    c_cuts: DFF<Bits<64>>,
    drops: DFF<Bits<32>>,
    drop_x_r: DFF<Bits<COORD_BITS>>,
    drop_y_r: DFF<Bits<COORD_BITS>>,
    bank_err: DFF<Bit>,
    /// Consecutive clocks of waiting so far, modulo 16.
    bank_waits: DFF<Bits<4>>,
}

impl Logic for TrackerCounters {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, c_blinks, c_unconf, c_dropped, c_bridged, c_cuts, drops, drop_x_r,
            drop_y_r, bank_err, bank_waits
        );
        if self.blink.val() {
            self.c_blinks.d.next = self.c_blinks.q.val() + 1;
        }
        if self.unconfirmed_end.val() {
            self.c_unconf.d.next = self.c_unconf.q.val() + 1;
        }
        if self.bridge.val() {
            self.c_bridged.d.next = self.c_bridged.q.val() + 1;
        }
        if self.cut.val() {
            self.c_cuts.d.next = self.c_cuts.q.val() + 1;
        }
        if self.plane_end.val() {
            self.drops.d.next = 0.into();
        }
        if self.drop.val() {
            self.c_dropped.d.next = self.c_dropped.q.val() + 1;
            self.drops.d.next = self.drops.q.val() + 1;
            if self.drops.q.val() == 0 {
                self.drop_x_r.d.next = self.drop_x.val();
                self.drop_y_r.d.next = self.drop_y.val();
            }
        }
        // A wait longer than the pool's return latency means a bank was lost.
        self.bank_waits.d.next = 0.into();
        if self.bank_wait.val() {
            self.bank_waits.d.next = self.bank_waits.q.val() + 1;
            if self.bank_waits.q.val().all() {
                self.bank_err.d.next = true;
            }
        }
        if self.restart.val() {
            self.drops.d.next = 0.into();
            self.c_blinks.d.next = 0.into();
            self.c_unconf.d.next = 0.into();
            self.c_dropped.d.next = 0.into();
            self.c_bridged.d.next = 0.into();
            self.c_cuts.d.next = 0.into();
            self.bank_err.d.next = false;
        }
        self.totals.blinks.next = self.c_blinks.q.val();
        self.totals.unconfirmed.next = self.c_unconf.q.val();
        self.totals.dropped.next = self.c_dropped.q.val();
        self.totals.bridged.next = self.c_bridged.q.val();
        self.totals.cuts.next = self.c_cuts.q.val();
        self.plane_drops.next = self.drops.q.val();
        self.first_x.next = self.drop_x_r.q.val();
        self.first_y.next = self.drop_y_r.q.val();
        self.bank_error.next = self.bank_err.q.val();
    }
}
