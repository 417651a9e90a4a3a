//! What each study simulates: its points (x values), the camera
//! configurations simulated at every point, the schemes (curves) measured on
//! them, and the ratios its summary reports.

use crate::error::StudyError;
use serde::{Deserialize, Serialize};
use smartagg_model::params::PresetName;

/// The studies of `smartagg study`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StudyName {
    /// Fig. 4 (simulated): SPCIMAGER, fixed 500-plane frames vs smart aggregation.
    SmartVsFixed,
    /// Fig. 8 top left: current vs projected SPAD, fixed and smart.
    FutureSpad,
    /// Fig. 8 top right: projected SPAD (smart) vs EMCCD and sCMOS, merged or not.
    Cameras,
    /// Fig. 8 bottom left: 150× vs 60× for current and projected SPAD (smart).
    Objective,
    /// Fig. 8 bottom right: hot pixels ignored vs interpolated, 150× and 60×.
    HotPixels,
    /// Beyond the paper: every estimator on the same smart-aggregated ROIs.
    Localizers,
}

impl StudyName {
    /// Every study, in the order of the paper's figures.
    pub const ALL: [StudyName; 6] = [
        StudyName::SmartVsFixed,
        StudyName::FutureSpad,
        StudyName::Cameras,
        StudyName::Objective,
        StudyName::HotPixels,
        StudyName::Localizers,
    ];

    /// The command-line name.
    pub fn as_str(self) -> &'static str {
        match self {
            StudyName::SmartVsFixed => "smart-vs-fixed",
            StudyName::FutureSpad => "future-spad",
            StudyName::Cameras => "cameras",
            StudyName::Objective => "objective",
            StudyName::HotPixels => "hot-pixels",
            StudyName::Localizers => "localizers",
        }
    }

    /// Parses a command-line name.
    pub fn parse(s: &str) -> Result<StudyName, StudyError> {
        StudyName::ALL
            .into_iter()
            .find(|n| n.as_str() == s)
            .ok_or_else(|| StudyError::UnknownStudy(s.to_string()))
    }

    /// One-line title for plots and summaries.
    pub fn title(self) -> &'static str {
        match self {
            StudyName::SmartVsFixed => "SPCIMAGER: smart vs fixed aggregation",
            StudyName::FutureSpad => "Current vs projected SPAD",
            StudyName::Cameras => "Projected SPAD and SPAD512S (smart) vs EMCCD and sCMOS",
            StudyName::Objective => "150x vs 60x objective (smart aggregation)",
            StudyName::HotPixels => "Hot pixels: ignored vs interpolated (SPCIMAGER, 50 ms on)",
            StudyName::Localizers => {
                "Localisers on the same smart-aggregated ROIs (SPCIMAGER 150x)"
            }
        }
    }
}

impl std::fmt::Display for StudyName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Options of a study run. Everything that changes a result is here (and in
/// the shard manifest), so that shards can check they belong together.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyOptions {
    /// Blinks simulated per point (per configuration: every configuration of
    /// a point sees the same blinks).
    pub blinks_per_point: u32,
    /// Master seed; every work item derives its own from it.
    pub seed: u64,
    /// Fewer points (x values) for a fast run.
    pub quick: bool,
    /// Blinks per work item: one continuous recording per configuration.
    pub block: u32,
    /// Bootstrap resamples for the confidence intervals.
    pub bootstrap: u32,
    /// Fit the PSF width (ThunderSTORM's default) or fix it to the optics' σ.
    pub fit_sigma: bool,
    /// Localisations further than this from the truth are false, nm.
    pub match_radius_nm: f64,
    /// Explicit x values (blink durations in ms, or hot-pixel percentages)
    /// instead of the study's defaults.
    pub points: Option<Vec<f64>>,
    /// Override of the smart scheme's L_min, planes a track must stay on to
    /// be confirmed. Default [`LMin::Design`]: the field design's own
    /// (`L_min = 1`: its open threshold already keeps background within 1
    /// false blink/s over the study field). The paper's literal scheme (the
    /// `smart (paper's scheme)` curve of `smart-vs-fixed`) is never
    /// overridden.
    pub l_min: LMin,
    /// Override of the smart scheme's association radius, pixels (default:
    /// the field design's, round(2σ) of the PSF).
    pub r_assoc: Option<u32>,
    /// Frame detection threshold in units of std of the first wavelet level
    /// (ThunderSTORM-like default 1.5).
    pub frame_threshold: f64,
    /// A calibrated sensor (`smartagg calibrate`) whose maps replace the
    /// synthetic ones of the SPCImager configurations ([`crate::sensor`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<crate::sensor::SensorCalibration>,
}

