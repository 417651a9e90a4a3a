//! The lengths of the head record's packet and the room check.
//!
//! By record kind (`model/PACKETS.md`): the payload length the header
//! carries, the bytes of the prefix the packetiser assembles (header and
//! fixed payload, with a Blink's count-block head) less one, and `need`,
//! the bytes the output FIFO must have free for the whole packet — the
//! header (10), the payload and the CRC (4), and the 22 bytes of an
//! Overflow packet first when records are pending.
//! * StreamStart: payload `start_len − 10` (its kernel's length fixes it),
//!   prefix `start_len`;
//! * Blink: payload `35 + varint + 1 + code bytes`, prefix `10 + 35 +
//!   varint + 1` (the codes are streamed after it);
//! * Dropped: payload 14, prefix 24;
//! * StreamEnd: payload 48, prefix 58.
//!
//! The room check is a register, so that Decide's adder and compare end
//! in a flip-flop: `room` is `fifo_free ≥ need` as of last clock, and
//! `ready` says that it was computed in Decide (Decide acts from its
//! second clock, when `room` speaks of this record's final lengths).

use rust_hdl::prelude::*;

/// The packet's lengths and the registered room check.
#[derive(LogicBlock)]
pub struct PacketLength {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// The record's kind ([`crate::blink_tracker::record_kind`]).
    pub kind: Signal<In, Bits<2>>,
    /// A Blink: bytes of its base's varint (1 ..= 5).
    pub varint_len: Signal<In, Bits<16>>,
    /// A Blink: bytes of its codes.
    pub code_bytes: Signal<In, Bits<16>>,
    /// Records are pending: an Overflow packet goes first.
    pub pending: Signal<In, Bit>,
    /// Free bytes in the output FIFO.
    pub fifo_free: Signal<In, Bits<16>>,
    /// The packetiser is in Decide.
    pub decide: Signal<In, Bit>,
    /// The payload length of the header.
    pub payload_len: Signal<Out, Bits<16>>,
    /// The record's prefix bytes less one.
    pub prefix_rest: Signal<Out, Bits<16>>,
    /// The output FIFO had room for the packet (and the Overflow packet
    /// first, if pending) last clock.
    pub room: Signal<Out, Bit>,
    /// `room` was computed in Decide: Decide's second clock on.
    pub ready: Signal<Out, Bit>,
    room_ok: DFF<Bit>,
    dec_ready: DFF<Bit>,
    payload: Signal<Local, Bits<16>>,
    rest: Signal<Local, Bits<16>>,
    need: Signal<Local, Bits<16>>,
    /// Bytes of the StreamStart packet but its CRC.
    start_len: Constant<Bits<16>>,
}

impl PacketLength {
    /// The lengths for a configuration whose StreamStart packet has
    /// `stream_start_bytes` bytes before its CRC
    /// ([`crate::config::BackHalfConfig::stream_start_bytes`]).
    pub fn new(stream_start_bytes: usize) -> Self {
        PacketLength {
            clock: Default::default(),
            kind: Default::default(),
            varint_len: Default::default(),
            code_bytes: Default::default(),
            pending: Default::default(),
            fifo_free: Default::default(),
            decide: Default::default(),
            payload_len: Default::default(),
            prefix_rest: Default::default(),
            room: Default::default(),
            ready: Default::default(),
            room_ok: Default::default(),
            dec_ready: Default::default(),
            payload: Default::default(),
            rest: Default::default(),
            need: Default::default(),
            start_len: Constant::new((stream_start_bytes as u64).to_bits()),
        }
    }
}

impl Logic for PacketLength {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, room_ok, dec_ready);
        self.payload.next = 37.into();
        self.rest.next = self.start_len.val() - 1;
        match self.kind.val().index() {
            1 => {
                self.payload.next = self.varint_len.val() + 36 + self.code_bytes.val();
                self.rest.next = self.varint_len.val() + 45;
            }
            2 => {
                self.payload.next = 14.into();
                self.rest.next = 23.into();
            }
            3 => {
                self.payload.next = 48.into();
                self.rest.next = 57.into();
            }
            _ => {
                self.payload.next = self.start_len.val() - 10;
            }
        }
        // Outputs are assigned once (see "Outputs without transients" in
        // the packetiser's module doc).
        self.payload_len.next = self.payload.val();
        self.prefix_rest.next = self.rest.val();
        self.need.next = self.payload.val() + 14;
        if self.pending.val() {
            self.need.next = self.payload.val() + 36;
        }
        self.room_ok.d.next = self.fifo_free.val() >= self.need.val();
        self.dec_ready.d.next = self.decide.val();
        self.room.next = self.room_ok.q.val();
        self.ready.next = self.dec_ready.q.val();
    }
}
