//! Hostile input to every command that reads files or numbers: empty,
//! truncated, foreign (text where an image or a checkpoint is expected),
//! huge (an image header claiming 100,000 px a side) and out-of-range
//! inputs. Each must be refused: a failing exit status (never a panic or a
//! signal), exactly one line on stderr that names the file or the
//! argument at fault, and no output left behind. The suite counts the
//! inputs that were accepted (lax accepts) and the refusals that broke one
//! of these rules, and asserts there are none.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The hostile files, made once per test in a folder of their own.
struct Files {
    dir: tempfile::TempDir,
}

impl Files {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let files = Files { dir };
        let coffee = std::fs::read(Path::new(&assets("photos")).join("coffee.jpg")).unwrap();
        let png = std::fs::read(Path::new(&assets("textures")).join("grass.jpg")).unwrap();
        let png = {
            let image = image::load_from_memory(&png).unwrap().to_rgb8();
            let mut bytes = Vec::new();
            image
                .write_to(
                    &mut std::io::Cursor::new(&mut bytes),
                    image::ImageFormat::Png,
                )
                .unwrap();
            bytes
        };
        files.write("empty.jpg", b"");
        files.write("text.jpg", b"this is a text file, not a photo\n");
        files.write("cut.jpg", &coffee[..coffee.len() / 2]);
        files.write("cut.png", &png[..png.len() / 2]);
        files.write("huge.png", &huge_png_header());
        files.write("empty.toml", b"");
        files.write("binary.toml", &[0xFF, 0xFE, 0x00, 0x01, 0x9C, 0x80]);
        files.write("nan.toml", b"[scene]\np_hard = nan\n");
        files.write("range.toml", b"[scene]\nsize_min = 5\n");
        files.write("frames-inf.toml", b"frames = 100000000000\n");
        files.write("empty.json", b"");
        files.write(
            "colours.json",
            br#"{"model": "default", "radius": 5, "positive": [[1.0]], "negative": [], "positive_colours": [[1.0, 2.0]]}"#,
        );
        files.write("junk.json", b"{\"objects\": [1, 2,");
        // Saved selections that read as JSON but select nothing sound.
        let colours = format!("[{}]", vec!["1e30"; 32].join(", "));
        for (name, fields) in [
            (
                "zero.json",
                r#""positive": [[0.0, 0.0]], "negative": []"#.to_string(),
            ),
            (
                "huge.json",
                r#""positive": [[1e30, 1.0]], "negative": []"#.to_string(),
            ),
            (
                "max.json",
                r#""positive": [[3e38, 3e38]], "negative": []"#.to_string(),
            ),
            (
                "bright.json",
                format!(
                    r#""positive": [[1.0, 0.0]], "negative": [], "positive_colours": [{colours}]"#
                ),
            ),
            (
                "both.json",
                r#""positive": [[0.6, 0.8]], "negative": [[0.6, 0.8]]"#.to_string(),
            ),
        ] {
            files.write(
                name,
                format!(r#"{{"model": "default", "radius": 5, {fields}}}"#).as_bytes(),
            );
        }
        files.write(
            "far.json",
            br#"{"model": "default", "radius": -1, "positive": [[1.0]], "negative": []}"#,
        );
        files.write(
            "nameless.json",
            br#"{"model": "", "radius": 5, "positive": [[1.0]], "negative": []}"#,
        );
        files.write("empty.pth", b"");
        files.write("text.pth", b"not a checkpoint");
        files.write(
            "cut.safetensors",
            b"\x10\x00\x00\x00\x00\x00\x00\x00{\"a\":",
        );
        files.write("lying.safetensors", &lying_safetensors());
        for folder in [
            "bad-photos",
            "bench/images",
            "bench/data/cut",
            "masks",
            "blank",
        ] {
            std::fs::create_dir_all(files.path(folder)).unwrap();
        }
        for name in ["empty.jpg", "text.jpg", "cut.jpg"] {
            std::fs::copy(files.path(name), files.path(&format!("bad-photos/{name}"))).unwrap();
        }
        std::fs::copy(files.path("cut.jpg"), files.path("bench/images/cut.jpg")).unwrap();
        files.write(
            "bench/data/cut/data.json",
            br#"{"1": {"pt_im": [[10, 10, 5]]}, "2": {"pt_im": [[50, 50, 5]]}}"#,
        );
        std::fs::copy(files.path("cut.jpg"), files.path("masks/a.jpg")).unwrap();
        files.write("masks/a.mask0.png", &png[..png.len() / 3]);
        // A mask benchmark with nothing to score: its one mask is empty.
        let grass = image::load_from_memory(&png).unwrap();
        files.write("blank/a.png", &png);
        image::GrayImage::new(grass.width(), grass.height())
            .save(files.path("blank/a.mask0.png"))
            .unwrap();
        // Three small frames of a clip.
        std::fs::create_dir_all(files.path("frames")).unwrap();
        let frame = grass.resize_exact(64, 48, image::imageops::FilterType::Triangle);
        for k in 0..3 {
            frame
                .save(files.path(&format!("frames/{k:04}.png")))
                .unwrap();
        }
        // A generated dataset whose one sample lost its first mask.
        matseg_ok(&[
            "generate",
            "-n",
            "1",
            "--size-range",
            "64..64",
            "--out",
            &files.arg("gen-no-mask0"),
        ]);
        std::fs::remove_file(files.path("gen-no-mask0/00000000/mask0.png")).unwrap();
        // A selection the shipped model made, to apply.
        if cfg!(feature = "net") {
            let made = files.path("made");
            matseg_ok(&[
                "segment",
                &assets("photos/coffee.jpg"),
                "--point",
                "290,130",
                "--out",
                made.to_str().unwrap(),
            ]);
            std::fs::rename(made.join("selection_0.json"), files.path("selection.json")).unwrap();
        }
        files
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn arg(&self, name: &str) -> String {
        self.path(name).display().to_string()
    }

    fn write(&self, name: &str, bytes: &[u8]) {
        std::fs::write(self.path(name), bytes).unwrap();
    }
}

/// A PNG whose header says 100,000 x 100,000 pixels, with a few bytes of
/// data.
fn huge_png_header() -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut crc_input = kind.to_vec();
        crc_input.extend_from_slice(data);
        png.extend_from_slice(&crc_input);
        png.extend_from_slice(&crc32(&crc_input).to_be_bytes());
    };
    let mut header = Vec::new();
    header.extend_from_slice(&100_000u32.to_be_bytes());
    header.extend_from_slice(&100_000u32.to_be_bytes());
    header.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(b"IHDR", &header);
    chunk(b"IDAT", &[0x78, 0x9C, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    chunk(b"IEND", &[]);
    png
}

/// The CRC-32 PNG chunks carry.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// A safetensors file whose one tensor claims 2^40 floats.
fn lying_safetensors() -> Vec<u8> {
    let header =
        br#"{"w":{"dtype":"F32","shape":[1099511627776],"data_offsets":[0,4398046511104]}}"#;
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend_from_slice(header);
    bytes.extend_from_slice(&[0; 16]);
    bytes
}

/// One hostile run: the arguments, what its error must name, and the
/// output it must not leave (none for commands that write nothing).
struct Case {
    args: Vec<String>,
    names: String,
    out: Option<PathBuf>,
}

/// What went wrong with a case, if anything.
fn judge(case: &Case) -> Option<String> {
    let mut command = Command::new(env!("CARGO_BIN_EXE_matseg"));
    command.args(&case.args).env("MATSEG_CACHE", test_cache());
    let out = command.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let shown = format!("matseg {}", case.args.join(" "));
    let Some(code) = out.status.code() else {
        return Some(format!("{shown}: ended by a signal: {err}"));
    };
    if code == 0 {
        return Some(format!("{shown}: LAX ACCEPT (exit 0): {err}"));
    }
    let mut problems = Vec::new();
    if !matches!(code, 1 | 2) {
        problems.push(format!("exit {code}"));
    }
    if err.contains("panicked") {
        problems.push("a panic".into());
    }
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.starts_with("warning: "))
        .collect();
    if lines.len() != 1 || !lines[0].starts_with("error: ") {
        problems.push(format!("{} error lines", lines.len()));
    } else if !lines[0].contains(&case.names) {
        problems.push(format!("does not name {:?}", case.names));
    }
    if let Some(path) = &case.out {
        if path.exists() {
            problems.push(format!("left {}", path.display()));
        }
        let mut partial = path.as_os_str().to_owned();
        partial.push(".partial");
        if Path::new(&partial).exists() {
            problems.push("left a .partial folder".into());
        }
    }
    (!problems.is_empty()).then(|| format!("{shown}: {}: {err}", problems.join(", ")))
}

