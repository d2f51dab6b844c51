//! `matseg demo`: the pipeline on the bundled assets, with an HTML report.

#[cfg(feature = "net")]
mod net;
mod page;
mod scenes_3d;

use crate::common::{init_threads, load_libraries, progress_bar, report_skipped};
use anyhow::{Context, Result};
use matseg_data::{generate_dataset, sample_rng, Dataset, Format, GenerateOptions, JobSlice};
use matseg_extract::pbr::{make_pbr, preview_sphere, PbrRecipe};
use matseg_extract::textures::{extract_textures, TextureOptions};
use matseg_image::io::{encode_png_gray, encode_png_rgb, read_rgb, write_atomic};
use matseg_image::{LicenceFilter, PhotoLibrary};
use matseg_pipeline::sources::{assets_dir, Defaults, DEFAULT_CACHE_MB};
use matseg_scene::Recipe2d;
use page::{sample_cards, STYLE};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `matseg demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder for the samples and `index.html`.
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// Number of 2D samples.
    #[arg(short = 'n', long = "samples", value_name = "N", default_value_t = 36)]
    n: u64,
    /// Number of 3D samples (0: no 3D page).
    #[arg(long, default_value_t = 6)]
    samples_3d: u64,
    /// Side of the 3D samples, in pixels.
    #[arg(long, default_value_t = 256)]
    size_3d: u32,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Steps of the demo's training demonstration (0: none; the net page
    /// still shows the shipped model).
    #[cfg(feature = "net")]
    #[arg(long, default_value_t = 150)]
    train_steps: u64,
}

/// Runs `matseg demo`: generates samples from the bundled assets and writes the HTML report.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let libs = load_libraries(
        &[],
        &[],
        DEFAULT_CACHE_MB,
        Defaults::Bundled,
        &LicenceFilter::default(),
    )?;
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
    report_skipped(&libs);

    // Read the samples back through the dataset reader, so the report shows
    // what a training run would see.
    let dataset = Dataset::open(&samples_dir)?;
    let cards = sample_cards(&dataset, &args.out, "samples-2d", "", |meta| {
        let hard = meta["scene"]["hard"].as_bool().unwrap_or(false);
        (if hard { "hard" } else { "soft" }).to_string()
    })?;
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>matseg demo</title>
{style}</head><body>
<h1>matseg demo: 2D scenes</h1>
<p>See also <a href="materials.html">textures and PBR materials</a> extracted from the bundled photos{scenes_3d}{net_link}.</p>
<p>{n} scenes generated from the bundled CC0 photos and textures (seed {seed}). Left: the image;
right: its annotation, each material in its own colour, mixtures as mixed colours, background black.
Samples are in MatSeg folder layout under <code>samples-2d/</code>.</p>
<div class="grid">
{cards}</div></body></html>
"#,
        style = STYLE,
        n = dataset.len(),
        seed = args.seed,
        scenes_3d = if args.samples_3d > 0 {
            r#", <a href="scenes-3d.html">3D scenes</a> path traced with their annotations"#
        } else {
            ""
        },
        net_link = if cfg!(feature = "net") {
            r#", and <a href="net.html">the net</a> trained on scenes like these, segmenting the photos"#
        } else {
            ""
        },
    );
    let index = args.out.join("index.html");
    write_atomic(&index, html.as_bytes()).with_context(|| index.display().to_string())?;
    materials_page(&args.out, args.seed)?;
    if args.samples_3d > 0 {
        scenes_3d::scenes_page(&args.out, args.samples_3d, args.size_3d, args.seed)?;
    }
    #[cfg(feature = "net")]
    net::net_page(&args.out, args.train_steps, args.seed)?;
    eprintln!(
        "{}: demo report with {} samples",
        index.display(),
        dataset.len()
    );
    Ok(())
}

/// `materials.html`: uniform textures extracted from the bundled photos
/// (pipeline.md §4) and one PBR material per bundled texture (pipeline.md §5), each with
/// its main maps and a lit-sphere preview.
fn materials_page(out: &Path, seed: u64) -> Result<()> {
    let assets = assets_dir();
    let dir = out.join("materials");
    std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
    let write_png = |name: &str, bytes: Vec<u8>| -> Result<String> {
        let path = dir.join(name);
        write_atomic(&path, &bytes).with_context(|| path.display().to_string())?;
        Ok(format!("materials/{name}"))
    };

    // Textures: the bundled photos are small, so 20-pixel cells.
    let options = TextureOptions {
        cell: 20,
        ..TextureOptions::default()
    };
    let (photos, _) = PhotoLibrary::scan(&[assets.join("photos")], 0)?;
    let mut textures = String::new();
    for entry in photos.entries() {
        let img = read_rgb(&entry.path)?;
        for (k, (square, crop)) in extract_textures(&img, &options).into_iter().enumerate() {
            let stem = entry.flat_stem();
            let src = write_png(&format!("texture_{stem}_{k}.png"), encode_png_rgb(&crop))?;
            writeln!(
                textures,
                r#"<figure><img src="{src}"><figcaption>{name}: {side}px at ({x}, {y}), score {score:.2}</figcaption></figure>"#,
                name = entry.name,
                side = square.side,
                x = square.x,
                y = square.y,
                score = square.score
            )?;
        }
    }

    // PBR: one material per bundled texture, its maps and a sphere.
    let (library, _) = PhotoLibrary::scan(&[assets.join("textures")], 0)?;
    let mut rows = String::new();
    for (i, entry) in library.entries().iter().enumerate() {
        let texture = read_rgb(&entry.path)?;
        let m = make_pbr(
            &mut sample_rng(seed, i as u64),
            &texture,
            &PbrRecipe::default(),
        );
        let stem = entry.flat_stem();
        let grey = |k: usize, what: &str| -> Result<String> {
            let map = &m.maps[k].1;
            write_png(
                &format!("pbr_{stem}_{what}.png"),
                encode_png_gray(map.width(), map.height(), map.as_raw()),
            )
        };
        let cells = [
            write_png(
                &format!("pbr_{stem}_sphere.png"),
                encode_png_rgb(&preview_sphere(&m, 200)),
            )?,
            write_png(&format!("pbr_{stem}_color.png"), encode_png_rgb(&m.color))?,
            write_png(&format!("pbr_{stem}_normal.png"), encode_png_rgb(&m.normal))?,
            grey(0, "height")?,
            grey(1, "roughness")?,
            grey(2, "metalness")?,
        ];
        rows.push_str("<tr>");
        for src in cells {
            write!(rows, r#"<td><img src="{src}"></td>"#)?;
        }
        writeln!(rows, "<td>{}</td></tr>", entry.name)?;
    }
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>matseg demo: materials</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; background: #fafafa; }}
.grid {{ display: grid; grid-template-columns: repeat(auto-fill, minmax(180px, 1fr)); gap: .6em; }}
figure {{ margin: 0; background: #fff; padding: .4em; border: 1px solid #ddd; }}
figure img {{ width: 100%; }}
figcaption {{ font-size: .75em; color: #444; }}
td img {{ width: 140px; height: 140px; object-fit: cover; }}
td {{ font-size: .8em; padding: 2px; }}
</style></head><body>
<h1>matseg demo: textures and PBR materials</h1>
<p><a href="index.html">Back to the 2D scenes.</a></p>
<h2>Uniform textures found in the bundled photos</h2>
<p>Squares of 20-pixel cells that are pairwise similar in 13 colour and gradient channels
(pipeline.md §4; <code>matseg textures</code>).</p>
<div class="grid">
{textures}</div>
<h2>PBR materials from the bundled textures</h2>
<p>One material per texture (pipeline.md §5; <code>matseg pbr</code>): a lit sphere, then colour,
normals (OpenGL), height, roughness and metalness.</p>
<table><tr><th>sphere</th><th>colour</th><th>normal</th><th>height</th><th>roughness</th><th>metalness</th><th>texture</th></tr>
{rows}</table></body></html>
"#
    );
    let page = out.join("materials.html");
    write_atomic(&page, html.as_bytes()).with_context(|| page.display().to_string())
}
