//! Detection designed for the whole field: two thresholds (open and hold),
//! chosen for a false-blink budget over the sensor, instead of the paper's
//! one per-pixel 3σ threshold.
//!
//! ## Why
//!
//! The paper's threshold (Eq. 7, `T = N·E(F_off) + 3√(N·Var F_off)`) is a
//! per-pixel rule derived for one molecule in a 32×32 ROI. Over a 320×240
//! sensor at 10 kHz, background alone crosses it in hundreds of thousands of
//! places a second: every crossing opens a track, the slots fill with
//! background and real blinks find none. Raising `L_min` (confirm only long
//! tracks) removes the false blinks but also every blink shorter than about
//! three windows.
//!
//! ## The design (Neyman–Pearson over the field)
//!
//! * **Open level** `T_open` (the pipeline's `T_int`): the smallest integer
//!   threshold whose background-only track openings over the field stay
//!   within the budget `β` false blinks per second:
//!   `P(U; T_open) · W·H · f ≤ β`, with `P(U) = P(H_{t−1} < T ≤ H_t)` the
//!   exact per-pixel up-crossing probability
//!   ([`crate::false_alarm::BackgroundProcess::upcrossing`]) and f the plane
//!   rate. A background track can only open where some pixel up-crosses
//!   `T_open`, and one excursion usually up-crosses at several neighbouring
//!   pixels, so this is an upper bound on the false-blink rate (measured
//!   against simulation in `tests/field_design.rs` and by
//!   `smartagg study field-detection`).
//! * **Hold level** `T_hold`: the paper's Eq. 7 threshold (at most
//!   `T_open`). An open track stays on while the 3×3 maximum of H around its
//!   anchor is `≥ T_hold`: the molecule's own shot noise cannot split its
//!   blink into several tracks, and the track's live range (and so its ROI)
//!   spans the blink as the paper's rule does.
//! * **Association radius** `r_assoc = max(1, round(2σ))` pixels (σ the PSF
//!   width): the maxima of one blink's H wander by about the PSF's width,
//!   and a candidate within 2σ of a live anchor belongs to that molecule.
//! * **`L_min = 1`**: the open level already controls the false blinks, so
//!   every open track is confirmed and short blinks are kept.
//! * **N** stays the paper's Eq. 6 window.
//! * **Summed planes** `end_trim = ⌊N/2⌋`: a dropped segment sums
//!   `[t_cross − N, t_drop − ⌊N/2⌋]`, from a window before the crossing to
//!   the estimated end of the blink `t_e`. With the paper's rule
//!   (`end_trim = 0`, sum to `t_drop`) the ROI also takes the planes after
//!   the blink in which the window still held it above the hold level —
//!   about `(1 − k)·N` planes of background alone, `k` the fraction of the
//!   window's signal that the hold level needs — and at the study's light
//!   the background, mostly dark counts, is what limits a short blink's
//!   localisation. The open level is high, so the crossing comes late in
//!   the blink's first window and the whole pre-roll `t_cross − N` is kept.
//!
//! ## Predicted recall
//!
//! A blink of `D` planes is detected when H at its pixel reaches `T_open`.
//! With `k = min(D, N)` on-planes in the window, H is approximately normal
//! with mean `N·E(F_off) + k·(E F_on − E F_off)` and variance
//! `(N−k)·Var F_off + k·Var F_on` (Eq. 3–4); [`FieldDesign::recall`] takes
//! the chance `p` that it reaches `T_open` at the window's peak, and counts
//! the plateau of a blink longer than N as `(D − N)/N` more independent
//! looks: `1 − (1 − p)^(1 + (D − N)/N)`. It ignores that a molecule between
//! pixel centres gives a lower peak and that the candidate is the maximum of
//! several noisy pixels; the study (`smartagg study field-detection`) prints
//! it beside the measured recall.

use crate::config::{ConfigError, PipelineConfig};
use crate::false_alarm::{BackgroundProcess, FalseAlarmError};
use crate::stats::{normal_sf, Detection};
use serde::Serialize;
use thiserror::Error;

/// Default false-blink budget over the whole field, per second.
pub const DEFAULT_FALSE_BLINKS_PER_S: f64 = 1.0;

