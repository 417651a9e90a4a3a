//! The device register map of the XEM6310 gateware ([`crate::xem6310`]).
//!
//! The host's table (`host/src/transport/registers.rs`, on branch
//! `transport`, not yet on main) is the contract; this module copies its
//! addresses and bit meanings so that the gateware can be built and tested
//! on its own. A change on either side is a change of
//! [`REGISTER_MAP_VERSION`].
//!
//! | endpoint | name | meaning |
//! |---|---|---|
//! | wire-in 0x00 | `CONTROL` | bit 0 `SOURCE_REPLAY` (planes from pipe-in 0x80, else the sensor port), bit 1 `MASK_ENABLE` |
//! | wire-in 0x01 | `N_WINDOW` | N (1 ..= `MAX_N`) |
//! | wire-in 0x02 | `THRESHOLD_INT` | T_int (≥ 1) |
//! | wire-in 0x03 | `L_MIN` | L_min (≥ 1) |
//! | wire-in 0x04 | `L_MAX` | L_max (max(L_min, N) ..= the generated L_max,max) |
//! | wire-in 0x05 | `PLANE_PERIOD_NS` | copied into StreamStart |
//! | wire-in 0x06 | `MASKED_PIXELS` | copied into StreamStart (0 without `MASK_ENABLE`) |
//! | wire-out 0x20 | `STATUS` | see [`status`] |
//! | wire-out 0x21 | `FIFO_BYTES` | packet bytes waiting in the output FIFO |
//! | wire-out 0x22 | `VERSION` | packet format version (7:0), register-map version (15:8) |
//! | wire-out 0x23 | `GEOMETRY` | width (15:0), height (31:16) |
//! | wire-out 0x24 | `GENERATION` | kernel length (7:0), kernel shift (15:8), ROI side (23:16), slots (31:24) |
//! | wire-out 0x25 | `KERNEL_CRC` | CRC-32C of the kernel weights, u16 little-endian each |
//! | wire-out 0x26 | `R_ASSOC` | association radius (7:0) |
//! | wire-out 0x27 | `MAX_N` | largest N the delay line holds |
//! | trigger-in 0x40 | bit 0 `RESET`, bit 1 `START`, bit 2 `STOP` | one pulse each |
//! | pipe-in 0x80 | replay | bit-planes, W·H bits each, raster order, pixel i in bit i of the little-endian stream |
//! | pipe-in 0x81 | mask | one plane of mask bits, same packing (1 = hot); load while stopped |
//! | pipe-out 0xA0 | stream | the packet bytes of `model/PACKETS.md`, byte k in bits 8k+7..8k of 32-bit word ⌊k/4⌋ |
//!
//! **Pipes are block-throttled** (FrontPanel `okBTPipeIn`/`okBTPipeOut`,
//! host calls `WriteToBlockPipeIn`/`ReadFromBlockPipeOut` with blocks of
//! [`PIPE_BLOCK_BYTES`]): the replay consumes P bits per clock, slower than
//! USB 3.0 delivers, so a pipe without flow control would overflow; the
//! pipe-out offers a block when [`PIPE_BLOCK_BYTES`] are ready, and at
//! stream end pads the last block with zero bytes that `FIFO_BYTES` never
//! counts (the host keeps only `FIFO_BYTES` bytes).

use smartagg_model::packet::{crc32c, VERSION as PACKET_VERSION};

/// Version of this register map (wire-out `VERSION` bits 15:8).
pub const REGISTER_MAP_VERSION: u8 = 1;

/// Block size of the pipes, bytes (FrontPanel USB 3.0 granule).
pub const PIPE_BLOCK_BYTES: usize = 16;

/// Wire-in addresses.
pub mod wire_in {
    /// `SOURCE_REPLAY` (bit 0), `MASK_ENABLE` (bit 1).
    pub const CONTROL: u8 = 0x00;
    /// N.
    pub const N_WINDOW: u8 = 0x01;
    /// T_int.
    pub const THRESHOLD_INT: u8 = 0x02;
    /// L_min.
    pub const L_MIN: u8 = 0x03;
    /// L_max.
    pub const L_MAX: u8 = 0x04;
    /// Plane period, ns.
    pub const PLANE_PERIOD_NS: u8 = 0x05;
    /// Masked pixels.
    pub const MASKED_PIXELS: u8 = 0x06;
    /// How many wire-ins there are (0x00 … 0x06).
    pub const COUNT: usize = 7;
}

