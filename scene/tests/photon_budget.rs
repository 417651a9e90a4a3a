//! Photons per blink: detected = flux × η × exposed on-time × (PSF fraction
//! inside the field), for the three cameras, including the EMCCD's read-out
//! dead time. The expected values are computed here independently: the
//! in-field fraction by Simpson integration of the Gaussian density (no erf)
//! and the exposed on-time by summing the overlap with every exposure window.

use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_scene::{BlinkTruth, EmccdSimulator, Scene, ScmosSimulator, SpadSimulator};

/// Fraction of N(c, σ²) in [0, len] by composite Simpson (4000 intervals).
fn simpson_fraction(c: f64, sigma: f64, len: f64) -> f64 {
    let m = 4000;
    let h = len / m as f64;
    let f = |x: f64| {
        (-(x - c) * (x - c) / (2.0 * sigma * sigma)).exp()
            / (sigma * (2.0 * std::f64::consts::PI).sqrt())
    };
    let mut s = f(0.0) + f(len);
    for k in 1..m {
        s += f(k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

fn exposed(b: &BlinkTruth, frames: u64, period: f64, exposure: f64) -> f64 {
    (0..frames)
        .map(|k| {
            let t0 = k as f64 * period;
            (b.t_off_s.min(t0 + exposure) - b.t_on_s.max(t0)).max(0.0)
        })
        .sum()
}

/// Checks every blink and the total; returns (blinks checked, total z).
fn check_blinks(
    truth: &[BlinkTruth],
    frames: u64,
    period: f64,
    exposure: f64,
    eta: f64,
    sigma_nm: f64,
    field_nm: f64,
) -> (usize, f64) {
    let (mut det, mut exp_det, mut em, mut exp_em) = (0.0, 0.0, 0.0, 0.0);
    for b in truth {
        let on = exposed(b, frames, period, exposure);
        assert!(
            (b.on_exposed_s - on).abs() < 1e-9,
            "blink {}: {} vs {on}",
            b.blink,
            b.on_exposed_s
        );
        let frac = simpson_fraction(b.x_nm, sigma_nm, field_nm)
            * simpson_fraction(b.y_nm, sigma_nm, field_nm);
        let e = b.flux_hz * on * eta * frac;
        if e == 0.0 {
            assert_eq!(b.photons_detected, 0);
            assert_eq!(b.photons_emitted, 0);
            continue;
        }
        let z = (b.photons_detected as f64 - e) / e.sqrt();
        assert!(
            z.abs() < 5.0,
            "blink {}: detected {} expected {e:.1}",
            b.blink,
            b.photons_detected
        );
        assert!(b.photons_detected <= b.photons_emitted);
        det += b.photons_detected as f64;
        exp_det += e;
        em += b.photons_emitted as f64;
        exp_em += b.flux_hz * on;
    }
    let z_em = (em - exp_em) / exp_em.sqrt();
    assert!(z_em.abs() < 4.0, "emitted {em} vs {exp_em}");
    let z = (det - exp_det) / exp_det.sqrt();
    eprintln!("detected {det} vs expected {exp_det:.1} (z = {z:.2}); emitted {em} vs {exp_em:.1}");
    assert!(z.abs() < 4.0, "total detected {det} vs {exp_det}");
    (truth.len(), z)
}

#[test]
fn spad_photons_per_blink() {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(cam) = &p.camera else {
        unreachable!()
    };
    // No margin: blinks near and on the edge lose part of their PSF.
    let scene = Scene {
        margin_px: 0.0,
        ..Scene::study(&p, 0.02)
    };
    let maps = smartagg_scene::uniform_maps(cam, scene.width, scene.height);
    let mut sim = SpadSimulator::with_maps(cam, &scene, maps, 5).unwrap();
    let planes = 40_000;
    for _ in 0..planes {
        sim.next_plane();
    }
    let field_nm = scene.width as f64 * sim.pixel_nm();
    let (n, _) = check_blinks(
        sim.truth(),
        planes,
        cam.plane_period_s,
        cam.exposure_s,
        cam.eta(),
        scene.optics.psf_sigma_nm(),
        field_nm,
    );
    assert!(n > 40, "{n} blinks");
    // Some blinks really lose light over the edge.
    let near_edge = sim
        .truth()
        .iter()
        .filter(|b| {
            b.x_nm
                .min(b.y_nm)
                .min(field_nm - b.x_nm)
                .min(field_nm - b.y_nm)
                < 60.0
        })
        .count();
    assert!(near_edge > 0);
}

#[test]
fn emccd_photons_per_blink_with_dead_time() {
    let p = Preset::new(PresetName::Emccd, 150).unwrap();
    let Camera::Emccd(mut cam) = p.camera.clone() else {
        unreachable!()
    };
    // The paper's experiment: 64 ms frames, 30 ms read-out dead time.
    cam.frame_period_s = 0.064;
    cam.exposure_s = 0.034;
    let scene = Scene {
        margin_px: 0.0,
        ..Scene::study(&p, 0.02)
    };
    let mut sim = EmccdSimulator::new(&cam, &scene, 6).unwrap();
    let frames = 400;
    for _ in 0..frames {
        sim.next_frame();
    }
    let field_nm = scene.width as f64 * sim.pixel_nm();
    let (n, _) = check_blinks(
        sim.truth(),
        frames,
        cam.frame_period_s,
        cam.exposure_s,
        cam.qe,
        scene.optics.psf_sigma_nm(),
        field_nm,
    );
    assert!(n > 100);
    // Dead time matters: some blinks were entirely lost, some cut.
    let lost = sim
        .truth()
        .iter()
        .filter(|b| b.on_exposed_s == 0.0 && b.t_off_s < 25.0)
        .count();
    let cut = sim
        .truth()
        .iter()
        .filter(|b| {
            b.on_exposed_s > 0.0 && b.on_exposed_s < b.duration_s() - 1e-9 && b.t_off_s < 25.0
        })
        .count();
    assert!(lost > 0 && cut > 0, "lost {lost}, cut {cut}");
}

#[test]
fn scmos_photons_per_blink() {
    let p = Preset::new(PresetName::Scmos, 150).unwrap();
    let Camera::Scmos(mut cam) = p.camera.clone() else {
        unreachable!()
    };
    cam.prnu = 0.0;
    let scene = Scene {
        margin_px: 0.0,
        ..Scene::study(&p, 0.03)
    };
    let mut sim = ScmosSimulator::new(&cam, &scene, 7).unwrap();
    let frames = 300;
    for _ in 0..frames {
        sim.next_frame();
    }
    let field_nm = scene.width as f64 * sim.pixel_nm();
    let (n, _) = check_blinks(
        sim.truth(),
        frames,
        cam.frame_period_s,
        cam.exposure_s,
        cam.qe,
        scene.optics.psf_sigma_nm(),
        field_nm,
    );
    assert!(n > 100);
}
