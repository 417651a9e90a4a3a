//! EMCCD excess noise and clipping; sCMOS offset and read-noise maps
//! recovered from dark stacks.

use smartagg_model::params::{Camera, Preset, PresetName, SceneLight};
use smartagg_scene::{Blinking, EmccdSimulator, Layout, OnTime, Scene, ScmosSimulator};

/// A field with no molecules and the given background.
fn empty_scene(p: &Preset, side: u32, background_per_um2_hz: f64) -> Scene {
    Scene {
        width: side,
        height: side,
        optics: p.optics,
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

fn mean_var(v: &[f64]) -> (f64, f64) {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64;
    (m, var)
}

/// Excess noise factor measured from ADU: F² = (Var(e) − σ_read² − q²/12) / (g² μ_in).
fn measured_enf(gain: f64, read_noise_e: f64) -> (f64, f64) {
    let p = Preset::new(PresetName::Emccd, 150).unwrap();
    let Camera::Emccd(mut cam) = p.camera.clone() else {
        unreachable!()
    };
    cam.em_gain = gain;
    cam.read_noise_e = read_noise_e;
    // Keep the output well inside 16 bits: ≈ 5 e⁻ in × g out.
    cam.e_per_adu = (gain / 20.0).max(0.25);
    cam.offset_adu = 500.0;
    // Background giving ≈ 5 input electrons per pixel per frame.
    let px_um2 = (p.pixel_nm() / 1000.0).powi(2);
    let bg = 5.0 / (cam.qe * cam.exposure_s * px_um2);
    let scene = empty_scene(&p, 64, bg);
    let mut sim = EmccdSimulator::new(&cam, &scene, 42).unwrap();
    let mu_in = sim.mean_background_electrons();
    let mut e = Vec::new();
    for _ in 0..60 {
        let f = sim.next_frame();
        assert_eq!(f.clipped, 0);
        e.extend(
            f.adu
                .iter()
                .map(|&a| (a as f64 - cam.offset_adu) * cam.e_per_adu),
        );
    }
    let (m, var) = mean_var(&e);
    let read_var = (read_noise_e * gain).powi(2);
    let q_var = cam.e_per_adu * cam.e_per_adu / 12.0;
    let f2 = (var - read_var - q_var) / (gain * gain * mu_in);
    (f2.sqrt(), m / (gain * mu_in))
}

#[test]
fn emccd_excess_noise_factor_tends_to_sqrt2_at_high_gain() {
    for (gain, rn) in [(300.0, 0.2), (1000.0, 0.0)] {
        let (f, gain_ratio) = measured_enf(gain, rn);
        let expected = (2.0 - 1.0 / gain).sqrt();
        eprintln!("gain {gain}: F = {f:.4} (model {expected:.4}, sqrt 2 = 1.4142), mean/(g mu) = {gain_ratio:.4}");
        assert!((f - std::f64::consts::SQRT_2).abs() < 0.02, "F = {f}");
        assert!((gain_ratio - 1.0).abs() < 0.01, "{gain_ratio}");
    }
    // Without multiplication there is no excess noise; at g = 2, F² = 1.5.
    let (f1, _) = measured_enf(1.0, 0.0);
    assert!((f1 - 1.0).abs() < 0.02, "F(g=1) = {f1}");
    let (f2, _) = measured_enf(2.0, 0.0);
    assert!((f2 - 1.5f64.sqrt()).abs() < 0.02, "F(g=2) = {f2}");
}

#[test]
fn emccd_clipping_is_counted_not_silent() {
    let p = Preset::new(PresetName::Emccd, 150).unwrap();
    let Camera::Emccd(mut cam) = p.camera.clone() else {
        unreachable!()
    };
    cam.em_gain = 1000.0;
    cam.e_per_adu = 1.0;
    let px_um2 = (p.pixel_nm() / 1000.0).powi(2);
    let scene = empty_scene(&p, 32, 100.0 / (cam.qe * cam.exposure_s * px_um2));
    let mut sim = EmccdSimulator::new(&cam, &scene, 3).unwrap();
    let f = sim.next_frame();
    let at_max = f.adu.iter().filter(|&&a| a == 65535).count() as u32;
    assert!(f.clipped > 100, "{}", f.clipped);
    assert_eq!(f.clipped, at_max);
    assert_eq!(sim.clipped_total(), f.clipped as u64);
    assert!(f.electrons.iter().all(|e| e.is_finite() && *e >= 0.0));
}

#[test]
fn scmos_offset_and_read_noise_maps_recovered_from_dark_stacks() {
    let p = Preset::new(PresetName::Scmos, 150).unwrap();
    let Camera::Scmos(cam) = p.camera.clone() else {
        unreachable!()
    };
    let scene = empty_scene(&p, 16, 0.0);
    let mut sim = ScmosSimulator::new(&cam, &scene, 8).unwrap();
    let n = 256;
    let frames = 3000;
    let mut sum = vec![0.0; n];
    let mut sum2 = vec![0.0; n];
    for _ in 0..frames {
        let f = sim.next_frame();
        for i in 0..n {
            let a = f.adu[i] as f64;
            sum[i] += a;
            sum2[i] += a * a;
        }
    }
    let m = sim.maps().clone();
    let nf = frames as f64;
    let (mut off_err, mut rn_err) = (Vec::new(), Vec::new());
    let (mut rn_est_all, mut rn_true_all) = (Vec::new(), Vec::new());
    for i in 0..n {
        let mean = sum[i] / nf;
        let var = (sum2[i] - sum[i] * sum[i] / nf) / (nf - 1.0);
        let g = m.gain_adu_per_e[i];
        let dark_e = m.dark_e_per_s[i] * cam.frame_period_s;
        // Offset: mean ADU less the (tiny) dark signal.
        let offset_est = mean - g * dark_e;
        let sd_mean = (var / nf).sqrt();
        off_err.push((offset_est - m.offset_adu[i]) / sd_mean);
        // Read noise: variance less quantisation (1/12 ADU²) and dark shot noise.
        let rn_est = ((var - 1.0 / 12.0) / (g * g) - dark_e).max(0.0).sqrt();
        // Relative sd of a sample standard deviation: 1/sqrt(2(n−1)).
        rn_err.push((rn_est / m.read_noise_e[i] - 1.0) * (2.0 * (nf - 1.0)).sqrt());
        rn_est_all.push(rn_est);
        rn_true_all.push(m.read_noise_e[i]);
    }
    let max_abs = |v: &[f64]| v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    eprintln!(
        "offset max |z| {:.2}, read noise max |z| {:.2}",
        max_abs(&off_err),
        max_abs(&rn_err)
    );
    assert!(max_abs(&off_err) < 5.0);
    assert!(max_abs(&rn_err) < 5.5);
    // The maps are non-trivial: offsets spread by ~2 ADU, read noise by ~30 %.
    let (_, v_off) = mean_var(&m.offset_adu);
    assert!(v_off.sqrt() > 1.0);
    let (rn_mean, rn_var) = mean_var(&rn_true_all);
    assert!(rn_var.sqrt() / rn_mean > 0.15);
    let (_, v_est) = mean_var(&rn_est_all);
    assert!((v_est.sqrt() / rn_var.sqrt() - 1.0).abs() < 0.1);
}
