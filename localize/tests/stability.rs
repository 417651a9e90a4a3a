//! Numerical stability: zero-photon, saturated, edge, hot-pixel-only and
//! non-finite ROIs, tiny and huge σ — no panic, no NaN in the table, every
//! failure flagged and counted.

use rand::SeedableRng;
use smartagg_localize::crlb::Emitter;
use smartagg_localize::spad::{fit_binomial, SpadRoi};
use smartagg_localize::table::{CsvTable, LocTable, Localization};
use smartagg_localize::{
    fit_roi, synth, Estimator, Fit, FitOptions, FitStatus, PixelMaps, RoiView, SigmaMode,
};

const SIDE: usize = 9;

fn all_options() -> Vec<FitOptions> {
    vec![
        FitOptions::new(SigmaMode::Fixed(1.5)),
        FitOptions::new(SigmaMode::Fitted { initial: 1.3 }),
    ]
}

/// Every frame estimator and the SPAD fit (counts rounded) on one ROI.
fn fit_all(data: &[f64], maps: Option<&PixelMaps>, planes: u32) -> Vec<(String, Fit)> {
    let mut out = Vec::new();
    for opts in all_options() {
        for est in [Estimator::Centroid, Estimator::Lsq, Estimator::Mle] {
            let v = RoiView {
                side: SIDE,
                data,
                maps,
            };
            out.push((format!("{est:?} {:?}", opts.sigma), fit_roi(est, &v, &opts)));
        }
        let counts: Vec<u32> = data
            .iter()
            .map(|&v| {
                if v.is_finite() {
                    v.max(0.0).round() as u32
                } else {
                    0
                }
            })
            .collect();
        let r = SpadRoi {
            side: SIDE,
            counts: &counts,
            n_on: planes / 2,
            n_off: planes - planes / 2,
            maps,
        };
        out.push((format!("SpadMle {:?}", opts.sigma), fit_binomial(&r, &opts)));
    }
    out
}

fn assert_finite(label: &str, f: &Fit) {
    for (name, v) in [
        ("x", f.x),
        ("y", f.y),
        ("sigma", f.sigma),
        ("photons", f.photons),
        ("background", f.background),
        ("bkgstd", f.bkgstd),
        ("std_x", f.std_x),
        ("std_y", f.std_y),
        ("std_photons", f.std_photons),
    ] {
        assert!(v.is_finite(), "{label}: {name} = {v}");
    }
}

fn table_round_trip(fits: &[(String, Fit)]) {
    let rows: Vec<Localization> = fits
        .iter()
        .enumerate()
        .map(|(i, (_, f))| Localization::from_fit(f, 10.0, 20.0, 53.3, i as u64 + 1))
        .collect();
    let t = LocTable {
        extra_columns: vec![],
        merged: false,
        rows,
    };
    let mut buf = Vec::new();
    t.write_csv(&mut buf).unwrap();
    let text = String::from_utf8(buf.clone()).unwrap();
    assert!(
        !text.to_lowercase().contains("nan") && !text.contains("inf"),
        "{text}"
    );
    let back = CsvTable::read(&buf[..]).unwrap();
    assert_eq!(back.rows.len(), fits.len());
    let st = back.column(&["fit_status"]).unwrap();
    let failed = back.rows.iter().filter(|r| r[st] != 0.0).count();
    assert_eq!(failed, t.failures());
    for (r, (_, f)) in back.rows.iter().zip(fits) {
        assert!(r.iter().all(|v| v.is_finite()));
        assert_eq!(r[st] as u8, f.status.code());
    }
}

#[test]
fn zero_photon_roi() {
    let data = vec![0.0; SIDE * SIDE];
    let fits = fit_all(&data, None, 100);
    for (l, f) in &fits {
        assert_finite(l, f);
        assert_eq!(f.status, FitStatus::NoSignal, "{l}");
    }
    table_round_trip(&fits);
}

#[test]
fn saturated_spad_roi() {
    // Every bit 1 in every plane.
    let planes = 300;
    let data = vec![planes as f64; SIDE * SIDE];
    let fits = fit_all(&data, None, planes);
    for (l, f) in &fits {
        assert_finite(l, f);
        assert!(
            !f.status.is_ok(),
            "{l}: a flat saturated ROI cannot be localised"
        );
        if l.starts_with("SpadMle") {
            assert_eq!(f.status, FitStatus::Saturated, "{l}");
        }
    }
    // A count above the planes summed is impossible: flagged, not fitted.
    let mut counts = vec![3u32; SIDE * SIDE];
    counts[40] = 301;
    let r = SpadRoi::new(SIDE, &counts, 150, 150, None).unwrap();
    let f = fit_binomial(&r, &all_options()[0]);
    assert_eq!(f.status, FitStatus::InconsistentCounts);
    table_round_trip(&fits);
}

