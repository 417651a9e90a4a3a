//! Pass 3 of a Blink's count block, the last step of a code: from the
//! offset `d` and its quotient `q = d >> k`, the code (MSB first, right
//! aligned) and its length, as [`smartagg_model::rice::encode_counts`]
//! writes them: `q` ones, a zero, the k low bits of d (`q + 1 + k` bits);
//! or, when `q ≥ 32`, an escape: 32 ones and d in 32 bits (64 bits).
//!
//! The regular code's bits k + 1 … len − 1 are set: the difference of two
//! thermometers, no shift of the offset. The masks of k (bits k + 1 up,
//! the k low bits) and k + 1 are registers of `k`, a clock behind it: k
//! last changes in Choose, and the codes are made only in Codes (Decide
//! and Emit lie between), so no path here is deeper than one thermometer.

use rust_hdl::prelude::*;

/// A Rice code from an offset and its quotient. `RCW`: count bits (≤ 32).
#[derive(LogicBlock)]
pub struct RiceCode<const RCW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// The Rice parameter (< 32).
    pub k: Signal<In, Bits<8>>,
    /// `offset >> k` (of the k of a clock ago or earlier).
    pub quotient: Signal<In, Bits<32>>,
    /// The offset.
    pub offset: Signal<In, Bits<RCW>>,
    /// The code, right aligned.
    pub code: Signal<Out, Bits<64>>,
    /// Its length in bits (1 ..= 64).
    pub len: Signal<Out, Bits<8>>,
    /// k + 1.
    k1: DFF<Bits<8>>,
    /// Bits k + 1 and up.
    k_hi: DFF<Bits<64>>,
    /// The k low bits.
    k_lo: DFF<Bits<64>>,
    d64: Signal<Local, Bits<64>>,
    escape: Signal<Local, Bit>,
    /// `code` and `len`, computed here and assigned once (see [`super`]:
    /// outputs without transients).
    code_v: Signal<Local, Bits<64>>,
    len_v: Signal<Local, Bits<8>>,
    all64: Constant<Bits<64>>,
}

impl<const RCW: usize> Default for RiceCode<RCW> {
    fn default() -> Self {
        RiceCode {
            clock: Default::default(),
            k: Default::default(),
            quotient: Default::default(),
            offset: Default::default(),
            code: Default::default(),
            len: Default::default(),
            k1: Default::default(),
            k_hi: Default::default(),
            k_lo: Default::default(),
            d64: Default::default(),
            escape: Default::default(),
            code_v: Default::default(),
            len_v: Default::default(),
            all64: Constant::new(u64::MAX.to_bits()),
        }
    }
}

impl<const RCW: usize> Logic for RiceCode<RCW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, k1, k_hi, k_lo);
        self.k1.d.next = self.k.val() + 1;
        self.k_hi.d.next = self.all64.val() << (self.k.val() + 1);
        self.k_lo.d.next = !(self.all64.val() << self.k.val());
        self.d64.next = bit_cast::<64, RCW>(self.offset.val());
        self.escape.next = (self.quotient.val() >> 5).any();
        // (The mask changes no length: q < 32 unless escaped, when the
        // length is replaced; it tells synthesis how narrow the adder is.)
        self.len_v.next = bit_cast::<8, 32>(self.quotient.val() & 31) + self.k1.q.val();
        self.code_v.next = (!(self.all64.val() << self.len_v.val()) & self.k_hi.q.val())
            | (self.d64.val() & self.k_lo.q.val());
        if self.escape.val() {
            self.code_v.next = (bit_cast::<64, 32>(0xFFFF_FFFF_u64.into()) << 32) | self.d64.val();
            self.len_v.next = 64.into();
        }
        self.code.next = self.code_v.val();
        self.len.next = self.len_v.val();
    }
}
