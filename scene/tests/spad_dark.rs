//! A dark-only SPAD recording of 10⁶ bit-planes recovers the DCR map and its
//! DRNU from the between-pixel spread (16×16 field of the SPCImager: 2 % DRNU,
//! 100 Hz median DCR, 100 µs planes).

use smartagg_model::params::{spcimager, Preset, PresetName, SceneLight};
use smartagg_scene::{Blinking, Layout, OnTime, Scene, SpadSimulator};

#[test]
fn a_million_dark_planes_recover_the_dcr_map_and_its_drnu() {
    let cam = spcimager();
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let scene = Scene {
        width: 16,
        height: 16,
        optics: p.optics,
        light: SceneLight {
            flux_hz: 0.0,
            background_per_um2_hz: 0.0,
        },
        layout: Layout::List(vec![]),
        blinking: Blinking::Independent {
            on: OnTime::Fixed { seconds: 0.01 },
            mean_off_s: 1.0,
        },
        intensity_cv: 0.0,
        margin_px: 0.0,
    };
    let mut sim = SpadSimulator::new(&cam, &scene, 2024).unwrap();
    let n = 256usize;
    let planes = 1_000_000u64;
    let mut counts = vec![0u64; n];
    for _ in 0..planes {
        for i in sim.next_plane().bits().iter_ones() {
            counts[i] += 1;
        }
    }
    let tau = cam.exposure_s;
    let truth = sim.maps().dcr_hz.clone();

    // 1. Every pixel's count agrees with its own DCR (binomial z-scores).
    let mut chi2 = 0.0;
    let mut max_z: f64 = 0.0;
    for i in 0..n {
        let p = -(-truth[i] * tau).exp_m1();
        let z = (counts[i] as f64 - planes as f64 * p) / (planes as f64 * p * (1.0 - p)).sqrt();
        chi2 += z * z;
        max_z = max_z.max(z.abs());
    }
    let chi2_k = chi2 / n as f64;
    eprintln!("max |z| {max_z:.2}, chi2/k {chi2_k:.3}");
    assert!(max_z < 5.0, "max |z| = {max_z}");
    assert!(
        chi2_k < 1.0 + 5.0 * (2.0 / n as f64).sqrt(),
        "chi2/k = {chi2_k}"
    );

    // 2. The DCR map estimated from the counts (inverting the pile-up).
    let est: Vec<f64> = counts
        .iter()
        .map(|&c| -(-(c as f64) / planes as f64).ln_1p() / tau)
        .collect();
    let median = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        0.5 * (s[n / 2 - 1] + s[n / 2])
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let var = |v: &[f64]| {
        let m = mean(v);
        v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64
    };
    let med_est = median(&est);
    eprintln!(
        "median DCR estimated {med_est:.2} Hz (camera {} Hz)",
        cam.dcr_median_hz
    );
    assert!(
        (med_est / cam.dcr_median_hz - 1.0).abs() < 0.01,
        "{med_est}"
    );

    // The map is recovered pixel by pixel: estimate and truth correlate.
    let (me, mt) = (mean(&est), mean(&truth));
    let cov: f64 = est
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a - me) * (b - mt))
        .sum::<f64>()
        / (n - 1) as f64;
    let corr = cov / (var(&est) * var(&truth)).sqrt();
    eprintln!("correlation estimated/true DCR map: {corr:.3}");
    assert!(corr > 0.8, "{corr}");

    // 3. DRNU from the between-pixel spread, less the counting noise.
    let noise_var = mean(
        &est.iter()
            .map(|&l| {
                let p = -(-l * tau).exp_m1();
                p / ((1.0 - p) * planes as f64 * tau * tau)
            })
            .collect::<Vec<_>>(),
    );
    let drnu_est = (var(&est) - noise_var).max(0.0).sqrt() / med_est;
    let drnu_map = var(&truth).sqrt() / median(&truth);
    eprintln!(
        "DRNU: estimated {drnu_est:.4}, map {drnu_map:.4}, camera {}",
        cam.drnu
    );
    assert!(
        (drnu_est / drnu_map - 1.0).abs() < 0.15,
        "{drnu_est} vs map {drnu_map}"
    );
    assert!(
        (drnu_est / cam.drnu - 1.0).abs() < 0.25,
        "{drnu_est} vs camera {}",
        cam.drnu
    );
}
