//! The device register map: the one place where the host (`host/`) and the
//! gateware (`hdl/`) agree on endpoint addresses and bit meanings. Both use
//! these constants; a change here is a change of [`REGISTER_MAP_VERSION`].
//!
//! The addresses follow FrontPanel's endpoint ranges (wire-in 0x00–0x1F,
//! wire-out 0x20–0x3F, trigger-in 0x40–0x5F, pipe-in 0x80–0x9F, pipe-out
//! 0xA0–0xBF), so the same numbers serve the FrontPanel transport and the
//! plain-USB firmware, which reaches them with vendor control requests
//! (the host's `vendor` requests). Every value is a 32-bit little-endian word.
//!
//! # Wire-ins (host → device; latched by START, ignored while streaming)
//!
//! | addr | name              | meaning                                                    |
//! |------|-------------------|------------------------------------------------------------|
//! | 0x00 | `CONTROL`         | bit 0 `SOURCE_REPLAY`: bit-planes come from pipe-in 0x80 instead of the sensor; bit 1 `MASK_ENABLE`: apply the hot-pixel mask loaded through pipe-in 0x81 |
//! | 0x01 | `N_WINDOW`        | rolling window N, bit-planes (1 ..= `MAX_N`)               |
//! | 0x02 | `THRESHOLD_INT`   | integer threshold T_int on H that opens a track (≥ 1)      |
//! | 0x03 | `L_MIN`           | planes a track must stay on to be confirmed (≥ 1)          |
//! | 0x04 | `L_MAX`           | planes after which an on track is cut (≥ max(L_min, N))    |
//! | 0x05 | `PLANE_PERIOD_NS` | bit-plane period, ns, copied into the StreamStart record   |
//! | 0x06 | `MASKED_PIXELS`   | number of masked pixels, copied into the StreamStart record (0 is sent there without `MASK_ENABLE`, whatever this register holds) |
//! | 0x07 | `THRESHOLD_HOLD`  | integer threshold T_hold that holds an open track on (1 ..= T_int) |
//! | 0x08 | `END_TRIM`        | planes between a dropped segment's last summed plane and its t_drop (0 ..= N − 1; PACKETS.md §8.6) |
//!
//! # Wire-outs (device → host)
//!
//! | addr | name         | meaning                                                          |
//! |------|--------------|------------------------------------------------------------------|
//! | 0x20 | `STATUS`     | bit 0 `RUNNING`; bit 1 `ENDED`: the StreamEnd record is in the output FIFO (or already read); bit 2 `OVERFLOWED`: the device lost records since START, its output FIFO or its record queue being full (sticky; Overflow records carry the counts); bits 3–7 gateware diagnostics, see [`status`] |
//! | 0x21 | `FIFO_BYTES` | bytes of the packet stream waiting in the output FIFO            |
//! | 0x22 | `VERSION`    | bits 7:0 packet format version ([`crate::packet::VERSION`]), bits 15:8 register-map version ([`REGISTER_MAP_VERSION`]) |
//! | 0x23 | `GEOMETRY`   | sensor width (bits 15:0) and height (bits 31:16), pixels         |
//! | 0x24 | `GENERATION` | kernel length (7:0), kernel shift a (15:8), ROI side R (23:16), slots M (31:24) |
//! | 0x25 | `KERNEL_CRC` | CRC-32C of the kernel weights as u16 little-endian ([`kernel_crc`]) |
//! | 0x26 | `R_ASSOC`    | association radius, pixels (7:0)                                 |
//! | 0x27 | `MAX_N`      | largest N the delay line holds (block RAM or DDR2 depth)         |
//!
//! The generation words (0x23–0x27) are constants of the generated gateware:
//! the kernel weights, R, M and r_assoc are compile-time constants (§7 of the
//! design), so the host checks them against the preset before streaming and
//! refuses a bitfile generated for another preset.
//!
//! # Trigger-in 0x40 (host → device, one pulse per bit)
//!
//! | bit | name    | meaning                                                              |
//! |-----|---------|----------------------------------------------------------------------|
//! | 0   | `RESET` | clear the pipeline, the FIFOs, the mask and the sequence numbers (only while stopped) |
//! | 1   | `START` | latch the wire-ins, emit StreamStart (sequence 0), start processing bit-planes |
//! | 2   | `STOP`  | finish as the model's `Pipeline::finish` does (truncate open tracks), emit StreamEnd, stop |
//!
//! # Pipes
//!
//! | addr | direction | content                                                          |
//! |------|-----------|------------------------------------------------------------------|
//! | 0x80 | in        | bit-planes to replay (with `SOURCE_REPLAY`): each plane W·H bits, raster order, packed least significant bit first, padded to whole bytes |
//! | 0x81 | in        | hot-pixel mask, same packing as one bit-plane (1 = masked); load after RESET, before START |
//! | 0xA0 | out       | the packet stream of `model/PACKETS.md`                          |
//!
//! # Reading the packet stream through FrontPanel
//!
//! A FrontPanel pipe-out read must not ask for more than the FIFO holds (the
//! okPipeOut core would read past the FIFO's end) and its length must be a
//! multiple of [`PIPE_BLOCK_BYTES`] bytes. The host therefore reads `FIFO_BYTES`
//! rounded down to the granule. At the end of the stream (`ENDED` set), the
//! gateware pads its last partial granule with zero bytes that `FIFO_BYTES`
//! does not count; the host reads one whole granule and keeps only the
//! `FIFO_BYTES` bytes that belong to the stream, so the padding never reaches
//! the file or the decoder.
//!
//! # Configuration sequence (the host's `configure`, `start`, `stop`)
//!
//! 1. read the wire-outs 0x22–0x27 and compare them with the preset: any
//!    difference is an error naming each field;
//! 2. pulse `RESET`;
//! 3. write wire-ins 0x00–0x08 and commit them (FrontPanel `UpdateWireIns`);
//! 4. if a hot-pixel mask is set, write it to pipe-in 0x81;
//! 5. `START` pulses trigger 0x40 bit 1; `STOP` bit 2.

