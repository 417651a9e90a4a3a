//! Emitter layouts and blinking statistics seen through the ground truth.

use smartagg_model::params::{spcimager, Camera, Preset, PresetName, SpadCamera};
use smartagg_scene::{Blinking, Layout, OnTime, Scene, SpadSimulator};

/// A SPAD camera with 1 ms planes: long scenes in few planes.
fn slow_camera() -> SpadCamera {
    SpadCamera {
        plane_period_s: 1e-3,
        exposure_s: 1e-3,
        ..spcimager()
    }
}

#[test]
fn independent_kinetics_have_the_stated_means_and_occupancy() {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let cam = slow_camera();
    let mut sc = Scene::smlm(&p).with_field(64, 64);
    sc.blinking = Blinking::Independent {
        on: OnTime::Exponential { mean_s: 0.030 },
        mean_off_s: 0.5,
    };
    let mut sim = SpadSimulator::new(&cam, &sc, 31).unwrap();
    // Emitters: Poisson(density × area).
    let area = (64.0 * p.pixel_nm() / 1000.0).powi(2);
    let mean_n = 50.0 * area;
    let n = sim.emitters().len() as f64;
    assert!((n - mean_n).abs() < 5.0 * mean_n.sqrt(), "{n} vs {mean_n}");
    let span = 20.0;
    let planes = (span / cam.plane_period_s) as u64;
    for _ in 0..planes {
        sim.next_plane();
    }
    let truth = sim.truth();
    // Occupancy: time-averaged number on ≈ n · 30/(30 + 500).
    let on_time: f64 = truth.iter().map(|b| b.on_exposed_s).sum();
    let occupancy = on_time / span;
    let expected = n * 0.030 / 0.530;
    eprintln!(
        "{n} emitters, {} blinks, occupancy {occupancy:.2} (expected {expected:.2})",
        truth.len()
    );
    // The time average over 20 s fluctuates by ≈ √(2·E·τ_c/T) with τ_c ≈ 28 ms.
    let sd = (2.0 * expected * 0.028 / span).sqrt();
    assert!((occupancy - expected).abs() < 5.0 * sd, "sd {sd}");
    // Blinks that started after 0 and ended before the end: mean on ≈ 30 ms.
    let done: Vec<f64> = truth
        .iter()
        .filter(|b| b.t_on_s >= 0.0 && b.t_off_s < span - 1.0)
        .map(|b| b.duration_s())
        .collect();
    let m = done.iter().sum::<f64>() / done.len() as f64;
    assert!(
        (m - 0.030).abs() < 5.0 * 0.030 / (done.len() as f64).sqrt(),
        "{m}"
    );
    // Off times between consecutive blinks of one emitter: mean 0.5 s, never negative.
    let mut by_emitter: Vec<Vec<(f64, f64)>> = vec![Vec::new(); n as usize];
    for b in truth {
        by_emitter[b.emitter as usize].push((b.t_on_s, b.t_off_s));
    }
    let mut offs = Vec::new();
    for v in &by_emitter {
        for w in v.windows(2) {
            assert!(w[1].0 >= w[0].1, "an emitter's blinks overlap");
            offs.push(w[1].0 - w[0].1);
        }
    }
    let mo = offs.iter().sum::<f64>() / offs.len() as f64;
    assert!(
        (mo - 0.5).abs() < 5.0 * 0.5 / (offs.len() as f64).sqrt(),
        "{mo}"
    );
    // Blinks on at t = 0 started before the recording.
    assert!(truth.iter().any(|b| b.t_on_s < 0.0));
}

