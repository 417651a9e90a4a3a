//! Camera, optics, emitter and background parameters, and the presets of
//! Table 1 of the paper (Gyongy et al., "Smart-aggregation imaging for single
//! molecule localization with SPAD cameras").
//!
//! Units are SI unless the field name says otherwise (`_um`, `_nm`, `_hz`).
//! Rates called `..._hz` are events per second. Every constructor that takes
//! numbers from a user validates them and names the offending parameter.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A parameter that cannot describe a real camera, objective or scene.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParamError {
    /// A value outside its physical range; the message names the parameter.
    #[error("invalid parameter `{name}` = {}: {why}", fmt_num(*value))]
    Invalid {
        /// Name of the parameter as the user knows it.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What the value must satisfy.
        why: &'static str,
    },
    /// A value outside `lo ..= hi`; the message names the parameter and the range.
    #[error(
        "invalid parameter `{name}` = {}: must be a finite number in {} ..= {}",
        fmt_num(*value),
        fmt_num(*lo),
        fmt_num(*hi)
    )]
    OutOfRange {
        /// Name of the parameter as the user knows it (with its unit).
        name: &'static str,
        /// The offending value.
        value: f64,
        /// Smallest valid value.
        lo: f64,
        /// Largest valid value.
        hi: f64,
    },
    /// A preset name that does not exist.
    #[error(
        "unknown preset `{0}` (known: spcimager, spcimager-projected, spad512s, emccd, scmos)"
    )]
    UnknownPreset(String),
    /// An objective other than the study's 150x and 60x.
    #[error("unknown objective {0}x (known: 150, 60)")]
    UnknownObjective(u32),
}

/// A number for a message: plain when it is short (`0.5`, `1500`), in
/// scientific notation when plain would be long (`1e300`, `1e-320`), so no
/// error shows a 300-digit number.
pub fn fmt_num(v: f64) -> String {
    if !v.is_finite() || v == 0.0 {
        return format!("{v}");
    }
    let plain = format!("{v}");
    let a = v.abs();
    if v.fract() == 0.0 && plain.len() <= 10 && !plain.ends_with("000000") {
        // A whole number that is not round (a count of planes) reads best in full.
        plain
    } else if !(1e-4..1e7).contains(&a) {
        format!("{v:e}")
    } else if plain.len() <= 12 {
        plain
    } else {
        // Long only because of the binary fraction: 6 significant digits.
        let s = format!("{v:.*}", (5 - a.log10().floor() as i32).max(0) as usize);
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    }
}

/// Checks `value` is finite and within `[lo, hi]`; the error gives the range.
pub fn check_range(name: &'static str, value: f64, lo: f64, hi: f64) -> Result<f64, ParamError> {
    if !value.is_finite() || value < lo || value > hi {
        return Err(ParamError::OutOfRange {
            name,
            value,
            lo,
            hi,
        });
    }
    Ok(value)
}

/// Checks `value` is finite and strictly positive.
pub fn check_positive(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if !value.is_finite() || value <= 0.0 {
        return Err(ParamError::Invalid {
            name,
            value,
            why: "must be a finite number greater than zero",
        });
    }
    Ok(value)
}

/// Largest molecule flux, photons/s: a fluorophore's excited state lives
/// about a nanosecond, so one molecule cannot emit 10⁹ photons per second
/// (the study's is 5·10⁴).
pub const MAX_FLUX_HZ: f64 = 1e9;
/// Largest background, photons per µm² per second (the study's is 7·10⁴;
/// 10¹⁰ saturates every camera modelled here many times over).
pub const MAX_BACKGROUND_PER_UM2_HZ: f64 = 1e10;
/// Longest frame period of a frame camera, s.
pub const MAX_FRAME_PERIOD_S: f64 = 100.0;

/// Checks `value` is finite and not negative.
pub fn check_non_negative(name: &'static str, value: f64) -> Result<f64, ParamError> {
    if !value.is_finite() || value < 0.0 {
        return Err(ParamError::Invalid {
            name,
            value,
            why: "must be a finite number, zero or greater",
        });
    }
    Ok(value)
}

