//! What an opening by the item stage's candidate writes into its slot
//! (combinational; the compare stage registers it with the item): the
//! association window `[c − r_assoc, c + r_assoc]` in x and y (clipped at
//! 0 below; the coordinates have room above), and the 3×3 window of the
//! new anchor: columns `[cx − 1, cx + 1]` clipped to the field, as lane
//! masks of the (at most two) words that hold them, and the row at whose
//! end the window has streamed (`min(cy + 1, H − 1)`).
//!
//! The words are laid out as the tracker keeps them: `geo` at
//! [`slot_word`]'s offsets (without the bank), `win` with the low word's
//! lanes at bit 0 and the high word's at bit 32, `sh` at [`shadow`]'s
//! (without the bank; `FRESH` set), `bnd` x from 0, x to 10, y from 20,
//! y to 30.

use super::layout::{shadow, slot_word, COORD_BITS};
use crate::config::BackHalfConfig;
use rust_hdl::prelude::*;

/// The slot words an opening writes. `P`: pixels per word.
#[derive(LogicBlock)]
pub struct OpeningWindows<const P: usize> {
    /// The candidate's column (pixels).
    pub cx: Signal<In, Bits<COORD_BITS>>,
    /// Its row.
    pub cy: Signal<In, Bits<COORD_BITS>>,
    /// Its row is the field's last.
    pub lastrow: Signal<In, Bit>,
    /// The slot's `geo` word without its bank: anchor, the window's word
    /// columns and last row.
    pub geo: Signal<Out, Bits<64>>,
    /// The window's two lane masks.
    pub win: Signal<Out, Bits<64>>,
    /// The slot's ROI view entry without its bank (anchor, `FRESH`).
    pub sh: Signal<Out, Bits<64>>,
    /// The association window.
    pub bnd: Signal<Out, Bits<64>>,
    cx_lo: Signal<Local, Bits<COORD_BITS>>,
    cx_hi: Signal<Local, Bits<COORD_BITS>>,
    cy_lo: Signal<Local, Bits<COORD_BITS>>,
    cy_hi: Signal<Local, Bits<COORD_BITS>>,
    lo_col: Signal<Local, Bits<COORD_BITS>>,
    hi_col: Signal<Local, Bits<COORD_BITS>>,
    o_wl: Signal<Local, Bits<COORD_BITS>>,
    o_wh: Signal<Local, Bits<COORD_BITS>>,
    lo_lane: Signal<Local, Bits<COORD_BITS>>,
    hi_lane: Signal<Local, Bits<COORD_BITS>>,
    m_lo: Signal<Local, Bits<P>>,
    m_hi: Signal<Local, Bits<P>>,
    o_ml: Signal<Local, Bits<P>>,
    o_mh: Signal<Local, Bits<P>>,
    o_frow: Signal<Local, Bits<COORD_BITS>>,
    sh_open: Constant<Bits<64>>,
    all_lanes: Constant<Bits<P>>,
    log2p: Constant<Bits<8>>,
    pm1: Constant<Bits<COORD_BITS>>,
    r_assoc: Constant<Bits<COORD_BITS>>,
    last_col: Constant<Bits<COORD_BITS>>,
}

impl<const P: usize> OpeningWindows<P> {
    /// The opening of a configuration (its field, P and `r_assoc`; the
    /// tracker has checked them).
    pub fn new(cfg: &BackHalfConfig) -> Self {
        let cc = |v: u64| Constant::new(v.to_bits());
        OpeningWindows {
            cx: Default::default(),
            cy: Default::default(),
            lastrow: Default::default(),
            geo: Default::default(),
            win: Default::default(),
            sh: Default::default(),
            bnd: Default::default(),
            cx_lo: Default::default(),
            cx_hi: Default::default(),
            cy_lo: Default::default(),
            cy_hi: Default::default(),
            lo_col: Default::default(),
            hi_col: Default::default(),
            o_wl: Default::default(),
            o_wh: Default::default(),
            lo_lane: Default::default(),
            hi_lane: Default::default(),
            m_lo: Default::default(),
            m_hi: Default::default(),
            o_ml: Default::default(),
            o_mh: Default::default(),
            o_frow: Default::default(),
            sh_open: Constant::new((1u64 << shadow::FRESH).to_bits()),
            all_lanes: Constant::new(Bits::<P>::mask()),
            log2p: Constant::new((cfg.log2_p() as u64).to_bits()),
            pm1: cc(P as u64 - 1),
            r_assoc: cc(cfg.r_assoc as u64),
            last_col: cc(cfg.front.width as u64 - 1),
        }
    }
}

