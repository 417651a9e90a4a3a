//! The `smartagg` command end to end: simulate, aggregate with both engines,
//! and the errors a user sees.

use std::path::Path;

mod common;
use common::*;

#[test]
fn params_json_reports_the_papers_window() {
    let out = ok(&["params", "--preset", "spcimager", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for key in [
        "eta",
        "background_rate_hz",
        "flux_hz",
        "tau_s",
        "sigma_px",
        "kernel_size",
        "kernel_weights",
        "n_window",
        "threshold",
        "threshold_int",
    ] {
        assert!(v.get(key).is_some(), "JSON lacks `{key}`");
    }
    let n = v["n_window"].as_u64().unwrap();
    assert!((100..=110).contains(&n), "N = {n}");
    let n60: serde_json::Value =
        serde_json::from_str(&ok(&["params", "--objective", "60", "--json"])).unwrap();
    assert!(n60["n_window"].as_u64().unwrap() < n);
    assert!(err(&["params", "--preset", "emccd"]).contains("SPAD"));
    assert!(err(&["params", "--preset", "nope"]).contains("unknown preset"));
    assert!(err(&["params", "--objective", "100"]).contains("objective"));
}

#[test]
fn golden_and_fast_engines_write_identical_packets() {
    let dir = tempfile::tempdir().unwrap();
    let rec = p(dir.path(), "rulers.spad");
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--scene",
        "nanoruler",
        "--field",
        "48x40",
        "--planes",
        "3000",
        "--mean-off-s",
        "0.3",
        "--seed",
        "3",
        "--out",
        &rec,
    ]);
    assert!(dir.path().join("rulers.spad.truth.csv").exists());
    let golden = p(dir.path(), "golden.rois");
    let fast = p(dir.path(), "fast.rois");
    let fast1 = p(dir.path(), "fast1.rois");
    let summary = ok(&[
        "aggregate",
        &rec,
        "--out",
        &golden,
        "--engine",
        "golden",
        "--quiet",
    ]);
    assert!(summary.contains("3000 planes"), "{summary}");
    ok(&["aggregate", &rec, "--out", &fast, "--quiet"]);
    ok(&[
        "aggregate",
        &rec,
        "--out",
        &fast1,
        "--threads",
        "1",
        "--quiet",
    ]);
    let g = std::fs::read(&golden).unwrap();
    assert!(g.len() > 100);
    assert_eq!(g, std::fs::read(&fast).unwrap());
    assert_eq!(g, std::fs::read(&fast1).unwrap());
    // Through a pipe (no plane at an index: the reader thread reads them
    // all, where the workers read a file's chunks themselves).
    #[cfg(unix)]
    {
        use std::io::Write;
        let piped = p(dir.path(), "piped.rois");
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_smartagg"))
            .args(["aggregate", "/dev/stdin", "--out", &piped, "--threads", "3"])
            .arg("--quiet")
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        let bytes = std::fs::read(&rec).unwrap();
        let feed = std::thread::spawn(move || stdin.write_all(&bytes));
        assert!(child.wait().unwrap().success());
        feed.join().unwrap().unwrap();
        assert_eq!(g, std::fs::read(&piped).unwrap());
    }
    let decoded = smartagg_model::packet::decode_all(&g);
    assert!(!decoded.stats.any_loss());
    let blinks = decoded
        .packets
        .iter()
        .filter(|p| matches!(p.record, smartagg_model::record::Record::Blink(_)))
        .count();
    assert!(blinks >= 3, "the scene must blink: {blinks} blinks");
}

