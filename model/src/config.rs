//! Pipeline configuration: the generation parameters (sizes, kernel, slot
//! count, ROI size) and the runtime registers (N, T_int, L_min, L_max, mask)
//! that the gateware latches at stream start.

use crate::hot_pixel_mask::HotPixelMask;
use crate::record::StreamStart;
use thiserror::Error;

/// A configuration the pipeline cannot run with; the message names the field.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ConfigError {
    /// A field outside its allowed range.
    #[error("invalid pipeline configuration: `{field}` = {value}: {why}")]
    Invalid {
        /// Field name.
        field: &'static str,
        /// Offending value, as text.
        value: String,
        /// The rule it breaks.
        why: String,
    },
}

fn invalid(field: &'static str, value: impl ToString, why: impl ToString) -> ConfigError {
    ConfigError::Invalid {
        field,
        value: value.to_string(),
        why: why.to_string(),
    }
}

/// Everything the streaming pipeline needs.
///
/// Finite resources are explicit: `slots` (M), `roi_size` (R), `l_max`; the
/// pipeline never overflows a counter because [`PipelineConfig::validate`]
/// bounds every value it can reach (see the `max_*` methods).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PipelineConfig {
    /// Sensor width, pixels (1..=65535).
    pub width: usize,
    /// Sensor height, pixels (1..=65535).
    pub height: usize,
    /// Rolling window N, bit-planes (≥ 1).
    pub n_window: u32,
    /// 1-D integer kernel k1: odd length, symmetric, sums to `2^kernel_shift`.
    pub kernel: Vec<u32>,
    /// a: the 1-D kernel sums to 2^a, the 2-D kernel K = k1⊗k1 to 2^(2a).
    pub kernel_shift: u8,
    /// Integer threshold on H = K ⊛ S (≥ 1) that **opens** a track: a
    /// candidate is a 3×3 maximum with `H ≥ T_int`.
    pub threshold_int: u32,
    /// Integer threshold that **holds** a track on (hysteresis): an open
    /// track stays on while the 3×3 maximum of H around its anchor is
    /// `≥ T_hold`. `1 ≤ T_hold ≤ T_int`; `T_hold = T_int` is the paper's
    /// single-threshold rule.
    pub threshold_hold: u32,
    /// Planes between a dropped segment's last summed plane and its `t_drop`
    /// (`0 ≤ end_trim ≤ N − 1`): a segment that ends by a drop sums the
    /// bit-planes `[t_cross − N, t_drop − end_trim]`. 0 is the paper's rule
    /// (sum to `t_drop` = `t_e + N/2`); `⌊N/2⌋` sums to the estimated end of
    /// the blink `t_e`, leaving out the planes the window took to fall
    /// below the hold level (PACKETS.md §8.6).
    pub end_trim: u32,
    /// Planes a track must stay on to be confirmed (≥ 1).
    pub l_min: u32,
    /// Planes after which an on track is cut into a new segment (≥ max(L_min, N)).
    pub l_max: u32,
    /// Chebyshev distance within which a candidate belongs to an active track.
    pub r_assoc: u32,
    /// Number of tracking slots M (1..=255).
    pub slots: usize,
    /// ROI side R: odd, 1..=31.
    pub roi_size: usize,
    /// Bit-plane period, ns (carried in the stream start record).
    pub plane_period_ns: u32,
    /// Hot pixels that read 0 everywhere downstream, if the scene has any.
    pub hot_mask: Option<HotPixelMask>,
}

/// Default number of tracking slots M.
pub const DEFAULT_SLOTS: usize = 32;
/// Most pixels a pipeline's sensor may have (4096 × 4096): the engines keep
/// per-pixel state (the delay line alone holds N bits per pixel), so a
/// configuration above it is refused before anything is allocated.
pub const MAX_SENSOR_PIXELS: u64 = 1 << 24;
/// Default L_max: 10,000 planes (one second at 10 kHz).
pub const DEFAULT_L_MAX: u32 = 10_000;

