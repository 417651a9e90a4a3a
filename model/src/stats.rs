//! The paper's detection statistics (Eq. 1–7 of §3) with the integer kernel
//! actually used: the window N (bit-planes summed) and the threshold T.
//!
//! ## Model (paper §3)
//!
//! A molecule is centred on the centre of pixel (i,j). Its PSF `G` is the
//! pixel-integrated Gaussian of width σ (the 2-D product of 1-D `erf`
//! differences, [`crate::kernel::pixel_gaussian`]); `G` is the PSF, so it
//! is **not** renormalised to the k×k kernel footprint. Each pixel of a
//! bit-plane is a Bernoulli variable `B` with, writing `x = I·G·η·τ + b·τ`
//! (on) or `x = b·τ` (off):
//!
//! * Eq. 1: `E(B) = 1 − e^{−x}`, computed as `−expm1(−x)`;
//! * Eq. 2: `Var(B) = e^{−x}(1 − e^{−x})`, computed as `e^{−x}·(−expm1(−x))`.
//!
//! The filtered plane at (i,j) is `F = Σ K·B` with `K` the **normalised
//! integer kernel** (`k1⊗k1/2^(2a)`, exactly what the gateware computes):
//!
//! * Eq. 3/4 per plane: `E(F) = Σ K·E(B)`, `Var(F) = Σ K²·Var(B)`;
//!   the on/off difference is summed per pixel as
//!   `E(B_on) − E(B_off) = e^{−bτ}·(−expm1(−I·G·η·τ))`, so it never cancels;
//! * Eq. 6: `N = 9(√Var F_off + √Var F_on)² / (E F_on − E F_off)²`,
//!   reported real ([`Detection::n_window_real`]) and rounded up, at least 1
//!   ([`Detection::n_window`]);
//! * Eq. 7: `T = N·E(F_off) + 3√(N·Var F_off)` for the integer N, in
//!   normalised units; the pipeline's `H = Σ K_int·S` is in units of
//!   `2^−(2a)`, so `T_int = max(1, ⌈T·2^(2a)⌉)` and a pixel fires when
//!   `H ≥ T_int`. The `max(1, ·)` matters when b = 0: then T = 0 and "H ≥ 0"
//!   would fire everywhere.
//!
//! ## Decisions
//!
//! * An undetectable molecule is an error ([`StatsError::Undetectable`]),
//!   never NaN or ∞: no detected molecule photon (`I·η = 0`), no separation
//!   of the on and off means (saturated background), or `N` above
//!   [`MAX_WINDOW_PLANES`] (10^7 planes: 1000 s of 10 kHz bit-planes, far
//!   beyond any blink).
//! * The Gaussian-approximation probabilities at `T_int` use
//!   `P(H ≥ T_int) ≈ Q((T_int·2^(−2a) − E H)/sd H)` without continuity
//!   correction, as the paper's 3σ argument does; the exact ones are in
//!   [`crate::false_alarm`].
//! * `N` with the ideal (real) truncated Gaussian kernel is reported beside
//!   the integer kernel's as [`Detection::n_window_real_ideal_kernel`] to
//!   show the effect of quantisation.
//!
//! ## Values (default kernel, shift 8; `tests/statistics.rs` prints them)
//!
//! | preset | σ px | k1 | N (real) | N | T | T_int |
//! |---|---|---|---|---|---|---|
//! | SPCIMAGER 150× | 1.514 | 2 10 29 54 66 54 29 10 2 | 108.09 | 109 | 1.90174 | 124633 |
//! | SPCIMAGER 60× | 0.606 | 2 51 150 51 2 | 64.20 | 65 | 2.84112 | 186196 |
//! | projected 150× | 1.514 | as 150× | 17.59 | 18 | 0.35000 | 22938 |
//!
//! The paper quotes N ≈ 108, 65 and 18. With the real kernel N would be
//! 108.28, 64.46 and 17.64. At T_int the exact detection probability
//! (molecule on for the whole window, [`crate::false_alarm::detection_probability`])
//! is 0.9994 for SPCIMAGER 150× (Gaussian: 0.9987), so Eq. 5's ~99 % holds;
//! the exact false-alarm probability per pixel-plane is 2.77e-3, twice the
//! Gaussian 1.35e-3 ([`crate::false_alarm`]).