/// The smart scheme's confirmation length L_min.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LMin {
    /// The field design's (`model::field_design`: 1, every open track is
    /// confirmed; its open threshold controls the false blinks).
    Design,
    /// A fixed number of planes instead (1 = every open track is a blink).
    Planes(u32),
}

impl LMin {
    /// Parses `design` or a number of planes.
    pub fn parse(s: &str) -> Result<LMin, StudyError> {
        match s {
            "design" => Ok(LMin::Design),
            _ => s.parse().map(LMin::Planes).map_err(|_| StudyError::Option {
                name: "l-min",
                why: format!(
                    "`{s}`: expected a number of planes or `design` (the field design's L_min)"
                ),
            }),
        }
    }
}

impl std::fmt::Display for LMin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LMin::Design => f.write_str("design"),
            LMin::Planes(n) => write!(f, "{n}"),
        }
    }
}

/// Default blinks per point (the paper's 500).
pub const DEFAULT_BLINKS: u32 = 500;
/// Default blinks per work item.
pub const DEFAULT_BLOCK: u32 = 50;
/// Default bootstrap resamples.
pub const DEFAULT_BOOTSTRAP: u32 = 1000;
/// The paper's rule: further than one 150× SPCIMAGER pixel (53.3 nm) is false.
pub const DEFAULT_MATCH_RADIUS_NM: f64 = 53.3;
/// Fixed SPAD frames: 500 bit-planes (50 ms), as in Fig. 8.
pub const FIXED_FRAME_PLANES: u64 = 500;
/// Side of every fitted ROI (smart records and frame detections), pixels.
pub const ROI_SIDE: usize = 9;
/// Localisations of consecutive frames closer than this are merged, nm.
pub const MERGE_RADIUS_NM: f64 = 40.0;

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            blinks_per_point: DEFAULT_BLINKS,
            seed: 1,
            quick: false,
            block: DEFAULT_BLOCK,
            bootstrap: DEFAULT_BOOTSTRAP,
            fit_sigma: true,
            match_radius_nm: DEFAULT_MATCH_RADIUS_NM,
            points: None,
            l_min: LMin::Design,
            r_assoc: None,
            frame_threshold: 1.5,
            calibration: None,
        }
    }
}

impl StudyOptions {
    /// Checks every option, naming the first bad one.
    pub fn validate(&self) -> Result<(), StudyError> {
        let bad = |name: &'static str, why: &str| {
            Err(StudyError::Option {
                name,
                why: why.to_string(),
            })
        };
        if self.blinks_per_point == 0 || self.blinks_per_point > 1_000_000 {
            return bad("blinks-per-point", "must be 1..=1000000");
        }
        if self.block == 0 || self.block > 100_000 {
            return bad("block", "must be 1..=100000 blinks per work item");
        }
        if self.bootstrap < 10 || self.bootstrap > 1_000_000 {
            return bad("bootstrap", "must be 10..=1000000 resamples");
        }
        if !(self.match_radius_nm.is_finite() && self.match_radius_nm > 0.0) {
            return bad("match-radius-nm", "must be a positive number of nm");
        }
        if !(self.frame_threshold.is_finite() && self.frame_threshold > 0.0) {
            return bad(
                "frame-threshold",
                "must be a positive multiple of the noise std",
            );
        }
        if self.l_min == LMin::Planes(0) {
            return bad("l-min", "must be at least 1 plane");
        }
        if self.r_assoc.is_some_and(|r| r > 16) {
            return bad("r-assoc", "must be 0..=16 pixels");
        }
        if let Some(p) = &self.points {
            if p.is_empty() || p.len() > 1000 {
                return bad("points", "give 1..=1000 x values");
            }
            if p.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return bad("points", "every x value must be a finite number >= 0");
            }
        }
        Ok(())
    }
}

