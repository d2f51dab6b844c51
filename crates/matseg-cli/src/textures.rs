//! `matseg textures`: a library of uniform-texture crops from photos (pipeline.md §4).

use crate::common::{init_threads, progress_bar};
use anyhow::{Context, Result};
use matseg_extract::textures::{extract_textures, TextureOptions, TextureSquare, CHANNEL_NAMES};
use matseg_image::io::{encode_jpeg, read_rgb, write_atomic};
use matseg_image::library::PhotoEntry;
use matseg_image::PhotoLibrary;
use matseg_pipeline::bench::clock::process_cpu_seconds;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `matseg textures`.
#[derive(clap::Args)]
pub struct Args {
    /// Photos or folders of photos (walked recursively).
    #[arg(required = true, num_args = 1..)]
    photos: Vec<PathBuf>,
    /// Output texture library.
    #[arg(long)]
    out: PathBuf,
    /// Cell side in pixels.
    #[arg(long, default_value_t = 40)]
    cell: usize,
    /// Smallest square kept, in cells per side.
    #[arg(long, default_value_t = 6)]
    min_cells: usize,
    /// Largest Jensen-Shannon distance (per channel) between similar cells.
    #[arg(long, default_value_t = 0.5)]
    js_max: f64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

/// What one photo gave: written last, so a photo with a record is done.
#[derive(Serialize, Deserialize)]
struct PhotoRecord {
    source: String,
    licence: String,
    width: u32,
    height: u32,
    options: TextureOptions,
    channels: Vec<String>,
    textures: Vec<TextureRecord>,
}

#[derive(Serialize, Deserialize)]
struct TextureRecord {
    file: String,
    #[serde(flatten)]
    square: TextureSquare,
}

/// The record file of a photo: its path in the sources, flattened.
fn record_path(out: &Path, entry: &PhotoEntry) -> PathBuf {
    out.join("records")
        .join(format!("{}.json", entry.flat_name()))
}

/// Runs `matseg textures`.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let options = TextureOptions {
        cell: args.cell,
        min_cells: args.min_cells,
        js_max: args.js_max,
        ..TextureOptions::default()
    };
    anyhow::ensure!(
        options.cell >= 4 && options.min_cells >= 1,
        "--cell must be at least 4 and --min-cells at least 1"
    );
    let (library, report) = PhotoLibrary::scan(&args.photos, 0)?;
    for s in &report.skipped {
        eprintln!("warning: skipped {}: {}", s.path.display(), s.reason);
    }
    std::fs::create_dir_all(args.out.join("records"))
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let smallest = (options.cell * options.min_cells) as u32;
    let todo: Vec<usize> = (0..library.len())
        .filter(|&i| !record_path(&args.out, &library.entries()[i]).is_file())
        .collect();
    // The headers tell which photos cannot hold the smallest square.
    let (too_small, todo): (Vec<usize>, Vec<usize>) = todo.into_iter().partition(|&i| {
        let entry = &library.entries()[i];
        entry.width.min(entry.height) < smallest
    });
    let bar = progress_bar(todo.len() as u64, "photos");
    let (start, cpu) = (Instant::now(), process_cpu_seconds());
    let results: Vec<Result<(usize, u64), String>> = todo
        .par_iter()
        .map(|&i| {
            let outcome = extract_one(&args.out, &library, i, &options);
            bar.inc(1);
            outcome
        })
        .collect();
    bar.finish_and_clear();
    let mut failed = 0;
    let (mut textures, mut pixels) = (0usize, 0u64);
    for r in &results {
        match r {
            Ok((n, px)) => {
                textures += n;
                pixels += px;
            }
            Err(e) => {
                eprintln!("warning: skipped {e}");
                failed += 1;
            }
        }
    }
    write_licences(&args.out)?;
    let seconds = match (cpu, process_cpu_seconds()) {
        (Some(a), Some(b)) => b - a,
        _ => start.elapsed().as_secs_f64(),
    };
    println!(
        "{}: {textures} textures from {} photos ({} already done, {} smaller than {smallest} px, {failed} unreadable); {:.2} CPU s per megapixel",
        args.out.display(),
        todo.len() - failed,
        library.len() - todo.len() - too_small.len(),
        too_small.len(),
        if pixels > 0 { seconds / (pixels as f64 / 1e6) } else { 0.0 }
    );
    Ok(())
}

/// Extracts the textures of photo `i`, writes the crops and then the
/// record; returns the texture count and the photo's pixels.
fn extract_one(
    out: &Path,
    library: &PhotoLibrary,
    i: usize,
    options: &TextureOptions,
) -> Result<(usize, u64), String> {
    let entry = &library.entries()[i];
    let img = read_rgb(&entry.path).map_err(|e| e.to_string())?;
    let stem = entry.flat_stem();
    let mut textures = Vec::new();
    for (k, (square, crop)) in extract_textures(&img, options).into_iter().enumerate() {
        let file = format!("{stem}__{k}.jpg");
        write_atomic(&out.join(&file), &encode_jpeg(&crop, 95))
            .map_err(|e| format!("{}: cannot write: {e}", out.join(&file).display()))?;
        textures.push(TextureRecord { file, square });
    }
    let record = PhotoRecord {
        source: entry.name.clone(),
        licence: entry.licence.clone(),
        width: img.width(),
        height: img.height(),
        options: *options,
        channels: CHANNEL_NAMES.iter().map(|c| c.to_string()).collect(),
        textures,
    };
    let n = record.textures.len();
    let json = serde_json::to_vec_pretty(&record).expect("JSON");
    let path = record_path(out, entry);
    write_atomic(&path, &json).map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
    Ok((n, img.width() as u64 * img.height() as u64))
}

/// `licenses.json` for the library (each crop with its photo's licence),
/// rebuilt from all records, so the library works as `--textures`.
fn write_licences(out: &Path) -> Result<()> {
    let mut licences = BTreeMap::new();
    for entry in std::fs::read_dir(out.join("records"))? {
        let path = entry?.path();
        if path.extension().is_some_and(|e| e == "json") {
            let record: PhotoRecord = serde_json::from_slice(&std::fs::read(&path)?)
                .with_context(|| format!("{}: bad record", path.display()))?;
            for t in record.textures {
                licences.insert(t.file, record.licence.clone());
            }
        }
    }
    write_atomic(
        &out.join("licenses.json"),
        &serde_json::to_vec_pretty(&licences).expect("JSON"),
    )
    .with_context(|| format!("{}: cannot write", out.display()))
}
