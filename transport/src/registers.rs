//! The host's side of the device register map. The map itself (addresses,
//! bits, versions: the table of wire-ins, wire-outs, triggers and pipes) is
//! [`smartagg_model::registers`], which the gateware (`hdl/`) uses too, so the
//! two sides cannot drift apart. Here: the configuration a device gets from a
//! pipeline configuration ([`DeviceConfig`]), the check of the generation
//! words against the preset, the configuration sequence over any
//! [`RegisterBus`], and the vendor requests of the plain-USB firmware
//! ([`vendor`]), which reach the same registers as FrontPanel's endpoints.
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
//! # Configuration sequence ([`configure`], [`start`], [`stop`])
//!
//! 1. read the wire-outs 0x22–0x27 and compare them with the preset
//!    ([`check_generation`]): any difference is an error naming each field;
//! 2. pulse `RESET`;
//! 3. write wire-ins 0x00–0x06 and commit them (FrontPanel `UpdateWireIns`);
//! 4. if a hot-pixel mask is set, write it to pipe-in 0x81;
//! 5. `START` pulses trigger 0x40 bit 1; `STOP` bit 2.

use super::TransportError;
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::VERSION as PACKET_VERSION;
use smartagg_model::record::StreamStart;

pub use smartagg_model::registers::{
    control, pipe, status, trigger, wire_in, wire_out, StreamRegisters, PIPE_BLOCK_BYTES,
    REGISTER_MAP_VERSION,
};

/// The vendor control requests of the plain-USB (bulk) firmware, which give
/// the same registers as FrontPanel's wires, triggers and pipes.
///
/// | bRequest | bmRequestType | wValue  | wIndex | data                          |
/// |----------|---------------|---------|--------|-------------------------------|
/// | 0x01 `WRITE_WIRE_IN`    | 0x40 (OUT, vendor, device) | address | 0   | 4 bytes, u32 LE |
/// | 0x02 `ACTIVATE_TRIGGER` | 0x40                       | address | bit | none            |
/// | 0x03 `READ_WIRE_OUT`    | 0xC0 (IN, vendor, device)  | address | 0   | 4 bytes, u32 LE |
/// | 0x04 `WRITE_PIPE_IN`    | 0x40                       | address | 0   | up to [`vendor::MAX_CONTROL_DATA`] bytes; consecutive requests append |
///
/// Wire-ins take effect at once (there is no `UpdateWireIns`); the firmware
/// latches them at START like the FrontPanel gateware. The packet stream
/// itself arrives on the bulk IN endpoint chosen with `--endpoint`.
pub mod vendor {
    /// bmRequestType of host-to-device vendor requests.
    pub const REQUEST_TYPE_OUT: u8 = 0x40;
    /// bmRequestType of device-to-host vendor requests.
    pub const REQUEST_TYPE_IN: u8 = 0xC0;
    /// Write a wire-in.
    pub const WRITE_WIRE_IN: u8 = 0x01;
    /// Pulse one trigger bit.
    pub const ACTIVATE_TRIGGER: u8 = 0x02;
    /// Read a wire-out.
    pub const READ_WIRE_OUT: u8 = 0x03;
    /// Append bytes to a pipe-in.
    pub const WRITE_PIPE_IN: u8 = 0x04;
    /// Most data bytes in one control request (libusb's limit).
    pub const MAX_CONTROL_DATA: usize = 4096;
}

/// What the host writes into the device before START, derived from a
/// [`PipelineConfig`]; also the values the generated gateware must have been
/// built with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceConfig {
    /// The runtime registers and the hot-pixel mask's pipe-in bytes, as
    /// the host writes them (the model's [`StreamRegisters`], which the
    /// co-simulation harness writes too; planes from the sensor).
    pub registers: StreamRegisters,
    /// Generation constant: sensor width.
    pub width: u16,
    /// Generation constant: sensor height.
    pub height: u16,
    /// Generation constant: the 1-D kernel weights.
    pub kernel: Vec<u16>,
    /// Generation constant: kernel shift a.
    pub kernel_shift: u8,
    /// Generation constant: ROI side R.
    pub roi_size: u8,
    /// Generation constant: tracking slots M.
    pub slots: u8,
    /// Generation constant: association radius.
    pub r_assoc: u8,
}

