//! The net part of `matseg demo`: `net.html`, the shipped model's
//! similarity maps of points clicked on the bundled photos and automatic
//! segmentations, then a short training run from the ImageNet MobileNetV2
//! encoder straight from the generator, labelled as a demonstration, with
//! the same maps from it. The page lists the `matseg` commands that redo
//! each step by hand.

use super::DemoTraining;
use crate::error::PipelineError;
use crate::files::{write_file, write_folder};
use crate::progress::Progress;
use crate::segment::{
    describe, load_model, write_clusters, write_point_maps, Model, DEFAULT_RADIUS,
};
use crate::select::MaterialClicks;
use crate::sources::{assets_dir, Defaults, Libraries};
use crate::train::{resume, start, TrainConfig, TrainData, TrainInputs};
use matseg_image::device::ComputeDevice;
use matseg_image::io::read_rgb;
use matseg_image::{LicenceFilter, MemoryBudget};
use matseg_net::data::BatchPlan;
use matseg_net::infer::{default_model_dir, DEFAULT_MODEL};
use matseg_net::train::{read_run_config, RUN_FILE};
use matseg_query::ClusterOptions;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

/// Bundled photos on the page, and the points clicked on each (pixels),
/// one per material.
const CLICKS: [(&str, &[(f32, f32)]); 4] = [
    (
        "coffee.jpg",
        &[
            (290.0, 130.0),
            (120.0, 300.0),
            (540.0, 80.0),
            (365.0, 290.0),
        ],
    ),
    (
        "astronaut.jpg",
        &[(150.0, 380.0), (230.0, 120.0), (420.0, 420.0)],
    ),
    (
        "chelsea.jpg",
        &[(80.0, 200.0), (430.0, 60.0), (170.0, 110.0)],
    ),
    (
        "rocket.jpg",
        &[(320.0, 40.0), (40.0, 250.0), (320.0, 400.0)],
    ),
];

/// Clusters of the automatic segmentations.
const AUTO_K: usize = 4;

/// Writes `OUT/net.html`: the shipped default model's similarity maps and
/// segmentations of the bundled photos, then, with `steps > 0`, a
/// training demonstration: `OUT/net-run` trained for `steps` steps (or
/// continued, if an earlier demo left it unfinished; its steps reported to
/// `progress`) and the same maps from it.
pub fn net_page(
    out: &Path,
    steps: u64,
    seed: u64,
    budget: Arc<MemoryBudget>,
    progress: &dyn Progress,
) -> Result<Option<DemoTraining>, PipelineError> {
    let mut commands = Vec::new();
    let shipped = match default_model_dir() {
        Some(dir) => {
            let net = load_model(&dir, ComputeDevice::Cpu)?;
            let rows = segmentation_rows(&net, DEFAULT_MODEL, "net/default", out, &mut commands)?;
            format!(
                r#"<h2>The shipped model</h2>
<p>The default model (<code>models/default</code>, see its MODEL.md): what <code>matseg segment</code>
uses with no <code>--model</code>. Each red overlay shows, for the circled point, how strongly every
pixel is taken for the same material: exp((cosine - 1) / 0.2), the training softmax's weight. Then
the photo split by nearest point, and split into {AUTO_K} clusters of descriptors with no points
at all.</p>
<table>{rows}</table>"#
            )
        }
        None => "<h2>The shipped model</h2><p>Not in this checkout (models/default).</p>".into(),
    };
    let (demonstration, training) = if steps > 0 {
        let (section, training) =
            training_demonstration(out, (steps, seed), budget, &mut commands, progress)?;
        (section, Some(training))
    } else {
        (String::new(), None)
    };
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>matseg demo: the net</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; background: #fafafa; }}
table {{ width: 100%; table-layout: fixed; }}
td {{ font-size: .8em; padding: 3px; vertical-align: top; }}
td img {{ width: 100%; max-width: 220px; }}
img {{ max-width: 100%; }}
pre {{ font-size: .75em; white-space: pre-wrap; }}
</style></head><body>
<h1>matseg demo: the material-descriptor net</h1>
<p><a href="index.html">Back to the 2D scenes.</a></p>
{shipped}
{demonstration}
<h2>Commands</h2>
<pre>{commands}</pre>
</body></html>
"#,
        commands = commands.join("\n"),
    );
    write_file(&out.join("net.html"), html.as_bytes())?;
    Ok(training)
}

