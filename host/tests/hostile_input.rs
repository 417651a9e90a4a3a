//! Hostile input through the real binary (issue 36): `simulate`, `render`,
//! `download --source file:` and `.spad` reading. Every case gives a clear
//! error (never a panic, hang or runaway write) and leaves existing files as
//! they were.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn smartagg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_smartagg"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("the smartagg binary runs")
}

/// Runs and kills the command after `limit`; returns its output and whether
/// it had to be killed.
fn smartagg_within(args: &[&str], limit: Duration) -> (Output, bool) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_smartagg"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the smartagg binary runs");
    let t0 = Instant::now();
    let mut killed = false;
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > limit {
            let _ = child.kill();
            killed = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    (child.wait_with_output().unwrap(), killed)
}

/// The command fails cleanly (an error's exit status, not a panic's 101 or
/// a signal) and says something.
fn err(args: &[&str]) -> String {
    let o = smartagg(args);
    failed_cleanly(args, &o)
}

fn failed_cleanly(args: &[&str], o: &Output) -> String {
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        matches!(o.status.code(), Some(c) if c != 0 && c != 101),
        "smartagg {args:?}: {:?} {e}",
        o.status
    );
    assert!(!e.contains("panicked"), "smartagg {args:?}: {e}");
    assert!(
        !e.chars().any(|c| c.is_ascii_digit()) || !has_long_number(&e),
        "a number too long to read: {e}"
    );
    e
}

fn has_long_number(s: &str) -> bool {
    let mut run = 0;
    for c in s.chars() {
        run = if c.is_ascii_digit() { run + 1 } else { 0 };
        if run > 24 {
            return true;
        }
    }
    false
}