#[test]
fn bad_recordings_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let empty = p(dir.path(), "empty.spad");
    std::fs::write(&empty, b"").unwrap();
    assert!(err(&["aggregate", &empty, "--out", &p(dir.path(), "x.rois")]).contains("empty"));
    let text = p(dir.path(), "notes.spad");
    std::fs::write(
        &text,
        b"hello world, not a recording at all; long enough for a header....",
    )
    .unwrap();
    assert!(
        err(&["aggregate", &text, "--out", &p(dir.path(), "x.rois")])
            .contains("not a .spad recording")
    );
    // Raw planes whose size is not a whole number of planes.
    let raw = p(dir.path(), "raw.bin");
    std::fs::write(&raw, vec![0u8; 8 * 8 / 8 * 3 + 5]).unwrap();
    let e = err(&[
        "aggregate",
        &raw,
        "--raw",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        &p(dir.path(), "x.rois"),
        "--engine",
        "golden",
    ]);
    assert!(e.contains("truncated inside plane 3"), "{e}");
    assert!(err(&[
        "aggregate",
        &p(dir.path(), "missing.spad"),
        "--out",
        &p(dir.path(), "x.rois")
    ])
    .contains("missing.spad"));
}

/// The detection design: `params` explains it, `aggregate` announces it, and
/// bad detection options are refused before any output is written.
#[test]
fn detection_design_is_explained_and_bad_levels_are_refused() {
    let out = ok(&["params"]);
    assert!(
        out.contains("field design") && out.contains("T_hold"),
        "{out}"
    );
    assert!(out.contains("predicted recall by blink duration"), "{out}");
    let v: serde_json::Value = serde_json::from_str(&ok(&["params", "--json"])).unwrap();
    let fd = &v["field_design"];
    let (open, hold) = (
        fd["threshold_open"].as_u64().unwrap(),
        fd["threshold_hold"].as_u64().unwrap(),
    );
    assert_eq!(hold, v["threshold_int"].as_u64().unwrap());
    assert!(open > hold);
    assert!(fd["predicted_false_blinks_per_s"].as_f64().unwrap() <= 1.0);
    // A tighter budget asks for a higher open level.
    let tight: serde_json::Value =
        serde_json::from_str(&ok(&["params", "--json", "--false-blinks-per-s", "0.01"])).unwrap();
    assert!(tight["field_design"]["threshold_open"].as_u64().unwrap() > open);

    let dir = tempfile::tempdir().unwrap();
    let rec = p(dir.path(), "bg.spad");
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--scene",
        "random",
        "--density",
        "0",
        "--field",
        "64x48",
        "--planes",
        "300",
        "--out",
        &rec,
    ]);
    let rois = p(dir.path(), "x.rois");
    let e = err(&[
        "aggregate",
        &rec,
        "--out",
        &rois,
        "--threshold-int",
        "1000",
        "--threshold-hold",
        "2000",
    ]);
    assert!(e.contains("threshold_hold"), "{e}");
    for bad in ["0", "-1", "nan"] {
        let opt = format!("--false-blinks-per-s={bad}");
        let e = err(&["aggregate", &rec, "--out", &rois, &opt]);
        assert!(e.contains("`false_blinks_per_s`"), "{bad}: {e}");
    }
    assert!(!dir.path().join("x.rois").exists());
    // The default run says what it chose, in the field's own terms.
    let o = smartagg(&["aggregate", &rec, "--out", &rois, "--quiet"]);
    assert!(o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("a track opens at T_int") && e.contains("64x48 field"),
        "{e}"
    );
    // The paper's scheme is still there: one threshold, r_assoc 1.
    let o = smartagg(&[
        "aggregate",
        &rec,
        "--out",
        &rois,
        "--quiet",
        "--detection",
        "paper",
    ]);
    assert!(o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("r_assoc = 1") && !e.contains("a track opens at"),
        "{e}"
    );
}

