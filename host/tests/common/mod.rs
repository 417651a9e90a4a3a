//! Running the `smartagg` binary from the CLI tests (each test file uses
//! some of these).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs `smartagg ARGS`.
pub fn smartagg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_smartagg"))
        .args(args)
        .output()
        .expect("the smartagg binary runs")
}

/// Runs `smartagg ARGS`, which must succeed; its stdout.
pub fn ok(args: &[&str]) -> String {
    let out = smartagg(args);
    assert!(
        out.status.success(),
        "smartagg {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `smartagg ARGS`, which must fail; its stderr.
pub fn err(args: &[&str]) -> String {
    let out = smartagg(args);
    assert!(!out.status.success(), "smartagg {args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `dir/name` as a string argument.
pub fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_str().unwrap().to_string()
}
