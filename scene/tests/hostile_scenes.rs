//! Extreme but valid scenes finish in a time that does not grow with the
//! photon count, and no NaN or infinity reaches a frame (issue 36).

use smartagg_model::params::{
    Camera, EmccdCamera, Preset, PresetName, SceneLight, MAX_FLUX_HZ, MAX_FRAME_PERIOD_S,
};
use smartagg_scene::{Blinking, EmccdSimulator, ExplicitBlink, Layout, Position, Scene};
use std::time::{Duration, Instant};

fn emccd() -> (Preset, EmccdCamera) {
    let p = Preset::new(PresetName::Emccd, 150).unwrap();
    let Camera::Emccd(c) = p.camera.clone() else {
        unreachable!()
    };
    (p, c)
}

fn one_blink(p: &Preset, cam: &EmccdCamera, flux_hz: f64, seconds: f64) -> Scene {
    let pn = p.optics.pixel_nm(cam.pixel_pitch_um);
    Scene {
        width: 24,
        height: 24,
        optics: p.optics,
        light: SceneLight {
            flux_hz,
            background_per_um2_hz: 70_000.0,
        },
        layout: Layout::List(vec![]),
        blinking: Blinking::Explicit(vec![ExplicitBlink {
            emitter: 0,
            position: Position {
                x_nm: 12.3 * pn,
                y_nm: 11.6 * pn,
            },
            t_on_s: 0.0,
            t_off_s: seconds,
            flux_factor: 1.0,
        }]),
        intensity_cv: 0.0,
        margin_px: 0.0,
    }
}

#[test]
fn the_brightest_molecule_in_the_longest_frame_takes_no_longer_than_a_dim_one() {
    let (p, mut cam) = emccd();
    cam.frame_period_s = MAX_FRAME_PERIOD_S;
    cam.exposure_s = MAX_FRAME_PERIOD_S;
    // 10^11 photons per frame: photon by photon this would take minutes.
    let sc = one_blink(&p, &cam, MAX_FLUX_HZ, 10.0 * MAX_FRAME_PERIOD_S);
    let mut sim = EmccdSimulator::new(&cam, &sc, 7).unwrap();
    let t = Instant::now();
    for _ in 0..3 {
        let f = sim.next_frame();
        assert!(f.electrons.iter().all(|e| e.is_finite() && *e >= 0.0));
        assert!(f.clipped > 0, "10^11 photons saturate the centre");
    }
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    let b = &sim.truth()[0];
    let expected = MAX_FLUX_HZ * 3.0 * MAX_FRAME_PERIOD_S;
    assert!(
        b.photons_emitted as f64 > 0.999 * expected
            && (b.photons_emitted as f64) < 1.001 * expected
    );
    // The whole PSF is in the field: detected ≈ QE × emitted.
    let ratio = b.photons_detected as f64 / b.photons_emitted as f64;
    assert!(
        (ratio - cam.qe).abs() < 0.01 * cam.qe,
        "{ratio} vs QE {}",
        cam.qe
    );
}

#[test]
fn per_pixel_sampling_keeps_the_photon_statistics() {
    // Just above and below the switch to per-pixel sampling, the detected
    // photons agree with flux × time × QE × (fraction in the field).
    let (p, mut cam) = emccd();
    cam.em_gain = 1.0;
    for flux in [1.5e6, 3e6] {
        let sc = one_blink(&p, &cam, flux, 100.0);
        let mut sim = EmccdSimulator::new(&cam, &sc, 11).unwrap();
        let frames = 40;
        for _ in 0..frames {
            sim.next_frame();
        }
        let b = &sim.truth()[0];
        let mean = flux * frames as f64 * cam.exposure_s * cam.qe;
        let z = (b.photons_detected as f64 - mean) / mean.sqrt();
        assert!(
            z.abs() < 6.0,
            "flux {flux}: {} vs {mean}",
            b.photons_detected
        );
    }
}

#[test]
fn a_vanishing_intensity_spread_does_not_panic() {
    let (p, cam) = emccd();
    let mut sc = Scene::smlm(&p).with_field(16, 16);
    for cv in [1e-320, f64::MIN_POSITIVE, 1e-9] {
        sc.intensity_cv = cv;
        let mut sim = EmccdSimulator::new(&cam, &sc, 1).unwrap();
        for _ in 0..3 {
            let f = sim.next_frame();
            assert!(f.electrons.iter().all(|e| e.is_finite()));
        }
    }
}

#[test]
fn absurd_light_and_frame_periods_are_refused_with_the_limit() {
    let (p, mut cam) = emccd();
    let e = EmccdSimulator::new(&cam, &one_blink(&p, &cam, 1e300, 1.0), 1)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("flux_hz") && e.contains("1e300") && e.contains("..= 1e9"),
        "{e}"
    );
    cam.frame_period_s = 1e305;
    cam.exposure_s = 1e305;
    let e = EmccdSimulator::new(&cam, &one_blink(&p, &cam, 1e4, 1.0), 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame_period_s") && e.contains("..= 100"), "{e}");
}