#[test]
fn one_at_a_time_blinks_never_overlap_and_last_exactly() {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(cam) = &p.camera else {
        unreachable!()
    };
    let sc = Scene::study(&p, 0.012);
    let mut sim = SpadSimulator::new(cam, &sc, 8).unwrap();
    // 6 s: about 6 / (12 + 10 + 40 ms) = 97 blinks.
    for _ in 0..60_000 {
        sim.next_plane();
    }
    let t = sim.truth();
    assert!(t.len() > 60, "{}", t.len());
    let margin_nm = sc.margin_px * sim.pixel_nm();
    let side_nm = sc.width as f64 * sim.pixel_nm();
    let mut gaps = Vec::new();
    for w in t.windows(2) {
        let gap = w[1].t_on_s - w[0].t_off_s;
        assert!(gap >= 0.010 - 1e-12, "gap {gap}");
        gaps.push(gap);
    }
    for b in t {
        assert!((b.duration_s() - 0.012).abs() < 1e-12);
        assert!(b.x_nm >= margin_nm && b.x_nm <= side_nm - margin_nm);
        assert!(b.y_nm >= margin_nm && b.y_nm <= side_nm - margin_nm);
        assert_eq!(b.flux_hz, sc.light.flux_hz);
    }
    let mg = gaps.iter().sum::<f64>() / gaps.len() as f64;
    assert!(
        (mg - 0.050).abs() < 5.0 * 0.040 / (gaps.len() as f64).sqrt(),
        "{mg}"
    );
}

#[test]
fn nanorulers_are_three_markers_80_nm_apart_on_a_line() {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(cam) = &p.camera else {
        unreachable!()
    };
    let sim = SpadSimulator::new(cam, &Scene::nanorulers(&p), 12).unwrap();
    let e = sim.emitters();
    assert!(
        e.len() >= 3 * 50 && e.len().is_multiple_of(3),
        "{}",
        e.len()
    );
    let mut angles = Vec::new();
    for r in e.chunks(3) {
        let d = |a: usize, b: usize| {
            ((r[a].x_nm - r[b].x_nm).powi(2) + (r[a].y_nm - r[b].y_nm).powi(2)).sqrt()
        };
        assert!((d(0, 1) - 80.0).abs() < 1e-9 && (d(1, 2) - 80.0).abs() < 1e-9);
        assert!((d(0, 2) - 160.0).abs() < 1e-9, "collinear");
        angles.push((r[2].y_nm - r[0].y_nm).atan2(r[2].x_nm - r[0].x_nm));
    }
    // Orientations are spread, not all the same.
    let spread = angles.iter().cloned().fold(f64::MIN, f64::max)
        - angles.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread > 2.5, "{spread}");
}

#[test]
fn intensity_variation_per_blink() {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let cam = slow_camera();
    let mut sc = Scene::study(&p, 0.005);
    sc.intensity_cv = 0.3;
    let mut sim = SpadSimulator::new(&cam, &sc, 2).unwrap();
    for _ in 0..30_000 {
        sim.next_plane();
    }
    let f: Vec<f64> = sim
        .truth()
        .iter()
        .map(|b| b.flux_hz / sc.light.flux_hz)
        .collect();
    let n = f.len() as f64;
    let m = f.iter().sum::<f64>() / n;
    let cv = (f.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0)).sqrt() / m;
    eprintln!("{n} blinks: mean factor {m:.3}, cv {cv:.3}");
    assert!(n > 400.0);
    assert!((m - 1.0).abs() < 5.0 * 0.3 / n.sqrt());
    assert!((cv - 0.3).abs() < 0.05);
    assert!(f.iter().all(|&x| x > 0.0 && x.is_finite()));
}

#[test]
fn a_user_list_blinks_one_at_a_time() {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let cam = slow_camera();
    let mut sc = Scene::study(&p, 0.01);
    let pts = vec![
        smartagg_scene::Position {
            x_nm: 500.0,
            y_nm: 600.0,
        },
        smartagg_scene::Position {
            x_nm: 1200.0,
            y_nm: 900.0,
        },
    ];
    sc.layout = Layout::List(pts.clone());
    let mut sim = SpadSimulator::new(&cam, &sc, 2).unwrap();
    for _ in 0..5000 {
        sim.next_plane();
    }
    let t = sim.truth();
    assert!(t.len() > 50);
    for b in t {
        let q = pts[b.emitter as usize];
        assert_eq!((b.x_nm, b.y_nm), (q.x_nm, q.y_nm));
    }
    assert!(t.iter().any(|b| b.emitter == 0) && t.iter().any(|b| b.emitter == 1));
}