impl PipelineConfig {
    /// A configuration with the defaults for everything but the essentials:
    /// T_hold = T_int, end_trim 0 and L_min 1 (the paper's rule), L_max 10,000,
    /// r_assoc 1, 32 slots, ROI side = kernel size.
    pub fn new(
        width: usize,
        height: usize,
        n_window: u32,
        kernel: Vec<u32>,
        kernel_shift: u8,
        threshold_int: u32,
    ) -> PipelineConfig {
        let roi_size = kernel.len().clamp(1, 31) | 1;
        PipelineConfig {
            width,
            height,
            n_window,
            kernel,
            kernel_shift,
            threshold_int,
            threshold_hold: threshold_int,
            end_trim: 0,
            l_min: 1,
            l_max: DEFAULT_L_MAX.max(n_window),
            r_assoc: 1,
            slots: DEFAULT_SLOTS,
            roi_size,
            plane_period_ns: 100_000,
            hot_mask: None,
        }
    }

    /// Kernel size k.
    pub fn kernel_size(&self) -> usize {
        self.kernel.len()
    }

    /// Largest value the rolling count S can take: N.
    pub fn max_count(&self) -> u64 {
        self.n_window as u64
    }

    /// Largest value H = K ⊛ S can take: N · 2^(2a).
    pub fn max_filtered(&self) -> u64 {
        self.n_window as u64 * (1u64 << (2 * self.kernel_shift as u32))
    }

    /// A bound on the planes one ROI segment sums: the N planes before the
    /// crossing plus at most L_max + 1 live planes (a cut waits out a
    /// one-plane dip).
    pub fn max_planes_summed(&self) -> u64 {
        self.n_window as u64 + self.l_max as u64 + 1
    }

