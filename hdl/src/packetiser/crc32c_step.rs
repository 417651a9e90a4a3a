//! One byte of CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), the
//! packet's checksum ([`smartagg_model::packet::crc32c`]), in the table-free
//! form: the reflected byte table T is linear in its index, so
//! `crc' = (crc >> 8) ^ ⊕ᵢ vᵢ·T(2ⁱ)` with `v = (crc ^ byte) & 0xFF` — eight
//! 32-bit constants and an XOR tree, no 256-entry table (combinational).

use rust_hdl::prelude::*;

/// The reflected CRC-32C table's entries of the single-bit bytes 2⁰ … 2⁷.
fn crc32c_bit_entries() -> [u32; 8] {
    let mut t = [0u32; 8];
    for (i, e) in t.iter_mut().enumerate() {
        let mut c = 1u32 << i;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0x82F6_3B78
            } else {
                c >> 1
            };
        }
        *e = c;
    }
    t
}

/// The CRC register after one more byte.
#[derive(LogicBlock)]
pub struct Crc32cStep {
    /// The CRC register (before the final inversion).
    pub crc: Signal<In, Bits<32>>,
    /// The byte.
    pub data: Signal<In, Bits<8>>,
    /// The CRC register with the byte added.
    pub updated: Signal<Out, Bits<32>>,
    v: Signal<Local, Bits<8>>,
    ct: Vec<Signal<Local, Bits<32>>>,
    entries: Vec<Constant<Bits<32>>>,
}

impl Default for Crc32cStep {
    fn default() -> Self {
        Crc32cStep {
            crc: Default::default(),
            data: Default::default(),
            updated: Default::default(),
            v: Default::default(),
            ct: (0..8).map(|_| Default::default()).collect(),
            entries: crc32c_bit_entries()
                .iter()
                .map(|&e| Constant::new((e as u64).to_bits()))
                .collect(),
        }
    }
}

impl Logic for Crc32cStep {
    #[hdl_gen]
    fn update(&mut self) {
        self.v.next = self.crc.val().get_bits::<8>(0) ^ self.data.val();
        for i in 0..8 {
            self.ct[i].next = 0.into();
            if self.v.val().get_bit(i) {
                self.ct[i].next = self.entries[i].val();
            }
        }
        self.updated.next = (self.crc.val() >> 8)
            ^ self.ct[0].val()
            ^ self.ct[1].val()
            ^ self.ct[2].val()
            ^ self.ct[3].val()
            ^ self.ct[4].val()
            ^ self.ct[5].val()
            ^ self.ct[6].val()
            ^ self.ct[7].val();
    }
}
