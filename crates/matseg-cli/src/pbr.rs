//! `matseg pbr`: PBR materials from a texture library (SPEC 5).

use crate::common::{flat_stem, init_threads, progress_bar, write_material_folder};
use anyhow::{Context, Result};
use matseg_data::sample_rng;
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
    let (library, report) = PhotoLibrary::scan(&args.textures, 0)?;
    for s in &report.skipped {
        eprintln!("warning: skipped {}: {}", s.path.display(), s.reason);
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let recipe = PbrRecipe::default();
    let jobs: Vec<(usize, u64)> = (0..library.len())
        .flat_map(|i| (0..args.per_texture).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            !folder(&args.out, &library, i, j)
                .join("material.json")
                .is_file()
        })
        .collect();
    let bar = progress_bar(jobs.len() as u64, "materials");
    let results: Vec<Result<Timing, String>> = jobs
        .par_iter()
        .map(|&(i, j)| {
            let result = make_one(
                &args.out,
                &library,
                (i, j),
                args.seed,
                args.seamless,
                &recipe,
            );
            bar.inc(1);
            result.map_err(|e| format!("{e:#}"))
        })
        .collect();
    bar.finish_and_clear();
    let mut total = Timing::default();
    let mut failed = 0;
    for r in results {
        match r {
            Ok(t) => {
                total.megapixels += t.megapixels;
                total.generate += t.generate;
                total.write += t.write;
            }
            Err(e) => {
                eprintln!("warning: skipped {e}");
                failed += 1;
            }
        }
    }
    let per_mp = |s: f64| {
        if total.megapixels > 0.0 {
            s / total.megapixels
        } else {
            0.0
        }
    };
    println!(
        "{}: {} materials written ({} already there, {failed} failed); per megapixel of material: {:.3} s making the maps, {:.3} s encoding and writing them",
        args.out.display(),
        jobs.len() - failed,
        library.len() as u64 * args.per_texture - jobs.len() as u64,
        per_mp(total.generate),
        per_mp(total.write),
    );
    Ok(())
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
