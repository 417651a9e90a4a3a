//! Stage-drift correction of a localisation table.
//!
//! The localisations are split into `K` segments of equal duration. Each
//! segment's drift `d_k` (nm, relative to the first segment: `d_0 = 0`) is
//! estimated by one of two methods:
//!
//! * [`rcc`] — redundant cross-correlation (Wang et al. 2014, Opt. Express
//!   22:15982): every segment is rendered as a histogram image, every pair
//!   `i < j` is cross-correlated (FFT) and the peak located to sub-bin
//!   precision, giving `r_ij ≈ d_j − d_i`; the over-determined system is
//!   solved in least squares, the pair with the largest residual above a
//!   threshold is dropped and the system re-solved, until every residual is
//!   below the threshold (or dropping one more pair would leave a segment
//!   unconnected).
//! * [`fiducials`] — spots present in every segment (beads, or any marker
//!   that keeps blinking) are followed from segment to segment; the drift is
//!   the mean of their displacements.
//!
//! The drift at any time is then interpolated linearly between the segments'
//! mean times (and extrapolated linearly before the first and after the last
//! — at most half a segment): [`DriftEstimate::at`]. Correcting a
//! localisation at time `t` subtracts `at(t)`.
//!
//! Time is in whatever unit the caller uses (frames, bit-planes, seconds);
//! positions in nm.

mod fiducials;
mod rcc;
#[cfg(test)]
mod tests;

pub use fiducials::fiducials;
pub use rcc::rcc;

use crate::table::{format_decimal, CsvTable};
use std::fmt::Write as _;
use thiserror::Error;

/// Fewest segments an estimate uses.
pub const MIN_SEGMENTS: usize = 2;
/// Most segments an estimate uses (the pairs grow as K²).
pub const MAX_SEGMENTS: usize = 200;
/// Fewest localisations per segment.
pub const MIN_PER_SEGMENT: usize = 10;
/// Largest image (FFT size, bins) one segment may be rendered to: 16 MiB of
/// complex numbers each.
pub const MAX_FFT_BINS: usize = 1 << 20;

/// Why a drift cannot be estimated.
#[derive(Debug, Error, PartialEq)]
pub enum DriftError {
    /// An option outside its range; the message names it.
    #[error("invalid option `{name}` = {value}: {why}")]
    Option {
        /// The option as the user knows it.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must satisfy.
        why: &'static str,
    },
    /// Fewer localisations than the segments need.
    #[error("{found} localisations with a finite position and time: drift correction needs at least {needed} ({per} per segment × {segments} segments)")]
    TooFew {
        /// Usable localisations.
        found: usize,
        /// Needed.
        needed: usize,
        /// Needed per segment.
        per: usize,
        /// Segments asked for.
        segments: usize,
    },
    /// Every localisation has the same time: there is no drift to see.
    #[error("every localisation has the same time ({t}): there is no time course to correct")]
    NoTimeSpan {
        /// The one time.
        t: f64,
    },
    /// A segment with too few localisations.
    #[error("time segment {segment} of {segments} holds {found} localisations, fewer than {needed}: use fewer (longer) segments")]
    SparseSegment {
        /// Segment (1-based).
        segment: usize,
        /// Segments.
        segments: usize,
        /// Localisations in it.
        found: usize,
        /// Needed.
        needed: usize,
    },
    /// The field would need too large an image at the bin size asked for.
    #[error("the localisations span {span_nm:.0} nm: at {bin_nm} nm bins the images would be larger than {max} bins; give a larger bin size")]
    ImageTooLarge {
        /// Largest extent of the localisations plus the search range, nm.
        span_nm: f64,
        /// Bin size, nm.
        bin_nm: f64,
        /// Largest image, bins.
        max: usize,
    },
    /// A segment's image correlates with no other (an empty correlation).
    #[error("segment {segment} has no correlation with any other segment: the structure changes completely between segments")]
    NoCorrelation {
        /// Segment (1-based).
        segment: usize,
    },
    /// No spot persists through every segment.
    #[error("no fiducial: no spot has at least {min} localisations within {radius_nm} nm in every one of the {segments} segments (use --method rcc, fewer segments or a larger radius)")]
    NoFiducial {
        /// Localisations per segment required.
        min: usize,
        /// Search radius, nm.
        radius_nm: f64,
        /// Segments.
        segments: usize,
    },
}

