//! `smartagg calibrate` end to end: recordings from the scene simulator with
//! known maps are written to disk, the command calibrates them, and the
//! calibration directory is read back here with plain TOML/TIFF readers, as
//! any other tool would (the format is the contract, not the Rust types).

use std::collections::BTreeSet;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use smartagg_io::stack::StackWriter;
use smartagg_model::params::{spcimager, Camera, Preset, PresetName, SceneLight, SpadCamera};
use smartagg_model::recording::{pack_plane, BitOrder, RecordingWriter};
use smartagg_model::sensor_maps::SensorMaps;
use smartagg_scene::{
    generate_maps, Blinking, Layout, OnTime, Scene, ScmosSimulator, SpadSimulator,
};

const W: u32 = 16;

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

/// SPCImager with 30 % DRNU, 5 % PRNU and 5 % hot pixels at 5 kHz.
fn camera() -> SpadCamera {
    SpadCamera {
        drnu: 0.3,
        prnu: 0.05,
        hot_pixel_fraction: 0.05,
        hot_pixel_dcr_hz: 5000.0,
        ..spcimager()
    }
}

/// Writes `planes` simulated planes of `maps` to a .spad file (and, with
/// `raw`, the same planes headerless to a second file).
fn record(path: &Path, maps: &SensorMaps, light: f64, planes: u64, seed: u64, raw: Option<&Path>) {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    record_scene(path, &empty_scene(&p, W, light), maps, planes, seed, raw);
}

/// Writes `planes` simulated planes of `scene` seen through `maps` to a
/// .spad file (and, with `raw`, headerless to a second file).
fn record_scene(
    path: &Path,
    scene: &Scene,
    maps: &SensorMaps,
    planes: u64,
    seed: u64,
    raw: Option<&Path>,
) {
    let mut sim = SpadSimulator::with_maps(&camera(), scene, maps.clone(), seed).unwrap();
    let header = sim.recording_header(planes, BitOrder::LsbFirst);
    let f = BufWriter::new(std::fs::File::create(path).unwrap());
    let mut wr = RecordingWriter::new(f, header).unwrap();
    let mut raw_bytes = Vec::new();
    for _ in 0..planes {
        let plane = sim.next_plane();
        wr.write_plane(&plane).unwrap();
        if raw.is_some() {
            pack_plane(&plane, BitOrder::MsbFirst, &mut raw_bytes);
        }
    }
    wr.finish().unwrap();
    if let Some(r) = raw {
        std::fs::write(r, raw_bytes).unwrap();
    }
}

fn smartagg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_smartagg"))
        .args(args)
        .output()
        .expect("the smartagg binary runs")
}

fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `smartagg calibrate` of a short dark recording (`--allow-short`), which must succeed.
fn calibrate_short(dark: &Path, out: &Path) {
    ok(&smartagg(&[
        "calibrate",
        "--dark",
        s(dark),
        "--out",
        s(out),
        "--allow-short",
        "--quiet",
    ]));
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn header(dir: &Path) -> toml::Table {
    std::fs::read_to_string(dir.join("calibration.toml"))
        .unwrap()
        .parse()
        .unwrap()
}

/// Reads a map through the header's `[maps]` table.
fn map_f32(dir: &Path, name: &str) -> Vec<f64> {
    let h = header(dir);
    let entry = &h["maps"][name];
    assert_eq!(entry["sample"].as_str(), Some("f32"));
    let file = std::fs::File::open(dir.join(entry["file"].as_str().unwrap())).unwrap();
    let mut d = tiff::decoder::Decoder::new(file).unwrap();
    assert_eq!(d.dimensions().unwrap(), (W, W));
    match d.read_image().unwrap() {
        tiff::decoder::DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        _ => panic!("{name} is not f32"),
    }
}

/// Pixels listed in a CSV whose first two columns are x, y.
fn csv_pixels(path: &Path) -> BTreeSet<(u32, u32)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let mut it = l.split(',');
            (
                it.next().unwrap().parse().unwrap(),
                it.next().unwrap().parse().unwrap(),
            )
        })
        .collect()
}

struct Fixture {
    _tmp: tempfile::TempDir,
    dir: PathBuf,
    maps: SensorMaps,
}

impl Fixture {
    fn new(seed: u64) -> Fixture {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let maps = generate_maps(&camera(), W, W, seed);
        Fixture {
            _tmp: tmp,
            dir,
            maps,
        }
    }
    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }
}

