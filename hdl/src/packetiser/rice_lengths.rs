//! Pass 2 of a Blink's count block: the length of one offset's Rice code
//! for every parameter k the packetiser scans (0 ..= [`super::rice_candidates`]
//! − 1), less the 1 + k bits every code has (the length accumulators start
//! at R² (k + 1), so that each adds one term). With `q = d >> k` a code is
//! `q + 1 + k` bits, or 64 when `q ≥ 32` (an escape:
//! [`smartagg_model::rice::code_len`]); so the lane of k is `q`, or 63 − k.
//!
//! The escape test of every k reads one bit of the offset's suffix OR (bit
//! i: some bit ≥ i of the offset is set; q ≥ 32 is a bit ≥ k + 5), built as
//! a parallel prefix of log depth rather than one OR per k
//! (combinational).

use crate::stream::lanes;
use rust_hdl::prelude::*;

/// A code's bits less 1 + k, for every k scanned. `RCW`: count bits.
#[derive(LogicBlock)]
pub struct RiceLengths<const RCW: usize> {
    /// The offset `d = c − base`.
    pub offset: Signal<In, Bits<RCW>>,
    /// Lane k: the length of d's code with parameter k, less 1 + k.
    pub extra: Vec<Signal<Out, Bits<16>>>,
    d32: Signal<Local, Bits<32>>,
    /// Bit i: some bit ≥ i of the offset is set (64 bits: the escape test
    /// of k ≤ 31 reads bit k + 5).
    suffix: Signal<Local, Bits<64>>,
    q: Vec<Signal<Local, Bits<32>>>,
    len: Vec<Signal<Local, Bits<32>>>,
    kc: Vec<Constant<Bits<8>>>,
    /// 63 − k: an escaped code's 64 bits less its k + 1.
    k63c: Vec<Constant<Bits<32>>>,
    _kn: usize,
}

impl<const RCW: usize> RiceLengths<RCW> {
    /// Lanes for k = 0 .. `kn` (at most 32).
    pub fn new(kn: usize) -> Self {
        RiceLengths {
            offset: Default::default(),
            extra: lanes(kn),
            d32: Default::default(),
            suffix: Default::default(),
            q: lanes(kn),
            len: lanes(kn),
            kc: (0..kn)
                .map(|k| Constant::new((k as u64).to_bits()))
                .collect(),
            k63c: (0..kn)
                .map(|k| Constant::new((63 - k as u64).to_bits()))
                .collect(),
            _kn: kn,
        }
    }
}

impl<const RCW: usize> Logic for RiceLengths<RCW> {
    #[hdl_gen]
    fn update(&mut self) {
        self.d32.next = bit_cast::<32, RCW>(self.offset.val());
        self.suffix.next = bit_cast::<64, RCW>(self.offset.val());
        self.suffix.next = self.suffix.val() | (self.suffix.val() >> 1);
        self.suffix.next = self.suffix.val() | (self.suffix.val() >> 2);
        self.suffix.next = self.suffix.val() | (self.suffix.val() >> 4);
        self.suffix.next = self.suffix.val() | (self.suffix.val() >> 8);
        self.suffix.next = self.suffix.val() | (self.suffix.val() >> 16);
        for k in 0..self._kn {
            self.q[k].next = self.d32.val() >> self.kc[k].val();
            self.len[k].next = self.q[k].val();
            if self.suffix.val().get_bit(k + 5) {
                self.len[k].next = self.k63c[k].val();
            }
            self.extra[k].next = self.len[k].val().get_bits::<16>(0);
        }
    }
}
