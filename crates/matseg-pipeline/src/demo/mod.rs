//! `matseg demo`: the pipeline on the bundled assets, written as an HTML
//! report: 2D scenes beside their annotations (`index.html`), textures and
//! PBR materials extracted from the bundled photos (`materials.html`), 3D
//! scenes path traced with their exact annotations (`scenes-3d.html`) and,
//! with the net, the shipped model's segmentations and a short training
//! demonstration (`net.html`).

#[cfg(feature = "net")]
mod net;
mod page;
mod scenes_3d;

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use crate::progress::Progress;
use crate::sources::{assets_dir, Defaults, Libraries, DEFAULT_CACHE_MB};
use crate::train_summary::TrainSummary;
use matseg_data::{generate_dataset, sample_rng, Dataset, Format, GenerateOptions, JobSlice};
use matseg_extract::pbr::{make_pbr, preview_sphere, PbrRecipe};
use matseg_extract::textures::{extract_textures, TextureOptions};
use matseg_image::io::{encode_png_grey, encode_png_rgb, read_rgb};
use matseg_image::outputs::{Layout, SharedFolder, Sign};
use matseg_image::{LicenceFilter, PhotoLibrary};
use matseg_scene::Recipe2d;
use page::{sample_cards, STYLE};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What the demo makes.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    /// Output folder for the samples and `index.html`.
    pub out: PathBuf,
    /// Number of 2D samples.
    pub samples_2d: u64,
    /// Number of 3D samples (0: no 3D page).
    pub samples_3d: u64,
    /// Side of the 3D samples, in pixels.
    pub size_3d: u32,
    /// Seed.
    pub seed: u64,
    /// Steps of the training demonstration (0: none; the net page still
    /// shows the shipped model). A build without the net has no net page
    /// and refuses any other number.
    pub train_steps: u64,
}

/// What the demo wrote.
#[derive(Clone, Debug)]
pub struct DemoReport {
    /// The report's first page.
    pub index: PathBuf,
    /// 2D samples on it.
    pub samples: usize,
    /// The training demonstration, when one ran (never in a build without
    /// the net).
    pub training: Option<DemoTraining>,
}

/// The demo's training run, when it trained.
#[derive(Clone, Debug)]
pub struct DemoTraining {
    /// The run folder.
    pub dir: PathBuf,
    /// Steps trained in all.
    pub step: u64,
    /// The run's latest weights.
    pub model_file: PathBuf,
    /// Where its initial weights came from (a new run).
    pub initial_weights: Option<String>,
    /// What this call of the training did.
    pub summary: TrainSummary,
}

