//! `smartagg-calibration`: camera calibration from the camera's own
//! recordings (paper §2) — computing it, writing and reading the
//! calibration folder, and its human-readable report.
//!
//! What every SPAD user does first: measure each pixel's dark-count rate
//! (DCR), find the hot pixels, and measure the photon-response
//! non-uniformity (PRNU). Stage 0 of the pipeline (the hot-pixel mask) and
//! the SPAD likelihood's per-pixel maps use exactly these. The same
//! `smartagg calibrate` command calibrates EMCCD and sCMOS cameras (offset,
//! gain and read-noise maps).
//!
//! Users: the `smartagg` host (`calibrate` writes a calibration;
//! `aggregate`, `localize` and `study --calibration` read one). The crate
//! depends on `smartagg-model` and `smartagg-io` only.
//!
//! ## SPAD estimators ([`spad`], [`estimate`])
//!
//! * **DCR**: a pixel that read 1 in k of n dark bit-planes of exposure τ
//!   has `rate = −ln(1 − k/n)/τ` (the pile-up-correct maximum-likelihood
//!   estimate: a plane reads 1 with `p = 1 − e^{−rate·τ}`), with the
//!   delta-method uncertainty `sd = √(p/(n(1 − p)))/τ`. No count (k = 0):
//!   rate 0, flag `NO_COUNTS`, 95 % upper bound `ln 20/(nτ)` in the report.
//!   Every plane 1 (k = n): no finite MLE; the rate of `k = n − ½`,
//!   `ln(2n)/τ`, a finite lower estimate, flag `SATURATED`. Nothing is
//!   subtracted: a dark recording is dark.
//! * **Median DCR and DRNU**: the median over all pixels; DRNU is
//!   `1.4826·MAD/median` over the pixels neither hot nor saturated, reported
//!   as measured and with the counting noise removed
//!   (`√max(0, DRNU² − noise²)`, noise the RMS relative uncertainty).
//! * **Precision**: `--precision r` asks for relative uncertainty r at the
//!   median DCR; that needs `n = p/((1 − p)(r·ln(1/(1 − p)))²) ≈ 1/(p r²)`
//!   planes (p at the median DCR). A shorter recording is an error
//!   ([`CalibrationError::TooShort`]) unless accepted (`--allow-short`),
//!   and the report always states the planes needed.
//! * **Hot pixels**: [`HotCriterion`] (docs/DESIGN.md §3 stage 0, §4): a pixel is
//!   hot when its own dark counts alone would make the expected H at its
//!   position reach T_int, the other pixels at the median background.
//! * **PRNU** (with a uniformly lit flat recording): each pixel's photon
//!   response, its pile-up-corrected flat rate minus its DCR, divided by the
//!   mean response of the pixels neither hot, saturated nor dead: a relative
//!   PDE map of mean 1, with uncertainty `√(sd_flat² + sd_dark²)/mean`
//!   (the mean's own uncertainty, ~1/√pixels smaller, is neglected). A pixel
//!   responding with less than `--dead-below` (10 %) of the median is `DEAD`.
//!
//! Frame cameras: see [`frames`].
//!
//! ## File format, version 1 ([`format`](mod@format))
//!
//! A calibration is a directory:
//!
//! | file | content |
//! |---|---|
//! | `calibration.toml` | header: `format = "smartagg-calibration"`, `version = 1`, `kind` (`spad`, `emccd`, `scmos`), `width`, `height`, `[provenance]` (recordings, planes/frames, preset, command, notes), every scalar (`[spad]`, `[spad.dark]`, `[spad.flat]`, `[spad.hot_criterion]` or `[frame]`) and `[maps.NAME]` = file, sample type, unit, description of each map |
//! | `NAME.tif` | one map: a single-page 32-bit float (`f32`) or 8-bit (`u8`, the flags) greyscale TIFF, raster order, width × height; ImageJ/Fiji open them directly |
//! | `report.md`, `*_histogram.png`, `*_pixels.csv` | the human-readable report (not read back) |
//!
//! SPAD maps: `dcr_hz`, `dcr_sd_hz`, `flags`, and with a flat `prnu`,
//! `prnu_sd`. Frame maps: `offset_adu`, `offset_sd_adu`, `read_noise_adu`,
//! `read_noise_sd_adu`, `flags`, and when known `gain_adu_per_e`,
//! `gain_sd_adu_per_e`, `read_noise_e`, `prnu`, `prnu_sd`. Maps are stored
//! as f32 (7 significant digits, far below any stated uncertainty), so a
//! loaded calibration equals the computed one to f32 rounding. Flags are
//! the bits of [`flags`]; the hot-pixel mask is the `HOT` bit.
//! Readers reject a newer `version`, a header naming maps that are absent,
//! maps of another size or sample type, non-finite or out-of-range values
//! and unknown flag bits, each with an error naming the map.

pub mod counter;
pub mod error;
pub mod estimate;
pub mod flags;
pub mod format;
pub mod frames;
pub mod report;
pub mod spad;

use serde::{Deserialize, Serialize};
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::sensor_maps::SensorMaps;

pub use counter::PlaneCounter;
pub use error::CalibrationError;
pub use frames::{FrameCalibration, FrameCamera};
pub use spad::{DarkSummary, FlatSummary, HotCriterion};