/// Checks a sensor's size in pixels (1 ..= 65535 each way).
fn check_sensor_size(width: u32, height: u32) -> Result<(), ParamError> {
    check_range("width", width as f64, 1.0, 65535.0)?;
    check_range("height", height as f64, 1.0, 65535.0)?;
    Ok(())
}

/// Checks a frame camera's timing: positive period and exposure, and an
/// exposure no longer than the period.
fn check_frame_timing(frame_period_s: f64, exposure_s: f64) -> Result<(), ParamError> {
    check_positive("frame_period_s", frame_period_s)?;
    check_range("frame_period_s", frame_period_s, 0.0, MAX_FRAME_PERIOD_S)?;
    check_positive("exposure_s", exposure_s)?;
    if exposure_s > frame_period_s * (1.0 + 1e-12) {
        return Err(ParamError::Invalid {
            name: "exposure_s",
            value: exposure_s,
            why: "a frame cannot expose longer than its period",
        });
    }
    Ok(())
}

/// A binary single-photon avalanche diode camera (the SPCImager class).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpadCamera {
    /// Pixel pitch on the sensor, µm.
    pub pixel_pitch_um: f64,
    /// Sensor width in pixels.
    pub width: u32,
    /// Sensor height in pixels.
    pub height: u32,
    /// Photon detection efficiency of the active area (0..1).
    pub pde: f64,
    /// Fraction of the pixel that is photosensitive (0..1).
    pub fill_factor: f64,
    /// Median dark-count rate per pixel, Hz.
    pub dcr_median_hz: f64,
    /// Dark-rate non-uniformity: relative spread (std/median) of the DCR across pixels.
    pub drnu: f64,
    /// Photon-response non-uniformity: relative spread of PDE across pixels.
    pub prnu: f64,
    /// Time from one bit-plane to the next, s.
    pub plane_period_s: f64,
    /// Exposure of one bit-plane, s (equals the period for back-to-back rolling shutter).
    pub exposure_s: f64,
    /// Fraction of hot pixels (0..1); 0 for the presets (the paper models them separately).
    pub hot_pixel_fraction: f64,
    /// Dark-count rate of a hot pixel, Hz.
    pub hot_pixel_dcr_hz: f64,
}

impl SpadCamera {
    /// Effective detection efficiency η = PDE × fill factor (paper §3).
    pub fn eta(&self) -> f64 {
        self.pde * self.fill_factor
    }

    /// Validates every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_positive("pixel_pitch_um", self.pixel_pitch_um)?;
        check_sensor_size(self.width, self.height)?;
        check_range("pde", self.pde, 0.0, 1.0)?;
        check_range("fill_factor", self.fill_factor, 0.0, 1.0)?;
        check_non_negative("dcr_median_hz", self.dcr_median_hz)?;
        check_range("drnu", self.drnu, 0.0, 10.0)?;
        check_range("prnu", self.prnu, 0.0, 1.0)?;
        check_positive("plane_period_s", self.plane_period_s)?;
        check_positive("exposure_s", self.exposure_s)?;
        if self.exposure_s > self.plane_period_s * (1.0 + 1e-12) {
            return Err(ParamError::Invalid {
                name: "exposure_s",
                value: self.exposure_s,
                why: "a bit-plane cannot expose longer than its period",
            });
        }
        check_range("hot_pixel_fraction", self.hot_pixel_fraction, 0.0, 1.0)?;
        check_non_negative("hot_pixel_dcr_hz", self.hot_pixel_dcr_hz)?;
        Ok(())
    }
}

/// An electron-multiplying CCD (Andor iXon Ultra 897 class).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EmccdCamera {
    /// Pixel pitch, µm.
    pub pixel_pitch_um: f64,
    /// Sensor width in pixels.
    pub width: u32,
    /// Sensor height in pixels.
    pub height: u32,
    /// Quantum efficiency (0..1).
    pub qe: f64,
    /// Read noise referred to the input (divided by the EM gain), e⁻ rms.
    pub read_noise_e: f64,
    /// Dark current, e⁻ per pixel per second.
    pub dark_e_per_s: f64,
    /// Clock-induced charge, events per pixel per frame.
    pub cic_per_frame: f64,
    /// Electron-multiplication gain.
    pub em_gain: f64,
    /// Frame period, s.
    pub frame_period_s: f64,
    /// Exposure within a frame, s (period minus read-out dead time).
    pub exposure_s: f64,
    /// Electrons (after multiplication) per ADU.
    pub e_per_adu: f64,
    /// ADU offset (bias) added to every pixel.
    pub offset_adu: f64,
}