#[test]
fn spad_dark_and_flat_recordings_give_the_maps_hot_pixels_and_report() {
    let fx = Fixture::new(7);
    let (dark, flat, out) = (fx.path("dark.spad"), fx.path("flat.spad"), fx.path("calib"));
    let cam = camera();
    record(&dark, &fx.maps, 0.0, 150_000, 8, None);
    let px_um = Preset::new(PresetName::Spcimager, 150).unwrap().pixel_nm() / 1000.0;
    record(
        &flat,
        &fx.maps,
        3000.0 / (cam.eta() * px_um * px_um),
        30_000,
        9,
        None,
    );
    let stdout = ok(&smartagg(&[
        "calibrate",
        "--dark",
        s(&dark),
        "--flat",
        s(&flat),
        "--out",
        s(&out),
        "--quiet",
    ]));
    assert!(
        stdout.contains("hot pixels") && stdout.contains("PRNU spread"),
        "{stdout}"
    );

    let h = header(&out);
    assert_eq!(h["format"].as_str(), Some("smartagg-calibration"));
    assert_eq!(h["version"].as_integer(), Some(1));
    assert_eq!(h["kind"].as_str(), Some("spad"));
    assert_eq!(h["spad"]["planes"].as_integer(), Some(150_000));
    let dcr = map_f32(&out, "dcr_hz");
    let sd = map_f32(&out, "dcr_sd_hz");
    let n = (W * W) as usize;
    let z: Vec<f64> = (0..n)
        .map(|i| (dcr[i] - fx.maps.dcr_hz[i]) / sd[i])
        .collect();
    let within = z.iter().filter(|z| z.abs() < 3.0).count() as f64 / n as f64;
    let chi2 = z.iter().map(|z| z * z).sum::<f64>() / n as f64;
    eprintln!("DCR: {:.2} % within 3 sd, chi2/k {chi2:.3}", 100.0 * within);
    // P(|z| ≥ 3) = 0.27 %: 0.7 of 256 pixels expected, more than 4 has
    // probability < 10⁻³ (so ≥ 98.4 % within 3 sd); χ²/k within 5 standard errors.
    assert!(within >= 0.984 && chi2 < 1.0 + 5.0 * (2.0 / n as f64).sqrt());

    // Hot pixels: the CSV lists exactly the simulator's.
    let truth: BTreeSet<(u32, u32)> = (0..n)
        .filter(|&i| fx.maps.hot[i])
        .map(|i| (i as u32 % W, i as u32 / W))
        .collect();
    assert!(!truth.is_empty());
    assert_eq!(csv_pixels(&out.join("hot_pixels.csv")), truth);
    let hot_count = h["spad"]["dark"]["hot_pixels"].as_integer().unwrap() as usize;
    assert_eq!(hot_count, truth.len());

    // PRNU map against η / mean η over the pixels it was normalised on.
    let prnu = map_f32(&out, "prnu");
    let psd = map_f32(&out, "prnu_sd");
    let normal: Vec<usize> = (0..n).filter(|&i| !fx.maps.hot[i]).collect();
    let eta = fx.maps.efficiency(camera().eta());
    let mean_eta = normal.iter().map(|&i| eta[i]).sum::<f64>() / normal.len() as f64;
    let zp: Vec<f64> = (0..n)
        .map(|i| (prnu[i] - eta[i] / mean_eta) / psd[i])
        .collect();
    let within = zp.iter().filter(|z| z.abs() < 3.0).count() as f64 / n as f64;
    eprintln!("PRNU: {:.2} % within 3 sd", 100.0 * within);
    assert!(within >= 0.984);

    // The report a person reads.
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for want in [
        "## Dark-count rate",
        "Planes needed",
        "## Hot pixels",
        "## PRNU",
        "critical DCR",
    ] {
        assert!(md.contains(want), "{want}");
    }
    let png = png::Decoder::new(std::fs::File::open(out.join("dcr_histogram.png")).unwrap());
    let info = png.read_info().unwrap();
    assert_eq!((info.info().width, info.info().height), (900, 560));
}

