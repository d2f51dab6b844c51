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

/// A small scene: a split blob lit by the bundled forest HDRI, on a ground.
pub fn write_scene(dir: &Path) -> std::path::PathBuf {
    let scene = serde_json::json!({
        "width": 40, "height": 30, "spp": 4, "seed": 2,
        "camera": {"position": {"x": 0, "y": -150, "z": 60}, "target": {"x": 0, "y": 0, "z": 30}},
        "environment": {"hdri": assets("hdris/forest.exr"), "rotation_deg": 40},
        "materials": [
            {"base_color": {"x": 0.8, "y": 0.1, "z": 0.1}},
            {"base_color": {"x": 0.9, "y": 0.9, "z": 0.9}, "metallic": 1.0, "roughness": 0.2},
            {"base_color": {"x": 0.3, "y": 0.3, "z": 0.3}}
        ],
        "maps": [{"photo": assets("photos/coffee.jpg"), "channel": "R", "normalise": "max"}],
        "objects": [
            {"mesh": {"primitive": {"shape": "blob", "seed": 1, "bumps": 5, "amplitude": 0.2}}, "radius": 30,
             "main": true, "transform": {"translation": {"x": 0, "y": 0, "z": 30}},
             "surface": {"split": {"map": 0, "placement": {"scale": 0.5}, "ramp": {"low": 0.4, "high": 0.6},
                                   "below": {"material": 0}, "above": {"material": 1}}}},
            {"mesh": "plane", "transform": {"scale": 300}, "surface": {"material": 2}}
        ]
    });
    let path = dir.join("scene.json");
    std::fs::write(&path, serde_json::to_vec_pretty(&scene).unwrap()).unwrap();
    path
}
