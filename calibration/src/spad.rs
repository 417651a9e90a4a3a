//! SPAD calibration: dark-count map, hot pixels and PRNU from bit-plane counts.

use serde::{Deserialize, Serialize};
use smartagg_model::kernel::IntegerKernel;
use smartagg_model::stats::Detection;

use super::counter::PlaneCounts;
use super::estimate::{
    mean_sd, median, noise_corrected, plane_probability, planes_for_precision, rate_from_counts,
    rate_of_probability, relative_precision, robust_sd, RateKind, LN_20,
};
use super::{flags, Calibration, CalibrationError, Provenance};

/// Stage 0's criterion (docs/DESIGN.md §3, §4): which dark-count rates make a pixel hot.
///
/// A pixel is hot when its own dark counts alone would make the filtered
/// rolling sum H at its position reach the threshold, the other pixels of
/// the kernel seeing the median background:
///
/// `N·(K_c·p_pix + (ΣK − K_c)·p_bg) ≥ T_int`  (integer kernel units)
///
/// with `K_c` the centre weight of the 2-D integer kernel, `ΣK = 2^(2a)`,
/// `p = 1 − e^{−rate·τ}`, `rate_pix = DCR + light`, `rate_bg = median DCR +
/// light`, and `light` the detected background light per pixel while imaging
/// (the preset's; a dark recording has none). Solving for the pixel gives a
/// critical probability `p_crit = (T_int/N − (ΣK − K_c)·p_bg)/K_c` and a
/// critical dark-count rate `DCR_crit = −ln(1 − p_crit)/τ − light`; a pixel
/// is hot when `DCR ≥ DCR_crit`.
///
/// This is the *expected* H reaching T_int. H is a sum of N·k² Bernoulli
/// variables, so its median is close to its mean: a pixel at DCR_crit holds H
/// at or above T_int on about half of all planes, i.e. it would open a false
/// blink almost at once and hold it. Pixels a little below DCR_crit still
/// raise the false-alarm rate; the report counts those within 3 sd of
/// DCR_crit as ambiguous. The expected-value form is kept (rather than a
/// probability level) because it gives one exact rate per (N, T_int,
/// kernel), which is what a mask register loaded at stream start needs.
/// Simulated with the SPCIMAGER 150× registers (N = 109, T_int = 124633,
/// critical DCR 1009 Hz; `hot_criterion_follows_the_threshold`), a pixel at
/// 0.7, 1 and 1.3 × the critical DCR holds H ≥ T_int on 22 %, 49 % and 74 %
/// of planes.
/// A hot pixel raises H most at its own position (weight K_c); pairs of warm
/// neighbours that would cross only together are not masked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HotCriterion {
    /// N, the rolling window, bit-planes.
    pub n_window: u32,
    /// T_int, the integer threshold on H.
    pub threshold_int: u64,
    /// `k1`, the 1-D integer kernel.
    pub kernel_weights: Vec<u32>,
    /// a: `k1` sums to `2^a`.
    pub kernel_shift: u8,
    /// K_c, the centre weight of the 2-D kernel (`k1[c]²`).
    pub kernel_centre_weight: u64,
    /// ΣK = `2^(2a)`.
    pub kernel_sum: u64,
    /// τ, the bit-plane exposure the rates refer to, s.
    pub tau_s: f64,
    /// Detected background light per pixel while imaging, Hz (added to every pixel).
    pub background_light_hz: f64,
    /// Dark-count rate of the other pixels of the kernel (the median), Hz.
    pub neighbour_dcr_hz: f64,
    /// DCR at and above which a pixel is hot, Hz; absent when no rate can
    /// make a pixel cross on its own (even a pixel reading 1 in every plane).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dcr_critical_hz: Option<f64>,
    /// Where N and T_int came from (preset, objective, flux or overrides).
    pub source: String,
}

