//! The generated designs, one per (preset, objective) (docs/DESIGN.md §7): the
//! single place that maps a scene to its Verilog, its constraints and its
//! device.
//!
//! Everything the circuit carries follows from the model's statistics
//! ([`smartagg_model::stats::derive`] of the preset, as `smartagg params`
//! prints them):
//! * the kernel weights `k1` and shift `a` (constants of the filter), hence
//!   the ROI side R = k and the widths of V and H;
//! * N_max, the largest runtime N, from the model's N: **block RAM** when the
//!   delay line of N_max planes takes at most half of the device's block RAM
//!   (N_max = N rounded up to a multiple of 8, room for a dimmer scene),
//!   otherwise the XEM6310's **DDR2** (N_max = 128: the widths of the
//!   existing SPCImager design, 9.8 Mbit, a small part of the 1-Gbit DDR2);
//! * the device: the SPCImager on the XEM6310-LX45, the projected SPCImager
//!   (whose delay line must stay on chip) on the XEM6310-LX150.
//!
//! The detection follows the model's field design
//! ([`smartagg_model::field_design::design`] for the whole sensor at the
//! preset's plane rate and the default false-blink budget): the open level
//! T_open (the T_int register's default), the hold level T_hold (the
//! T_hold register's default), the end trim `⌊N/2⌋` (the END_TRIM
//! register's default: a dropped segment sums up to its estimated end
//! `t_e`) and the association radius r_assoc (a compile-time constant of
//! the tracker). M = 32 slots and L_max up to 65,535 planes are the model's
//! defaults. N, T_int, T_hold, END_TRIM, L_min, L_max and the hot-pixel
//! mask are runtime registers, latched at stream start
//! ([`crate::stream_control::StreamControl`]).
//!
//! rust-hdl widths are const generics, so each design is one type alias
//! here; its `new` checks the alias against the configuration.

use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::device::{device_for, Device};
use crate::front_half::verilog;
use crate::pipeline::{Pipeline, PipelineDdr};
use crate::xem6310::{Xem6310Top, Xem6310TopOnChip};
use crate::xem6310_core::{XemCore, XemCoreOnChip};
use smartagg_model::field_design;
use smartagg_model::params::{Preset, PresetName};
use smartagg_model::stats::{self, DetectionInputs};

/// Where the N-plane delay line lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DelayLineKind {
    /// On-chip block RAM ([`crate::delay_line::DelayLine`]).
    BlockRam,
    /// The XEM6310's DDR2 through the Spartan-6 MCB
    /// ([`crate::delay_line_ddr::DelayLineDdr`]).
    Ddr2,
}

/// Which XEM6310 top the generated Verilog holds (both have the board's
/// pins, placed by `constraints/xem6310.ucf`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopKind {
    /// [`Xem6310Top`]: the delay line in the DDR2, through the MIG.
    Xem6310,
    /// [`Xem6310TopOnChip`]: the delay line in block RAM, the DDR2 parked.
    Xem6310OnChip,
}

/// The objectives the gateware is generated for.
pub const OBJECTIVES: [u32; 2] = [150, 60];

/// The bit-plane presets the gateware is generated for.
pub const PRESETS: [PresetName; 2] = [PresetName::Spcimager, PresetName::SpcimagerProjected];

/// The XEM6310 constraints (pins and I/O standards of every top port, the
/// 9.92 ns host-interface clock).
pub const XEM6310_UCF: &str = include_str!("../../constraints/xem6310.ucf");

/// One generated design: a preset at an objective.
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// The camera preset.
    pub preset: PresetName,
    /// Objective magnification.
    pub objective: u32,
    /// The device it is built for.
    pub device: Device,
    /// Where the delay line lives.
    pub delay_line: DelayLineKind,
    /// The top module of the Verilog.
    pub top: TopKind,
    /// The model's window N (the N register's default).
    pub n_window: u32,
    /// The field design's open level T_open (the T_int register's default).
    pub threshold_int: u64,
    /// The field design's hold level T_hold (the T_hold register's default,
    /// ≤ `threshold_int`).
    pub threshold_hold: u64,
    /// The field design's end trim (the END_TRIM register's default,
    /// ≤ `n_window − 1`).
    pub end_trim: u32,
    /// The generation parameters (sensor, P, N_max, kernel, M, R, …).
    pub config: BackHalfConfig,
}

/// Pixels per clock of every design: 4,800 words per 320×240 plane, 47.6 %
/// of the 100.8 MHz clock at 10,000 planes/s.
pub const PIXELS_PER_CLOCK: usize = 16;

