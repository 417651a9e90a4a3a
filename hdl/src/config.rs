//! Generation configuration: the model's [`PipelineConfig`] plus the pixels
//! per clock P and the largest window N_max the gateware is built for.
//!
//! rust-hdl widths are compile-time constants, so one configuration is one
//! set of const generics on the blocks. [`GatewareConfig`] computes the widths
//! a configuration needs, and every block's `new` checks that its type
//! parameters match them ([`GatewareConfig::check_width`]), so a mismatched
//! type alias is a clear error and never a silent overflow.
//!
//! Widths follow from the bounds of [`PipelineConfig`]:
//! * count bits `CW = ⌈log2(N_max + 1)⌉`: `0 ≤ S ≤ N ≤ N_max`;
//! * vertical-pass bits `VW = CW + a`: `V ≤ N_max·2^a` (k1 sums to `2^a`);
//! * filtered bits `HW = CW + 2a`: `H ≤ N_max·2^(2a)`.
//!
//! N, T_int and T_hold are runtime registers (latched by the top at stream start);
//! the kernel weights are constants of the generated circuit.
//!
//! The back half's parameters and widths (M, R, the record queue, the
//! banks, the counters and the packet prefix) are [`BackHalfConfig`], in
//! `config/back_half.rs`.

use smartagg_model::config::{ConfigError, PipelineConfig};
use thiserror::Error;

mod back_half;

pub use back_half::BackHalfConfig;

/// The most tracking slots M the blink tracker holds: each per-slot flag is
/// one register of `MAX_SLOTS` bits (see "Registers" in
/// [`crate::blink_tracker`]'s module doc).
pub const MAX_SLOTS: usize = 32;

/// A configuration the gateware cannot be generated for; names what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum GatewareError {
    /// The model configuration itself is invalid.
    #[error(transparent)]
    Model(#[from] ConfigError),
    /// A generation parameter outside what the gateware supports.
    #[error("gateware configuration: `{field}` = {value}: {why}")]
    Invalid {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: String,
        /// The rule it breaks.
        why: String,
    },
    /// A block's const generic does not match the configuration.
    #[error(
        "block `{block}`: type parameter {param} is {has} but the configuration needs {needs}"
    )]
    Width {
        /// Block name.
        block: &'static str,
        /// Parameter name.
        param: &'static str,
        /// Value in the type.
        has: usize,
        /// Value the configuration needs.
        needs: usize,
    },
}

fn invalid(field: &'static str, value: impl ToString, why: impl ToString) -> GatewareError {
    GatewareError::Invalid {
        field,
        value: value.to_string(),
        why: why.to_string(),
    }
}

/// Bits needed to hold every value `0..=max`.
pub fn bits_for(max: u64) -> usize {
    (64 - max.leading_zeros() as usize).max(1)
}

/// Everything the generated front half depends on at generation time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GatewareConfig {
    /// Sensor width, pixels (a multiple of P, at least 2P).
    pub width: usize,
    /// Sensor height, pixels (more than the kernel half-width, at least 2).
    pub height: usize,
    /// Pixels per clock P.
    pub pixels_per_clock: usize,
    /// Largest rolling window N the circuit supports (runtime N ≤ N_max).
    pub n_max: u32,
    /// 1-D integer kernel k1 (constants of the circuit).
    pub kernel: Vec<u32>,
    /// a: k1 sums to 2^a.
    pub kernel_shift: u8,
    /// How many of the spatial filter's constant multiplies go to DSP48A1
    /// slices (the costliest in LUTs first, see
    /// [`crate::spatial_filter::SpatialFilter`]); the rest are shift-and-add
    /// in LUTs. At most the device's slices; 0 for none.
    pub dsp_multipliers: usize,
    /// The largest field the memories' address widths are sized for
    /// (`None`: exactly this field). Every memory and counter is bounded by
    /// this field's own constants, never by a width, so a design sized for
    /// its sensor's whole field runs any smaller window of it (the
    /// co-simulation runs the shipped designs on smaller fields this way).
    pub sized_for: Option<(usize, usize)>,
}