use crate::kernel::{
    pixel_gaussian, IntegerKernel, KernelError, KernelQuantisation, DEFAULT_SHIFT,
};
use crate::params::{check_non_negative, check_positive, check_range, Camera, ParamError, Preset};
use serde::Serialize;
use thiserror::Error;

/// Largest window accepted: beyond 10^7 bit-planes (1000 s at 10 kHz) the
/// molecule is called undetectable.
pub const MAX_WINDOW_PLANES: f64 = 1e7;

/// Why the window and threshold could not be derived.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StatsError {
    /// An input outside its physical range (the message names it).
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The kernel size or shift is invalid (the message names it).
    #[error(transparent)]
    Kernel(#[from] KernelError),
    /// The molecule cannot be told apart from the background.
    #[error(
        "the molecule is undetectable: {why} (flux_hz = {}, background_rate_hz = {}, eta = {}, tau_s = {}, sigma_px = {})",
        crate::params::fmt_num(*flux_hz),
        crate::params::fmt_num(*background_rate_hz),
        crate::params::fmt_num(*eta),
        crate::params::fmt_num(*tau_s),
        crate::params::fmt_num(*sigma_px)
    )]
    Undetectable {
        /// What failed.
        why: String,
        /// Molecule flux I, photons/s.
        flux_hz: f64,
        /// Detected background b per pixel, Hz.
        background_rate_hz: f64,
        /// Detection efficiency η.
        eta: f64,
        /// Bit-plane exposure τ, s.
        tau_s: f64,
        /// PSF width σ, pixels.
        sigma_px: f64,
    },
    /// A frame camera preset was given where bit-planes are needed.
    #[error("preset `{preset}` is a {kind} frame camera: the window N and threshold T apply to bit-plane (SPAD) cameras only")]
    NotBitPlaneCamera {
        /// The preset's name.
        preset: String,
        /// Its camera technology.
        kind: &'static str,
    },
}

/// Inputs of Eq. 1–7.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DetectionInputs {
    /// η: PDE × fill factor (0..=1).
    pub eta: f64,
    /// b: detected background per pixel, Hz (background light × η + dark count).
    pub background_rate_hz: f64,
    /// I: molecule photons per second onto the sensor while on.
    pub flux_hz: f64,
    /// τ: bit-plane exposure, s (the exposure, not the plane period).
    pub tau_s: f64,
    /// σ: PSF and kernel width, pixels (0.3..=6).
    pub sigma_px: f64,
    /// Kernel size k; `None` for the default `2⌈2σ⌉+1`.
    pub kernel_size: Option<usize>,
    /// Kernel precision a (`k1` sums to `2^a`), 4..=12.
    pub kernel_shift: u8,
}

impl DetectionInputs {
    /// The inputs of a SPAD preset: η = PDE × fill factor, b =
    /// [`Preset::background_rate_hz`], τ = the bit-plane exposure, σ =
    /// [`Preset::sigma_px`], the preset's molecule flux unless overridden,
    /// default kernel size and [`DEFAULT_SHIFT`].
    ///
    /// EMCCD and sCMOS presets are rejected: N and T describe bit-planes.
    pub fn from_preset(preset: &Preset, flux_override: Option<f64>) -> Result<Self, StatsError> {
        let cam = match &preset.camera {
            Camera::Spad(c) => c,
            Camera::Emccd(_) => {
                return Err(StatsError::NotBitPlaneCamera {
                    preset: preset.name.to_string(),
                    kind: "EMCCD",
                })
            }
            Camera::Scmos(_) => {
                return Err(StatsError::NotBitPlaneCamera {
                    preset: preset.name.to_string(),
                    kind: "sCMOS",
                })
            }
        };
        let flux_hz = match flux_override {
            Some(f) => check_non_negative("flux_hz", f)?,
            None => preset.light.flux_hz,
        };
        let inputs = DetectionInputs {
            eta: cam.eta(),
            background_rate_hz: preset.background_rate_hz(),
            flux_hz,
            tau_s: cam.exposure_s,
            sigma_px: preset.sigma_px(),
            kernel_size: None,
            kernel_shift: DEFAULT_SHIFT,
        };
        inputs.validate()?;
        Ok(inputs)
    }

