//! Estimator accuracy on simulated ROIs with fixed seeds: RMSE against the
//! Cramér–Rao bound of the model fitted, and the bound against Mortensen's
//! closed form. (The 5 % figures are measured by `smartagg bench localize`
//! on more ROIs; here 10 % keeps the tests fast and robust.)

use smartagg_localize::bench::{score_frames, simulate_frames, FrameScenario};
use smartagg_localize::crlb::{
    crlb_frame, mortensen_lsq_variance, mortensen_mle_variance, Emitter,
};
use smartagg_localize::{Estimator, FitOptions, NoiseModel, SigmaMode};

fn fixed() -> FitOptions {
    FitOptions::new(SigmaMode::Fixed(1.5))
}

fn fitted() -> FitOptions {
    FitOptions::new(SigmaMode::Fitted { initial: 1.3 })
}

#[test]
fn mle_reaches_the_bound_at_230_photons() {
    let set = simulate_frames(&FrameScenario::spcimager_blink(3000, 7));
    for opts in [fixed(), fitted()] {
        let s = score_frames(&set, Estimator::Mle, &opts);
        assert!(
            s.ratio() < 1.10 && s.ratio() > 0.93,
            "{opts:?}: RMSE/CRLB = {}",
            s.ratio()
        );
        // The reported uncertainty describes the actual error.
        assert!(
            (s.reported_over_rmse - 1.0).abs() < 0.1,
            "{}",
            s.reported_over_rmse
        );
        assert!(s.failures <= 3, "{} failures", s.failures);
        assert!(s.bias_x.abs() < 0.02 && s.bias_y.abs() < 0.02);
    }
}

#[test]
fn mle_reaches_the_bound_at_1000_photons_and_beats_lsq_and_centroid() {
    let mut sc = FrameScenario::spcimager_blink(3000, 8);
    sc.photons = 1000.0;
    let set = simulate_frames(&sc);
    let mle = score_frames(&set, Estimator::Mle, &fitted());
    assert!(mle.ratio() < 1.10, "{}", mle.ratio());
    assert_eq!(mle.failures, 0);
    // Least squares ignores the Poisson weights: measurably less precise.
    let lsq = score_frames(&set, Estimator::Lsq, &fitted());
    assert!(
        lsq.rmse > 1.05 * mle.rmse,
        "lsq {} mle {}",
        lsq.rmse,
        mle.rmse
    );
    // The LSQ sandwich uncertainty describes the LSQ error.
    assert!(
        (lsq.reported_over_rmse - 1.0).abs() < 0.1,
        "{}",
        lsq.reported_over_rmse
    );
    let cen = score_frames(&set, Estimator::Centroid, &fixed());
    assert!(
        cen.rmse > mle.rmse,
        "centroid {} mle {}",
        cen.rmse,
        mle.rmse
    );
}

#[test]
fn emccd_and_scmos_noise_models() {
    let mut sc = FrameScenario::spcimager_blink(2000, 9);
    sc.photons = 500.0;
    sc.background = 3.0;
    sc.noise = NoiseModel::Emccd;
    let set = simulate_frames(&sc);
    let mut o = fixed();
    o.noise = NoiseModel::Emccd;
    let s = score_frames(&set, Estimator::Mle, &o);
    assert!(
        s.ratio() < 1.10 && s.ratio() > 0.9,
        "EMCCD RMSE/CRLB {}",
        s.ratio()
    );
    // The EMCCD bound is √2 × the Poisson one.
    let em = set.truth[0];
    let p = crlb_frame(9, &em, None, NoiseModel::Poisson, false).unwrap();
    let e = crlb_frame(9, &em, None, NoiseModel::Emccd, false).unwrap();
    assert!((e.uncertainty() / p.uncertainty() - 2f64.sqrt()).abs() < 1e-9);

    sc.noise = NoiseModel::Scmos;
    sc.read_var = 4.0;
    let set = simulate_frames(&sc);
    o.noise = NoiseModel::Scmos;
    let s = score_frames(&set, Estimator::Mle, &o);
    assert!(
        s.ratio() < 1.10 && s.ratio() > 0.9,
        "sCMOS RMSE/CRLB {}",
        s.ratio()
    );
    assert!(
        (s.reported_over_rmse - 1.0).abs() < 0.12,
        "{}",
        s.reported_over_rmse
    );
}

#[test]
fn crlb_agrees_with_mortensen_in_a_large_roi() {
    // Large ROI (no truncation), σ fixed: Mortensen's σa² = σ² + a²/12 closed
    // form is the asymptotic MLE variance; it should match the bound.
    for (n, b) in [(1000.0, 1.0), (300.0, 2.0), (5000.0, 10.0)] {
        let em = Emitter {
            x: 12.5,
            y: 12.5,
            sigma: 1.5,
            photons: n,
            background: b,
        };
        let c = crlb_frame(25, &em, None, NoiseModel::Poisson, false).unwrap();
        let m = mortensen_mle_variance(1.5, 1.0, n, b, 1.0);
        assert!(
            (c.var_x / m - 1.0).abs() < 0.01,
            "N={n} b={b}: {} vs {m}",
            c.var_x
        );
        // Least squares is less precise than maximum likelihood (16/9 of the
        // variance without background).
        assert!(mortensen_lsq_variance(1.5, 1.0, n, b, 1.0) > 1.2 * m);
    }
    // In a 9×9 ROI the truncation costs information: the bound is larger.
    let em = Emitter {
        x: 4.5,
        y: 4.5,
        sigma: 1.5,
        photons: 230.0,
        background: 5.9,
    };
    let c = crlb_frame(9, &em, None, NoiseModel::Poisson, false).unwrap();
    assert!(c.var_x > mortensen_mle_variance(1.5, 1.0, 230.0, 5.9, 1.0));
    let m0 = mortensen_mle_variance(1.5, 1.0, 1000.0, 0.0, 1.0);
    assert!((mortensen_lsq_variance(1.5, 1.0, 1000.0, 0.0, 1.0) / m0 - 16.0 / 9.0).abs() < 1e-12);
}
