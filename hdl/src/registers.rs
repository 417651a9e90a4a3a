//! The device register map of the XEM6310 gateware ([`crate::xem6310`]):
//! the host↔gateware contract [`smartagg_model::registers`], which the host
//! uses too, so the two sides cannot drift apart (its module docs hold the
//! table of wire-ins, wire-outs, triggers and pipes).
//!
//! **Pipes are block-throttled** (FrontPanel `okBTPipeIn`/`okBTPipeOut`,
//! host calls `WriteToBlockPipeIn`/`ReadFromBlockPipeOut` with blocks of
//! [`PIPE_BLOCK_BYTES`]): the replay consumes P bits per clock, slower than
//! USB 3.0 delivers, so a pipe without flow control would overflow; the
//! pipe-out offers a block when [`PIPE_BLOCK_BYTES`] are ready, and at
//! stream end pads the last block with zero bytes that `FIFO_BYTES` never
//! counts (the host keeps only `FIFO_BYTES` bytes).

pub use smartagg_model::registers::{
    control, pipe, status, trigger, version_word, wire_in, wire_out, PIPE_BLOCK_BYTES,
    REGISTER_MAP_VERSION,
};

/// Wire-out `KERNEL_CRC` of the generated kernel: CRC-32C of the weights,
/// each as u16 little-endian (weights are at most 2^a ≤ 2^15).
pub fn kernel_crc(kernel: &[u32]) -> u32 {
    smartagg_model::registers::kernel_crc(kernel.iter().map(|&w| w as u16))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernel_word_is_the_hosts() {
        assert_eq!(version_word(), 0x0303);
        let k = [2u32, 10, 29, 54, 66, 54, 29, 10, 2];
        assert_eq!(
            kernel_crc(&k),
            smartagg_model::registers::kernel_crc(k.iter().map(|&w| w as u16))
        );
        assert_ne!(kernel_crc(&[1, 2, 1]), kernel_crc(&[1, 2, 2]));
    }
}