/// One localisation as drift correction sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftPoint {
    /// Time (any unit, the same for every point).
    pub t: f64,
    /// x, nm.
    pub x_nm: f64,
    /// y, nm.
    pub y_nm: f64,
}

/// Options of both methods.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftOptions {
    /// Number of time segments, [`MIN_SEGMENTS`] ..= [`MAX_SEGMENTS`].
    pub segments: usize,
    /// RCC: histogram bin, nm (`None`: [`DEFAULT_BIN_NM`], larger if the
    /// field needs it to fit [`MAX_FFT_BINS`]).
    pub bin_nm: Option<f64>,
    /// Largest drift searched for between two segments, nm.
    pub max_drift_nm: f64,
    /// RCC: a pair whose residual exceeds this is dropped, nm.
    pub reject_nm: f64,
    /// Fiducials: a spot's localisations lie within this of its centre, nm.
    pub fiducial_radius_nm: f64,
    /// Fiducials: localisations a spot needs in every segment.
    pub fiducial_min: usize,
}

/// Default RCC histogram bin, nm: a few times finer than the structures
/// (80 nm rulers) and about the localisation precision.
pub const DEFAULT_BIN_NM: f64 = 15.0;

impl Default for DriftOptions {
    fn default() -> Self {
        DriftOptions {
            segments: 10,
            bin_nm: None,
            max_drift_nm: 500.0,
            reject_nm: 20.0,
            fiducial_radius_nm: 40.0,
            fiducial_min: 5,
        }
    }
}

impl DriftOptions {
    /// Checks every option; the error names the first bad one.
    pub fn validate(&self) -> Result<(), DriftError> {
        let bad = |name, value: f64, why| Err(DriftError::Option { name, value, why });
        if !(MIN_SEGMENTS..=MAX_SEGMENTS).contains(&self.segments) {
            return bad("segments", self.segments as f64, "must be 2 ..= 200");
        }
        if let Some(b) = self.bin_nm {
            if !(b.is_finite() && (0.1..=1e5).contains(&b)) {
                return bad("bin (nm)", b, "must be 0.1 ..= 100000 nm");
            }
        }
        for (name, v) in [
            ("max drift (nm)", self.max_drift_nm),
            ("reject (nm)", self.reject_nm),
            ("fiducial radius (nm)", self.fiducial_radius_nm),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 1e7) {
                return bad(name, v, "must be a positive distance of at most 1e7 nm");
            }
        }
        if self.fiducial_min == 0 || self.fiducial_min > 1_000_000 {
            return bad(
                "fiducial localisations",
                self.fiducial_min as f64,
                "must be 1 ..= 1000000",
            );
        }
        Ok(())
    }
}

/// The drift of one time segment.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentDrift {
    /// First time of the segment.
    pub t_start: f64,
    /// End of the segment (exclusive, except for the last).
    pub t_end: f64,
    /// Mean time of its localisations: where its drift applies.
    pub t_mean: f64,
    /// Localisations in it.
    pub count: usize,
    /// Drift relative to the first segment, nm.
    pub dx_nm: f64,
    /// Drift relative to the first segment, nm.
    pub dy_nm: f64,
}

/// A drift estimate: the segments and how they were found.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftEstimate {
    /// Per segment, in time order.
    pub segments: Vec<SegmentDrift>,
    /// RCC: histogram bin used, nm (0 for fiducials).
    pub bin_nm: f64,
    /// RCC: pairs kept in the final solution; fiducials: spots followed.
    pub used: usize,
    /// RCC: pairs correlated; fiducials: candidate spots in the first segment.
    pub total: usize,
    /// RCC: RMS residual of the kept pairs, nm; fiducials: RMS spread of the
    /// spots' displacements about their mean, nm.
    pub residual_rms_nm: f64,
}

impl DriftEstimate {
    /// The trajectory as CSV, one row per segment (`t_mean_s` filled when
    /// the length of a time unit, `frame_s` seconds, is known).
    pub fn trajectory_csv(&self, frame_s: Option<f64>) -> String {
        let mut s =
            String::from("segment,t_start,t_end,t_mean,t_mean_s,localisations,dx_nm,dy_nm\n");
        for (k, g) in self.segments.iter().enumerate() {
            let secs = frame_s.map_or(String::new(), |f| format_decimal(g.t_mean * f, 6));
            let _ = writeln!(
                s,
                "{},{},{},{},{secs},{},{},{}",
                k + 1,
                format_decimal(g.t_start, 3),
                format_decimal(g.t_end, 3),
                format_decimal(g.t_mean, 3),
                g.count,
                format_decimal(g.dx_nm, 3),
                format_decimal(g.dy_nm, 3)
            );
        }
        s
    }

