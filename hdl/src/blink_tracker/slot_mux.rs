//! The multiplexer of the walk's read stage
//! ([`WalkPipeline`](super::WalkPipeline)): one slot's state
//! (combinational) — its flags, anchor and counter bank, and the slot
//! one-hot, which W2 uses to write it back. The fields only the walks read
//! come from [`WalkMemory`](super::WalkMemory) instead.
//!
//! The flags are read as AND-OR of the one-hot and each flag word, so that
//! every bit of the words is read (with M < 32 slots, a bit-by-bit
//! multiplexer leaves the words' top bits unread, which Verilator's lint
//! flags). A slot index past M, or a read stage that is off (`enable`
//! low), gives 0 everywhere.

use super::layout::COORD_BITS;
use crate::config::MAX_SLOTS;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// Slot `slot`'s state out of all M. `BW`: bits of a counter bank.
#[derive(LogicBlock)]
pub struct SlotMux<const BW: usize> {
    /// The slot to read.
    pub slot: Signal<In, Bits<8>>,
    /// Read (else every output is 0).
    pub enable: Signal<In, Bit>,
    /// The busy flags (bit i: slot i).
    pub busy: Signal<In, Bits<MAX_SLOTS>>,
    /// The live flags.
    pub live: Signal<In, Bits<MAX_SLOTS>>,
    /// The dip flags.
    pub dip: Signal<In, Bits<MAX_SLOTS>>,
    /// The drops the walk has yet to settle (`pend`).
    pub pend: Signal<In, Bits<MAX_SLOTS>>,
    /// The slots opened in this plane.
    pub opened: Signal<In, Bits<MAX_SLOTS>>,
    /// The bridges of this plane.
    pub bridges: Signal<In, Bits<MAX_SLOTS>>,
    /// Each slot's anchor column.
    pub anchor_cols: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// Each slot's anchor row.
    pub anchor_rows: Vec<Signal<In, Bits<COORD_BITS>>>,
    /// Each slot's counter bank.
    pub banks: Vec<Signal<In, Bits<BW>>>,
    /// The slot, one-hot.
    pub selected: Signal<Out, Bits<MAX_SLOTS>>,
    /// Its busy flag.
    pub s_busy: Signal<Out, Bit>,
    /// Its live flag.
    pub s_live: Signal<Out, Bit>,
    /// Its dip flag.
    pub s_dip: Signal<Out, Bit>,
    /// Its `pend` flag.
    pub s_pend: Signal<Out, Bit>,
    /// Opened in this plane.
    pub s_opened: Signal<Out, Bit>,
    /// Bridged in this plane.
    pub s_bridge: Signal<Out, Bit>,
    /// Its anchor column.
    pub s_ax: Signal<Out, Bits<COORD_BITS>>,
    /// Its anchor row.
    pub s_ay: Signal<Out, Bits<COORD_BITS>>,
    /// Its counter bank.
    pub s_bank: Signal<Out, Bits<BW>>,
    sel_v: Signal<Local, Bits<MAX_SLOTS>>,
    busy_v: Signal<Local, Bit>,
    live_v: Signal<Local, Bit>,
    dip_v: Signal<Local, Bit>,
    pend_v: Signal<Local, Bit>,
    opened_v: Signal<Local, Bit>,
    bridge_v: Signal<Local, Bit>,
    ax_v: Signal<Local, Bits<COORD_BITS>>,
    ay_v: Signal<Local, Bits<COORD_BITS>>,
    bank_v: Signal<Local, Bits<BW>>,
    slot_id: Vec<Constant<Bits<8>>>,
    _m: usize,
}

impl<const BW: usize> SlotMux<BW> {
    /// The multiplexer of `m` slots (at most [`MAX_SLOTS`]).
    pub fn new(m: usize) -> Self {
        assert!((1..=MAX_SLOTS).contains(&m), "{m} slots");
        SlotMux {
            slot: Default::default(),
            enable: Default::default(),
            busy: Default::default(),
            live: Default::default(),
            dip: Default::default(),
            pend: Default::default(),
            opened: Default::default(),
            bridges: Default::default(),
            anchor_cols: lanes(m),
            anchor_rows: lanes(m),
            banks: lanes(m),
            selected: Default::default(),
            s_busy: Default::default(),
            s_live: Default::default(),
            s_dip: Default::default(),
            s_pend: Default::default(),
            s_opened: Default::default(),
            s_bridge: Default::default(),
            s_ax: Default::default(),
            s_ay: Default::default(),
            s_bank: Default::default(),
            sel_v: Default::default(),
            busy_v: Default::default(),
            live_v: Default::default(),
            dip_v: Default::default(),
            pend_v: Default::default(),
            opened_v: Default::default(),
            bridge_v: Default::default(),
            ax_v: Default::default(),
            ay_v: Default::default(),
            bank_v: Default::default(),
            slot_id: (0..m)
                .map(|i| Constant::new((i as u64).to_bits()))
                .collect(),
            _m: m,
        }
    }
}

impl<const BW: usize> Logic for SlotMux<BW> {
    #[hdl_gen]
    fn update(&mut self) {
        self.sel_v.next = 0.into();
        self.ax_v.next = 0.into();
        self.ay_v.next = 0.into();
        self.bank_v.next = 0.into();
        if self.enable.val() {
            for i in 0..self._m {
                if self.slot.val() == self.slot_id[i].val() {
                    self.sel_v.next = self.sel_v.val().replace_bit(i, true);
                    self.ax_v.next = self.anchor_cols[i].val();
                    self.ay_v.next = self.anchor_rows[i].val();
                    self.bank_v.next = self.banks[i].val();
                }
            }
        }
        self.busy_v.next = (self.busy.val() & self.sel_v.val()).any();
        self.live_v.next = (self.live.val() & self.sel_v.val()).any();
        self.dip_v.next = (self.dip.val() & self.sel_v.val()).any();
        self.pend_v.next = (self.pend.val() & self.sel_v.val()).any();
        self.opened_v.next = (self.opened.val() & self.sel_v.val()).any();
        self.bridge_v.next = (self.bridges.val() & self.sel_v.val()).any();
        self.selected.next = self.sel_v.val();
        self.s_busy.next = self.busy_v.val();
        self.s_live.next = self.live_v.val();
        self.s_dip.next = self.dip_v.val();
        self.s_pend.next = self.pend_v.val();
        self.s_opened.next = self.opened_v.val();
        self.s_bridge.next = self.bridge_v.val();
        self.s_ax.next = self.ax_v.val();
        self.s_ay.next = self.ay_v.val();
        self.s_bank.next = self.bank_v.val();
    }
}
