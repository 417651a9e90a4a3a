//! The FPGAs a design is generated for and reported against, and which one
//! a preset's design targets. A leaf module: the blocks that size
//! themselves by a device (the spatial filter's DSP slices) and the named
//! designs ([`crate::designs`]) both read it.

use smartagg_model::params::PresetName;

/// An FPGA the design is reported against (Spartan-6 capacities from the
/// Xilinx DS160 family overview).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Device {
    /// Part name.
    pub name: &'static str,
    /// 6-input LUTs.
    pub luts: u64,
    /// Flip-flops.
    pub ffs: u64,
    /// 18-Kbit block RAMs (RAMB16BWER; a RAMB8BWER is half of one).
    pub ramb16: u64,
    /// DSP48A1 slices.
    pub dsp48a1: u64,
}

/// The XC6SLX45 of the XEM6310-LX45.
pub const XC6SLX45: Device = Device {
    name: "XC6SLX45",
    luts: 27_288,
    ffs: 54_576,
    ramb16: 116,
    dsp48a1: 58,
};

/// The XC6SLX150 of the XEM6310-LX150.
pub const XC6SLX150: Device = Device {
    name: "XC6SLX150",
    luts: 92_152,
    ffs: 184_304,
    ramb16: 268,
    dsp48a1: 180,
};

/// Both devices, in report order.
pub const DEVICES: [Device; 2] = [XC6SLX45, XC6SLX150];

/// The device a preset's design is generated for: the SPCImager's on the
/// XEM6310-LX45, the larger sensors' on the LX150.
pub fn device_for(preset: PresetName) -> Device {
    match preset {
        PresetName::Spcimager => XC6SLX45,
        _ => XC6SLX150,
    }
}

impl Device {
    /// Bits of block RAM.
    pub fn block_ram_bits(&self) -> u64 {
        self.ramb16 * 18 * 1024
    }
}