/// How a configuration is localised into a curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// SPAD: consecutive 500-plane frames of the same bit-planes, frame
    /// detection, Poisson MLE.
    Fixed,
    /// SPAD: the blink ROIs of the smart scheme (the field design, through
    /// the packet stream), Poisson MLE.
    Smart,
    /// SPAD: the same ROIs, SPAD binomial MLE with the record's on/off split.
    SmartSpadMle,
    /// SPAD: the paper's literal scheme (one threshold T, L_min 1, r_assoc
    /// 1, end_trim 0) on the same bit-planes, Poisson MLE.
    SmartPaper,
    /// Reference: the Cramér–Rao bound (binomial, true on/off split, true
    /// position) of every matched smart ROI; its "error" is √(mean bound).
    SmartCrlb,
    /// EMCCD/sCMOS: every frame's localisations, unmerged.
    Frames,
    /// EMCCD/sCMOS: localisations of consecutive frames within 40 nm merged.
    FramesMerged,
    /// Hot pixels left out of the likelihood.
    HotIgnore,
    /// Hot pixels replaced by the mean of their valid 4-neighbours.
    HotInterpolate,
    /// One estimator on the smart ROIs ([`Estimator`]).
    Estimator(Estimator),
}

/// The estimators compared by the `localizers` study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Estimator {
    /// Background-subtracted centroid.
    Centroid,
    /// Least squares, σ fitted.
    Lsq,
    /// Poisson MLE, σ fixed to the optics' value.
    MleFixedSigma,
    /// Poisson MLE, σ fitted.
    Mle,
    /// SPAD binomial MLE, σ fixed.
    SpadMleFixedSigma,
    /// SPAD binomial MLE, σ fitted.
    SpadMle,
}

impl Estimator {
    /// Every estimator, fastest first.
    pub const ALL: [Estimator; 6] = [
        Estimator::Centroid,
        Estimator::Lsq,
        Estimator::MleFixedSigma,
        Estimator::Mle,
        Estimator::SpadMleFixedSigma,
        Estimator::SpadMle,
    ];

    /// Short name.
    pub fn as_str(self) -> &'static str {
        match self {
            Estimator::Centroid => "centroid",
            Estimator::Lsq => "lsq",
            Estimator::MleFixedSigma => "mle-fixed-sigma",
            Estimator::Mle => "mle",
            Estimator::SpadMleFixedSigma => "spad-mle-fixed-sigma",
            Estimator::SpadMle => "spad-mle",
        }
    }
}

impl Method {
    /// Short name used in scheme identifiers.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Fixed => "fixed",
            Method::Smart => "smart",
            Method::SmartSpadMle => "smart-spad-mle",
            Method::SmartPaper => "smart-paper",
            Method::SmartCrlb => "smart-crlb",
            Method::Frames => "frames",
            Method::FramesMerged => "frames-merged",
            Method::HotIgnore => "ignore",
            Method::HotInterpolate => "interpolate",
            Method::Estimator(e) => e.as_str(),
        }
    }

    /// Whether the curve is a reference (a bound), not a measured error.
    pub fn is_reference(self) -> bool {
        matches!(self, Method::SmartCrlb)
    }

    /// Human-readable description for labels.
    pub fn label(self) -> &'static str {
        match self {
            Method::Fixed => "fixed 50 ms",
            Method::Smart => "smart",
            Method::SmartSpadMle => "smart (SPAD MLE)",
            Method::SmartPaper => "smart (paper's scheme)",
            Method::SmartCrlb => "CRLB",
            Method::Frames => "50 ms frames",
            Method::FramesMerged => "merged",
            Method::HotIgnore => "ignore",
            Method::HotInterpolate => "interpolate",
            Method::Estimator(e) => e.as_str(),
        }
    }
}