/// The output path the cases name: each case writes (or must not write)
/// to a folder of its own, `OUT` in its arguments.
const OUT: &str = "OUT";

/// The cases being listed; each `add` gives its case an output folder of
/// its own under `dir`.
struct Cases<'a> {
    dir: &'a Path,
    /// Names this list's output folders apart from another list's.
    prefix: &'a str,
    list: Vec<Case>,
}

impl Cases<'_> {
    fn add(&mut self, args: &[&str], names: &str) {
        let out = self.dir.join(format!("{}{}", self.prefix, self.list.len()));
        let args = args
            .iter()
            .map(|a| {
                if *a == OUT {
                    out.display().to_string()
                } else {
                    a.to_string()
                }
            })
            .collect();
        self.list.push(Case {
            args,
            names: names.to_string(),
            out: Some(out),
        });
    }
}

/// The cases every build has (no net needed).
fn cases(f: &Files) -> Vec<Case> {
    let o = OUT;
    let mut cases = Cases {
        dir: f.dir.path(),
        prefix: "out",
        list: Vec::new(),
    };
    let mut add = |args: &[&str], names: &str| cases.add(args, names);
    // Photos: one file of each kind, and a folder of only unusable ones.
    for photo in [
        "missing.jpg",
        "empty.jpg",
        "text.jpg",
        "cut.jpg",
        "cut.png",
        "huge.png",
    ] {
        let p = f.arg(photo);
        add(&["maps", &p, "--out", o], photo);
        add(&["textures", &p, "--out", o], photo);
        add(&["pbr", &p, "--out", o], photo);
        add(&["generate", "-n", "1", "--sources", &p, "--out", o], photo);
        add(
            &["generate", "-n", "1", "--textures", &p, "--out", o],
            photo,
        );
    }
    let bad = f.arg("bad-photos");
    add(
        &["generate", "-n", "2", "--sources", &bad, "--out", o],
        "bad-photos",
    );
    add(&["textures", &bad, "--out", o], "bad-photos");
    add(&["pbr", &bad, "--out", o], "bad-photos");
    add(&["pbr-mix", &bad, "--out", o], "bad-photos");
    // Recipes and camera paths.
    for config in [
        "empty.toml",
        "binary.toml",
        "nan.toml",
        "range.toml",
        "missing.toml",
    ] {
        if config != "empty.toml" {
            add(
                &[
                    "generate",
                    "-n",
                    "1",
                    "--config",
                    &f.arg(config),
                    "--out",
                    o,
                ],
                config,
            );
        }
    }
    for path in ["binary.toml", "frames-inf.toml", "junk.json"] {
        let p = f.arg(path);
        add(
            &[
                "generate",
                "--kind",
                "3d",
                "-n",
                "1",
                "--camera-path",
                &p,
                "--out",
                o,
            ],
            path,
        );
    }
    // Out-of-range numbers.
    add(
        &[
            "generate",
            "-n",
            "1",
            "--size-range",
            "0..100000",
            "--out",
            o,
        ],
        "size",
    );
    add(
        &["generate", "-n", "1", "--size-range", "a..b", "--out", o],
        "--size-range",
    );
    add(
        &["generate", "-n", "99999999999999999999", "--out", o],
        "99999999999999999999",
    );
    add(
        &[
            "generate",
            "-n",
            "1",
            "--shard-index",
            "3",
            "--num-shards",
            "2",
            "--out",
            o,
        ],
        "shard",
    );
    add(
        &["maps", &assets("photos/coffee.jpg"), "-n", "0", "--out", o],
        "-n",
    );
    add(
        &["textures", &assets("photos"), "--cell", "0", "--out", o],
        "--cell",
    );
    // Scene descriptions.
    for scene in ["empty.json", "junk.json", "text.jpg", "missing.json"] {
        add(&["render", &f.arg(scene), "--out", o], scene);
    }
    // Benchmarks.
    add(
        &[
            "eval",
            "points",
            &f.arg("bench"),
            "--baseline",
            "rgb",
            "--model",
            "none",
        ],
        "cut.jpg",
    );
    add(
        &["bench-set", "draw", &f.arg("bench"), "--out", o],
        "cut.jpg",
    );
    add(
        &[
            "eval",
            "masks",
            &f.arg("masks"),
            "--baseline",
            "rgb",
            "--model",
            "none",
        ],
        "a.",
    );
    add(
        &[
            "eval",
            "masks",
            &f.arg("masks"),
            "--radius",
            "1e9",
            "--model",
            "none",
        ],
        "radius",
    );
    add(&["bench-set", "make", "-n", "0", "--out", o], "--scenes");
    add(
        &[
            "eval",
            "clicks",
            &f.arg("blank"),
            "--baseline",
            "rgb",
            "--model",
            "none",
        ],
        "no mask could be scored",
    );
    add(
        &[
            "bench-set",
            "masks",
            "--from",
            &f.arg("gen-no-mask0"),
            "--out",
            o,
        ],
        "mask0.png is missing",
    );
    // Weights.
    for file in ["empty.pth", "text.pth", "cut.jpg", "missing.pth"] {
        add(&["weights", "import", &f.arg(file), "--out", o], file);
    }
    for file in ["cut.safetensors", "lying.safetensors", "text.pth"] {
        add(&["weights", "half", &f.arg(file), "--out", o], file);
    }
    cases.list
}

