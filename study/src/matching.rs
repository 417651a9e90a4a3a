//! Truth matching: which localisation belongs to which blink.
//!
//! **The rule.** A localisation matches a blink when it lies within the
//! match radius (the paper's 53.3 nm, one 150× SPCIMAGER pixel) of the blink's
//! true position *and* its time interval overlaps the blink's on-time (smart
//! ROIs: the bit-planes summed into the ROI; frames: the frame's exposure;
//! merged localisations: the union of their frames). A localisation that
//! could match several blinks goes to the nearest. Unmatched localisations
//! are false positives; a blink with no match is missed. Every match counts
//! in the RMS error — a blink spread over three EMCCD frames contributes
//! three localisations, some of them poor, which is the paper's point.

/// One localisation, in the field's coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loc {
    /// x, nm from the field's left edge.
    pub x_nm: f64,
    /// y, nm from the field's top edge.
    pub y_nm: f64,
    /// Start of the data it came from, s.
    pub t0_s: f64,
    /// End of the data it came from, s (exclusive).
    pub t1_s: f64,
    /// Fitted photons (detections).
    pub photons: f64,
}

/// What one scheme made of one blink.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BlinkOutcome {
    /// Localisations matched to the blink.
    pub matches: u32,
    /// Σ of squared distances to the truth over the matches, nm².
    /// For a reference scheme (a bound): Σ of the bound's `var_x + var_y`.
    pub sse_nm2: f64,
    /// Σ of x errors (localisation − truth), nm.
    pub sum_dx_nm: f64,
    /// Σ of y errors, nm.
    pub sum_dy_nm: f64,
}

/// What one scheme made of one work item.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SchemeOutcome {
    /// One entry per blink of the item, in time order.
    pub blinks: Vec<BlinkOutcome>,
    /// Detections: smart records, or frame candidates (merged: chains plus
    /// failed fits). Each gives at most one localisation.
    pub detections: u32,
    /// Detections that gave no matched localisation (unmatched, failed fit,
    /// or a record that could not match any blink and was not fitted).
    pub false_pos: u32,
    /// Fits that failed (not converged, outside the ROI, …) and were dropped.
    pub failed_fits: u32,
}

/// A blink's truth as seen by the matcher.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    /// x, nm.
    pub x_nm: f64,
    /// y, nm.
    pub y_nm: f64,
    /// Start of the on-time, s.
    pub t_on_s: f64,
    /// End of the on-time, s.
    pub t_off_s: f64,
}

impl From<&crate::timeline::BlinkNm> for Truth {
    fn from(b: &crate::timeline::BlinkNm) -> Truth {
        Truth {
            x_nm: b.x_nm,
            y_nm: b.y_nm,
            t_on_s: b.t_on_s,
            t_off_s: b.t_off_s,
        }
    }
}

impl From<&smartagg_scene::truth::BlinkTruth> for Truth {
    fn from(b: &smartagg_scene::truth::BlinkTruth) -> Truth {
        Truth {
            x_nm: b.x_nm,
            y_nm: b.y_nm,
            t_on_s: b.t_on_s,
            t_off_s: b.t_off_s,
        }
    }
}

/// For every localisation, the blink it matches (index into `truth`), or
/// `None` for a false positive.
pub fn assign(truth: &[Truth], locs: &[Loc], radius_nm: f64) -> Vec<Option<usize>> {
    let r2 = radius_nm * radius_nm;
    locs.iter()
        .map(|l| {
            let mut best: Option<(usize, f64)> = None;
            for (i, b) in truth.iter().enumerate() {
                // Overlap of [t0, t1) with [t_on, t_off): both strict, so
                // touching intervals do not overlap.
                if !(l.t0_s < b.t_off_s && l.t1_s > b.t_on_s) {
                    continue;
                }
                let d2 = (l.x_nm - b.x_nm).powi(2) + (l.y_nm - b.y_nm).powi(2);
                if d2 <= r2 && best.is_none_or(|(_, bd)| d2 < bd) {
                    best = Some((i, d2));
                }
            }
            best.map(|(i, _)| i)
        })
        .collect()
}