    /// Checks every input; the error names the first bad one.
    pub fn validate(&self) -> Result<(), StatsError> {
        check_range("eta", self.eta, 0.0, 1.0)?;
        check_non_negative("background_rate_hz", self.background_rate_hz)?;
        check_non_negative("flux_hz", self.flux_hz)?;
        check_positive("tau_s", self.tau_s)?;
        check_range(
            "sigma_px",
            self.sigma_px,
            crate::kernel::MIN_SIGMA_PX,
            crate::kernel::MAX_SIGMA_PX,
        )?;
        Ok(())
    }

    /// The integer kernel these inputs select.
    pub fn kernel(&self) -> Result<IntegerKernel, StatsError> {
        let size = self
            .kernel_size
            .unwrap_or_else(|| IntegerKernel::default_size(self.sigma_px));
        Ok(IntegerKernel::gaussian(
            self.sigma_px,
            size,
            self.kernel_shift,
        )?)
    }
}

/// Everything Eq. 1–7 give for one set of inputs (printed as JSON by the CLI).
///
/// "Normalised units" means units of the normalised kernel (`ΣK = 1`): a
/// pixel that detects a photon in every plane adds 1 per plane to F.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// η, as given.
    pub eta: f64,
    /// b, Hz, as given.
    pub background_rate_hz: f64,
    /// I, photons/s, as given.
    pub flux_hz: f64,
    /// τ, s, as given.
    pub tau_s: f64,
    /// σ, pixels, as given.
    pub sigma_px: f64,
    /// Kernel size k.
    pub kernel_size: usize,
    /// Kernel shift a (`k1` sums to `2^a`).
    pub kernel_shift: u8,
    /// `k1`, the 1-D integer weights.
    pub kernel_weights: Vec<u32>,
    /// Quantisation error of the kernel.
    pub kernel_quantisation: KernelQuantisation,
    /// Eq. 1 off: E(B) of a background-only pixel, `1 − e^{−bτ}`.
    pub p_off: f64,
    /// Eq. 2 off: Var(B) of a background-only pixel.
    pub var_b_off: f64,
    /// Eq. 1 on: E(B) over the k×k window around the molecule, row-major.
    pub e_b_on: Vec<f64>,
    /// Eq. 2 on: Var(B) over the k×k window, row-major.
    pub var_b_on: Vec<f64>,
    /// Fraction of the PSF falling inside the k×k window (Σ G).
    pub psf_fraction_in_window: f64,
    /// Eq. 3 off: E(F) per plane, normalised units.
    pub e_f_off: f64,
    /// Eq. 4 off: Var(F) per plane.
    pub var_f_off: f64,
    /// Eq. 3 on: E(F) per plane at the molecule's pixel.
    pub e_f_on: f64,
    /// Eq. 4 on: Var(F) per plane at the molecule's pixel.
    pub var_f_on: f64,
    /// Eq. 6 before rounding.
    pub n_window_real: f64,
    /// Eq. 6 with the ideal (unquantised) truncated Gaussian kernel, for comparison.
    pub n_window_real_ideal_kernel: f64,
    /// N: Eq. 6 rounded up, at least 1 — the window in bit-planes.
    pub n_window: u32,
    /// T: Eq. 7 at the integer N, normalised units.
    pub threshold: f64,
    /// `T_int = max(1, ⌈T·2^(2a)⌉)`: the pipeline fires when `H ≥ T_int`.
    pub threshold_int: u64,
    /// `2^(−2a)`: the value of one unit of H in normalised units.
    pub threshold_unit: f64,
    /// `T_int·2^(−2a) − T`: the threshold's quantisation error, normalised units.
    pub threshold_quantisation_abs: f64,
    /// `(T_int·2^(−2a) − T)/T`; `None` when T = 0 (b = 0).
    pub threshold_quantisation_rel: Option<f64>,
    /// E(H) = N·E(F) when off (normalised units, integer N).
    pub e_h_off: f64,
    /// sd(H) = √(N·Var F) when off.
    pub sd_h_off: f64,
    /// E(H) when on for the whole window.
    pub e_h_on: f64,
    /// sd(H) when on for the whole window.
    pub sd_h_on: f64,
    /// Gaussian approximation of P(H ≥ T_int) for a molecule on for N planes.
    pub gaussian_detection_probability: f64,
    /// Gaussian approximation of P(H ≥ T_int) per background-only pixel-plane.
    pub gaussian_false_alarm_probability: f64,
}

