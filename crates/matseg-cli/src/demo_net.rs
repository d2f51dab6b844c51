//! The net part of `matseg demo`: a short training run from the ImageNet
//! MobileNetV2 encoder straight from the generator, then `net.html`, the
//! similarity maps of points clicked on the bundled photos and automatic
//! segmentations. Each step is an ordinary `matseg` command, shown on the
//! page so it can be re-run by hand.

use crate::common::assets_dir;
use anyhow::{bail, Context, Result};
use clap::Parser;
use matseg_image::io::write_atomic;
use matseg_net::train::{read_run_config, RUN_FILE};
use std::fmt::Write as _;
use std::path::Path;

/// Bundled photos on the page, and the points clicked on each (pixels),
/// one per material.
const CLICKS: [(&str, &[(u32, u32)]); 4] = [
    (
        "coffee.jpg",
        &[(290, 130), (120, 300), (540, 80), (365, 290)],
    ),
    ("astronaut.jpg", &[(150, 380), (230, 120), (420, 420)]),
    ("chelsea.jpg", &[(80, 200), (430, 60), (170, 110)]),
    ("rocket.jpg", &[(320, 40), (40, 250), (320, 400)]),
];

/// Clusters of the automatic segmentations.
const AUTO_K: usize = 4;

/// Parses a `matseg train` or `matseg segment` command line.
#[derive(Parser)]
#[command(name = "matseg")]
enum Step {
    Train(crate::train::Args),
    Segment(crate::segment::Args),
}

/// Runs `command` (words after `matseg`) as the CLI would.
fn run_step(command: &[String]) -> Result<()> {
    let step = Step::try_parse_from(std::iter::once("matseg".to_string()).chain(command.to_vec()))
        .with_context(|| format!("demo step `matseg {}`", command.join(" ")))?;
    match step {
        Step::Train(args) => crate::train::run(args),
        Step::Segment(args) => crate::segment::run(args),
    }
}

/// Trains `OUT/net-run` for `steps` steps (or continues it, if an earlier
/// demo left it unfinished) and writes `OUT/net.html`.
pub fn net_page(out: &Path, steps: u64, seed: u64) -> Result<()> {
    let run = out.join("net-run");
    let run_arg = run.display().to_string();
    let train: Vec<String> = if run.join(RUN_FILE).is_file() {
        let planned = read_run_config(&run)?.options.steps;
        if planned != steps {
            bail!(
                "{}: holds a demo run of {planned} steps; pass --train-steps {planned}, or remove it",
                run.display()
            );
        }
        vec!["train".into(), "--resume".into(), run_arg.clone()]
    } else {
        let mut words = vec!["train", "--online", "--out", &run_arg, "--init", "imagenet"];
        // 224 x 224, 4 images a batch: about 1 s a step on 2 CPU cores.
        words.extend([
            "--min-side",
            "224",
            "--max-side",
            "224",
            "--batch-pixels",
            "200704",
            "--lr",
            "1e-4",
            "--warmup",
            "30",
            "--validation-batches",
            "2",
        ]);
        let mut words: Vec<String> = words.into_iter().map(String::from).collect();
        words.extend([
            "--steps".into(),
            steps.to_string(),
            "--checkpoint-every".into(),
            steps.to_string(),
            "--seed".into(),
            seed.to_string(),
        ]);
        words
    };
    run_step(&train)?;

    let photos = assets_dir().join("photos");
    let mut commands = vec![format!("matseg {}", train.join(" "))];
    let mut rows = String::new();
    for (name, points) in CLICKS {
        let stem = name.trim_end_matches(".jpg");
        let photo = photos.join(name).display().to_string();
        let by_points = format!("net/{stem}");
        let auto = format!("net/{stem}-auto");
        let mut segment = vec![
            "segment".to_string(),
            photo.clone(),
            "--model".into(),
            run_arg.clone(),
        ];
        for (x, y) in points {
            segment.extend(["--point".into(), format!("{x},{y}")]);
        }
        segment.extend(["--out".into(), out.join(&by_points).display().to_string()]);
        run_step(&segment)?;
        let clustering = vec![
            "segment".to_string(),
            photo,
            "--model".into(),
            run_arg.clone(),
            "--auto".into(),
            AUTO_K.to_string(),
            "--out".into(),
            out.join(&auto).display().to_string(),
        ];
        run_step(&clustering)?;
        commands.push(format!("matseg {}", segment.join(" ")));
        commands.push(format!("matseg {}", clustering.join(" ")));

        rows.push_str("<tr>");
        for (i, (x, y)) in points.iter().enumerate() {
            write!(
                rows,
                r#"<td><img src="{by_points}/overlay_{i}.png"><br>point ({x}, {y})</td>"#
            )?;
        }
        for _ in points.len()..4 {
            rows.push_str("<td></td>");
        }
        writeln!(
            rows,
            r#"<td><img src="{by_points}/segmentation.png"><br>nearest point</td><td><img src="{auto}/segmentation.png"><br>{AUTO_K} clusters</td></tr>"#
        )?;
    }
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>matseg demo: the net</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; background: #fafafa; }}
td {{ font-size: .8em; padding: 3px; vertical-align: top; }}
td img {{ width: 220px; }}
pre {{ font-size: .75em; white-space: pre-wrap; }}
</style></head><body>
<h1>matseg demo: the material-descriptor net</h1>
<p><a href="index.html">Back to the 2D scenes.</a></p>
<p>A MobileNetV2 net (ImageNet encoder, SPEC 8) trained for {steps} steps on scenes generated on the
fly from the bundled assets: a few minutes on a laptop CPU, a sketch of what a long run on a GPU
learns. Each red overlay shows, for the circled point, how strongly every pixel is taken for the
same material: exp((cosine - 1) / 0.2), the training softmax's weight. Then the photo split by
nearest point, and split into {AUTO_K} clusters of descriptors with no points at all.</p>
<p><img src="net-run/loss.png" alt="training loss"></p>
<table>{rows}</table>
<h2>Commands</h2>
<pre>{commands}</pre>
</body></html>
"#,
        commands = commands.join("\n"),
    );
    let page = out.join("net.html");
    write_atomic(&page, html.as_bytes()).with_context(|| page.display().to_string())
}
