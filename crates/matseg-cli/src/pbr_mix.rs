//! `matseg pbr-mix`: new PBR materials by mixing existing ones (pipeline.md §5).

use crate::common::{init_threads, progress_bar};
use anyhow::{ensure, Context, Result};
use matseg_data::sample_rng;
use matseg_extract::material_library::{
    find_materials, read_material, write_material_folder, MaterialMaps,
};
use matseg_extract::pbr_mix::{mix_materials, MixRecipe};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Arguments of `matseg pbr-mix`.
#[derive(clap::Args)]
pub struct Args {
    /// A folder of material folders (ours, ambientCG, MatSeg or MatSynth naming).
    materials: PathBuf,
    /// Output folder: one folder per mix.
    #[arg(long)]
    out: PathBuf,
    /// Number of mixes.
    #[arg(short = 'n', long = "count", default_value_t = 10)]
    n: u64,
    /// Seed: mix i depends only on (seed, i) and the materials.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// Runs `matseg pbr-mix`.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let dirs = find_materials(&args.materials)?;
    ensure!(
        dirs.len() >= 2,
        "{}: mixing needs at least two material folders, found {}",
        args.materials.display(),
        dirs.len()
    );
    let library: Vec<MaterialMaps> = dirs
        .par_iter()
        .map(|d| read_material(d))
        .collect::<Result<_, _>>()?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let todo: Vec<u64> = (0..args.n)
        .filter(|&i| !mix_dir(&args.out, i).join("material.json").is_file())
        .collect();
    let bar = progress_bar(todo.len() as u64, "mixes");
    let recipe = MixRecipe::default();
    todo.par_iter()
        .map(|&i| {
            let result = write_mix(&args.out, i, args.seed, &library, &args.materials, &recipe);
            bar.inc(1);
            result
        })
        .collect::<Result<Vec<()>>>()?;
    bar.finish_and_clear();
    println!(
        "{}: {} mixes of {} materials written ({} already there)",
        args.out.display(),
        todo.len(),
        library.len(),
        args.n - todo.len() as u64
    );
    Ok(())
}

fn mix_dir(out: &Path, i: u64) -> PathBuf {
    out.join(format!("mix{i:05}"))
}

/// Makes mix `i` and writes its folder (through a partial folder, renamed
/// when complete).
fn write_mix(
    out: &Path,
    i: u64,
    seed: u64,
    library: &[MaterialMaps],
    root: &Path,
    recipe: &MixRecipe,
) -> Result<()> {
    let (mixed, record) = mix_materials(&mut sample_rng(seed, i), library, recipe);
    let sources: Vec<String> = record
        .sources
        .iter()
        .map(|&s| {
            let d = &library[s].dir;
            d.strip_prefix(root).unwrap_or(d).display().to_string()
        })
        .collect();
    // The mix carries every source's licence (from its licenses.json).
    let mut licences: Vec<String> = record
        .sources
        .iter()
        .map(|&s| folder_licence(&library[s].dir))
        .collect();
    licences.sort();
    licences.dedup();
    let licence = licences.join(" AND ");
    let json = serde_json::json!({
        "sources": sources,
        "mode": record.mode,
        "weights": record.weights,
        "seed": seed,
    });
    write_material_folder(&mix_dir(out, i), &licence, |d| mixed.write_maps(d), json)?;
    Ok(())
}

/// The licence a material folder's `licenses.json` gives all its files
/// (`"*"`), or `unknown`.
fn folder_licence(dir: &Path) -> String {
    std::fs::read(dir.join("licenses.json"))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .and_then(|v| v["*"].as_str().map(str::to_string))
        .unwrap_or_else(|| matseg_image::library::UNKNOWN_LICENCE.to_string())
}