/// The outcome of localisations `locs` (from `detections` detections, of
/// which `failed_fits` failed) against `truth`.
pub fn outcome(
    truth: &[Truth],
    locs: &[Loc],
    radius_nm: f64,
    detections: u32,
    failed_fits: u32,
) -> SchemeOutcome {
    let a = assign(truth, locs, radius_nm);
    let matched = a.iter().filter(|m| m.is_some()).count() as u32;
    let mut out = SchemeOutcome {
        blinks: vec![BlinkOutcome::default(); truth.len()],
        detections,
        false_pos: detections.saturating_sub(matched),
        failed_fits,
    };
    for (l, m) in locs.iter().zip(&a) {
        if let Some(i) = m {
            let (dx, dy) = (l.x_nm - truth[*i].x_nm, l.y_nm - truth[*i].y_nm);
            let o = &mut out.blinks[*i];
            o.matches += 1;
            o.sse_nm2 += dx * dx + dy * dy;
            o.sum_dx_nm += dx;
            o.sum_dy_nm += dy;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loc(x: f64, y: f64, t0: f64, t1: f64) -> Loc {
        Loc {
            x_nm: x,
            y_nm: y,
            t0_s: t0,
            t1_s: t1,
            photons: 100.0,
        }
    }

    fn truth() -> Vec<Truth> {
        vec![
            Truth {
                x_nm: 500.0,
                y_nm: 500.0,
                t_on_s: 0.10,
                t_off_s: 0.15,
            },
            Truth {
                x_nm: 900.0,
                y_nm: 500.0,
                t_on_s: 0.20,
                t_off_s: 0.25,
            },
        ]
    }

    #[test]
    fn radius_and_time_overlap_both_decide() {
        let t = truth();
        let locs = [
            loc(530.0, 500.0, 0.12, 0.13),   // 30 nm, overlapping: match 0
            loc(553.2, 500.0, 0.12, 0.13),   // 53.2 nm: match 0
            loc(553.4, 500.0, 0.12, 0.13),   // 53.4 nm: false
            loc(500.0, 500.0, 0.15, 0.20),   // right place, starts at t_off: false
            loc(500.0, 500.0, 0.05, 0.10),   // ends at t_on: false
            loc(500.0, 500.0, 0.05, 0.1001), // overlaps by 0.1 ms: match 0
            loc(900.0, 510.0, 0.0, 1.0),     // long frame over both: nearest is 1
        ];
        let a = assign(&t, &locs, 53.3);
        assert_eq!(
            a,
            vec![Some(0), Some(0), None, None, None, Some(0), Some(1)]
        );
        let o = outcome(&t, &locs, 53.3, 9, 2);
        assert_eq!(o.detections, 9);
        // 3 unmatched localisations and 2 failed fits.
        assert_eq!(o.false_pos, 5);
        assert_eq!(o.failed_fits, 2);
        assert_eq!(o.blinks[0].matches, 3);
        assert_eq!(o.blinks[1].matches, 1);
        let sse0 = 30.0f64.powi(2) + 53.2f64.powi(2);
        assert!((o.blinks[0].sse_nm2 - sse0).abs() < 1e-9);
        assert!((o.blinks[0].sum_dx_nm - 83.2).abs() < 1e-9);
        assert!((o.blinks[1].sum_dy_nm - 10.0).abs() < 1e-12);
    }

    #[test]
    fn a_missed_blink_has_no_match() {
        let t = truth();
        let o = outcome(&t, &[loc(900.0, 500.0, 0.2, 0.25)], 53.3, 1, 0);
        assert_eq!(o.blinks[0], BlinkOutcome::default());
        assert_eq!(o.blinks[1].matches, 1);
        assert_eq!(o.false_pos, 0);
    }
}