/// N_max of the DDR2 designs.
pub const DDR2_N_MAX: u32 = 128;

/// Tracking slots M of every design (the model's default).
pub const SLOTS: usize = 32;

/// N_max of a block-RAM delay line for a window of `n_window` planes: N
/// rounded up to a multiple of 8 (a whole byte of planes per pixel address).
pub fn block_ram_n_max(n_window: u32) -> u32 {
    n_window.div_ceil(8) * 8
}

/// Largest L_max register value (6.5 s of planes).
pub const L_MAX_MAX: u32 = 65_535;

impl Design {
    /// The design of a preset at an objective; an error names an unsupported
    /// preset or objective, or a configuration the gateware cannot carry.
    pub fn new(preset: PresetName, objective: u32) -> Result<Design, GatewareError> {
        let unsupported = |why: String| GatewareError::Invalid {
            field: "preset",
            value: format!("{preset} at {objective}x"),
            why,
        };
        if !PRESETS.contains(&preset) {
            return Err(unsupported(format!(
                "the gateware aggregates bit-planes: use one of {}",
                PRESETS.map(|p| p.as_str()).join(", ")
            )));
        }
        let p = Preset::new(preset, objective).map_err(|e| unsupported(e.to_string()))?;
        let inputs =
            DetectionInputs::from_preset(&p, None).map_err(|e| unsupported(e.to_string()))?;
        let det = stats::derive(&inputs).map_err(|e| unsupported(e.to_string()))?;
        let (width, height) = p.camera.size();
        let device = device_for(preset);
        let plane_bits = width as u64 * height as u64;
        let n_bram = block_ram_n_max(det.n_window);
        let (delay_line, n_max, top) = if 2 * n_bram as u64 * plane_bits <= device.block_ram_bits()
        {
            (DelayLineKind::BlockRam, n_bram, TopKind::Xem6310OnChip)
        } else {
            (
                DelayLineKind::Ddr2,
                DDR2_N_MAX.max(det.n_window),
                TopKind::Xem6310,
            )
        };
        let front = GatewareConfig {
            width: width as usize,
            height: height as usize,
            pixels_per_clock: PIXELS_PER_CLOCK,
            n_max,
            kernel: det.kernel_weights.clone(),
            kernel_shift: det.kernel_shift,
            // Every DSP slice of the device is the filter's: nothing else
            // multiplies.
            dsp_multipliers: device.dsp48a1 as usize,
            sized_for: None,
        };
        let fd = field_design::design(
            &det,
            width,
            height,
            1.0 / p.period_s(),
            field_design::DEFAULT_FALSE_BLINKS_PER_S,
        )
        .map_err(|e| unsupported(e.to_string()))?;
        let mut cfg = smartagg_model::config::PipelineConfig::new(
            front.width,
            front.height,
            det.n_window,
            front.kernel.clone(),
            front.kernel_shift,
            u32::try_from(fd.threshold_open).unwrap_or(u32::MAX),
        );
        cfg.threshold_hold = u32::try_from(fd.threshold_hold).unwrap_or(u32::MAX);
        cfg.end_trim = fd.end_trim;
        cfg.slots = SLOTS;
        cfg.roi_size = front.kernel.len();
        cfg.r_assoc = fd.r_assoc;
        cfg.validate().map_err(|e| unsupported(e.to_string()))?;
        let config = BackHalfConfig::new(&cfg, front, L_MAX_MAX)?;
        Ok(Design {
            preset,
            objective,
            device,
            delay_line,
            top,
            n_window: det.n_window,
            threshold_int: fd.threshold_open,
            threshold_hold: fd.threshold_hold,
            end_trim: fd.end_trim,
            config,
        })
    }

    /// Every design: each bit-plane preset at each objective.
    pub fn all() -> Result<Vec<Design>, GatewareError> {
        PRESETS
            .iter()
            .flat_map(|&p| OBJECTIVES.iter().map(move |&o| Design::new(p, o)))
            .collect()
    }

    /// A short name, e.g. `spcimager-150x`.
    pub fn name(&self) -> String {
        format!("{}-{}x", self.preset, self.objective)
    }

    /// The Verilog of the design (top module `top`): the file that
    /// `smartagg hdl generate` writes, yosys synthesises and Verilator lints.
    pub fn verilog(&self) -> Result<String, GatewareError> {
        on_generation_stack(|| self.verilog_here())
    }

