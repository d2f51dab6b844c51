//! `matseg apply`: a selection made by clicks on one photo (its
//! `selection.json`) applied to other photos of any size: a mask per photo
//! and each photo's share of the material in `areas.csv`.

use crate::net_args::parse_device;
use anyhow::{bail, Result};
use matseg_image::io::{find_files, IMAGE_EXTENSIONS};
use matseg_image::outputs::StagedOutput;
use matseg_pipeline::segment::load_model;
use matseg_pipeline::select::{apply_to_folder, read_selection};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `matseg apply`.
#[derive(clap::Args)]
pub struct Args {
    /// The saved selection: `selection_K.json` from `matseg segment`, or
    /// `selection.json` from the web app or Python's `Model.select`.
    selection: PathBuf,
    /// Photos, or folders searched for photos (jpg, jpeg, png).
    #[arg(required = true)]
    photos: Vec<PathBuf>,
    /// The model; by default the one the selection was made with (a
    /// selection's descriptors mean nothing to another model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Output folder: `masks/NAME.png`, `areas.csv`, `selection.json`;
    /// written whole, replacing only an earlier apply output
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
}

/// Runs `matseg apply`.
pub fn run(args: Args) -> Result<()> {
    let saved = read_selection(&args.selection)?;
    let named = |what: &str| format!("{}: {what}", args.selection.display());
    let model = match &args.model {
        Some(model) => model.clone(),
        None if saved.model.trim().is_empty() => {
            bail!(
                "{}",
                named("names no model (\"model\" is empty): give --model")
            )
        }
        None => PathBuf::from(&saved.model),
    };
    let photos = find_photos(&args.photos)?;
    let inputs: Vec<&Path> = [args.selection.as_path()]
        .into_iter()
        .chain(args.photos.iter().map(PathBuf::as_path))
        .collect();
    let staged = StagedOutput::begin(&args.out, "apply", &inputs)?;
    let device = parse_device(&args.device)?;
    let net = match &args.model {
        Some(_) => load_model(&model, device)?,
        None => load_model(&model, device)
            .map_err(|e| anyhow::anyhow!("{}", named(&format!("its model: {e}"))))?,
    };
    saved
        .check(net.net().output_dim())
        .map_err(|e| anyhow::anyhow!("{}", named(&e.to_string())))?;
    let started = Instant::now();
    let total = photos.len();
    let mut done = 0;
    let areas = apply_to_folder(&net, &saved, &photos, staged.dir(), &mut |area| {
        done += 1;
        eprintln!(
            "[{done}/{total}] {}: {:.2}% selected",
            area.photo.display(),
            100.0 * area.share()
        );
    })?;
    staged.finish()?;
    let mean = areas.iter().map(|a| a.share()).sum::<f64>() / areas.len().max(1) as f64;
    println!(
        "{}: {} masks and areas.csv (mean share {:.2}%), {:.2} s a photo",
        args.out.display(),
        areas.len(),
        100.0 * mean,
        started.elapsed().as_secs_f64() / areas.len().max(1) as f64
    );
    Ok(())
}

/// The photos `roots` name (folders searched recursively); none is an
/// error naming the first root.
fn find_photos(roots: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let photos = find_files(roots, &IMAGE_EXTENSIONS)?;
    if photos.is_empty() {
        bail!(
            "{}: no photos (jpg, jpeg, png) to apply the selection to",
            roots[0].display()
        );
    }
    Ok(photos)
}
