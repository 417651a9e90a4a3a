//! `P(H ≥ T_int)` of one window, exact or by the saddle point, and the
//! public functions on it: the tail, the detection probability and the
//! false-alarm report beside the Gaussian.

use super::lattice::{background_classes, Class, Prepared};
use super::saddle_point::saddle_point_tail;
use super::{
    check_p, check_window, invalid, pixel_classes, DetectionProbability, FalseAlarmError,
    FalseAlarmReport, Method, TailProbability,
};
use crate::kernel::IntegerKernel;
use crate::stats::Detection;
use std::collections::BTreeMap;

/// `P(X ≥ threshold)` for a sum of scaled binomials, exact when affordable.
pub(super) fn class_tail(classes: &[Class], threshold: u64) -> TailProbability {
    let prep = Prepared::new(classes, threshold);
    if threshold == 0 {
        return TailProbability {
            p: 1.0,
            method: Method::Exact,
            truncation_bound: 0.0,
        };
    }
    if threshold > prep.max {
        return TailProbability {
            p: 0.0,
            method: Method::Exact,
            truncation_bound: 0.0,
        };
    }
    if prep.exact_feasible() {
        let l = prep.exact();
        TailProbability {
            p: l.tail,
            method: Method::Exact,
            truncation_bound: l.truncated,
        }
    } else {
        TailProbability {
            p: saddle_point_tail(classes, threshold),
            method: Method::SaddlePoint,
            truncation_bound: 0.0,
        }
    }
}

/// `P(H ≥ T_int)` per background-only pixel-plane: H summed over
/// `n_window` planes with the integer kernel, every pixel Bernoulli(`p_off`)
/// per plane. Exact lattice method, or the saddle point over budget.
pub fn tail_probability(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
) -> Result<TailProbability, FalseAlarmError> {
    check_window(n_window)?;
    check_p("p_off", p_off)?;
    let pixels = pixel_classes(kernel)?;
    Ok(class_tail(
        &background_classes(&pixels, n_window as u64, p_off),
        threshold_int,
    ))
}

/// The Lugannani–Rice approximation of [`tail_probability`], whatever the
/// budget (for comparisons).
pub fn tail_probability_saddle_point(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
) -> Result<f64, FalseAlarmError> {
    check_window(n_window)?;
    check_p("p_off", p_off)?;
    let pixels = pixel_classes(kernel)?;
    Ok(saddle_point_tail(
        &background_classes(&pixels, n_window as u64, p_off),
        threshold_int,
    ))
}

/// Exact detection probability of a molecule on for the whole window: H at
/// the molecule's pixel with each pixel Bernoulli(`E(B_on)`) from
/// [`Detection::e_b_on`], at `T_int`.
pub fn detection_probability(det: &Detection) -> Result<DetectionProbability, FalseAlarmError> {
    let kernel = det.kernel();
    kernel.validate()?;
    check_window(det.n_window)?;
    let k = kernel.size();
    if det.e_b_on.len() != k * k {
        return Err(invalid(
            "e_b_on",
            det.e_b_on.len() as f64,
            "must hold k×k probabilities",
        ));
    }
    let mut map: BTreeMap<(u64, u64), u64> = BTreeMap::new();
    for i in 0..k {
        for j in 0..k {
            let p = check_p("e_b_on", det.e_b_on[i * k + j])?;
            *map.entry((kernel.weight_2d(i, j), p.to_bits()))
                .or_insert(0) += 1;
        }
    }
    let classes: Vec<Class> = map
        .into_iter()
        .map(|((w, pb), c)| Class {
            weight: w,
            trials: c * det.n_window as u64,
            p: f64::from_bits(pb),
        })
        .collect();
    let prep = Prepared::new(&classes, det.threshold_int);
    if prep.exact_feasible() && det.threshold_int <= prep.max {
        let l = prep.exact();
        let miss: f64 = l.below.iter().sum();
        Ok(DetectionProbability {
            detection: l.tail,
            miss,
            method: Method::Exact,
        })
    } else {
        let t = class_tail(&classes, det.threshold_int);
        Ok(DetectionProbability {
            detection: t.p,
            miss: 1.0 - t.p,
            method: t.method,
        })
    }
}

/// Per pixel-plane and per second false alarms of a derived threshold, beside
/// the Gaussian prediction, for a `width × height` field at `plane_rate_hz`.
pub fn false_alarm_report(
    det: &Detection,
    width: u32,
    height: u32,
    plane_rate_hz: f64,
) -> Result<FalseAlarmReport, FalseAlarmError> {
    if !plane_rate_hz.is_finite() || plane_rate_hz <= 0.0 {
        return Err(invalid(
            "plane_rate_hz",
            plane_rate_hz,
            "must be finite and > 0",
        ));
    }
    let tail = tail_probability(&det.kernel(), det.n_window, det.p_off, det.threshold_int)?;
    let field_pixels = width as u64 * height as u64;
    let g = det.gaussian_false_alarm_probability;
    Ok(FalseAlarmReport {
        n_window: det.n_window,
        threshold_int: det.threshold_int,
        per_pixel_plane: tail.p,
        method: tail.method,
        gaussian_per_pixel_plane: g,
        ratio_to_gaussian: (g > 0.0).then(|| tail.p / g),
        field_pixels,
        plane_rate_hz,
        per_second: tail.p * field_pixels as f64 * plane_rate_hz,
        gaussian_per_second: g * field_pixels as f64 * plane_rate_hz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_tails() {
        let k = IntegerKernel::gaussian(1.0, 3, 4).unwrap();
        // p = 0: H = 0 always.
        let t = tail_probability(&k, 10, 0.0, 1).unwrap();
        assert_eq!(t.p, 0.0);
        // Threshold 0 is always reached; a threshold above the maximum never.
        assert_eq!(tail_probability(&k, 10, 0.1, 0).unwrap().p, 1.0);
        assert_eq!(tail_probability(&k, 10, 0.1, 256 * 10 + 1).unwrap().p, 0.0);
        // The maximum: every pixel fires in every plane.
        let t = tail_probability(&k, 2, 0.5, 256 * 2).unwrap();
        assert!((t.p - 0.5f64.powi(18)).abs() < 1e-18, "{}", t.p);
        // p = 1: H is the maximum.
        assert_eq!(tail_probability(&k, 3, 1.0, 768).unwrap().p, 1.0);
        assert!(
            (saddle_point_tail(
                &background_classes(&pixel_classes(&k).unwrap(), 2, 0.5),
                512
            ) - 0.5f64.powi(18))
            .abs()
                < 1e-18
        );
    }
}
