//! Impossible parameters are refused with the parameter's name; extremes stay
//! exact and finite.

use smartagg_model::params::{spcimager, Camera, Preset, PresetName, SceneLight, SpadCamera};
use smartagg_model::recording::{BitOrder, RecordingReader, RecordingWriter};
use smartagg_scene::{
    Blinking, EmccdSimulator, ExplicitBlink, Layout, OnTime, Position, Scene, ScmosSimulator,
    SpadSimulator,
};

fn spad_preset() -> (Preset, SpadCamera) {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(c) = p.camera.clone() else {
        unreachable!()
    };
    (p, c)
}

fn err_spad(cam: &SpadCamera, sc: &Scene) -> String {
    SpadSimulator::new(cam, sc, 1).unwrap_err().to_string()
}

#[test]
fn impossible_parameters_name_the_parameter() {
    let (p, cam) = spad_preset();
    let base = Scene::study(&p, 0.03);

    let mut sc = base.clone();
    sc.light.flux_hz = -5.0;
    assert!(err_spad(&cam, &sc).contains("`flux_hz`"));

    let mut sc = base.clone();
    sc.light.background_per_um2_hz = f64::NAN;
    assert!(err_spad(&cam, &sc).contains("`background_per_um2_hz`"));

    let mut sc = base.clone();
    sc.optics.na = 1.6;
    let e = err_spad(&cam, &sc);
    assert!(e.contains("`na`") && e.contains("refractive index"), "{e}");

    let mut bad = cam.clone();
    bad.pixel_pitch_um = 0.0;
    assert!(err_spad(&bad, &base).contains("`pixel_pitch_um`"));

    let e = err_spad(&cam, &base.clone().with_field(400, 32));
    assert!(e.contains("`width` = 400") && e.contains("320"), "{e}");
    let e = err_spad(&cam, &base.clone().with_field(32, 0));
    assert!(e.contains("`height`"), "{e}");

    let mut sc = base.clone();
    sc.blinking = Blinking::OneAtATime {
        on: OnTime::Fixed { seconds: 0.0 },
        gap_min_s: 0.0,
        gap_mean_s: 0.01,
    };
    assert!(err_spad(&cam, &sc).contains("blink duration"));

    let mut sc = Scene::smlm(&p);
    sc.layout = Layout::Random {
        density_per_um2: -1.0,
    };
    assert!(err_spad(&cam, &sc).contains("`density_per_um2`"));

    let mut sc = base.clone();
    sc.blinking = Blinking::Explicit(vec![ExplicitBlink {
        emitter: 0,
        position: Position {
            x_nm: 1.0,
            y_nm: 1.0,
        },
        t_on_s: 1.0,
        t_off_s: 0.5,
        flux_factor: 1.0,
    }]);
    assert!(err_spad(&cam, &sc).contains("`t_off_s`"));

    let mut bad = cam.clone();
    bad.exposure_s = 2.0 * bad.plane_period_s;
    assert!(err_spad(&bad, &base).contains("`exposure_s`"));

    // Maps of the wrong size.
    let maps = smartagg_scene::uniform_maps(&cam, 8, 8);
    let e = SpadSimulator::with_maps(&cam, &base, maps, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("maps"), "{e}");

    // Frame cameras check the same things.
    let pe = Preset::new(PresetName::Emccd, 150).unwrap();
    let Camera::Emccd(mut ce) = pe.camera.clone() else {
        unreachable!()
    };
    ce.em_gain = 0.5;
    let e = EmccdSimulator::new(&ce, &Scene::study(&pe, 0.03), 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`em_gain`"), "{e}");
    let ps = Preset::new(PresetName::Scmos, 150).unwrap();
    let Camera::Scmos(cs) = ps.camera.clone() else {
        unreachable!()
    };
    let e = ScmosSimulator::new(&cs, &Scene::study(&ps, 0.03).with_field(4096, 8), 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`width`"), "{e}");
}

fn dark_scene(
    p: &Preset,
    w: u32,
    h: u32,
    blinks: Vec<ExplicitBlink>,
    flux_hz: f64,
    bg: f64,
) -> Scene {
    Scene {
        width: w,
        height: h,
        optics: p.optics,
        light: SceneLight {
            flux_hz,
            background_per_um2_hz: bg,
        },
        layout: Layout::List(vec![]),
        blinking: Blinking::Explicit(blinks),
        intensity_cv: 0.0,
        margin_px: 0.0,
    }
}

#[test]
fn i_tau_1e4_with_perfect_detection_saturates_every_footprint_bit() {
    let (p, mut cam) = spad_preset();
    cam.pde = 1.0;
    cam.fill_factor = 1.0;
    cam.prnu = 0.0;
    let pn = p.pixel_nm();
    let blink = ExplicitBlink {
        emitter: 0,
        position: Position {
            x_nm: 8.5 * pn,
            y_nm: 8.5 * pn,
        },
        t_on_s: 0.0,
        t_off_s: 1.0,
        flux_factor: 1.0,
    };
    let sc = dark_scene(&p, 17, 17, vec![blink], 1e4 / cam.exposure_s, 70_000.0);
    let mut sim = SpadSimulator::new(&cam, &sc, 3).unwrap();
    for _ in 0..200 {
        let plane = sim.next_plane();
        // Within 2σ (≈ 3 px) every pixel gets ≥ 1e4·G ≫ 1 photons: always 1.
        for y in 6..=10 {
            for x in 6..=10 {
                assert!(plane.get(x, y), "({x},{y})");
            }
        }
    }
    let b = &sim.truth()[0];
    assert!(b.photons_detected > 200 * 9_000 && b.photons_detected <= b.photons_emitted);
    assert!((b.on_exposed_s - 200.0 * cam.exposure_s).abs() < 1e-12);
}

#[test]
fn zero_background_and_zero_dark_give_only_molecule_bits() {
    let (p, mut cam) = spad_preset();
    cam.dcr_median_hz = 0.0;
    let sc = dark_scene(&p, 32, 32, vec![], 0.0, 0.0);
    let mut sim = SpadSimulator::new(&cam, &sc, 3).unwrap();
    for _ in 0..10_000 {
        assert_eq!(sim.next_plane().count_ones(), 0);
    }
    assert!(sim.background_rate_hz().iter().all(|&r| r == 0.0));
}

#[test]
fn background_too_low_for_one_jump_to_land() {
    let (p, mut cam) = spad_preset();
    // p ≈ 1e-310 per pixel-plane: a subnormal probability.
    cam.dcr_median_hz = 1e-306;
    let sc = dark_scene(&p, 320, 240, vec![], 0.0, 0.0);
    let mut sim = SpadSimulator::new(&cam, &sc, 3).unwrap();
    for _ in 0..1000 {
        assert_eq!(sim.next_plane().count_ones(), 0);
    }
    // A merely low rate still produces the right number of ones:
    // 0.5 Hz × 100 µs = 5e-5 per pixel-plane, 64×64 × 20,000 planes → 4,096.
    cam.dcr_median_hz = 0.5;
    let sc = dark_scene(&p, 64, 64, vec![], 0.0, 0.0);
    let mut sim = SpadSimulator::new(&cam, &sc, 4).unwrap();
    let expected: f64 = sim
        .background_rate_hz()
        .iter()
        .map(|&r| -(-r * cam.exposure_s).exp_m1())
        .sum::<f64>()
        * 20_000.0;
    let ones: usize = (0..20_000).map(|_| sim.next_plane().count_ones()).sum();
    let z = (ones as f64 - expected) / expected.sqrt();
    assert!(z.abs() < 5.0, "{ones} vs {expected}");
}

#[test]
fn recordings_longer_than_2_pow_32_pixel_planes() {
    // A 2048×2048 sensor: 1025 planes are 4.3e9 pixel-planes.
    let cam = SpadCamera {
        width: 2048,
        height: 2048,
        dcr_median_hz: 1.0,
        ..spcimager()
    };
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let sc = dark_scene(&p, 2048, 2048, vec![], 0.0, 0.0);
    let mut sim = SpadSimulator::new(&cam, &sc, 9).unwrap();
    let planes = 1025u64;
    let header = sim.recording_header(planes, BitOrder::MsbFirst);
    // Count what the container carries rather than keeping 537 MB.
    struct Count(u64);
    impl std::io::Write for Count {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0 += b.len() as u64;
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let mut w = RecordingWriter::new(Count(0), header).unwrap();
    let mut ones = 0u64;
    for _ in 0..planes {
        let plane = sim.next_plane();
        ones += plane.count_ones() as u64;
        w.write_plane(&plane).unwrap();
    }
    let bytes = w.finish().unwrap().0;
    assert_eq!(sim.pixel_planes_done(), planes * 2048 * 2048);
    assert!(sim.pixel_planes_done() > 1 << 32);
    assert_eq!(bytes, 48 + planes * 2048 * 2048 / 8);
    let expected: f64 = sim
        .background_rate_hz()
        .iter()
        .map(|&r| -(-r * cam.exposure_s).exp_m1())
        .sum::<f64>()
        * planes as f64;
    let z = (ones as f64 - expected) / expected.sqrt();
    assert!(z.abs() < 5.0, "{ones} vs {expected}");
    assert!((sim.time_s() - planes as f64 * cam.plane_period_s).abs() < 1e-12);
}

#[test]
fn simulated_planes_survive_the_container() {
    let (p, cam) = spad_preset();
    let sc = Scene::smlm(&p).with_field(40, 30);
    let mut sim = SpadSimulator::new(&cam, &sc, 77).unwrap();
    let planes: Vec<_> = (0..50).map(|_| sim.next_plane()).collect();
    for order in [BitOrder::LsbFirst, BitOrder::MsbFirst] {
        let mut w = RecordingWriter::new(Vec::new(), sim.recording_header(50, order)).unwrap();
        for pl in &planes {
            w.write_plane(pl).unwrap();
        }
        let bytes = w.finish().unwrap();
        let r = RecordingReader::open(&bytes[..]).unwrap();
        assert_eq!(r.header().plane_period_ns, 100_000);
        let back: Vec<_> = r.map(|x| x.unwrap()).collect();
        assert_eq!(back, planes);
    }
}