impl EmccdCamera {
    /// Validates every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_positive("pixel_pitch_um", self.pixel_pitch_um)?;
        check_sensor_size(self.width, self.height)?;
        check_range("qe", self.qe, 0.0, 1.0)?;
        check_non_negative("read_noise_e", self.read_noise_e)?;
        check_non_negative("dark_e_per_s", self.dark_e_per_s)?;
        check_non_negative("cic_per_frame", self.cic_per_frame)?;
        check_range("em_gain", self.em_gain, 1.0, 10000.0)?;
        check_frame_timing(self.frame_period_s, self.exposure_s)?;
        check_positive("e_per_adu", self.e_per_adu)?;
        check_non_negative("offset_adu", self.offset_adu)?;
        Ok(())
    }
}

/// A scientific CMOS camera (Hamamatsu ORCA-Flash4.0 V2 class).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScmosCamera {
    /// Pixel pitch, µm.
    pub pixel_pitch_um: f64,
    /// Sensor width in pixels.
    pub width: u32,
    /// Sensor height in pixels.
    pub height: u32,
    /// Quantum efficiency (0..1).
    pub qe: f64,
    /// Median read noise, e⁻ rms.
    pub read_noise_e: f64,
    /// Mean dark current, e⁻ per pixel per second.
    pub dark_e_per_s: f64,
    /// Dark-rate non-uniformity (relative spread).
    pub drnu: f64,
    /// Photon-response non-uniformity (relative spread).
    pub prnu: f64,
    /// Frame period, s.
    pub frame_period_s: f64,
    /// Exposure within a frame, s.
    pub exposure_s: f64,
    /// Electrons per ADU (median gain).
    pub e_per_adu: f64,
    /// Median ADU offset.
    pub offset_adu: f64,
}

impl ScmosCamera {
    /// Validates every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_positive("pixel_pitch_um", self.pixel_pitch_um)?;
        check_sensor_size(self.width, self.height)?;
        check_range("qe", self.qe, 0.0, 1.0)?;
        check_non_negative("read_noise_e", self.read_noise_e)?;
        check_non_negative("dark_e_per_s", self.dark_e_per_s)?;
        check_range("drnu", self.drnu, 0.0, 10.0)?;
        check_range("prnu", self.prnu, 0.0, 1.0)?;
        check_frame_timing(self.frame_period_s, self.exposure_s)?;
        check_positive("e_per_adu", self.e_per_adu)?;
        check_non_negative("offset_adu", self.offset_adu)?;
        Ok(())
    }
}

/// One of the three camera technologies of the paper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Camera {
    /// Binary SPAD camera producing bit-planes.
    Spad(SpadCamera),
    /// EMCCD producing frames.
    Emccd(EmccdCamera),
    /// sCMOS producing frames.
    Scmos(ScmosCamera),
}

impl Camera {
    /// Pixel pitch on the sensor, µm.
    pub fn pixel_pitch_um(&self) -> f64 {
        match self {
            Camera::Spad(c) => c.pixel_pitch_um,
            Camera::Emccd(c) => c.pixel_pitch_um,
            Camera::Scmos(c) => c.pixel_pitch_um,
        }
    }

    /// Sensor size (width, height) in pixels.
    pub fn size(&self) -> (u32, u32) {
        match self {
            Camera::Spad(c) => (c.width, c.height),
            Camera::Emccd(c) => (c.width, c.height),
            Camera::Scmos(c) => (c.width, c.height),
        }
    }

    /// Detection efficiency: PDE × fill factor for SPAD, QE otherwise.
    pub fn eta(&self) -> f64 {
        match self {
            Camera::Spad(c) => c.eta(),
            Camera::Emccd(c) => c.qe,
            Camera::Scmos(c) => c.qe,
        }
    }

    /// Validates the camera; the error names the first bad parameter.
    pub fn validate(&self) -> Result<(), ParamError> {
        match self {
            Camera::Spad(c) => c.validate(),
            Camera::Emccd(c) => c.validate(),
            Camera::Scmos(c) => c.validate(),
        }
    }
}