// The offsets that `update` writes as literals (hdl_gen needs numbers).
const _: () = assert!(
    slot_word::AX == 0
        && slot_word::AY == 10
        && slot_word::WL == 34
        && slot_word::WH == 44
        && slot_word::FROW == 54
        && shadow::AX == 0
        && shadow::AY == 10
        && COORD_BITS == 10
);

impl<const P: usize> Logic for OpeningWindows<P> {
    #[hdl_gen]
    fn update(&mut self) {
        self.cx_lo.next = 0.into();
        if self.cx.val() >= self.r_assoc.val() {
            self.cx_lo.next = self.cx.val() - self.r_assoc.val();
        }
        self.cx_hi.next = self.cx.val() + self.r_assoc.val();
        self.cy_lo.next = 0.into();
        if self.cy.val() >= self.r_assoc.val() {
            self.cy_lo.next = self.cy.val() - self.r_assoc.val();
        }
        self.cy_hi.next = self.cy.val() + self.r_assoc.val();
        self.lo_col.next = 0.into();
        if self.cx.val() != 0 {
            self.lo_col.next = self.cx.val() - 1;
        }
        self.hi_col.next = self.cx.val() + 1;
        if self.cx.val() == self.last_col.val() {
            self.hi_col.next = self.cx.val();
        }
        self.o_wl.next = self.lo_col.val() >> self.log2p.val();
        self.o_wh.next = self.hi_col.val() >> self.log2p.val();
        self.lo_lane.next = self.lo_col.val() & self.pm1.val();
        self.hi_lane.next = self.hi_col.val() & self.pm1.val();
        self.m_lo.next = self.all_lanes.val() << self.lo_lane.val();
        self.m_hi.next = self.all_lanes.val() >> (self.pm1.val() - self.hi_lane.val());
        self.o_ml.next = self.m_lo.val();
        self.o_mh.next = self.m_hi.val();
        if self.o_wl.val() == self.o_wh.val() {
            self.o_ml.next = self.m_lo.val() & self.m_hi.val();
            self.o_mh.next = self.m_lo.val() & self.m_hi.val();
        }
        self.o_frow.next = self.cy.val() + 1;
        if self.lastrow.val() {
            self.o_frow.next = self.cy.val();
        }
        self.geo.next = bit_cast::<64, 10>(self.cx.val())
            | (bit_cast::<64, 10>(self.cy.val()) << 10)
            | (bit_cast::<64, 10>(self.o_wl.val()) << 34)
            | (bit_cast::<64, 10>(self.o_wh.val()) << 44)
            | (bit_cast::<64, 10>(self.o_frow.val()) << 54);
        self.win.next =
            bit_cast::<64, P>(self.o_ml.val()) | (bit_cast::<64, P>(self.o_mh.val()) << 32);
        self.sh.next = bit_cast::<64, 10>(self.cx.val())
            | (bit_cast::<64, 10>(self.cy.val()) << 10)
            | self.sh_open.val();
        self.bnd.next = bit_cast::<64, 10>(self.cx_lo.val())
            | (bit_cast::<64, 10>(self.cx_hi.val()) << 10)
            | (bit_cast::<64, 10>(self.cy_lo.val()) << 20)
            | (bit_cast::<64, 10>(self.cy_hi.val()) << 30);
    }
}