#[test]
fn a_recording_too_short_for_the_precision_says_so() {
    let fx = Fixture::new(17);
    let dark = fx.path("dark.spad");
    // 100 Hz at 100 µs: 5 % needs ≈ 40,000 planes; 4,000 are recorded.
    record(&dark, &fx.maps, 0.0, 4_000, 18, None);
    let out = smartagg(&[
        "calibrate",
        "--dark",
        s(&dark),
        "--out",
        s(&fx.path("c")),
        "--quiet",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("too short") && err.contains("4000 bit-planes") && err.contains("needs"),
        "{err}"
    );
    assert!(!fx.path("c").join("calibration.toml").exists());
    // A precision the recording supports is fine.
    ok(&smartagg(&[
        "calibrate",
        "--dark",
        s(&dark),
        "--out",
        s(&fx.path("c")),
        "--precision",
        "0.2",
        "--quiet",
    ]));
    // Accepted: written, and the report and stderr say it is short.
    let out = smartagg(&[
        "calibrate",
        "--dark",
        s(&dark),
        "--out",
        s(&fx.path("c")),
        "--allow-short",
        "--quiet",
    ]);
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("warning"));
    let md = std::fs::read_to_string(fx.path("c").join("report.md")).unwrap();
    assert!(md.contains("too short"), "{md}");
    let h = header(&fx.path("c"));
    let needed = h["spad"]["dark"]["planes_needed"].as_integer().unwrap();
    assert!((30_000..60_000).contains(&needed), "{needed}");
}

#[test]
fn the_threshold_moves_the_hot_set_and_raw_planes_read_like_spad_files() {
    let mut fx = Fixture::new(27);
    // A very wide DCR spread, so many pixels sit near the critical DCR.
    let wide = SpadCamera {
        drnu: 3.0,
        hot_pixel_fraction: 0.0,
        ..camera()
    };
    fx.maps = generate_maps(&wide, W, W, 27);
    let (dark, raw) = (fx.path("dark.spad"), fx.path("dark.raw"));
    record(&dark, &fx.maps, 0.0, 60_000, 28, Some(&raw));
    let hot = |extra: &[&str], name: &str| {
        let out = fx.path(name);
        let mut args = vec!["calibrate", "--dark", s(&dark), "--out", s(&out), "--quiet"];
        args.extend_from_slice(extra);
        ok(&smartagg(&args));
        csv_pixels(&out.join("hot_pixels.csv"))
    };
    let base = hot(&[], "base");
    let lower = hot(&["--threshold-int", "110000"], "lower");
    let higher = hot(&["--threshold-int", "150000"], "higher");
    eprintln!(
        "hot pixels at T_int 110000 / default / 150000: {} / {} / {}",
        lower.len(),
        base.len(),
        higher.len()
    );
    assert!(higher.is_subset(&base) && base.is_subset(&lower));
    assert!(higher.len() < base.len() && base.len() < lower.len());
    // The 60x objective's criterion is another one.
    let sixty = hot(&["--objective", "60"], "sixty");
    assert_ne!(sixty, base);

    // Raw MSB-first planes with the size given: the same DCR map.
    let raw_out = fx.path("raw");
    ok(&smartagg(&[
        "calibrate",
        "--dark",
        s(&raw),
        "--out",
        s(&raw_out),
        "--raw",
        "--width",
        "16",
        "--height",
        "16",
        "--bit-order",
        "msb",
        "--quiet",
    ]));
    assert_eq!(
        map_f32(&raw_out, "dcr_hz"),
        map_f32(&fx.path("base"), "dcr_hz")
    );
    // The wrong bit order reads other pixels.
    ok(&smartagg(&[
        "calibrate",
        "--dark",
        s(&raw),
        "--out",
        s(&raw_out),
        "--raw",
        "--width",
        "16",
        "--height",
        "16",
        "--quiet",
        "--precision",
        "0.5",
    ]));
    assert_ne!(
        map_f32(&raw_out, "dcr_hz"),
        map_f32(&fx.path("base"), "dcr_hz")
    );
}

