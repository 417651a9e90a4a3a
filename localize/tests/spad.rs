//! SPAD binomial maximum likelihood: unbiased under pile-up where the
//! Poisson MLE is not; at the binomial bound; hot pixels better ignored than
//! interpolated (paper §4, Fig. 8).

use rand::SeedableRng;
use smartagg_localize::bench::{
    score_hot_pixels, score_spad, score_spad_hot_pixels, simulate_spad, FrameScenario, SpadScenario,
};
use smartagg_localize::spad::{fit_binomial, SpadEmitter, SpadRoi};
use smartagg_localize::{
    lm, synth, Estimator, FitOptions, HotPixelMode, PixelMaps, RoiView, SigmaMode,
};

/// Strong pile-up: S = 10 detections per on-plane put ~0.5 detections per
/// plane on the centre pixel (λ ≈ 0.69).
fn piled_up(offset: (f64, f64), seed: u64) -> SpadScenario {
    SpadScenario {
        side: 9,
        sigma: 1.5,
        signal_per_plane: 10.0,
        background_per_plane: 0.0118,
        n_on: 200,
        n_off: 108,
        offset,
        jitter: 0.0,
        count: 1500,
        seed,
    }
}

#[test]
fn pile_up_biases_poisson_but_not_binomial() {
    let set = simulate_spad(&piled_up((0.0, 0.0), 21));
    let fitted = FitOptions::new(SigmaMode::Fitted { initial: 1.3 });
    let fixed = FitOptions::new(SigmaMode::Fixed(1.5));
    let poisson = score_spad(&set, Estimator::Mle, &fitted);
    let binomial = score_spad(&set, Estimator::SpadMle, &fitted);
    // Poisson: photons low, σ high (flattened peak).
    assert!(
        poisson.photon_bias < -0.10,
        "Poisson photon bias {}",
        poisson.photon_bias
    );
    assert!(
        poisson.sigma_bias > 0.05,
        "Poisson σ bias {}",
        poisson.sigma_bias
    );
    // Binomial: unbiased.
    assert!(
        binomial.photon_bias.abs() < 0.02,
        "binomial photon bias {}",
        binomial.photon_bias
    );
    assert!(
        binomial.sigma_bias.abs() < 0.01,
        "binomial σ bias {}",
        binomial.sigma_bias
    );
    assert!(
        binomial.ratio() < 1.10 && binomial.ratio() > 0.9,
        "RMSE/CRLB {}",
        binomial.ratio()
    );
    assert_eq!(binomial.failures, 0);
    let poisson = score_spad(&set, Estimator::Mle, &fixed);
    let binomial = score_spad(&set, Estimator::SpadMle, &fixed);
    assert!(poisson.photon_bias < -0.15, "{}", poisson.photon_bias);
    assert!(
        binomial.photon_bias.abs() < 0.02,
        "{}",
        binomial.photon_bias
    );
}

#[test]
fn asymmetric_pile_up_biases_the_poisson_position() {
    // A PRNU gradient across the ROI makes pile-up asymmetric: the brighter
    // side saturates more. Both fits know the gain map; only the binomial
    // model knows saturation.
    let side = 9;
    let mut maps = PixelMaps::uniform(side);
    for j in 0..side {
        for i in 0..side {
            maps.gain[j * side + i] = 0.6 + 0.8 * i as f64 / 8.0;
        }
    }
    let em = SpadEmitter {
        x: 4.5,
        y: 4.5,
        sigma: 1.5,
        signal_per_plane: 10.0,
        background_per_plane: 0.0118,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let opts = FitOptions::new(SigmaMode::Fitted { initial: 1.3 });
    let (mut bp, mut bb) = (0.0, 0.0);
    let n = 1500;
    for _ in 0..n {
        let c = synth::spad_roi(&mut rng, side, &em, 200, 108, Some(&maps));
        let f: Vec<f64> = c.iter().map(|&v| v as f64).collect();
        let p = lm::fit_mle(&RoiView::new(side, &f, Some(&maps)).unwrap(), &opts);
        let b = fit_binomial(
            &SpadRoi::new(side, &c, 200, 108, Some(&maps)).unwrap(),
            &opts,
        );
        assert!(p.status.is_ok() && b.status.is_ok());
        bp += p.x - em.x;
        bb += b.x - em.x;
    }
    let (bp, bb) = (bp / n as f64, bb / n as f64);
    // Standard error of the mean ≈ 0.041/√1500 ≈ 0.001 px.
    assert!(bp < -0.015, "Poisson x bias {bp}");
    assert!(bb.abs() < 0.005, "binomial x bias {bb}");
}

#[test]
fn binomial_reaches_its_bound_without_pile_up() {
    // A 50 ms SPCImager blink: 500 on-planes, 0.45 detections per plane.
    let sc = SpadScenario {
        side: 9,
        sigma: 1.5,
        signal_per_plane: 0.45,
        background_per_plane: 0.0118,
        n_on: 500,
        n_off: 108,
        offset: (0.0, 0.0),
        jitter: 0.5,
        count: 2000,
        seed: 4,
    };
    let set = simulate_spad(&sc);
    let s = score_spad(
        &set,
        Estimator::SpadMle,
        &FitOptions::new(SigmaMode::Fixed(1.5)),
    );
    assert!(s.ratio() < 1.10 && s.ratio() > 0.9, "{}", s.ratio());
    assert!(
        (s.reported_over_rmse - 1.0).abs() < 0.1,
        "{}",
        s.reported_over_rmse
    );
}

#[test]
fn ignoring_hot_pixels_beats_interpolating_them() {
    let o = FitOptions::new(SigmaMode::Fixed(1.5));
    // Poisson MLE on aggregated blinks, 20 % hot pixels.
    let sc = FrameScenario::spcimager_blink(2000, 2);
    let ignore = score_hot_pixels(&sc, 0.2, HotPixelMode::Ignore, &o);
    let interp = score_hot_pixels(&sc, 0.2, HotPixelMode::Interpolate, &o);
    assert!(
        ignore.rmse < interp.rmse,
        "ignore {} interpolate {}",
        ignore.rmse,
        interp.rmse
    );
    // SPAD binomial MLE, same comparison.
    let sc = SpadScenario {
        side: 9,
        sigma: 1.5,
        signal_per_plane: 0.45,
        background_per_plane: 0.0118,
        n_on: 500,
        n_off: 108,
        offset: (0.0, 0.0),
        jitter: 0.5,
        count: 2000,
        seed: 1,
    };
    let set = simulate_spad(&sc);
    let ignore = score_spad_hot_pixels(&set, 0.2, HotPixelMode::Ignore, &o);
    let interp = score_spad_hot_pixels(&set, 0.2, HotPixelMode::Interpolate, &o);
    assert!(
        ignore.rmse < interp.rmse,
        "ignore {} interpolate {}",
        ignore.rmse,
        interp.rmse
    );
    assert_eq!(ignore.failures + interp.failures, 0);
}
