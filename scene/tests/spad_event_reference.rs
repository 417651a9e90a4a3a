//! The fast SPAD sampler against an independent event-level sampler.
//!
//! If the simulator drew bits as Bernoulli(Eq. 1), checking it against Eq. 1
//! would prove nothing. Here the reference (tests/common) simulates photon
//! arrival *times* within each exposure (background, dark counts and molecule
//! photons as Poisson processes, blinks switching on and off inside planes),
//! places molecule photons at continuous Gaussian positions (no erf), thins
//! every photon by the η of the pixel it lands in, and sets a bit when a pixel
//! has any event. Per-pixel frequencies of 1 are compared with two-proportion
//! z-tests: every |z| < 5 and χ²/k ≤ 1 + 5√(2/k). Negative controls show the
//! comparison has the power to see a 0.2-plane timing error or a 10 % PSF
//! width error.

mod common;

use common::{event_plane, two_sample, EventScene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use smartagg_model::params::{spcimager, Preset, PresetName, SceneLight, SpadCamera};
use smartagg_scene::{Blinking, ExplicitBlink, Layout, Position, Scene, SpadSimulator};

const W: u32 = 16;

/// SPCImager with exaggerated non-uniformities and 5 % hot pixels, so that the
/// per-pixel maps matter.
fn camera() -> SpadCamera {
    SpadCamera {
        prnu: 0.2,
        drnu: 0.5,
        hot_pixel_fraction: 0.05,
        hot_pixel_dcr_hz: 3000.0,
        ..spcimager()
    }
}

fn scene(blinks: Vec<ExplicitBlink>, flux_hz: f64) -> Scene {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    Scene {
        width: W,
        height: W,
        optics: p.optics,
        light: SceneLight {
            flux_hz,
            background_per_um2_hz: 70_000.0,
        },
        layout: Layout::List(vec![]),
        blinking: Blinking::Explicit(blinks),
        intensity_cv: 0.0,
        margin_px: 0.0,
    }
}

fn pos(sc: &Scene, x_px: f64, y_px: f64) -> Position {
    let p = sc.optics.pixel_nm(8.0);
    Position {
        x_nm: x_px * p,
        y_nm: y_px * p,
    }
}

/// Per-class, per-pixel counts of 1 from the fast simulator.
fn fast_counts(
    sim: &mut SpadSimulator,
    planes: u64,
    class: impl Fn(u64) -> usize,
    classes: usize,
) -> Vec<Vec<u64>> {
    let n = (W * W) as usize;
    let mut c = vec![vec![0u64; n]; classes];
    for k in 0..planes {
        let plane = sim.next_plane();
        let cl = class(k);
        for i in plane.bits().iter_ones() {
            c[cl][i] += 1;
        }
    }
    c
}

fn event_counts(
    es: &EventScene,
    planes: u64,
    class: impl Fn(u64) -> usize,
    classes: usize,
    seed: u64,
) -> Vec<Vec<u64>> {
    let n = (W * W) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut c = vec![vec![0u64; n]; classes];
    for k in 0..planes {
        let bits = event_plane(es, k, &mut rng);
        let cl = class(k);
        for (i, &b) in bits.iter().enumerate() {
            c[cl][i] += b as u64;
        }
    }
    c
}

#[test]
fn blinks_starting_and_stopping_inside_planes_match_the_event_level_sampler() {
    let cam = camera();
    let t = cam.plane_period_s;
    let cycles = 3000u64;
    // Period of 5 planes: on from 0.3 into plane 0 until 0.55 into plane 3.
    // Plane classes: 0 = starts mid-plane (0.7 τ on), 1 and 2 = on throughout,
    // 3 = stops mid-plane (0.55 τ on), 4 = off.
    let base = scene(vec![], 0.0);
    let p0 = pos(&base, 7.3, 8.6);
    let blinks: Vec<ExplicitBlink> = (0..cycles)
        .map(|m| ExplicitBlink {
            emitter: 0,
            position: p0,
            t_on_s: (5 * m) as f64 * t + 0.3 * t,
            t_off_s: (5 * m) as f64 * t + 3.55 * t,
            flux_factor: 1.0,
        })
        .collect();
    // I·τ = 200: the centre pixel reads 1 about 2/3 of the time.
    let flux = 2.0e6;
    let sc = scene(blinks.clone(), flux);
    let mut sim = SpadSimulator::new(&cam, &sc, 11).unwrap();
    assert!(sim.maps().hot_pixels() > 5);
    let planes = 5 * cycles;
    let class = |k: u64| (k % 5) as usize;
    let fast = fast_counts(&mut sim, planes, class, 5);

    let es = EventScene {
        maps: sim.maps(),
        eta: sim.efficiency(),
        background_photons_hz: sc
            .light
            .background_per_pixel_hz(&sc.optics, cam.pixel_pitch_um),
        blinks: &blinks,
        flux_hz: flux,
        sigma_nm: sc.optics.psf_sigma_nm(),
        pixel_nm: sc.optics.pixel_nm(cam.pixel_pitch_um),
        period_s: t,
        exposure_s: cam.exposure_s,
    };
    let reference = event_counts(&es, planes, class, 5, 12345);

    let centre = 8 * W as usize + 7;
    for c in 0..5 {
        let r = two_sample(&fast[c], &reference[c], cycles);
        eprintln!(
            "class {c}: centre fast {} ref {} / {cycles}; {r:?}",
            fast[c][centre], reference[c][centre]
        );
        assert!(r.cells > 50, "class {c}: too few informative pixels");
        assert!(r.max_abs_z < 5.0, "class {c}: {r:?}");
        assert!(r.chi2_per_cell() < r.chi2_bound(), "class {c}: {r:?}");
    }
    // The pattern is really there: full > start (0.7 τ) > end (0.55 τ) > off.
    let f = |c: usize| fast[c][centre];
    assert!(
        f(1) > f(0) && f(0) > f(3) && f(3) > f(4) + 1000,
        "{:?}",
        (0..5).map(f).collect::<Vec<_>>()
    );

    // Negative control 1: the blink starting 0.2 τ later must be detected.
    let shifted: Vec<ExplicitBlink> = blinks
        .iter()
        .map(|b| ExplicitBlink {
            t_on_s: b.t_on_s + 0.2 * t,
            ..*b
        })
        .collect();
    let es_shift = EventScene {
        blinks: &shifted,
        ..es
    };
    let r = two_sample(
        &fast[0],
        &event_counts(&es_shift, planes, class, 5, 777)[0],
        cycles,
    );
    eprintln!("control (timing): {r:?}");
    assert!(
        r.chi2_per_cell() > r.chi2_bound() || r.max_abs_z > 5.0,
        "control (timing) not detected: {r:?}"
    );
    // Negative control 2: a PSF 10 % wider must be detected.
    let es_wide = EventScene {
        sigma_nm: es.sigma_nm * 1.1,
        blinks: &blinks,
        ..es
    };
    let r = two_sample(
        &fast[1],
        &event_counts(&es_wide, planes, class, 5, 778)[1],
        cycles,
    );
    eprintln!("control (sigma): {r:?}");
    assert!(
        r.chi2_per_cell() > r.chi2_bound() || r.max_abs_z > 5.0,
        "control (sigma) not detected: {r:?}"
    );
}

#[test]
fn pile_up_at_i_tau_1e4_matches_the_event_level_sampler() {
    let cam = camera();
    let t = cam.plane_period_s;
    let base = scene(vec![], 0.0);
    let blinks = vec![ExplicitBlink {
        emitter: 0,
        position: pos(&base, 8.0, 7.5),
        t_on_s: -1.0,
        t_off_s: 1.0e6,
        flux_factor: 1.0,
    }];
    // I·τ = 1e4 photons per plane reaching the sensor.
    let flux = 1.0e4 / cam.exposure_s;
    let sc = scene(blinks.clone(), flux);
    let mut sim = SpadSimulator::new(&cam, &sc, 21).unwrap();
    let planes = 1000u64;
    let fast = fast_counts(&mut sim, planes, |_| 0, 1);
    let es = EventScene {
        maps: sim.maps(),
        eta: sim.efficiency(),
        background_photons_hz: sc
            .light
            .background_per_pixel_hz(&sc.optics, cam.pixel_pitch_um),
        blinks: &blinks,
        flux_hz: flux,
        sigma_nm: sc.optics.psf_sigma_nm(),
        pixel_nm: sc.optics.pixel_nm(cam.pixel_pitch_um),
        period_s: t,
        exposure_s: cam.exposure_s,
    };
    let reference = event_counts(&es, planes, |_| 0, 1, 999);
    // Every pixel within 1σ of the molecule reads 1 in every plane (in both).
    for (y, x) in [(7usize, 8usize), (7, 7), (6, 8), (8, 8)] {
        let i = y * W as usize + x;
        assert_eq!(fast[0][i], planes, "pixel ({x},{y})");
        assert_eq!(reference[0][i], planes, "pixel ({x},{y})");
    }
    let r = two_sample(&fast[0], &reference[0], planes);
    eprintln!("{r:?}");
    // The ring where pile-up bends the response (0 < p < 1) is wide enough to test.
    assert!(r.cells > 30, "{r:?}");
    assert!(r.max_abs_z < 5.0, "{r:?}");
    assert!(r.chi2_per_cell() < r.chi2_bound(), "{r:?}");
    // The truth counts every detection, far more than the bits can show.
    let b = &sim.truth()[0];
    let ones: u64 = fast[0].iter().sum();
    assert!(
        b.photons_detected > 3 * ones,
        "{} detections vs {ones} ones",
        b.photons_detected
    );
}
