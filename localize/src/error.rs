//! Errors of the localisation crate: each names what is wrong.

use thiserror::Error;

/// Something the caller gave cannot be localised or read.
#[derive(Debug, Error)]
pub enum LocalizeError {
    /// An option outside its valid range; the message names it.
    #[error("invalid option `{name}` = {value}: {why}")]
    InvalidOption {
        /// Name of the option as the user knows it.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What it must satisfy.
        why: String,
    },
    /// An ROI whose data does not have `side²` values, or a side out of range.
    #[error("ROI of side {side} holds {len} values (expected side² with 1 ≤ side ≤ {max})")]
    RoiShape {
        /// Declared side.
        side: usize,
        /// Number of values supplied.
        len: usize,
        /// Largest side supported.
        max: usize,
    },
    /// A per-pixel map whose size does not match the ROI or frame.
    #[error("{map} map has {len} values, expected {expected}")]
    MapShape {
        /// Which map.
        map: &'static str,
        /// Values supplied.
        len: usize,
        /// Values expected.
        expected: usize,
    },
    /// A frame too small for any fit (under 3 × 3 pixels).
    #[error(
        "frame {width}x{height} is smaller than {side}x{side} pixels, the smallest fitting ROI"
    )]
    FrameTooSmall {
        /// Frame width.
        width: usize,
        /// Frame height.
        height: usize,
        /// Smallest ROI side.
        side: usize,
    },
    /// A TIFF file that cannot be read or written.
    #[error("TIFF {path}: {why}")]
    Tiff {
        /// The file (or a description of the stream).
        path: String,
        /// What went wrong.
        why: String,
    },
    /// A localisation table that cannot be parsed.
    #[error("table line {line}: {why}")]
    Table {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        why: String,
    },
    /// An image that would be unreasonably large.
    #[error("rendered image would be {width}x{height} pixels (limit {limit} pixels); use a larger pixel size")]
    ImageTooLarge {
        /// Width in pixels.
        width: u64,
        /// Height in pixels.
        height: u64,
        /// Largest pixel count allowed.
        limit: u64,
    },
    /// A table that could not be rewritten in place (its text and the
    /// rows read from it disagree).
    #[error("{0}")]
    Rewrite(&'static str),
    /// Input/output failure.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
}

impl From<smartagg_io::Error> for LocalizeError {
    /// A TIFF failure keeps its file name and what failed.
    fn from(e: smartagg_io::Error) -> Self {
        LocalizeError::Tiff {
            why: e.why(),
            path: e.name,
        }
    }
}

/// Checks a finite value within `[lo, hi]`, naming the option otherwise.
pub fn check_option(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
) -> Result<f64, LocalizeError> {
    if !value.is_finite() {
        return Err(LocalizeError::InvalidOption {
            name,
            value,
            why: "must be a finite number".into(),
        });
    }
    if value < lo || value > hi {
        return Err(LocalizeError::InvalidOption {
            name,
            value,
            why: format!("must lie in [{lo}, {hi}]"),
        });
    }
    Ok(value)
}
