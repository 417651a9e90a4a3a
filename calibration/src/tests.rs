//! Calibration against the scene simulator's known maps, the estimators at
//! their extremes, the hot criterion against T, and the file format.

use super::counter::PlaneCounts;
use super::frames::{calibrate_frames, FrameOptions, FrameSource};
use super::spad::{calibrate_spad, Counted, CriterionSpec, SpadOptions};
use super::*;
use rand::{Rng, SeedableRng};
use smartagg_model::params::{spcimager, Camera, Preset, PresetName, SceneLight, SpadCamera};
use smartagg_model::sensor_maps::SensorMaps;
use smartagg_model::stats::{derive, DetectionInputs};
use smartagg_scene::{
    Blinking, EmccdSimulator, Layout, OnTime, Scene, ScmosSimulator, SpadSimulator,
};

const W: u32 = 16;

/// An empty field (no molecules) of `side` pixels with the given background light.
fn empty_scene(preset: &Preset, side: u32, background_per_um2_hz: f64) -> Scene {
    Scene {
        width: side,
        height: side,
        optics: preset.optics,
        light: SceneLight {
            flux_hz: 0.0,
            background_per_um2_hz,
        },
        layout: Layout::List(vec![]),
        blinking: Blinking::Independent {
            on: OnTime::Fixed { seconds: 0.01 },
            mean_off_s: 1.0,
        },
        intensity_cv: 0.0,
        margin_px: 0.0,
    }
}

fn spcimager_preset() -> Preset {
    Preset::new(PresetName::Spcimager, 150).unwrap()
}

/// The preset's criterion inputs (N = 109, T_int = 124633, 9-tap kernel).
fn preset_spec() -> CriterionSpec {
    let p = spcimager_preset();
    let det = derive(&DetectionInputs::from_preset(&p, None).unwrap()).unwrap();
    CriterionSpec {
        n_window: det.n_window,
        threshold_int: det.threshold_int,
        kernel: det.kernel(),
        background_light_hz: det.background_rate_hz - spcimager().dcr_median_hz,
        source: "test: spcimager 150x".into(),
    }
}

/// Counts `planes` simulated planes of `maps` under `background` light.
fn simulate(
    cam: &SpadCamera,
    maps: &SensorMaps,
    background: f64,
    planes: u64,
    seed: u64,
) -> Counted {
    let p = spcimager_preset();
    let scene = empty_scene(&p, maps.width, background);
    let mut sim = SpadSimulator::with_maps(cam, &scene, maps.clone(), seed).unwrap();
    let mut c = PlaneCounter::new(maps.width, maps.height);
    let mut words = vec![0u64; (maps.width * maps.height).div_ceil(64) as usize];
    for _ in 0..planes {
        sim.next_plane_words(&mut words);
        c.push_words(&words);
    }
    Counted {
        counts: c.finish(),
        tau_s: cam.exposure_s,
        plane_period_s: cam.plane_period_s,
    }
}

fn prov() -> Provenance {
    Provenance {
        dark: "dark (simulated)".into(),
        flat: Some("flat (simulated)".into()),
        created_by: "test".into(),
        ..Default::default()
    }
}

/// Fraction of |z| < 3, χ²/k and max |z| of `(est − truth)/sd` over `pixels`.
fn z_stats(est: &[f64], truth: &[f64], sd: &[f64], pixels: &[usize]) -> (f64, f64, f64) {
    let z: Vec<f64> = pixels
        .iter()
        .map(|&i| (est[i] - truth[i]) / sd[i])
        .collect();
    let within = z.iter().filter(|z| z.abs() < 3.0).count() as f64 / z.len() as f64;
    let chi2 = z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64;
    let max = z.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    (within, chi2, max)
}

/// The stated uncertainties are right: at most as many |z| ≥ 3 as a normal
/// z gives with probability 1 − 10⁻³ (P(|z| ≥ 3) = 0.27 %; for 256 pixels at
/// most 4, i.e. ≥ 98.4 % within 3 sd; for k ≥ 2000 this is ≥ 99 %), χ²/k
/// within 5 standard errors of 1, and no |z| ≥ 5.
fn assert_calibrated(name: &str, est: &[f64], truth: &[f64], sd: &[f64], pixels: &[usize]) {
    let (within, chi2, max) = z_stats(est, truth, sd, pixels);
    let k = pixels.len();
    eprintln!(
        "{name}: {:.2} % within 3 sd, chi2/k {chi2:.3}, max |z| {max:.2} ({k} pixels)",
        100.0 * within
    );
    let lambda = 0.0027 * k as f64;
    // Smallest m with P(Poisson(λ) > m) < 1e-3.
    let (mut m, mut term, mut cdf) = (0usize, (-lambda).exp(), (-lambda).exp());
    while 1.0 - cdf >= 1e-3 {
        m += 1;
        term *= lambda / m as f64;
        cdf += term;
    }
    let outside = ((1.0 - within) * k as f64).round() as usize;
    assert!(
        outside <= m,
        "{name}: {outside} pixels beyond 3 sd, at most {m} expected"
    );
    assert!(chi2 < chi2_limit(k), "{name}: chi2/k {chi2}");
    assert!(max < 5.0, "{name}: max |z| {max}");
}

fn chi2_limit(k: usize) -> f64 {
    1.0 + 5.0 * (2.0 / k as f64).sqrt()
}