impl HotCriterion {
    /// The criterion for window `n_window`, threshold `threshold_int` and
    /// `kernel`, at exposure `tau_s`, with `background_light_hz` of detected
    /// light per pixel and the other pixels at `neighbour_dcr_hz`.
    ///
    /// Fails when an input is out of range, or when the background alone
    /// (a pixel with no dark count) already reaches the threshold: then every
    /// pixel would be hot and the threshold does not suit this camera.
    pub fn new(
        n_window: u32,
        threshold_int: u64,
        kernel: &IntegerKernel,
        tau_s: f64,
        background_light_hz: f64,
        neighbour_dcr_hz: f64,
        source: impl Into<String>,
    ) -> Result<HotCriterion, CalibrationError> {
        kernel
            .validate()
            .map_err(|e| CalibrationError::invalid("kernel", e.to_string()))?;
        if n_window == 0 {
            return Err(CalibrationError::invalid("n_window", "must be at least 1"));
        }
        if threshold_int == 0 {
            return Err(CalibrationError::invalid(
                "threshold_int",
                "must be at least 1",
            ));
        }
        for (name, v) in [
            ("tau_s", tau_s),
            ("background_light_hz", background_light_hz),
            ("neighbour_dcr_hz", neighbour_dcr_hz),
        ] {
            if !v.is_finite() || v < 0.0 || (name == "tau_s" && v == 0.0) {
                return Err(CalibrationError::invalid(
                    name,
                    format!("{v} is not a finite rate or time of the right sign"),
                ));
            }
        }
        let c = kernel.size() / 2;
        let kc = kernel.weight_2d(c, c);
        let sum = kernel.sum_2d();
        let p_bg = plane_probability(background_light_hz + neighbour_dcr_hz, tau_s);
        let p_crit =
            (threshold_int as f64 / n_window as f64 - (sum - kc) as f64 * p_bg) / kc as f64;
        let p_light = plane_probability(background_light_hz, tau_s);
        let dcr_critical_hz = if p_crit >= 1.0 {
            None
        } else if p_crit <= p_light {
            return Err(CalibrationError::invalid(
                "threshold_int",
                format!(
                    "T_int = {threshold_int} with N = {n_window} is reached by the background alone (light {background_light_hz:.3} Hz, neighbours' DCR {neighbour_dcr_hz:.3} Hz): every pixel would be hot. Derive N and T for this camera's measured dark-count rate (--flux, --n-window, --threshold-int)"
                ),
            ));
        } else {
            Some((rate_of_probability(p_crit, tau_s) - background_light_hz).max(0.0))
        };
        Ok(HotCriterion {
            n_window,
            threshold_int,
            kernel_weights: kernel.weights.clone(),
            kernel_shift: kernel.shift,
            kernel_centre_weight: kc,
            kernel_sum: sum,
            tau_s,
            background_light_hz,
            neighbour_dcr_hz,
            dcr_critical_hz,
            source: source.into(),
        })
    }

    /// The criterion of a derived detection ([`smartagg_model::stats::derive`]):
    /// its N, T_int, kernel and τ, with the given light and neighbour DCR.
    // Library API for `aggregate --calibration` (a mask for the registers a
    // run actually uses); the calibrate command itself starts from a preset.
    #[allow(dead_code)]
    pub fn from_detection(
        det: &Detection,
        background_light_hz: f64,
        neighbour_dcr_hz: f64,
        source: impl Into<String>,
    ) -> Result<HotCriterion, CalibrationError> {
        HotCriterion::new(
            det.n_window,
            det.threshold_int,
            &det.kernel(),
            det.tau_s,
            background_light_hz,
            neighbour_dcr_hz,
            source,
        )
    }

    /// The same criterion with other N and T_int (kernel, τ, light and
    /// neighbours kept): what a pipeline run with overridden registers needs.
    pub fn with_threshold(
        &self,
        n_window: u32,
        threshold_int: u64,
    ) -> Result<HotCriterion, CalibrationError> {
        HotCriterion::new(
            n_window,
            threshold_int,
            &self.kernel()?,
            self.tau_s,
            self.background_light_hz,
            self.neighbour_dcr_hz,
            format!(
                "{} with N = {n_window}, T_int = {threshold_int}",
                self.source
            ),
        )
    }

    /// The integer kernel.
    pub fn kernel(&self) -> Result<IntegerKernel, CalibrationError> {
        let half = self.kernel_weights.len() / 2;
        let k = IntegerKernel {
            shift: self.kernel_shift,
            weights: self.kernel_weights.clone(),
            // Not used by the criterion; any valid width.
            sigma_px: (half as f64 / 2.0).max(smartagg_model::kernel::MIN_SIGMA_PX),
        };
        k.validate()
            .map_err(|e| CalibrationError::invalid("kernel_weights", e.to_string()))?;
        Ok(k)
    }