use crate::packet::{crc32c, VERSION as PACKET_VERSION};

/// Version of this register map, reported in bits 15:8 of wire-out `VERSION`.
/// Version 2 added wire-in `THRESHOLD_HOLD` (0x07), version 3 `END_TRIM` (0x08).
pub const REGISTER_MAP_VERSION: u8 = 3;

/// FrontPanel pipe transfers are whole multiples of this many bytes (the
/// USB 3.0 granule of the XEM6310; block-throttled pipes use blocks of it).
pub const PIPE_BLOCK_BYTES: usize = 16;

/// Wire-in addresses (host → device).
pub mod wire_in {
    /// `SOURCE_REPLAY` (bit 0) and `MASK_ENABLE` (bit 1), see [`super::control`].
    pub const CONTROL: u8 = 0x00;
    /// Rolling window N, bit-planes.
    pub const N_WINDOW: u8 = 0x01;
    /// Integer threshold T_int.
    pub const THRESHOLD_INT: u8 = 0x02;
    /// L_min, planes.
    pub const L_MIN: u8 = 0x03;
    /// L_max, planes.
    pub const L_MAX: u8 = 0x04;
    /// Bit-plane period, ns.
    pub const PLANE_PERIOD_NS: u8 = 0x05;
    /// Number of masked pixels.
    pub const MASKED_PIXELS: u8 = 0x06;
    /// Integer threshold T_hold (hysteresis: holds an open track on).
    pub const THRESHOLD_HOLD: u8 = 0x07;
    /// Planes between a dropped segment's last summed plane and its t_drop.
    pub const END_TRIM: u8 = 0x08;
    /// How many wire-ins there are (0x00 ..= 0x08).
    pub const COUNT: usize = 9;
}

/// Bits of wire-in [`wire_in::CONTROL`].
pub mod control {
    /// Bit-planes come from pipe-in [`super::pipe::REPLAY_IN`] instead of the sensor.
    pub const SOURCE_REPLAY: u32 = 1 << 0;
    /// Apply the hot-pixel mask loaded through pipe-in [`super::pipe::MASK_IN`].
    pub const MASK_ENABLE: u32 = 1 << 1;
}

