//! `matseg generate --frames`, `matseg track` and `matseg eval track` end
//! to end: sequences with exact labels, a material followed through them
//! from a frame folder and from videos, and one-line errors for bad input.
//! Videos are made and read with the ffmpeg that scripts/ffmpeg-env.sh
//! installs (as .ci/run does).

#![cfg(feature = "net")]

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The ffmpeg program matseg uses (see `matseg_pipeline::frames`).
fn ffmpeg() -> PathBuf {
    let ffmpeg = matseg_pipeline::frames::ffmpeg_program("ffmpeg");
    assert!(
        matseg_pipeline::frames::ffmpeg_available(),
        "{} does not run: scripts/ffmpeg-env.sh installs it",
        ffmpeg.display()
    );
    ffmpeg
}

/// Runs ffmpeg with `args`, asserting success.
fn run_ffmpeg(args: &[&str]) {
    let out = Command::new(ffmpeg())
        .args(["-v", "error", "-y"])
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
}

/// A sequence of `frames` frames of one 128 px scene with two materials,
/// generated into `out` with `threads` workers.
fn generate_sequence(dir: &Path, out: &Path, frames: u32, threads: &str) -> std::process::Output {
    let recipe = dir.join("recipe.toml");
    std::fs::write(
        &recipe,
        "p_single_object = 1.0\np_many_materials = 0.0\ndistinct_materials = true\n\
         p_transmissive = 0.0\np_metal = 0.0\np_ground = 0.0\np_distractors = 0.0\n\
         map_scale_log10 = [-0.3, 0.2]\n",
    )
    .unwrap();
    matseg(&[
        "generate",
        "--kind",
        "3d",
        "--frames",
        &frames.to_string(),
        "-n",
        "1",
        "--seed",
        "6",
        "--size",
        "128",
        "--spp",
        "4",
        "--config",
        recipe.to_str().unwrap(),
        "--threads",
        threads,
        "--out",
        out.to_str().unwrap(),
    ])
}

/// Pixels of a frame of [`generate_sequence`].
const PIXELS: f64 = 128.0 * 128.0;

/// The bytes of every image and mask of a dataset, by file.
fn dataset_bytes(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files = Vec::new();
    for sample in std::fs::read_dir(root).unwrap().map(|e| e.unwrap().path()) {
        if !sample.is_dir() {
            continue;
        }
        for file in std::fs::read_dir(&sample)
            .unwrap()
            .map(|e| e.unwrap().path())
        {
            let name = file.file_name().unwrap().to_string_lossy().into_owned();
            if name.ends_with(".png") || name.ends_with(".jpg") {
                let key = format!("{}/{name}", sample.file_name().unwrap().to_string_lossy());
                files.push((key, std::fs::read(&file).unwrap()));
            }
        }
    }
    files.sort();
    files
}

fn grey(path: &Path) -> image::GrayImage {
    image::open(path).unwrap().to_luma8()
}

/// The `k`-th output file of each kind in a track folder, sorted.
fn pngs(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    files
}

