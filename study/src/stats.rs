//! Summary statistics of a study: RMS error, detection and false-positive
//! rates, bias, and bootstrap confidence intervals.
//!
//! **RMS error** of a scheme at a point: `√(Σ d² / matches)` over every
//! matched localisation of every blink (d the distance to the truth, in the
//! plane: the paper's "distances to ground truth combined to form a mean
//! square error"). **Detection rate**: blinks with at least one match /
//! blinks. **False-positive rate**: detections (smart records, frame
//! candidates) without a matched localisation / detections.
//!
//! **Bootstrap** (percentile, 95 %): the blinks of a point are resampled with
//! replacement `B` times (1000 by default); each resample recomputes every
//! scheme's RMS and every ratio from the *same* resampled blinks, so ratios
//! are paired. The resample indices come from one seeded stream and are the
//! same at every point (all points have the same number of blinks), which
//! also pairs ratios across points (the hot-pixel study's "vs 0 %").
//! Resamples in which a scheme has no match at all are left out of that
//! scheme's interval; with fewer than half left, or fewer than
//! [`MIN_DETECTED_FOR_CI`] detected blinks behind the value, the interval is
//! not given (a "95 % interval" of one localisation would be a point).

use crate::item::ItemResult;
use crate::matching::BlinkOutcome;
use crate::spec::Plan;
use crate::timeline::{derive_seed, key_hash};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Detected blinks needed behind a value for its interval to be given.
pub const MIN_DETECTED_FOR_CI: usize = 10;

fn detected(b: &[BlinkOutcome]) -> usize {
    b.iter().filter(|o| o.matches > 0).count()
}

/// A value with its 95 % bootstrap interval; `None` where undefined (no match).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Estimate {
    /// Point estimate.
    pub value: Option<f64>,
    /// 2.5 % percentile.
    pub lo: Option<f64>,
    /// 97.5 % percentile.
    pub hi: Option<f64>,
}

/// What one scheme achieved at one point.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SchemeStats {
    /// Blinks simulated.
    pub blinks: u64,
    /// Blinks with at least one matched localisation.
    pub detected: u64,
    /// Matched localisations.
    pub matches: u64,
    /// Detections (smart records, frame candidates).
    pub detections: u64,
    /// Detections without a matched localisation.
    pub false_pos: u64,
    /// Fits dropped because they failed.
    pub failed_fits: u64,
    /// RMS error, nm, with its bootstrap interval.
    pub rms: Estimate,
    /// Mean x error of the matches, nm.
    pub bias_x: Option<f64>,
    /// Mean y error of the matches, nm.
    pub bias_y: Option<f64>,
}

impl SchemeStats {
    /// Detected blinks / blinks.
    pub fn detection_rate(&self) -> f64 {
        if self.blinks == 0 {
            0.0
        } else {
            self.detected as f64 / self.blinks as f64
        }
    }

    /// Detections without a match / detections (0 with no detection).
    pub fn false_pos_rate(&self) -> f64 {
        if self.detections == 0 {
            0.0
        } else {
            self.false_pos as f64 / self.detections as f64
        }
    }
}

/// Everything measured at one point.
#[derive(Debug, Clone, PartialEq)]
pub struct PointStats {
    /// x value.
    pub x: f64,
    /// One entry per scheme of the plan.
    pub schemes: Vec<SchemeStats>,
    /// One entry per ratio of the plan.
    pub ratios: Vec<Estimate>,
    /// Wall seconds spent on this point (all items, all stages).
    pub seconds: f64,
}

/// Totals of one timing stage over the whole study.
#[derive(Debug, Clone, PartialEq)]
pub struct StageTotal {
    /// Stage name.
    pub stage: String,
    /// Units of work.
    pub count: u64,
    /// Seconds.
    pub seconds: f64,
}

/// A whole study's statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// One entry per point.
    pub points: Vec<PointStats>,
    /// Time per stage, summed over items (wall time inside each worker).
    pub stages: Vec<StageTotal>,
}

/// Blinks of a point for every scheme, concatenated over blocks in order.
fn point_blinks(plan: &Plan, items: &[&ItemResult]) -> Vec<Vec<BlinkOutcome>> {
    (0..plan.schemes.len())
        .map(|s| {
            items
                .iter()
                .flat_map(|it| it.outcomes[s].blinks.iter().copied())
                .collect()
        })
        .collect()
}

fn rms(sse: f64, matches: u64) -> Option<f64> {
    (matches > 0).then(|| (sse / matches as f64).sqrt())
}