fn ok(args: &[&str]) -> String {
    let o = smartagg(args);
    assert!(
        o.status.success(),
        "smartagg {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

// ------------------------------------------------------------------ simulate

#[test]
fn simulate_checks_every_argument_before_touching_an_existing_output() {
    let dir = tempfile::tempdir().unwrap();
    let keep = dir.path().join("keep.spad");
    let before = b"precious recording".to_vec();
    std::fs::write(&keep, &before).unwrap();
    let cases: &[&[&str]] = &[
        &["--planes", "0"],
        &["--seconds", "0"],
        &["--seconds", "-1"],
        &["--seconds", "nan"],
        &["--seconds", "inf"],
        &["--seconds", "1e12"],
        &["--seconds", "1e9"],
        &["--planes", "18446744073709551615"],
        &["--planes", "10", "--flux", "1e300"],
        &["--planes", "10", "--blink-ms", "1e-320"],
        &["--planes", "10", "--max-out-gib", "0"],
    ];
    for extra in cases {
        let mut args = vec!["simulate", "--preset", "spcimager", "--out", s(&keep)];
        args.extend_from_slice(extra);
        let (o, killed) = smartagg_within(&args, Duration::from_secs(20));
        assert!(!killed, "{extra:?} ran on");
        let e = failed_cleanly(&args, &o);
        let opt = extra[extra.len() - 2];
        assert!(
            e.contains(opt),
            "{extra:?}: the error names the option: {e}"
        );
        assert_eq!(
            std::fs::read(&keep).unwrap(),
            before,
            "{extra:?} touched the file"
        );
        assert_eq!(
            names(dir.path()),
            ["keep.spad"],
            "{extra:?} left a file behind"
        );
    }
}

#[test]
fn simulate_refuses_absurd_sizes_with_the_limit_and_its_unit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.spad");
    let e = err(&[
        "simulate",
        "--preset",
        "spcimager",
        "--planes",
        "18446744073709551615",
        "--out",
        s(&out),
    ]);
    assert!(
        e.contains("GiB") && e.contains("--max-out-gib 64 GiB"),
        "{e}"
    );
    let e = err(&[
        "simulate",
        "--preset",
        "emccd",
        "--seconds",
        "1e9",
        "--out",
        s(&dir.path().join("big.tif")),
    ]);
    assert!(
        e.contains("--seconds") && e.contains("1e9 s") && e.contains("GiB"),
        "{e}"
    );
    assert!(names(dir.path()).is_empty());
}

#[test]
fn simulate_refuses_an_extension_that_says_another_format() {
    let dir = tempfile::tempdir().unwrap();
    let e = err(&[
        "simulate",
        "--preset",
        "emccd",
        "--planes",
        "2",
        "--out",
        s(&dir.path().join("e.spad")),
    ]);
    assert!(e.contains(".tif"), "{e}");
    let e = err(&[
        "simulate",
        "--preset",
        "spcimager",
        "--planes",
        "2",
        "--out",
        s(&dir.path().join("s.tif")),
    ]);
    assert!(e.contains(".spad"), "{e}");
    let e = err(&[
        "simulate",
        "--preset",
        "spcimager",
        "--planes",
        "2",
        "--raw",
        "--out",
        s(&dir.path().join("r.spad")),
    ]);
    assert!(e.contains("--raw") && e.contains(".bin"), "{e}");
    assert!(names(dir.path()).is_empty());
}

#[test]
fn simulate_extreme_light_finishes_or_is_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let tif = dir.path().join("e.tif");
    // Refused with the limit: no 300-digit number, no hang.
    for (opt, v, what) in [
        ("--flux", "1e300", "1e300"),
        ("--frame-ms", "1e308", "1e308"),
        ("--background", "1e300", "1e300"),
    ] {
        let args = [
            "simulate",
            "--preset",
            "emccd",
            "--planes",
            "2",
            opt,
            v,
            "--out",
            s(&tif),
        ];
        let (o, killed) = smartagg_within(&args, Duration::from_secs(20));
        assert!(!killed, "{opt} {v} ran on");
        let e = failed_cleanly(&args, &o);
        assert!(
            e.contains(opt) && e.contains(what) && e.contains("..="),
            "{e}"
        );
    }
    // The brightest allowed molecule and a vanishing intensity spread run.
    for extra in [
        ["--flux", "1e9", "--intensity-cv", "1e-320"],
        ["--flux", "1e-300", "--intensity-cv", "0"],
    ] {
        let mut args = vec![
            "simulate",
            "--preset",
            "emccd",
            "--scene",
            "random",
            "--field",
            "32x32",
            "--planes",
            "3",
            "--out",
            s(&tif),
        ];
        args.extend_from_slice(&extra);
        let (o, killed) = smartagg_within(&args, Duration::from_secs(30));
        assert!(!killed, "{extra:?} ran on");
        assert!(
            o.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    assert_eq!(names(dir.path()), ["e.tif", "e.tif.truth.csv"]);
}

#[test]
fn simulate_replaces_an_output_only_when_complete() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.spad");
    std::fs::write(&out, b"old").unwrap();
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--field",
        "16x16",
        "--planes",
        "50",
        "--out",
        s(&out),
    ]);
    assert_eq!(names(dir.path()), ["a.spad", "a.spad.truth.csv"]);
    assert_eq!(std::fs::metadata(&out).unwrap().len(), 48 + 50 * 32);
    // And a recording read back through aggregate's reader.
    let rois = dir.path().join("a.rois");
    let o = smartagg(&["aggregate", s(&out), "--out", s(&rois), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

// -------------------------------------------------------------- .spad input

#[test]
fn a_short_spad_claiming_huge_planes_fails_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let spad = dir.path().join("liar.spad");
    let mut b = Vec::new();
    b.extend_from_slice(b"SPADBITS");
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&48u16.to_le_bytes());
    b.extend_from_slice(&65535u32.to_le_bytes());
    b.extend_from_slice(&32768u32.to_le_bytes());
    b.extend_from_slice(&10_000u64.to_le_bytes());
    b.extend_from_slice(&10_000u64.to_le_bytes());
    b.extend_from_slice(&[0, 0, 0, 0]);
    b.extend_from_slice(&100u64.to_le_bytes());
    b.resize(4096, 0x11);
    std::fs::write(&spad, &b).unwrap();
    let rois = dir.path().join("x.rois");
    for engine in [&[][..], &["--engine", "golden"][..]] {
        let mut args = vec!["aggregate", s(&spad), "--out", s(&rois), "--quiet"];
        args.extend_from_slice(engine);
        let (o, killed) = smartagg_within(&args, Duration::from_secs(20));
        assert!(!killed);
        let e = failed_cleanly(&args, &o);
        assert!(
            e.contains("truncated inside plane 0") && e.contains("268431360"),
            "{e}"
        );
    }
    assert!(!rois.exists());
}