/// SPCImager with 30 % DRNU, 5 % hot pixels at 5 kHz, 5 % PRNU; pixel 0 is
/// stuck at 1 (DCR 10⁹ Hz) and pixel 1 is dead (η = 0, DCR = 0).
fn test_camera_and_maps(seed: u64) -> (SpadCamera, SensorMaps) {
    let cam = SpadCamera {
        drnu: 0.3,
        prnu: 0.05,
        hot_pixel_fraction: 0.05,
        hot_pixel_dcr_hz: 5000.0,
        ..spcimager()
    };
    let mut maps = smartagg_scene::generate_maps(&cam, W, W, seed);
    maps.dcr_hz[0] = 1e9;
    maps.hot[0] = true;
    maps.dcr_hz[1] = 0.0;
    maps.prnu.as_mut().expect("generated maps have a PRNU map")[1] = 0.0;
    maps.hot[1] = false;
    (cam, maps)
}

#[test]
fn dark_map_hot_set_and_extremes_match_the_simulators_truth() {
    let (cam, maps) = test_camera_and_maps(11);
    let n = 300_000;
    let dark = simulate(&cam, &maps, 0.0, n, 12);
    let spec = preset_spec();
    let cal = calibrate_spad(&dark, None, &spec, &SpadOptions::default(), prov()).unwrap();
    let normal: Vec<usize> = (2..(W * W) as usize).collect();

    // Every regular pixel within its stated uncertainty.
    assert_calibrated("DCR", &cal.dcr_hz, &maps.dcr_hz, &cal.dcr_sd_hz, &normal);

    // Hot set: exactly the simulator's hot pixels (5 kHz against a critical
    // DCR of about 1 kHz, regular pixels near 100 Hz).
    let crit = cal.hot_criterion.dcr_critical_hz.unwrap();
    assert!((900.0..1100.0).contains(&crit), "{crit}");
    for i in 0..(W * W) as usize {
        assert_eq!(
            cal.flags[i] & flags::HOT != 0,
            maps.hot[i],
            "pixel {i}: DCR {} (truth {})",
            cal.dcr_hz[i],
            maps.dcr_hz[i]
        );
    }
    assert_eq!(cal.dark.hot_pixels, maps.hot_pixels());
    assert_eq!(cal.hot_mask().count(), maps.hot_pixels());
    assert!(cal.hot_mask().is_masked(0, 0));

    // The stuck pixel: finite lower estimate, flagged.
    assert_eq!(cal.flags[0], flags::HOT | flags::SATURATED);
    assert!((cal.dcr_hz[0] - (2.0 * n as f64).ln() / cam.exposure_s).abs() < 1e-6);
    assert!(cal.dcr_sd_hz[0].is_finite() && cal.dcr_sd_hz[0] > 0.0);
    // The dark pixel: rate 0, finite uncertainty, not hot, not called dead without a flat.
    assert_eq!(cal.flags[1], flags::NO_COUNTS);
    assert_eq!(cal.dcr_hz[1], 0.0);
    assert!(cal.dcr_sd_hz[1].is_finite() && cal.dcr_sd_hz[1] > 0.0);
    assert_eq!(
        (cal.dark.saturated_pixels, cal.dark.no_count_pixels),
        (1, 1)
    );

    // Median and DRNU against the same estimators on the true map.
    let true_normal: Vec<f64> = normal
        .iter()
        .filter(|&&i| !maps.hot[i])
        .map(|&i| maps.dcr_hz[i])
        .collect();
    let est_normal: Vec<f64> = normal
        .iter()
        .filter(|&&i| !maps.hot[i])
        .map(|&i| cal.dcr_hz[i])
        .collect();
    let true_median = estimate::median(&maps.dcr_hz).unwrap();
    assert!(
        (cal.dark.median_dcr_hz / true_median - 1.0).abs() < 0.01,
        "{} vs {true_median}",
        cal.dark.median_dcr_hz
    );
    let m = estimate::median(&true_normal).unwrap();
    let true_drnu = estimate::robust_sd(&true_normal).unwrap() / m;
    let est_m = estimate::median(&est_normal).unwrap();
    let est_drnu = estimate::robust_sd(&est_normal).unwrap() / est_m;
    eprintln!(
        "DRNU {:.4} (measured {est_drnu:.4}) vs truth {true_drnu:.4}",
        cal.dark.drnu
    );
    assert!(
        (cal.dark.drnu - true_drnu).abs() < 0.02,
        "{} vs {true_drnu}",
        cal.dark.drnu
    );
    // The counting noise is small here: the correction is small.
    assert!(cal.dark.drnu <= cal.dark.drnu_measured);
    assert!(cal.dark.precision_achieved.unwrap() < 0.05);
    assert!(
        cal.provenance.notes.is_empty(),
        "{:?}",
        cal.provenance.notes
    );
}

#[test]
fn flat_gives_the_prnu_map_within_stated_uncertainty_and_finds_the_dead_pixel() {
    let (cam, maps) = test_camera_and_maps(21);
    let dark = simulate(&cam, &maps, 0.0, 200_000, 22);
    // Background light of about 3 kHz detected per pixel (p ≈ 0.26 per plane: pile-up matters).
    let light_per_um2 = 3000.0 / (cam.eta() * (spcimager_preset().pixel_nm() / 1000.0).powi(2));
    let flat = simulate(&cam, &maps, light_per_um2, 50_000, 23);
    let cal = calibrate_spad(
        &dark,
        Some(&flat),
        &preset_spec(),
        &SpadOptions::default(),
        prov(),
    )
    .unwrap();
    let prnu = cal.prnu.as_ref().unwrap();
    let sd = cal.prnu_sd.as_ref().unwrap();
    let fs = cal.flat.as_ref().unwrap();
    let norm: Vec<usize> = (0..(W * W) as usize)
        .filter(|&i| cal.flags[i] & (flags::HOT | flags::SATURATED | flags::DEAD) == 0)
        .collect();
    assert_eq!(fs.normalising_pixels, norm.len());
    let eta = maps.efficiency(cam.eta());
    let mean_eta = norm.iter().map(|&i| eta[i]).sum::<f64>() / norm.len() as f64;
    let truth: Vec<f64> = eta.iter().map(|e| e / mean_eta).collect();
    // Hot pixels too (their response is noisier but stated so).
    let measured: Vec<usize> = (2..(W * W) as usize).collect();
    assert_calibrated("PRNU", prnu, &truth, sd, &measured);
    let true_spread = estimate::mean_sd(&norm.iter().map(|&i| truth[i]).collect::<Vec<_>>())
        .unwrap()
        .1;
    eprintln!(
        "PRNU spread {:.4} (measured {:.4}, noise {:.4}) vs truth {true_spread:.4}",
        fs.prnu_spread, fs.prnu_spread_measured, fs.prnu_noise
    );
    assert!(
        (fs.prnu_spread - true_spread).abs() < 0.005,
        "{} vs {true_spread}",
        fs.prnu_spread
    );
    // The dead pixel: no counts in the dark or the flat, finite, flagged.
    assert_eq!(cal.flags[1], flags::NO_COUNTS | flags::DEAD);
    assert_eq!(prnu[1], 0.0);
    assert!(sd[1].is_finite());
    assert_eq!(fs.dead_pixels, 1);
}

