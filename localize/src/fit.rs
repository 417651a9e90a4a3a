//! What every estimator returns, its options, and the dispatcher.

use crate::error::{check_option, LocalizeError};
use crate::roi::RoiView;
use serde::{Deserialize, Serialize};

/// Outcome of one fit. The code is written to the `fit_status` column of the
/// table (0 = ok); a failed fit keeps finite values and is never dropped
/// silently.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[repr(u8)]
pub enum FitStatus {
    /// Converged inside the ROI with a finite Cramér–Rao bound.
    Ok = 0,
    /// No photons above background: a zero-photon ROI, a fitted intensity
    /// at its lower bound, or one below its own standard deviation.
    NoSignal = 1,
    /// Stopped at the iteration limit.
    NotConverged = 2,
    /// The fitted position lies outside the ROI (by more than half a pixel).
    OutsideRoi = 3,
    /// The fitted σ sits on its lower or upper bound (hot pixel, merged
    /// emitters, or wrong PSF model).
    SigmaAtBound = 4,
    /// The Fisher information is singular: the position is not determined.
    Singular = 5,
    /// The ROI contains NaN or infinite values.
    NonFiniteInput = 6,
    /// Every pixel of a SPAD ROI detected in every bit-plane: the rate is
    /// unbounded.
    Saturated = 7,
    /// Counts impossible for the record (a SPAD pixel count above the number
    /// of bit-planes summed).
    InconsistentCounts = 8,
}

impl FitStatus {
    /// Every status, by code.
    pub const ALL: [FitStatus; 9] = [
        FitStatus::Ok,
        FitStatus::NoSignal,
        FitStatus::NotConverged,
        FitStatus::OutsideRoi,
        FitStatus::SigmaAtBound,
        FitStatus::Singular,
        FitStatus::NonFiniteInput,
        FitStatus::Saturated,
        FitStatus::InconsistentCounts,
    ];

    /// Numeric code (the `fit_status` column).
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The status of a code, if it is one.
    pub fn from_code(code: u8) -> Option<FitStatus> {
        FitStatus::ALL.get(code as usize).copied()
    }

    /// Whether the fit succeeded.
    pub fn is_ok(self) -> bool {
        self == FitStatus::Ok
    }

    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            FitStatus::Ok => "ok",
            FitStatus::NoSignal => "no-signal",
            FitStatus::NotConverged => "not-converged",
            FitStatus::OutsideRoi => "outside-roi",
            FitStatus::SigmaAtBound => "sigma-at-bound",
            FitStatus::Singular => "singular",
            FitStatus::NonFiniteInput => "non-finite-input",
            FitStatus::Saturated => "saturated",
            FitStatus::InconsistentCounts => "inconsistent-counts",
        }
    }
}

/// Whether the PSF width is known or fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SigmaMode {
    /// σ fixed to this value (pixels).
    Fixed(f64),
    /// σ fitted, starting from this value (pixels) — what ThunderSTORM and
    /// Picasso do by default.
    Fitted {
        /// Initial σ, pixels.
        initial: f64,
    },
}

impl SigmaMode {
    /// The fixed or initial σ.
    pub fn value(self) -> f64 {
        match self {
            SigmaMode::Fixed(s) => s,
            SigmaMode::Fitted { initial } => initial,
        }
    }

    /// Whether σ is a fit parameter.
    pub fn is_fitted(self) -> bool {
        matches!(self, SigmaMode::Fitted { .. })
    }
}

/// The camera noise model: it sets the Fisher information (hence the
/// Cramér–Rao bound) and, for sCMOS, the likelihood itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NoiseModel {
    /// Ideal photon counting (SPAD aggregates without pile-up, simulations).
    #[default]
    Poisson,
    /// EMCCD at high gain: variance 2μ (excess-noise factor F² = 2). The MLE
    /// point estimate is the Poisson one; the Fisher information is halved.
    Emccd,
    /// sCMOS with per-pixel read-noise variance v (the `read_var` map): the
    /// Poisson approximation of Huang et al. (Nat. Methods 2013) that fits
    /// `data + v` with `μ + v`, Fisher information `Σ ∂μ∂μ / (μ + v)`.
    Scmos,
}

impl NoiseModel {
    /// Excess-noise factor F² (variance / mean of the signal).
    pub fn excess_noise(self) -> f64 {
        match self {
            NoiseModel::Emccd => 2.0,
            _ => 1.0,
        }
    }
}

/// The localisation estimators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Estimator {
    /// Background-subtracted centroid (fast, biased towards the ROI centre).
    Centroid,
    /// Unweighted least-squares fit of the pixel-integrated Gaussian.
    Lsq,
    /// Poisson maximum likelihood (pixel-integrated Gaussian).
    Mle,
    /// SPAD binomial maximum likelihood with the record's on/off split.
    SpadMle,
}

impl Estimator {
    /// Every estimator.
    pub const ALL: [Estimator; 4] = [
        Estimator::Centroid,
        Estimator::Lsq,
        Estimator::Mle,
        Estimator::SpadMle,
    ];

    /// Command-line name.
    pub fn as_str(self) -> &'static str {
        match self {
            Estimator::Centroid => "centroid",
            Estimator::Lsq => "lsq",
            Estimator::Mle => "mle",
            Estimator::SpadMle => "spad-mle",
        }
    }

    /// Parses a command-line name.
    pub fn parse(s: &str) -> Option<Estimator> {
        Estimator::ALL.into_iter().find(|e| e.as_str() == s)
    }
}

