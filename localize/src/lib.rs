#![warn(missing_docs)]
//! # smartagg-localize — molecule positions from ROIs and frames
//!
//! Turns each aggregated blink ROI (or each EMCCD/sCMOS/fixed-aggregation
//! frame) into molecule positions with the precision the photons allow.
//!
//! * Estimators ([`fit`]): [`centroid`], least squares and Poisson maximum
//!   likelihood ([`lm`], Levenberg–Marquardt on the pixel-integrated Gaussian,
//!   σ fixed or fitted), and the SPAD binomial maximum likelihood ([`spad`]),
//!   exact under pile-up, using the record's on/off bit-plane split, dark-count
//!   and PRNU maps, and hot pixels ignored or interpolated ([`roi`]).
//!   [`record_fit`] fits a blink record's ROI where it lies on the sensor,
//!   with the sensor's calibration maps cut to it.
//! * Uncertainty ([`crlb`]): the Cramér–Rao bound of the model actually
//!   fitted (Poisson, EMCCD F² = 2, sCMOS per-pixel read variance, SPAD
//!   binomial), reported per localisation; Mortensen's closed forms.
//! * Frames ([`frames`]): B-spline wavelet filter, threshold, 8-neighbour
//!   local maxima, ROI fits; [`merge`] joins localisations of consecutive
//!   frames within 40 nm (the paper's merging).
//! * [`drift`]: stage-drift correction by redundant cross-correlation (RCC)
//!   or fiducials.
//! * Exchange: ThunderSTORM CSV ([`table`]), the pages of an ROI export
//!   ([`export`]; TIFF input and output is `smartagg_io`'s),
//!   normalised-Gaussian rendering ([`render`]); with the crate's features,
//!   Picasso's HDF5 tables (`picasso`) and publishable PNG figures with a
//!   colour map and a scale bar (`figure`).
//! * [`synth`]: simulated ROIs and frames with known truth.
//!
//! Coordinates: ROI pixel `i` spans `[i, i + 1)` (ImageJ convention), so a
//! localisation at sensor column `X` (pixels) is at `X · pixel_nm` nm with
//! `X = roi_x0 + x_fit`.

// Numeric kernels index several parallel arrays (Jacobian, Hessian, parameter
// vectors) by parameter number: index loops are the clearer form there.
#![allow(clippy::needless_range_loop)]
// `!(x > y)` is deliberate where a NaN must take the "bad" branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Reference values of erf are written with every digit the tables give.
#![allow(clippy::excessive_precision)]

pub mod bench;
pub mod centroid;
pub mod crlb;
pub mod drift;
pub mod erf;
pub mod error;
pub mod export;
pub(crate) mod fastmath;
#[cfg(feature = "figure")]
pub mod figure;
pub mod fit;
pub mod frames;
pub mod linalg;
pub mod lm;
pub mod merge;
#[cfg(feature = "picasso")]
pub mod picasso;
pub mod psf;
pub mod record_fit;
pub mod render;
pub mod roi;
pub mod spad;
pub mod stackbench;
pub mod synth;
pub mod table;

pub use error::LocalizeError;
pub use fit::{fit_roi, Estimator, Fit, FitOptions, FitStatus, NoiseModel, SigmaMode};
pub use record_fit::{fit_record, RecordFitConfig};
pub use roi::{HotPixelMode, PixelMaps, RoiView};
pub use spad::{fit_binomial, SpadRoi};
pub use table::{LocTable, Localization};
