//! Property tests of the checks `FrameSource::open` makes of the video
//! frames a user names: a folder of image files, or a video whose stream
//! ffprobe describes (width, height, frame rate, frame count, rotation).
//!
//! A folder whose files have image extensions but hold anything (random
//! bytes, the start of a PNG or JPEG and then anything, valid frames of
//! different sizes among them) opens to frames that each read or fail, or
//! fails to open, with a one-line error naming a file of the folder, never
//! a panic. For videos, ffprobe is replaced by a program that answers with
//! the file's own bytes, so any answer can be given: whatever it holds,
//! opening gives a source or a one-line error naming the video, and a
//! frame rate written as ffprobe writes them (`30000/1001`, `25/1`,
//! `0/0` when unknown) gives that rate, or 25 when there is none. FFmpeg
//! itself is not tested here.

#[path = "../../../testing/properties.rs"]
mod support;

use image::RgbImage;
use matseg_pipeline::frames::FrameSource;
use proptest::prelude::*;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The seed of the cases.
const SEED: u64 = 6;

fn config() -> ProptestConfig {
    support::config(SEED)
}

/// Points `MATSEG_FFMPEG` at a folder whose `ffprobe` prints its last
/// argument, the file it is asked about: a "video" there is the answer
/// ffprobe gives about it. Set once, before any test of this file reads a
/// video (the variable is read by nothing else here).
fn fake_ffprobe() {
    static FOLDER: OnceLock<tempfile::TempDir> = OnceLock::new();
    FOLDER.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let ffprobe = dir.path().join("ffprobe");
        std::fs::write(
            &ffprobe,
            "#!/bin/sh\nfor last; do :; done\ncat -- \"$last\"\n",
        )
        .unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&ffprobe, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::env::set_var("MATSEG_FFMPEG", dir.path().join("ffmpeg"));
        dir
    });
}

/// Checks that `error` is one line that starts with one of `named` (a
/// file or folder). A decoder's message may end in a newline (the JPEG
/// decoder's do, and image errors keep them); no other is allowed.
fn names_one_of(error: &impl std::fmt::Display, named: &[PathBuf]) -> Result<(), TestCaseError> {
    let text = error.to_string();
    prop_assert!(!text.contains('\n'), "{:?}", text);
    prop_assert!(
        named
            .iter()
            .any(|p| text.starts_with(&p.display().to_string())),
        "{} names none of {:?}",
        text,
        named
    );
    Ok(())
}

/// Opens `path`: a source, or one line naming one of `named`.
fn open(path: &Path, named: &[PathBuf]) -> Result<Option<FrameSource>, TestCaseError> {
    match FrameSource::open(path) {
        Ok(source) => Ok(Some(source)),
        Err(e) => {
            names_one_of(&e, named)?;
            Ok(None)
        }
    }
}

// ---------------------------------------------------------------- folders

/// A frame file: a valid PNG of a few sizes, or bytes that start as a PNG
/// or a JPEG does (or not at all) and go on with anything.
#[derive(Clone, Debug)]
enum Frame {
    Png(u32, u32),
    Bytes(&'static [u8], Vec<u8>),
}

fn frame() -> impl Strategy<Value = Frame> {
    prop_oneof![
        (1u32..4, 1u32..4).prop_map(|(w, h)| Frame::Png(w, h)),
        (
            prop::sample::select(vec![
                &b""[..],
                b"\x89PNG\r\n\x1a\n",
                b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR",
                b"\xff\xd8\xff",
                b"\xff\xd8\xff\xc0\0\x11\x08",
            ]),
            prop::collection::vec(any::<u8>(), 0..96),
        )
            .prop_map(|(start, rest)| Frame::Bytes(start, rest)),
    ]
}

fn frame_bytes(frame: &Frame) -> Vec<u8> {
    match frame {
        Frame::Png(w, h) => {
            matseg_image::io::encode_png_rgb(&RgbImage::from_pixel(*w, *h, image::Rgb([9, 8, 7])))
        }
        Frame::Bytes(start, rest) => [start.to_vec(), rest.clone()].concat(),
    }
}

// ---------------------------------------------------------------- videos

/// Rates as ffprobe writes them: a fraction of integers, `0/0` when the
/// rate is unknown, now and then a decimal.
fn ffprobe_rate() -> impl Strategy<Value = (String, Option<f64>)> {
    prop_oneof![
        (1u32..1_000_000, 1u32..100_000)
            .prop_map(|(n, d)| (format!("{n}/{d}"), Some(n as f64 / d as f64))),
        Just(("0/0".to_string(), None)),
        (0u32..1000).prop_map(|n| (format!("{n}/0"), None)),
        (1u32..240).prop_map(|n| (format!("{n}"), Some(n as f64))),
        (0.01f64..1000.0).prop_map(|r| (format!("{r}"), Some(r))),
    ]
}

/// Any text where a rate goes: numbers of every form, signs, slashes.
fn any_rate() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<String>(),
        "[-+0-9.eE/a-z ]{0,12}",
        (any::<f64>(), any::<f64>()).prop_map(|(n, d)| format!("{n}/{d}")),
        prop::sample::select(vec![
            "inf",
            "-inf",
            "NaN",
            "nan/1",
            "1/inf",
            "1e300/1e-300",
            "1e-300/1e300",
            "/",
            "1/",
            "/1",
            "1//1",
            "-1/-1",
            "0x10/1",
            "1/0",
            "",
        ])
        .prop_map(str::to_string),
    ]
}