/// The cases of the commands that need the net.
#[cfg(feature = "net")]
fn net_cases(f: &Files) -> Vec<Case> {
    let o = OUT;
    let coffee = assets("photos/coffee.jpg");
    let mut cases = Cases {
        dir: f.dir.path(),
        prefix: "net-out",
        list: Vec::new(),
    };
    let mut add = |args: &[&str], names: &str| cases.add(args, names);
    for photo in ["empty.jpg", "text.jpg", "cut.jpg", "huge.png"] {
        add(
            &["segment", &f.arg(photo), "--point", "1,1", "--out", o],
            photo,
        );
    }
    for (flag, value, names) in [
        ("--point", "-5,10", "point -5,10"),
        ("--point", "9999,1", "point 9999,1"),
        ("--point", "1", "--point"),
        ("--radius", "-1", "radius -1"),
        ("--radius", "NaN", "radius NaN"),
        ("--radius", "1e9", "radius 1000000000"),
    ] {
        let mut args = vec!["segment", &coffee, "--out", o, flag, value];
        if flag != "--point" {
            args.extend(["--point", "1,1"]);
        }
        add(&args, names);
    }
    add(
        &["segment", &coffee, "--not", "1,1", "--out", o],
        "give a --point",
    );
    add(
        &[
            "segment", &coffee, "--point", "1,1", "--not", "1,9999", "--out", o,
        ],
        "not 1,9999",
    );
    add(
        &["segment", &coffee, "--point", "x:1,1", "--out", o],
        "x:1,1",
    );
    let many: Vec<&str> = std::iter::repeat_n(["--point", "1,1"], 300)
        .flatten()
        .collect();
    add(
        &[&["segment", coffee.as_str(), "--out", o], many.as_slice()].concat(),
        "300 points",
    );
    for selection in [
        "text.jpg",
        "empty.jpg",
        "colours.json",
        "zero.json",
        "huge.json",
        "max.json",
        "bright.json",
        "both.json",
        "far.json",
        "nameless.json",
    ] {
        add(
            &["apply", &f.arg(selection), &coffee, "--out", o],
            selection,
        );
    }
    add(
        &[
            "track",
            &f.arg("frames"),
            "--point",
            "30,45",
            "--not",
            "30,45",
            "--out",
            o,
        ],
        "not 30,45",
    );
    add(
        &[
            "segment",
            &coffee,
            "--point",
            "30,45",
            "--not",
            "30.5,45.2",
            "--out",
            o,
        ],
        "not 30.5,45.2",
    );
    // A truncated photo among good ones: refused before any is described.
    add(
        &[
            "apply",
            &f.arg("selection.json"),
            &coffee,
            &f.arg("cut.jpg"),
            "--out",
            o,
        ],
        "cut.jpg",
    );
    add(&["segment", &coffee, "--auto", "1", "--out", o], "--auto");
    add(&["segment", &coffee, "--auto", "900", "--out", o], "--auto");
    add(
        &[
            "segment",
            &coffee,
            "--point",
            "1,1",
            "--model",
            &f.arg("text.pth"),
            "--out",
            o,
        ],
        "text.pth",
    );
    add(
        &["track", &f.arg("bad-photos"), "--point", "1,1", "--out", o],
        "bad-photos",
    );
    add(
        &[
            "train",
            "--data",
            &f.arg("bad-photos"),
            "--steps",
            "1",
            "--out",
            o,
        ],
        "bad-photos",
    );
    add(
        &["features", "--data", &f.arg("bad-photos"), "--out", o],
        "bad-photos",
    );
    add(
        &["serve", "--bench", &f.arg("masks"), "--port", "0"],
        "masks",
    );
    add(
        &["serve", "--data", &f.arg("cut.jpg"), "--port", "0"],
        "cut.jpg",
    );
    add(&["serve", "--port", "0", "--upload-mb", "x"], "--upload-mb");
    cases.list
}