/// Wire-out addresses (device → host).
pub mod wire_out {
    /// Status bits, see [`super::status`].
    pub const STATUS: u8 = 0x20;
    /// Bytes waiting in the output FIFO.
    pub const FIFO_BYTES: u8 = 0x21;
    /// Packet format version (7:0) and register-map version (15:8).
    pub const VERSION: u8 = 0x22;
    /// Width (15:0) and height (31:16).
    pub const GEOMETRY: u8 = 0x23;
    /// Kernel length (7:0), kernel shift (15:8), ROI side (23:16), slots (31:24).
    pub const GENERATION: u8 = 0x24;
    /// CRC-32C of the kernel weights (u16 little-endian each).
    pub const KERNEL_CRC: u8 = 0x25;
    /// Association radius (7:0).
    pub const R_ASSOC: u8 = 0x26;
    /// Largest N the delay line holds.
    pub const MAX_N: u8 = 0x27;
    /// How many wire-outs there are (0x20 ..= 0x27).
    pub const COUNT: usize = 8;
}

/// Bits of wire-out [`wire_out::STATUS`]. Bits 0–2 are what the host needs to
/// stream; bits 3–7 are gateware diagnostics the host shows.
pub mod status {
    /// The pipeline is processing bit-planes.
    pub const RUNNING: u32 = 1 << 0;
    /// The StreamEnd record is in the output FIFO (or already read).
    pub const ENDED: u32 = 1 << 1;
    /// The device lost records since START, its output FIFO or its record
    /// queue being full (sticky; Overflow records carry the counts).
    pub const OVERFLOWED: u32 = 1 << 2;
    /// START was refused: a register is out of range.
    pub const CONFIG_ERROR: u32 = 1 << 3;
    /// A buffer overflowed or the DDR2 delay line under-ran (the stream is not exact).
    pub const FAULT: u32 = 1 << 4;
    /// The DDR2 memory has calibrated (START waits for it); always set where
    /// the delay line is in block RAM.
    pub const MEM_READY: u32 = 1 << 5;
    /// The source's start-of-plane came inside a plane.
    pub const FRAMING_ERROR: u32 = 1 << 6;
    /// The sensor port's clock-crossing FIFO overflowed.
    pub const SENSOR_OVERFLOW: u32 = 1 << 7;
}

/// Trigger-in address and bits.
pub mod trigger {
    /// The control trigger-in endpoint.
    pub const CONTROL: u8 = 0x40;
    /// Bit: reset the pipeline (while stopped).
    pub const RESET: u8 = 0;
    /// Bit: latch the wire-ins and start streaming, once the mask pipe has
    /// drained into the mask and the memory has calibrated (a START before
    /// then waits; RESET cancels it).
    pub const START: u8 = 1;
    /// Bit: finish, emit StreamEnd and stop.
    pub const STOP: u8 = 2;
}

/// Pipe addresses.
pub mod pipe {
    /// Bit-planes to replay (pipe-in).
    pub const REPLAY_IN: u8 = 0x80;
    /// Hot-pixel mask (pipe-in).
    pub const MASK_IN: u8 = 0x81;
    /// The packet stream (pipe-out).
    pub const STREAM_OUT: u8 = 0xA0;
}

/// Wire-out `VERSION`: packet format version (7:0), register-map version (15:8).
pub fn version_word() -> u32 {
    PACKET_VERSION as u32 | (REGISTER_MAP_VERSION as u32) << 8
}

/// Wire-out `KERNEL_CRC`: CRC-32C of the kernel weights, each as u16
/// little-endian (weights are at most 2^a ≤ 2^12, the configuration's limit
/// `a ≤ 12`, so each fits its u16).
pub fn kernel_crc(weights: impl IntoIterator<Item = u16>) -> u32 {
    let bytes: Vec<u8> = weights.into_iter().flat_map(u16::to_le_bytes).collect();
    crc32c(&bytes)
}

