//! The Slurm scripts of `tools/slurm`, run here without Slurm: every task of
//! the job array (`SLURM_ARRAY_TASK_ID` set, as Slurm does) and then the
//! merge job give exactly the files of one unsharded run; `submit.sh`
//! validates its options, and submits the merge with a dependency on the
//! array (a stand-in `sbatch` records the calls).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_smartagg");

fn slurm_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/slurm")
}

/// A tiny smart-vs-fixed study (as `study/tests/shards.rs`): seconds.
const STUDY_ARGS: [&str; 8] = [
    "--blinks-per-point",
    "12",
    "--block",
    "4",
    "--bootstrap",
    "50",
    "--points",
    "30,60",
];

fn check(out: Output, what: &str) -> String {
    assert!(
        out.status.success(),
        "{what} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn array_tasks_and_the_merge_job_give_the_unsharded_result() {
    let tmp = tempfile::tempdir().unwrap();
    let results = tmp.path().join("results");
    let r = results.to_str().unwrap();
    let n = 3;
    for task in 1..=n {
        let out = Command::new("bash")
            .arg(slurm_dir().join("study-array.sbatch"))
            .args(["smart-vs-fixed", &n.to_string(), r, BIN])
            .args(STUDY_ARGS)
            .env("SLURM_ARRAY_TASK_ID", task.to_string())
            .env("SLURM_CPUS_PER_TASK", "1")
            .output()
            .unwrap();
        check(out, &format!("array task {task}"));
        assert!(results
            .join(format!("shard-{task}-of-{n}/manifest.json"))
            .exists());
    }
    // A task index outside the array is refused.
    let out = Command::new("bash")
        .arg(slurm_dir().join("study-array.sbatch"))
        .args(["smart-vs-fixed", &n.to_string(), r, BIN])
        .env("SLURM_ARRAY_TASK_ID", "4")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("1..3"));
    let out = Command::new("bash")
        .arg(slurm_dir().join("study-merge.sbatch"))
        .args([&n.to_string(), r, BIN])
        .output()
        .unwrap();
    check(out, "merge job");
    let whole = tmp.path().join("whole");
    let out = Command::new(BIN)
        .args([
            "study",
            "smart-vs-fixed",
            "--quiet",
            "--threads",
            "1",
            "--out",
        ])
        .arg(&whole)
        .args(STUDY_ARGS)
        .output()
        .unwrap();
    check(out, "unsharded study");
    for f in ["points.csv", "ratios.csv", "blinks.csv", "items.csv"] {
        assert!(
            read(&whole.join(f)) == read(&results.join("merged").join(f)),
            "{f} differs between the merged array and one run"
        );
    }
    assert!(results.join("merged/summary.md").exists());
}

fn submit(args: &[&str], path: Option<&Path>) -> Output {
    let mut c = Command::new("bash");
    c.arg(slurm_dir().join("submit.sh")).args(args);
    if let Some(dir) = path {
        let old = std::env::var("PATH").unwrap_or_default();
        c.env("PATH", format!("{}:{old}", dir.display()));
    }
    c.output().unwrap()
}

#[test]
fn submit_names_the_dependency_and_validates_its_options() {
    let tmp = tempfile::tempdir().unwrap();
    let results = tmp.path().join("res");
    let r = results.to_str().unwrap();
    let base = [
        "--experiment",
        "smart-vs-fixed",
        "--shards",
        "4",
        "--results",
        r,
        "--binary",
        BIN,
    ];
    let dry: Vec<&str> = base
        .iter()
        .copied()
        .chain(["--dry-run", "--", "--blinks-per-point", "12"])
        .collect();
    let out = check(submit(&dry, None), "submit.sh --dry-run");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    assert!(
        lines[0].starts_with("sbatch ")
            && lines[0].contains("--array=1-4")
            && lines[0].contains("study-array.sbatch smart-vs-fixed 4 ")
            && lines[0].contains("--blinks-per-point 12"),
        "{out}"
    );
    assert!(
        lines[1].contains("--dependency=afterok:ARRAY_JOB_ID")
            && lines[1].contains("study-merge.sbatch 4 "),
        "{out}"
    );
    assert!(!results.exists(), "a dry run creates nothing");

    // Submitting: a stand-in sbatch prints job ids and records its calls.
    let bin = tmp.path().join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let log = tmp.path().join("sbatch.log");
    let fake = bin.join("sbatch");
    std::fs::write(
        &fake,
        format!(
            "#!/bin/bash\necho \"$*\" >> {log}\nn=$(wc -l < {log})\necho $((1000 + n))\n",
            log = log.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let out = check(submit(&base, Some(&bin)), "submit.sh");
    assert!(
        out.contains("array job 1001") && out.contains("merge job 1002"),
        "{out}"
    );
    let calls = std::fs::read_to_string(&log).unwrap();
    let calls: Vec<&str> = calls.lines().collect();
    assert!(calls[0].contains("--array=1-4"), "{calls:?}");
    assert!(calls[1].contains("--dependency=afterok:1001"), "{calls:?}");
    assert!(results.join("logs").is_dir());

    // Bad options are refused before anything is submitted.
    for (args, needle) in [
        (
            vec![
                "--experiment",
                "nanoruler",
                "--shards",
                "2",
                "--results",
                r,
                "--binary",
                BIN,
            ],
            "shards",
        ),
        (
            vec![
                "--experiment",
                "smart-vs-fixed",
                "--shards",
                "0",
                "--results",
                r,
                "--binary",
                BIN,
            ],
            "1..1000",
        ),
        (
            vec![
                "--experiment",
                "smart-vs-fixed",
                "--shards",
                "2",
                "--binary",
                BIN,
            ],
            "--results",
        ),
        (
            vec![
                "--experiment",
                "smart-vs-fixed",
                "--shards",
                "2",
                "--results",
                r,
                "--binary",
                "/nonexistent/smartagg",
            ],
            "not executable",
        ),
        (
            vec!["--shards", "2", "--results", r, "--binary", BIN],
            "--experiment",
        ),
        (
            vec![
                "--experiment",
                "smart-vs-fixed",
                "--shards",
                "2",
                "--results",
                r,
                "--binary",
                BIN,
                "--",
                "--out",
                "x",
            ],
            "--out",
        ),
    ] {
        let out = submit(&args, Some(&bin));
        assert!(!out.status.success(), "{args:?} accepted");
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains(needle), "{args:?}: {e}");
    }
    assert_eq!(std::fs::read_to_string(&log).unwrap().lines().count(), 2);
}

/// The scripts are shellcheck-clean (`scripts/setup.sh` installs shellcheck;
/// without it this test fails rather than skips).
#[test]
fn scripts_are_shellcheck_clean() {
    let scripts = ["submit.sh", "study-array.sbatch", "study-merge.sbatch"];
    let out = Command::new("shellcheck")
        .args(scripts.iter().map(|s| slurm_dir().join(s)))
        .output()
        .expect("shellcheck must be installed (bash scripts/setup.sh installs it)");
    check(out, "shellcheck");
}
