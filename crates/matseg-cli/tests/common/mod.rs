//! Helpers of the `matseg` binary's end-to-end tests.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// The cache the tests' `matseg` runs use: the tests' own, so a corpus the
/// developer fetched does not become their default sources.
pub fn test_cache() -> std::path::PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("matseg-cache")
}

pub fn matseg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_matseg"))
        .args(args)
        .env("MATSEG_CACHE", test_cache())
        .output()
        .unwrap()
}

/// Runs `matseg` and asserts that it succeeded (stderr in the message).
pub fn matseg_ok(args: &[&str]) -> Output {
    let out = matseg(args);
    assert!(out.status.success(), "{}", stderr(&out));
    out
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub fn assets(sub: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets")
        .join(sub)
        .display()
        .to_string()
}

/// Asserts failure with exactly one line on stderr that contains `needle`.
pub fn assert_one_line_error(out: &Output, needle: &str) {
    let err = stderr(out);
    assert!(!out.status.success(), "expected failure, got: {err}");
    assert_eq!(err.lines().count(), 1, "not one line: {err}");
    assert!(err.starts_with("error: ") && err.contains(needle), "{err}");
}