impl GatewareConfig {
    /// The gateware configuration for a model configuration, P and N_max.
    pub fn new(
        cfg: &PipelineConfig,
        pixels_per_clock: usize,
        n_max: u32,
    ) -> Result<GatewareConfig, GatewareError> {
        cfg.validate()?;
        let g = GatewareConfig {
            width: cfg.width,
            height: cfg.height,
            pixels_per_clock,
            n_max,
            kernel: cfg.kernel.clone(),
            kernel_shift: cfg.kernel_shift,
            dsp_multipliers: 0,
            sized_for: None,
        };
        g.validate()?;
        if cfg.n_window > n_max {
            return Err(invalid(
                "n_window",
                cfg.n_window,
                format!("must not exceed the generated N_max = {n_max}"),
            ));
        }
        Ok(g)
    }

    /// Checks the generation parameters.
    pub fn validate(&self) -> Result<(), GatewareError> {
        let p = self.pixels_per_clock;
        if p == 0 || p > 64 {
            return Err(invalid("pixels_per_clock", p, "must be 1..=64"));
        }
        if !self.width.is_multiple_of(p) || self.width < 2 * p {
            return Err(invalid(
                "width",
                self.width,
                format!("must be a multiple of P = {p} and at least 2P (two words per row)"),
            ));
        }
        if self.width > 65535 || self.height > 65535 {
            return Err(invalid(
                "width/height",
                format!("{}x{}", self.width, self.height),
                "must fit 16 bits",
            ));
        }
        if let Some((w, h)) = self.sized_for {
            if w < self.width || h < self.height || !w.is_multiple_of(p) {
                return Err(invalid(
                    "sized_for",
                    format!("{w}x{h}"),
                    format!(
                        "must be at least the field {}x{} (width a multiple of P = {p})",
                        self.width, self.height
                    ),
                ));
            }
        }
        if self.kernel.is_empty() || self.kernel.len().is_multiple_of(2) {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                "length must be odd",
            ));
        }
        if self.half() > p {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                format!(
                    "half-width {} must not exceed P = {p} (context of one word each side)",
                    self.half()
                ),
            ));
        }
        if self.height < 2 || self.height <= self.half() {
            return Err(invalid(
                "height",
                self.height,
                format!(
                    "must be at least 2 and more than the kernel half-width {}",
                    self.half()
                ),
            ));
        }
        if self.n_max == 0 || self.n_max > 65535 {
            return Err(invalid("n_max", self.n_max, "must be 1..=65535"));
        }
        let sum: u64 = self.kernel.iter().map(|&w| w as u64).sum();
        if !(1..=12).contains(&self.kernel_shift) || sum != 1u64 << self.kernel_shift {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                format!("must sum to 2^a with a = {} in 1..=12", self.kernel_shift),
            ));
        }
        let k = self.kernel.len();
        if (0..k).any(|i| self.kernel[i] != self.kernel[k - 1 - i]) {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                "must be symmetric",
            ));
        }
        if self.filtered_bits() > 64 {
            return Err(invalid(
                "n_max",
                self.n_max,
                "H would need more than 64 bits",
            ));
        }
        Ok(())
    }

    /// Kernel half-width c = (k − 1)/2.
    pub fn half(&self) -> usize {
        self.kernel.len() / 2
    }

    /// Words (of P pixels) per row.
    pub fn words_per_row(&self) -> usize {
        self.width / self.pixels_per_clock
    }

    /// Words per bit-plane.
    pub fn words_per_plane(&self) -> usize {
        self.words_per_row() * self.height
    }

    /// CW: bits of a rolling count S (and of the runtime N register).
    pub fn count_bits(&self) -> usize {
        bits_for(self.n_max as u64)
    }

    /// VW: bits of the vertical-pass result `V ≤ N_max·2^a`.
    pub fn vertical_bits(&self) -> usize {
        self.count_bits() + self.kernel_shift as usize
    }

    /// HW: bits of `H ≤ N_max·2^(2a)` (and of the T_int register).
    pub fn filtered_bits(&self) -> usize {
        self.count_bits() + 2 * self.kernel_shift as usize
    }

    /// The field the address widths are sized for: [`GatewareConfig::sized_for`]
    /// or this field.
    pub fn address_field(&self) -> (usize, usize) {
        self.sized_for.unwrap_or((self.width, self.height))
    }

    /// Words per row and per plane of [`GatewareConfig::address_field`].
    fn address_words(&self) -> (u64, u64) {
        let (w, h) = self.address_field();
        let row = (w / self.pixels_per_clock) as u64;
        (row, row * h as u64)
    }

    /// Address bits of the counter memory (one word per P pixels).
    pub fn count_addr_bits(&self) -> usize {
        bits_for(self.address_words().1 - 1)
    }

    /// Address bits of a line buffer (one word per P pixels of a row).
    pub fn line_addr_bits(&self) -> usize {
        bits_for(self.address_words().0 - 1)
    }

    /// Address bits of the block-RAM delay line: N_max planes.
    pub fn delay_addr_bits(&self) -> usize {
        bits_for(self.n_max as u64 * self.address_words().1 - 1)
    }

    /// Bits of block RAM the delay line needs: N_max whole bit-planes.
    pub fn delay_line_bits(&self) -> u64 {
        self.n_max as u64 * (self.width * self.height) as u64
    }

    /// The T_int register value: T_int clamped to the largest HW-bit value.
    /// Clamping never changes a decision: `H ≤ N_max·2^(2a) < 2^HW − 1`.
    pub fn threshold_register(&self, threshold_int: u32) -> u64 {
        let max = if self.filtered_bits() >= 64 {
            u64::MAX
        } else {
            (1u64 << self.filtered_bits()) - 1
        };
        (threshold_int as u64).min(max)
    }

    /// Errors unless a block's type parameter `param = has` equals `needs`.
    pub fn check_width(
        block: &'static str,
        param: &'static str,
        has: usize,
        needs: usize,
    ) -> Result<(), GatewareError> {
        if has == needs {
            Ok(())
        } else {
            Err(GatewareError::Width {
                block,
                param,
                has,
                needs,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_follow_the_bounds() {
        let cfg = PipelineConfig::new(
            320,
            240,
            108,
            vec![1, 6, 28, 58, 70, 58, 28, 6, 1],
            8,
            40000,
        );
        let g = GatewareConfig::new(&cfg, 16, 128).unwrap();
        assert_eq!(g.count_bits(), 8); // 128 needs 8 bits
        assert_eq!(g.vertical_bits(), 16);
        assert_eq!(g.filtered_bits(), 24);
        assert_eq!(g.words_per_plane(), 4800);
        assert_eq!(g.count_addr_bits(), 13);
        assert_eq!(g.line_addr_bits(), 5);
        assert_eq!(bits_for(127), 7);
        assert_eq!(bits_for(0), 1);
    }

    #[test]
    fn a_design_sized_for_a_larger_field_keeps_that_fields_address_widths() {
        let cfg = PipelineConfig::new(96, 72, 20, vec![1, 2, 1], 2, 3);
        let exact = GatewareConfig::new(&cfg, 16, 24).unwrap();
        assert_eq!(
            (exact.count_addr_bits(), exact.line_addr_bits()),
            (9, 3) // 432 words, 6 per row
        );
        let sized = GatewareConfig {
            sized_for: Some((320, 240)),
            ..exact.clone()
        };
        sized.validate().unwrap();
        assert_eq!(sized.words_per_plane(), 432);
        assert_eq!(
            (
                sized.count_addr_bits(),
                sized.line_addr_bits(),
                sized.delay_addr_bits()
            ),
            (13, 5, 17) // 4,800 words, 20 per row, 24 planes
        );
        for bad in [(80, 240), (320, 64), (328, 240)] {
            let e = GatewareConfig {
                sized_for: Some(bad),
                ..exact.clone()
            }
            .validate()
            .unwrap_err()
            .to_string();
            assert!(e.contains("`sized_for`"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let cfg = PipelineConfig::new(20, 8, 4, vec![1, 2, 1], 2, 3);
        let e = GatewareConfig::new(&cfg, 8, 8).unwrap_err().to_string();
        assert!(e.contains("`width`"), "{e}");
        let e = GatewareConfig::new(&cfg, 4, 3).unwrap_err().to_string();
        assert!(e.contains("`n_window`"), "{e}");
        let cfg = PipelineConfig::new(16, 8, 4, vec![1, 2, 10, 2, 1], 4, 3);
        let e = GatewareConfig::new(&cfg, 1, 8).unwrap_err().to_string();
        assert!(e.contains("half-width"), "{e}");
    }
}