/// Recall that [`FieldDesign::shortest_blink_planes`] asks for.
pub const SHORTEST_BLINK_RECALL: f64 = 0.9;

/// Why a field design could not be made.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FieldDesignError {
    /// An input out of range (the message names it).
    #[error("field design: `{name}` = {value}: {why}")]
    Invalid {
        /// The input.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The rule it breaks.
        why: &'static str,
    },
    /// The false-alarm statistics failed.
    #[error(transparent)]
    FalseAlarm(#[from] FalseAlarmError),
    /// No threshold keeps background within the budget.
    #[error("no open threshold keeps background-only false blinks within {budget_per_s}/s over {pixels} pixels: even H at its maximum is crossed {best_per_s:.3e} times/s")]
    Unreachable {
        /// The budget, per second.
        budget_per_s: f64,
        /// Pixels in the field.
        pixels: u64,
        /// The rate at the highest threshold.
        best_per_s: f64,
    },
}

/// The detection parameters of a field, with what they predict.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FieldDesign {
    /// Field width, pixels.
    pub width: u32,
    /// Field height, pixels.
    pub height: u32,
    /// Plane rate, Hz.
    pub plane_rate_hz: f64,
    /// Budget of background-only false blinks over the field, per second.
    pub budget_per_s: f64,
    /// Window N, planes (the paper's Eq. 6).
    pub n_window: u32,
    /// `T_open`, integer units of H: the pipeline's `T_int`.
    pub threshold_open: u64,
    /// `T_hold`, integer units of H (the paper's Eq. 7 threshold, ≤ `T_open`).
    pub threshold_hold: u64,
    /// `T_open` in standard deviations of background H above its mean.
    pub open_sigmas: f64,
    /// `T_hold` in standard deviations of background H above its mean.
    pub hold_sigmas: f64,
    /// Association radius, pixels.
    pub r_assoc: u32,
    /// L_min, planes.
    pub l_min: u32,
    /// Planes between a dropped segment's last summed plane and its
    /// `t_drop`: `⌊N/2⌋`, the estimated end of the blink.
    pub end_trim: u32,
    /// Exact per-pixel up-crossing probability of `T_open` per plane.
    pub upcrossing_per_pixel_plane: f64,
    /// Bound on background-only false blinks over the field, per second.
    pub predicted_false_blinks_per_s: f64,
    /// Shortest blink, planes, detected with at least
    /// [`SHORTEST_BLINK_RECALL`] (predicted); `None` if no blink is.
    pub shortest_blink_planes: Option<u32>,
    /// The statistics' per-plane moments, normalised units:
    /// `(E F_off, Var F_off, E F_on, Var F_on)`.
    #[serde(skip)]
    moments: (f64, f64, f64, f64),
    /// One unit of H in normalised units.
    #[serde(skip)]
    unit: f64,
}