/// A criterion from the preset with another threshold.
fn criterion(t_int: u64, n: u32) -> HotCriterion {
    let s = preset_spec();
    HotCriterion::new(
        n,
        t_int,
        &s.kernel,
        1e-4,
        s.background_light_hz,
        100.0,
        "test",
    )
    .unwrap()
}

#[test]
fn hot_criterion_follows_the_threshold() {
    let s = preset_spec();
    let base = criterion(s.threshold_int, s.n_window);
    let crit = base.dcr_critical_hz.unwrap();
    // At the critical DCR the expected H is exactly T_int.
    assert!((base.expected_h(crit) / s.threshold_int as f64 - 1.0).abs() < 1e-9);
    // Raising T masks fewer pixels, lowering it more; a longer window with
    // the same T masks more.
    let rates: Vec<f64> = (0..400)
        .map(|i| 10f64.powf(1.0 + 4.0 * i as f64 / 400.0))
        .collect();
    let hot = |c: &HotCriterion| rates.iter().filter(|&&r| c.is_hot(r)).count();
    let mut last = usize::MAX;
    let mut strictly = 0;
    for t in [100_000u64, 115_000, 124_633, 135_000, 160_000, 250_000] {
        let c = criterion(t, s.n_window);
        let h = hot(&c);
        assert!(h <= last, "T_int {t}: {h} hot after {last}");
        if h < last && last != usize::MAX {
            strictly += 1;
        }
        last = h;
    }
    assert!(strictly >= 4);
    assert!(
        criterion(s.threshold_int, s.n_window + 20)
            .dcr_critical_hz
            .unwrap()
            < crit
    );
    // with_threshold keeps everything but N and T.
    let again = base.with_threshold(s.n_window, 135_000).unwrap();
    assert_eq!(
        again.dcr_critical_hz,
        criterion(135_000, s.n_window).dcr_critical_hz
    );
    // Unreachable: even a pixel reading 1 in every plane stays below T.
    let top = criterion(s.n_window as u64 * 65_536, s.n_window);
    assert_eq!(top.dcr_critical_hz, None);
    assert!(!top.is_hot(1e12));
    // Reached by the background alone: every pixel would be hot, an error.
    let e = HotCriterion::new(
        s.n_window,
        1000,
        &s.kernel,
        1e-4,
        s.background_light_hz,
        100.0,
        "t",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("background alone") && e.contains("threshold_int"),
        "{e}"
    );

    // The criterion means "H reaches T_int on about half the planes":
    // simulate H = Σ K·S at a pixel of DCR 0.7, 1 and 1.3× critical.
    let k = s.kernel.size();
    let c = k / 2;
    let p_bg = estimate::plane_probability(100.0 + s.background_light_hz, 1e-4);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut frac = |dcr: f64| {
        let p_pix = estimate::plane_probability(dcr + s.background_light_hz, 1e-4);
        let trials = 1500;
        let mut above = 0;
        for _ in 0..trials {
            let mut h = 0u64;
            for i in 0..k {
                for j in 0..k {
                    let p = if i == c && j == c { p_pix } else { p_bg };
                    let count = (0..s.n_window).filter(|_| rng.gen_bool(p)).count() as u64;
                    h += s.kernel.weight_2d(i, j) * count;
                }
            }
            above += (h >= s.threshold_int) as u32;
        }
        above as f64 / trials as f64
    };
    let (lo, mid, hi) = (frac(0.7 * crit), frac(crit), frac(1.3 * crit));
    eprintln!("P(H >= T_int) at 0.7, 1, 1.3 x critical DCR: {lo:.3} {mid:.3} {hi:.3}");
    assert!(
        lo < 0.35 && (0.35..0.65).contains(&mid) && hi > 0.65,
        "{lo} {mid} {hi}"
    );
}

fn synthetic(ones: Vec<u64>, planes: u64) -> Counted {
    Counted {
        counts: PlaneCounts {
            width: ones.len() as u32,
            height: 1,
            planes,
            ones,
        },
        tau_s: 1e-4,
        plane_period_s: 1e-4,
    }
}

