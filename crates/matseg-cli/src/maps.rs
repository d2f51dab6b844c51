//! `matseg maps`: the soft maps of one photo, for inspection or reuse.

use anyhow::{Context, Result};
use matseg_data::sample_rng;
use matseg_extract::{combine_maps, draw_channel_map, CombinedMaps, MapRecord, MAX_MAPS};
use matseg_image::io::{encode_png_gray, encode_png_rgb, read_rgb, write_atomic};
use matseg_image::{PhotoLibrary, Plane};
use matseg_scene::colourise;
use rand::Rng;
use serde::Serialize;
use std::path::PathBuf;

/// Arguments of `matseg maps`.
#[derive(clap::Args)]
pub struct Args {
    /// The photo to cut maps from.
    photo: PathBuf,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Number of maps.
    #[arg(short = 'n', long = "maps", value_name = "K", default_value_t = 4)]
    n: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Force a hard (one-hot) combination; default: drawn as for a scene.
    #[arg(long)]
    hard: bool,
    /// The maps are at most this many pixels on their longer side.
    #[arg(long, default_value_t = 1024)]
    max_side: u32,
    /// TOML recipe overriding map probabilities.
    #[arg(long)]
    config: Option<PathBuf>,
}

#[derive(Serialize)]
struct MapsFile {
    photo: String,
    width: usize,
    height: usize,
    hard: bool,
    max_occupancy: f64,
    maps: Vec<MapRecord>,
    combine: matseg_extract::CombineRecord,
}

/// Runs `matseg maps`: draws the maps of one photo and writes them.
pub fn run(args: Args) -> Result<()> {
    anyhow::ensure!(
        (1..=MAX_MAPS).contains(&args.n),
        "-n must be between 1 and {MAX_MAPS}"
    );
    anyhow::ensure!(args.max_side >= 16, "--max-side must be at least 16");
    let recipe = crate::common::load_recipe(args.config.as_deref(), None)?;
    let img = read_rgb(&args.photo)?;
    let (pw, ph) = img.dimensions();
    let shrink = (args.max_side as f64 / pw.max(ph) as f64).min(1.0);
    let (w, h) = (
        ((pw as f64 * shrink).round() as usize).max(1),
        ((ph as f64 * shrink).round() as usize).max(1),
    );
    let (library, _) = PhotoLibrary::scan(std::slice::from_ref(&args.photo), usize::MAX)?;

    let mut rng = sample_rng(args.seed, 0);
    let hard = args.hard || rng.random_bool(recipe.scene.p_hard);
    let max_occupancy = recipe.scene.draw_max_occupancy(&mut rng);
    let mut raw = Vec::with_capacity(args.n);
    let mut records = Vec::with_capacity(args.n);
    for _ in 0..args.n {
        let (map, record) =
            draw_channel_map(&mut rng, &library, w, h, max_occupancy, hard, &recipe.maps)
                .with_context(|| args.photo.display().to_string())?;
        raw.push(map);
        records.push(record);
    }
    let raw_planes: Vec<_> = raw.iter().map(|m| m.to_plane()).collect();
    let CombinedMaps {
        weights,
        background,
        record: combine,
        ..
    } = combine_maps(&mut rng, raw, hard, &recipe.maps);
    let weights: Vec<Plane> = weights.iter().map(|w| w.to_plane()).collect();

    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let write = |name: String, bytes: Vec<u8>| {
        let path = args.out.join(&name);
        write_atomic(&path, &bytes).with_context(|| path.display().to_string())
    };
    for (k, (r, wgt)) in raw_planes.iter().zip(&weights).enumerate() {
        write(
            format!("raw_{k:02}.png"),
            encode_png_gray(w as u32, h as u32, &r.to_u8()),
        )?;
        write(
            format!("weight_{k:02}.png"),
            encode_png_gray(w as u32, h as u32, &wgt.to_u8()),
        )?;
    }
    write(
        "background.png".into(),
        encode_png_gray(w as u32, h as u32, &background.to_u8()),
    )?;
    let slices: Vec<&[f32]> = weights.iter().map(|p| p.data.as_slice()).collect();
    write(
        "colour.png".into(),
        encode_png_rgb(&colourise(w, h, &slices)),
    )?;
    let file = MapsFile {
        photo: args.photo.display().to_string(),
        width: w,
        height: h,
        hard,
        max_occupancy,
        maps: records,
        combine,
    };
    write("maps.json".into(), serde_json::to_vec_pretty(&file)?)?;
    eprintln!(
        "{}: {} maps of {}x{} ({}) written",
        args.out.display(),
        args.n,
        w,
        h,
        if hard { "hard" } else { "soft" }
    );
    Ok(())
}