    /// Checks every field and every bound the pipeline relies on.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.width == 0 || self.width > 65535 {
            return Err(invalid("width", self.width, "must be 1..=65535 pixels"));
        }
        if self.height == 0 || self.height > 65535 {
            return Err(invalid("height", self.height, "must be 1..=65535 pixels"));
        }
        if self.width as u64 * self.height as u64 > MAX_SENSOR_PIXELS {
            return Err(invalid(
                "width",
                format!("{}x{}", self.width, self.height),
                format!(
                    "the sensor may have at most {MAX_SENSOR_PIXELS} pixels (4096x4096): the engines keep state for every pixel"
                ),
            ));
        }
        if self.n_window == 0 {
            return Err(invalid(
                "n_window",
                0,
                "the window must hold at least one bit-plane",
            ));
        }
        let k = self.kernel.len();
        if k == 0 || k.is_multiple_of(2) || k > 63 {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                "length must be odd, 1..=63",
            ));
        }
        if !(1..=12).contains(&self.kernel_shift) {
            return Err(invalid("kernel_shift", self.kernel_shift, "must be 1..=12"));
        }
        let sum: u64 = self.kernel.iter().map(|&w| w as u64).sum();
        if sum != 1u64 << self.kernel_shift {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                format!(
                    "weights must sum to exactly 2^{} = {}",
                    self.kernel_shift,
                    1u64 << self.kernel_shift
                ),
            ));
        }
        if (0..k).any(|i| self.kernel[i] != self.kernel[k - 1 - i]) {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                "weights must be symmetric",
            ));
        }
        if self.kernel.iter().any(|&w| w > u16::MAX as u32) {
            return Err(invalid(
                "kernel",
                format!("{:?}", self.kernel),
                "weights must fit 16 bits",
            ));
        }
        if self.max_filtered() > u32::MAX as u64 {
            return Err(invalid(
                "n_window",
                self.n_window,
                format!(
                    "N · 2^(2a) = {} must fit 32 bits (lower N or the kernel shift)",
                    self.max_filtered()
                ),
            ));
        }
        if self.threshold_int == 0 {
            return Err(invalid(
                "threshold_int",
                0,
                "must be at least 1 (H ≥ 0 fires everywhere)",
            ));
        }
        if self.threshold_hold == 0 || self.threshold_hold > self.threshold_int {
            return Err(invalid(
                "threshold_hold",
                self.threshold_hold,
                format!(
                    "the hold level must be 1..=T_int = {} (a track is held at or below the level that opens it)",
                    self.threshold_int
                ),
            ));
        }
        if self.end_trim >= self.n_window {
            return Err(invalid(
                "end_trim",
                self.end_trim,
                format!(
                    "must be 0..=N − 1 = {} (a dropped segment's last summed plane must be out of the window by the plane its drop is seen)",
                    self.n_window.saturating_sub(1)
                ),
            ));
        }
        if self.l_min == 0 {
            return Err(invalid(
                "l_min",
                0,
                "a track must stay on at least one plane",
            ));
        }
        if self.l_max < self.l_min.max(self.n_window) {
            return Err(invalid(
                "l_max",
                self.l_max,
                format!(
                    "must be at least max(L_min, N) = {}",
                    self.l_min.max(self.n_window)
                ),
            ));
        }
        if self.max_planes_summed() > u32::MAX as u64 {
            return Err(invalid(
                "l_max",
                self.l_max,
                "N + L_max + 1 must fit 32 bits",
            ));
        }
        if self.slots == 0 || self.slots > 255 {
            return Err(invalid("slots", self.slots, "must be 1..=255"));
        }
        if self.roi_size == 0 || self.roi_size.is_multiple_of(2) || self.roi_size > 31 {
            return Err(invalid("roi_size", self.roi_size, "must be odd, 1..=31"));
        }
        if self.r_assoc > 255 {
            return Err(invalid("r_assoc", self.r_assoc, "must be 0..=255"));
        }
        if let Some(mask) = &self.hot_mask {
            if mask.width() != self.width || mask.height() != self.height {
                return Err(invalid(
                    "hot_mask",
                    format!("{}x{}", mask.width(), mask.height()),
                    format!("must match the sensor {}x{}", self.width, self.height),
                ));
            }
        }
        Ok(())
    }

    /// The stream-start record that announces this configuration.
    pub fn stream_start(&self) -> StreamStart {
        StreamStart {
            width: self.width as u16,
            height: self.height as u16,
            n_window: self.n_window,
            threshold_int: self.threshold_int,
            threshold_hold: self.threshold_hold,
            end_trim: Some(self.end_trim),
            l_min: self.l_min,
            l_max: self.l_max,
            r_assoc: self.r_assoc as u8,
            slots: self.slots as u8,
            roi_size: self.roi_size as u8,
            kernel_shift: self.kernel_shift,
            kernel: self.kernel.iter().map(|&w| w as u16).collect(),
            plane_period_ns: self.plane_period_ns,
            masked_pixels: self.hot_mask.as_ref().map_or(0, |m| m.count() as u32),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> PipelineConfig {
        PipelineConfig::new(16, 12, 10, vec![1, 2, 1], 2, 20)
    }

    #[test]
    fn defaults_are_valid() {
        base().validate().unwrap();
    }

    #[test]
    fn every_bad_field_is_named() {
        type Mutation = Box<dyn Fn(&mut PipelineConfig)>;
        let cases: Vec<(&str, Mutation)> = vec![
            ("width", Box::new(|c| c.width = 0)),
            (
                "width",
                Box::new(|c| {
                    c.width = 65535;
                    c.height = 32768;
                }),
            ),
            ("n_window", Box::new(|c| c.n_window = 0)),
            ("kernel", Box::new(|c| c.kernel = vec![1, 3])),
            ("kernel", Box::new(|c| c.kernel = vec![1, 1, 1])),
            ("kernel", Box::new(|c| c.kernel = vec![2, 1, 1])),
            ("threshold_int", Box::new(|c| c.threshold_int = 0)),
            ("threshold_hold", Box::new(|c| c.threshold_hold = 0)),
            ("threshold_hold", Box::new(|c| c.threshold_hold = 21)),
            ("end_trim", Box::new(|c| c.end_trim = c.n_window)),
            ("l_min", Box::new(|c| c.l_min = 0)),
            ("l_max", Box::new(|c| c.l_max = 5)),
            ("slots", Box::new(|c| c.slots = 0)),
            ("roi_size", Box::new(|c| c.roi_size = 4)),
            (
                "hot_mask",
                Box::new(|c| c.hot_mask = Some(HotPixelMask::new(3, 3))),
            ),
            (
                "n_window",
                Box::new(|c| {
                    c.kernel = vec![0, 4096, 0];
                    c.kernel_shift = 12;
                    c.n_window = 1 << 10;
                    c.l_max = 1 << 10;
                }),
            ),
        ];
        for (field, mutate) in cases {
            let mut c = base();
            mutate(&mut c);
            let e = c.validate().unwrap_err().to_string();
            assert!(
                e.contains(&format!("`{field}`")),
                "expected {field} in: {e}"
            );
        }
    }
}
