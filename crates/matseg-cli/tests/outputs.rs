//! What every command that writes files may do to its output
//! (docs/outputs.md), case by case: an `--out` inside an input, an input
//! inside `--out`, a foreign `OUT.partial`, foreign files under the names
//! the command writes, an earlier output of another run, and a kill
//! during the write. A refused case must exit with status 1 and one error
//! line naming the path at fault, and leave every file that was there
//! before byte-identical.

mod common;

use common::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Every file below `root` with its bytes (relative path -> bytes).
fn snapshot(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                files.insert(path.strip_prefix(root).unwrap().to_path_buf(), bytes);
            }
        }
    }
    files
}

/// The inputs the commands read, made once: photos with a licence list
/// of the user's, textures, a scene, a frame folder, a point benchmark, a
/// generated dataset, a material library, weights and (with the net) a
/// saved selection.
struct Inputs {
    dir: tempfile::TempDir,
}

impl Inputs {
    fn new() -> Self {
        let inputs = Inputs {
            dir: tempfile::tempdir().unwrap(),
        };
        let copy = |from: String, to: &str| {
            let to = inputs.path(to);
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(from, to).unwrap();
        };
        copy(assets("photos/coffee.jpg"), "photos/coffee.jpg");
        copy(assets("photos/chelsea.jpg"), "photos/chelsea.jpg");
        std::fs::write(
            inputs.path("photos/licenses.json"),
            r#"{"coffee.jpg": "CC0-1.0", "chelsea.jpg": "CC0-1.0"}"#,
        )
        .unwrap();
        copy(assets("textures/grass.jpg"), "textures/grass.jpg");
        copy(assets("textures/brick.jpg"), "textures/brick.jpg");
        write_scene(inputs.dir.path());
        let frame = image::open(assets("photos/coffee.jpg"))
            .unwrap()
            .resize_exact(64, 48, image::imageops::FilterType::Triangle)
            .to_rgb8();
        std::fs::create_dir_all(inputs.path("clip/frames")).unwrap();
        for k in 0..3 {
            frame
                .save(inputs.path(&format!("clip/frames/{k:04}.png")))
                .unwrap();
        }
        let photos = inputs.arg("photos");
        let textures = inputs.arg("textures");
        let sources = ["--sources", &photos, "--textures", &textures];
        let make = |args: &[&str]| matseg_ok(&[args, &sources[..]].concat());
        make(&[
            "bench-set",
            "make",
            "-n",
            "2",
            "--out",
            &inputs.arg("bench"),
        ]);
        make(&[
            "generate",
            "-n",
            "1",
            "--size-range",
            "64..64",
            "--out",
            &inputs.arg("gen"),
        ]);
        matseg_ok(&["pbr", &textures, "-n", "1", "--out", &inputs.arg("mats")]);
        copy(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../models/default/model.safetensors")
                .display()
                .to_string(),
            "weights/model.safetensors",
        );
        if cfg!(feature = "net") {
            let out = inputs.path("made-selection");
            matseg_ok(&[
                "segment",
                &inputs.arg("photos/coffee.jpg"),
                "--point",
                "290,130",
                "--out",
                out.to_str().unwrap(),
            ]);
            std::fs::rename(out.join("selection_0.json"), inputs.path("selection.json")).unwrap();
            std::fs::remove_dir_all(out).unwrap();
        }
        inputs
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn arg(&self, name: &str) -> String {
        self.path(name).display().to_string()
    }
}

/// Runs `args` (`OUT` stands for `out`) and asserts it is refused: exit
/// status 1, one error line holding each of `names` (the paths at fault),
/// and every file below `root` as it was.
fn assert_refused(root: &Path, args: &[&str], out: &Path, names: &[&str]) {
    let before = snapshot(root);
    let out = out.display().to_string();
    let args: Vec<&str> = args
        .iter()
        .map(|&a| if a == "OUT" { out.as_str() } else { a })
        .collect();
    let run = matseg(&args);
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(1), "{args:?}: {err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.starts_with("warning: "))
        .collect();
    assert_eq!(lines.len(), 1, "{args:?}: {err}");
    assert!(
        lines[0].starts_with("error: ") && names.iter().all(|n| lines[0].contains(n)),
        "{args:?}: does not name {names:?}: {err}"
    );
    assert!(snapshot(root) == before, "{args:?}: files changed");
}

/// One command as the table runs it: its arguments (`OUT` for the
/// output), an input of the test's it reads (an `--out` inside it, or
/// holding it, is refused; none for commands that read only the bundled
/// assets) and a name it writes in its output folder (a file or folder of
/// the user's by that name is refused; empty: the output is that file).
struct Row {
    args: Vec<String>,
    input: Option<PathBuf>,
    writes: &'static str,
    /// Whether it writes its folder whole through `OUT.partial`.
    staged: bool,
}

fn rows(f: &Inputs) -> Vec<Row> {
    let row = |args: &[&str], input: &str, writes: &'static str, staged: bool| Row {
        args: args.iter().map(|a| a.to_string()).collect(),
        input: (!input.is_empty()).then(|| f.path(input)),
        writes,
        staged,
    };
    let (photos, textures) = (f.arg("photos"), f.arg("textures"));
    // A generator's arguments, reading the test's photos and textures.
    let sources = [
        "--sources",
        &photos,
        "--textures",
        &textures,
        "--out",
        "OUT",
    ];
    let sourced = |args: &[&'static str]| [args, &sources[..]].concat();
    let coffee = f.arg("photos/coffee.jpg");
    let mut rows = vec![
        row(
            &sourced(&["generate", "-n", "1", "--size-range", "64..64"]),
            "photos",
            "00000000",
            false,
        ),
        row(
            &["maps", &coffee, "--out", "OUT"],
            "photos/coffee.jpg",
            "colour.png",
            true,
        ),
        row(
            &["textures", &photos, "--out", "OUT"],
            "photos",
            "licenses.json",
            false,
        ),
        row(
            &["pbr", &textures, "-n", "1", "--out", "OUT"],
            "textures",
            "grass__pbr0",
            false,
        ),
        row(
            &["pbr-mix", &f.arg("mats"), "-n", "1", "--out", "OUT"],
            "mats",
            "mix00000",
            false,
        ),
        row(
            &["render", &f.arg("scene.json"), "--out", "OUT"],
            "scene.json",
            "image.png",
            true,
        ),
        row(
            &sourced(&["bench-set", "make", "-n", "2"]),
            "photos",
            "images",
            true,
        ),
        row(
            &[
                "bench-set",
                "masks",
                "--from",
                &f.arg("gen"),
                "--out",
                "OUT",
            ],
            "gen",
            "00000000.png",
            true,
        ),
        row(
            &["bench-set", "draw", &f.arg("bench"), "--out", "OUT"],
            "bench",
            "scene00000.png",
            true,
        ),
        row(
            &[
                "weights",
                "half",
                &f.arg("weights/model.safetensors"),
                "--out",
                "OUT",
            ],
            "weights/model.safetensors",
            "",
            false,
        ),
        row(
            &[
                "demo",
                "-n",
                "1",
                "--samples-3d",
                "0",
                "--train-steps",
                "0",
                "--out",
                "OUT",
            ],
            "",
            "index.html",
            false,
        ),
        row(
            &["assets", "fetch", "--only", "weights", "--cache", "OUT"],
            "",
            "notes.txt",
            false,
        ),
        row(
            &[
                "bench-render",
                "--size",
                "8",
                "--spp",
                "1",
                "--repeats",
                "1",
                "--write-scene",
                "OUT",
            ],
            "",
            "scene.json",
            true,
        ),
    ];
    if cfg!(feature = "net") {
        rows.extend([
            row(
                &["segment", &coffee, "--point", "290,130", "--out", "OUT"],
                "photos/coffee.jpg",
                "mask_0.png",
                true,
            ),
            row(
                &["apply", &f.arg("selection.json"), &photos, "--out", "OUT"],
                "photos",
                "masks",
                true,
            ),
            row(
                &[
                    "track",
                    &f.arg("clip/frames"),
                    "--point",
                    "30,20",
                    "--out",
                    "OUT",
                ],
                "clip/frames",
                "labels",
                true,
            ),
            row(
                &[
                    "features",
                    "--data",
                    &f.arg("gen"),
                    "--samples",
                    "1",
                    "--side",
                    "64",
                    "--out",
                    "OUT",
                ],
                "gen",
                "notes.txt",
                false,
            ),
            row(
                &[
                    "train",
                    "--data",
                    &f.arg("gen"),
                    "--steps",
                    "1",
                    "--out",
                    "OUT",
                ],
                "gen",
                "notes.txt",
                false,
            ),
        ]);
    }
    rows
}

#[test]
fn no_command_deletes_or_changes_a_file_it_did_not_make() {
    let f = Inputs::new();
    let root = f.dir.path();
    for (k, row) in rows(&f).iter().enumerate() {
        let args: Vec<&str> = row.args.iter().map(String::as_str).collect();
        if let Some(input) = &row.input {
            // An --out inside an input (or the input file itself), and one
            // holding it.
            let inside = if input.is_dir() {
                input.join("out")
            } else {
                input.clone()
            };
            let (out, input_name) = (inside.display().to_string(), input.display().to_string());
            assert_refused(root, &args, &inside, &[&out, &input_name]);
            // The folder holding it holds an input (this one, or another).
            let holding = input.parent().unwrap().to_path_buf();
            let out = holding.display().to_string();
            assert_refused(root, &args, &holding, &[&out, "holds the input"]);
        }
        // Someone else's file or folder under a name the command writes,
        // in a folder of its own (or someone's file as the output file).
        let folder = f.path(&format!("case{k}"));
        let out = folder.join("out");
        let foreign = out.join(row.writes);
        if row.writes.is_empty() {
            std::fs::create_dir_all(&folder).unwrap();
            std::fs::write(&out, "mine").unwrap();
        } else if row.writes.contains('.') {
            std::fs::create_dir_all(&out).unwrap();
            std::fs::write(&foreign, "mine").unwrap();
        } else {
            std::fs::create_dir_all(&foreign).unwrap();
            std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
        }
        assert_refused(root, &args, &out, &[&out.display().to_string()]);
        std::fs::remove_dir_all(&folder).unwrap();
        if row.staged {
            // Someone else's folder where the staging folder goes.
            let staging = partial(&out);
            std::fs::create_dir_all(&staging).unwrap();
            std::fs::write(staging.join("keep.txt"), "mine").unwrap();
            assert_refused(root, &args, &out, &[&staging.display().to_string()]);
        }
    }
}

/// The staging folder of the output folder `out`: `OUT.partial`.
fn partial(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// The files of the output of `args` (`OUT` for the output) run into a
/// new folder.
fn output_of(root: &Path, args: &[&str]) -> BTreeMap<PathBuf, Vec<u8>> {
    let out = root.join("alone");
    let _ = std::fs::remove_dir_all(&out);
    let out_arg = out.display().to_string();
    let args: Vec<&str> = args
        .iter()
        .map(|&a| if a == "OUT" { out_arg.as_str() } else { a })
        .collect();
    matseg_ok(&args);
    let files = snapshot(&out);
    std::fs::remove_dir_all(&out).unwrap();
    files
}

/// `args` with `OUT` for `out`.
fn into<'a>(args: &[&'a str], out: &'a str) -> Vec<&'a str> {
    args.iter()
        .map(|&a| if a == "OUT" { out } else { a })
        .collect()
}

#[test]
fn an_earlier_output_of_another_run_is_replaced_whole() {
    let f = Inputs::new();
    let root = f.dir.path();
    let out = f.path("out");
    let out_arg = out.display().to_string();
    let (coffee, chelsea) = (f.arg("photos/coffee.jpg"), f.arg("photos/chelsea.jpg"));
    let mut pairs: Vec<(Vec<&str>, Vec<&str>)> = vec![(
        vec!["maps", &coffee, "-n", "6", "--out", "OUT"],
        vec!["maps", &chelsea, "-n", "2", "--out", "OUT"],
    )];
    if cfg!(feature = "net") {
        pairs.push((
            vec![
                "segment", &coffee, "--point", "290,130", "--point", "100,300", "--out", "OUT",
            ],
            vec!["segment", &chelsea, "--point", "200,150", "--out", "OUT"],
        ));
    }
    for (first, second) in pairs {
        let _ = std::fs::remove_dir_all(&out);
        matseg_ok(&into(&first, &out_arg));
        matseg_ok(&into(&second, &out_arg));
        // The folder holds the second run's files alone, as a run into a
        // new folder writes them.
        assert!(
            snapshot(&out) == output_of(root, &second),
            "{second:?}: a folder mixing two runs"
        );
        assert!(!f.path("out.partial").exists());
    }
}

#[test]
fn a_run_killed_while_writing_leaves_the_earlier_output_or_the_new_one() {
    let f = Inputs::new();
    let root = f.dir.path();
    let out = f.path("out");
    let out_arg = out.display().to_string();
    let coffee = f.arg("photos/coffee.jpg");
    let earlier = ["maps", &coffee, "-n", "2", "--out", "OUT"];
    let later = ["maps", &coffee, "-n", "8", "--seed", "3", "--out", "OUT"];
    matseg_ok(&into(&earlier, &out_arg));
    let (old, new) = (snapshot(&out), output_of(root, &later));
    // Killed at moments from the start to well past the end of the write.
    for delay_ms in [0u64, 20, 60, 150, 400] {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_matseg"))
            .args(into(&later, &out_arg))
            .env("MATSEG_CACHE", test_cache())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill();
        child.wait().unwrap();
        let now = snapshot(&out);
        assert!(
            now == old || now == new,
            "killed after {delay_ms} ms: a mix"
        );
        // The next run takes the killed run's staging folder as its own.
        matseg_ok(&into(&earlier, &out_arg));
        assert!(snapshot(&out) == old);
        assert!(!f.path("out.partial").exists());
    }
}