/// Microscope optics between the sample and the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Optics {
    /// Total magnification from sample to sensor.
    pub magnification: f64,
    /// Numerical aperture of the objective.
    pub na: f64,
    /// Refractive index of the immersion medium (NA cannot exceed it).
    pub immersion_index: f64,
    /// Emission wavelength, nm.
    pub wavelength_nm: f64,
}

impl Optics {
    /// The study's objective: 150× or 60×, NA 1.45 oil, ATTO 550 emission (576 nm).
    pub fn objective(magnification: u32) -> Result<Optics, ParamError> {
        match magnification {
            150 | 60 => Ok(Optics {
                magnification: magnification as f64,
                na: 1.45,
                immersion_index: 1.518,
                wavelength_nm: 576.0,
            }),
            other => Err(ParamError::UnknownObjective(other)),
        }
    }

    /// Validates the optics; the error names the first bad parameter.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_positive("magnification", self.magnification)?;
        check_positive("immersion_index", self.immersion_index)?;
        check_positive("na", self.na)?;
        if self.na > self.immersion_index {
            return Err(ParamError::Invalid {
                name: "na",
                value: self.na,
                why: "the numerical aperture cannot exceed the immersion medium's refractive index",
            });
        }
        check_range("wavelength_nm", self.wavelength_nm, 100.0, 5000.0)?;
        Ok(())
    }

    /// Airy-disk radius r = 0.61 λ / NA in the sample plane, nm.
    pub fn airy_radius_nm(&self) -> f64 {
        0.61 * self.wavelength_nm / self.na
    }

    /// PSF standard deviation σ = r/3 in the sample plane, nm (paper §3).
    pub fn psf_sigma_nm(&self) -> f64 {
        self.airy_radius_nm() / 3.0
    }

    /// Size of one camera pixel projected into the sample plane, nm.
    pub fn pixel_nm(&self, pixel_pitch_um: f64) -> f64 {
        pixel_pitch_um * 1000.0 / self.magnification
    }

    /// PSF σ in pixels of a camera with the given pitch.
    pub fn psf_sigma_px(&self, pixel_pitch_um: f64) -> f64 {
        self.psf_sigma_nm() / self.pixel_nm(pixel_pitch_um)
    }
}

/// Background and molecule brightness of the study (paper §4.2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneLight {
    /// Photon flux from one molecule when on, photons/s reaching the sensor.
    pub flux_hz: f64,
    /// Background photons per µm² of sample per second (TIRF).
    pub background_per_um2_hz: f64,
}

impl SceneLight {
    /// The paper's study: 50,000 photons/s per molecule, 70,000 photons/s/µm² background.
    pub const STUDY: SceneLight = SceneLight {
        flux_hz: 50_000.0,
        background_per_um2_hz: 70_000.0,
    };

    /// Validates the light levels; the error names the first bad parameter.
    /// The molecule flux is at most [`MAX_FLUX_HZ`], the background at most
    /// [`MAX_BACKGROUND_PER_UM2_HZ`].
    pub fn validate(&self) -> Result<(), ParamError> {
        check_range("flux_hz", self.flux_hz, 0.0, MAX_FLUX_HZ)?;
        check_range(
            "background_per_um2_hz",
            self.background_per_um2_hz,
            0.0,
            MAX_BACKGROUND_PER_UM2_HZ,
        )?;
        Ok(())
    }

    /// Background photons per pixel per second (before detection efficiency).
    pub fn background_per_pixel_hz(&self, optics: &Optics, pixel_pitch_um: f64) -> f64 {
        let px_um = optics.pixel_nm(pixel_pitch_um) / 1000.0;
        self.background_per_um2_hz * px_um * px_um
    }
}

/// A named camera of Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PresetName {
    /// SPCImager as built: 26 % fill factor, 100 Hz median DCR.
    Spcimager,
    /// Projected future SPCImager: 3× fill factor (78 %), DCR/4 (25 Hz).
    SpcimagerProjected,
    /// Pi Imaging SPAD512S class binary SPAD camera: 512×512, 16.38 µm,
    /// 10.5 % fill factor, 100,000 bit-planes/s ([`spad512s`]).
    Spad512s,
    /// Andor iXon Ultra 897 class EMCCD.
    Emccd,
    /// Hamamatsu ORCA-Flash4.0 V2 class sCMOS.
    Scmos,
}