#[cfg(not(feature = "net"))]
fn net_cases(_: &Files) -> Vec<Case> {
    Vec::new()
}

#[test]
fn every_hostile_input_is_refused_in_one_line_with_nothing_left() {
    let files = Files::new();
    let all: Vec<Case> = cases(&files).into_iter().chain(net_cases(&files)).collect();
    let failures: Vec<String> = all.iter().filter_map(judge).collect();
    let lax = failures.iter().filter(|f| f.contains("LAX ACCEPT")).count();
    assert!(
        failures.is_empty(),
        "{} of {} hostile runs went wrong ({lax} lax accepts):\n{}",
        failures.len(),
        all.len(),
        failures.join("\n")
    );
}

/// Whether `dir` or anything below it is a `.partial` or `.tmp` leftover.
fn leftovers(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name.contains(".partial") || name.ends_with(".tmp") || name.contains(".tmp.") {
            found.push(path.clone());
        }
        if path.is_dir() {
            found.extend(leftovers(&path));
        }
    }
    found
}

#[test]
fn an_output_folder_named_with_a_trailing_slash_is_the_folder_itself() {
    let dir = tempfile::tempdir().unwrap();
    let textures = dir.path().join("textures");
    std::fs::create_dir(&textures).unwrap();
    std::fs::copy(
        Path::new(&assets("textures")).join("grass.jpg"),
        textures.join("grass.jpg"),
    )
    .unwrap();
    let out = |name: &str| format!("{}/", dir.path().join(name).display());
    let t = textures.display().to_string();
    let coffee = assets("photos/coffee.jpg");
    let mut runs: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "generate".into(),
                "-n".into(),
                "1".into(),
                "--size-range".into(),
                "64..64".into(),
                "--out".into(),
                out("gen"),
            ],
            "gen",
        ),
        (
            vec!["pbr".into(), t.clone(), "--out".into(), out("pbr")],
            "pbr",
        ),
        (
            vec!["maps".into(), coffee.clone(), "--out".into(), out("maps")],
            "maps",
        ),
        (
            vec![
                "textures".into(),
                assets("photos"),
                "--out".into(),
                out("tex"),
            ],
            "tex",
        ),
        (
            vec![
                "bench-set".into(),
                "make".into(),
                "-n".into(),
                "2".into(),
                "--out".into(),
                out("bench"),
            ],
            "bench",
        ),
    ];
    if cfg!(feature = "net") {
        runs.push((
            vec![
                "segment".into(),
                coffee.clone(),
                "--point".into(),
                "290,130".into(),
                "--out".into(),
                out("seg"),
            ],
            "seg",
        ));
    }
    for (args, name) in &runs {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let run = matseg(&args);
        assert!(run.status.success(), "{args:?}: {}", stderr(&run));
        let folder = dir.path().join(name);
        assert!(
            std::fs::read_dir(&folder).unwrap().next().is_some(),
            "{name}: written"
        );
        assert_eq!(leftovers(dir.path()), Vec::<PathBuf>::new(), "{args:?}");
    }
    // Mixing needs two materials: a second texture's.
    let run = matseg(&["pbr", &assets("textures"), "-n", "1", "--out", &out("pbr2")]);
    assert!(run.status.success(), "{}", stderr(&run));
    let mix = matseg(&[
        "pbr-mix",
        dir.path().join("pbr2").to_str().unwrap(),
        "-n",
        "1",
        "--out",
        &out("mix"),
    ]);
    assert!(mix.status.success(), "{}", stderr(&mix));
    assert_eq!(leftovers(dir.path()), Vec::<PathBuf>::new());
}
