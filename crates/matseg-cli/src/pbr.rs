//! `matseg pbr`: PBR materials from a texture library (pipeline.md §5).

use crate::common::{flat_stem, init_threads, progress_bar};
use anyhow::{Context, Result};
use matseg_data::sample_rng;
use matseg_extract::material_library::write_material_folder;
use matseg_extract::pbr::{make_pbr, PbrRecipe};
use matseg_image::io::read_rgb;
use matseg_image::PhotoLibrary;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `matseg pbr`.
#[derive(clap::Args)]
pub struct Args {
    /// Texture images or folders of them (e.g. a `matseg textures` library).
    #[arg(required = true, num_args = 1..)]
    textures: Vec<PathBuf>,
    /// Output folder: one folder per material.
    #[arg(long)]
    out: PathBuf,
    /// Materials per texture.
    #[arg(short = 'n', long = "per-texture", default_value_t = 1)]
    per_texture: u64,
    /// Seed: material j of texture i depends only on (seed, i, j).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Make every map tileable (edges match when the material is repeated).
    #[arg(long)]
    seamless: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Runs `matseg pbr`.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let made = make_library(
        &args.textures,
        &args.out,
        args.per_texture,
        args.seed,
        args.seamless,
    )?;
    let per_mp = |s: f64| {
        if made.timing.megapixels > 0.0 {
            s / made.timing.megapixels
        } else {
            0.0
        }
    };
    println!(
        "{}: {} materials written ({} already there, {} failed); per megapixel of material: {:.3} s making the maps, {:.3} s encoding and writing them",
        args.out.display(),
        made.written,
        made.existing,
        made.failed,
        per_mp(made.timing.generate),
        per_mp(made.timing.write),
    );
    Ok(())
}

/// What [`make_library`] did.
pub struct LibraryReport {
    /// Materials written now.
    pub written: usize,
    /// Materials found complete.
    pub existing: usize,
    /// Materials that failed (each warned about).
    pub failed: usize,
    timing: Timing,
}

/// Makes `per_texture` PBR materials from each texture under `textures`
/// into `out` (one folder each, skipping complete ones), on the current
/// rayon pool, with a progress bar and a warning per failure.
pub fn make_library(
    textures: &[PathBuf],
    out: &Path,
    per_texture: u64,
    seed: u64,
    seamless: bool,
) -> Result<LibraryReport> {
    let (library, report) = PhotoLibrary::scan(textures, 0)?;
    for s in &report.skipped {
        eprintln!("warning: skipped {}: {}", s.path.display(), s.reason);
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let recipe = PbrRecipe::default();
    let jobs: Vec<(usize, u64)> = (0..library.len())
        .flat_map(|i| (0..per_texture).map(move |j| (i, j)))
        .filter(|&(i, j)| !folder(out, &library, i, j).join("material.json").is_file())
        .collect();
    let bar = progress_bar(jobs.len() as u64, "materials");
    let results: Vec<Result<Timing, String>> = jobs
        .par_iter()
        .map(|&(i, j)| {
            let result = make_one(out, &library, (i, j), seed, seamless, &recipe);
            bar.inc(1);
            result.map_err(|e| format!("{e:#}"))
        })
        .collect();
    bar.finish_and_clear();
    let mut timing = Timing::default();
    let mut failed = 0;
    for r in results {
        match r {
            Ok(t) => {
                timing.megapixels += t.megapixels;
                timing.generate += t.generate;
                timing.write += t.write;
            }
            Err(e) => {
                eprintln!("warning: skipped {e}");
                failed += 1;
            }
        }
    }
    Ok(LibraryReport {
        written: jobs.len() - failed,
        existing: library.len() * per_texture as usize - jobs.len(),
        failed,
        timing,
    })
}

/// Where one material's time went (thread seconds) and its size.
#[derive(Default)]
struct Timing {
    megapixels: f64,
    generate: f64,
    write: f64,
}

/// The folder of material `j` of texture `i`.
fn folder(out: &Path, library: &PhotoLibrary, i: usize, j: u64) -> PathBuf {
    out.join(format!("{}__pbr{j}", flat_stem(&library.entries()[i].name)))
}

/// Makes one material and writes its folder: files go to `NAME.partial/`,
/// renamed into place, with `material.json` written last.
fn make_one(
    out: &Path,
    library: &PhotoLibrary,
    (i, j): (usize, u64),
    seed: u64,
    seamless: bool,
    recipe: &PbrRecipe,
) -> Result<Timing> {
    let entry = &library.entries()[i];
    let texture = read_rgb(&entry.path)?;
    let start = Instant::now();
    let mut rng = sample_rng(seed, ((i as u64) << 20) | j);
    let mut material = make_pbr(&mut rng, &texture, recipe);
    if seamless {
        material.make_seamless();
    }
    let generate = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let json = serde_json::json!({
        "source": entry.name,
        "seed": seed,
        "record": material.record,
    });
    write_material_folder(
        &folder(out, library, i, j),
        &entry.licence,
        |d| material.write_maps(d),
        json,
    )?;
    Ok(Timing {
        megapixels: (texture.width() as f64 * texture.height() as f64) / 1e6,
        generate,
        write: start.elapsed().as_secs_f64(),
    })
}