impl FieldDesign {
    /// Sets the design's detection in `cfg`, the one place that maps a
    /// design onto a pipeline (`smartagg aggregate`, the studies, the shipped
    /// gateware designs): `T_int = T_open`, `T_hold`, `r_assoc`, `L_min`,
    /// `end_trim`, and `L_max` raised to one second of bit-planes (and to
    /// `L_min`) if it is shorter: a blink is cut after a second whatever the
    /// plane rate (10,000 planes for the SPCImager, 100,000 for a SPAD512S,
    /// whose 10,000 planes would cut its 100 ms blinks). Fails when a
    /// threshold does not fit the pipeline's 32 bits.
    pub fn apply(&self, cfg: &mut PipelineConfig) -> Result<(), ConfigError> {
        let t32 = |field: &'static str, v: u64| {
            u32::try_from(v).map_err(|_| ConfigError::Invalid {
                field,
                value: v.to_string(),
                why: "the designed threshold does not fit 32 bits".into(),
            })
        };
        cfg.threshold_int = t32("threshold_int", self.threshold_open)?;
        cfg.threshold_hold = t32("threshold_hold", self.threshold_hold)?;
        cfg.r_assoc = self.r_assoc;
        cfg.l_min = self.l_min;
        let one_second = self.plane_rate_hz.round().clamp(1.0, 1e9) as u32;
        cfg.l_max = cfg.l_max.max(self.l_min).max(one_second);
        cfg.end_trim = self.end_trim;
        Ok(())
    }

    /// Predicted probability that a blink of `planes` bit-planes, centred on
    /// a pixel, opens a track (module docs).
    pub fn recall(&self, planes: u32) -> f64 {
        if planes == 0 {
            return 0.0;
        }
        let n = self.n_window as f64;
        let k = (planes.min(self.n_window)) as f64;
        let (e_off, v_off, e_on, v_on) = self.moments;
        let mean = n * e_off + k * (e_on - e_off);
        let var = (n - k) * v_off + k * v_on;
        let t = self.threshold_open as f64 * self.unit;
        let p = if var > 0.0 {
            normal_sf((t - mean) / var.sqrt())
        } else if mean >= t {
            1.0
        } else {
            0.0
        };
        // A plateau of D − N planes beyond the first full window: one more
        // independent look per N planes (fractional, so that the prediction
        // is continuous in D).
        let looks = 1.0 + planes.saturating_sub(self.n_window) as f64 / n;
        1.0 - (1.0 - p).powf(looks)
    }

    /// Shortest blink, planes, with predicted recall ≥ `recall` (searched up
    /// to 100 windows); `None` if none.
    pub fn shortest_blink(&self, recall: f64) -> Option<u32> {
        let max = self.n_window.saturating_mul(100).max(1);
        // recall() is non-decreasing in the duration: bisect.
        if self.recall(max) < recall {
            return None;
        }
        let (mut lo, mut hi) = (1u32, max);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if self.recall(mid) >= recall {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        Some(lo)
    }
}

/// Designs the open and hold thresholds, association radius and L_min of
/// a `width × height` field at `plane_rate_hz` for at most `budget_per_s`
/// background-only false blinks per second (module docs).
pub fn design(
    det: &Detection,
    width: u32,
    height: u32,
    plane_rate_hz: f64,
    budget_per_s: f64,
) -> Result<FieldDesign, FieldDesignError> {
    let bad = |name, value: f64, why| FieldDesignError::Invalid { name, value, why };
    if width == 0 || height == 0 {
        return Err(bad(
            "field",
            (width as u64 * height as u64) as f64,
            "must have at least one pixel",
        ));
    }
    if !plane_rate_hz.is_finite() || plane_rate_hz <= 0.0 {
        return Err(bad(
            "plane_rate_hz",
            plane_rate_hz,
            "must be finite and > 0",
        ));
    }
    if !budget_per_s.is_finite() || budget_per_s <= 0.0 {
        return Err(bad(
            "false_blinks_per_s",
            budget_per_s,
            "must be finite and > 0",
        ));
    }
    let kernel = det.kernel();
    let pixels = width as u64 * height as u64;
    let scale = pixels as f64 * plane_rate_hz;
    let rate_at = |t: u64| -> Result<(f64, f64), FieldDesignError> {
        let u = BackgroundProcess::new(&kernel, det.n_window, det.p_off, t)?.upcrossing();
        Ok((u, u * scale))
    };
    let hold = det.threshold_int.max(1);
    // H never exceeds N·2^(2a): a threshold above it never opens a track.
    let top = det.n_window as u64 * (1u64 << (2 * det.kernel_shift as u32));
    let (mut u_open, mut rate) = rate_at(hold)?;
    let mut open = hold;
    if rate > budget_per_s {
        if hold >= top {
            return Err(FieldDesignError::Unreachable {
                budget_per_s,
                pixels,
                best_per_s: rate,
            });
        }
        // The up-crossing rate falls with T. Double T until it is within
        // the budget (the lattice's work grows with T, so the bracket is
        // kept near the answer rather than reaching up to `top`), then
        // search the bracket for the smallest T within it.
        let mut below = (hold, rate);
        let above = loop {
            let t = below.0.saturating_mul(2).min(top);
            let (u, r) = rate_at(t)?;
            if r <= budget_per_s {
                break (t, r, u);
            }
            if t >= top {
                return Err(FieldDesignError::Unreachable {
                    budget_per_s,
                    pixels,
                    best_per_s: r,
                });
            }
            below = (t, r);
        };
        let (t, r, u) = smallest_within(below, above, budget_per_s, |t| {
            rate_at(t).map(|(u, r)| (r, u))
        })?;
        open = t;
        (u_open, rate) = (u, r);
    }
    let unit = det.threshold_unit;
    let sigmas = |t: u64| {
        if det.sd_h_off > 0.0 {
            (t as f64 * unit - det.e_h_off) / det.sd_h_off
        } else {
            f64::INFINITY
        }
    };
    let mut d = FieldDesign {
        width,
        height,
        plane_rate_hz,
        budget_per_s,
        n_window: det.n_window,
        threshold_open: open,
        threshold_hold: hold,
        open_sigmas: sigmas(open),
        hold_sigmas: sigmas(hold),
        r_assoc: ((2.0 * det.sigma_px).round() as u32).max(1),
        l_min: 1,
        end_trim: det.n_window / 2,
        upcrossing_per_pixel_plane: u_open,
        predicted_false_blinks_per_s: rate,
        shortest_blink_planes: None,
        moments: (det.e_f_off, det.var_f_off, det.e_f_on, det.var_f_on),
        unit,
    };
    d.shortest_blink_planes = d.shortest_blink(SHORTEST_BLINK_RECALL);
    Ok(d)
}