#[test]
fn calibration_masks_hot_pixels_in_aggregate() {
    let dir = tempfile::tempdir().unwrap();
    let dark = p(dir.path(), "dark.spad");
    // A dark recording (no light, no molecules) with 3 % hot pixels.
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--scene",
        "random",
        "--density",
        "0",
        "--background",
        "0",
        "--hot-pixels",
        "0.03",
        "--field",
        "24x20",
        "--planes",
        "60000",
        "--seed",
        "5",
        "--out",
        &dark,
    ]);
    let cal = p(dir.path(), "calib");
    ok(&[
        "calibrate",
        "--dark",
        &dark,
        "--out",
        &cal,
        "--preset",
        "spcimager",
        "--quiet",
    ]);
    let rois = p(dir.path(), "x.rois");
    let masked = p(dir.path(), "masked.rois");
    ok(&["aggregate", &dark, "--out", &rois, "--quiet"]);
    ok(&[
        "aggregate",
        &dark,
        "--out",
        &masked,
        "--calibration",
        &cal,
        "--quiet",
    ]);
    let start = |path: &str| {
        let d = smartagg_model::packet::decode_all(&std::fs::read(path).unwrap());
        let blinks = d
            .packets
            .iter()
            .filter(|p| matches!(p.record, smartagg_model::record::Record::Blink(_)))
            .count();
        match &d.packets[0].record {
            smartagg_model::record::Record::Start(s) => (s.masked_pixels, blinks),
            other => panic!("first record {other:?}"),
        }
    };
    let (m0, b0) = start(&rois);
    let (m1, b1) = start(&masked);
    assert_eq!(m0, 0);
    assert!(m1 >= 5, "hot pixels masked: {m1}");
    assert!(
        b0 > b1,
        "hot pixels fire as false blinks unless masked: {b0} vs {b1}"
    );
    // A calibration of another size is refused.
    let other = p(dir.path(), "other.spad");
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--scene",
        "random",
        "--density",
        "0",
        "--field",
        "16x16",
        "--planes",
        "10",
        "--out",
        &other,
    ]);
    assert!(err(&["aggregate", &other, "--out", &rois, "--calibration", &cal]).contains("24x20"));

    // `localize` reads the same calibration (its maps: dark counts, hot
    // pixels): the hot pixels that made the false blinks are left out of
    // their fits, so every blink keeps its row but the table changes.
    let plain = p(dir.path(), "plain.csv");
    let calibrated = p(dir.path(), "calibrated.csv");
    ok(&["localize", &rois, "--out", &plain]);
    ok(&[
        "localize",
        &rois,
        "--out",
        &calibrated,
        "--calibration",
        &cal,
    ]);
    let (a, c) = (
        std::fs::read_to_string(&plain).unwrap(),
        std::fs::read_to_string(&calibrated).unwrap(),
    );
    assert_eq!(a.lines().count(), b0 + 1, "one row per blink, and a header");
    assert_eq!(c.lines().count(), a.lines().count());
    assert!(a != c, "the calibration changes the fits");
    // A stream of another sensor is refused.
    let other_rois = p(dir.path(), "other.rois");
    ok(&["aggregate", &other, "--out", &other_rois, "--quiet"]);
    let e = err(&[
        "localize",
        &other_rois,
        "--out",
        &plain,
        "--calibration",
        &cal,
    ]);
    assert!(e.contains("24x20") && e.contains("16x16"), "{e}");
}

#[test]
fn demo_on_a_field_without_gateware_says_how_to_run_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = p(dir.path(), "demo");
    let e = err(&["demo", "--out", &out, "--field", "64", "--quiet"]);
    assert!(
        e.contains("48x48") && e.contains("--gateware-planes 0"),
        "{e}"
    );
}

#[test]
fn demo_writes_every_output_and_engines_agree() {
    let dir = tempfile::tempdir().unwrap();
    let out = p(dir.path(), "demo");
    let report = ok(&[
        "demo",
        "--out",
        &out,
        "--seconds",
        "4",
        "--mean-off-s",
        "0.4",
        "--quiet",
    ]);
    // By default the whole recording goes through the gateware.
    assert!(
        report.contains("| gateware (Verilated pipeline core) vs golden model | byte-identical on all 40000 bit-planes"),
        "{report}"
    );
    for f in [
        "blinks.rois",
        "blinks.rois.json",
        "localisations.csv",
        "render.png",
        "report.md",
    ] {
        let path = dir.path().join("demo").join(f);
        assert!(
            std::fs::metadata(&path)
                .map(|m| m.len() > 0)
                .unwrap_or(false),
            "{f} missing or empty"
        );
    }
    assert!(report.contains("byte-identical packet streams"), "{report}");
    assert!(
        report.contains("| losses in the packet stream | none |"),
        "{report}"
    );
    let csv = std::fs::read_to_string(dir.path().join("demo/localisations.csv")).unwrap();
    assert!(csv.starts_with("\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"sigma [nm]\",\"intensity [photon]\",\"offset [photon]\",\"bkgstd [photon]\",\"uncertainty [nm]\""));
    assert!(
        csv.lines().count() > 10,
        "the rulers must blink and be localised"
    );
    // The received stream decodes to the blinks of the table.
    let d = smartagg_model::packet::decode_all(
        &std::fs::read(dir.path().join("demo/blinks.rois")).unwrap(),
    );
    let blinks = d
        .packets
        .iter()
        .filter(|p| matches!(p.record, smartagg_model::record::Record::Blink(_)))
        .count();
    assert_eq!(blinks, csv.lines().count() - 1);
}