    /// Expected H at a pixel of dark-count rate `dcr_hz`, integer kernel units.
    pub fn expected_h(&self, dcr_hz: f64) -> f64 {
        let p = plane_probability(dcr_hz + self.background_light_hz, self.tau_s);
        let p_bg = plane_probability(self.neighbour_dcr_hz + self.background_light_hz, self.tau_s);
        self.n_window as f64
            * (self.kernel_centre_weight as f64 * p
                + (self.kernel_sum - self.kernel_centre_weight) as f64 * p_bg)
    }

    /// Whether a pixel of dark-count rate `dcr_hz` is hot.
    pub fn is_hot(&self, dcr_hz: f64) -> bool {
        self.dcr_critical_hz.is_some_and(|c| dcr_hz >= c)
    }
}

/// What the dark recording says about the whole sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DarkSummary {
    /// Median DCR over all pixels, Hz.
    pub median_dcr_hz: f64,
    /// Mean DCR over the pixels neither hot nor saturated, Hz.
    pub mean_dcr_hz: f64,
    /// DRNU as measured: `1.4826·MAD/median` over pixels neither hot nor saturated.
    pub drnu_measured: f64,
    /// Median per-pixel DCR uncertainty relative to the median DCR.
    pub dcr_relative_sd_median: f64,
    /// DRNU with the counting noise removed: `√max(0, drnu² − noise²)`,
    /// noise = RMS of the per-pixel relative uncertainties.
    pub drnu: f64,
    /// Pixels flagged hot.
    pub hot_pixels: usize,
    /// Hot pixels / all pixels.
    pub hot_fraction: f64,
    /// Pixels within 3 sd of the critical DCR (their hot/not call is uncertain).
    pub ambiguous_pixels: usize,
    /// Pixels that read 1 in every plane.
    pub saturated_pixels: usize,
    /// Pixels without a single count.
    pub no_count_pixels: usize,
    /// Requested relative DCR uncertainty at the median pixel.
    pub precision_requested: f64,
    /// Relative uncertainty reached at the median pixel (absent when it had no count).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub precision_achieved: Option<f64>,
    /// Planes the requested precision needs at the median DCR.
    pub planes_needed: u64,
    /// Whether `planes_needed` is only a lower bound (no count at the median pixel).
    pub planes_needed_is_bound: bool,
}

/// What the flat recording says (present only with a flat).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlatSummary {
    /// Bit-plane exposure of the flat, s.
    pub tau_s: f64,
    /// Bit-plane period of the flat, s.
    pub plane_period_s: f64,
    /// Bit-planes in the flat.
    pub planes: u64,
    /// Median detection rate in the flat (light + dark), Hz.
    pub median_rate_hz: f64,
    /// Mean photon response (flat rate − DCR) of the normalising pixels, Hz:
    /// PRNU = 1 means this response.
    pub mean_response_hz: f64,
    /// Pixels used for the normalisation (not hot, saturated, flat-saturated or dead).
    pub normalising_pixels: usize,
    /// Standard deviation of the PRNU map over the normalising pixels.
    pub prnu_spread_measured: f64,
    /// `1.4826·MAD` of the PRNU map over the normalising pixels.
    pub prnu_spread_robust: f64,
    /// RMS per-pixel PRNU uncertainty over the normalising pixels.
    pub prnu_noise: f64,
    /// PRNU spread with the counting noise removed, `√max(0, spread² − noise²)`.
    pub prnu_spread: f64,
    /// A pixel responding with less than this fraction of the median is dead.
    pub dead_below: f64,
    /// Pixels flagged dead.
    pub dead_pixels: usize,
    /// Pixels that read 1 in every plane of the flat.
    pub flat_saturated_pixels: usize,
}

/// Choices of the SPAD calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct SpadOptions {
    /// Relative DCR uncertainty wanted at the median DCR (e.g. 0.05).
    pub precision: f64,
    /// Accept a recording too short for `precision` (with a warning).
    pub allow_short: bool,
    /// Dead-pixel threshold: response below this fraction of the median.
    pub dead_below: f64,
}

impl Default for SpadOptions {
    fn default() -> Self {
        SpadOptions {
            precision: 0.05,
            allow_short: false,
            dead_below: 0.1,
        }
    }
}

/// How the hot criterion is set up before the median DCR is known.
#[derive(Debug, Clone, PartialEq)]
pub struct CriterionSpec {
    /// N.
    pub n_window: u32,
    /// T_int.
    pub threshold_int: u64,
    /// The integer kernel.
    pub kernel: IntegerKernel,
    /// Detected background light per pixel while imaging, Hz.
    pub background_light_hz: f64,
    /// Where these came from.
    pub source: String,
}

