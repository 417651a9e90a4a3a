//! EMCCD and sCMOS calibration: offset, read-noise, gain and PRNU maps from
//! dark and flat stacks of 16-bit frames.
//!
//! ## Estimators (per pixel i, M dark and M' flat frames, values in ADU)
//!
//! * **offset** = mean of the dark frames (it includes the dark signal of
//!   the dark exposure: the same exposure must be used while imaging), with
//!   sd `s/√M`;
//! * **read noise** (ADU) = `√max(0, s² − 1/12)`: the sample variance of the
//!   dark frames less the rounding to whole ADU (Sheppard's correction;
//!   valid when s ≳ 1 ADU), sd `≈ σ/√(2(M−1))`. For an EMCCD, clock-induced
//!   charge puts rare, gain-amplified spikes into dark frames; offset and read
//!   noise are then taken from a second pass over the dark stack that keeps
//!   only values within ±4 s of the first-pass mean (the spikes rejected are
//!   counted and reported);
//! * **gain** from the photon-transfer curve: with `Δμ = μ_flat − μ_dark` and
//!   `Δv = v_flat − v_dark` (both passes unclipped, so the same charge is in
//!   both), shot noise gives `Δv = F²·g·Δμ` with g in ADU per (input)
//!   electron. sCMOS: F² = 1 and `g_i = Δv_i/Δμ_i` per pixel, with the
//!   delta-method sd from `Var(v̂) ≈ 2v²/(M−1)` and `Var(μ̂) = v/M` (normal
//!   approximation of the frame values). EMCCD: one gain for the sensor (one
//!   amplifier), `g = (ΣΔv/ΣΔμ)/F²` over the usable pixels, `F² = 2 − 1/G` for
//!   EM gain G (the excess-noise factor of the multiplication register; 2 at
//!   high gain, the default), its sd from the scatter of `Δv_i − F²g·Δμ_i`.
//!   Read noise in electrons (input-referred for the EMCCD) is the ADU read
//!   noise divided by g;
//! * **PRNU** = `Δμ_i / mean(Δμ)` over the usable pixels: the flat-field
//!   response in ADU (QE and gain non-uniformity together), what a flat-field
//!   correction divides by.
//!
//! ## Flags
//!
//! SATURATED: some dark or flat frame is 0 or 65535 ADU at the pixel (the
//! camera clipped; moments are biased). NOISY: read noise above 3× the
//! median. HOT: dark level more than 10 median read-noise sd above the
//! median offset. DEAD: flat response below the dead fraction of the median.
//! UNMEASURED: sCMOS pixel with no positive photon-transfer slope (the median
//! gain is stored).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::estimate::{mean_sd, median, noise_corrected, robust_sd, Welford};
use super::{flags, CalibrationError, Provenance};

/// The two frame-camera technologies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameCamera {
    /// Electron-multiplying CCD: one amplifier, excess noise F² ≈ 2.
    Emccd,
    /// Scientific CMOS: one amplifier per pixel.
    Scmos,
}

impl FrameCamera {
    /// `emccd` or `scmos`.
    pub fn as_str(self) -> &'static str {
        match self {
            FrameCamera::Emccd => "emccd",
            FrameCamera::Scmos => "scmos",
        }
    }
}

/// What a [`FrameSource`] calls for each frame: `(width, height, ADU values)`.
pub type Visit<'a> = dyn FnMut(u32, u32, &[u16]) -> Result<(), CalibrationError> + 'a;

/// A source of 16-bit frames, read from the start each time it is visited.
pub trait FrameSource {
    /// How to name the source in messages.
    fn name(&self) -> String;
    /// Calls `visit(width, height, frame)` for every frame in order and
    /// returns the number of frames.
    fn for_each_frame(&self, visit: &mut Visit<'_>) -> Result<u64, CalibrationError>;
}

/// A multi-page 16-bit greyscale TIFF stack on disk, read page by page
/// (never whole into memory).
#[derive(Debug, Clone)]
pub struct TiffStack {
    /// The file.
    pub path: PathBuf,
}

impl FrameSource for TiffStack {
    fn name(&self) -> String {
        self.path.display().to_string()
    }