#[test]
fn bad_inputs_are_named() {
    let fx = Fixture::new(37);
    let dark = fx.path("dark.spad");
    record(&dark, &fx.maps, 0.0, 50_000, 38, None);
    let fail = |args: &[&str], want: &str| {
        let out = smartagg(args);
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    };
    let out = s(&fx.path("c")).to_string();
    fail(
        &[
            "calibrate",
            "--dark",
            s(&fx.path("none.spad")),
            "--out",
            &out,
        ],
        "none.spad",
    );
    // A flat of another size.
    let small = generate_maps(&camera(), W, W, 1);
    let small = SensorMaps {
        width: 8,
        height: 8,
        prnu: small.prnu.map(|p| p[..64].to_vec()),
        dcr_hz: small.dcr_hz[..64].to_vec(),
        hot: small.hot[..64].to_vec(),
    };
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let mut sim = SpadSimulator::with_maps(&camera(), &empty_scene(&p, 8, 1e6), small, 2).unwrap();
    let flat = fx.path("flat8.spad");
    let mut wr = RecordingWriter::new(
        std::fs::File::create(&flat).unwrap(),
        sim.recording_header(10, BitOrder::LsbFirst),
    )
    .unwrap();
    for _ in 0..10 {
        wr.write_plane(&sim.next_plane()).unwrap();
    }
    wr.finish().unwrap();
    fail(
        &[
            "calibrate",
            "--dark",
            s(&dark),
            "--flat",
            s(&flat),
            "--out",
            &out,
        ],
        "expected 16x16 pixels, found 8x8",
    );
    // A text file is not a recording.
    let txt = fx.path("notes.txt");
    std::fs::write(&txt, "hello").unwrap();
    fail(
        &["calibrate", "--dark", s(&txt), "--out", &out],
        "not a .spad recording",
    );
    // A TIFF without the camera kind.
    fail(
        &["calibrate", "--dark", s(&fx.path("x.tif")), "--out", &out],
        "--camera emccd or --camera scmos",
    );
    fail(
        &[
            "calibrate",
            "--dark",
            s(&dark),
            "--out",
            &out,
            "--camera",
            "scmos",
            "--preset",
            "spcimager",
        ],
        "contradicts",
    );
    fail(
        &[
            "calibrate",
            "--dark",
            s(&dark),
            "--out",
            &out,
            "--precision",
            "2",
        ],
        "precision",
    );
    // Output path that is a file.
    fail(
        &["calibrate", "--dark", s(&dark), "--out", s(&txt)],
        "not a directory",
    );
}

#[test]
fn scmos_stacks_give_offset_read_noise_and_gain_maps() {
    let tmp = tempfile::tempdir().unwrap();
    let p = Preset::new(PresetName::Scmos, 150).unwrap();
    let Camera::Scmos(cam) = p.camera.clone() else {
        unreachable!()
    };
    let maps = smartagg_scene::ScmosMaps::generate(&cam, &Default::default(), W, W, 5);
    let bg = 200.0 / (cam.qe * cam.exposure_s * (p.pixel_nm() / 1000.0).powi(2));
    let write = |name: &str, light: f64, seed: u64| {
        let path = tmp.path().join(name);
        let mut sim =
            ScmosSimulator::with_maps(&cam, &empty_scene(&p, W, light), maps.clone(), seed)
                .unwrap();
        let mut w = StackWriter::new(std::fs::File::create(&path).unwrap(), W, W).unwrap();
        for _ in 0..800 {
            w.write_frame(&sim.next_frame().adu).unwrap();
        }
        path
    };
    let (dark, flat) = (write("dark.tif", 0.0, 6), write("flat.tif", bg, 7));
    let out = tmp.path().join("calib");
    let stdout = ok(&smartagg(&[
        "calibrate",
        "--camera",
        "scmos",
        "--dark",
        s(&dark),
        "--flat",
        s(&flat),
        "--out",
        s(&out),
    ]));
    assert!(stdout.contains("photon transfer"), "{stdout}");
    let h = header(&out);
    assert_eq!(h["kind"].as_str(), Some("scmos"));
    let gain = map_f32(&out, "gain_adu_per_e");
    let gsd = map_f32(&out, "gain_sd_adu_per_e");
    let n = (W * W) as usize;
    let within = (0..n)
        .filter(|&i| ((gain[i] - maps.gain_adu_per_e[i]) / gsd[i]).abs() < 3.0)
        .count() as f64
        / n as f64;
    eprintln!("sCMOS gain map: {:.2} % within 3 sd", 100.0 * within);
    assert!(within >= 0.984);
    let offset = map_f32(&out, "offset_adu");
    assert!((0..n).all(|i| (offset[i] - maps.offset_adu[i]).abs() < 1.0));
    let g = h["frame"]["gain_adu_per_e"].as_float().unwrap();
    assert!((g * cam.e_per_adu - 1.0).abs() < 0.03, "{g}");
    assert!(std::fs::read_to_string(out.join("report.md"))
        .unwrap()
        .contains("sCMOS calibration"));
    // The preset says which camera; a SPAD preset contradicts a TIFF stack's kind.
    ok(&smartagg(&[
        "calibrate",
        "--preset",
        "scmos",
        "--dark",
        s(&dark),
        "--out",
        s(&out),
        "--quiet",
    ]));
    let h = header(&out);
    assert!(h["frame"]["gain_source"]
        .as_str()
        .unwrap()
        .contains("preset scmos"));
}