/// Percentile (linear interpolation between order statistics) of sorted `v`.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let (i, f) = (pos.floor() as usize, pos - pos.floor());
    if i + 1 < sorted.len() {
        sorted[i] + f * (sorted[i + 1] - sorted[i])
    } else {
        sorted[i]
    }
}

fn interval(mut v: Vec<f64>, resamples: usize) -> (Option<f64>, Option<f64>) {
    if v.len() * 2 < resamples || v.is_empty() {
        return (None, None);
    }
    v.sort_by(f64::total_cmp);
    (Some(percentile(&v, 0.025)), Some(percentile(&v, 0.975)))
}

/// The bootstrap resample indices of `n` blinks: `resamples` rows of `n`
/// indices, from the study's seed only.
pub fn resample_indices(seed: u64, n: usize, resamples: usize) -> Vec<Vec<u32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(&[seed, key_hash("bootstrap")]));
    (0..resamples)
        .map(|_| (0..n).map(|_| rng.gen_range(0..n as u32)).collect())
        .collect()
}

/// RMS of a resample of blinks.
fn resampled_rms(b: &[BlinkOutcome], idx: &[u32]) -> Option<f64> {
    let (mut sse, mut m) = (0.0, 0u64);
    for &i in idx {
        let o = &b[i as usize];
        sse += o.sse_nm2;
        m += o.matches as u64;
    }
    rms(sse, m)
}

/// Point estimate and bootstrap interval of the RMS of `blinks`.
pub fn rms_estimate(blinks: &[BlinkOutcome], idx: &[Vec<u32>]) -> Estimate {
    let sse: f64 = blinks.iter().map(|b| b.sse_nm2).sum();
    let m: u64 = blinks.iter().map(|b| b.matches as u64).sum();
    let (lo, hi) = if detected(blinks) >= MIN_DETECTED_FOR_CI {
        let v: Vec<f64> = idx
            .iter()
            .filter_map(|r| resampled_rms(blinks, r))
            .collect();
        interval(v, idx.len())
    } else {
        (None, None)
    };
    Estimate {
        value: rms(sse, m),
        lo,
        hi,
    }
}

/// Point estimate and paired bootstrap interval of `RMS(num) / RMS(den)`
/// (the two must describe the same blinks, index by index).
pub fn ratio_estimate(num: &[BlinkOutcome], den: &[BlinkOutcome], idx: &[Vec<u32>]) -> Estimate {
    let ratio = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => Some(a / b),
        _ => None,
    };
    let all: Vec<u32> = (0..num.len().min(den.len()) as u32).collect();
    let value = ratio(resampled_rms(num, &all), resampled_rms(den, &all));
    let (lo, hi) = if detected(num).min(detected(den)) >= MIN_DETECTED_FOR_CI {
        let v: Vec<f64> = idx
            .iter()
            .filter_map(|r| ratio(resampled_rms(num, r), resampled_rms(den, r)))
            .collect();
        interval(v, idx.len())
    } else {
        (None, None)
    };
    Estimate { value, lo, hi }
}

