//! `smartagg drift` end to end: a seeded nanoruler simulation with stage
//! drift, aggregated and localised by the CLI, is corrected and the
//! estimated trajectory compared with the drift the truth reports.

use std::path::Path;

mod common;
use common::*;

fn err(args: &[&str]) -> String {
    let out = smartagg(args);
    assert!(!out.status.success(), "smartagg {args:?} should fail");
    assert_eq!(
        out.status.code(),
        Some(2),
        "an error, not a crash: {args:?}"
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A CSV file as a header and rows of fields.
fn read_csv(path: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(|s| s.trim_matches('"').to_string())
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

fn col(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// RMS of `a − b` over pairs of 2-D vectors, after removing the mean
/// difference (a drift estimate is relative to its first segment).
fn rms_about_mean(d: &[(f64, f64)]) -> f64 {
    let n = d.len() as f64;
    let mx = d.iter().map(|v| v.0).sum::<f64>() / n;
    let my = d.iter().map(|v| v.1).sum::<f64>() / n;
    (d.iter()
        .map(|v| (v.0 - mx).powi(2) + (v.1 - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
}

#[test]
fn rcc_recovers_the_simulated_drift() {
    let dir = tempfile::tempdir().unwrap();
    let rec = p(dir.path(), "rulers.spad");
    // 20 s of a 32x32 field (1.7 µm) of dense rulers, blinking often:
    // ~1000 localisations, ~100 per segment; the stage wanders 100 nm.
    ok(&[
        "simulate",
        "--preset",
        "spcimager",
        "--scene",
        "nanoruler",
        "--field",
        "32x32",
        "--seconds",
        "20",
        "--density",
        "4",
        "--mean-off-s",
        "0.5",
        "--drift-nm",
        "100",
        "--seed",
        "3",
        "--out",
        &rec,
    ]);
    let rois = p(dir.path(), "blinks.rois");
    ok(&["aggregate", &rec, "--out", &rois, "--quiet"]);
    let locs = p(dir.path(), "locs.csv");
    ok(&["localize", &rois, "--out", &locs]);
    let out = p(dir.path(), "corrected.csv");
    let said = ok(&["drift", &locs, "--out", &out, "--frame-s", "1e-4"]);
    assert!(said.contains("RCC: 10 segments"), "{said}");
    let traj = p(dir.path(), "corrected.drift.csv");
    assert!(
        std::fs::metadata(p(dir.path(), "corrected.drift.png"))
            .unwrap()
            .len()
            > 1000
    );

    // The truth's drift, blink by blink, at the middle of each blink.
    let (th, truth) = read_csv(&format!("{rec}.truth.csv"));
    let (ton, toff, dx, dy) = (
        col(&th, "t_on_s"),
        col(&th, "t_off_s"),
        col(&th, "drift_x_nm"),
        col(&th, "drift_y_nm"),
    );
    let mut true_drift: Vec<(f64, f64, f64)> = truth
        .iter()
        .map(|r| {
            let f = |k: usize| r[k].parse::<f64>().unwrap();
            let t0 = f(ton).max(0.0);
            (0.5 * (t0 + f(toff).max(t0)), f(dx), f(dy))
        })
        .collect();
    true_drift.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Blinks start ~80 times a second: the nearest one in time is within
    // ~10 ms, when the stage moves ~0.1 nm.
    let drift_at = |t: f64| {
        let i = true_drift.partition_point(|d| d.0 < t);
        let j = [i.saturating_sub(1), i.min(true_drift.len() - 1)]
            .into_iter()
            .min_by(|&a, &b| {
                (true_drift[a].0 - t)
                    .abs()
                    .total_cmp(&(true_drift[b].0 - t).abs())
            })
            .unwrap();
        (true_drift[j].1, true_drift[j].2)
    };

    let (sh, segs) = read_csv(&traj);
    assert_eq!(segs.len(), 10);
    let (ts, ex, ey) = (col(&sh, "t_mean_s"), col(&sh, "dx_nm"), col(&sh, "dy_nm"));
    let mut residual = Vec::new();
    let mut uncorrected = Vec::new();
    for s in &segs {
        let f = |k: usize| s[k].parse::<f64>().unwrap();
        let d = drift_at(f(ts));
        residual.push((f(ex) - d.0, f(ey) - d.1));
        uncorrected.push(d);
    }
    let (rms, before) = (rms_about_mean(&residual), rms_about_mean(&uncorrected));
    // Each segment's shift rests on ~100 localisations of ~12 nm precision:
    // ≈ 12·√(2/100) ≈ 1.7 nm per axis, ≈ 2.4 nm in 2-D; 6 nm is 2.5 times
    // that. Uncorrected, the drift itself spreads by tens of nm.
    assert!(before > 25.0, "uncorrected drift RMS {before:.1} nm");
    assert!(
        rms < 6.0,
        "residual drift {rms:.2} nm (uncorrected {before:.1} nm)"
    );

    // The corrected table: the same rows and columns, only x and y moved.
    let (h0, r0) = read_csv(&locs);
    let (h1, r1) = read_csv(&out);
    assert_eq!(h0, h1);
    assert_eq!(r0.len(), r1.len());
    let (cx, cy) = (col(&h0, "x [nm]"), col(&h0, "y [nm]"));
    let mut moved = 0;
    for (a, b) in r0.iter().zip(&r1) {
        for k in 0..a.len() {
            if k != cx && k != cy {
                assert_eq!(a[k], b[k]);
            }
        }
        moved += usize::from(a[cx] != b[cx] || a[cy] != b[cy]);
    }
    assert!(moved > r0.len() / 2, "{moved} of {} rows moved", r0.len());

    // Nanoruler markers are no fiducials at ~3 localisations per segment.
    let e = err(&["drift", &locs, "--out", &out, "--method", "fiducials"]);
    assert!(e.contains("no fiducial"), "{e}");
}

#[test]
fn bad_tables_and_options_are_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let out = p(dir.path(), "out.csv");
    let empty = p(dir.path(), "empty.csv");
    std::fs::write(&empty, "").unwrap();
    assert!(err(&["drift", &empty, "--out", &out]).contains("empty"));
    let header = "\"id\",\"frame\",\"x [nm]\",\"y [nm]\",\"fit_status\"\n";
    let one = p(dir.path(), "one.csv");
    std::fs::write(&one, format!("{header}1,1,10,20,0\n")).unwrap();
    assert!(err(&["drift", &one, "--out", &out]).contains("at least 100"));
    let nan = p(dir.path(), "nan.csv");
    std::fs::write(&nan, format!("{header}1,1,NaN,20,0\n")).unwrap();
    assert!(err(&["drift", &nan, "--out", &out]).contains("non-finite"));
    let no_time = p(dir.path(), "no_time.csv");
    std::fs::write(&no_time, "\"x [nm]\",\"y [nm]\"\n1,2\n").unwrap();
    assert!(err(&["drift", &no_time, "--out", &out]).contains("no time column"));
    // Every row at one frame.
    let still = p(dir.path(), "still.csv");
    let mut text = header.to_string();
    for i in 0..200 {
        text.push_str(&format!("{},5,{},{},0\n", i + 1, i * 7 % 300, i * 13 % 300));
    }
    std::fs::write(&still, &text).unwrap();
    assert!(err(&["drift", &still, "--out", &out]).contains("same time"));
    // Options, and the input is never an output.
    assert!(err(&["drift", &still, "--out", &still]).contains("destroy the input"));
    assert!(err(&["drift", &still, "--out", &out, "--segments", "1"]).contains("segments"));
    assert!(err(&["drift", &still, "--out", &out, "--pixel-nm", "0"]).contains("bin"));
    assert!(err(&["drift", &still, "--out", &out, "--frame-s", "nan"]).contains("--frame-s"));
    assert!(err(&["drift", &still, "--out", &out, "--segment-s", "5"]).contains("--frame-s"));
    assert!(
        !Path::new(&out).exists(),
        "nothing written by a refused run"
    );
}