/// The smallest integer `t` in `(lo.0, hi.0]` whose rate is within
/// `budget`, with that rate and what `rate` gave beside it: `lo` is
/// `(t, rate)` and `hi` `(t, rate, extra)` with `rate(lo) > budget ≥
/// rate(hi)`, and the rate does not rise with `t`. `rate(t)` returns
/// `(rate, extra)` and is only called strictly inside the bracket.
///
/// Each evaluation of the design's rate is a lattice convolution, so the
/// search steps by the secant of `ln(rate / budget)` through the last two
/// levels evaluated (a smooth function of T for an exact tail, whose root it
/// approaches superlinearly from either side), falling back to the
/// bracket's own secant (regula falsi) when that one leaves the bracket.
/// After three steps in a row that do not halve the bracket (a secant
/// converging from one side leaves the other end where it was), it
/// bisects: at most four times bisection's evaluations, whatever the
/// rate's shape.
fn smallest_within<X, E>(
    lo: (u64, f64),
    hi: (u64, f64, X),
    budget: f64,
    mut rate: impl FnMut(u64) -> Result<(f64, X), E>,
) -> Result<(u64, f64, X), E> {
    // ln(rate / budget): > 0 at the low end, ≤ 0 at the high end (−∞ for a
    // rate of 0, where the secants give way to bisection).
    let excess = |r: f64| (r / budget).ln();
    let (mut lo, mut g_lo) = (lo.0, excess(lo.1));
    let mut g_hi = excess(hi.1);
    let mut hi = hi;
    // The last two levels evaluated, with their excess.
    let (mut prev, mut last) = ((lo, g_lo), (hi.0, g_hi));
    // Steps in a row that did not halve the bracket.
    let mut slow = 0;
    // Where the secant through (a, g_a) and (b, g_b) crosses zero, if it
    // does strictly inside the bracket.
    let secant = |(a, ga): (u64, f64), (b, gb): (u64, f64), lo: u64, hi: u64| {
        let x = b as f64 - gb * (b as f64 - a as f64) / (gb - ga);
        (ga.is_finite() && gb.is_finite() && x > lo as f64 && x < hi as f64).then_some(x)
    };
    while hi.0 - lo > 1 {
        let width = hi.0 - lo;
        let x = (slow < 3)
            .then(|| {
                secant(prev, last, lo, hi.0).or_else(|| secant((lo, g_lo), (hi.0, g_hi), lo, hi.0))
            })
            .flatten();
        let t = match x {
            Some(x) => (x.round() as u64).clamp(lo + 1, hi.0 - 1),
            None => lo + width / 2,
        };
        let (r, extra) = rate(t)?;
        let g = excess(r);
        if r <= budget {
            (hi, g_hi) = ((t, r, extra), g);
        } else {
            (lo, g_lo) = (t, g);
        }
        (prev, last) = (last, (t, g));
        // Bisection leaves at most ⌈width/2⌉.
        slow = if 2 * (hi.0 - lo) > width + 1 {
            slow + 1
        } else {
            0
        };
    }
    Ok(hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{Preset, PresetName};
    use crate::stats::{derive, DetectionInputs};

    fn spcimager(objective: u32) -> Detection {
        let p = Preset::new(PresetName::Spcimager, objective).unwrap();
        derive(&DetectionInputs::from_preset(&p, None).unwrap()).unwrap()
    }

    #[test]
    fn the_open_level_is_the_smallest_within_the_budget() {
        let det = spcimager(150);
        let d = design(&det, 320, 240, 10_000.0, 1.0).unwrap();
        assert_eq!(d.threshold_hold, det.threshold_int);
        assert!(d.threshold_open > d.threshold_hold);
        assert!(d.predicted_false_blinks_per_s <= 1.0);
        // One unit lower is over the budget: the search found the edge.
        let below =
            BackgroundProcess::new(&det.kernel(), det.n_window, det.p_off, d.threshold_open - 1)
                .unwrap()
                .upcrossing()
                * 320.0
                * 240.0
                * 10_000.0;
        assert!(below > 1.0, "{below}");
        assert!(
            d.open_sigmas > 6.0 && d.open_sigmas < 8.0,
            "{}",
            d.open_sigmas
        );
        assert!((d.hold_sigmas - 3.0).abs() < 0.01, "{}", d.hold_sigmas);
        assert_eq!((d.r_assoc, d.l_min), (3, 1));
        // A smaller field affords a lower open level; a larger budget too.
        let small = design(&det, 32, 32, 10_000.0, 1.0).unwrap();
        assert!(small.threshold_open < d.threshold_open);
        let loose = design(&det, 320, 240, 10_000.0, 100.0).unwrap();
        assert!(loose.threshold_open < d.threshold_open);
        // At 60× the PSF is 0.6 px: r_assoc 1.
        assert_eq!(
            design(&spcimager(60), 320, 240, 10_000.0, 1.0)
                .unwrap()
                .r_assoc,
            1
        );
    }

    #[test]
    fn a_blink_is_cut_after_one_second_whatever_the_plane_rate() {
        let det = spcimager(150);
        let mut cfg = PipelineConfig::new(
            320,
            240,
            det.n_window,
            det.kernel_weights.clone(),
            det.kernel_shift,
            1,
        );
        design(&det, 320, 240, 10_000.0, 1.0)
            .unwrap()
            .apply(&mut cfg)
            .unwrap();
        assert_eq!(cfg.l_max, 10_000);
        design(&det, 320, 240, 100_000.0, 1.0)
            .unwrap()
            .apply(&mut cfg)
            .unwrap();
        assert_eq!(cfg.l_max, 100_000);
        assert!(cfg.validate().is_ok());
    }

    #[test]
    fn recall_rises_with_duration_and_names_the_shortest_blink() {
        let d = design(&spcimager(150), 320, 240, 10_000.0, 1.0).unwrap();
        assert_eq!(d.recall(0), 0.0);
        let mut last = 0.0;
        for planes in [1, 10, 50, 100, 109, 150, 200, 300, 1000] {
            let r = d.recall(planes);
            assert!(r.is_finite() && (0.0..=1.0).contains(&r));
            assert!(r >= last, "{planes}: {r} < {last}");
            last = r;
        }
        let s = d.shortest_blink_planes.unwrap();
        assert!(d.recall(s) >= SHORTEST_BLINK_RECALL);
        assert!(d.recall(s - 1) < SHORTEST_BLINK_RECALL);
        // Blinks a window long or more are detected at this budget.
        assert!(s > 50 && s < 1000, "{s}");
    }

    #[test]
    fn bad_inputs_are_named() {
        let det = spcimager(150);
        for (w, h, rate, budget, name) in [
            (0, 240, 1e4, 1.0, "field"),
            (320, 240, 0.0, 1.0, "plane_rate_hz"),
            (320, 240, f64::NAN, 1.0, "plane_rate_hz"),
            (320, 240, 1e4, 0.0, "false_blinks_per_s"),
            (320, 240, 1e4, -1.0, "false_blinks_per_s"),
            (320, 240, 1e4, f64::INFINITY, "false_blinks_per_s"),
        ] {
            let e = design(&det, w, h, rate, budget).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{e}");
        }
    }

    #[test]
    fn an_unreachable_budget_is_an_error() {
        // One plane of a bright background, held near H's mean: H at its
        // maximum (every pixel on) is crossed at about 0.9^81 per
        // pixel-plane, far above 1/s over the field.
        let mut det = spcimager(150);
        (det.n_window, det.p_off, det.threshold_int) = (1, 0.9, 58_000);
        match design(&det, 320, 240, 10_000.0, 1.0) {
            Err(FieldDesignError::Unreachable { best_per_s, .. }) => {
                assert!(best_per_s > 1e3, "{best_per_s}")
            }
            other => panic!("{other:?}"),
        }
        // A hold level already above H's maximum: no search, no panic.
        det.threshold_int = 1 << 17;
        let d = design(&det, 320, 240, 10_000.0, 1.0).unwrap();
        assert_eq!(d.threshold_open, 1 << 17);
        assert_eq!(d.predicted_false_blinks_per_s, 0.0);
    }

    /// Evaluations that bisecting a bracket `(lo, lo + width]` makes.
    fn bisections(width: u64) -> u32 {
        64 - (width - 1).leading_zeros()
    }

    proptest::proptest! {
        #[test]
        fn the_search_finds_the_first_level_within_the_budget(
            lo in 0u64..1_000,
            width in 1u64..5_000,
            edge_at in 0.0f64..1.0,
            shape in 0usize..5,
            a in 1e-3f64..2.0,
            budget in 1e-9f64..1e3,
        ) {
            let hi = lo + width;
            // The first level within the budget, in (lo, hi].
            let edge = lo + 1 + ((width - 1) as f64 * edge_at) as u64;
            // rate / budget: > 1 below the edge, ≤ 1 from it on, never rising.
            let ratio = |t: u64| -> f64 {
                let (t, e) = (t as f64, edge as f64);
                match shape {
                    0 => (-a * (t - e)).exp(),
                    1 => (-a * ((t - lo as f64).powi(2) - (e - lo as f64).powi(2)) / width as f64).exp(),
                    2 => if t < e { 2.0 } else { 0.0 },
                    3 => 1.0 - 1e-12 * (t - e + 0.5),
                    _ => if t < e { 1e300 } else { 1e-300 },
                }
            };
            let rate = |t: u64| budget * ratio(t);
            let mut calls = Vec::new();
            let (t, r, x) = smallest_within((lo, rate(lo)), (hi, rate(hi), hi), budget, |t| {
                calls.push(t);
                Ok::<_, ()>((rate(t), t))
            })
            .unwrap();
            proptest::prop_assert_eq!((t, r, x), (edge, rate(edge), edge));
            proptest::prop_assert!(calls.iter().all(|&c| c > lo && c < hi), "{:?}", calls);
            proptest::prop_assert!(
                calls.len() as u32 <= 4 * bisections(width),
                "{} calls for a bracket of {}: {:?}", calls.len(), width, calls
            );
        }
    }

    #[test]
    fn the_open_level_takes_a_handful_of_lattices() {
        let det = spcimager(150);
        let d = design(&det, 320, 240, 10_000.0, 1.0).unwrap();
        let (kernel, scale) = (det.kernel(), 320.0 * 240.0 * 10_000.0);
        let rate = |t| {
            BackgroundProcess::new(&kernel, det.n_window, det.p_off, t)
                .map(|b| b.upcrossing() * scale)
        };
        // The bracket the design's doubling finds.
        let (lo, hi) = (det.threshold_int, 2 * det.threshold_int);
        let (r_lo, r_hi) = (rate(lo).unwrap(), rate(hi).unwrap());
        assert!(r_lo > 1.0 && r_hi <= 1.0, "{r_lo} {r_hi}");
        let mut calls = 0;
        let (t, r, ()) = smallest_within((lo, r_lo), (hi, r_hi, ()), 1.0, |t| {
            calls += 1;
            rate(t).map(|r| (r, ()))
        })
        .unwrap();
        assert_eq!((t, r), (d.threshold_open, d.predicted_false_blinks_per_s));
        // Bisection takes 17 lattices for this bracket.
        assert_eq!(bisections(hi - lo), 17);
        assert!(calls <= 6, "{calls} lattices");
    }
}