    fn for_each_frame(&self, visit: &mut Visit<'_>) -> Result<u64, CalibrationError> {
        read_tiff_stack(&self.path, visit)
    }
}

fn read_tiff_stack(path: &Path, visit: &mut Visit<'_>) -> Result<u64, CalibrationError> {
    let stack_err = |e: smartagg_io::Error| CalibrationError::Stack {
        path: path.to_path_buf(),
        why: e.why(),
    };
    let mut stack = match smartagg_io::stack::open_stack(path) {
        Ok(s) => s,
        Err(smartagg_io::Error {
            kind: smartagg_io::ErrorKind::File(e),
            ..
        }) => return Err(CalibrationError::io(path, "opening", e)),
        Err(e) => return Err(stack_err(e)),
    };
    let mut pages = 0u64;
    while let Some(frame) = stack.next_u16() {
        let f = frame.map_err(stack_err)?;
        visit(f.width as u32, f.height as u32, &f.data)?;
        pages += 1;
    }
    Ok(pages)
}

/// Choices of the frame calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameOptions {
    /// Which camera.
    pub camera: FrameCamera,
    /// EMCCD excess-noise factor squared F² (2 at high gain, `2 − 1/G` exactly).
    pub excess_noise_f2: f64,
    /// Dead-pixel threshold: flat response below this fraction of the median.
    pub dead_below: f64,
    /// Gain (ADU per input electron) to use without a flat, e.g. the preset's.
    pub fallback_gain: Option<(f64, String)>,
}

/// Sensor-wide figures of a frame calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameSummary {
    /// Dark frames read.
    pub dark_frames: u64,
    /// Flat frames read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flat_frames: Option<u64>,
    /// Median offset, ADU.
    pub offset_median_adu: f64,
    /// Median read noise, ADU.
    pub read_noise_median_adu: f64,
    /// Median read noise, e⁻ (input-referred for the EMCCD).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub read_noise_median_e: Option<f64>,
    /// Sensor gain, ADU per (input) electron: EMCCD pooled photon transfer,
    /// sCMOS median of the per-pixel gains.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_adu_per_e: Option<f64>,
    /// Standard uncertainty of `gain_adu_per_e`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_sd_adu_per_e: Option<f64>,
    /// sCMOS: per-pixel gain spread (std/median) with the measurement noise removed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_spread: Option<f64>,
    /// `photon transfer`, `preset ...` (not measured) or `none`.
    pub gain_source: String,
    /// F² used for the gain (1 for sCMOS).
    pub excess_noise_f2: f64,
    /// Mean flat signal above offset, ADU.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flat_signal_mean_adu: Option<f64>,
    /// PRNU spread (std of the PRNU map, counting noise removed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prnu_spread: Option<f64>,
    /// RMS per-pixel PRNU uncertainty.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prnu_noise: Option<f64>,
    /// Dark values at 0 or 65535 ADU.
    pub clipped_dark_values: u64,
    /// Flat values at 0 or 65535 ADU.
    pub clipped_flat_values: u64,
    /// EMCCD: dark values outside ±4 s rejected as clock-induced-charge spikes.
    pub rejected_dark_values: u64,
    /// Dead-pixel threshold used.
    pub dead_below: f64,
    /// Pixels flagged hot.
    pub hot_pixels: usize,
    /// Pixels flagged noisy.
    pub noisy_pixels: usize,
    /// Pixels flagged dead.
    pub dead_pixels: usize,
    /// Pixels flagged saturated.
    pub saturated_pixels: usize,
    /// Pixels flagged unmeasured.
    pub unmeasured_pixels: usize,
}