impl PresetName {
    /// Every preset, in the order `smartagg presets` lists them.
    pub const ALL: [PresetName; 5] = [
        PresetName::Spcimager,
        PresetName::SpcimagerProjected,
        PresetName::Spad512s,
        PresetName::Emccd,
        PresetName::Scmos,
    ];

    /// The name used on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            PresetName::Spcimager => "spcimager",
            PresetName::SpcimagerProjected => "spcimager-projected",
            PresetName::Spad512s => "spad512s",
            PresetName::Emccd => "emccd",
            PresetName::Scmos => "scmos",
        }
    }

    /// Parses a command-line preset name.
    pub fn parse(s: &str) -> Result<PresetName, ParamError> {
        PresetName::ALL
            .into_iter()
            .find(|p| p.as_str() == s)
            .ok_or_else(|| ParamError::UnknownPreset(s.to_string()))
    }
}

impl std::fmt::Display for PresetName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A complete, validated set-up: camera, optics and light levels, plus the
/// study's simulated field of view for that camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Preset {
    /// Which preset this is.
    pub name: PresetName,
    /// One-line description for `smartagg presets`.
    pub description: String,
    /// The camera.
    pub camera: Camera,
    /// The optics (objective).
    pub optics: Optics,
    /// Molecule and background light.
    pub light: SceneLight,
    /// Side of the square field the study simulates, pixels (32 SPAD, 16 EMCCD, 40 sCMOS).
    pub study_field_px: u32,
}

/// SPCImager as characterised in Table 1 of the paper.
pub fn spcimager() -> SpadCamera {
    SpadCamera {
        pixel_pitch_um: 8.0,
        width: 320,
        height: 240,
        pde: 0.35,
        fill_factor: 0.26,
        dcr_median_hz: 100.0,
        drnu: 0.02,
        prnu: 0.01,
        plane_period_s: 100e-6,
        exposure_s: 100e-6,
        hot_pixel_fraction: 0.0,
        hot_pixel_dcr_hz: 10_000.0,
    }
}

/// A SPAD512S-class camera (Pi Imaging Technology; its sensor is SwissSPAD2),
/// from the published figures:
///
/// * 512 × 512 pixels at a 16.38 µm pitch, 10.5 % native fill factor (no
///   microlenses), 1-bit planes at up to 97,700–100,000 per second: A. C.
///   Ulku et al., "A 512×512 SPAD image sensor with integrated gating for
///   widefield FLIM", IEEE J. Sel. Top. Quantum Electron. 25(1), 6801212
///   (2019), and the SPAD512S product data (100,000 fps 1-bit).
/// * Photon detection probability 50 %: the published peak (at 520 nm); at
///   the 576 nm emission this crate assumes it is somewhat lower, so the
///   preset is the bright end of what the camera sees.
/// * Dark counts 25 Hz per pixel: the product data's "typical, less than
///   25 counts per second" (the median pixel of the paper is lower).
/// * 10 µs between planes (100,000 planes/s), exposed back to back.
///
/// DRNU and PRNU are not published for this sensor; the SPCImager's are used.
pub fn spad512s() -> SpadCamera {
    SpadCamera {
        pixel_pitch_um: 16.38,
        width: 512,
        height: 512,
        pde: 0.50,
        fill_factor: 0.105,
        dcr_median_hz: 25.0,
        plane_period_s: 10e-6,
        exposure_s: 10e-6,
        ..spcimager()
    }
}