impl Detection {
    /// The same statistics with window `n` (≥ 1) instead of Eq. 6's: Eq. 7's
    /// threshold `T = N·E(F_off) + 3√(N·Var F_off)`, `T_int = max(1,
    /// ⌈T·2^(2a)⌉)` and the window's moments follow it ([`derive()`] ends here
    /// with Eq. 6's N).
    pub fn at_window(&self, n: u32) -> Detection {
        let n = n.max(1);
        let nf = n as f64;
        let threshold = nf * self.e_f_off + 3.0 * (nf * self.var_f_off).sqrt();
        let threshold_int = ((threshold / self.threshold_unit).ceil() as u64).max(1);
        let t_q = threshold_int as f64 * self.threshold_unit;
        let e_h_off = nf * self.e_f_off;
        let sd_h_off = (nf * self.var_f_off).sqrt();
        let e_h_on = nf * self.e_f_on;
        let sd_h_on = (nf * self.var_f_on).sqrt();
        Detection {
            n_window: n,
            threshold,
            threshold_int,
            threshold_quantisation_abs: t_q - threshold,
            threshold_quantisation_rel: (threshold > 0.0).then(|| (t_q - threshold) / threshold),
            e_h_off,
            sd_h_off,
            e_h_on,
            sd_h_on,
            gaussian_detection_probability: gaussian_at_least(t_q, e_h_on, sd_h_on),
            gaussian_false_alarm_probability: gaussian_at_least(t_q, e_h_off, sd_h_off),
            ..self.clone()
        }
    }

    /// The integer kernel these statistics used.
    pub fn kernel(&self) -> IntegerKernel {
        IntegerKernel {
            shift: self.kernel_shift,
            weights: self.kernel_weights.clone(),
            sigma_px: self.sigma_px,
        }
    }
}

/// Standard normal upper tail `Q(z) = P(Z ≥ z) = erfc(z/√2)/2`.
pub fn normal_sf(z: f64) -> f64 {
    0.5 * crate::kernel::erfc(z / std::f64::consts::SQRT_2)
}

/// Gaussian approximation of `P(X ≥ x)` for mean `mean` and sd `sd`; a
/// degenerate (sd = 0) variable is a point mass.
fn gaussian_at_least(x: f64, mean: f64, sd: f64) -> f64 {
    if sd > 0.0 {
        normal_sf((x - mean) / sd)
    } else if mean >= x {
        1.0
    } else {
        0.0
    }
}

/// Per-plane filtered statistics for a normalised kernel `k` (k×k row-major).
struct PlaneStats {
    e_f_off: f64,
    var_f_off: f64,
    delta_e_f: f64,
    var_f_on: f64,
}

