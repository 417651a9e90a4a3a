//! Known structures moved by a known drift: the estimate must follow it.

use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Three-marker rulers (80 nm) at random places in a 3 µm field.
fn rulers(rng: &mut ChaCha8Rng, n: usize) -> Vec<(f64, f64)> {
    let mut v = Vec::new();
    for _ in 0..n {
        let (cx, cy) = (rng.gen_range(200.0..2800.0), rng.gen_range(200.0..2800.0));
        let th: f64 = rng.gen_range(0.0..std::f64::consts::PI);
        for m in -1..=1 {
            v.push((
                cx + m as f64 * 80.0 * th.cos(),
                cy + m as f64 * 80.0 * th.sin(),
            ));
        }
    }
    v
}

/// `n` localisations over `t ∈ [0, 1000)`, each of a random emitter with
/// 10 nm precision, moved by `drift(t)`.
fn localise(
    rng: &mut ChaCha8Rng,
    emitters: &[(f64, f64)],
    n: usize,
    drift: impl Fn(f64) -> (f64, f64),
) -> Vec<DriftPoint> {
    let noise = Normal::new(0.0, 10.0).unwrap();
    (0..n)
        .map(|_| {
            let t = rng.gen_range(0.0..1000.0);
            let e = emitters[rng.gen_range(0..emitters.len())];
            let d = drift(t);
            DriftPoint {
                t,
                x_nm: e.0 + d.0 + noise.sample(rng),
                y_nm: e.1 + d.1 + noise.sample(rng),
            }
        })
        .collect()
}