#[test]
fn a_generated_sequence_is_followed_on_every_frame_from_folders_and_videos() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("seq");
    let result = generate_sequence(dir.path(), &data, 6, "2");
    assert!(result.status.success(), "{}", stderr(&result));

    // Byte-identical with one thread, and resumed after a lost frame.
    let again = dir.path().join("again");
    assert!(generate_sequence(dir.path(), &again, 6, "1")
        .status
        .success());
    assert_eq!(dataset_bytes(&data), dataset_bytes(&again));
    std::fs::remove_file(again.join("00000004/Finished.txt")).unwrap();
    assert!(generate_sequence(dir.path(), &again, 6, "2")
        .status
        .success());
    assert_eq!(dataset_bytes(&data), dataset_bytes(&again));
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data.join("00000004/meta.json")).unwrap()).unwrap();
    assert_eq!(
        meta["frame"],
        serde_json::json!({"sequence": 0, "frame": 4, "frames": 6})
    );

    // The benchmark: the clicked material is found on every frame.
    let eval = matseg_ok(&["eval", "track", data.to_str().unwrap(), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&eval.stdout).unwrap();
    assert_eq!(report["sequences"], 1);
    assert_eq!(report["frames"], 6);
    for query in report["per_query"].as_array().unwrap() {
        let ious: Vec<f64> = query["memory"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|v| v.as_f64())
            .collect();
        assert_eq!(ious.len(), 6, "{query}");
        assert!(ious.iter().all(|&iou| iou >= 0.6), "{query}");
    }

    // The frames as a folder, a lossless video and an H.264 one.
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    for f in 0..6 {
        let image = image::open(data.join(format!("{f:08}/RGB__RGB.jpg")))
            .unwrap()
            .to_rgb8();
        image.save(frames.join(format!("f{f}.png"))).unwrap();
    }
    let pattern = frames.join("f%d.png");
    let lossless = dir.path().join("frames.mkv");
    let h264 = dir.path().join("frames.mp4");
    run_ffmpeg(&[
        "-framerate",
        "10",
        "-i",
        pattern.to_str().unwrap(),
        "-c:v",
        "ffv1",
        "-pix_fmt",
        "bgr0",
        lossless.to_str().unwrap(),
    ]);
    run_ffmpeg(&[
        "-framerate",
        "10",
        "-i",
        pattern.to_str().unwrap(),
        "-c:v",
        "libx264",
        "-crf",
        "12",
        "-pix_fmt",
        "yuv444p",
        h264.to_str().unwrap(),
    ]);
    let click = report["per_query"][0]["point"].as_array().unwrap();
    let point = format!("{},{}", click[0], click[1]);
    let track = |source: &Path, out: &str, extra: &[&str]| {
        let out = dir.path().join(out);
        let mut args = vec![
            "track",
            source.to_str().unwrap(),
            "--point",
            &point,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        matseg_ok(&args);
        out
    };
    let from_folder = track(&frames, "t-folder", &[]);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(from_folder.join("track.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], 6);
    assert_eq!(summary["areas"].as_array().unwrap().len(), 6);
    assert_eq!(summary["overlay"], "overlay.mp4");
    assert!(from_folder.join("overlay.mp4").is_file());
    let labels = pngs(&from_folder.join("labels"));
    assert_eq!(labels.len(), 6);
    assert_eq!(pngs(&from_folder.join("similarity/0")).len(), 6);
    // The labels cover the clicked material and the areas count them.
    let material = report["per_query"][0]["material"].as_u64().unwrap();
    for (f, file) in labels.iter().enumerate() {
        let l = grey(file);
        let truth = grey(&data.join(format!("{f:08}/mask{material}.png")));
        let (mut both, mut either, mut labelled) = (0, 0, 0);
        for (a, t) in l.as_raw().iter().zip(truth.as_raw()) {
            let (a, t) = (*a == 1, *t >= 128);
            both += (a && t) as u32;
            either += (a || t) as u32;
            labelled += a as u32;
        }
        assert!(
            both as f64 / either as f64 >= 0.5,
            "frame {f}: IoU {}",
            both as f64 / either as f64
        );
        let area = summary["areas"][f][0].as_f64().unwrap();
        assert!((area - labelled as f64 / PIXELS).abs() < 1e-9);
    }
    // The lossless video gives the very same maps; H.264 nearly.
    let from_mkv = track(&lossless, "t-mkv", &[]);
    for kind in ["labels", "similarity/0"] {
        for (a, b) in pngs(&from_folder.join(kind))
            .iter()
            .zip(pngs(&from_mkv.join(kind)))
        {
            assert_eq!(grey(a), grey(&b), "{}", a.display());
        }
    }
    let from_mp4 = track(&h264, "t-mp4", &[]);
    for (a, b) in labels.iter().zip(pngs(&from_mp4.join("labels"))) {
        let (a, b) = (grey(a), grey(&b));
        let same = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .filter(|(x, y)| x == y)
            .count();
        assert!(
            same as f64 >= 0.95 * PIXELS,
            "{same} of {PIXELS} pixels agree"
        );
    }
    // An animated PNG preview on request; a second run replaces the output.
    let preview = track(&frames, "t-folder", &["--preview"]);
    assert!(preview.join("overlay.png").is_file() && !preview.join("overlay.mp4").exists());
    let apng = std::fs::read(preview.join("overlay.png")).unwrap();
    assert!(apng.windows(4).any(|w| w == b"acTL"), "an animated PNG");
}

#[test]
fn bad_videos_and_settings_are_one_line_errors_that_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name);
    let frames = d("frames");
    std::fs::create_dir(&frames).unwrap();
    for f in 0..4 {
        image::RgbImage::from_pixel(32, 24, image::Rgb([40 * f, 90, 160]))
            .save(frames.join(format!("{f}.png")))
            .unwrap();
    }
    let video = d("clip.mp4");
    let pattern = frames.join("%d.png");
    run_ffmpeg(&[
        "-framerate",
        "10",
        "-i",
        pattern.to_str().unwrap(),
        "-c:v",
        "libx264",
        "-pix_fmt",
        "yuv420p",
        "-movflags",
        "+faststart",
        video.to_str().unwrap(),
    ]);
    let bytes = std::fs::read(&video).unwrap();
    std::fs::write(d("truncated.mp4"), &bytes[..bytes.len() * 2 / 3]).unwrap();
    std::fs::write(
        d("random.mp4"),
        (0..4000u32)
            .map(|i| (i * 7919 % 251) as u8)
            .collect::<Vec<_>>(),
    )
    .unwrap();
    std::fs::create_dir(d("empty")).unwrap();
    let mixed = d("mixed");
    std::fs::create_dir(&mixed).unwrap();
    std::fs::copy(frames.join("0.png"), mixed.join("a.png")).unwrap();
    image::RgbImage::new(30, 24)
        .save(mixed.join("b.png"))
        .unwrap();
    let huge = d("huge");
    std::fs::create_dir(&huge).unwrap();
    image::GrayImage::new(16400, 1)
        .save(huge.join("f.png"))
        .unwrap();

    let cases: [(&Path, &[&str], String); 8] = [
        (
            &d("random.mp4"),
            &[],
            format!("{}: not a readable video", d("random.mp4").display()),
        ),
        (
            &d("truncated.mp4"),
            &[],
            format!(
                "{}: corrupt or truncated video",
                d("truncated.mp4").display()
            ),
        ),
        (
            &d("empty"),
            &[],
            "no frames (PNG or JPEG files) in the folder".into(),
        ),
        (
            &mixed,
            &[],
            "b.png: frame is 30x24, the first frame 32x24".into(),
        ),
        (
            &huge,
            &[],
            "frames are 16400x1; frames up to 8192 px a side".into(),
        ),
        (
            &frames,
            &["--point", "32,5"],
            "point 32,5: outside frame 0".into(),
        ),
        (&frames, &["--frame", "9"], "frame 9: past the end:".into()),
        (&video, &["--frame", "7"], "has 4 frames".into()),
    ];
    for (source, extra, needle) in &cases {
        let out = d("out");
        let mut args = vec![
            "track",
            source.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        if !extra.contains(&"--point") {
            args.extend(["--point", "3,3"]);
        }
        args.extend_from_slice(extra);
        assert_one_line_error(&matseg(&args), needle);
        assert!(
            !out.exists() && !d("out.partial").exists(),
            "{needle}: output left behind"
        );
    }
    // A folder that is not a track output is never replaced.
    let taken = d("taken");
    std::fs::create_dir(&taken).unwrap();
    std::fs::write(taken.join("keep.txt"), "mine").unwrap();
    let out = matseg(&[
        "track",
        frames.to_str().unwrap(),
        "--point",
        "3,3",
        "--out",
        taken.to_str().unwrap(),
    ]);
    assert_one_line_error(&out, "holds \"keep.txt\", which matseg did not write");
    assert!(taken.join("keep.txt").is_file());
    // Nor is an earlier output with a file of the user's beside it.
    let track_into = |out: &str| {
        matseg(&[
            "track",
            frames.to_str().unwrap(),
            "--point",
            "3,3",
            "--out",
            out,
        ])
    };
    let earlier = d("earlier");
    assert!(track_into(earlier.to_str().unwrap()).status.success());
    std::fs::write(earlier.join("notes.txt"), "mine").unwrap();
    let listing = |dir: &Path| {
        let mut names: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        names
    };
    let before = listing(&earlier);
    let out = track_into(&format!("{}/", earlier.display()));
    assert_one_line_error(
        &out,
        "holds \"notes.txt\", which `matseg track` did not write",
    );
    assert_eq!(listing(&earlier), before);
    // A trailing slash names the folder itself: its earlier output is
    // replaced, and nothing is left beside or inside it.
    std::fs::remove_file(earlier.join("notes.txt")).unwrap();
    for out in [
        format!("{}/", earlier.display()),
        format!("{}//.", earlier.display()),
    ] {
        let run = track_into(&out);
        assert!(run.status.success(), "{out}: {}", stderr(&run));
        assert!(earlier.join("track.json").is_file(), "{out}");
        assert!(
            !d("earlier.partial").exists() && !earlier.join(".partial").exists(),
            "{out}"
        );
    }
    // Radii out of range, and a negative coordinate taken as a point.
    for (extra, needle) in [
        (
            ["--radius", "-1"],
            "radius -1: give a disc radius from 0 to 256 pixels",
        ),
        (["--radius", "NaN"], "radius NaN: give a disc radius"),
        (["--point", "-5,10"], "point -5,10: outside frame 0"),
    ] {
        let out = d("out");
        let mut args = vec![
            "track",
            frames.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(&extra);
        if extra[0] != "--point" {
            args.extend(["--point", "3,3"]);
        }
        assert_one_line_error(&matseg(&args), needle);
        assert!(!out.exists(), "{needle}");
    }
    // Sequences are 3D only; a dataset without frames is no track benchmark.
    let two_d = matseg(&[
        "generate",
        "--frames",
        "4",
        "-n",
        "1",
        "--out",
        d("g").to_str().unwrap(),
    ]);
    assert_one_line_error(&two_d, "add --kind 3d");
}