/// One simulated camera configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Identifier, e.g. `spcimager-150x`; also seeds the camera's photons, so
    /// the same configuration at the same point gives the same data in every study.
    pub key: String,
    /// Label for plots.
    pub label: String,
    /// Camera preset.
    pub preset: PresetName,
    /// Objective magnification.
    pub objective: u32,
}

impl Config {
    fn new(preset: PresetName, objective: u32) -> Config {
        let (key, label) = match preset {
            PresetName::Spcimager => (format!("spcimager-{objective}x"), "SPCIMAGER"),
            PresetName::SpcimagerProjected => (format!("projected-{objective}x"), "projected SPAD"),
            PresetName::Spad512s => (format!("spad512s-{objective}x"), "SPAD512S"),
            PresetName::Emccd => (format!("emccd-{objective}x"), "EMCCD"),
            PresetName::Scmos => (format!("scmos-{objective}x"), "sCMOS"),
        };
        Config {
            key,
            label: format!("{label} {objective}x"),
            preset,
            objective,
        }
    }

    /// Whether the camera is a bit-plane (SPAD) camera.
    pub fn is_spad(&self) -> bool {
        matches!(
            self.preset,
            PresetName::Spcimager | PresetName::SpcimagerProjected | PresetName::Spad512s
        )
    }
}

/// One curve: a method applied to a configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Scheme {
    /// Identifier `config/method`, e.g. `spcimager-150x/smart`.
    pub id: String,
    /// Label for plots and tables.
    pub label: String,
    /// Index into [`Plan::configs`].
    pub config: usize,
    /// How it is localised.
    pub method: Method,
}

/// A ratio of two schemes' RMS errors reported with a paired bootstrap CI.
#[derive(Debug, Clone, PartialEq)]
pub struct RatioSpec {
    /// What the ratio means, for tables.
    pub label: String,
    /// Numerator scheme index.
    pub num: usize,
    /// Denominator scheme index.
    pub den: usize,
    /// `Some(i)`: the denominator is always taken at point `i` (e.g. the
    /// 0 % hot-pixel point); `None`: at the same point as the numerator.
    pub den_point: Option<usize>,
}

/// What the x axis is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Blink duration, ms.
    BlinkMs,
    /// Hot-pixel fraction, %.
    HotPercent,
}

impl Axis {
    /// Axis label.
    pub fn label(self) -> &'static str {
        match self {
            Axis::BlinkMs => "blink duration (ms)",
            Axis::HotPercent => "hot pixels (%)",
        }
    }

    /// Column name in the CSV files.
    pub fn column(self) -> &'static str {
        match self {
            Axis::BlinkMs => "blink_ms",
            Axis::HotPercent => "hot_pixel_percent",
        }
    }
}

/// A fully specified study: points, configurations, schemes and ratios.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Which study.
    pub study: StudyName,
    /// Its options.
    pub options: StudyOptions,
    /// What x is.
    pub axis: Axis,
    /// x values (blink ms or hot-pixel %), one per point.
    pub points: Vec<f64>,
    /// Configurations simulated at every point.
    pub configs: Vec<Config>,
    /// Curves.
    pub schemes: Vec<Scheme>,
    /// Ratios reported in the summary.
    pub ratios: Vec<RatioSpec>,
}

/// Blink durations of the full runs, ms (the paper's range, 10 points).
pub const DURATIONS_MS: [f64; 10] = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0];
/// Blink durations of `--quick` runs, ms.
pub const QUICK_DURATIONS_MS: [f64; 3] = [20.0, 50.0, 100.0];
/// Hot-pixel percentages of the full run.
pub const HOT_PERCENT: [f64; 9] = [0.0, 2.5, 5.0, 7.5, 10.0, 12.5, 15.0, 17.5, 20.0];
/// Hot-pixel percentages of `--quick` runs.
pub const QUICK_HOT_PERCENT: [f64; 4] = [0.0, 5.0, 10.0, 20.0];