#[test]
fn emitter_on_the_roi_edge() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let em = Emitter {
        x: 0.0,
        y: 4.5,
        sigma: 1.5,
        photons: 1000.0,
        background: 5.9,
    };
    let opts = FitOptions::new(SigmaMode::Fixed(1.5));
    let (mut ok, mut sum, mut sq) = (0, 0.0, 0.0);
    let n = 300;
    for _ in 0..n {
        let data = synth::poisson_roi(&mut rng, SIDE, &em, None);
        let v = RoiView::new(SIDE, &data, None).unwrap();
        let f = fit_roi(Estimator::Mle, &v, &opts);
        assert_finite("edge", &f);
        if f.status.is_ok() {
            ok += 1;
            sum += f.x - em.x;
            sq += (f.x - em.x).powi(2);
        }
        for (l, g) in fit_all(&data, None, 1000) {
            assert_finite(&l, &g);
        }
    }
    assert!(ok >= n * 95 / 100, "{ok} of {n} ok");
    let bias = sum / ok as f64;
    let rmse = (sq / ok as f64).sqrt();
    let crlb = smartagg_localize::crlb::crlb_frame(SIDE, &em, None, Default::default(), false)
        .unwrap()
        .var_x
        .sqrt();
    assert!(bias.abs() < 0.05, "bias {bias}");
    assert!(rmse < 1.3 * crlb, "rmse {rmse} crlb {crlb}");
}

#[test]
fn hot_pixel_only_roi() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let em = Emitter {
        x: 4.5,
        y: 4.5,
        sigma: 1.5,
        photons: 0.0,
        background: 5.9,
    };
    let mut data = synth::poisson_roi(&mut rng, SIDE, &em, None);
    data[3 * SIDE + 6] = 5000.0;
    let fits = fit_all(&data, None, 6000);
    for (l, f) in &fits {
        assert_finite(l, f);
    }
    // With σ fitted, a single bright pixel drives σ to its lower bound: flagged.
    let mle = fit_roi(
        Estimator::Mle,
        &RoiView::new(SIDE, &data, None).unwrap(),
        &FitOptions::new(SigmaMode::Fitted { initial: 1.3 }),
    );
    assert_eq!(mle.status, FitStatus::SigmaAtBound);
    // Ignoring it leaves a background-only ROI.
    let mut maps = PixelMaps::uniform(SIDE);
    maps.ignore[3 * SIDE + 6] = true;
    let fits = fit_all(&data, Some(&maps), 6000);
    for (l, f) in &fits {
        assert_finite(l, f);
        assert!(
            f.photons < 200.0,
            "{l}: {} photons from background alone",
            f.photons
        );
    }
    table_round_trip(&fits);
}

#[test]
fn tiny_and_huge_sigma() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for true_sigma in [0.05, 0.2, 20.0, 1e3] {
        let em = Emitter {
            x: 4.3,
            y: 4.6,
            sigma: true_sigma,
            photons: 2000.0,
            background: 2.0,
        };
        let data = synth::poisson_roi(&mut rng, SIDE, &em, None);
        let fits = fit_all(&data, None, 5000);
        for (l, f) in &fits {
            assert_finite(&format!("σ={true_sigma} {l}"), f);
        }
        let fitted = fit_roi(
            Estimator::Mle,
            &RoiView::new(SIDE, &data, None).unwrap(),
            &FitOptions::new(SigmaMode::Fitted { initial: 1.3 }),
        );
        if true_sigma < 0.25 {
            // Narrower than the σ bound: flagged, not silently accepted.
            assert_eq!(
                fitted.status,
                FitStatus::SigmaAtBound,
                "σ={true_sigma}: {fitted:?}"
            );
            assert!((fitted.x - em.x).abs() < 0.5);
        }
        table_round_trip(&fits);
    }
    // Extreme options on ordinary data: rejected up front or fitted finitely.
    let em = Emitter {
        x: 4.5,
        y: 4.5,
        sigma: 1.5,
        photons: 500.0,
        background: 2.0,
    };
    let data = synth::poisson_roi(&mut rng, SIDE, &em, None);
    for s in [0.05, 1000.0] {
        for mode in [SigmaMode::Fixed(s), SigmaMode::Fitted { initial: s }] {
            let o = FitOptions::new(mode);
            assert!(o.validate().is_ok());
            for est in [Estimator::Centroid, Estimator::Lsq, Estimator::Mle] {
                let f = fit_roi(est, &RoiView::new(SIDE, &data, None).unwrap(), &o);
                assert_finite(&format!("{est:?} {mode:?}"), &f);
            }
        }
    }
    assert!(FitOptions::new(SigmaMode::Fixed(0.0)).validate().is_err());
    assert!(FitOptions::new(SigmaMode::Fixed(f64::NAN))
        .validate()
        .is_err());
}

#[test]
fn non_finite_input() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(6);
    let em = Emitter {
        x: 4.5,
        y: 4.5,
        sigma: 1.5,
        photons: 500.0,
        background: 2.0,
    };
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut data = synth::poisson_roi(&mut rng, SIDE, &em, None);
        data[10] = bad;
        for opts in all_options() {
            for est in [Estimator::Centroid, Estimator::Lsq, Estimator::Mle] {
                let f = fit_roi(est, &RoiView::new(SIDE, &data, None).unwrap(), &opts);
                assert_finite("non-finite", &f);
                assert_eq!(f.status, FitStatus::NonFiniteInput, "{est:?}");
            }
        }
        // The same pixel ignored: an ordinary fit.
        let mut maps = PixelMaps::uniform(SIDE);
        maps.ignore[10] = true;
        let f = fit_roi(
            Estimator::Mle,
            &RoiView::new(SIDE, &data, Some(&maps)).unwrap(),
            &all_options()[0],
        );
        assert_eq!(f.status, FitStatus::Ok);
        assert!((f.x - 4.5).abs() < 1.0);
    }
}
