//! Test videos are made with the ffmpeg matseg uses (scripts/ffmpeg-env.sh
//! installs it; `make test` runs that first).

// Each test binary uses its own share of these.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::path::Path;

/// Runs ffmpeg (errors only) with `args`; the test fails with its message
/// when it cannot run or fails.
pub fn run_ffmpeg<I: AsRef<OsStr>>(args: impl IntoIterator<Item = I>) {
    let ffmpeg = matseg_pipeline::frames::ffmpeg_program("ffmpeg");
    let out = std::process::Command::new(&ffmpeg)
        .args(["-v", "error"])
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "{}: {e}; scripts/ffmpeg-env.sh installs it",
                ffmpeg.display()
            )
        });
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// FFmpeg's test pattern, 160x120, 6 frames, lossless (FFV1 in MKV).
pub fn write_test_pattern(file: &Path) {
    let pattern = ["-f", "lavfi", "-i", "testsrc=size=160x120:rate=10"];
    let output = ["-frames:v", "6", "-c:v", "ffv1"].map(OsStr::new);
    run_ffmpeg(
        pattern
            .map(OsStr::new)
            .into_iter()
            .chain(output)
            .chain([file.as_os_str()]),
    );
}
