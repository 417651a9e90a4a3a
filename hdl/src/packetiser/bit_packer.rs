//! Pass 3's bit packer: codes go in MSB first, bytes come out. `pk` holds
//! the bits not yet sent in its low `nb` bits (< 8 + 64: a code of up to
//! 64 bits is appended only when fewer than 8 wait). A byte is sent while
//! `nb ≥ 8`; after the last code the remaining `nb < 8` bits leave as one
//! zero-padded byte.
//!
//! The byte's shift reads a register: `nb − 8` (mod 256) is kept beside
//! `nb`. Only the low `nb < 8` bits of `pk` survive an append or the pad
//! (older bits have left as bytes), so neither shifts more than 72 bits.
//!
//! The owner decides, a clock at a time, which one command applies:
//! `start` (empty the packer), `send` (a byte out: only when `full`),
//! `append` (a code in: only when not `full`), `pad` (the last bits out as
//! a byte, empty again).

use rust_hdl::prelude::*;

/// The bit packer.
#[derive(LogicBlock)]
pub struct BitPacker {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Empty the packer.
    pub start: Signal<In, Bit>,
    /// Send the byte `next_byte` (`full` must be high).
    pub send: Signal<In, Bit>,
    /// Append `code` of `len` bits (`full` must be low).
    pub append: Signal<In, Bit>,
    /// The code, right aligned.
    pub code: Signal<In, Bits<64>>,
    /// Its length (1 ..= 64).
    pub len: Signal<In, Bits<8>>,
    /// Send the last bits as a zero-padded byte and empty the packer.
    pub pad: Signal<In, Bit>,
    /// At least 8 bits wait: `next_byte` is a whole byte.
    pub full: Signal<Out, Bit>,
    /// No bits wait.
    pub empty: Signal<Out, Bit>,
    /// The next 8 bits if `full`, else the waiting bits padded with zeros.
    pub next_byte: Signal<Out, Bits<8>>,
    pk: DFF<Bits<72>>,
    nb: DFF<Bits<8>>,
    /// `nb − 8` (mod 256).
    nb8: DFF<Bits<8>>,
    shifted: Signal<Local, Bits<72>>,
    low: Signal<Local, Bits<72>>,
    pad_shift: Signal<Local, Bits<72>>,
    /// `next_byte`, computed here and assigned once (see [`super`]:
    /// outputs without transients).
    byte_sel: Signal<Local, Bits<8>>,
    low_byte: Constant<Bits<72>>,
}

impl Default for BitPacker {
    fn default() -> Self {
        BitPacker {
            clock: Default::default(),
            start: Default::default(),
            send: Default::default(),
            append: Default::default(),
            code: Default::default(),
            len: Default::default(),
            pad: Default::default(),
            full: Default::default(),
            empty: Default::default(),
            next_byte: Default::default(),
            pk: Default::default(),
            nb: Default::default(),
            nb8: Default::default(),
            shifted: Default::default(),
            low: Default::default(),
            pad_shift: Default::default(),
            byte_sel: Default::default(),
            low_byte: Constant::new(0xFFu64.to_bits()),
        }
    }
}

impl Logic for BitPacker {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, pk, nb, nb8);
        self.full.next = self.nb.q.val() >= 8;
        self.empty.next = self.nb.q.val() == 0;
        // (Verilog cannot slice an expression: shift into a signal first.)
        // Read only when nb ≥ 8, when nb − 8 ≤ 63: the mask changes no
        // byte sent.
        self.shifted.next = self.pk.q.val() >> (self.nb8.q.val() & 63);
        self.low.next = self.pk.q.val() & self.low_byte.val();
        // The nb bits to the top of the byte: `<< (8 − nb)` as `<< 8 >> nb`
        // (no subtraction before the shifter; nb < 8 when padding).
        self.pad_shift.next = (self.low.val() << 8) >> (self.nb.q.val() & 7);
        self.byte_sel.next = self.pad_shift.val().get_bits::<8>(0);
        if self.full.val() {
            self.byte_sel.next = self.shifted.val().get_bits::<8>(0);
        }
        self.next_byte.next = self.byte_sel.val();
        if self.send.val() {
            self.nb.d.next = self.nb.q.val() - 8;
            self.nb8.d.next = self.nb8.q.val() - 8;
        }
        if self.append.val() {
            self.pk.d.next =
                (self.low.val() << self.len.val()) | bit_cast::<72, 64>(self.code.val());
            self.nb.d.next = self.nb.q.val() + self.len.val();
            self.nb8.d.next = self.nb8.q.val() + self.len.val();
        }
        if self.start.val() | self.pad.val() {
            self.nb.d.next = 0.into();
            self.nb8.d.next = 0xF8.into();
        }
    }
}