#[test]
fn a_stream_says_its_camera_and_no_output_destroys_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let rec = p(dir.path(), "rulers.spad");
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--objective",
        "60",
        "--scene",
        "nanoruler",
        "--field",
        "48x40",
        "--planes",
        "3000",
        "--mean-off-s",
        "0.3",
        "--seed",
        "5",
        "--out",
        &rec,
    ]);
    let recording = std::fs::read(&rec).unwrap();
    let rois = p(dir.path(), "blinks.rois");
    let out = ok(&[
        "aggregate",
        &rec,
        "--out",
        &rois,
        "--objective",
        "60",
        "--quiet",
    ]);
    assert!(out.contains("blinks.rois.json"), "{out}");
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(format!("{rois}.json")).unwrap()).unwrap();
    assert_eq!(side["camera"], "spcimager");
    assert_eq!(side["objective"], 60);
    assert_eq!(
        (side["width"].as_u64(), side["height"].as_u64()),
        (Some(48), Some(40))
    );

    // No camera flags: the sidecar gives the 60x pixel (133.3 nm).
    let locs = p(dir.path(), "locs.csv");
    let o = smartagg(&["localize", &rois, "--out", &locs]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("camera from") && stderr.contains("60x"),
        "{stderr}"
    );
    assert!(stderr.contains("133.33 nm"), "{stderr}");
    let table = std::fs::read_to_string(&locs).unwrap();
    assert!(table.lines().count() > 3, "{table}");
    // A flag wins over the sidecar.
    let o = smartagg(&["localize", &rois, "--out", &locs, "--pixel-nm", "100"]);
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("camera from"));
    // A sidecar for another sensor is refused.
    let mut wrong = side.clone();
    wrong["width"] = 320.into();
    std::fs::write(format!("{rois}.json"), wrong.to_string()).unwrap();
    let e = err(&["localize", &rois, "--out", &locs]);
    assert!(e.contains("48x40") && e.contains("--preset"), "{e}");
    // Without the sidecar the error says where the camera would be.
    std::fs::remove_file(format!("{rois}.json")).unwrap();
    let e = err(&["localize", &rois, "--out", &locs]);
    assert!(e.contains("blinks.rois.json"), "{e}");

    // Outputs onto an input are refused and leave it as it was: the same
    // path, a hard link, the stream as the table.
    let link = p(dir.path(), "link.spad");
    std::fs::hard_link(&rec, &link).unwrap();
    for target in [&rec, &link] {
        let e = err(&["aggregate", &rec, "--out", target, "--quiet"]);
        assert!(e.contains("destroy the input"), "{e}");
    }
    let e = err(&["localize", &rois, "--out", &rois, "--pixel-nm", "100"]);
    assert!(e.contains("destroy the input"), "{e}");
    assert_eq!(std::fs::read(&rec).unwrap(), recording);

    // A failed aggregate leaves no partial stream, and an old one intact.
    let cut = p(dir.path(), "cut.spad");
    std::fs::write(&cut, &recording[..recording.len() / 2]).unwrap();
    let before = std::fs::read(&rois).unwrap();
    let e = err(&["aggregate", &cut, "--out", &rois, "--quiet"]);
    assert!(e.contains("truncated"), "{e}");
    assert_eq!(std::fs::read(&rois).unwrap(), before);
    let fresh = p(dir.path(), "fresh.rois");
    err(&["aggregate", &cut, "--out", &fresh, "--quiet"]);
    assert!(!Path::new(&fresh).exists());
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.ends_with(".partial")), "{names:?}");
}

