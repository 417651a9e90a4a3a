//! The packet's CRC-32C (`model/PACKETS.md` §1): the register starts at
//! all ones with the packet (`start`), takes each byte the packet sends
//! (`add`, one [`super::Crc32cStep`] a clock), then goes out inverted, least
//! significant byte first, a byte a clock (`tail`). `start` wins over `add`
//! and `tail`.

use super::Crc32cStep;
use rust_hdl::prelude::*;

/// The CRC register and its four bytes.
#[derive(LogicBlock, Default)]
pub struct PacketCrc {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// A packet starts: the register is all ones, the tail at its first byte.
    pub start: Signal<In, Bit>,
    /// `data` is a byte of the packet: add it.
    pub add: Signal<In, Bit>,
    /// The byte.
    pub data: Signal<In, Bits<8>>,
    /// `tail_byte` goes out this clock: the next one follows.
    pub tail: Signal<In, Bit>,
    /// The CRC's byte of this clock (inverted register, LSB first).
    pub tail_byte: Signal<Out, Bits<8>>,
    /// It is the fourth.
    pub tail_last: Signal<Out, Bit>,
    step: Crc32cStep,
    crc: DFF<Bits<32>>,
    /// The tail's byte (0–3).
    tail_i: DFF<Bits<2>>,
    shifted: Signal<Local, Bits<32>>,
}

impl Logic for PacketCrc {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, crc, tail_i);
        self.step.crc.next = self.crc.q.val();
        self.step.data.next = self.data.val();
        if self.add.val() {
            self.crc.d.next = self.step.updated.val();
        }
        if self.tail.val() {
            self.tail_i.d.next = self.tail_i.q.val() + 1;
        }
        if self.start.val() {
            self.crc.d.next = 0xFFFF_FFFF_u64.into();
            self.tail_i.d.next = 0.into();
        }
        self.shifted.next = !(self.crc.q.val() >> (bit_cast::<32, 2>(self.tail_i.q.val()) << 3));
        self.tail_byte.next = self.shifted.val().get_bits::<8>(0);
        self.tail_last.next = self.tail_i.q.val() == 3;
    }
}