/// Bits of wire-in `CONTROL`.
pub mod control {
    /// Bit-planes from pipe-in 0x80.
    pub const SOURCE_REPLAY: u32 = 1 << 0;
    /// Apply the hot-pixel mask.
    pub const MASK_ENABLE: u32 = 1 << 1;
}

/// Wire-out addresses.
pub mod wire_out {
    /// Status bits ([`super::status`]).
    pub const STATUS: u8 = 0x20;
    /// Bytes waiting in the output FIFO.
    pub const FIFO_BYTES: u8 = 0x21;
    /// Versions.
    pub const VERSION: u8 = 0x22;
    /// Width and height.
    pub const GEOMETRY: u8 = 0x23;
    /// Kernel length, shift, ROI side, slots.
    pub const GENERATION: u8 = 0x24;
    /// CRC-32C of the kernel.
    pub const KERNEL_CRC: u8 = 0x25;
    /// Association radius.
    pub const R_ASSOC: u8 = 0x26;
    /// Largest N.
    pub const MAX_N: u8 = 0x27;
    /// How many wire-outs there are (0x20 … 0x27).
    pub const COUNT: usize = 8;
}

/// Bits of wire-out `STATUS`. Bits 0–2 are the host's table; 3–7 are
/// gateware diagnostics the host may show.
pub mod status {
    /// A stream is running.
    pub const RUNNING: u32 = 1 << 0;
    /// StreamEnd is in the output FIFO (or already read).
    pub const ENDED: u32 = 1 << 1;
    /// Records were lost since START (sticky; Overflow records carry the counts).
    pub const OVERFLOWED: u32 = 1 << 2;
    /// START was refused: a register is out of range.
    pub const CONFIG_ERROR: u32 = 1 << 3;
    /// A buffer overflowed or the DDR2 delay line under-ran (the stream is not exact).
    pub const FAULT: u32 = 1 << 4;
    /// The DDR2 memory has calibrated (START waits for it).
    pub const MEM_READY: u32 = 1 << 5;
    /// The source's start-of-plane came inside a plane.
    pub const FRAMING_ERROR: u32 = 1 << 6;
    /// The sensor port's clock-crossing FIFO overflowed.
    pub const SENSOR_OVERFLOW: u32 = 1 << 7;
}

/// Trigger-in address and bits.
pub mod trigger {
    /// The control trigger.
    pub const CONTROL: u8 = 0x40;
    /// Reset (while stopped).
    pub const RESET: u8 = 0;
    /// Latch the wire-ins and start.
    pub const START: u8 = 1;
    /// Finish and stop.
    pub const STOP: u8 = 2;
}

/// Pipe addresses.
pub mod pipe {
    /// Bit-planes to replay.
    pub const REPLAY_IN: u8 = 0x80;
    /// Hot-pixel mask.
    pub const MASK_IN: u8 = 0x81;
    /// The packet stream.
    pub const STREAM_OUT: u8 = 0xA0;
}

/// Wire-out `VERSION`.
pub fn version_word() -> u32 {
    PACKET_VERSION as u32 | (REGISTER_MAP_VERSION as u32) << 8
}

/// Wire-out `KERNEL_CRC`: CRC-32C of the weights, each as u16 little-endian.
pub fn kernel_crc(kernel: &[u32]) -> u32 {
    let bytes: Vec<u8> = kernel
        .iter()
        .flat_map(|&w| (w as u16).to_le_bytes())
        .collect();
    crc32c(&bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_follow_the_table() {
        assert_eq!(version_word(), 0x0101);
        // CRC-32C check value of the format's definition.
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
        assert_ne!(kernel_crc(&[1, 2, 1]), kernel_crc(&[1, 2, 2]));
        assert_eq!(
            wire_out::MAX_N - wire_out::STATUS + 1,
            wire_out::COUNT as u8
        );
    }
}