#[test]
fn options_are_checked_where_they_are_parsed() {
    let dir = tempfile::tempdir().unwrap();
    let rois = p(dir.path(), "x.rois");
    std::fs::write(&rois, b"anything").unwrap();
    let out = p(dir.path(), "x.csv");
    for (opt, value, want) in [
        ("--pixel-nm", "1e-320", "outside 0.1..=1000000 nm"),
        ("--pixel-nm", "1e308", "outside 0.1..=1000000 nm"),
        ("--read-noise-e", "nan", "outside 0..=10000 e- rms"),
        ("--read-noise-e", "-5", "outside 0..=10000 e- rms"),
        ("--sigma", "inf", "camera pixels"),
        ("--threads", "4294967296", "give 1 to 1024"),
        ("--threads", "0", "give 1 to 1024"),
        ("--planes", "0", "1..="),
    ] {
        let e = err(&["localize", &rois, "--out", &out, opt, value]);
        assert!(e.contains(want), "{opt} {value}: {e}");
    }
    for (opt, value, want) in [
        ("--threads", "18446744073709551615", "give 1 to 1024"),
        ("--threads", "0", "give 1 to 1024"),
        ("--l-max", "0", "shorter than the window N"),
    ] {
        let rec = p(dir.path(), "r.spad");
        ok(&[
            "simulate",
            "--preset",
            "spcimager",
            "--scene",
            "single",
            "--field",
            "16x16",
            "--planes",
            "200",
            "--out",
            &rec,
        ]);
        let e = err(&[
            "aggregate",
            &rec,
            "--out",
            &p(dir.path(), "o.rois"),
            opt,
            value,
        ]);
        assert!(e.contains(want), "{opt} {value}: {e}");
        assert!(!dir.path().join("o.rois").exists());
    }
    assert!(!Path::new(&out).exists());
}

/// Counts of planes are at least one: no golden planes would leave every
/// speed-up against it undefined (NaN and ∞ in the table).
#[test]
fn bench_aggregate_refuses_zero_planes() {
    for flag in ["--planes", "--golden-planes", "--pool"] {
        let e = err(&["bench", "aggregate", flag, "0"]);
        assert!(e.contains(flag) && e.contains("1.."), "{flag}: {e}");
    }
}

#[test]
fn bench_aggregate_streams_the_scene_asked_for() {
    fn stream(scene: Option<&str>) -> Vec<&str> {
        let mut a = vec![
            "bench",
            "aggregate",
            "--width",
            "64",
            "--height",
            "48",
            "--stream",
            "--planes",
            "2000",
            "--pool",
            "64",
            "--threads",
            "2",
        ];
        if let Some(s) = scene {
            a.extend(["--scene", s]);
        }
        a
    }
    for (scene, name) in [
        (None, "typical"),
        (Some("dense"), "dense"),
        (Some("spad512s,dense"), "dense"),
    ] {
        let out = ok(&stream(scene));
        assert!(
            out.contains(&format!("of the {name} scene")),
            "{scene:?}:\n{out}"
        );
        assert!(
            out.contains("RSS MiB")
                && out.contains(" records, ")
                && out.contains("all 2000 planes through the engine in ")
                && out.contains("reader/tracker/sums/records/workers")
                && out.contains(" % answered ahead by the workers"),
            "{out}"
        );
        // The last row (all planes read) names each role's CPU. The reader
        // prints the row and the calling thread makes the records: both are
        // alive, so both are numbers. The tracker, the sums and the workers may not
        // have started yet when a short run's planes are all read (the
        // reader runs up to 3·threads + 1 chunks of at least 512 planes
        // ahead): each is a number (the two workers a lowest and a
        // highest) or `-`.
        let last = out
            .lines()
            .find(|l| l.trim_start().starts_with("2000 "))
            .unwrap_or_else(|| panic!("no row at 2000 planes:\n{out}"));
        let roles: Vec<&str> = last
            .split_whitespace()
            .last()
            .unwrap_or("")
            .split('/')
            .collect();
        let number = |p: &str| p.parse::<f64>().is_ok();
        assert!(
            roles.len() == 5
                && number(roles[0])
                && (number(roles[1]) || roles[1] == "-")
                && (number(roles[2]) || roles[2] == "-")
                && number(roles[3])
                && (roles[4] == "-"
                    || roles[4].split_once('-').is_some_and(|(lo, hi)| {
                        number(lo) && number(hi) && lo.parse::<f64>().ok() <= hi.parse::<f64>().ok()
                    })),
            "{last}"
        );
    }
    let e = err(&stream(Some("spad512s")));
    assert!(e.contains("--preset spad512s"), "{e}");
}