/// Options of the frame-type fits (centroid, LSQ, MLE).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Fixed or fitted σ (pixels).
    pub sigma: SigmaMode,
    /// Noise model for the likelihood and the Cramér–Rao bound.
    pub noise: NoiseModel,
    /// Iteration limit of Levenberg–Marquardt.
    pub max_iterations: u32,
    /// Lower bound of a fitted σ, pixels.
    pub sigma_min: f64,
    /// Upper bound of a fitted σ, pixels (also capped at the ROI side).
    pub sigma_max: f64,
}

impl FitOptions {
    /// Defaults: the given σ mode, Poisson noise, 50 iterations, σ in [0.25, 10] px.
    pub fn new(sigma: SigmaMode) -> FitOptions {
        FitOptions {
            sigma,
            noise: NoiseModel::Poisson,
            max_iterations: 50,
            sigma_min: 0.25,
            sigma_max: 10.0,
        }
    }

    /// Checks every option, naming the first bad one.
    pub fn validate(&self) -> Result<(), LocalizeError> {
        check_option("sigma-min", self.sigma_min, 0.05, 100.0)?;
        check_option("sigma-max", self.sigma_max, self.sigma_min, 1000.0)?;
        match self.sigma {
            SigmaMode::Fixed(s) => check_option("sigma", s, 0.05, 1000.0)?,
            SigmaMode::Fitted { initial } => check_option("sigma", initial, 0.05, 1000.0)?,
        };
        check_option("max-iterations", self.max_iterations as f64, 1.0, 10_000.0)?;
        Ok(())
    }
}

/// One localisation in ROI coordinates (pixels; pixel `i` spans `[i, i+1)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    /// Column position, pixels from the ROI's left edge.
    pub x: f64,
    /// Row position, pixels from the ROI's top edge.
    pub y: f64,
    /// PSF σ, pixels (fixed or fitted).
    pub sigma: f64,
    /// Emitter photons (detections) in the ROI data. For the SPAD binomial
    /// fit: the pile-up-corrected number of detections an ideal counter would
    /// have made over the on-planes.
    pub photons: f64,
    /// Background per pixel, in data units (photons, or detections summed
    /// over all bit-planes for SPAD ROIs).
    pub background: f64,
    /// Standard deviation of the background per pixel under the noise model.
    pub bkgstd: f64,
    /// Precision of x, pixels: the Cramér–Rao bound of the model fitted for
    /// the MLEs; the sandwich covariance for LSQ; propagated Poisson error
    /// for the centroid.
    pub std_x: f64,
    /// Precision of y, pixels (as `std_x`).
    pub std_y: f64,
    /// Precision of the photon number.
    pub std_photons: f64,
    /// Outcome.
    pub status: FitStatus,
    /// Iterations used (0 for the centroid and for fits not attempted).
    pub iterations: u32,
}

impl Fit {
    /// `sqrt((var_x + var_y) / 2)`, pixels: the `uncertainty [nm]` column
    /// divided by the pixel size.
    pub fn uncertainty_px(&self) -> f64 {
        ((self.std_x * self.std_x + self.std_y * self.std_y) / 2.0).sqrt()
    }

    /// A fit that was not attempted: ROI centre, zero signal, the fallback
    /// uncertainty (the ROI side), and the given status.
    pub fn failed(side: usize, sigma: f64, status: FitStatus) -> Fit {
        let c = side as f64 / 2.0;
        Fit {
            x: c,
            y: c,
            sigma: if sigma.is_finite() { sigma } else { 0.0 },
            photons: 0.0,
            background: 0.0,
            bkgstd: 0.0,
            std_x: side as f64,
            std_y: side as f64,
            std_photons: 0.0,
            status,
            iterations: 0,
        }
    }

    /// Replaces any non-finite field by a finite fallback (position → ROI
    /// centre, precision → ROI side, others → 0) and marks the fit
    /// [`FitStatus::Singular`] if it was ok. Guarantees no NaN reaches a table.
    pub fn sanitized(mut self, side: usize) -> Fit {
        let c = side as f64 / 2.0;
        let mut bad = false;
        let mut fix = |v: &mut f64, fallback: f64| {
            if !v.is_finite() {
                *v = fallback;
                bad = true;
            }
        };
        fix(&mut self.x, c);
        fix(&mut self.y, c);
        fix(&mut self.sigma, 0.0);
        fix(&mut self.photons, 0.0);
        fix(&mut self.background, 0.0);
        fix(&mut self.bkgstd, 0.0);
        fix(&mut self.std_x, side as f64);
        fix(&mut self.std_y, side as f64);
        fix(&mut self.std_photons, 0.0);
        if bad && self.status.is_ok() {
            self.status = FitStatus::Singular;
        }
        self
    }
}

/// Fits one ROI with a frame-type estimator (centroid, LSQ or Poisson MLE).
/// For [`Estimator::SpadMle`] use [`crate::spad::fit_binomial`], which needs
/// the record's bit-plane split; passed here it falls back to the Poisson MLE.
pub fn fit_roi(estimator: Estimator, roi: &RoiView, opts: &FitOptions) -> Fit {
    match estimator {
        Estimator::Centroid => crate::centroid::centroid(roi, opts),
        Estimator::Lsq => crate::lm::fit_lsq(roi, opts),
        Estimator::Mle | Estimator::SpadMle => crate::lm::fit_mle(roi, opts),
    }
}
