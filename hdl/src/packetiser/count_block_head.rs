//! The first bytes of a Blink's count block (`model/PACKETS.md`, "Count
//! block"): the base as an unsigned LEB128 varint (7 bits a byte, low
//! group first, bit 7 set on every byte but the last), then the Rice
//! parameter k. The varint's length is a register: it is read only from
//! Decide on, when the base has held still since pass 1 ended. Six byte
//! lanes, the varint's one to five bytes then k, the rest 0.

use crate::stream::lanes;
use rust_hdl::prelude::*;

/// Bytes of the head: a varint of at most 5 bytes, and k.
pub const HEAD_BYTES: usize = 6;

/// The count block's base and k as bytes. `RCW`: count bits (≤ 32).
#[derive(LogicBlock)]
pub struct CountBlockHead<const RCW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// The block's base (the ROI's smallest count).
    pub base: Signal<In, Bits<RCW>>,
    /// The Rice parameter.
    pub k: Signal<In, Bits<8>>,
    /// Bytes of the varint (1 ..= 5), of the base a clock ago.
    pub varint_len: Signal<Out, Bits<16>>,
    /// The varint, then k, then zeros.
    pub bytes: Vec<Signal<Out, Bits<8>>>,
    len: DFF<Bits<16>>,
    /// The base's 7-bit groups, low first.
    group: Vec<Signal<Local, Bits<8>>>,
    /// `bytes`, computed here and assigned once (see [`super`]: outputs
    /// without transients).
    b: Vec<Signal<Local, Bits<8>>>,
}

impl<const RCW: usize> Default for CountBlockHead<RCW> {
    fn default() -> Self {
        CountBlockHead {
            clock: Default::default(),
            base: Default::default(),
            k: Default::default(),
            varint_len: Default::default(),
            bytes: lanes(HEAD_BYTES),
            len: Default::default(),
            group: lanes(5),
            b: lanes(HEAD_BYTES),
        }
    }
}

impl<const RCW: usize> Logic for CountBlockHead<RCW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, len);
        self.len.d.next = 5.into();
        if (self.base.val() >> 28) == 0 {
            self.len.d.next = 4.into();
        }
        if (self.base.val() >> 21) == 0 {
            self.len.d.next = 3.into();
        }
        if (self.base.val() >> 14) == 0 {
            self.len.d.next = 2.into();
        }
        if (self.base.val() >> 7) == 0 {
            self.len.d.next = 1.into();
        }
        self.varint_len.next = self.len.q.val();
        self.group[0].next = bit_cast::<8, RCW>(self.base.val()) & 0x7F;
        self.group[1].next = bit_cast::<8, RCW>(self.base.val() >> 7) & 0x7F;
        self.group[2].next = bit_cast::<8, RCW>(self.base.val() >> 14) & 0x7F;
        self.group[3].next = bit_cast::<8, RCW>(self.base.val() >> 21) & 0x7F;
        self.group[4].next = bit_cast::<8, RCW>(self.base.val() >> 28) & 0x7F;
        self.b[0].next = self.group[0].val();
        if self.len.q.val() > 1 {
            self.b[0].next = self.group[0].val() | 0x80;
        }
        self.b[1].next = 0.into();
        if self.len.q.val() == 1 {
            self.b[1].next = self.k.val();
        }
        if self.len.q.val() == 2 {
            self.b[1].next = self.group[1].val();
        }
        if self.len.q.val() > 2 {
            self.b[1].next = self.group[1].val() | 0x80;
        }
        self.b[2].next = 0.into();
        if self.len.q.val() == 2 {
            self.b[2].next = self.k.val();
        }
        if self.len.q.val() == 3 {
            self.b[2].next = self.group[2].val();
        }
        if self.len.q.val() > 3 {
            self.b[2].next = self.group[2].val() | 0x80;
        }
        self.b[3].next = 0.into();
        if self.len.q.val() == 3 {
            self.b[3].next = self.k.val();
        }
        if self.len.q.val() == 4 {
            self.b[3].next = self.group[3].val();
        }
        if self.len.q.val() > 4 {
            self.b[3].next = self.group[3].val() | 0x80;
        }
        self.b[4].next = 0.into();
        if self.len.q.val() == 4 {
            self.b[4].next = self.k.val();
        }
        if self.len.q.val() == 5 {
            self.b[4].next = self.group[4].val();
        }
        self.b[5].next = 0.into();
        if self.len.q.val() == 5 {
            self.b[5].next = self.k.val();
        }
        for i in 0..6 {
            self.bytes[i].next = self.b[i].val();
        }
    }
}