impl Plan {
    /// The plan of `study` with `options`.
    pub fn new(study: StudyName, options: StudyOptions) -> Result<Plan, StudyError> {
        options.validate()?;
        if options.calibration.is_some() && study == StudyName::HotPixels {
            return Err(StudyError::Option {
                name: "calibration",
                why: "the hot-pixels study sweeps synthetic hot-pixel fractions; a calibrated sensor has its own (run the other studies with it)".into(),
            });
        }
        use Method::*;
        use PresetName::*;
        let spc150 = Config::new(Spcimager, 150);
        let spc60 = Config::new(Spcimager, 60);
        let prj150 = Config::new(SpcimagerProjected, 150);
        let prj60 = Config::new(SpcimagerProjected, 60);
        let (axis, configs, methods): (Axis, Vec<Config>, Vec<(usize, Method)>) = match study {
            StudyName::SmartVsFixed => (
                Axis::BlinkMs,
                vec![spc150],
                vec![
                    (0, Fixed),
                    (0, Smart),
                    (0, SmartSpadMle),
                    (0, SmartPaper),
                    (0, SmartCrlb),
                ],
            ),
            StudyName::FutureSpad => (
                Axis::BlinkMs,
                vec![spc150, prj150],
                vec![
                    (0, Fixed),
                    (0, Smart),
                    (0, SmartSpadMle),
                    (0, SmartCrlb),
                    (1, Fixed),
                    (1, Smart),
                    (1, SmartSpadMle),
                    (1, SmartCrlb),
                ],
            ),
            StudyName::Cameras => (
                Axis::BlinkMs,
                vec![
                    prj150,
                    Config::new(Spad512s, 150),
                    Config::new(Emccd, 150),
                    Config::new(Scmos, 150),
                ],
                vec![
                    (0, Smart),
                    (1, Smart),
                    (2, Frames),
                    (2, FramesMerged),
                    (3, Frames),
                    (3, FramesMerged),
                ],
            ),
            StudyName::Objective => (
                Axis::BlinkMs,
                vec![spc150, spc60, prj150, prj60],
                vec![(0, Smart), (1, Smart), (2, Smart), (3, Smart)],
            ),
            StudyName::HotPixels => (
                Axis::HotPercent,
                vec![spc150, spc60],
                vec![
                    (0, HotIgnore),
                    (0, HotInterpolate),
                    (1, HotIgnore),
                    (1, HotInterpolate),
                ],
            ),
            StudyName::Localizers => {
                let mut m: Vec<(usize, Method)> = crate::spec::Estimator::ALL
                    .into_iter()
                    .map(|e| (0, Estimator(e)))
                    .collect();
                m.push((0, SmartCrlb));
                (Axis::BlinkMs, vec![spc150], m)
            }
        };
        let schemes: Vec<Scheme> = methods
            .into_iter()
            .map(|(c, m)| Scheme {
                id: format!("{}/{}", configs[c].key, m.as_str()),
                label: format!("{} {}", configs[c].label, m.label()),
                config: c,
                method: m,
            })
            .collect();
        let points = match (&options.points, axis, options.quick) {
            (Some(p), _, _) => p.clone(),
            (None, Axis::BlinkMs, false) => DURATIONS_MS.to_vec(),
            (None, Axis::BlinkMs, true) => QUICK_DURATIONS_MS.to_vec(),
            (None, Axis::HotPercent, false) => HOT_PERCENT.to_vec(),
            (None, Axis::HotPercent, true) => QUICK_HOT_PERCENT.to_vec(),
        };
        match axis {
            Axis::BlinkMs => {
                if points.iter().any(|&d| !(0.1..=10_000.0).contains(&d)) {
                    return Err(StudyError::Option {
                        name: "points",
                        why: "blink durations must be 0.1..=10000 ms".into(),
                    });
                }
            }
            Axis::HotPercent => {
                if points.iter().any(|&h| h > 90.0) {
                    return Err(StudyError::Option {
                        name: "points",
                        why: "hot-pixel percentages must be 0..=90".into(),
                    });
                }
            }
        }
        let idx = |id: &str| {
            schemes
                .iter()
                .position(|s| s.id == id)
                .expect("ratio of a scheme of the plan")
        };
        let ratio = |label: &str, num: &str, den: &str, den_point: Option<usize>| RatioSpec {
            label: label.to_string(),
            num: idx(num),
            den: idx(den),
            den_point,
        };
        let ratios = match study {
            StudyName::SmartVsFixed => vec![
                ratio(
                    "fixed / smart",
                    "spcimager-150x/fixed",
                    "spcimager-150x/smart",
                    None,
                ),
                ratio(
                    "smart / smart SPAD MLE",
                    "spcimager-150x/smart",
                    "spcimager-150x/smart-spad-mle",
                    None,
                ),
                ratio(
                    "smart / CRLB",
                    "spcimager-150x/smart",
                    "spcimager-150x/smart-crlb",
                    None,
                ),
                ratio(
                    "smart paper / smart",
                    "spcimager-150x/smart-paper",
                    "spcimager-150x/smart",
                    None,
                ),
                ratio(
                    "fixed / smart paper",
                    "spcimager-150x/fixed",
                    "spcimager-150x/smart-paper",
                    None,
                ),
            ],
            StudyName::FutureSpad => vec![
                ratio(
                    "current / projected (smart)",
                    "spcimager-150x/smart",
                    "projected-150x/smart",
                    None,
                ),
                ratio(
                    "current / projected (fixed)",
                    "spcimager-150x/fixed",
                    "projected-150x/fixed",
                    None,
                ),
                ratio(
                    "projected: fixed / smart",
                    "projected-150x/fixed",
                    "projected-150x/smart",
                    None,
                ),
            ],
            StudyName::Cameras => vec![
                ratio(
                    "EMCCD merged / projected smart",
                    "emccd-150x/frames-merged",
                    "projected-150x/smart",
                    None,
                ),
                ratio(
                    "sCMOS merged / projected smart",
                    "scmos-150x/frames-merged",
                    "projected-150x/smart",
                    None,
                ),
                ratio(
                    "EMCCD / projected smart",
                    "emccd-150x/frames",
                    "projected-150x/smart",
                    None,
                ),
                ratio(
                    "sCMOS / projected smart",
                    "scmos-150x/frames",
                    "projected-150x/smart",
                    None,
                ),
                ratio(
                    "SPAD512S smart / projected smart",
                    "spad512s-150x/smart",
                    "projected-150x/smart",
                    None,
                ),
            ],
            StudyName::Objective => vec![
                ratio(
                    "SPCIMAGER 150x / 60x",
                    "spcimager-150x/smart",
                    "spcimager-60x/smart",
                    None,
                ),
                ratio(
                    "projected 150x / 60x",
                    "projected-150x/smart",
                    "projected-60x/smart",
                    None,
                ),
            ],
            StudyName::HotPixels => vec![
                ratio(
                    "150x interpolate / ignore",
                    "spcimager-150x/interpolate",
                    "spcimager-150x/ignore",
                    None,
                ),
                ratio(
                    "60x interpolate / ignore",
                    "spcimager-60x/interpolate",
                    "spcimager-60x/ignore",
                    None,
                ),
                ratio(
                    "150x ignore / 0 % hot",
                    "spcimager-150x/ignore",
                    "spcimager-150x/ignore",
                    Some(0),
                ),
                ratio(
                    "60x ignore / 0 % hot",
                    "spcimager-60x/ignore",
                    "spcimager-60x/ignore",
                    Some(0),
                ),
            ],
            StudyName::Localizers => crate::spec::Estimator::ALL
                .into_iter()
                .map(|e| {
                    ratio(
                        &format!("{} / CRLB", e.as_str()),
                        &format!("spcimager-150x/{}", e.as_str()),
                        "spcimager-150x/smart-crlb",
                        None,
                    )
                })
                .collect(),
        };
        Ok(Plan {
            study,
            options,
            axis,
            points,
            configs,
            schemes,
            ratios,
        })
    }