/// A bit-plane recording's counts with its timing.
#[derive(Debug, Clone, PartialEq)]
pub struct Counted {
    /// Per-pixel ones.
    pub counts: PlaneCounts,
    /// Exposure of one bit-plane, s.
    pub tau_s: f64,
    /// Plane period, s.
    pub plane_period_s: f64,
}

/// Computes the SPAD calibration from dark (and optionally flat) counts.
///
/// Returns the calibration and the warnings a user must see (also stored in
/// `provenance.notes`).
pub fn calibrate_spad(
    dark: &Counted,
    flat: Option<&Counted>,
    spec: &CriterionSpec,
    options: &SpadOptions,
    mut provenance: Provenance,
) -> Result<Calibration, CalibrationError> {
    check_options(options)?;
    let (w, h) = (dark.counts.width, dark.counts.height);
    let n = dark.counts.planes;
    if n == 0 {
        return Err(CalibrationError::Empty {
            input: format!("dark recording {}", provenance.dark),
        });
    }
    check_tau("dark recording exposure", dark.tau_s)?;
    if let Some(f) = flat {
        if (f.counts.width, f.counts.height) != (w, h) {
            return Err(CalibrationError::SizeMismatch {
                what: format!(
                    "flat recording {} against the dark recording",
                    provenance.flat.as_deref().unwrap_or("flat")
                ),
                expected: (w, h),
                found: (f.counts.width, f.counts.height),
            });
        }
    }
    let tau = dark.tau_s;
    let pixels = w as usize * h as usize;
    let mut dcr = Vec::with_capacity(pixels);
    let mut sd = Vec::with_capacity(pixels);
    let mut fl = vec![0u8; pixels];
    for (i, &k) in dark.counts.ones.iter().enumerate() {
        let e = rate_from_counts(k, n, tau);
        match e.kind {
            RateKind::Estimate => {}
            RateKind::NoCounts { .. } => fl[i] |= flags::NO_COUNTS,
            RateKind::Saturated => fl[i] |= flags::SATURATED,
        }
        dcr.push(e.rate_hz);
        sd.push(e.sd_hz);
    }
    let median_dcr = median(&dcr).unwrap_or(0.0);

    // Precision at the median pixel, and the planes it needs.
    let (achieved, needed, needed_is_bound) = if median_dcr > 0.0 {
        let p = plane_probability(median_dcr, tau);
        (
            Some(relative_precision(p, n as f64)),
            planes_for_precision(p, options.precision).ceil(),
            false,
        )
    } else {
        // No count at the median pixel: its rate is below ln 20/(nτ), and a
        // lower rate needs more planes, so this gives a lower bound.
        let p_up = plane_probability(LN_20 / (n as f64 * tau), tau);
        (
            None,
            planes_for_precision(p_up, options.precision).ceil(),
            true,
        )
    };
    let needed = if needed.is_finite() {
        needed.min(u64::MAX as f64) as u64
    } else {
        u64::MAX
    };
    if needed > n || needed_is_bound {
        let err = CalibrationError::TooShort {
            planes: n,
            needed: needed.max(n + 1),
            needed_is_bound,
            precision: options.precision,
            achieved,
            median_dcr_hz: if needed_is_bound {
                LN_20 / (n as f64 * tau)
            } else {
                median_dcr
            },
            plane_period_s: dark.plane_period_s,
        };
        if !options.allow_short {
            return Err(err);
        }
        provenance
            .notes
            .push(format!("accepted with --allow-short: {err}"));
    }

    // Hot pixels.
    let criterion = HotCriterion::new(
        spec.n_window,
        spec.threshold_int,
        &spec.kernel,
        tau,
        spec.background_light_hz,
        median_dcr,
        spec.source.clone(),
    )?;
    let mut ambiguous = 0;
    for i in 0..pixels {
        if criterion.is_hot(dcr[i]) {
            fl[i] |= flags::HOT;
        }
        if let Some(c) = criterion.dcr_critical_hz {
            if fl[i] & flags::SATURATED == 0 && (dcr[i] - c).abs() < 3.0 * sd[i] {
                ambiguous += 1;
            }
        }
    }
    if criterion.dcr_critical_hz.is_none() {
        provenance.notes.push(format!(
            "no dark-count rate can make a pixel cross T_int = {} on its own (N = {}): no pixel is hot",
            criterion.threshold_int, criterion.n_window
        ));
    }

    // DRNU over the pixels neither hot nor saturated.
    let normal: Vec<usize> = (0..pixels)
        .filter(|&i| fl[i] & (flags::HOT | flags::SATURATED) == 0)
        .collect();
    let normal_dcr: Vec<f64> = normal.iter().map(|&i| dcr[i]).collect();
    let (mean_dcr, drnu_measured, noise) = if median_dcr > 0.0 && !normal.is_empty() {
        let (m, _) = mean_sd(&normal_dcr).unwrap_or((0.0, 0.0));
        let spread = robust_sd(&normal_dcr).unwrap_or(0.0) / median_dcr;
        let ms: f64 = normal
            .iter()
            .map(|&i| (sd[i] / median_dcr).powi(2))
            .sum::<f64>()
            / normal.len() as f64;
        (m, spread, ms.sqrt())
    } else {
        (mean_sd(&normal_dcr).map_or(0.0, |v| v.0), 0.0, 0.0)
    };
    let rel_sd: Vec<f64> = if median_dcr > 0.0 {
        sd.iter().map(|s| s / median_dcr).collect()
    } else {
        vec![0.0]
    };
    let hot = flags::count(&fl, flags::HOT);
    let summary = DarkSummary {
        median_dcr_hz: median_dcr,
        mean_dcr_hz: mean_dcr,
        drnu_measured,
        dcr_relative_sd_median: median(&rel_sd).unwrap_or(0.0),
        drnu: noise_corrected(drnu_measured, noise),
        hot_pixels: hot,
        hot_fraction: hot as f64 / pixels as f64,
        ambiguous_pixels: ambiguous,
        saturated_pixels: flags::count(&fl, flags::SATURATED),
        no_count_pixels: flags::count(&fl, flags::NO_COUNTS),
        precision_requested: options.precision,
        precision_achieved: achieved,
        planes_needed: needed,
        planes_needed_is_bound: needed_is_bound,
    };

    let (prnu, prnu_sd, flat_summary) = match flat {
        None => (None, None, None),
        Some(f) => {
            let (p, s, summary) = prnu_from_flat(f, &dcr, &sd, &mut fl, options, &provenance)?;
            (Some(p), Some(s), Some(summary))
        }
    };
    let cal = Calibration {
        width: w,
        height: h,
        tau_s: tau,
        plane_period_s: dark.plane_period_s,
        planes: n,
        dcr_hz: dcr,
        dcr_sd_hz: sd,
        flags: fl,
        prnu,
        prnu_sd,
        hot_criterion: criterion,
        dark: summary,
        flat: flat_summary,
        provenance,
    };
    cal.validate()?;
    Ok(cal)
}

