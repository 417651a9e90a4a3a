//! S1 of the sweep: the R columns of an ROI row, `ax − h … ax + h`, cut
//! from the two ring words that hold them (combinational). The ring keeps
//! even and odd words in separate banks, read in one clock; the left word
//! (`wq − 1`) is the even one when `wq` is odd. A word off the sensor reads
//! 0. Bit j of the result is bit `off + j` of the pair (left word low),
//! for the delayed bits and the mask bits alike.

use rust_hdl::prelude::*;

/// An ROI row's bits from two ring words. `P`: pixels per word.
#[derive(LogicBlock, Default)]
pub struct RoiRow<const P: usize> {
    /// The even bank's word: delayed bits.
    pub even_delayed: Signal<In, Bits<P>>,
    /// The even bank's word: mask bits.
    pub even_mask: Signal<In, Bits<P>>,
    /// The odd bank's word: delayed bits.
    pub odd_delayed: Signal<In, Bits<P>>,
    /// The odd bank's word: mask bits.
    pub odd_mask: Signal<In, Bits<P>>,
    /// `wq` is odd: the left word is the even bank's.
    pub wq_odd: Signal<In, Bit>,
    /// The left word is on the sensor (`wq ≠ 0`).
    pub lo_ok: Signal<In, Bit>,
    /// The right word is on the sensor (`wq` < words per row).
    pub hi_ok: Signal<In, Bit>,
    /// The ROI row's first column within the left word.
    pub off: Signal<In, Bits<16>>,
    /// `P − off` (registered beside it by the aggregator, so that the
    /// shifts start from registers).
    pub sh_hi: Signal<In, Bits<16>>,
    /// The row's delayed bits (bit j: column `ax − h + j`).
    pub delayed: Signal<Out, Bits<P>>,
    /// The row's mask bits.
    pub mask: Signal<Out, Bits<P>>,
    lo_d: Signal<Local, Bits<P>>,
    lo_m: Signal<Local, Bits<P>>,
    hi_d: Signal<Local, Bits<P>>,
    hi_m: Signal<Local, Bits<P>>,
}

impl<const P: usize> Logic for RoiRow<P> {
    #[hdl_gen]
    fn update(&mut self) {
        self.lo_d.next = 0.into();
        self.lo_m.next = 0.into();
        self.hi_d.next = 0.into();
        self.hi_m.next = 0.into();
        if self.lo_ok.val() {
            if self.wq_odd.val() {
                self.lo_d.next = self.even_delayed.val();
                self.lo_m.next = self.even_mask.val();
            } else {
                self.lo_d.next = self.odd_delayed.val();
                self.lo_m.next = self.odd_mask.val();
            }
        }
        if self.hi_ok.val() {
            if self.wq_odd.val() {
                self.hi_d.next = self.odd_delayed.val();
                self.hi_m.next = self.odd_mask.val();
            } else {
                self.hi_d.next = self.even_delayed.val();
                self.hi_m.next = self.even_mask.val();
            }
        }
        self.delayed.next =
            (self.lo_d.val() >> self.off.val()) | (self.hi_d.val() << self.sh_hi.val());
        self.mask.next =
            (self.lo_m.val() >> self.off.val()) | (self.hi_m.val() << self.sh_hi.val());
    }
}