fn plane_stats(k: &[f64], p_off: f64, var_b_off: f64, dp: &[f64], var_b_on: &[f64]) -> PlaneStats {
    let mut s = PlaneStats {
        e_f_off: 0.0,
        var_f_off: 0.0,
        delta_e_f: 0.0,
        var_f_on: 0.0,
    };
    for (idx, &w) in k.iter().enumerate() {
        s.e_f_off += w * p_off;
        s.var_f_off += w * w * var_b_off;
        s.delta_e_f += w * dp[idx];
        s.var_f_on += w * w * var_b_on[idx];
    }
    s
}

/// Eq. 6 before rounding, or `None` when the means are not separated.
fn window_real(s: &PlaneStats) -> Option<f64> {
    if s.delta_e_f.is_nan() || s.delta_e_f <= 0.0 || !s.delta_e_f.is_finite() {
        return None;
    }
    // Written as a square of a ratio so a tiny separation cannot underflow.
    let ratio = 3.0 * (s.var_f_off.sqrt() + s.var_f_on.sqrt()) / s.delta_e_f;
    let n = ratio * ratio;
    n.is_finite().then_some(n)
}

/// Derives N and T (Eq. 1–7) with the integer kernel of `inputs`.
pub fn derive(inputs: &DetectionInputs) -> Result<Detection, StatsError> {
    inputs.validate()?;
    let kernel = inputs.kernel()?;
    let undetectable = |why: String| StatsError::Undetectable {
        why,
        flux_hz: inputs.flux_hz,
        background_rate_hz: inputs.background_rate_hz,
        eta: inputs.eta,
        tau_s: inputs.tau_s,
        sigma_px: inputs.sigma_px,
    };
    let signal = inputs.flux_hz * inputs.eta * inputs.tau_s; // detected photons/plane
    if !signal.is_finite() {
        return Err(ParamError::Invalid {
            name: "flux_hz",
            value: inputs.flux_hz,
            why: "flux_hz × eta × tau_s overflows a floating-point number",
        }
        .into());
    }
    if signal.is_nan() || signal <= 0.0 {
        return Err(undetectable(
            "no molecule photon is detected (flux_hz × eta × tau_s = 0)".into(),
        ));
    }
    let k = kernel.size();
    let half = (k / 2) as f64;
    let g1: Vec<f64> = (0..k)
        .map(|i| pixel_gaussian(inputs.sigma_px, i as f64 - half))
        .collect();
    let bt = inputs.background_rate_hz * inputs.tau_s;
    let p_off = -(-bt).exp_m1();
    let e_off = (-bt).exp();
    let var_b_off = e_off * p_off;
    let mut e_b_on = Vec::with_capacity(k * k);
    let mut var_b_on = Vec::with_capacity(k * k);
    let mut dp = Vec::with_capacity(k * k);
    let mut psf_fraction_in_window = 0.0;
    for gi in &g1 {
        for gj in &g1 {
            let g = gi * gj;
            psf_fraction_in_window += g;
            let s = signal * g;
            let x = s + bt;
            let p = -(-x).exp_m1();
            e_b_on.push(p);
            var_b_on.push((-x).exp() * p);
            dp.push(e_off * -(-s).exp_m1());
        }
    }
    let k_int: Vec<f64> = kernel.normalised_2d().into_iter().flatten().collect();
    let ideal = kernel.ideal_1d();
    let k_ideal: Vec<f64> = ideal
        .iter()
        .flat_map(|a| ideal.iter().map(move |b| a * b))
        .collect();
    let st = plane_stats(&k_int, p_off, var_b_off, &dp, &var_b_on);
    let st_ideal = plane_stats(&k_ideal, p_off, var_b_off, &dp, &var_b_on);
    let n_real = window_real(&st).ok_or_else(|| {
        undetectable(format!(
            "the mean filtered value when on does not exceed the one when off (E(F_on) − E(F_off) = {:e}); {}",
            st.delta_e_f,
            if p_off > 0.5 {
                "the background saturates the pixels"
            } else {
                "the molecule gives too few photons per bit-plane (flux_hz × eta × tau_s) to tell apart"
            }
        ))
    })?;
    if n_real > MAX_WINDOW_PLANES {
        return Err(undetectable(format!(
            "Eq. 6 needs a window of N = {n_real:.4e} bit-planes, more than the cap of {MAX_WINDOW_PLANES:e}"
        )));
    }
    let n_real_ideal = window_real(&st_ideal).unwrap_or(f64::MAX);
    let n = (n_real.ceil() as u32).max(1);
    // H is in units of 2^−(2a), the 2-D kernel's sum (a power of two, so
    // that dividing by the unit is exact).
    let threshold_unit = 1.0 / kernel.sum_2d() as f64;
    let e_f_on = st.e_f_off + st.delta_e_f;
    // Eq. 7 and the window's moments at the integer N: `at_window`.
    let per_plane = Detection {
        eta: inputs.eta,
        background_rate_hz: inputs.background_rate_hz,
        flux_hz: inputs.flux_hz,
        tau_s: inputs.tau_s,
        sigma_px: inputs.sigma_px,
        kernel_size: k,
        kernel_shift: kernel.shift,
        kernel_quantisation: kernel.quantisation(),
        kernel_weights: kernel.weights,
        p_off,
        var_b_off,
        e_b_on,
        var_b_on,
        psf_fraction_in_window,
        e_f_off: st.e_f_off,
        var_f_off: st.var_f_off,
        e_f_on,
        var_f_on: st.var_f_on,
        n_window_real: n_real,
        n_window_real_ideal_kernel: n_real_ideal,
        n_window: n,
        threshold: 0.0,
        threshold_int: 0,
        threshold_unit,
        threshold_quantisation_abs: 0.0,
        threshold_quantisation_rel: None,
        e_h_off: 0.0,
        sd_h_off: 0.0,
        e_h_on: 0.0,
        sd_h_on: 0.0,
        gaussian_detection_probability: 0.0,
        gaussian_false_alarm_probability: 0.0,
    };
    Ok(per_plane.at_window(n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::PresetName;

    #[test]
    fn a_vanishing_flux_is_too_dim_not_a_saturating_background() {
        let p = Preset::new(PresetName::Spcimager, 150).unwrap();
        let e = DetectionInputs::from_preset(&p, Some(1e-300))
            .and_then(|i| derive(&i))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("too few photons") && !e.contains("saturates"),
            "{e}"
        );
        assert!(e.contains("flux_hz = 1e-300") && e.len() < 400, "{e}");
    }

    #[test]
    fn presets_give_the_papers_windows() {
        let n = |name, obj| {
            let p = Preset::new(name, obj).unwrap();
            derive(&DetectionInputs::from_preset(&p, None).unwrap()).unwrap()
        };
        let d = n(PresetName::Spcimager, 150);
        assert_eq!(d.n_window, 109, "{}", d.n_window_real);
        assert_eq!(d.kernel_weights, vec![2, 10, 29, 54, 66, 54, 29, 10, 2]);
        assert_eq!(n(PresetName::Spcimager, 60).n_window, 65);
        assert_eq!(n(PresetName::SpcimagerProjected, 150).n_window, 18);
    }

    #[test]
    fn frame_cameras_are_rejected() {
        let p = Preset::new(PresetName::Emccd, 150).unwrap();
        let e = DetectionInputs::from_preset(&p, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("bit-plane (SPAD)") && e.contains("emccd"), "{e}");
        let p = Preset::new(PresetName::Scmos, 60).unwrap();
        assert!(DetectionInputs::from_preset(&p, None).is_err());
    }
}
