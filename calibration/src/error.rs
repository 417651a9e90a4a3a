//! Everything that can go wrong while calibrating or reading a calibration.
//!
//! (`Display` and `Error` are written out here, as they were when this
//! module was part of the host, which does not depend on `thiserror`.)

use std::fmt;
use std::path::PathBuf;

/// Why a calibration could not be computed, written or read. Every message
/// names the file, map or option at fault.
#[derive(Debug)]
pub enum CalibrationError {
    /// Opening, reading or writing a file failed.
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done (`reading`, `creating`, ...).
        action: &'static str,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A recording or stack holds no plane or frame.
    Empty {
        /// Which input.
        input: String,
    },
    /// Two inputs (or an input and a map) do not have the same size.
    SizeMismatch {
        /// What was compared.
        what: String,
        /// The size expected (width, height).
        expected: (u32, u32),
        /// The size found.
        found: (u32, u32),
    },
    /// The dark recording is too short for the requested precision.
    TooShort {
        /// Planes in the recording.
        planes: u64,
        /// Planes the precision needs (a lower bound when `needed_is_bound`).
        needed: u64,
        /// Whether `needed` is only a lower bound (no count at the median pixel).
        needed_is_bound: bool,
        /// Requested relative uncertainty at the median DCR.
        precision: f64,
        /// Relative uncertainty reached (`None` when the median pixel had no count).
        achieved: Option<f64>,
        /// Median DCR, Hz (an upper bound when `needed_is_bound`).
        median_dcr_hz: f64,
        /// Bit-plane period, s (to say how long to record).
        plane_period_s: f64,
    },
    /// The flat recording is too short to measure the photon response
    /// (PRNU) to the requested precision.
    FlatTooShort {
        /// Planes in the flat.
        planes: u64,
        /// Planes the precision needs.
        needed: u64,
        /// Requested relative uncertainty.
        precision: f64,
        /// Relative uncertainty of the median pixel's photon response reached.
        achieved: f64,
        /// Bit-plane period of the flat, s.
        plane_period_s: f64,
    },
    /// An option or parameter outside its range; the message names it.
    Invalid {
        /// The option or parameter.
        name: &'static str,
        /// What is wrong with it.
        why: String,
    },
    /// A TIFF stack page is unreadable or of the wrong kind.
    Stack {
        /// The stack file.
        path: PathBuf,
        /// What is wrong (names the page).
        why: String,
    },
    /// The calibration header is missing or is not a smartagg calibration.
    NotCalibration {
        /// The file or directory given.
        path: PathBuf,
        /// Why it is not one.
        why: String,
    },
    /// The calibration header does not parse or a field is invalid.
    Header {
        /// The header file.
        path: PathBuf,
        /// The parser's message or the field at fault.
        why: String,
    },
    /// Written by a newer version of the format.
    UnsupportedVersion {
        /// The header file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Newest version this code reads.
        supported: u32,
    },
    /// A calibration of another camera kind than the caller needs.
    WrongKind {
        /// The header file.
        path: PathBuf,
        /// Kind in the file.
        found: String,
        /// Kind needed.
        expected: &'static str,
    },
    /// A map named by the header (or required by the kind) is missing.
    MissingMap {
        /// The map's name.
        name: String,
        /// Where it should be.
        path: PathBuf,
    },
    /// A map is unreadable, of the wrong size or type, or holds bad values.
    Map {
        /// The map's name.
        name: String,
        /// Its file.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
}

impl CalibrationError {
    /// An [`CalibrationError::Invalid`] for option `name`.
    pub fn invalid(name: &'static str, why: impl Into<String>) -> CalibrationError {
        CalibrationError::Invalid {
            name,
            why: why.into(),
        }
    }

    /// An [`CalibrationError::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, action: &'static str, source: std::io::Error) -> Self {
        CalibrationError::Io {
            path: path.into(),
            action,
            source,
        }
    }
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use CalibrationError::*;
        match self {
            Io {
                path,
                action,
                source,
            } => write!(f, "{action} {}: {source}", path.display()),
            Empty { input } => write!(f, "{input} holds no bit-plane or frame"),
            SizeMismatch {
                what,
                expected,
                found,
            } => write!(
                f,
                "{what}: expected {}x{} pixels, found {}x{}",
                expected.0, expected.1, found.0, found.1
            ),
            TooShort {
                planes,
                needed,
                needed_is_bound,
                precision,
                achieved,
                median_dcr_hz,
                plane_period_s,
            } => {
                let at_least = if *needed_is_bound { "at least " } else { "" };
                let median = if *needed_is_bound {
                    format!("the median pixel saw no dark count, so the median DCR is below {median_dcr_hz:.3} Hz")
                } else {
                    format!("median DCR {median_dcr_hz:.3} Hz")
                };
                let reached = match achieved {
                    Some(a) => format!("reaches {:.2} %", 100.0 * a),
                    None => "cannot state a precision".to_string(),
                };
                write!(
                    f,
                    "the dark recording is too short: {planes} bit-planes {reached} relative DCR uncertainty at the median pixel ({median}); {:.2} % needs {at_least}{needed} planes ({at_least}{:.1} s of recording). Record longer, relax --precision, or pass --allow-short to accept it",
                    100.0 * precision,
                    *needed as f64 * plane_period_s
                )
            }
            FlatTooShort {
                planes,
                needed,
                precision,
                achieved,
                plane_period_s,
            } => write!(
                f,
                "the flat recording is too short: {planes} bit-planes reach {:.2} % relative uncertainty of the median pixel's photon response (PRNU); {:.2} % needs {needed} planes ({:.1} s of recording). Record longer, relax --precision, or pass --allow-short to accept it",
                100.0 * achieved,
                100.0 * precision,
                *needed as f64 * plane_period_s
            ),
            Invalid { name, why } => write!(f, "invalid `{name}`: {why}"),
            Stack { path, why } => write!(f, "frame stack {}: {why}", path.display()),
            NotCalibration { path, why } => {
                write!(f, "{} is not a smartagg calibration: {why}", path.display())
            }
            Header { path, why } => write!(f, "calibration header {}: {why}", path.display()),
            UnsupportedVersion {
                path,
                found,
                supported,
            } => write!(
                f,
                "calibration {} is format version {found}, newer than the supported version {supported}",
                path.display()
            ),
            WrongKind {
                path,
                found,
                expected,
            } => write!(
                f,
                "calibration {} is for a {found} camera, a {expected} calibration is needed",
                path.display()
            ),
            MissingMap { name, path } => write!(
                f,
                "calibration map `{name}` is missing (expected {})",
                path.display()
            ),
            Map { name, path, why } => {
                write!(f, "calibration map `{name}` ({}): {why}", path.display())
            }
        }
    }
}

impl std::error::Error for CalibrationError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CalibrationError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}