/// What the host writes to configure one stream (steps 3 and 4 of the
/// configuration sequence): the wire-ins and the hot-pixel mask's pipe-in
/// bytes. The host's `configure` and the co-simulation harness both write
/// exactly these, so the registers go into the gateware one way only.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StreamRegisters {
    /// `CONTROL` bit `SOURCE_REPLAY`: bit-planes from pipe-in 0x80.
    pub source_replay: bool,
    /// Rolling window N.
    pub n_window: u32,
    /// T_int.
    pub threshold_int: u32,
    /// T_hold.
    pub threshold_hold: u32,
    /// END_TRIM.
    pub end_trim: u32,
    /// L_min.
    pub l_min: u32,
    /// L_max.
    pub l_max: u32,
    /// Bit-plane period, ns.
    pub plane_period_ns: u32,
    /// The bytes for pipe-in [`pipe::MASK_IN`] ([`mask_bytes`]); `None`: no
    /// mask is loaded and `MASK_ENABLE` is clear.
    pub mask: Option<Vec<u8>>,
}

impl StreamRegisters {
    /// The registers of a pipeline configuration (its hot-pixel mask, if
    /// any, loaded and enabled; planes from the sensor).
    pub fn of(cfg: &crate::config::PipelineConfig) -> StreamRegisters {
        StreamRegisters {
            source_replay: false,
            n_window: cfg.n_window,
            threshold_int: cfg.threshold_int,
            threshold_hold: cfg.threshold_hold,
            end_trim: cfg.end_trim,
            l_min: cfg.l_min,
            l_max: cfg.l_max,
            plane_period_ns: cfg.plane_period_ns,
            mask: cfg.hot_mask.as_ref().map(mask_bytes),
        }
    }

    /// The `MASKED_PIXELS` value: the pixels the mask's pipe-in bytes mask
    /// (0 without a mask).
    pub fn masked_pixels(&self) -> u32 {
        self.mask.as_deref().map_or(0, masked_pixels_in)
    }

    /// The wire-in writes (address, value), in address order.
    pub fn wire_ins(&self) -> [(u8, u32); wire_in::COUNT] {
        let mut ctl = 0;
        if self.source_replay {
            ctl |= control::SOURCE_REPLAY;
        }
        if self.mask.is_some() {
            ctl |= control::MASK_ENABLE;
        }
        [
            (wire_in::CONTROL, ctl),
            (wire_in::N_WINDOW, self.n_window),
            (wire_in::THRESHOLD_INT, self.threshold_int),
            (wire_in::L_MIN, self.l_min),
            (wire_in::L_MAX, self.l_max),
            (wire_in::PLANE_PERIOD_NS, self.plane_period_ns),
            (wire_in::MASKED_PIXELS, self.masked_pixels()),
            (wire_in::THRESHOLD_HOLD, self.threshold_hold),
            (wire_in::END_TRIM, self.end_trim),
        ]
    }
}

/// A hot-pixel mask as pipe-in [`pipe::MASK_IN`] takes it: packed like a
/// bit-plane (W·H bits, raster order, least significant bit first, 1 =
/// masked), padded to whole bytes.
pub fn mask_bytes(mask: &crate::hot_pixel_mask::HotPixelMask) -> Vec<u8> {
    let (w, h) = (mask.width(), mask.height());
    let mut bytes = vec![0u8; (w * h).div_ceil(8)];
    for y in 0..h {
        for x in 0..w {
            if mask.is_masked(x as i64, y as i64) {
                let i = y * w + x;
                bytes[i / 8] |= 1 << (i % 8);
            }
        }
    }
    bytes
}

/// Bit-planes as pipe-in [`pipe::REPLAY_IN`] takes them: each plane's W·H
/// bits in raster order, least significant bit first, padded to whole
/// bytes ([`crate::recording::pack_plane`]), planes back to back.
pub fn replay_bytes(planes: &[crate::plane::BitPlane]) -> Vec<u8> {
    let mut bytes = Vec::new();
    for p in planes {
        crate::recording::pack_plane(p, crate::recording::BitOrder::LsbFirst, &mut bytes);
    }
    bytes
}

/// Pipe-in bytes as the pipe's 32-bit little-endian words, the last one
/// zero-padded.
pub fn pipe_words(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks(4)
        .map(|c| {
            let mut b = [0u8; 4];
            b[..c.len()].copy_from_slice(c);
            u32::from_le_bytes(b)
        })
        .collect()
}

/// [`replay_bytes`] as the pipe's 32-bit words ([`pipe_words`]).
pub fn replay_words(planes: &[crate::plane::BitPlane]) -> Vec<u32> {
    pipe_words(&replay_bytes(planes))
}