impl DeviceConfig {
    /// The device configuration of a validated pipeline configuration.
    pub fn from_pipeline(cfg: &PipelineConfig) -> Result<DeviceConfig, TransportError> {
        cfg.validate()
            .map_err(|e| TransportError::Config(e.to_string()))?;
        // validate() bounds every field below to its register width.
        let start = cfg.stream_start();
        Ok(DeviceConfig {
            registers: StreamRegisters::of(cfg),
            width: start.width,
            height: start.height,
            kernel: start.kernel.clone(),
            kernel_shift: start.kernel_shift,
            roi_size: start.roi_size,
            slots: start.slots,
            r_assoc: start.r_assoc,
        })
    }

    /// The StreamStart record a device configured with this must send first.
    pub fn expected_start(&self) -> StreamStart {
        let r = &self.registers;
        StreamStart {
            width: self.width,
            height: self.height,
            n_window: r.n_window,
            threshold_int: r.threshold_int,
            threshold_hold: r.threshold_hold,
            end_trim: Some(r.end_trim),
            l_min: r.l_min,
            l_max: r.l_max,
            r_assoc: self.r_assoc,
            slots: self.slots,
            roi_size: self.roi_size,
            kernel_shift: self.kernel_shift,
            kernel: self.kernel.clone(),
            plane_period_ns: r.plane_period_ns,
            masked_pixels: r.masked_pixels(),
        }
    }

    /// The wire-in values, in address order ([`StreamRegisters::wire_ins`]:
    /// `MASKED_PIXELS` counts the pixels of the mask bytes written).
    pub fn wire_ins(&self) -> [(u8, u32); wire_in::COUNT] {
        self.registers.wire_ins()
    }
}

/// CRC-32C of kernel weights, each as u16 little-endian (wire-out `KERNEL_CRC`).
pub fn kernel_crc(kernel: &[u16]) -> u32 {
    smartagg_model::registers::kernel_crc(kernel.iter().copied())
}

/// Register access shared by the FrontPanel and the plain-USB transports (and
/// by a co-simulated device): the configuration sequence is written once
/// against this.
pub trait RegisterBus {
    /// Sets a wire-in (FrontPanel: takes effect at [`RegisterBus::commit_wire_ins`]).
    fn set_wire_in(&mut self, addr: u8, value: u32) -> Result<(), TransportError>;
    /// Sends the wire-ins set so far (FrontPanel `UpdateWireIns`; no-op on USB).
    fn commit_wire_ins(&mut self) -> Result<(), TransportError>;
    /// Reads the current value of a wire-out (FrontPanel: `UpdateWireOuts` then
    /// `GetWireOutValue`).
    fn wire_out(&mut self, addr: u8) -> Result<u32, TransportError>;
    /// Pulses one bit of a trigger-in.
    fn trigger(&mut self, addr: u8, bit: u8) -> Result<(), TransportError>;
    /// Writes bytes to a pipe-in.
    fn write_pipe_in(&mut self, addr: u8, data: &[u8]) -> Result<(), TransportError>;
}

/// The generation constants a device reports (wire-outs 0x22–0x27).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Generation {
    /// Packet format version.
    pub packet_version: u8,
    /// Register-map version.
    pub map_version: u8,
    /// Width.
    pub width: u16,
    /// Height.
    pub height: u16,
    /// Kernel length.
    pub kernel_len: u8,
    /// Kernel shift a.
    pub kernel_shift: u8,
    /// ROI side R.
    pub roi_size: u8,
    /// Slots M.
    pub slots: u8,
    /// CRC-32C of the kernel weights.
    pub kernel_crc: u32,
    /// Association radius.
    pub r_assoc: u8,
    /// Largest N the delay line holds.
    pub max_n: u32,
}

