//! Test videos are made with the ffmpeg matseg uses (scripts/ffmpeg-env.sh
//! installs it; `make test` runs that first).

use std::ffi::OsStr;

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