#[test]
fn aggregate_raw_on_an_empty_file_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("empty.bin");
    std::fs::write(&raw, b"").unwrap();
    let e = err(&[
        "aggregate",
        s(&raw),
        "--raw",
        "--width",
        "64",
        "--height",
        "64",
        "--out",
        s(&dir.path().join("x.rois")),
        "--quiet",
    ]);
    assert!(e.contains("empty") && e.contains("64x64"), "{e}");
}

// ---------------------------------------------------------- download file:

#[test]
fn download_rate_outside_its_range_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.rois");
    std::fs::write(&input, b"").unwrap();
    for rate in ["1e-100", "0", "1e300", "nan"] {
        let src = format!("file:{}", s(&input));
        let e = err(&[
            "download",
            "--source",
            &src,
            "--out",
            s(&dir.path().join("o.rois")),
            "--rate-mbps",
            rate,
            "--quiet",
        ]);
        assert!(
            e.contains("--rate-mbps") && e.contains("MB/s"),
            "{rate}: {e}"
        );
    }
}

#[cfg(unix)]
#[test]
fn download_from_a_fifo_without_writer_honours_the_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success());
    let src = format!("file:{}", s(&fifo));
    let out = dir.path().join("o.rois");
    let args = [
        "download",
        "--source",
        &src,
        "--out",
        s(&out),
        "--timeout",
        "1",
        "--quiet",
    ];
    let t0 = Instant::now();
    let (o, killed) = smartagg_within(&args, Duration::from_secs(30));
    assert!(!killed, "blocked in open()");
    assert!(t0.elapsed() < Duration::from_secs(15));
    let e = failed_cleanly(&args, &o);
    assert!(e.contains("pipe"), "{e}");
}

#[cfg(target_os = "linux")]
#[test]
fn download_of_dev_zero_stops_as_not_a_stream() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.rois");
    let args = [
        "download",
        "--source",
        "file:/dev/zero",
        "--out",
        s(&out),
        "--quiet",
    ];
    let (o, killed) = smartagg_within(&args, Duration::from_secs(30));
    assert!(!killed, "copied /dev/zero for ever");
    let e = failed_cleanly(&args, &o);
    assert!(
        e.contains("/dev/zero") && e.contains("not a packet stream"),
        "{e}"
    );
    let written = std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0);
    assert!(written <= 8 << 20, "{written} bytes written");
}

#[test]
fn download_from_a_directory_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let src = format!("file:{}", s(dir.path()));
    let e = err(&[
        "download",
        "--source",
        &src,
        "--out",
        s(&dir.path().join("o.rois")),
        "--quiet",
    ]);
    assert!(e.contains("is a directory"), "{e}");
}

// ------------------------------------------------------------------- render

const TABLE: &str = "\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"uncertainty [nm]\",\"fit_status\"\n";