    fn verilog_here(&self) -> Result<String, GatewareError> {
        let c = &self.config;
        let k = c.front.kernel.len();
        Ok(match (self.delay_line, k) {
            (DelayLineKind::Ddr2, 9) => verilog(Spcimager150Xem::new(c)?),
            (DelayLineKind::Ddr2, 5) => verilog(Spcimager60Xem::new(c)?),
            (DelayLineKind::BlockRam, 9) => verilog(Projected150Xem::new(c)?),
            (DelayLineKind::BlockRam, 5) => verilog(Projected60Xem::new(c)?),
            _ => {
                return Err(GatewareError::Invalid {
                    field: "kernel",
                    value: format!("{:?}", c.front.kernel),
                    why: format!("no generated type for {k} taps with this delay line"),
                })
            }
        })
    }

    /// The constraints of the top: the XEM6310 UCF (both tops have its pins).
    pub fn ucf(&self) -> &'static str {
        XEM6310_UCF
    }

    /// The throughput arithmetic of the design at the sensor's 10,000
    /// planes/s on the 100.8 MHz host-interface clock.
    pub fn throughput(&self) -> Throughput {
        let f = &self.config.front;
        let words_per_plane = f.words_per_plane();
        let planes_per_s = 10_000.0;
        let clock_hz = CLOCK_HZ;
        Throughput {
            pixels_per_clock: f.pixels_per_clock,
            clock_hz,
            words_per_plane,
            planes_per_s,
            busy_fraction: words_per_plane as f64 * planes_per_s / clock_hz,
            refresh_fraction: match self.delay_line {
                DelayLineKind::Ddr2 => DDR2_T_RFC_NS / DDR2_T_REFI_NS,
                DelayLineKind::BlockRam => 0.0,
            },
        }
    }

    /// Bits of memory the delay line needs (N_max whole bit-planes).
    pub fn delay_line_bits(&self) -> u64 {
        self.config.front.delay_line_bits()
    }
}

/// Stack of the thread that builds and generates a design, bytes.
pub const GENERATION_STACK: usize = 256 << 20;

/// Runs `f` on a thread of its own with a [`GENERATION_STACK`]-byte stack
/// and returns its result. A whole top is a value of about 200 KB that is
/// moved several times while its blocks are built, and its generation
/// recurses through every block: more than a test thread's 2 MiB holds,
/// whatever thread the caller is on. (Only the pages used are committed.)
pub fn on_generation_stack<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    std::thread::scope(|s| {
        let h = std::thread::Builder::new()
            .name("hdl-generation".into())
            .stack_size(GENERATION_STACK)
            .spawn_scoped(s, f)
            .expect("the system refused a thread for the design's generation");
        match h.join() {
            Ok(v) => v,
            Err(e) => std::panic::resume_unwind(e),
        }
    })
}