/// Runs the demo: generates samples from the bundled assets and writes
/// the HTML report, reporting each long step (2D and 3D samples, training
/// steps) and each unreadable file to `progress`.
pub fn run(options: &DemoOptions, progress: &dyn Progress) -> Result<DemoReport, PipelineError> {
    #[cfg(not(feature = "net"))]
    if options.train_steps > 0 {
        return Err(PipelineError::setting(
            "train steps",
            Some(options.train_steps),
            crate::error::NO_NET,
        ));
    }
    let layout = Layout {
        command: "demo",
        sign: Sign::Marker,
        owns: &is_demo_entry,
    };
    let folder = SharedFolder::open(&options.out, &layout, &[&assets_dir()])?;
    let options = &DemoOptions {
        out: folder.dir().to_path_buf(),
        ..options.clone()
    };
    let libs = Libraries::load(
        &[],
        &[],
        DEFAULT_CACHE_MB,
        Defaults::Bundled,
        &LicenceFilter::default(),
    )?;
    let samples_dir = options.out.join("samples-2d");
    let opts = GenerateOptions {
        out: samples_dir.clone(),
        n: options.samples_2d,
        seed: options.seed,
        format: Format::Folders,
        shard_size: 1,
        job: JobSlice::ALL,
    };
    generate_dataset(&opts, &Recipe2d::default(), libs.sources(), progress)?;
    for s in libs
        .skipped_at_scan()
        .iter()
        .chain(&libs.failed_since_scan())
    {
        progress.warn(&format!("{}: {}", s.path.display(), s.reason));
    }

    // Read the samples back through the dataset reader, so the report shows
    // what a training run would see.
    let dataset = Dataset::open(&samples_dir)?;
    let cards = sample_cards(&dataset, &options.out, "samples-2d", "", |meta| {
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
        seed = options.seed,
        scenes_3d = if options.samples_3d > 0 {
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
    let index = options.out.join("index.html");
    write_file(&index, html.as_bytes())?;
    materials_page(&options.out, options.seed)?;
    if options.samples_3d > 0 {
        scenes_3d::scenes_page(
            &options.out,
            (options.samples_3d, options.size_3d, options.seed),
            libs.budget(),
            progress,
        )?;
    }
    #[cfg(feature = "net")]
    let training = net::net_page(
        &options.out,
        options.train_steps,
        options.seed,
        libs.budget(),
        progress,
    )?;
    #[cfg(not(feature = "net"))]
    let training = None;
    Ok(DemoReport {
        index,
        samples: dataset.len(),
        training,
    })
}

/// Whether `path`, an entry of a demo folder, is one the demo writes (a
/// page, or the folder of a page's files) in a folder the demo made: one
/// holding the demo's dataset, `samples-2d/dataset.json`.
fn is_demo_entry(path: &Path) -> bool {
    if !path
        .with_file_name("samples-2d")
        .join("dataset.json")
        .is_file()
    {
        return false;
    }
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let pages = ["index.html", "materials.html", "scenes-3d.html", "net.html"];
    let folders = [
        "materials",
        "previews",
        "samples-2d",
        "samples-3d",
        "net",
        "net-run",
    ];
    (pages.contains(&name.as_ref()) && path.is_file())
        || (folders.contains(&name.as_ref()) && path.is_dir())
}

/// `materials.html`: uniform textures extracted from the bundled photos
/// (pipeline.md §4) and one PBR material per bundled texture (pipeline.md §5), each with
/// its main maps and a lit-sphere preview.
fn materials_page(out: &Path, seed: u64) -> Result<(), PipelineError> {
    let assets = assets_dir();
    let dir = out.join("materials");
    create_folder(&dir)?;
    let write_png = |name: &str, bytes: Vec<u8>| -> Result<String, PipelineError> {
        write_file(&dir.join(name), &bytes)?;
        Ok(format!("materials/{name}"))
    };

    // Textures: the bundled photos are small, so 20-pixel cells.
    let options = TextureOptions {
        cell: 20,
        ..TextureOptions::default()
    };
    let (photos, _) = scan(&assets.join("photos"))?;
    let mut textures = String::new();
    for entry in photos.entries() {
        let img = read_rgb(&entry.path)?;
        for (k, (square, crop)) in extract_textures(&img, &options).into_iter().enumerate() {
            let stem = entry.flat_stem();
            let src = write_png(&format!("texture_{stem}_{k}.png"), encode_png_rgb(&crop))?;
            let _ = writeln!(
                textures,
                r#"<figure><img src="{src}"><figcaption>{name}: {side}px at ({x}, {y}), score {score:.2}</figcaption></figure>"#,
                name = entry.name,
                side = square.side,
                x = square.x,
                y = square.y,
                score = square.score
            );
        }
    }

    // PBR: one material per bundled texture, its maps and a sphere.
    let (library, _) = scan(&assets.join("textures"))?;
    let mut rows = String::new();
    for (i, entry) in library.entries().iter().enumerate() {
        let texture = read_rgb(&entry.path)?;
        let m = make_pbr(
            &mut sample_rng(seed, i as u64),
            &texture,
            &PbrRecipe::default(),
        );
        let stem = entry.flat_stem();
        let grey = |k: usize, what: &str| -> Result<String, PipelineError> {
            let map = &m.maps[k].1;
            write_png(
                &format!("pbr_{stem}_{what}.png"),
                encode_png_grey(map.width(), map.height(), map.as_raw()),
            )
        };
        let cells = [
            write_png(
                &format!("pbr_{stem}_sphere.png"),
                encode_png_rgb(&preview_sphere(&m, 200)),
            )?,
            write_png(&format!("pbr_{stem}_color.png"), encode_png_rgb(&m.colour))?,
            write_png(&format!("pbr_{stem}_normal.png"), encode_png_rgb(&m.normal))?,
            grey(0, "height")?,
            grey(1, "roughness")?,
            grey(2, "metalness")?,
        ];
        rows.push_str("<tr>");
        for src in cells {
            let _ = write!(rows, r#"<td><img src="{src}"></td>"#);
        }
        let _ = writeln!(rows, "<td>{}</td></tr>", entry.name);
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
    write_file(&out.join("materials.html"), html.as_bytes())
}

/// The photo library of one bundled folder.
fn scan(folder: &Path) -> Result<(PhotoLibrary, matseg_image::ScanReport), PipelineError> {
    PhotoLibrary::scan(&[folder.to_path_buf()], 0)
        .map_err(|e| crate::sources::SourceError::from(e).into())
}