#[test]
fn render_never_writes_over_its_table() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path().join("t.csv");
    let body = format!("{TABLE}1,1,500,400,10,0\n2,1,520,410,10,0\n");
    std::fs::write(&t, &body).unwrap();
    let e = err(&["render", s(&t), "--out", s(&t)]);
    assert!(e.contains("destroy the input"), "{e}");
    let link = dir.path().join("hard.png");
    std::fs::hard_link(&t, &link).unwrap();
    let e = err(&["render", s(&t), "--out", s(&link)]);
    assert!(e.contains("destroy the input"), "{e}");
    assert_eq!(std::fs::read_to_string(&t).unwrap(), body);
    // A failure leaves an existing image as it was.
    let png = dir.path().join("img.png");
    std::fs::write(&png, b"old image").unwrap();
    let empty = dir.path().join("empty.csv");
    std::fs::write(&empty, TABLE).unwrap();
    err(&["render", s(&empty), "--out", s(&png)]);
    assert_eq!(std::fs::read(&png).unwrap(), b"old image");
    ok(&["render", s(&t), "--out", s(&png)]);
    assert_ne!(std::fs::read(&png).unwrap(), b"old image");
    assert_eq!(
        names(dir.path()),
        ["empty.csv", "hard.png", "img.png", "t.csv"]
    );
}

#[cfg(target_os = "linux")]
#[test]
fn render_of_dev_zero_reads_a_bounded_line() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("z.png");
    let args = ["render", "/dev/zero", "--out", s(&png)];
    let (o, killed) = smartagg_within(&args, Duration::from_secs(20));
    assert!(!killed);
    let e = failed_cleanly(&args, &o);
    assert!(
        e.contains("/dev/zero") && e.contains("not a CSV table"),
        "{e}"
    );
}

#[test]
fn render_skips_outliers_and_bad_rows_and_counts_them() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path().join("t.csv");
    let mut body = TABLE.to_string();
    for i in 0..20 {
        body += &format!("{i},1,{},{},10,0\n", 500 + 7 * i, 400 + 3 * i);
    }
    body += "90,1,1e300,400,10,0\n"; // far outside
    body += "91,1,600,1e12,10,0\n"; // far outside
    body += "92,1,600,450,1e200,0\n"; // hopeless uncertainty
    body += "93,1,600,oops,10,0\n"; // not a number
    body += "94,1,600\n"; // short row
    std::fs::write(&t, &body).unwrap();
    let png = dir.path().join("img.png");
    let o = smartagg(&["render", s(&t), "--out", s(&png)]);
    let (out, e) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{e}");
    assert!(out.contains("20 localisations rendered"), "{out}");
    assert!(
        out.contains("3 outliers left out") && out.contains("2 rows not numbers"),
        "{out}"
    );
    assert!(
        e.contains("2 rows skipped") && e.contains("3 localisations far"),
        "{e}"
    );
    // Only outliers: an error that says so.
    let t2 = dir.path().join("t2.csv");
    std::fs::write(&t2, format!("{TABLE}1,1,0,0,10,0\n2,1,1e300,0,10,0\n")).unwrap();
    let o = smartagg(&["render", s(&t2), "--out", s(&png)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_header_claiming_a_huge_sensor_with_no_planes_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let spad = dir.path().join("zero.spad");
    let mut h = b"SPADBITS".to_vec();
    h.extend_from_slice(&1u16.to_le_bytes());
    h.extend_from_slice(&48u16.to_le_bytes());
    h.extend_from_slice(&65535u32.to_le_bytes());
    h.extend_from_slice(&32768u32.to_le_bytes());
    h.extend_from_slice(&100_000u64.to_le_bytes());
    h.extend_from_slice(&100_000u64.to_le_bytes());
    h.extend_from_slice(&[0, 0, 0, 0]);
    h.extend_from_slice(&0u64.to_le_bytes());
    assert_eq!(h.len(), 48);
    std::fs::write(&spad, &h).unwrap();
    let out = dir.path().join("z.rois");
    for engine in ["golden", "fast"] {
        let o = smartagg(&[
            "aggregate",
            spad.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--engine",
            engine,
        ]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains("at most 16777216 pixels"), "{e}");
        assert!(!out.exists());
    }
}