impl Generation {
    /// Reads the generation wire-outs.
    pub fn read(bus: &mut dyn RegisterBus) -> Result<Generation, TransportError> {
        let version = bus.wire_out(wire_out::VERSION)?;
        let geometry = bus.wire_out(wire_out::GEOMETRY)?;
        let generation = bus.wire_out(wire_out::GENERATION)?;
        Ok(Generation {
            packet_version: version as u8,
            map_version: (version >> 8) as u8,
            width: geometry as u16,
            height: (geometry >> 16) as u16,
            kernel_len: generation as u8,
            kernel_shift: (generation >> 8) as u8,
            roi_size: (generation >> 16) as u8,
            slots: (generation >> 24) as u8,
            kernel_crc: bus.wire_out(wire_out::KERNEL_CRC)?,
            r_assoc: bus.wire_out(wire_out::R_ASSOC)? as u8,
            max_n: bus.wire_out(wire_out::MAX_N)?,
        })
    }

    /// The words a device generated for `cfg` reports, address by address
    /// (what a simulated device or the gateware test bench must return).
    #[allow(dead_code)] // for the co-simulation and the tests
    pub fn words_for(cfg: &DeviceConfig, max_n: u32) -> [(u8, u32); 6] {
        [
            (wire_out::VERSION, smartagg_model::registers::version_word()),
            (
                wire_out::GEOMETRY,
                cfg.width as u32 | (cfg.height as u32) << 16,
            ),
            (
                wire_out::GENERATION,
                cfg.kernel.len() as u32
                    | (cfg.kernel_shift as u32) << 8
                    | (cfg.roi_size as u32) << 16
                    | (cfg.slots as u32) << 24,
            ),
            (wire_out::KERNEL_CRC, kernel_crc(&cfg.kernel)),
            (wire_out::R_ASSOC, cfg.r_assoc as u32),
            (wire_out::MAX_N, max_n),
        ]
    }
}

/// Every difference between what the device was generated for and what the
/// preset needs, one sentence each (empty: they agree).
pub fn check_generation(dev: &Generation, cfg: &DeviceConfig) -> Vec<String> {
    let mut diffs = Vec::new();
    let mut diff = |what: &str, device: String, preset: String| {
        diffs.push(format!("{what}: device {device}, preset {preset}"));
    };
    if dev.packet_version != PACKET_VERSION {
        diff(
            "packet format version",
            dev.packet_version.to_string(),
            format!("{PACKET_VERSION} (this smartagg)"),
        );
    }
    if dev.map_version != REGISTER_MAP_VERSION {
        diff(
            "register map version",
            dev.map_version.to_string(),
            format!("{REGISTER_MAP_VERSION} (this smartagg)"),
        );
    }
    if (dev.width, dev.height) != (cfg.width, cfg.height) {
        diff(
            "sensor size",
            format!("{}x{}", dev.width, dev.height),
            format!("{}x{}", cfg.width, cfg.height),
        );
    }
    if dev.kernel_len as usize != cfg.kernel.len() {
        diff(
            "kernel length",
            dev.kernel_len.to_string(),
            cfg.kernel.len().to_string(),
        );
    }
    if dev.kernel_shift != cfg.kernel_shift {
        diff(
            "kernel shift",
            dev.kernel_shift.to_string(),
            cfg.kernel_shift.to_string(),
        );
    }
    if dev.kernel_crc != kernel_crc(&cfg.kernel) {
        diff(
            "kernel weights (CRC-32C)",
            format!("0x{:08X}", dev.kernel_crc),
            format!("0x{:08X} for {:?}", kernel_crc(&cfg.kernel), cfg.kernel),
        );
    }
    if dev.roi_size != cfg.roi_size {
        diff(
            "ROI side",
            dev.roi_size.to_string(),
            cfg.roi_size.to_string(),
        );
    }
    if dev.slots != cfg.slots {
        diff(
            "tracking slots",
            dev.slots.to_string(),
            cfg.slots.to_string(),
        );
    }
    if dev.r_assoc != cfg.r_assoc {
        diff(
            "association radius",
            dev.r_assoc.to_string(),
            cfg.r_assoc.to_string(),
        );
    }
    if cfg.registers.n_window > dev.max_n {
        diffs.push(format!(
            "window N = {} exceeds the device's delay line ({} planes)",
            cfg.registers.n_window, dev.max_n
        ));
    }
    diffs
}

