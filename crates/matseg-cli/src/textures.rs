//! `matseg textures`: a library of uniform-texture crops from photos
//! (pipeline.md §4; `matseg_pipeline::textures`).

use crate::common::{init_threads, BarProgress};
use anyhow::Result;
use matseg_extract::textures::TextureOptions;
use matseg_pipeline::textures::make_texture_library;
use std::path::PathBuf;

/// Arguments of `matseg textures`.
#[derive(clap::Args)]
pub struct Args {
    /// Photos or folders of photos (walked recursively).
    #[arg(required = true, num_args = 1..)]
    photos: Vec<PathBuf>,
    /// Output texture library; a rerun adds the photos not yet done
    /// (docs/outputs.md).
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

/// Runs `matseg textures`.
pub fn run(args: Args) -> Result<()> {
    init_threads(args.threads)?;
    let options = TextureOptions {
        cell: args.cell,
        min_cells: args.min_cells,
        js_max: args.js_max,
        ..TextureOptions::default()
    };
    let r = make_texture_library(&args.photos, &args.out, &options, &BarProgress::default())?;
    for e in &r.unreadable {
        eprintln!("warning: skipped {e}");
    }
    println!(
        "{}: {} textures from {} of {} photos ({} already done, {} smaller than {} px, {} unreadable); {:.2} CPU s per megapixel",
        args.out.display(),
        r.textures,
        r.photos,
        r.found,
        r.already,
        r.too_small,
        r.smallest,
        r.unreadable.len(),
        r.cpu_seconds_per_megapixel
    );
    Ok(())
}