/// Declares a design's XEM6310 top, its core (the top without the
/// FrontPanel host interface and the DDR2 pins: what the co-simulation
/// drives) and its pipeline (the core without the endpoints) from one
/// parameter list, so the three cannot differ. Parameters: those of
/// [`PipelineDdr`] (DDR2 designs: P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW,
/// CAW2, BW, QAW, QW, PW, TW, TAW, OAW) or of [`Pipeline`] (block-RAM
/// designs: DAW in place of PAW). Each type's `new` checks them against
/// the configuration.
macro_rules! design_types {
    (
        $(#[$doc:meta])*
        $top:ident = $Top:ident,
        $core:ident = $Core:ident,
        $pipe:ident = $Pipe:ident,
        [$($p:literal),*]
    ) => {
        $(#[$doc])*
        pub type $top = $Top<$($p),*>;
        $(#[$doc])*
        ///
        /// The core: the top's logic without the host interface and the DDR2 pins.
        pub type $core = $Core<$($p),*>;
        $(#[$doc])*
        ///
        /// The pipeline: the core's stream logic without its endpoints.
        pub type $pipe = $Pipe<$($p),*>;
    };
}

design_types!(
    /// The XEM6310 top of the SPCImager at 150× (k = 9, N_max = 128, DDR2).
    Spcimager150Xem = Xem6310Top,
    Spcimager150Core = XemCore,
    Spcimager150Pipeline = PipelineDdr,
    [16, 9, 8, 13, 16, 24, 5, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12]
);

design_types!(
    /// The XEM6310 top of the SPCImager at 60× (k = 5, N_max = 128, DDR2).
    Spcimager60Xem = Xem6310Top,
    Spcimager60Core = XemCore,
    Spcimager60Pipeline = PipelineDdr,
    [16, 9, 8, 13, 16, 24, 5, 8, 17, 9, 7, 6, 233, 488, 53, 9, 12]
);

design_types!(
    /// The XEM6310 top of the projected SPCImager at 150× (k = 9, N_max =
    /// 24, block RAM; for the XEM6310-LX150).
    Projected150Xem = Xem6310TopOnChip,
    Projected150Core = XemCoreOnChip,
    Projected150Pipeline = Pipeline,
    [16, 17, 5, 13, 13, 21, 5, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12]
);

design_types!(
    /// The XEM6310 top of the projected SPCImager at 60× (k = 5, N_max =
    /// 24, block RAM; for the XEM6310-LX150).
    Projected60Xem = Xem6310TopOnChip,
    Projected60Core = XemCoreOnChip,
    Projected60Pipeline = Pipeline,
    [16, 17, 5, 13, 13, 21, 5, 8, 17, 9, 7, 6, 233, 488, 53, 9, 12]
);

design_types!(
    /// The small test configuration's design with the DDR2 delay line
    /// ([`crate::pipeline::test_back_config`]`(4, 3, 1)`, a prefetch of 64
    /// words): for the tests and the lint.
    TestXem = Xem6310Top,
    TestXemCore = XemCore,
    TestPipelineDdr = PipelineDdr,
    [4, 6, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11]
);

design_types!(
    /// The small test configuration's design with the block-RAM delay line
    /// ([`crate::pipeline::test_back_config`]`(4, 3, 1)`).
    TestXemOnChip = Xem6310TopOnChip,
    TestXemCoreOnChip = XemCoreOnChip,
    TestPipeline = Pipeline,
    [4, 8, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11]
);

/// The core clock: FrontPanel's host-interface clock `okClk`, Hz.
pub const CLOCK_HZ: f64 = 100.8e6;

/// DDR2 refresh interval tREFI (MT47H64M16, 0–85 °C), ns.
pub const DDR2_T_REFI_NS: f64 = 7_800.0;

/// DDR2 refresh cycle time tRFC of a 1-Gbit device, ns.
pub const DDR2_T_RFC_NS: f64 = 127.5;

/// Throughput arithmetic of a design (see [`Design::throughput`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Throughput {
    /// Pixels per clock P.
    pub pixels_per_clock: usize,
    /// Core clock, Hz.
    pub clock_hz: f64,
    /// Stream words per bit-plane (W·H/P): the pipeline's cycles per plane,
    /// as it takes one word per clock and never inserts a bubble.
    pub words_per_plane: usize,
    /// The sensor's plane rate, planes/s.
    pub planes_per_s: f64,
    /// Fraction of the clocks that carry a word at that rate.
    pub busy_fraction: f64,
    /// Fraction of the time the DDR2 is refreshing (tRFC/tREFI; 0 for a
    /// block-RAM delay line), counted as lost clocks though the prefetch
    /// FIFO hides most of it.
    pub refresh_fraction: f64,
}

impl Throughput {
    /// Spare fraction of the clocks after the stream and the refresh.
    pub fn headroom(&self) -> f64 {
        1.0 - self.busy_fraction - self.refresh_fraction
    }
}

/// A CRC-64/XZ of a text, as 16 hex digits: the identity of a generated
/// Verilog file (which file yosys, Verilator and ISE were given), not a
/// cryptographic digest.
pub fn text_hash(text: &str) -> String {
    let crc = crc::Crc::<u64>::new(&crc::CRC_64_XZ);
    format!("{:016x}", crc.checksum(text.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::{XC6SLX150, XC6SLX45};

    #[test]
    fn configurations_follow_the_model() {
        let d = Design::new(PresetName::Spcimager, 150).unwrap();
        assert_eq!(d.delay_line, DelayLineKind::Ddr2);
        assert_eq!(d.device, XC6SLX45);
        assert!(d.n_window <= d.config.front.n_max);
        assert_eq!(d.config.front.kernel.len(), 9);
        assert_eq!(d.config.roi_size, 9);
        let d = Design::new(PresetName::Spcimager, 60).unwrap();
        assert_eq!(d.delay_line, DelayLineKind::Ddr2);
        assert_eq!(d.config.front.kernel.len(), 5);
        let d = Design::new(PresetName::SpcimagerProjected, 150).unwrap();
        assert_eq!(d.delay_line, DelayLineKind::BlockRam);
        assert_eq!(d.device, XC6SLX150);
        assert_eq!(d.config.front.n_max, 24);
        assert_eq!(d.top, TopKind::Xem6310OnChip);
        assert!(Design::new(PresetName::Emccd, 150).is_err());
        assert!(Design::new(PresetName::Spcimager, 100).is_err());
    }
}