/// `smartagg study --calibration`: the study runs on the calibrated sensor's
/// maps, its summary and manifest name the calibration, and the studies it
/// does not apply to, or a sensor smaller than the study field, are refused.
#[test]
fn the_study_simulates_a_calibrated_sensor() {
    let fx = Fixture::new(3);
    let side = 48;
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let maps = generate_maps(&camera(), side, side, 5);
    let dark = fx.path("dark48.spad");
    record_scene(&dark, &empty_scene(&p, side, 0.0), &maps, 4000, 6, None);
    let cal = fx.path("calib48");
    calibrate_short(&dark, &cal);
    let out = fx.path("svf");
    let run = |study: &str, out: &Path, cal: &Path| {
        smartagg(&[
            "study",
            study,
            "--calibration",
            s(cal),
            "--out",
            s(out),
            "--points",
            "50",
            "--blinks-per-point",
            "12",
            "--bootstrap",
            "10",
            "--quiet",
        ])
    };
    ok(&run("smart-vs-fixed", &out, &cal));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("**Calibrated sensor**"), "{summary}");
    assert!(summary.contains("calib48 (48x48 px, 4000 dark planes, maps CRC-32C "));
    let manifest = std::fs::read_to_string(out.join("manifest.json")).unwrap();
    assert!(manifest.contains("calib48 (48x48 px"), "{manifest}");

    for (study, why) in [
        ("hot-pixels", "sweeps synthetic hot-pixel fractions"),
        ("nanoruler", "simulates its own cameras"),
    ] {
        let o = run(study, &fx.path("no"), &cal);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(why), "{study}: {err}");
    }
    // The 16x16 sensor of the other tests is smaller than the study field.
    let small = fx.path("calib16");
    record(&fx.path("dark16.spad"), &fx.maps, 0.0, 4000, 8, None);
    ok(&smartagg(&[
        "calibrate",
        "--dark",
        s(&fx.path("dark16.spad")),
        "--out",
        s(&small),
        "--allow-short",
        "--quiet",
    ]));
    let o = run("smart-vs-fixed", &fx.path("no16"), &small);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("16x16") && err.contains("smaller"),
        "{err}"
    );
}

/// `download --calibration`: the calibration's hot pixels (judged at the
/// device's N and T_int) are loaded into the gateware's mask through the
/// register map — here the Verilated XEM6310 core of `--source cosim` — and
/// the device's StreamStart reports them.
#[test]
fn download_loads_the_calibrated_hot_pixels_into_the_device() {
    let fx = Fixture::new(4);
    let (w, h) = (320u32, 240u32);
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let cam = camera();
    let mut maps = smartagg_scene::uniform_maps(&cam, w, h);
    // Twelve pixels that fire in nearly every plane: hot under any criterion.
    let hot: Vec<usize> = (0..12).map(|i| 1000 + i * 6007).collect();
    for &i in &hot {
        maps.dcr_hz[i] = 2e5;
        maps.hot[i] = true;
    }
    let mut scene = empty_scene(&p, w, 0.0);
    scene.height = h;
    let dark = fx.path("dark-full.spad");
    record_scene(&dark, &scene, &maps, 1500, 2, None);
    let cal = fx.path("calib-full");
    calibrate_short(&dark, &cal);
    let out = fx.path("o.rois");
    let o = smartagg(&[
        "download",
        "--source",
        "cosim:spcimager:3",
        "--calibration",
        s(&cal),
        "--quiet",
        "--timeout",
        "600",
        "--out",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{err}");
    assert!(err.contains(": 12 hot pixels masked"), "{err}");
    let d = smartagg_model::packet::decode_all(&std::fs::read(&out).unwrap());
    assert!(!d.stats.any_loss(), "{}", d.stats);
    match &d.packets.first().map(|p| &p.record) {
        Some(smartagg_model::record::Record::Start(s)) => assert_eq!(s.masked_pixels, 12),
        other => panic!("the stream starts with {other:?}"),
    }
}