/// Where a calibration came from (the `[provenance]` table).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The dark recording or stack, as given.
    pub dark: String,
    /// The flat recording or stack, as given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flat: Option<String>,
    /// Camera preset used for the hot criterion or the fallback gain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Objective magnification of the preset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objective: Option<u32>,
    /// The command line that made the calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command: Option<String>,
    /// Program and version.
    #[serde(default)]
    pub created_by: String,
    /// Unix time of creation, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub created_unix_s: Option<u64>,
    /// Warnings the user must see (short recording, unreachable criterion, ...).
    #[serde(default)]
    pub notes: Vec<String>,
}

/// Calibration of a SPAD (bit-plane) camera: per-pixel maps in raster order.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Bit-plane exposure τ of the dark recording, s.
    pub tau_s: f64,
    /// Bit-plane period of the dark recording, s.
    pub plane_period_s: f64,
    /// Dark bit-planes used.
    pub planes: u64,
    /// Dark-count rate, Hz (finite; 0 for `NO_COUNTS`, a lower estimate for `SATURATED`).
    pub dcr_hz: Vec<f64>,
    /// Standard uncertainty of the DCR, Hz.
    pub dcr_sd_hz: Vec<f64>,
    /// Per-pixel [`flags`].
    pub flags: Vec<u8>,
    /// Relative photon detection efficiency (mean 1 over the normalising pixels), with a flat.
    pub prnu: Option<Vec<f64>>,
    /// Uncertainty of the PRNU map.
    pub prnu_sd: Option<Vec<f64>>,
    /// The hot-pixel criterion the `HOT` flags follow.
    pub hot_criterion: HotCriterion,
    /// Sensor-wide dark figures.
    pub dark: DarkSummary,
    /// Sensor-wide flat figures, with a flat.
    pub flat: Option<FlatSummary>,
    /// Where the data came from.
    pub provenance: Provenance,
}

impl Calibration {
    /// Width × height.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The stage-0 mask: every pixel flagged `HOT`.
    pub fn hot_mask(&self) -> HotPixelMask {
        let mut m = HotPixelMask::new(self.width as usize, self.height as usize);
        for (x, y) in self.hot_pixels() {
            m.set(x, y, true);
        }
        m
    }

    /// The mask another criterion (e.g. the N and T_int a pipeline actually
    /// runs with, [`HotCriterion::with_threshold`]) gives for this DCR map.
    pub fn hot_mask_for(&self, criterion: &HotCriterion) -> HotPixelMask {
        let w = self.width as usize;
        let mut m = HotPixelMask::new(w, self.height as usize);
        for (i, &d) in self.dcr_hz.iter().enumerate() {
            if criterion.is_hot(d) {
                m.set(i % w, i / w, true);
            }
        }
        m
    }

    /// (x, y) of every pixel flagged `HOT`, raster order.
    pub fn hot_pixels(&self) -> Vec<(usize, usize)> {
        let w = self.width as usize;
        self.flags
            .iter()
            .enumerate()
            .filter(|(_, &f)| f & flags::HOT != 0)
            .map(|(i, _)| (i % w, i / w))
            .collect()
    }

    /// The sensor's maps as every consumer reads them: the DCR, the PRNU
    /// (with a flat) and the `HOT` flags as hot pixels.
    pub fn sensor_maps(&self) -> SensorMaps {
        SensorMaps {
            width: self.width,
            height: self.height,
            dcr_hz: self.dcr_hz.clone(),
            prnu: self.prnu.clone(),
            hot: self.flags.iter().map(|&f| f & flags::HOT != 0).collect(),
        }
    }

    /// Checks sizes and values (what [`Calibration::save`] and
    /// [`Calibration::load`] guarantee).
    pub fn validate(&self) -> Result<(), CalibrationError> {
        format::validate_spad(self)
    }

    /// Writes the calibration directory `dir` (created if needed; existing
    /// calibration files in it are replaced).
    pub fn save(&self, dir: &std::path::Path) -> Result<(), CalibrationError> {
        format::save_spad(self, dir)
    }

    /// Reads a SPAD calibration: `path` is the directory or its
    /// `calibration.toml`. A frame-camera calibration is
    /// [`CalibrationError::WrongKind`].
    pub fn load(path: &std::path::Path) -> Result<Calibration, CalibrationError> {
        match AnyCalibration::load(path)? {
            AnyCalibration::Spad(c) => Ok(c),
            AnyCalibration::Frame(f) => Err(CalibrationError::WrongKind {
                path: path.to_path_buf(),
                found: f.camera.as_str().to_string(),
                expected: "spad",
            }),
        }
    }
}

impl FrameCalibration {
    /// Writes the calibration directory `dir`.
    pub fn save(&self, dir: &std::path::Path) -> Result<(), CalibrationError> {
        format::save_frame(self, dir)
    }

    /// Reads an EMCCD or sCMOS calibration (a SPAD one is [`CalibrationError::WrongKind`]).
    pub fn load(path: &std::path::Path) -> Result<FrameCalibration, CalibrationError> {
        match AnyCalibration::load(path)? {
            AnyCalibration::Frame(f) => Ok(f),
            AnyCalibration::Spad(_) => Err(CalibrationError::WrongKind {
                path: path.to_path_buf(),
                found: "spad".to_string(),
                expected: "emccd or scmos",
            }),
        }
    }
}

/// A calibration of any of the three cameras.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyCalibration {
    /// Bit-plane camera.
    Spad(Calibration),
    /// EMCCD or sCMOS.
    Frame(FrameCalibration),
}

impl AnyCalibration {
    /// Reads whichever calibration `path` holds.
    pub fn load(path: &std::path::Path) -> Result<AnyCalibration, CalibrationError> {
        format::load(path)
    }
}

#[cfg(test)]
mod tests;
