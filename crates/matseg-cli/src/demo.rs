//! `matseg demo`: the pipeline on the bundled assets, with an HTML report.

use crate::common::{init_threads, progress_bar, Libraries, DEFAULT_CACHE_MB};
use anyhow::{Context, Result};
use matseg_data::{generate_dataset, Dataset, Format, GenerateOptions, JobSlice};
use matseg_image::io::{encode_png_rgb, write_atomic};
use matseg_scene::{colorize, Recipe2d};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `matseg demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder for the samples and `index.html`.
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// Number of 2D samples.
    #[arg(short = 'n', long = "samples", value_name = "N", default_value_t = 36)]
    n: u64,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Runs `matseg demo`: generates samples from the bundled assets and writes the HTML report.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let libs = Libraries::load(&[], &[], DEFAULT_CACHE_MB)?;
    let samples_dir = args.out.join("samples-2d");
    let opts = GenerateOptions {
        out: samples_dir.clone(),
        n: args.n,
        seed: args.seed,
        format: Format::Folders,
        shard_size: 1,
        job: JobSlice::ALL,
    };
    let bar = progress_bar(args.n, "2D samples");
    generate_dataset(&opts, &Recipe2d::default(), libs.sources(), &|k| bar.inc(k))?;
    bar.finish_and_clear();
    libs.report_skipped();

    // Read the samples back through the dataset reader, so the report shows
    // what a training run would see.
    let dataset = Dataset::open(&samples_dir)?;
    let previews = args.out.join("previews");
    std::fs::create_dir_all(&previews).with_context(|| previews.display().to_string())?;
    let mut cards = String::new();
    for sample in dataset.iter() {
        let sample = sample?;
        let (w, h) = sample.image.dimensions();
        let masks: Vec<Vec<f32>> = sample
            .masks
            .iter()
            .map(|m| m.as_raw().iter().map(|&v| v as f32 / 255.0).collect())
            .collect();
        let slices: Vec<&[f32]> = masks.iter().map(Vec::as_slice).collect();
        let name = format!("{}_annotation.png", sample.key);
        let path = previews.join(&name);
        write_atomic(
            &path,
            &encode_png_rgb(&colorize(w as usize, h as usize, &slices)),
        )
        .with_context(|| path.display().to_string())?;
        let meta = sample.meta.as_ref();
        let hard = meta
            .and_then(|m| m["scene"]["hard"].as_bool())
            .unwrap_or(false);
        let licences = meta
            .and_then(|m| m["licences"].as_array())
            .map(|l| {
                l.iter()
                    .filter_map(|v| v.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default();
        write!(
            cards,
            r#"<figure><div class="pair"><img src="samples-2d/{key}/RGB__RGB.jpg"><img src="previews/{name}"></div>
<figcaption>#{key}: {w}x{h}, {k} material(s), {kind}; {licences}</figcaption></figure>
"#,
            key = sample.key,
            k = sample.masks.len(),
            kind = if hard { "hard" } else { "soft" },
        )?;
    }
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>matseg demo</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; background: #fafafa; }}
.grid {{ display: grid; grid-template-columns: repeat(auto-fill, minmax(420px, 1fr)); gap: 1em; }}
figure {{ margin: 0; background: #fff; padding: .5em; border: 1px solid #ddd; }}
.pair {{ display: grid; grid-template-columns: 1fr 1fr; gap: 4px; }}
.pair img {{ width: 100%; height: 200px; object-fit: contain; background: #000; }}
figcaption {{ font-size: .8em; color: #444; margin-top: .3em; }}
</style></head><body>
<h1>matseg demo: 2D scenes</h1>
<p>{n} scenes generated from the bundled CC0 photos and textures (seed {seed}). Left: the image;
right: its annotation, each material in its own colour, mixtures as mixed colours, background black.
Samples are in MatSeg folder layout under <code>samples-2d/</code>.</p>
<div class="grid">
{cards}</div></body></html>
"#,
        n = dataset.len(),
        seed = args.seed,
    );
    let index = args.out.join("index.html");
    write_atomic(&index, html.as_bytes()).with_context(|| index.display().to_string())?;
    eprintln!(
        "{}: demo report with {} samples",
        index.display(),
        dataset.len()
    );
    Ok(())
}