/// Calibration of an EMCCD or sCMOS camera (raster-order maps).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameCalibration {
    /// Which camera.
    pub camera: FrameCamera,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Offset (bias + dark signal of the exposure), ADU.
    pub offset_adu: Vec<f64>,
    /// Uncertainty of the offset, ADU.
    pub offset_sd_adu: Vec<f64>,
    /// Read noise, ADU rms.
    pub read_noise_adu: Vec<f64>,
    /// Uncertainty of the read noise, ADU.
    pub read_noise_sd_adu: Vec<f64>,
    /// Gain, ADU per (input) electron (EMCCD: the sensor's gain everywhere).
    pub gain_adu_per_e: Option<Vec<f64>>,
    /// Uncertainty of the gain.
    pub gain_sd_adu_per_e: Option<Vec<f64>>,
    /// Read noise, e⁻ rms (input-referred for the EMCCD).
    pub read_noise_e: Option<Vec<f64>>,
    /// Relative flat-field response in ADU (mean 1 over the usable pixels).
    pub prnu: Option<Vec<f64>>,
    /// Uncertainty of the PRNU.
    pub prnu_sd: Option<Vec<f64>>,
    /// Per-pixel flags ([`super::flags`]).
    pub flags: Vec<u8>,
    /// Sensor-wide figures.
    pub summary: FrameSummary,
    /// Where the data came from.
    pub provenance: Provenance,
}