/// Checks the device's generation against `cfg`, resets it and writes the
/// runtime registers and the mask (steps 1–4 of the module docs).
pub fn configure(bus: &mut dyn RegisterBus, cfg: &DeviceConfig) -> Result<(), TransportError> {
    let generation = Generation::read(bus)?;
    let diffs = check_generation(&generation, cfg);
    if !diffs.is_empty() {
        return Err(TransportError::GenerationMismatch(diffs));
    }
    bus.trigger(trigger::CONTROL, trigger::RESET)?;
    for (addr, value) in cfg.wire_ins() {
        bus.set_wire_in(addr, value)?;
    }
    bus.commit_wire_ins()?;
    if let Some(mask) = &cfg.registers.mask {
        bus.write_pipe_in(pipe::MASK_IN, mask)?;
    }
    Ok(())
}

/// Starts streaming (trigger START).
pub fn start(bus: &mut dyn RegisterBus) -> Result<(), TransportError> {
    bus.trigger(trigger::CONTROL, trigger::START)
}

/// Asks the device to finish the stream (trigger STOP): it emits StreamEnd.
pub fn stop(bus: &mut dyn RegisterBus) -> Result<(), TransportError> {
    bus.trigger(trigger::CONTROL, trigger::STOP)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use smartagg_model::hot_pixel_mask::HotPixelMask;
    use std::collections::HashMap;

    /// A register bus that records what the host does and answers wire-outs
    /// from a table.
    #[derive(Default)]
    pub(crate) struct MockBus {
        pub wire_outs: HashMap<u8, u32>,
        pub pending: HashMap<u8, u32>,
        pub committed: HashMap<u8, u32>,
        pub log: Vec<String>,
        pub pipe_in: HashMap<u8, Vec<u8>>,
    }

    impl RegisterBus for MockBus {
        fn set_wire_in(&mut self, addr: u8, value: u32) -> Result<(), TransportError> {
            self.pending.insert(addr, value);
            Ok(())
        }
        fn commit_wire_ins(&mut self) -> Result<(), TransportError> {
            self.committed.extend(self.pending.drain());
            self.log.push("commit".into());
            Ok(())
        }
        fn wire_out(&mut self, addr: u8) -> Result<u32, TransportError> {
            Ok(self.wire_outs.get(&addr).copied().unwrap_or(0))
        }
        fn trigger(&mut self, addr: u8, bit: u8) -> Result<(), TransportError> {
            self.log.push(format!("trigger {addr:#04x}.{bit}"));
            Ok(())
        }
        fn write_pipe_in(&mut self, addr: u8, data: &[u8]) -> Result<(), TransportError> {
            self.log
                .push(format!("pipe {addr:#04x} {} bytes", data.len()));
            self.pipe_in
                .entry(addr)
                .or_default()
                .extend_from_slice(data);
            Ok(())
        }
    }

    pub(crate) fn pipeline() -> PipelineConfig {
        let mut cfg = PipelineConfig::new(16, 12, 10, vec![1, 2, 1], 2, 20);
        cfg.threshold_hold = 13;
        cfg.end_trim = 4;
        cfg.l_min = 3;
        cfg.l_max = 50;
        cfg.plane_period_ns = 100_000;
        cfg
    }

    pub(crate) fn bus_for(cfg: &DeviceConfig) -> MockBus {
        let mut bus = MockBus::default();
        bus.wire_outs.extend(Generation::words_for(cfg, 4096));
        bus
    }

    #[test]
    fn configure_writes_every_runtime_register_after_reset() {
        let mut p = pipeline();
        let (mask, _) = HotPixelMask::from_pixels(16, 12, &[(0, 0), (9, 0), (15, 11)]);
        p.hot_mask = Some(mask);
        let cfg = DeviceConfig::from_pipeline(&p).unwrap();
        let mut bus = bus_for(&cfg);
        configure(&mut bus, &cfg).unwrap();
        let c = &bus.committed;
        assert_eq!(c[&wire_in::N_WINDOW], 10);
        assert_eq!(c[&wire_in::THRESHOLD_INT], 20);
        assert_eq!(c[&wire_in::THRESHOLD_HOLD], p.threshold_hold);
        assert_eq!(c[&wire_in::END_TRIM], 4);
        assert_eq!(c[&wire_in::L_MIN], 3);
        assert_eq!(c[&wire_in::L_MAX], 50);
        assert_eq!(c[&wire_in::PLANE_PERIOD_NS], 100_000);
        assert_eq!(c[&wire_in::MASKED_PIXELS], 3);
        assert_eq!(c[&wire_in::CONTROL], control::MASK_ENABLE);
        assert!(bus.pending.is_empty(), "every wire-in was committed");
        assert_eq!(
            bus.log,
            ["trigger 0x40.0", "commit", "pipe 0x81 24 bytes"],
            "reset first, then registers, then the mask"
        );
        // Mask packing: raster order, least significant bit first.
        let m = &bus.pipe_in[&pipe::MASK_IN];
        assert_eq!(m.len(), 16 * 12 / 8);
        assert_eq!(m[0], 0b0000_0001);
        assert_eq!(m[1], 0b0000_0010);
        assert_eq!(m[23], 0b1000_0000);
        assert_eq!(m.iter().map(|b| b.count_ones()).sum::<u32>(), 3);
        start(&mut bus).unwrap();
        stop(&mut bus).unwrap();
        assert_eq!(&bus.log[3..], ["trigger 0x40.1", "trigger 0x40.2"]);
    }

    #[test]
    fn expected_start_is_the_pipelines_stream_start() {
        let p = pipeline();
        let cfg = DeviceConfig::from_pipeline(&p).unwrap();
        assert_eq!(cfg.expected_start(), p.stream_start());
        assert_eq!(cfg.registers.mask, None);
        assert_eq!(cfg.wire_ins()[0], (wire_in::CONTROL, 0));
    }

    #[test]
    fn a_bitfile_for_another_preset_is_refused_field_by_field() {
        let cfg = DeviceConfig::from_pipeline(&pipeline()).unwrap();
        let mut other = pipeline();
        other.kernel = vec![1, 6, 1];
        other.kernel_shift = 3;
        other.roi_size = 5;
        let other = DeviceConfig::from_pipeline(&other).unwrap();
        let mut bus = bus_for(&other);
        let e = configure(&mut bus, &cfg).unwrap_err().to_string();
        for needle in [
            "kernel shift: device 3, preset 2",
            "kernel weights",
            "ROI side: device 5, preset 3",
        ] {
            assert!(e.contains(needle), "{needle} missing from: {e}");
        }
        assert!(!e.contains("sensor size"), "{e}");
        assert!(bus.log.is_empty(), "nothing written to a mismatched device");

        // A window longer than the delay line.
        let mut bus = bus_for(&cfg);
        bus.wire_outs.insert(wire_out::MAX_N, 8);
        let e = configure(&mut bus, &cfg).unwrap_err().to_string();
        assert!(
            e.contains("window N = 10 exceeds the device's delay line (8 planes)"),
            "{e}"
        );

        // A device that answers nothing (all zeros): version and size named.
        let mut bus = MockBus::default();
        let e = configure(&mut bus, &cfg).unwrap_err().to_string();
        assert!(e.contains("packet format version: device 0"), "{e}");
        assert!(e.contains("sensor size: device 0x0, preset 16x12"), "{e}");
    }

    #[test]
    fn kernel_crc_is_crc32c_of_le_weights() {
        // [1, 2, 1] as u16 LE = 01 00 02 00 01 00.
        assert_eq!(
            kernel_crc(&[1, 2, 1]),
            smartagg_model::packet::crc32c(&[1, 0, 2, 0, 1, 0])
        );
        assert_ne!(kernel_crc(&[1, 2, 1]), kernel_crc(&[1, 2, 2]));
    }

    #[test]
    fn invalid_pipeline_configuration_is_a_clear_error() {
        let mut p = pipeline();
        p.threshold_int = 0;
        let e = DeviceConfig::from_pipeline(&p).unwrap_err().to_string();
        assert!(e.contains("threshold_int"), "{e}");
    }
}
