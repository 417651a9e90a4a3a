//! Sharded runs merge into exactly what one run writes, and the outputs a
//! person reads (CSV, PNG, Markdown) are produced; bad shard sets and
//! corrupted files are refused with a message naming the problem.

use smartagg_study::spec::{Plan, Shard, StudyName, StudyOptions};
use smartagg_study::{run, StudyError};
use std::path::Path;

fn plan() -> Plan {
    Plan::new(
        StudyName::SmartVsFixed,
        StudyOptions {
            blinks_per_point: 12,
            block: 4,
            bootstrap: 50,
            points: Some(vec![30.0, 60.0]),
            ..Default::default()
        },
    )
    .unwrap()
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn shards_merge_bit_identically_and_outputs_are_written() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = plan();
    let whole = tmp.path().join("whole");
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let w = run::run_to_dir(&plan, Shard::ALL, &whole, &|_, _| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap();
    // 2 points x 3 blocks, plus the initial call.
    assert_eq!(calls.into_inner(), 7);
    assert!(w.warnings.is_empty(), "{:?}", w.warnings);
    for f in [
        "points.csv",
        "ratios.csv",
        "timing.csv",
        "summary.md",
        "smart-vs-fixed.png",
    ] {
        assert!(whole.join(f).exists(), "{f} missing");
    }
    let png = read(&whole.join("smart-vs-fixed.png"));
    assert_eq!(&png[1..4], b"PNG");
    assert!(png.len() > 10_000, "a real plot, not an empty image");
    let md = String::from_utf8(read(&whole.join("summary.md"))).unwrap();
    assert!(md.contains("53.3 nm") && md.contains("detection") && md.contains("time s"));
    // The notes' figures are named as the default run's, with its command.
    assert!(
        md.contains("earlier results, not this run's")
            && md.contains("`smartagg study smart-vs-fixed --out DIR`"),
        "{md}"
    );
    let points = String::from_utf8(read(&whole.join("points.csv"))).unwrap();
    // Header plus 2 points x 5 schemes, every one with the matching rule.
    assert_eq!(points.lines().count(), 1 + 2 * 5);
    assert!(points.lines().skip(1).all(|l| l.ends_with(",53.3")));
    let columns = points.lines().next().unwrap().split(',').count();
    assert!(points.lines().all(|l| l.split(',').count() == columns));
    assert!(!points.contains("NaN") && !points.contains("inf"));

    for n in [2u32, 3] {
        let dirs: Vec<_> = (1..=n)
            .map(|i| {
                let d = tmp.path().join(format!("shard-{i}-of-{n}"));
                let w =
                    run::run_to_dir(&plan, Shard { index: i, count: n }, &d, &|_, _| {}).unwrap();
                // Shards write only raw results.
                assert!(!d.join("points.csv").exists());
                assert_eq!(w.files.len(), 4);
                d
            })
            .collect();
        let merged = tmp.path().join(format!("merged-{n}"));
        run::merge_to_dir(&dirs, &merged).unwrap();
        for f in ["points.csv", "ratios.csv", "blinks.csv", "items.csv"] {
            assert!(
                read(&whole.join(f)) == read(&merged.join(f)),
                "{f} differs after merging {n} shards"
            );
        }
    }
}

#[test]
fn incomplete_duplicate_or_foreign_shards_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = plan();
    let s1 = tmp.path().join("s1");
    let s2 = tmp.path().join("s2");
    run::run_to_dir(&plan, Shard { index: 1, count: 2 }, &s1, &|_, _| {}).unwrap();
    run::run_to_dir(&plan, Shard { index: 2, count: 2 }, &s2, &|_, _| {}).unwrap();
    let out = tmp.path().join("out");
    let e = run::merge_to_dir(std::slice::from_ref(&s1), &out).unwrap_err();
    assert!(
        matches!(e, StudyError::Merge(_)) && e.to_string().contains("missing"),
        "{e}"
    );
    let e = run::merge_to_dir(&[s1.clone(), s2.clone(), s1.clone()], &out).unwrap_err();
    assert!(e.to_string().contains("in both"), "{e}");
    // A shard of another seed.
    let other = Plan::new(
        StudyName::SmartVsFixed,
        StudyOptions {
            seed: 2,
            ..plan.options.clone()
        },
    )
    .unwrap();
    let s3 = tmp.path().join("s3");
    run::run_to_dir(&other, Shard { index: 2, count: 2 }, &s3, &|_, _| {}).unwrap();
    let e = run::merge_to_dir(&[s1.clone(), s3], &out).unwrap_err();
    assert!(e.to_string().contains("different run"), "{e}");
    // A corrupted row names its file and line.
    let blinks = s2.join("blinks.csv");
    let text = std::fs::read_to_string(&blinks).unwrap();
    let bad = text.replacen(",spcimager-150x/", ",spcimager-150x/x", 1);
    std::fs::write(&blinks, bad).unwrap();
    let e = run::merge_to_dir(&[s1.clone(), s2.clone()], &out).unwrap_err();
    assert!(matches!(e, StudyError::Parse { line: 2, .. }), "{e}");
    assert!(e.to_string().contains("blinks.csv"), "{e}");
    let negative = text.replacen(
        ",spcimager-150x/fixed,0,0,",
        ",spcimager-150x/fixed,0,-1,",
        1,
    );
    if negative != text {
        std::fs::write(&blinks, negative).unwrap();
        let e = run::merge_to_dir(&[s1.clone(), s2.clone()], &out).unwrap_err();
        assert!(e.to_string().contains("not negative"), "{e}");
    }
    let truncated: String = text.lines().take(5).map(|l| format!("{l}\n")).collect();
    std::fs::write(&blinks, truncated).unwrap();
    let e = run::merge_to_dir(&[s1, s2], &out).unwrap_err();
    assert!(e.to_string().contains("rows"), "{e}");
    // Missing directory.
    let e = run::merge_to_dir(&[tmp.path().join("nope")], &out).unwrap_err();
    assert!(e.to_string().contains("manifest.json"), "{e}");
}

#[test]
fn bad_shard_and_options_are_named() {
    for bad in ["0/2", "3/2", "x", "1/"] {
        let e = Shard::parse(bad).unwrap_err().to_string();
        assert!(e.contains(bad), "{e}");
    }
    let e = Plan::new(
        StudyName::HotPixels,
        StudyOptions {
            points: Some(vec![95.0]),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("hot-pixel"), "{e}");
    use smartagg_study::spec::LMin;
    let e = LMin::parse("soon").unwrap_err();
    assert!(e.to_string().contains("l-min"), "{e}");
    // `design` keeps the field design's L_min; a number overrides it; the
    // false-alarm bound on the paper's threshold (`auto`) is gone.
    assert_eq!(LMin::parse("design").unwrap(), LMin::Design);
    assert!(LMin::parse("auto").is_err());
    assert_eq!(LMin::parse("7").unwrap(), LMin::Planes(7));
    assert!(LMin::parse("auto:2").is_err());
    assert_eq!(
        LMin::parse(&LMin::Design.to_string()).unwrap(),
        LMin::Design
    );
}