/// The statistics of a study from its work items (any order; every item
/// of the plan exactly once — the caller checks).
pub fn summarise(plan: &Plan, items: &[ItemResult]) -> Summary {
    let n = plan.options.blinks_per_point as usize;
    let idx = resample_indices(plan.options.seed, n, plan.options.bootstrap as usize);
    let mut sorted: Vec<&ItemResult> = items.iter().collect();
    sorted.sort_by_key(|it| (it.point, it.block));
    let per_point: Vec<Vec<&ItemResult>> = (0..plan.points.len())
        .map(|p| sorted.iter().copied().filter(|it| it.point == p).collect())
        .collect();
    let blinks: Vec<Vec<Vec<BlinkOutcome>>> = per_point
        .iter()
        .map(|its| point_blinks(plan, its))
        .collect();
    let mut points = Vec::with_capacity(plan.points.len());
    for (p, its) in per_point.iter().enumerate() {
        let schemes = (0..plan.schemes.len())
            .map(|s| {
                let b = &blinks[p][s];
                let m: u64 = b.iter().map(|o| o.matches as u64).sum();
                let sdx: f64 = b.iter().map(|o| o.sum_dx_nm).sum();
                let sdy: f64 = b.iter().map(|o| o.sum_dy_nm).sum();
                SchemeStats {
                    blinks: b.len() as u64,
                    detected: b.iter().filter(|o| o.matches > 0).count() as u64,
                    matches: m,
                    detections: its.iter().map(|it| it.outcomes[s].detections as u64).sum(),
                    false_pos: its.iter().map(|it| it.outcomes[s].false_pos as u64).sum(),
                    failed_fits: its.iter().map(|it| it.outcomes[s].failed_fits as u64).sum(),
                    rms: rms_estimate(b, &idx),
                    bias_x: (m > 0).then(|| sdx / m as f64),
                    bias_y: (m > 0).then(|| sdy / m as f64),
                }
            })
            .collect();
        let ratios = plan
            .ratios
            .iter()
            .map(|r| {
                let dp = r.den_point.unwrap_or(p);
                ratio_estimate(&blinks[p][r.num], &blinks[dp][r.den], &idx)
            })
            .collect();
        points.push(PointStats {
            x: plan.points[p],
            schemes,
            ratios,
            seconds: its
                .iter()
                .flat_map(|it| it.timings.iter().map(|t| t.seconds))
                .sum(),
        });
    }
    let mut stages: Vec<StageTotal> = Vec::new();
    for it in &sorted {
        for t in &it.timings {
            match stages.iter_mut().find(|s| s.stage == t.stage) {
                Some(s) => {
                    s.count += t.count;
                    s.seconds += t.seconds;
                }
                None => stages.push(StageTotal {
                    stage: t.stage.clone(),
                    count: t.count,
                    seconds: t.seconds,
                }),
            }
        }
    }
    Summary { points, stages }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::{Distribution, Normal};

    fn blinks_with_error(sd: f64, n: usize, seed: u64) -> Vec<BlinkOutcome> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, sd).unwrap();
        (0..n)
            .map(|_| {
                let (dx, dy) = (d.sample(&mut rng), d.sample(&mut rng));
                BlinkOutcome {
                    matches: 1,
                    sse_nm2: dx * dx + dy * dy,
                    sum_dx_nm: dx,
                    sum_dy_nm: dy,
                }
            })
            .collect()
    }

    #[test]
    fn percentile_interpolates() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&v, 1.0), 5.0);
        assert_eq!(percentile(&v, 0.5), 3.0);
        assert!((percentile(&v, 0.125) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn bootstrap_intervals_cover_the_truth_at_about_95_percent() {
        // Per-axis sd 10 nm: true RMS distance is 10·√2 nm.
        let truth = 10.0 * 2f64.sqrt();
        let idx = resample_indices(1, 200, 400);
        let mut covered = 0;
        let trials = 100;
        for t in 0..trials {
            let b = blinks_with_error(10.0, 200, 1000 + t);
            let e = rms_estimate(&b, &idx);
            let (lo, hi) = (e.lo.unwrap(), e.hi.unwrap());
            assert!(lo < e.value.unwrap() && e.value.unwrap() < hi);
            covered += (lo <= truth && truth <= hi) as u32;
        }
        assert!((88..=99).contains(&covered), "coverage {covered}/{trials}");
    }

    #[test]
    fn paired_ratio_is_tighter_than_the_rmses_and_centred() {
        // The same errors scaled by 2: the ratio is exactly 2 in every resample.
        let a = blinks_with_error(10.0, 300, 5);
        let b: Vec<BlinkOutcome> = a
            .iter()
            .map(|o| BlinkOutcome {
                sse_nm2: 4.0 * o.sse_nm2,
                ..*o
            })
            .collect();
        let idx = resample_indices(2, 300, 200);
        let r = ratio_estimate(&b, &a, &idx);
        assert!((r.value.unwrap() - 2.0).abs() < 1e-12);
        assert!((r.lo.unwrap() - 2.0).abs() < 1e-9 && (r.hi.unwrap() - 2.0).abs() < 1e-9);
        // Independent errors: the interval contains 1 for equal spreads.
        let c = blinks_with_error(10.0, 300, 6);
        let r = ratio_estimate(&a, &c, &idx);
        assert!(r.lo.unwrap() < 1.0 && r.hi.unwrap() > 1.0, "{r:?}");
    }

    #[test]
    fn too_few_detected_blinks_give_no_interval() {
        let mut b = vec![BlinkOutcome::default(); 500];
        b[7] = blinks_with_error(10.0, 1, 9)[0];
        let idx = resample_indices(4, 500, 200);
        let e = rms_estimate(&b, &idx);
        assert!(e.value.is_some());
        assert_eq!((e.lo, e.hi), (None, None));
    }

    #[test]
    fn no_match_gives_no_value_rather_than_nan() {
        let b = vec![BlinkOutcome::default(); 50];
        let idx = resample_indices(3, 50, 100);
        let e = rms_estimate(&b, &idx);
        assert_eq!(e, Estimate::default());
        let r = ratio_estimate(&b, &blinks_with_error(1.0, 50, 1), &idx);
        assert_eq!(r.value, None);
    }
}