/// How many pixels mask bytes written to pipe-in [`pipe::MASK_IN`] mask: the
/// set bits (padding is zero).
pub fn masked_pixels_in(bytes: &[u8]) -> u32 {
    bytes.iter().map(|b| b.count_ones()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replay_words_pack_pixel_i_in_bit_i() {
        use crate::plane::BitPlane;
        // Two 16×2 planes: 32 bits each, one word each.
        let a = BitPlane::from_fn(16, 2, |x, y| (x, y) == (0, 0) || (x, y) == (15, 1));
        let b = BitPlane::from_fn(16, 2, |x, y| (x, y) == (3, 0));
        assert_eq!(replay_words(&[a.clone(), b]), [1 | 1 << 31, 1 << 3]);
        // A plane of 8×1 pixels is one byte: the word is zero-padded.
        let c = BitPlane::from_fn(8, 1, |x, _| x == 7);
        let c = [c];
        assert_eq!(replay_bytes(&c), [0x80]);
        assert_eq!(replay_words(&c), [0x80]);
        // Stream words of the same plane, P = 4 and P = 16.
        assert_eq!(a.stream_word(4, 0), 1);
        assert_eq!(a.stream_word(4, 7), 1 << 3);
        assert_eq!(a.stream_word(16, 1), 1 << 15);
    }

    #[test]
    fn words_follow_the_table() {
        assert_eq!(version_word(), 0x0303);
        // CRC-32C of [1, 2, 1] as u16 LE, and it depends on every weight.
        assert_eq!(kernel_crc([1, 2, 1]), crc32c(&[1, 0, 2, 0, 1, 0]));
        assert_ne!(kernel_crc([1, 2, 1]), kernel_crc([1, 2, 2]));
        assert_eq!(
            wire_out::MAX_N - wire_out::STATUS + 1,
            wire_out::COUNT as u8
        );
        assert_eq!(wire_in::END_TRIM as usize + 1, wire_in::COUNT);
        // Every status bit is distinct.
        let bits = [
            status::RUNNING,
            status::ENDED,
            status::OVERFLOWED,
            status::CONFIG_ERROR,
            status::FAULT,
            status::MEM_READY,
            status::FRAMING_ERROR,
            status::SENSOR_OVERFLOW,
        ];
        assert_eq!(bits.iter().fold(0, |a, b| a | b).count_ones(), 8);
    }

    #[test]
    fn stream_registers_write_the_mask_and_its_count() {
        use crate::config::PipelineConfig;
        use crate::hot_pixel_mask::HotPixelMask;
        let mut cfg = PipelineConfig::new(12, 10, 3, vec![1, 2, 1], 2, 8);
        let plain = StreamRegisters::of(&cfg);
        assert_eq!(plain.mask, None);
        assert_eq!(plain.wire_ins()[0], (wire_in::CONTROL, 0));
        assert_eq!(plain.wire_ins()[6], (wire_in::MASKED_PIXELS, 0));
        cfg.hot_mask = Some(HotPixelMask::from_pixels(12, 10, &[(0, 0), (11, 9), (3, 4)]).0);
        let regs = StreamRegisters {
            source_replay: true,
            ..StreamRegisters::of(&cfg)
        };
        let bytes = regs.mask.clone().unwrap();
        assert_eq!(bytes.len(), 15);
        // Pixel (3, 4) is bit 51: byte 6, bit 3; (11, 9) is the last pixel.
        assert_eq!((bytes[0], bytes[6], bytes[14]), (1, 1 << 3, 1 << 7));
        let w = regs.wire_ins();
        for (i, (a, _)) in w.iter().enumerate() {
            assert_eq!(*a as usize, i);
        }
        assert_eq!(w[0].1, control::SOURCE_REPLAY | control::MASK_ENABLE);
        assert_eq!(w[wire_in::MASKED_PIXELS as usize].1, 3);
        assert_eq!(w[wire_in::N_WINDOW as usize].1, 3);
        assert_eq!(w[wire_in::THRESHOLD_INT as usize].1, 8);
        assert_eq!(masked_pixels_in(&bytes), 3);
    }
}