fn check_options(o: &SpadOptions) -> Result<(), CalibrationError> {
    if !(o.precision.is_finite() && o.precision > 0.0 && o.precision < 1.0) {
        return Err(CalibrationError::invalid(
            "precision",
            format!("{} must be a relative uncertainty in (0, 1)", o.precision),
        ));
    }
    if !(o.dead_below.is_finite() && (0.0..1.0).contains(&o.dead_below)) {
        return Err(CalibrationError::invalid(
            "dead_below",
            format!("{} must be a fraction in [0, 1)", o.dead_below),
        ));
    }
    Ok(())
}

fn check_tau(name: &'static str, tau: f64) -> Result<(), CalibrationError> {
    if tau.is_finite() && tau > 0.0 {
        Ok(())
    } else {
        Err(CalibrationError::invalid(
            name,
            format!("{tau} s is not a positive exposure"),
        ))
    }
}

/// PRNU: each pixel's photon response (flat rate − DCR, both pile-up
/// corrected) divided by the mean response of the normalising pixels.
fn prnu_from_flat(
    f: &Counted,
    dcr: &[f64],
    dcr_sd: &[f64],
    fl: &mut [u8],
    options: &SpadOptions,
    provenance: &Provenance,
) -> Result<(Vec<f64>, Vec<f64>, FlatSummary), CalibrationError> {
    let pixels = dcr.len();
    let flat_name = provenance.flat.clone().unwrap_or_else(|| "flat".into());
    let n = f.counts.planes;
    if n == 0 {
        return Err(CalibrationError::Empty {
            input: format!("flat recording {flat_name}"),
        });
    }
    check_tau("flat recording exposure", f.tau_s)?;
    let mut rate = Vec::with_capacity(pixels);
    let mut response = Vec::with_capacity(pixels);
    let mut response_sd = Vec::with_capacity(pixels);
    for (i, &k) in f.counts.ones.iter().enumerate() {
        let e = rate_from_counts(k, n, f.tau_s);
        if e.kind == RateKind::Saturated {
            fl[i] |= flags::FLAT_SATURATED;
        }
        rate.push(e.rate_hz);
        response.push(e.rate_hz - dcr[i]);
        response_sd.push(e.sd_hz.hypot(dcr_sd[i]));
    }
    let usable = |f: u8| f & (flags::HOT | flags::SATURATED | flags::FLAT_SATURATED) == 0;
    let usable_resp: Vec<f64> = (0..pixels)
        .filter(|&i| usable(fl[i]))
        .map(|i| response[i])
        .collect();
    let median_resp = median(&usable_resp).unwrap_or(0.0);
    if median_resp.is_nan() || median_resp <= 0.0 {
        return Err(CalibrationError::invalid(
            "flat",
            format!(
                "the flat {flat_name} shows no photon response: the median pixel detects {median_resp:.3} Hz more in the flat than in the dark"
            ),
        ));
    }
    // The counting noise of the median pixel's response, against the
    // precision asked of the dark: a short flat would mark pixels dead and
    // report a PRNU that is only noise.
    let usable_sd: Vec<f64> = (0..pixels)
        .filter(|&i| usable(fl[i]))
        .map(|i| response_sd[i])
        .collect();
    let achieved = median(&usable_sd).unwrap_or(f64::INFINITY) / median_resp;
    if achieved.is_nan() || achieved > options.precision {
        let needed = if achieved.is_finite() {
            (n as f64 * (achieved / options.precision).powi(2)).ceil() as u64
        } else {
            u64::MAX
        };
        let err = CalibrationError::FlatTooShort {
            planes: n,
            needed,
            precision: options.precision,
            achieved,
            plane_period_s: f.plane_period_s,
        };
        if !options.allow_short {
            return Err(err);
        }
        eprintln!("warning: {err} (accepted with --allow-short)");
    }
    for i in 0..pixels {
        if response[i] < options.dead_below * median_resp && fl[i] & flags::FLAT_SATURATED == 0 {
            fl[i] |= flags::DEAD;
        }
    }
    let norm: Vec<usize> = (0..pixels)
        .filter(|&i| usable(fl[i]) && fl[i] & flags::DEAD == 0)
        .collect();
    let mean_resp = norm.iter().map(|&i| response[i]).sum::<f64>() / norm.len().max(1) as f64;
    if norm.is_empty() || mean_resp.is_nan() || mean_resp <= 0.0 {
        return Err(CalibrationError::invalid(
            "flat",
            format!("no pixel of the flat {flat_name} is usable to normalise the PRNU"),
        ));
    }
    // Negative responses (possible only for dead pixels) are stored as 0:
    // a relative efficiency is never negative.
    let prnu: Vec<f64> = response.iter().map(|r| r.max(0.0) / mean_resp).collect();
    let prnu_sd: Vec<f64> = response_sd.iter().map(|s| s / mean_resp).collect();
    let norm_prnu: Vec<f64> = norm.iter().map(|&i| prnu[i]).collect();
    let spread = mean_sd(&norm_prnu).map_or(0.0, |v| v.1);
    let noise =
        (norm.iter().map(|&i| prnu_sd[i] * prnu_sd[i]).sum::<f64>() / norm.len() as f64).sqrt();
    let summary = FlatSummary {
        tau_s: f.tau_s,
        plane_period_s: f.plane_period_s,
        planes: n,
        median_rate_hz: median(&rate).unwrap_or(0.0),
        mean_response_hz: mean_resp,
        normalising_pixels: norm.len(),
        prnu_spread_measured: spread,
        prnu_spread_robust: robust_sd(&norm_prnu).unwrap_or(0.0),
        prnu_noise: noise,
        prnu_spread: noise_corrected(spread, noise),
        dead_below: options.dead_below,
        dead_pixels: flags::count(fl, flags::DEAD),
        flat_saturated_pixels: flags::count(fl, flags::FLAT_SATURATED),
    };
    Ok((prnu, prnu_sd, summary))
}