    /// Number of work items per point.
    pub fn blocks(&self) -> usize {
        self.options.blinks_per_point.div_ceil(self.options.block) as usize
    }

    /// Blinks of block `b` (the last block may be shorter).
    pub fn blinks_in_block(&self, b: usize) -> usize {
        let start = b as u64 * self.options.block as u64;
        (self.options.blinks_per_point as u64 - start).min(self.options.block as u64) as usize
    }

    /// Every work item `(point, block)`, in the canonical order.
    pub fn items(&self) -> Vec<(usize, usize)> {
        (0..self.points.len())
            .flat_map(|p| (0..self.blocks()).map(move |b| (p, b)))
            .collect()
    }

    /// Index of a scheme by id.
    pub fn scheme(&self, id: &str) -> Option<usize> {
        self.schemes.iter().position(|s| s.id == id)
    }
}

/// `--shard I/N`: this run computes the items whose canonical index `k`
/// has `k mod N = I − 1` (interleaved, so every shard gets every point).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 1-based shard number.
    pub index: u32,
    /// Number of shards.
    pub count: u32,
}

impl Shard {
    /// The whole study in one run.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Parses `I/N`.
    pub fn parse(s: &str) -> Result<Shard, StudyError> {
        let err = || StudyError::Shard(s.to_string());
        let (i, n) = s.split_once('/').ok_or_else(err)?;
        let index: u32 = i.trim().parse().map_err(|_| err())?;
        let count: u32 = n.trim().parse().map_err(|_| err())?;
        if index == 0 || count == 0 || index > count {
            return Err(err());
        }
        Ok(Shard { index, count })
    }