impl Preset {
    /// Builds a preset with the given objective (150 or 60).
    pub fn new(name: PresetName, objective: u32) -> Result<Preset, ParamError> {
        let optics = Optics::objective(objective)?;
        let (camera, description, field) = match name {
            PresetName::Spcimager => (
                Camera::Spad(spcimager()),
                "SPCImager binary SPAD: 320x240, 8 um, 35 % PDE x 26 % fill, 100 Hz median DCR, 10 kHz bit-planes",
                32,
            ),
            PresetName::SpcimagerProjected => (
                Camera::Spad(SpadCamera {
                    fill_factor: 0.78,
                    dcr_median_hz: 25.0,
                    ..spcimager()
                }),
                "Projected SPCImager: 3x fill factor (78 %), DCR/4 (25 Hz), otherwise as SPCImager",
                32,
            ),
            PresetName::Spad512s => (
                Camera::Spad(spad512s()),
                "SPAD512S-class binary SPAD: 512x512, 16.38 um, 50 % PDP x 10.5 % fill, 25 Hz DCR, 100 kHz bit-planes",
                32,
            ),
            PresetName::Emccd => (
                Camera::Emccd(EmccdCamera {
                    pixel_pitch_um: 16.0,
                    width: 512,
                    height: 512,
                    qe: 0.90,
                    read_noise_e: 0.2,
                    dark_e_per_s: 0.001,
                    cic_per_frame: 0.0018,
                    em_gain: 300.0,
                    frame_period_s: 0.050,
                    exposure_s: 0.050,
                    e_per_adu: 12.0,
                    offset_adu: 100.0,
                }),
                "EMCCD (Andor iXon Ultra 897 class): 512x512, 16 um, 90 % QE, 0.2 e- input-referred read noise, 50 ms frames",
                16,
            ),
            PresetName::Scmos => (
                Camera::Scmos(ScmosCamera {
                    pixel_pitch_um: 6.5,
                    width: 2048,
                    height: 2048,
                    qe: 0.80,
                    read_noise_e: 1.4,
                    dark_e_per_s: 0.05,
                    drnu: 0.01,
                    prnu: 0.005,
                    frame_period_s: 0.050,
                    exposure_s: 0.050,
                    e_per_adu: 0.46,
                    offset_adu: 100.0,
                }),
                "sCMOS (Hamamatsu ORCA-Flash4.0 V2 class): 2048x2048, 6.5 um, 80 % QE, 1.4 e- read noise, 50 ms frames",
                40,
            ),
        };
        let preset = Preset {
            name,
            description: description.to_string(),
            camera,
            optics,
            light: SceneLight::STUDY,
            study_field_px: field,
        };
        preset.validate()?;
        Ok(preset)
    }