impl FrameCalibration {
    /// Width × height.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// Per-pixel moments of one pass over a stack.
struct Pass {
    width: u32,
    height: u32,
    frames: u64,
    moments: Welford,
    clipped: Vec<u32>,
    clipped_total: u64,
    rejected: u64,
}

fn pass(
    src: &dyn FrameSource,
    what: &str,
    expect: Option<(u32, u32)>,
    keep: Option<&(Vec<f64>, Vec<f64>)>,
) -> Result<Pass, CalibrationError> {
    let mut p: Option<Pass> = None;
    let frames = src.for_each_frame(&mut |w, h, frame| {
        if let Some(e) = expect {
            if (w, h) != e {
                return Err(CalibrationError::SizeMismatch {
                    what: format!("{what} {} against the dark stack", src.name()),
                    expected: e,
                    found: (w, h),
                });
            }
        }
        let st = p.get_or_insert_with(|| Pass {
            width: w,
            height: h,
            frames: 0,
            moments: Welford::new(frame.len()),
            clipped: vec![0; frame.len()],
            clipped_total: 0,
            rejected: 0,
        });
        for (i, &a) in frame.iter().enumerate() {
            if a == 0 || a == u16::MAX {
                st.clipped[i] += 1;
                st.clipped_total += 1;
            }
            let x = a as f64;
            if let Some((lo, hi)) = keep {
                if x < lo[i] || x > hi[i] {
                    st.rejected += 1;
                    continue;
                }
            }
            st.moments.push(i, x);
        }
        st.frames += 1;
        Ok(())
    })?;
    match p {
        Some(p) if frames > 0 => Ok(p),
        _ => Err(CalibrationError::Empty {
            input: format!("{what} {}", src.name()),
        }),
    }
}

/// Computes the frame calibration from a dark stack and an optional flat stack.
pub fn calibrate_frames(
    dark: &dyn FrameSource,
    flat: Option<&dyn FrameSource>,
    options: &FrameOptions,
    mut provenance: Provenance,
) -> Result<FrameCalibration, CalibrationError> {
    let f2 = match options.camera {
        FrameCamera::Scmos => 1.0,
        FrameCamera::Emccd => options.excess_noise_f2,
    };
    if !(f2.is_finite() && (1.0..=2.0).contains(&f2)) {
        return Err(CalibrationError::invalid(
            "excess_noise_f2",
            format!("{f2} must be in [1, 2] (F² = 2 − 1/G for EM gain G)"),
        ));
    }
    if !(options.dead_below.is_finite() && (0.0..1.0).contains(&options.dead_below)) {
        return Err(CalibrationError::invalid(
            "dead_below",
            format!("{} must be a fraction in [0, 1)", options.dead_below),
        ));
    }
    let d1 = pass(dark, "dark stack", None, None)?;
    let (w, h) = (d1.width, d1.height);
    let n = w as usize * h as usize;
    if d1.frames < 2 {
        return Err(CalibrationError::invalid(
            "dark",
            format!(
                "the dark stack {} has {} frame; a variance needs at least 2",
                dark.name(),
                d1.frames
            ),
        ));
    }
    // EMCCD: a second pass without the clock-induced-charge spikes.
    let d2 = if options.camera == FrameCamera::Emccd {
        let lim: (Vec<f64>, Vec<f64>) = (0..n)
            .map(|i| {
                let s = d1.moments.variance(i).sqrt().max(1.0);
                (d1.moments.mean(i) - 4.0 * s, d1.moments.mean(i) + 4.0 * s)
            })
            .unzip();
        Some(pass(dark, "dark stack", Some((w, h)), Some(&lim))?)
    } else {
        None
    };
    let dn = d2.as_ref().unwrap_or(&d1);
    let mut fl = vec![0u8; n];
    let mut offset = Vec::with_capacity(n);
    let mut offset_sd = Vec::with_capacity(n);
    let mut rn = Vec::with_capacity(n);
    let mut rn_sd = Vec::with_capacity(n);
    for (i, f) in fl.iter_mut().enumerate() {
        let m = dn.moments.count(i).max(1) as f64;
        let var = dn.moments.variance(i);
        offset.push(dn.moments.mean(i));
        offset_sd.push((var / m).sqrt());
        let s = (var - 1.0 / 12.0).max(0.0).sqrt();
        rn.push(s);
        rn_sd.push(s / (2.0 * (m - 1.0).max(1.0)).sqrt());
        if d1.clipped[i] > 0 {
            *f |= flags::SATURATED;
        }
    }
    let offset_median = median(&offset).unwrap_or(0.0);
    let rn_median = median(&rn).unwrap_or(0.0);
    for i in 0..n {
        if rn[i] > 3.0 * rn_median {
            fl[i] |= flags::NOISY;
        }
        if offset[i] - offset_median > 10.0 * rn_median.max(0.5) {
            fl[i] |= flags::HOT;
        }
    }

    let mut summary = FrameSummary {
        dark_frames: d1.frames,
        flat_frames: None,
        offset_median_adu: offset_median,
        read_noise_median_adu: rn_median,
        read_noise_median_e: None,
        gain_adu_per_e: None,
        gain_sd_adu_per_e: None,
        gain_spread: None,
        gain_source: "none".into(),
        excess_noise_f2: f2,
        flat_signal_mean_adu: None,
        prnu_spread: None,
        prnu_noise: None,
        clipped_dark_values: d1.clipped_total,
        clipped_flat_values: 0,
        rejected_dark_values: d2.as_ref().map_or(0, |p| p.rejected),
        dead_below: options.dead_below,
        hot_pixels: 0,
        noisy_pixels: 0,
        dead_pixels: 0,
        saturated_pixels: 0,
        unmeasured_pixels: 0,
    };
    let mut gain_map = None;
    let mut gain_sd_map = None;
    let mut prnu = None;
    let mut prnu_sd = None;
    if let Some(flat) = flat {
        let f = pass(flat, "flat stack", Some((w, h)), None)?;
        if f.frames < 2 {
            return Err(CalibrationError::invalid(
                "flat",
                format!(
                    "the flat stack {} has {} frame; a variance needs at least 2",
                    flat.name(),
                    f.frames
                ),
            ));
        }
        summary.flat_frames = Some(f.frames);
        summary.clipped_flat_values = f.clipped_total;
        let (md, mf) = (d1.frames as f64, f.frames as f64);
        let mut dmu = Vec::with_capacity(n);
        let mut dmu_sd = Vec::with_capacity(n);
        let mut dv = Vec::with_capacity(n);
        let mut ratio_var = Vec::with_capacity(n);
        for (i, fi) in fl.iter_mut().enumerate() {
            if f.clipped[i] > 0 {
                *fi |= flags::SATURATED;
            }
            let (vd, vf) = (d1.moments.variance(i), f.moments.variance(i));
            let a = f.moments.mean(i) - d1.moments.mean(i);
            let b = vf - vd;
            dmu.push(a);
            dmu_sd.push((vf / mf + vd / md).sqrt());
            dv.push(b);
            // Relative variance of b/a (delta method), see the module docs.
            let var_b = 2.0 * vf * vf / (mf - 1.0) + 2.0 * vd * vd / (md - 1.0);
            let var_a = vf / mf + vd / md;
            ratio_var.push((var_b / (b * b) + var_a / (a * a)).max(0.0));
        }
        let usable0: Vec<f64> = (0..n)
            .filter(|&i| fl[i] & (flags::SATURATED | flags::HOT) == 0)
            .map(|i| dmu[i])
            .collect();
        let median_dmu = median(&usable0).unwrap_or(0.0);
        if median_dmu.is_nan() || median_dmu <= 0.0 {
            return Err(CalibrationError::invalid(
                "flat",
                format!(
                    "the flat stack {} is not brighter than the dark stack (median difference {median_dmu:.3} ADU)",
                    flat.name()
                ),
            ));
        }
        for i in 0..n {
            if dmu[i] < options.dead_below * median_dmu {
                fl[i] |= flags::DEAD;
            }
        }
        let good: Vec<usize> = (0..n)
            .filter(|&i| fl[i] & (flags::SATURATED | flags::HOT | flags::DEAD) == 0)
            .collect();
        if good.is_empty() {
            return Err(CalibrationError::invalid(
                "flat",
                "no pixel is usable for the photon-transfer curve (all saturated, hot or dead)",
            ));
        }
        let mean_dmu = good.iter().map(|&i| dmu[i]).sum::<f64>() / good.len() as f64;
        summary.flat_signal_mean_adu = Some(mean_dmu);
        let p: Vec<f64> = dmu.iter().map(|d| d.max(0.0) / mean_dmu).collect();
        let psd: Vec<f64> = dmu_sd.iter().map(|s| s / mean_dmu).collect();
        let gp: Vec<f64> = good.iter().map(|&i| p[i]).collect();
        let spread = mean_sd(&gp).map_or(0.0, |v| v.1);
        let noise = (good.iter().map(|&i| psd[i] * psd[i]).sum::<f64>() / good.len() as f64).sqrt();
        summary.prnu_spread = Some(noise_corrected(spread, noise));
        summary.prnu_noise = Some(noise);
        prnu = Some(p);
        prnu_sd = Some(psd);

        let (gains, gains_sd) = match options.camera {
            FrameCamera::Emccd => {
                let sum_a: f64 = good.iter().map(|&i| dmu[i]).sum();
                let sum_b: f64 = good.iter().map(|&i| dv[i]).sum();
                let slope = sum_b / sum_a;
                let k = good.len() as f64;
                let resid: f64 = good
                    .iter()
                    .map(|&i| (dv[i] - slope * dmu[i]).powi(2))
                    .sum::<f64>()
                    * k
                    / (k - 1.0).max(1.0);
                let slope_sd = resid.sqrt() / sum_a;
                if slope.is_nan() || slope <= 0.0 {
                    return Err(CalibrationError::invalid(
                        "flat",
                        format!(
                            "the photon-transfer slope of {} is {slope:.4} ADU: the flat's variance does not exceed the dark's",
                            flat.name()
                        ),
                    ));
                }
                let g = slope / f2;
                let g_sd = slope_sd / f2;
                summary.gain_adu_per_e = Some(g);
                summary.gain_sd_adu_per_e = Some(g_sd);
                (vec![g; n], vec![g_sd; n])
            }
            FrameCamera::Scmos => {
                let mut g = vec![0.0; n];
                let mut g_sd = vec![0.0; n];
                let mut measured = Vec::new();
                for i in 0..n {
                    if dmu[i] > 0.0 && dv[i] > 0.0 && fl[i] & flags::DEAD == 0 {
                        g[i] = dv[i] / dmu[i];
                        let r = ratio_var[i].sqrt();
                        // A slope barely above 0 is known to no better than itself.
                        g_sd[i] = if r.is_finite() {
                            g[i] * r.min(1.0)
                        } else {
                            g[i]
                        };
                        if fl[i] & (flags::SATURATED | flags::HOT) == 0 {
                            measured.push(g[i]);
                        }
                    } else {
                        fl[i] |= flags::UNMEASURED;
                    }
                }
                let Some(gm) = median(&measured) else {
                    return Err(CalibrationError::invalid(
                        "flat",
                        "no pixel has a positive photon-transfer slope: the gain cannot be measured",
                    ));
                };
                for i in 0..n {
                    if fl[i] & flags::UNMEASURED != 0 {
                        g[i] = gm;
                        g_sd[i] = gm;
                    }
                }
                let k = measured.len() as f64;
                let sd = mean_sd(&measured).map_or(0.0, |v| v.1);
                let noise = (good
                    .iter()
                    .filter(|&&i| fl[i] & flags::UNMEASURED == 0)
                    .map(|&i| (g_sd[i] / gm).powi(2))
                    .sum::<f64>()
                    / k)
                    .sqrt();
                summary.gain_adu_per_e = Some(gm);
                // Standard error of a median: 1.2533·sd/√k.
                summary.gain_sd_adu_per_e = Some(1.2533 * sd / k.sqrt());
                summary.gain_spread = Some(noise_corrected(
                    robust_sd(&measured).unwrap_or(0.0) / gm,
                    noise,
                ));
                (g, g_sd)
            }
        };
        summary.gain_source = "photon transfer".into();
        gain_map = Some(gains);
        gain_sd_map = Some(gains_sd);
    } else if let Some((g, src)) = &options.fallback_gain {
        if !(g.is_finite() && *g > 0.0) {
            return Err(CalibrationError::invalid(
                "gain",
                format!("{g} ADU/e- is not a positive gain"),
            ));
        }
        summary.gain_adu_per_e = Some(*g);
        summary.gain_source = format!("{src} (not measured: no flat stack)");
        provenance.notes.push(format!(
            "no flat stack: the gain {g:.4} ADU/e- is the {src}'s, not measured"
        ));
        gain_map = Some(vec![*g; n]);
        gain_sd_map = Some(vec![0.0; n]);
    } else {
        provenance.notes.push(
            "no flat stack and no preset: gain, read noise in electrons and PRNU are not known"
                .into(),
        );
    }
    let read_noise_e = gain_map
        .as_ref()
        .map(|g| rn.iter().zip(g).map(|(r, g)| r / g).collect::<Vec<f64>>());
    if let Some(re) = &read_noise_e {
        summary.read_noise_median_e = median(re);
    }
    summary.hot_pixels = flags::count(&fl, flags::HOT);
    summary.noisy_pixels = flags::count(&fl, flags::NOISY);
    summary.dead_pixels = flags::count(&fl, flags::DEAD);
    summary.saturated_pixels = flags::count(&fl, flags::SATURATED);
    summary.unmeasured_pixels = flags::count(&fl, flags::UNMEASURED);
    if summary.clipped_dark_values + summary.clipped_flat_values > 0 {
        provenance.notes.push(format!(
            "{} dark and {} flat values were clipped at 0 or 65535 ADU ({} pixels flagged SATURATED)",
            summary.clipped_dark_values, summary.clipped_flat_values, summary.saturated_pixels
        ));
    }
    let cal = FrameCalibration {
        camera: options.camera,
        width: w,
        height: h,
        offset_adu: offset,
        offset_sd_adu: offset_sd,
        read_noise_adu: rn,
        read_noise_sd_adu: rn_sd,
        gain_adu_per_e: gain_map,
        gain_sd_adu_per_e: gain_sd_map,
        read_noise_e,
        prnu,
        prnu_sd,
        flags: fl,
        summary,
        provenance,
    };
    super::format::validate_frame(&cal)?;
    Ok(cal)
}