#[test]
fn bench_aggregate_prints_the_scaling_curve_and_the_serial_ceiling() {
    // A small SPAD512S field, so that the debug build runs it quickly: the
    // golden check, stages 1-4 and 5-7 alone, and the curve 1, 2, 3 threads.
    let out = ok(&[
        "bench",
        "aggregate",
        "--preset",
        "spad512s",
        "--width",
        "64",
        "--height",
        "64",
        "--planes",
        "300",
        "--golden-planes",
        "40",
        "--threads",
        "3",
        "--scene",
        "typical",
    ]);
    for row in [
        "stages 1-4 portable",
        "stages 5-7, 3 thr",
        "fast, chunked x1 ",
        "fast, chunked x2 ",
        "fast, chunked x3 ",
    ] {
        assert!(out.contains(row), "no `{row}` row:\n{out}");
    }
    assert!(
        out.contains("Gpixel/s") && out.contains("vs 1 thr"),
        "{out}"
    );
    assert!(out.contains("golden bytes identical: yes"), "{out}");
    // The dense scene was not asked for.
    assert!(!out.contains("\ndense "), "{out}");
    let e = err(&["bench", "aggregate", "--scene", "sparse"]);
    assert!(e.contains("typical") && e.contains("spad512s"), "{e}");
}

/// Issue #37: a stack of 9 × 9 frames is localised with the default ROI
/// (11, adapted to 9 and said once), the end-to-end benchmark finds nearly
/// every spot, and frames too small for any fit are an error, not a panic.
#[test]
fn small_frames_are_localised_and_tiny_ones_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = p(dir.path(), "stack");
    let out = ok(&[
        "bench",
        "frames",
        "--frames",
        "300",
        "--threads",
        "1",
        "--repeats",
        "1",
        "--dir",
        &d,
    ]);
    let row = out
        .lines()
        .find(|l| l.trim_start().starts_with("1 "))
        .unwrap_or_else(|| panic!("no row for one thread:\n{out}"));
    let found: f64 = row
        .split_whitespace()
        .find_map(|f| f.strip_suffix('%'))
        .and_then(|f| f.parse().ok())
        .unwrap_or_else(|| panic!("no found column: {row}"));
    assert!(found >= 95.0, "{row}");
    let stack = format!("{d}/spots.tif");
    let table = p(dir.path(), "locs.csv");
    let run = smartagg(&["localize", &stack, "--out", &table, "--pixel-nm", "100"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert_eq!(
        stderr.matches("fitting 9x9 ROIs instead of 11x11").count(),
        1,
        "{stderr}"
    );
    let rows = std::fs::read_to_string(&table).unwrap().lines().count() - 1;
    assert!((285..=320).contains(&rows), "{rows} localisations");
    let e = err(&[
        "bench",
        "frames",
        "--frames",
        "5",
        "--side",
        "2",
        "--threads",
        "1",
        "--repeats",
        "1",
    ]);
    assert!(e.contains("frame 2x2 is smaller than 3x3"), "{e}");
}