    /// Validates camera, optics and light.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.camera.validate()?;
        self.optics.validate()?;
        self.light.validate()?;
        let (w, h) = self.camera.size();
        if self.study_field_px == 0 || self.study_field_px > w.min(h) {
            return Err(ParamError::Invalid {
                name: "study_field_px",
                value: self.study_field_px as f64,
                why: "the simulated field (ROI) must be at least 1 pixel and no larger than the sensor",
            });
        }
        Ok(())
    }

    /// PSF σ in this camera's pixels.
    pub fn sigma_px(&self) -> f64 {
        self.optics.psf_sigma_px(self.camera.pixel_pitch_um())
    }

    /// Pixel size in the sample plane, nm.
    pub fn pixel_nm(&self) -> f64 {
        self.optics.pixel_nm(self.camera.pixel_pitch_um())
    }

    /// Detected background rate per pixel, Hz: background light × η plus the
    /// median dark count (SPAD) or dark current (frame cameras).
    pub fn background_rate_hz(&self) -> f64 {
        let light = self
            .light
            .background_per_pixel_hz(&self.optics, self.camera.pixel_pitch_um())
            * self.camera.eta();
        let dark = match &self.camera {
            Camera::Spad(c) => c.dcr_median_hz,
            Camera::Emccd(c) => c.dark_e_per_s,
            Camera::Scmos(c) => c.dark_e_per_s,
        };
        light + dark
    }

    /// Exposure of one bit-plane or frame, s.
    pub fn exposure_s(&self) -> f64 {
        match &self.camera {
            Camera::Spad(c) => c.exposure_s,
            Camera::Emccd(c) => c.exposure_s,
            Camera::Scmos(c) => c.exposure_s,
        }
    }

    /// Period of one bit-plane or frame, s.
    pub fn period_s(&self) -> f64 {
        match &self.camera {
            Camera::Spad(c) => c.plane_period_s,
            Camera::Emccd(c) => c.frame_period_s,
            Camera::Scmos(c) => c.frame_period_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_in_messages_stay_short() {
        assert_eq!(fmt_num(0.5), "0.5");
        assert_eq!(fmt_num(1500.0), "1500");
        assert_eq!(fmt_num(65535.0), "65535");
        assert_eq!(fmt_num(1e9), "1e9");
        assert_eq!(fmt_num(536_870_912.0), "536870912");
        assert_eq!(fmt_num(2.5e10), "2.5e10");
        assert_eq!(fmt_num(1e300), "1e300");
        assert_eq!(fmt_num(-1e12), "-1e12");
        assert_eq!(fmt_num(1e-320), "1e-320");
        assert_eq!(fmt_num(0.1 + 0.2), "0.3");
        assert_eq!(fmt_num(f64::NAN), "NaN");
        let e = check_range("--flux (photons/s)", 1e300, 0.0, MAX_FLUX_HZ)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "invalid parameter `--flux (photons/s)` = 1e300: must be a finite number in 0 ..= 1e9"
        );
        let e = check_positive("x", 1e-300)
            .map(|_| ())
            .and(check_positive("x", -1e300));
        assert!(e.unwrap_err().to_string().contains("= -1e300:"));
    }

    #[test]
    fn light_and_frame_timing_have_physical_limits() {
        let mut l = SceneLight::STUDY;
        l.flux_hz = 1e300;
        assert!(l.validate().unwrap_err().to_string().contains("flux_hz"));
        l.flux_hz = MAX_FLUX_HZ;
        l.background_per_um2_hz = 1e11;
        assert!(l.validate().is_err());
        assert!(check_frame_timing(1e306, 1e306).is_err());
        assert!(check_frame_timing(MAX_FRAME_PERIOD_S, 1.0).is_ok());
    }

    #[test]
    fn spcimager_150x_sigma_and_background() {
        let p = Preset::new(PresetName::Spcimager, 150).unwrap();
        // r = 0.61*576/1.45 = 242.3 nm; sigma = 80.8 nm; pixel = 53.33 nm.
        assert!((p.pixel_nm() - 53.333).abs() < 1e-2);
        assert!((p.sigma_px() - 1.5146).abs() < 1e-3, "{}", p.sigma_px());
        // 70,000/um^2/s * 0.05333^2 um^2 * 0.091 + 100 Hz = 118.1 Hz
        assert!((p.background_rate_hz() - 118.12).abs() < 0.1);
    }

    #[test]
    fn spad512s_is_the_published_camera() {
        let p = Preset::new(PresetName::Spad512s, 150).unwrap();
        assert_eq!(p.camera.size(), (512, 512));
        assert_eq!(p.period_s(), 10e-6, "100,000 planes/s");
        // 16.38 um / 150 = 109.2 nm; sigma 80.8 nm = 0.740 px.
        assert!((p.pixel_nm() - 109.2).abs() < 1e-9);
        assert!((p.sigma_px() - 0.7398).abs() < 1e-3, "{}", p.sigma_px());
        // 70,000/um^2/s * 0.1092^2 um^2 * (0.50 * 0.105) + 25 Hz = 68.82 Hz
        assert!((p.background_rate_hz() - 68.82).abs() < 0.01);
        assert_eq!(PresetName::parse("spad512s").unwrap(), PresetName::Spad512s);
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut o = Optics::objective(150).unwrap();
        o.na = 1.6;
        let e = o.validate().unwrap_err().to_string();
        assert!(e.contains("`na`"), "{e}");
        let mut c = spcimager();
        c.pixel_pitch_um = 0.0;
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("pixel_pitch_um"));
        let l = SceneLight {
            flux_hz: -1.0,
            background_per_um2_hz: 1.0,
        };
        assert!(l.validate().unwrap_err().to_string().contains("flux_hz"));
        assert!(Preset::new(PresetName::Spcimager, 100).is_err());
        assert!(PresetName::parse("ccd").is_err());
    }

    #[test]
    fn every_preset_and_objective_is_valid() {
        for name in PresetName::ALL {
            for obj in [150, 60] {
                let p = Preset::new(name, obj).unwrap();
                assert_eq!(PresetName::parse(name.as_str()).unwrap(), name);
                // The SPAD512S's 16.38 µm pixels under the 60x objective are
                // 273 nm wide: σ = 0.30 px, the PSF undersampled.
                assert!(p.sigma_px() > 0.25 && p.sigma_px() < 6.0);
            }
        }
    }
}