/// JSON numbers of every size and sign.
fn json_number() -> impl Strategy<Value = Value> {
    prop_oneof![
        (0u64..20_000).prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        Just(Value::from(u32::MAX as u64 + 17)),
        (-1e6f64..1e6).prop_map(Value::from),
    ]
}

/// An ffprobe answer for one stream, every field of any value or left out.
fn probe_answer() -> impl Strategy<Value = Value> {
    let field = |values: BoxedStrategy<Value>| prop::option::of(values);
    (
        field(json_number().boxed()),
        field(json_number().boxed()),
        field(any_rate().prop_map(Value::from).boxed()),
        field(
            prop_oneof![
                (0u64..1000).prop_map(|n| Value::from(n.to_string())),
                any::<String>().prop_map(Value::from),
                json_number(),
            ]
            .boxed(),
        ),
        field(json_number().boxed()),
    )
        .prop_map(|(width, height, rate, packets, rotation)| {
            let mut stream = serde_json::Map::new();
            for (key, value) in [
                ("width", width),
                ("height", height),
                ("avg_frame_rate", rate),
                ("nb_read_packets", packets),
            ] {
                if let Some(value) = value {
                    stream.insert(key.into(), value);
                }
            }
            if let Some(rotation) = rotation {
                stream.insert("side_data_list".into(), json!([{ "rotation": rotation }]));
            }
            json!({ "streams": [stream] })
        })
}

/// Writes `answer` as a video file in a new folder: the folder and file.
fn video(answer: &[u8]) -> (tempfile::TempDir, PathBuf) {
    fake_ffprobe();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("clip.mp4");
    std::fs::write(&path, answer).unwrap();
    (dir, path)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn folders_of_any_frames_open_or_name_a_file(
        frames in prop::collection::vec(
            (frame(), prop::sample::select(vec!["png", "jpg", "jpeg", "PNG", "txt"])),
            0..5,
        ),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let mut named = vec![dir.path().to_path_buf()];
        for (k, (frame, ext)) in frames.iter().enumerate() {
            let path = dir.path().join(format!("frame{k:03}.{ext}"));
            std::fs::write(&path, frame_bytes(frame)).unwrap();
            named.push(path);
        }
        if let Some(source) = open(dir.path(), &named)? {
            // Every file it reads is one of the folder's images, each of
            // the size of the first, else an error naming it.
            for frame in source.frames().unwrap() {
                match frame {
                    Ok(f) => prop_assert_eq!(f.dimensions(), (source.width, source.height)),
                    Err(e) => names_one_of(&e, &named[1..])?,
                }
            }
        }
    }

    #[test]
    fn rates_as_ffprobe_writes_them_are_read(
        (rate, want) in ffprobe_rate(),
        (w, h) in (1u64..4000, 1u64..4000),
        frames in 1u64..10_000,
    ) {
        let answer = json!({ "streams": [{
            "width": w, "height": h, "avg_frame_rate": rate, "nb_read_packets": frames.to_string(),
        }] });
        let (_dir, path) = video(answer.to_string().as_bytes());
        let source = FrameSource::open(&path).unwrap();
        prop_assert_eq!(source.fps, want.unwrap_or(25.0));
        prop_assert!(source.fps.is_finite() && source.fps > 0.0);
        prop_assert_eq!((source.width as u64, source.height as u64), (w, h));
        prop_assert_eq!(source.frame_count(), frames);
    }

    #[test]
    fn rates_of_any_text_never_panic(rate in any_rate()) {
        let answer = json!({ "streams": [{
            "width": 8, "height": 8, "avg_frame_rate": rate, "nb_read_packets": "3",
        }] });
        let (_dir, path) = video(answer.to_string().as_bytes());
        let source = FrameSource::open(&path).unwrap();
        prop_assert!(!source.fps.is_nan());
    }

    #[test]
    fn probe_answers_of_any_values_open_or_name_the_video(answer in probe_answer()) {
        let (_dir, path) = video(answer.to_string().as_bytes());
        if let Some(source) = open(&path, std::slice::from_ref(&path))? {
            let side = matseg_pipeline::frames::MAX_FRAME_SIDE;
            prop_assert!((1..=side).contains(&source.width) && (1..=side).contains(&source.height));
            prop_assert!(source.frame_count() > 0);
        }
    }

    #[test]
    fn probe_answers_of_arbitrary_bytes_are_errors(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
        let (_dir, path) = video(&bytes);
        open(&path, std::slice::from_ref(&path))?;
    }
}
