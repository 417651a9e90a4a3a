//! `smartagg download` through the real binary: every source's command-line
//! path and its messages. There is no USB bus and no FrontPanel SDK on the
//! machines that run these tests, so the device paths are tested for their
//! errors; the device-independent logic has unit tests in `src/transport`.

use smartagg_model::config::PipelineConfig;
use smartagg_model::packetiser::encode_stream;
use smartagg_model::record::{BlinkRecord, Record, StreamEnd};
use std::path::Path;
use std::process::{Command, Output};

fn smartagg() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_smartagg"));
    // The FrontPanel search must not find a library the developer happens to have.
    c.env_remove("OKFP_LIB");
    c
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A valid stream with `blinks` blinks.
fn stream(blinks: u32) -> Vec<u8> {
    stream_claiming(blinks, blinks as u64)
}

/// A stream with `blinks` blinks whose StreamEnd says `claimed`.
fn stream_claiming(blinks: u32, claimed: u64) -> Vec<u8> {
    let cfg = PipelineConfig::new(64, 48, 10, vec![1, 2, 1], 2, 20);
    let mut records = vec![Record::Start(cfg.stream_start())];
    for i in 0..blinks {
        records.push(Record::Blink(BlinkRecord {
            slot: (i % 32) as u8,
            flags: 0,
            anchor_x: (i % 60) as u16,
            anchor_y: 9,
            t_cross: 100 + i as u64,
            t_drop: 130 + i as u64,
            t_s: 95 + i as i64,
            t_e: 125 + i as i64,
            planes_summed: 40,
            roi_size: 3,
            counts: vec![1, 2, 1, 2, 5 + i % 9, 2, 1, 2, 1],
        }));
    }
    records.push(Record::End(StreamEnd {
        planes: 1000,
        blinks: claimed,
        ..Default::default()
    }));
    encode_stream(&records).unwrap()
}

fn download_file(input: &Path, out: &Path, extra: &[&str]) -> Output {
    smartagg()
        .arg("download")
        .arg(format!("--source=file:{}", input.display()))
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn a_whole_recording_is_copied_byte_for_byte_and_summarised() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = stream(25);
    let input = dir.path().join("in.rois");
    std::fs::write(&input, &bytes).unwrap();
    let out = dir.path().join("out.rois");
    let o = download_file(&input, &out, &[]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    assert_eq!(std::fs::read(&out).unwrap(), bytes);
    assert!(
        t.contains(&format!("{} bytes from file", bytes.len())),
        "{t}"
    );
    assert!(t.contains("27 packets, 25 blinks"), "{t}");
    assert!(t.contains("device totals: 1000 planes, 25 blinks"), "{t}");
    assert!(t.contains("27 packets decoded"), "{t}");
    assert!(t.contains("nothing lost"), "{t}");
    assert!(!t.contains("WARNING"), "{t}");
    // The sidecar gives localize the camera, with the stream's own sensor.
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out.rois.json")).unwrap()).unwrap();
    assert_eq!(side["camera"], "spcimager");
    assert_eq!(side["objective"], 150);
    let start = smartagg_model::packet::decode_all(&bytes)
        .packets
        .iter()
        .find_map(|p| match &p.record {
            smartagg_model::record::Record::Start(s) => Some((s.width, s.height)),
            _ => None,
        })
        .unwrap();
    assert_eq!(side["width"].as_u64(), Some(start.0 as u64));
    assert_eq!(side["height"].as_u64(), Some(start.1 as u64));
}

#[test]
fn the_output_may_not_overwrite_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = stream(3);
    let input = dir.path().join("in.rois");
    std::fs::write(&input, &bytes).unwrap();
    let link = dir.path().join("link.rois");
    std::fs::hard_link(&input, &link).unwrap();
    let o = download_file(&input, &link, &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("is the input file itself"));
    let o = download_file(&input, &input, &[]);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(t.contains("is the input file itself"), "{t}");
    assert_eq!(
        std::fs::read(&input).unwrap(),
        bytes,
        "the recording survives"
    );
}

#[test]
fn a_time_limit_stops_a_paced_file_and_the_prefix_is_kept() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = stream(2000);
    let input = dir.path().join("in.rois");
    std::fs::write(&input, &bytes).unwrap();
    let out = dir.path().join("out.rois");
    // 0.02 MB/s for 0.3 s: a few kilobytes of a ~100 kB stream.
    let args = ["--rate-mbps", "0.02", "--seconds", "0.3"];
    let o = download_file(&input, &out, &args);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(t.contains("no stream-end record"), "{t}");
    let got = std::fs::read(&out).unwrap();
    assert!(
        !got.is_empty() && got.len() < bytes.len(),
        "{} bytes",
        got.len()
    );
    assert_eq!(
        got,
        bytes[..got.len()],
        "the output is a prefix of the stream"
    );
    let o = download_file(&input, &out, &[&args[..], &["--allow-loss"]].concat());
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("WARNING: the stream has no stream-end record"));
}