#[test]
fn short_recordings_say_so_unless_accepted() {
    // p = 0.01 per plane at the median: 5 % needs ≈ 40,000 planes.
    let dark = synthetic(vec![10; 64], 1000);
    let opts = SpadOptions::default();
    let e = calibrate_spad(&dark, None, &preset_spec(), &opts, prov()).unwrap_err();
    match &e {
        CalibrationError::TooShort {
            planes: 1000,
            needed,
            needed_is_bound: false,
            achieved: Some(a),
            ..
        } => {
            let want = estimate::planes_for_precision(0.01, 0.05).ceil() as u64;
            assert_eq!(*needed, want);
            assert!((39_000..41_000).contains(needed), "{needed}");
            assert!((a - estimate::relative_precision(0.01, 1000.0)).abs() < 1e-12);
        }
        other => panic!("{other:?}"),
    }
    let msg = e.to_string();
    assert!(
        msg.contains("too short") && msg.contains("--allow-short") && msg.contains("needs"),
        "{msg}"
    );
    // Accepted: the calibration states it.
    let ok = calibrate_spad(
        &dark,
        None,
        &preset_spec(),
        &SpadOptions {
            allow_short: true,
            ..opts.clone()
        },
        prov(),
    )
    .unwrap();
    assert!(ok.dark.planes_needed > ok.planes);
    assert!(ok.provenance.notes.iter().any(|n| n.contains("too short")));
    // Long enough: no complaint.
    let long = synthetic(vec![410; 64], 41_000);
    let ok = calibrate_spad(&long, None, &preset_spec(), &opts, prov()).unwrap();
    assert!(ok.provenance.notes.is_empty() && ok.dark.planes_needed <= 41_000);
    // A looser precision accepts the short one.
    assert!(calibrate_spad(
        &dark,
        None,
        &preset_spec(),
        &SpadOptions {
            precision: 0.35,
            ..opts.clone()
        },
        prov()
    )
    .is_ok());
    // No count at the median pixel: only a lower bound on the planes needed.
    let e = calibrate_spad(
        &synthetic(vec![0; 64], 1000),
        None,
        &preset_spec(),
        &opts,
        prov(),
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            CalibrationError::TooShort {
                needed_is_bound: true,
                achieved: None,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("at least"));
}

#[test]
fn a_flat_too_short_for_the_precision_is_refused_unless_allowed() {
    let (cam, maps) = test_camera_and_maps(21);
    let dark = simulate(&cam, &maps, 0.0, 200_000, 22);
    let light_per_um2 = 3000.0 / (cam.eta() * (spcimager_preset().pixel_nm() / 1000.0).powi(2));
    let flat = simulate(&cam, &maps, light_per_um2, 20, 23);
    let e = calibrate_spad(
        &dark,
        Some(&flat),
        &preset_spec(),
        &SpadOptions::default(),
        prov(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("the flat recording is too short: 20 bit-planes"),
        "{e}"
    );
    assert!(e.contains("--allow-short"), "{e}");
    let needed: u64 = e
        .split(" needs ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap();
    // Counting noise at p ≈ 0.26: 5 % needs a few thousand planes, not 20.
    assert!((500..50_000).contains(&needed), "{needed}: {e}");
    let allowed = SpadOptions {
        allow_short: true,
        ..Default::default()
    };
    assert!(calibrate_spad(&dark, Some(&flat), &preset_spec(), &allowed, prov()).is_ok());
}

#[test]
fn saturated_dead_and_one_plane_recordings_are_finite_and_flagged() {
    let n = 2000;
    let mut dark = vec![20u64; 64];
    dark[0] = n; // stuck on
    dark[1] = 0; // no dark count
    let mut flat = vec![600u64; 64];
    flat[0] = n;
    flat[1] = 0; // dead
    flat[2] = n; // saturated in the flat only
    flat[3] = 25; // barely above its dark rate: dead
    let opts = SpadOptions {
        allow_short: true,
        ..Default::default()
    };
    let cal = calibrate_spad(
        &synthetic(dark, n),
        Some(&synthetic(flat, n)),
        &preset_spec(),
        &opts,
        prov(),
    )
    .unwrap();
    let prnu = cal.prnu.as_ref().unwrap();
    let psd = cal.prnu_sd.as_ref().unwrap();
    for v in [&cal.dcr_hz, &cal.dcr_sd_hz, prnu, psd] {
        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0));
    }
    assert_eq!(
        cal.flags[0] & (flags::SATURATED | flags::HOT | flags::FLAT_SATURATED),
        flags::SATURATED | flags::HOT | flags::FLAT_SATURATED
    );
    assert_eq!(cal.flags[1], flags::NO_COUNTS | flags::DEAD);
    assert_eq!(cal.flags[2], flags::FLAT_SATURATED);
    assert!(
        prnu[2] > 1.0,
        "a lower estimate above the others: {}",
        prnu[2]
    );
    assert_eq!(cal.flags[3], flags::DEAD);
    assert!(cal.flags[4..].iter().all(|&f| f == 0));
    assert!((prnu[10] - 1.0).abs() < 1e-12);
    // One single plane: still finite.
    let one = calibrate_spad(
        &synthetic(vec![0, 1, 1, 0], 1),
        Some(&synthetic(vec![1, 1, 0, 1], 1)),
        &preset_spec(),
        &opts,
        prov(),
    );
    match one {
        Ok(c) => assert!(c.dcr_hz.iter().chain(&c.dcr_sd_hz).all(|x| x.is_finite())),
        Err(e) => assert!(matches!(e, CalibrationError::Invalid { .. }), "{e}"),
    }
    // An empty recording and a flat of another size are errors naming them.
    let e = calibrate_spad(
        &synthetic(vec![0; 4], 0),
        None,
        &preset_spec(),
        &opts,
        prov(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("dark (simulated)"), "{e}");
    let e = calibrate_spad(
        &synthetic(vec![1; 4], 10),
        Some(&synthetic(vec![1; 5], 10)),
        &preset_spec(),
        &opts,
        prov(),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("expected 4x1 pixels, found 5x1"),
        "{e}"
    );
    // A flat no brighter than the dark.
    let e = calibrate_spad(
        &synthetic(vec![10; 4], 1000),
        Some(&synthetic(vec![10; 4], 1000)),
        &preset_spec(),
        &opts,
        prov(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("no photon response"), "{e}");
}

/// The calibration with its maps rounded to f32, as the file stores them.
fn rounded(c: &Calibration) -> Calibration {
    let r = |v: &Vec<f64>| v.iter().map(|&x| x as f32 as f64).collect::<Vec<_>>();
    Calibration {
        dcr_hz: r(&c.dcr_hz),
        dcr_sd_hz: r(&c.dcr_sd_hz),
        prnu: c.prnu.as_ref().map(r),
        prnu_sd: c.prnu_sd.as_ref().map(r),
        ..c.clone()
    }
}

fn small_calibration() -> Calibration {
    let mut dark: Vec<u64> = (0..48).map(|i| 600 + i).collect();
    dark[5] = 30_000; // hot
    dark[6] = 0;
    let flat: Vec<u64> = (0..48).map(|i| 18_000 + 13 * i).collect();
    let mut c = calibrate_spad(
        &Counted {
            counts: PlaneCounts {
                width: 8,
                height: 6,
                planes: 60_000,
                ones: dark,
            },
            tau_s: 1e-4,
            plane_period_s: 1e-4,
        },
        Some(&Counted {
            counts: PlaneCounts {
                width: 8,
                height: 6,
                planes: 60_000,
                ones: flat,
            },
            tau_s: 1e-4,
            plane_period_s: 1e-4,
        }),
        &preset_spec(),
        &SpadOptions::default(),
        prov(),
    )
    .unwrap();
    c.provenance.notes.push("a note with \"quotes\"".into());
    c
}

fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
}

fn edit_header(dir: &std::path::Path, f: impl Fn(String) -> String) {
    let p = dir.join(format::HEADER_FILE);
    let s = std::fs::read_to_string(&p).unwrap();
    std::fs::write(&p, f(s)).unwrap();
}

fn write_f32_tiff(path: &std::path::Path, w: u32, h: u32, v: &[f32]) {
    let f = std::fs::File::create(path).unwrap();
    let mut enc = tiff::encoder::TiffEncoder::new(f).unwrap();
    enc.write_image::<tiff::encoder::colortype::Gray32Float>(w, h, v)
        .unwrap();
}

#[test]
fn spad_calibration_round_trips_and_corrupt_directories_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_calibration();
    assert_eq!(c.dark.hot_pixels, 1);
    let dir = tmp.path().join("calib");
    c.save(&dir).unwrap();
    let back = Calibration::load(&dir).unwrap();
    assert_eq!(back, rounded(&c));
    assert_eq!(
        Calibration::load(&dir.join(format::HEADER_FILE)).unwrap(),
        back
    );
    assert_eq!(back.hot_pixels(), vec![(5, 0)]);
    assert!(back.hot_mask().is_masked(5, 0) && back.hot_mask().count() == 1);
    // Saving what was loaded gives the same files.
    let dir2 = tmp.path().join("again");
    back.save(&dir2).unwrap();
    for name in ["dcr_hz.tif", "flags.tif", "prnu.tif", "calibration.toml"] {
        assert_eq!(
            std::fs::read(dir.join(name)).unwrap(),
            std::fs::read(dir2.join(name)).unwrap(),
            "{name}"
        );
    }
    // Saving without a flat removes the stale PRNU maps.
    let no_flat = Calibration {
        prnu: None,
        prnu_sd: None,
        flat: None,
        ..back.clone()
    };
    no_flat.save(&dir2).unwrap();
    assert!(!dir2.join("prnu.tif").exists());
    assert_eq!(Calibration::load(&dir2).unwrap().prnu, None);
    // Invalid calibrations are not written.
    let mut bad = c.clone();
    bad.dcr_hz[3] = f64::NAN;
    assert!(bad
        .save(&tmp.path().join("bad"))
        .unwrap_err()
        .to_string()
        .contains("pixel (3, 0)"));

    let case = |name: &str,
                damage: &dyn Fn(&std::path::Path),
                want: &dyn Fn(&CalibrationError) -> bool,
                text: &str| {
        let d = tmp.path().join(name);
        copy_dir(&dir, &d);
        damage(&d);
        let e = AnyCalibration::load(&d).unwrap_err();
        assert!(want(&e), "{name}: {e:?}");
        assert!(e.to_string().contains(text), "{name}: {e}");
    };
    case(
        "missing",
        &|d| std::fs::remove_file(d.join("dcr_hz.tif")).unwrap(),
        &|e| matches!(e, CalibrationError::MissingMap { name, .. } if name == "dcr_hz"),
        "dcr_hz",
    );
    case(
        "unlisted",
        &|d| edit_header(d, |s| s.replace("[maps.dcr_sd_hz]", "[maps.unused]")),
        &|e| matches!(e, CalibrationError::MissingMap { name, .. } if name == "dcr_sd_hz"),
        "missing",
    );
    case(
        "wrong size",
        &|d| write_f32_tiff(&d.join("prnu.tif"), 4, 6, &[1.0; 24]),
        &|e| matches!(e, CalibrationError::Map { name, .. } if name == "prnu"),
        "4x6 pixels, the calibration is 8x6",
    );
    case(
        "truncated",
        &|d| {
            let p = d.join("flags.tif");
            let b = std::fs::read(&p).unwrap();
            std::fs::write(&p, &b[..b.len() / 2]).unwrap();
        },
        &|e| matches!(e, CalibrationError::Map { name, .. } if name == "flags"),
        "flags",
    );
    case(
        "wrong type",
        &|d| write_f32_tiff(&d.join("flags.tif"), 8, 6, &[0.0; 48]),
        &|e| matches!(e, CalibrationError::Map { .. }),
        "not a single-channel u8",
    );
    case(
        "nan",
        &|d| {
            let mut v = vec![1.0f32; 48];
            v[9] = f32::NAN;
            write_f32_tiff(&d.join("dcr_hz.tif"), 8, 6, &v);
        },
        &|e| matches!(e, CalibrationError::Map { .. }),
        "pixel (1, 1)",
    );
    case(
        "negative",
        &|d| write_f32_tiff(&d.join("dcr_sd_hz.tif"), 8, 6, &[-1.0; 48]),
        &|e| matches!(e, CalibrationError::Map { .. }),
        "not negative",
    );
    case(
        "flag bits",
        &|d| {
            let f = std::fs::File::create(d.join("flags.tif")).unwrap();
            let mut v = vec![0u8; 48];
            v[47] = 0x80;
            tiff::encoder::TiffEncoder::new(f)
                .unwrap()
                .write_image::<tiff::encoder::colortype::Gray8>(8, 6, &v)
                .unwrap();
        },
        &|e| matches!(e, CalibrationError::Map { .. }),
        "pixel (7, 5)",
    );
    case(
        "newer",
        &|d| edit_header(d, |s| s.replace("version = 1", "version = 2")),
        &|e| {
            matches!(
                e,
                CalibrationError::UnsupportedVersion {
                    found: 2,
                    supported: 1,
                    ..
                }
            )
        },
        "newer",
    );
    case(
        "other format",
        &|d| edit_header(d, |s| s.replace("smartagg-calibration", "something-else")),
        &|e| matches!(e, CalibrationError::NotCalibration { .. }),
        "something-else",
    );
    case(
        "garbage",
        &|d| {
            std::fs::write(
                d.join("calibration.toml"),
                "format = \"smartagg-calibration\"\nversion = 1\nwidth = [",
            )
            .unwrap()
        },
        &|e| matches!(e, CalibrationError::Header { .. }),
        "TOML",
    );
    case(
        "missing field",
        &|d| edit_header(d, |s| s.replace("planes = 60000\n", "")),
        &|e| matches!(e, CalibrationError::Header { .. }),
        "planes",
    );
    case(
        "edited threshold",
        &|d| {
            edit_header(d, |s| {
                s.replace("threshold_int = 124633", "threshold_int = 200000")
            })
        },
        &|e| matches!(e, CalibrationError::Header { .. }),
        "edited or corrupted",
    );
    case(
        "escaping path",
        &|d| {
            edit_header(d, |s| {
                s.replace("file = \"prnu.tif\"", "file = \"../prnu.tif\"")
            })
        },
        &|e| matches!(e, CalibrationError::Map { .. }),
        "plain name",
    );
    case(
        "no header",
        &|d| std::fs::remove_file(d.join("calibration.toml")).unwrap(),
        &|e| matches!(e, CalibrationError::NotCalibration { .. }),
        "does not exist",
    );
    let e = FrameCalibration::load(&dir).unwrap_err();
    assert!(
        matches!(e, CalibrationError::WrongKind { .. }) && e.to_string().contains("spad camera"),
        "{e}"
    );
}

#[test]
fn report_files_are_written() {
    let tmp = tempfile::tempdir().unwrap();
    let c = small_calibration();
    c.save(tmp.path()).unwrap();
    let files = report::write_spad_report(&c, tmp.path()).unwrap();
    assert!(files.warnings.is_empty(), "{:?}", files.warnings);
    let md = std::fs::read_to_string(tmp.path().join("report.md")).unwrap();
    for want in [
        "median DCR",
        "Planes needed",
        "critical DCR",
        "1 of 48",
        "PRNU spread",
        "a note with",
    ] {
        assert!(md.contains(want), "{want} missing from\n{md}");
    }
    let csv = std::fs::read_to_string(tmp.path().join("hot_pixels.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2);
    assert!(csv.lines().nth(1).unwrap().starts_with("5,0,"));
    let png = std::fs::read(tmp.path().join("dcr_histogram.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

// ---------------------------------------------------------------------------
// Frame cameras

/// Frames held in memory.
struct Memory {
    width: u32,
    height: u32,
    frames: Vec<Vec<u16>>,
}

impl FrameSource for Memory {
    fn name(&self) -> String {
        "memory".into()
    }
    fn for_each_frame(
        &self,
        visit: &mut super::frames::Visit<'_>,
    ) -> Result<u64, CalibrationError> {
        for f in &self.frames {
            visit(self.width, self.height, f)?;
        }
        Ok(self.frames.len() as u64)
    }
}

#[test]
fn scmos_offset_read_noise_and_gain_maps_match_the_truth() {
    let p = Preset::new(PresetName::Scmos, 150).unwrap();
    let Camera::Scmos(cam) = p.camera.clone() else {
        unreachable!()
    };
    let nu = smartagg_scene::ScmosNonUniformity::default();
    let mut maps = smartagg_scene::ScmosMaps::generate(&cam, &nu, W, W, 31);
    maps.qe[3] = 0.0; // dead
    maps.read_noise_e[4] *= 10.0; // noisy
    maps.offset_adu[5] += 300.0; // hot (dark level far above the others)
                                 // ≈ 200 photo-electrons per frame in the flat.
    let px_um2 = (p.pixel_nm() / 1000.0).powi(2);
    let bg = 200.0 / (cam.qe * cam.exposure_s * px_um2);
    let frames = |light: f64, seed: u64, count: usize| {
        let mut sim =
            ScmosSimulator::with_maps(&cam, &empty_scene(&p, W, light), maps.clone(), seed)
                .unwrap();
        Memory {
            width: W,
            height: W,
            frames: (0..count).map(|_| sim.next_frame().adu).collect(),
        }
    };
    let (dark, flat) = (frames(0.0, 32, 1500), frames(bg, 33, 1500));
    let opts = FrameOptions {
        camera: FrameCamera::Scmos,
        excess_noise_f2: 2.0,
        dead_below: 0.1,
        fallback_gain: None,
    };
    let c = calibrate_frames(&dark, Some(&flat), &opts, prov()).unwrap();
    let n = (W * W) as usize;
    let t = cam.frame_period_s;
    let truth_offset: Vec<f64> = (0..n)
        .map(|i| maps.offset_adu[i] + maps.gain_adu_per_e[i] * maps.dark_e_per_s[i] * t)
        .collect();
    let truth_rn: Vec<f64> = (0..n)
        .map(|i| {
            maps.gain_adu_per_e[i]
                * (maps.read_noise_e[i].powi(2) + maps.dark_e_per_s[i] * t).sqrt()
        })
        .collect();
    let regular: Vec<usize> = (0..n).filter(|i| ![3, 4, 5].contains(i)).collect();
    for (name, est, truth, sd) in [
        ("offset", &c.offset_adu, &truth_offset, &c.offset_sd_adu),
        (
            "read noise",
            &c.read_noise_adu,
            &truth_rn,
            &c.read_noise_sd_adu,
        ),
        (
            "gain",
            c.gain_adu_per_e.as_ref().unwrap(),
            &maps.gain_adu_per_e,
            c.gain_sd_adu_per_e.as_ref().unwrap(),
        ),
    ] {
        assert_calibrated(name, est, truth, sd, &regular);
    }
    let s = &c.summary;
    let true_gain = estimate::median(
        &regular
            .iter()
            .map(|&i| maps.gain_adu_per_e[i])
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let (g, g_sd) = (s.gain_adu_per_e.unwrap(), s.gain_sd_adu_per_e.unwrap());
    eprintln!("sCMOS gain {g:.5} ± {g_sd:.5} vs median truth {true_gain:.5}");
    assert!((g - true_gain).abs() < 3.0 * g_sd + 0.002 * true_gain);
    let re = c.read_noise_e.as_ref().unwrap();
    let true_rn_e = estimate::median(
        &regular
            .iter()
            .map(|&i| maps.read_noise_e[i])
            .collect::<Vec<_>>(),
    )
    .unwrap();
    assert!(
        (s.read_noise_median_e.unwrap() / true_rn_e - 1.0).abs() < 0.03,
        "{:?} vs {true_rn_e}",
        s.read_noise_median_e
    );
    assert!(re.iter().all(|x| x.is_finite()));
    assert!(
        c.flags[3] & flags::DEAD != 0
            && c.flags[4] & flags::NOISY != 0
            && c.flags[5] & flags::HOT != 0
    );
    assert_eq!((s.dead_pixels, s.noisy_pixels, s.hot_pixels), (1, 1, 1));
    // The dead pixel has no photon-transfer slope: the median gain is stored.
    assert!(c.flags[3] & flags::UNMEASURED != 0 && c.gain_adu_per_e.as_ref().unwrap()[3] == g);
    // PRNU: relative QE × gain response.
    let prnu = c.prnu.as_ref().unwrap();
    assert!(prnu[3] < 0.05 && (prnu[10] - 1.0).abs() < 0.05);

    // Round trip.
    let tmp = tempfile::tempdir().unwrap();
    c.save(tmp.path()).unwrap();
    let back = FrameCalibration::load(tmp.path()).unwrap();
    assert_eq!(back.summary, c.summary);
    assert_eq!(back.flags, c.flags);
    assert!(back
        .offset_adu
        .iter()
        .zip(&c.offset_adu)
        .all(|(a, b)| (a - b).abs() <= 1e-6 * b.abs()));
    let e = Calibration::load(tmp.path()).unwrap_err();
    assert!(e.to_string().contains("scmos camera"), "{e}");
    let files = report::write_frame_report(&c, tmp.path()).unwrap();
    assert!(files.warnings.is_empty(), "{:?}", files.warnings);
    // A flat of another size.
    let small = Memory {
        width: 4,
        height: 4,
        frames: vec![vec![0; 16]; 3],
    };
    let e = calibrate_frames(&dark, Some(&small), &opts, prov()).unwrap_err();
    assert!(
        e.to_string().contains("expected 16x16 pixels, found 4x4"),
        "{e}"
    );
}

#[test]
fn emccd_gain_and_input_referred_read_noise_are_recovered() {
    let p = Preset::new(PresetName::Emccd, 150).unwrap();
    let Camera::Emccd(cam) = p.camera.clone() else {
        unreachable!()
    };
    // ≈ 20 input electrons per frame in the flat: 500 ADU above offset at g = 25.
    let px_um2 = (p.pixel_nm() / 1000.0).powi(2);
    let bg = 20.0 / (cam.qe * cam.exposure_s * px_um2);
    let side = 32;
    let frames = |light: f64, seed: u64, count: usize| {
        let mut sim = EmccdSimulator::new(&cam, &empty_scene(&p, side, light), seed).unwrap();
        Memory {
            width: side,
            height: side,
            frames: (0..count).map(|_| sim.next_frame().adu).collect(),
        }
    };
    let (dark, flat) = (frames(0.0, 41, 400), frames(bg, 42, 400));
    let opts = FrameOptions {
        camera: FrameCamera::Emccd,
        excess_noise_f2: 2.0 - 1.0 / cam.em_gain,
        dead_below: 0.1,
        fallback_gain: None,
    };
    let c = calibrate_frames(&dark, Some(&flat), &opts, prov()).unwrap();
    let s = &c.summary;
    let truth = cam.em_gain / cam.e_per_adu;
    let (g, sd) = (s.gain_adu_per_e.unwrap(), s.gain_sd_adu_per_e.unwrap());
    eprintln!("EMCCD gain {g:.4} ± {sd:.4} ADU/e- (truth {truth}); read noise {:.4} e- (truth {}); offset {:.3}; {} spikes rejected", s.read_noise_median_e.unwrap(), cam.read_noise_e, s.offset_median_adu, s.rejected_dark_values);
    assert!(
        (g - truth).abs() < 3.0 * sd && sd < 0.01 * truth,
        "{g} ± {sd}"
    );
    // Input-referred read noise 0.2 e- (5 ADU), with the CIC spikes rejected.
    assert!((s.read_noise_median_e.unwrap() / cam.read_noise_e - 1.0).abs() < 0.03);
    assert!((s.offset_median_adu - cam.offset_adu).abs() < 0.2);
    assert!(s.rejected_dark_values > 0);
    let regular: Vec<usize> = (0..(side * side) as usize).collect();
    let truth_offset = vec![cam.offset_adu; regular.len()];
    assert_calibrated(
        "EMCCD offset",
        &c.offset_adu,
        &truth_offset,
        &c.offset_sd_adu,
        &regular,
    );
    assert_eq!(s.hot_pixels + s.dead_pixels + s.noisy_pixels, 0);
    // Without a flat, the preset's gain stands in, and says so.
    let fb = FrameOptions {
        fallback_gain: Some((truth, "preset emccd".into())),
        ..opts
    };
    let c = calibrate_frames(&dark, None, &fb, prov()).unwrap();
    assert_eq!(c.summary.gain_adu_per_e, Some(truth));
    assert!(c.summary.gain_source.contains("not measured") && c.prnu.is_none());
    // One frame has no variance.
    let one = Memory {
        width: side,
        height: side,
        frames: dark.frames[..1].to_vec(),
    };
    assert!(calibrate_frames(&one, None, &fb, prov())
        .unwrap_err()
        .to_string()
        .contains("at least 2"));
}

#[test]
fn tiff_stacks_are_read_page_by_page_and_bad_pages_are_named() {
    use tiff::encoder::{colortype, TiffEncoder};
    let tmp = tempfile::tempdir().unwrap();
    let stack = |name: &str, pages: &[(u32, u32, bool)]| {
        let path = tmp.path().join(name);
        let mut enc = TiffEncoder::new(std::fs::File::create(&path).unwrap()).unwrap();
        for (k, &(w, h, eight_bit)) in pages.iter().enumerate() {
            let n = (w * h) as usize;
            if eight_bit {
                enc.write_image::<colortype::Gray8>(w, h, &vec![7u8; n])
                    .unwrap();
            } else {
                let v: Vec<u16> = (0..n).map(|i| (i + 1000 * k) as u16).collect();
                enc.write_image::<colortype::Gray16>(w, h, &v).unwrap();
            }
        }
        super::frames::TiffStack { path }
    };
    let read = |s: &super::frames::TiffStack| {
        let mut frames = Vec::new();
        s.for_each_frame(&mut |w, h, f| {
            frames.push((w, h, f.to_vec()));
            Ok(())
        })
        .map(|n| (n, frames))
    };
    let (n, frames) = read(&stack("good.tif", &[(3, 2, false); 3])).unwrap();
    assert_eq!(n, 3);
    assert_eq!(frames[2], (3, 2, vec![2000, 2001, 2002, 2003, 2004, 2005]));
    let e = read(&stack("mixed.tif", &[(3, 2, false), (4, 4, false)]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("page 2 is 4x4 pixels, but the first page is 3x2"),
        "{e}"
    );
    let e = read(&stack("bytes.tif", &[(3, 2, false), (3, 2, true)]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("page 2 is u8, not u16"), "{e}");
    let text = tmp.path().join("text.tif");
    std::fs::write(&text, "not an image").unwrap();
    let e = read(&super::frames::TiffStack { path: text })
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not a readable TIFF") && e.contains("text.tif"),
        "{e}"
    );
    let e = read(&super::frames::TiffStack {
        path: tmp.path().join("absent.tif"),
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("absent.tif"), "{e}");
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(64))]

    /// Damaged calibration directories (bytes flipped, cut or inserted in
    /// the header or any map) load or fail with an error; never a panic, and
    /// a map that loads is finite.
    #[test]
    fn damaged_calibrations_never_panic(
        file in 0usize..4,
        edits in proptest::collection::vec((proptest::num::usize::ANY, proptest::num::u8::ANY, 0u8..3), 1..6),
    ) {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("calib");
        small_calibration().save(&dir).unwrap();
        let name = ["calibration.toml", "dcr_hz.tif", "flags.tif", "prnu.tif"][file];
        let path = dir.join(name);
        let mut bytes = std::fs::read(&path).unwrap();
        for (at, value, kind) in edits {
            let i = at % (bytes.len() + 1);
            match kind {
                0 if i < bytes.len() => bytes[i] ^= value | 1,
                1 => bytes.truncate(i),
                _ => bytes.insert(i, value),
            }
        }
        std::fs::write(&path, &bytes).unwrap();
        if let Ok(c) = Calibration::load(&dir) {
            proptest::prop_assert!(c.dcr_hz.iter().all(|v| v.is_finite()));
            if let Some(p) = &c.prnu {
                proptest::prop_assert!(p.iter().all(|v| v.is_finite()));
            }
        }
    }
}

#[test]
fn a_save_that_fails_leaves_the_earlier_calibration_as_it_was() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("calib");
    let c = small_calibration();
    c.save(&dir).unwrap();
    let before = Calibration::load(&dir).unwrap();
    // The last map cannot be written (its file beside the target is a folder).
    std::fs::create_dir(dir.join(".prnu.tif.partial")).unwrap();
    let mut other = c.clone();
    other.dcr_hz[0] += 1.0;
    assert!(other.save(&dir).is_err());
    assert_eq!(Calibration::load(&dir).unwrap(), before);
    std::fs::remove_dir(dir.join(".prnu.tif.partial")).unwrap();
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    other.save(&dir).unwrap();
    assert_ne!(Calibration::load(&dir).unwrap(), before);
}
