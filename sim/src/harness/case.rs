//! A co-simulation case (runtime registers, planes, host behaviour) and
//! what it means on a design: the model's configuration, the registers the
//! host writes, a threshold placed at a quantile of the model's H.

use super::HarnessError;
use crate::designs::DesignSpec;
use smartagg_model::config::PipelineConfig;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::plane::BitPlane;
use smartagg_model::registers::StreamRegisters;
use std::collections::BTreeMap;

/// Where the planes enter the design.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The replay pipe-in (hardware-in-the-loop path).
    Replay,
    /// The sensor port's FIFO (DDR2 configurations).
    Sensor,
}

/// One co-simulation case: runtime registers, planes, host behaviour.
#[derive(Debug, Clone)]
pub struct Case {
    /// Rolling window N.
    pub n: u32,
    /// Threshold T_int (the open level of candidates).
    pub threshold: u32,
    /// Threshold T_hold (the hold level of live tracks, 1 ..= T_int);
    /// `None`: T_hold = T_int (the one-threshold rule), whatever T_int is
    /// set to later.
    pub threshold_hold: Option<u32>,
    /// END_TRIM (0 ..= N − 1): a dropped segment sums up to
    /// `t_drop − end_trim` (0: the paper's rule).
    pub end_trim: u32,
    /// L_min.
    pub l_min: u32,
    /// L_max.
    pub l_max: u32,
    /// The bit-planes.
    pub planes: Vec<BitPlane>,
    /// Hot pixels of the mask (loaded through pipe-in 0x81 and applied if
    /// `mask_enable`, as the host sends a mask: [`StreamRegisters`]).
    pub hot: Vec<(usize, usize)>,
    /// MASK_ENABLE.
    pub mask_enable: bool,
    /// Input path.
    pub source: Source,
    /// Percent of host opportunities skipped on the input side.
    pub input_stall: u32,
    /// Percent of host opportunities skipped on the output side.
    pub read_stall: u32,
    /// The host reads nothing until every plane has gone in (forces overflow).
    pub hold_reads: bool,
    /// Seed of the host stalls.
    pub seed: u64,
}

impl Case {
    /// The bit-planes replayed through the pipe-in with these registers
    /// (T_hold = T_int, END_TRIM 0: the paper's rules): no hot-pixel mask,
    /// no host stalls on either side (stall seed 1). Other cases change
    /// fields from this one (`Case { .., ..Case::replay(..) }`).
    pub fn replay(n: u32, threshold: u32, l_min: u32, l_max: u32, planes: Vec<BitPlane>) -> Case {
        Case {
            n,
            threshold,
            threshold_hold: None,
            end_trim: 0,
            l_min,
            l_max,
            planes,
            hot: Vec::new(),
            mask_enable: false,
            source: Source::Replay,
            input_stall: 0,
            read_stall: 0,
            hold_reads: false,
            seed: 1,
        }
    }

    /// The bit-planes replayed with a shipped design's register defaults,
    /// the field design's ([`smartagg_hdl::designs::Design`]): its N, the
    /// open level T_open as T_int, the hold level T_hold, its END_TRIM
    /// (⌊N/2⌋), L_min = 1 and
    /// L_max = 10,000 (the model's default). The design's r_assoc is a
    /// generation parameter: pass it to [`crate::designs::DesignSpec::with_r_assoc`].
    pub fn design_defaults(design: &smartagg_hdl::designs::Design, planes: Vec<BitPlane>) -> Case {
        let t = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        Case {
            threshold_hold: Some(t(design.threshold_hold)),
            end_trim: design.end_trim,
            ..Case::replay(
                design.n_window,
                t(design.threshold_int),
                1,
                smartagg_model::config::DEFAULT_L_MAX.max(design.n_window),
                planes,
            )
        }
    }

    /// The T_hold register: [`Case::threshold_hold`], or T_int.
    pub fn hold(&self) -> u32 {
        self.threshold_hold.unwrap_or(self.threshold)
    }
}

/// Plane period written to the register (ns).
pub const PLANE_PERIOD_NS: u32 = 100_000;

/// The model configuration of a case on a design: the design's kernel,
/// slots, ROI side and r_assoc, the case's registers and hot-pixel mask.
pub fn model_config(spec: &DesignSpec, case: &Case) -> Result<PipelineConfig, HarnessError> {
    let back = spec.back()?;
    let f = &back.front;
    let mut cfg = PipelineConfig::new(
        f.width,
        f.height,
        case.n,
        f.kernel.clone(),
        f.kernel_shift,
        case.threshold,
    );
    cfg.threshold_hold = case.hold();
    cfg.end_trim = case.end_trim;
    cfg.slots = back.slots;
    cfg.roi_size = back.roi_size;
    cfg.r_assoc = back.r_assoc;
    cfg.l_min = case.l_min;
    cfg.l_max = case.l_max;
    cfg.plane_period_ns = PLANE_PERIOD_NS;
    if case.mask_enable {
        cfg.hot_mask = Some(HotPixelMask::from_pixels(f.width, f.height, &case.hot).0);
    }
    cfg.validate()
        .map_err(|e| HarnessError::Model(e.to_string()))?;
    Ok(cfg)
}

/// The registers the host writes for a case on a design
/// ([`StreamRegisters::of`] of [`model_config`], the host's own code),
/// planes from the replay pipe-in or the sensor port as the case says.
pub fn stream_registers(spec: &DesignSpec, case: &Case) -> Result<StreamRegisters, HarnessError> {
    Ok(StreamRegisters {
        source_replay: case.source == Source::Replay,
        ..StreamRegisters::of(&model_config(spec, case)?)
    })
}

/// A threshold T_int at quantile `q` (0..1) of the model's H over the
/// planes (ignoring zeros): the cases' way to put the threshold where some
/// but few pixels cross it, whatever the scene's density.
pub fn threshold_at_quantile(cfg: &PipelineConfig, planes: &[BitPlane], q: f64) -> u32 {
    let Ok(mut p) = smartagg_model::pipeline::Pipeline::new(cfg.clone()) else {
        return 1;
    };
    let mut hist: BTreeMap<u32, u64> = BTreeMap::new();
    let mut total = 0u64;
    for pl in planes {
        if p.push_plane(pl).is_err() {
            break;
        }
        for &h in p.filtered() {
            if h > 0 {
                *hist.entry(h).or_default() += 1;
                total += 1;
            }
        }
    }
    let target = (total as f64 * q.clamp(0.0, 1.0)) as u64;
    let mut acc = 0;
    for (&h, &n) in &hist {
        acc += n;
        if acc > target {
            return h.max(1);
        }
    }
    hist.keys().next_back().copied().unwrap_or(1).max(1)
}