/// RMS of estimate − truth over the points' times, after removing the mean
/// difference (the estimate is relative to the first segment).
fn residual_rms(est: &DriftEstimate, pts: &[DriftPoint], drift: impl Fn(f64) -> (f64, f64)) -> f64 {
    let diffs: Vec<(f64, f64)> = pts
        .iter()
        .map(|p| {
            let (e, d) = (est.at(p.t), drift(p.t));
            (e.0 - d.0, e.1 - d.1)
        })
        .collect();
    let n = diffs.len() as f64;
    let mx = diffs.iter().map(|d| d.0).sum::<f64>() / n;
    let my = diffs.iter().map(|d| d.1).sum::<f64>() / n;
    (diffs
        .iter()
        .map(|d| (d.0 - mx).powi(2) + (d.1 - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
}

fn curved(t: f64) -> (f64, f64) {
    let u = t / 1000.0;
    (
        80.0 * u + 20.0 * (3.0 * u).sin(),
        -40.0 * u * u + 15.0 * (5.0 * u).sin(),
    )
}

#[test]
fn rcc_follows_a_curved_drift_of_100_nm() {
    let mut rng = ChaCha8Rng::seed_from_u64(37);
    let e = rulers(&mut rng, 30);
    let pts = localise(&mut rng, &e, 20_000, curved);
    let est = rcc(&pts, &DriftOptions::default()).unwrap();
    let rms = residual_rms(&est, &pts, curved);
    // Without correction the points scatter by the drift itself (~30 nm
    // RMS); 10 segments of 2000 localisations at 10 nm give a few nm.
    let uncorrected = residual_rms(
        &DriftEstimate {
            segments: vec![],
            ..est.clone()
        },
        &pts,
        curved,
    );
    assert!(uncorrected > 20.0, "{uncorrected}");
    assert!(
        rms < 4.0,
        "residual drift {rms:.2} nm (uncorrected {uncorrected:.1})"
    );
    assert_eq!(est.segments.len(), 10);
    assert!(
        est.used >= 40 && est.total == 45,
        "{} of {}",
        est.used,
        est.total
    );
    assert_eq!(est.bin_nm, DEFAULT_BIN_NM);
}

#[test]
fn rcc_sign_and_scale_on_a_pure_shift() {
    // Half the points at t < 500 unshifted, half shifted by (+60, −35) nm.
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let e = rulers(&mut rng, 20);
    let step = |t: f64| if t < 500.0 { (0.0, 0.0) } else { (60.0, -35.0) };
    let pts = localise(&mut rng, &e, 6000, step);
    let opts = DriftOptions {
        segments: 2,
        ..DriftOptions::default()
    };
    // (Fiducials follow a spot only by steps within their radius, 40 nm.)
    let est = rcc(&pts, &opts).unwrap();
    let s = &est.segments[1];
    assert!(
        (s.dx_nm - 60.0).abs() < 3.0 && (s.dy_nm + 35.0).abs() < 3.0,
        "{s:?}"
    );
    assert_eq!((est.segments[0].dx_nm, est.segments[0].dy_nm), (0.0, 0.0));
}

#[test]
fn fiducials_follow_persistent_spots() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // Isolated beads, each localised many times per segment.
    let beads: Vec<(f64, f64)> = (0..6)
        .map(|i| (400.0 + 400.0 * i as f64, 300.0 + 350.0 * (i % 3) as f64))
        .collect();
    let pts = localise(&mut rng, &beads, 3000, curved);
    let est = fiducials(&pts, &DriftOptions::default()).unwrap();
    assert_eq!(est.used, 6, "{est:?}");
    let rms = residual_rms(&est, &pts, curved);
    assert!(rms < 3.0, "{rms}");
    // A random scatter has no fiducial.
    let scatter: Vec<DriftPoint> = (0..3000)
        .map(|i| DriftPoint {
            t: i as f64,
            x_nm: rng.gen_range(0.0..20_000.0),
            y_nm: rng.gen_range(0.0..20_000.0),
        })
        .collect();
    let e = fiducials(&scatter, &DriftOptions::default()).unwrap_err();
    assert!(matches!(e, DriftError::NoFiducial { .. }), "{e}");
    assert!(e.to_string().contains("no fiducial"));
}

#[test]
fn degenerate_inputs_are_clear_errors() {
    let o = DriftOptions::default();
    for f in [rcc, fiducials] {
        assert!(matches!(
            f(&[], &o),
            Err(DriftError::TooFew { found: 0, .. })
        ));
        let one = [DriftPoint {
            t: 1.0,
            x_nm: 5.0,
            y_nm: 5.0,
        }];
        assert!(matches!(f(&one, &o), Err(DriftError::TooFew { .. })));
        // Enough points, all at one time.
        let same: Vec<DriftPoint> = (0..500)
            .map(|i| DriftPoint {
                t: 3.0,
                x_nm: i as f64,
                y_nm: 0.0,
            })
            .collect();
        assert_eq!(f(&same, &o), Err(DriftError::NoTimeSpan { t: 3.0 }));
        // All but a few in the first segment.
        let mut lopsided = same.clone();
        lopsided.push(DriftPoint {
            t: 100.0,
            ..same[0]
        });
        let e = f(&lopsided, &o).unwrap_err();
        assert!(
            matches!(
                e,
                DriftError::SparseSegment {
                    segment: 2,
                    found: 0,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("fewer (longer) segments"));
        // Non-finite points are left out, not propagated.
        let nan: Vec<DriftPoint> = (0..500)
            .map(|i| DriftPoint {
                t: i as f64,
                x_nm: f64::NAN,
                y_nm: 0.0,
            })
            .collect();
        assert!(matches!(
            f(&nan, &o),
            Err(DriftError::TooFew { found: 0, .. })
        ));
    }
    for bad in [
        DriftOptions {
            segments: 1,
            ..o.clone()
        },
        DriftOptions {
            segments: 100_000,
            ..o.clone()
        },
        DriftOptions {
            bin_nm: Some(0.0),
            ..o.clone()
        },
        DriftOptions {
            bin_nm: Some(f64::NAN),
            ..o.clone()
        },
        DriftOptions {
            max_drift_nm: -1.0,
            ..o.clone()
        },
        DriftOptions {
            reject_nm: f64::INFINITY,
            ..o.clone()
        },
        DriftOptions {
            fiducial_min: 0,
            ..o.clone()
        },
    ] {
        assert!(
            matches!(bad.validate(), Err(DriftError::Option { .. })),
            "{bad:?}"
        );
    }
}

#[test]
fn huge_fields_coarsen_the_bin_or_are_refused() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    // Two clusters 1 mm apart: the automatic bin grows, a fine one is refused.
    let pts: Vec<DriftPoint> = (0..400)
        .map(|i| DriftPoint {
            t: i as f64,
            x_nm: if i % 2 == 0 { 0.0 } else { 1e6 } + rng.gen_range(0.0..50.0),
            y_nm: rng.gen_range(0.0..50.0),
        })
        .collect();
    let o = DriftOptions::default();
    let est = rcc(&pts, &o).unwrap();
    assert!(est.bin_nm > DEFAULT_BIN_NM, "{}", est.bin_nm);
    let fine = DriftOptions {
        bin_nm: Some(10.0),
        ..o
    };
    assert!(matches!(
        rcc(&pts, &fine),
        Err(DriftError::ImageTooLarge { .. })
    ));
}

#[test]
fn interpolation_is_linear_between_segments_and_beyond() {
    let seg = |t: f64, d: f64| SegmentDrift {
        t_start: 0.0,
        t_end: 0.0,
        t_mean: t,
        count: 1,
        dx_nm: d,
        dy_nm: -d,
    };
    let est = DriftEstimate {
        segments: vec![seg(10.0, 0.0), seg(20.0, 10.0), seg(30.0, 30.0)],
        bin_nm: 15.0,
        used: 3,
        total: 3,
        residual_rms_nm: 0.0,
    };
    assert_eq!(est.at(15.0), (5.0, -5.0));
    assert_eq!(est.at(25.0), (20.0, -20.0));
    assert_eq!(est.at(5.0), (-5.0, 5.0));
    assert_eq!(est.at(35.0), (40.0, -40.0));
}