/// Trains `OUT/net-run` for `steps` steps (or continues it) and returns
/// the page's section on it: the loss curve and the trained net's maps.
fn training_demonstration(
    out: &Path,
    (steps, seed): (u64, u64),
    budget: Arc<MemoryBudget>,
    commands: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<(String, DemoTraining), PipelineError> {
    let run = out.join("net-run");
    let run_arg = run.display().to_string();
    // 224 x 224, 4 images a batch: about 1 s a step on 2 CPU cores.
    let config = TrainConfig {
        init: "imagenet".into(),
        plan: BatchPlan {
            min_side: 224,
            max_side: 224,
            pixels: 200_704,
            ..BatchPlan::SPEC
        },
        lr: Some(1e-4),
        warmup: 30,
        validation_batches: 2,
        steps,
        checkpoint_every: steps,
        seed,
        ..TrainConfig::new(&run, TrainData::Online)
    };
    let (mut training, arguments) = if run.join(RUN_FILE).is_file() {
        let planned = read_run_config(&run)?.options.steps;
        if planned != steps {
            return Err(PipelineError::file(
                run.display(),
                format!("holds a demo run of {planned} steps; pass --train-steps {planned}, or remove it"),
            ));
        }
        (resume(&run, ComputeDevice::Cpu)?, "--resume".to_string())
    } else {
        let arguments = format!(
            "--online --init imagenet --min-side 224 --max-side 224 --batch-pixels 200704 \
             --lr 1e-4 --warmup 30 --validation-batches 2 --steps {steps} \
             --checkpoint-every {steps} --seed {seed} --out"
        );
        (start(&config, ComputeDevice::Cpu)?, arguments)
    };
    let libraries = Libraries::load_within(
        &[],
        &[],
        budget,
        Defaults::CorpusOrBundled,
        &LicenceFilter::default(),
    )?;
    for s in libraries.skipped_at_scan() {
        progress.warn(&format!("{}: {}", s.path.display(), s.reason));
    }
    progress.start(steps - training.step().min(steps), "steps");
    let summary = training.train(&TrainInputs::new(&libraries), |_| progress.advance())?;
    progress.finish();
    commands.push(format!("matseg train {arguments} {run_arg}"));
    let net = load_model(&run, ComputeDevice::Cpu)?;
    let rows = segmentation_rows(&net, &run_arg, "net/demo-run", out, commands)?;
    let section = format!(
        r#"<h2>A training demonstration</h2>
<p>How a model is made, in miniature: a MobileNetV2 net (ImageNet encoder) trained here for {steps}
steps on scenes generated on the fly from the bundled assets, a few minutes on a laptop CPU. It is
a demonstration of the training, not a model to use: the shipped model above was trained far
longer on the whole corpus.</p>
<p><img src="net-run/loss.png" alt="training loss"></p>
<table>{rows}</table>"#
    );
    let done = DemoTraining {
        dir: run.clone(),
        step: training.step(),
        model_file: training.model_file(),
        initial_weights: training.initial_weights().map(String::from),
        summary,
    };
    Ok((section, done))
}

/// The table rows of `net`'s maps of the bundled photos (written under
/// `OUT/DIR/PHOTO` and `OUT/DIR/PHOTO-auto`), adding to `commands` the
/// `matseg segment` lines that redo them with `--model MODEL`.
fn segmentation_rows(
    net: &Model,
    model: &str,
    dir: &str,
    out: &Path,
    commands: &mut Vec<String>,
) -> Result<String, PipelineError> {
    let photos = assets_dir().join("photos");
    let mut rows = String::new();
    for (name, points) in CLICKS {
        let stem = name.trim_end_matches(".jpg");
        let photo = photos.join(name);
        let by_points = format!("{dir}/{stem}");
        let auto = format!("{dir}/{stem}-auto");
        let image = read_rgb(&photo)?;
        let map = describe(net, &image);
        let grouped: Vec<_> = points.iter().map(|&p| (None, p)).collect();
        let clicks = MaterialClicks::group(&grouped, Vec::new());
        // Written as `matseg segment` writes them, so the commands shown
        // beside them redo them in place.
        let inputs = [photo.as_path()];
        write_folder(&out.join(&by_points), "segment", &inputs, |dir| {
            write_point_maps(&image, &map, &clicks, DEFAULT_RADIUS, model, dir)
        })?;
        write_folder(&out.join(&auto), "segment", &inputs, |dir| {
            write_clusters(&image, &map, &ClusterOptions::new(AUTO_K), dir)
        })?;
        let point_args: String = points
            .iter()
            .map(|(x, y)| format!(" --point {x},{y}"))
            .collect();
        commands.push(format!(
            "matseg segment {photo} --model {model}{point_args} --out {}",
            out.join(&by_points).display(),
            photo = photo.display()
        ));
        commands.push(format!(
            "matseg segment {photo} --model {model} --auto {AUTO_K} --out {}",
            out.join(&auto).display(),
            photo = photo.display()
        ));
        rows.push_str("<tr>");
        for (i, (x, y)) in points.iter().enumerate() {
            let _ = write!(
                rows,
                r#"<td><img src="{by_points}/overlay_{i}.png"><br>point ({x}, {y})</td>"#
            );
        }
        for _ in points.len()..4 {
            rows.push_str("<td></td>");
        }
        let _ = writeln!(
            rows,
            r#"<td><img src="{by_points}/segmentation.png"><br>nearest point</td><td><img src="{auto}/segmentation.png"><br>{AUTO_K} clusters</td></tr>"#
        );
    }
    Ok(rows)
}