    /// The drift at time `t`, nm: linear between the segments' mean times,
    /// extrapolated linearly beyond the first and last.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let s = &self.segments;
        match s.len() {
            0 => (0.0, 0.0),
            1 => (s[0].dx_nm, s[0].dy_nm),
            n => {
                // The interval [k, k+1] holding t (the end ones extended).
                let k = s[1..n - 1].partition_point(|seg| seg.t_mean <= t);
                let (a, b) = (&s[k], &s[k + 1]);
                let span = b.t_mean - a.t_mean;
                let f = if span > 0.0 {
                    (t - a.t_mean) / span
                } else {
                    0.0
                };
                (
                    a.dx_nm + f * (b.dx_nm - a.dx_nm),
                    a.dy_nm + f * (b.dy_nm - a.dy_nm),
                )
            }
        }
    }
}

/// The time column(s) of a localisation table: a blink table's (start,
/// end) pair in bit-planes, or a frame table's `frame` (twice), with the
/// unit's name. A localisation's time is the middle of the two.
pub fn time_columns(t: &CsvTable) -> Option<(usize, usize, String)> {
    for (a, b) in [
        ("t_start [plane]", "t_end [plane]"),
        ("t_s [plane]", "t_e [plane]"),
    ] {
        if let (Some(i), Some(j)) = (t.column(&[a]), t.column(&[b])) {
            return Some((i, j, "plane".into()));
        }
    }
    t.column(&["frame"]).map(|i| (i, i, "frame".into()))
}

/// Segment time bounds and the points of each segment.
pub(crate) type Segments = (Vec<(f64, f64)>, Vec<Vec<DriftPoint>>);

/// The usable points split into segments of equal duration: the segments'
/// time bounds and the points of each. Errors name what is missing.
pub(crate) fn split(points: &[DriftPoint], opts: &DriftOptions) -> Result<Segments, DriftError> {
    opts.validate()?;
    let usable: Vec<DriftPoint> = points
        .iter()
        .filter(|p| p.t.is_finite() && p.x_nm.is_finite() && p.y_nm.is_finite())
        .copied()
        .collect();
    let k = opts.segments;
    let needed = k * MIN_PER_SEGMENT;
    if usable.len() < needed {
        return Err(DriftError::TooFew {
            found: usable.len(),
            needed,
            per: MIN_PER_SEGMENT,
            segments: k,
        });
    }
    let t0 = usable.iter().map(|p| p.t).fold(f64::INFINITY, f64::min);
    let t1 = usable.iter().map(|p| p.t).fold(f64::NEG_INFINITY, f64::max);
    let span = t1 - t0;
    if !(span > 0.0 && span.is_finite()) {
        return Err(DriftError::NoTimeSpan { t: t0 });
    }
    let mut groups: Vec<Vec<DriftPoint>> = vec![Vec::new(); k];
    for p in usable {
        let i = (((p.t - t0) / span) * k as f64).floor();
        groups[(i.max(0.0) as usize).min(k - 1)].push(p);
    }
    for (i, g) in groups.iter().enumerate() {
        if g.len() < MIN_PER_SEGMENT {
            return Err(DriftError::SparseSegment {
                segment: i + 1,
                segments: k,
                found: g.len(),
                needed: MIN_PER_SEGMENT,
            });
        }
    }
    let bounds = (0..k)
        .map(|i| {
            (
                t0 + span * i as f64 / k as f64,
                t0 + span * (i + 1) as f64 / k as f64,
            )
        })
        .collect();
    Ok((bounds, groups))
}

/// Segment records from per-segment drifts.
pub(crate) fn segments_from(
    bounds: &[(f64, f64)],
    groups: &[Vec<DriftPoint>],
    drift: &[(f64, f64)],
) -> Vec<SegmentDrift> {
    bounds
        .iter()
        .zip(groups)
        .zip(drift)
        .map(|((&(t_start, t_end), g), &(dx, dy))| SegmentDrift {
            t_start,
            t_end,
            t_mean: g.iter().map(|p| p.t).sum::<f64>() / g.len() as f64,
            count: g.len(),
            dx_nm: dx,
            dy_nm: dy,
        })
        .collect()
}