    /// Whether canonical item `k` belongs to this shard.
    pub fn owns(&self, k: usize) -> bool {
        k % self.count as usize == (self.index - 1) as usize
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_study_has_valid_ratios_and_unique_schemes() {
        for s in StudyName::ALL {
            let p = Plan::new(s, StudyOptions::default()).unwrap();
            let mut ids: Vec<&str> = p.schemes.iter().map(|s| s.id.as_str()).collect();
            ids.sort();
            ids.dedup();
            assert_eq!(ids.len(), p.schemes.len(), "{s}");
            assert!(!p.ratios.is_empty());
            assert_eq!(StudyName::parse(s.as_str()).unwrap(), s);
        }
        assert!(StudyName::parse("fig9").is_err());
    }

    #[test]
    fn shards_partition_the_items() {
        let p = Plan::new(
            StudyName::SmartVsFixed,
            StudyOptions {
                blinks_per_point: 120,
                block: 50,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(p.blocks(), 3);
        assert_eq!(p.blinks_in_block(2), 20);
        let n = p.items().len();
        for count in 1..5 {
            let mut seen = vec![0; n];
            for index in 1..=count {
                let sh = Shard { index, count };
                for (k, s) in seen.iter_mut().enumerate() {
                    *s += sh.owns(k) as u32;
                }
            }
            assert!(seen.iter().all(|&c| c == 1));
        }
        assert_eq!(Shard::parse("2/3").unwrap(), Shard { index: 2, count: 3 });
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn bad_options_are_named() {
        let o = StudyOptions {
            blinks_per_point: 0,
            ..Default::default()
        };
        let e = Plan::new(StudyName::Cameras, o).unwrap_err().to_string();
        assert!(e.contains("blinks-per-point"), "{e}");
        let o = StudyOptions {
            points: Some(vec![f64::NAN]),
            ..Default::default()
        };
        assert!(Plan::new(StudyName::Cameras, o).is_err());
    }
}