#[test]
fn bad_source_values_and_misplaced_options_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.rois");
    let run = |args: &[&str]| {
        smartagg()
            .args(["download", "--quiet", "--out"])
            .arg(&out)
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&["--source", "serial:/dev/ttyUSB0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("--source `serial:/dev/ttyUSB0`: unknown source; expected frontpanel, usb, file:PATH or cosim:PRESET"), "{}", text(&o));
    let o = run(&["--source", "usb", "--rate-mbps", "5"]);
    assert!(
        text(&o).contains("--rate-mbps applies to file sources only"),
        "{}",
        text(&o)
    );
    let rec = dir.path().join("in.rois");
    std::fs::write(&rec, stream(2)).unwrap();
    let file = format!("file:{}", rec.display());
    let o = run(&["--source", &file, "--n-window", "50", "--calibration", "/x"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("--n-window, --calibration configure a device; a file source replays"),
        "{}",
        text(&o)
    );
    assert!(!out.exists(), "nothing written for refused options");
    let o = run(&["--source", "usb", "--n-window", "0"]);
    assert!(text(&o).contains("0 is not in 1.."), "{}", text(&o));
    let o = run(&["--source", "usb", "--vid", "zz"]);
    assert!(
        text(&o).contains("`zz` is not a hexadecimal 16-bit id"),
        "{}",
        text(&o)
    );
    let o = run(&["--source", "file:/nonexistent/in.rois"]);
    assert!(
        text(&o).contains("/nonexistent/in.rois: No such file"),
        "{}",
        text(&o)
    );
    assert!(
        !out.exists(),
        "no output is created when the source cannot open"
    );
}

#[test]
fn usb_without_a_matching_device_says_so_and_how_to_choose_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.rois");
    let o = smartagg()
        .args([
            "download", "--source", "usb", "--vid", "0xfffe", "--pid", "fffd", "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    // No bus at all (libusb cannot start) or a bus without the device.
    assert!(
        t.contains("no device matches USB fffe:fffd (set --vid/--pid to the firmware's ids; the stock XEM6310 needs --source frontpanel)")
            || t.contains("cannot list USB devices"),
        "{t}"
    );
    assert!(!out.exists());
    let o = smartagg()
        .args(["download", "--source", "usb", "--endpoint", "0x02", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        text(&o).contains("--endpoint 0x02 is an OUT endpoint"),
        "{}",
        text(&o)
    );
}

#[test]
fn frontpanel_without_the_sdk_names_where_it_looked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.rois");
    let missing = dir.path().join("sdk/libokFrontPanel.so");
    let o = smartagg()
        .env("OKFP_LIB", &missing)
        .args(["download", "--source", "frontpanel", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(
        t.contains(&format!(
            "Opal Kelly FrontPanel library not found (looked in {}): install the FrontPanel SDK, set OKFP_LIB=/path/to/libokFrontPanel.so, or use --source usb",
            missing.display()
        )),
        "{t}"
    );
    // A library that is not FrontPanel's: the missing function is named.
    let o = smartagg()
        .env("OKFP_LIB", "libc.so.6")
        .args(["download", "--source", "frontpanel", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(
        t.contains("libc.so.6 has no function okFrontPanel_Construct"),
        "{t}"
    );
    assert!(!out.exists());
}

#[test]
fn cosim_source_plays_the_verilated_gateware_and_refuses_bad_specs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.rois");
    for (spec, want) in [
        ("cosim:spcimager:0", "not a positive number of planes"),
        ("cosim:emccd", "emccd"),
    ] {
        let o = smartagg()
            .args(["download", "--source", spec, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{spec}: {t}");
        assert!(t.contains(want), "{spec}: {t}");
    }
    // Four bit-planes through the Verilated XEM6310 core (replay pipe-in),
    // configured through the register map like a board: the stream arrives
    // whole, from StreamStart to the device's StreamEnd.
    let o = smartagg()
        .args([
            "download",
            "--source",
            "cosim:spcimager:4",
            "--quiet",
            "--timeout",
            "600",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let t = text(&o);
    assert_eq!(o.status.code(), Some(0), "{t}");
    let bytes = std::fs::read(&out).unwrap();
    let d = smartagg_model::packet::decode_all(&bytes);
    assert!(!d.stats.any_loss(), "{}", d.stats);
    let records: Vec<&Record> = d.packets.iter().map(|p| &p.record).collect();
    assert!(
        matches!(records.first(), Some(Record::Start(_))),
        "{records:?}"
    );
    match records.last() {
        Some(Record::End(e)) => assert_eq!(e.planes, 4, "{e:?}"),
        other => panic!("the stream ends with {other:?}"),
    }
}

#[test]
fn a_repeated_capture_and_a_lying_stream_end_are_not_whole() {
    let dir = tempfile::tempdir().unwrap();
    let twice = [stream(4), stream(4)].concat();
    let lying = stream_claiming(4, u64::MAX);
    for (name, bytes, want) in [
        ("twice", &twice, "4 packets repeat earlier ones"),
        (
            "lying",
            &lying,
            "count 18446744073709551615 blinks but 4 arrived",
        ),
    ] {
        let input = dir.path().join(format!("{name}.rois"));
        std::fs::write(&input, bytes).unwrap();
        let out = dir.path().join(format!("{name}-out.rois"));
        let o = download_file(&input, &out, &[]);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {t}");
        assert!(t.contains(want), "{name}: {t}");
        // Kept as received, for the record.
        assert_eq!(&std::fs::read(&out).unwrap(), bytes);
        let o = download_file(&input, &out, &["--allow-loss"]);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", text(&o));
        assert!(text(&o).contains("WARNING"), "{name}");
    }
}
