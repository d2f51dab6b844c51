//! `matseg bench-set make`: a point benchmark from generated scenes, so the
//! evaluation can run end to end without external data; `matseg bench-set
//! draw`: any point benchmark's annotations drawn on its photos.

use crate::common::{load_libraries, LicenceArgs};
use anyhow::{ensure, Context, Result};
use clap::Subcommand;
use matseg_data::sample_rng;
use matseg_eval::load_point_benchmark;
use matseg_eval::overlay::draw_points;
use matseg_eval::synthetic::{annotate_points, write_point_image, SyntheticOptions};
use matseg_image::io::{encode_png_rgb, read_rgb, write_atomic};
use matseg_pipeline::sources::{Defaults, DEFAULT_CACHE_MB};
use matseg_scene::{generate_2d, Recipe2d};
use std::path::PathBuf;

/// `matseg bench-set` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Write a point benchmark (MatSeg layout) made from generated 2D scenes.
    Make(MakeArgs),
    /// Draw each image's points on it (NAME.png: rings in one colour per
    /// material, labelled with its id), to check an annotation by eye.
    Draw(DrawArgs),
}

/// Arguments of `matseg bench-set draw`.
#[derive(clap::Args)]
pub struct DrawArgs {
    /// Benchmark folder (images/, data/NAME/data.json).
    bench: PathBuf,
    /// Output folder for the NAME.png overlays.
    #[arg(long)]
    out: PathBuf,
    /// Magnify photos whose longer side is below this many pixels twofold.
    #[arg(long, default_value_t = 450)]
    magnify_below: u32,
}

/// Arguments of `matseg bench-set make`.
#[derive(clap::Args)]
pub struct MakeArgs {
    /// Output folder (images/, data/).
    #[arg(long)]
    out: PathBuf,
    /// Number of scenes to generate (scenes with fewer than two pointed
    /// materials are left out).
    #[arg(short = 'n', long = "scenes", default_value_t = 20)]
    n: u64,
    /// Seed: scene i depends only on (seed, i).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Points per material.
    #[arg(long, default_value_t = 5)]
    points: usize,
    /// Folders of natural photos; default: the fetched corpus, else bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Folders of textures; default: the fetched corpus, else bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    #[command(flatten)]
    licences: LicenceArgs,
}

/// Runs `matseg bench-set`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Make(args) => make(args),
        Command::Draw(args) => draw(args),
    }
}

fn draw(args: DrawArgs) -> Result<()> {
    let bench = load_point_benchmark(&args.bench, false)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;
    let mut points = 0;
    for image in &bench.images {
        let photo = read_rgb(&image.image_path)?;
        let scale = if photo.width().max(photo.height()) < args.magnify_below {
            2
        } else {
            1
        };
        let path = args.out.join(format!("{}.png", image.name));
        write_atomic(&path, &encode_png_rgb(&draw_points(&photo, image, scale)))
            .with_context(|| format!("{}: cannot write", path.display()))?;
        points += image.points.iter().map(Vec::len).sum::<usize>();
    }
    println!(
        "{}: {} overlays, {points} points",
        args.out.display(),
        bench.images.len()
    );
    Ok(())
}

fn make(args: MakeArgs) -> Result<()> {
    ensure!(args.points >= 1, "--points must be at least 1");
    let libs = load_libraries(
        &args.sources,
        &args.textures,
        DEFAULT_CACHE_MB,
        Defaults::CorpusOrBundled,
        &args.licences.filter()?,
    )?;
    let recipe = Recipe2d::default();
    let options = SyntheticOptions {
        points_per_material: args.points,
        ..SyntheticOptions::default()
    };
    let (mut written, mut left_out) = (0u64, 0u64);
    for i in 0..args.n {
        let mut rng = sample_rng(args.seed, i);
        let scene = generate_2d(&mut rng, &recipe, libs.sources())?;
        let weights: Vec<_> = scene.weights.iter().map(|w| w.to_plane()).collect();
        let annotation = annotate_points(&mut rng, &weights, &options);
        if annotation.materials.len() < 2 {
            left_out += 1;
            continue;
        }
        let name = format!("scene{i:05}");
        write_point_image(&args.out, &name, &scene.image, &annotation)
            .with_context(|| format!("{}: cannot write {name}", args.out.display()))?;
        written += 1;
    }
    println!(
        "{}: point benchmark of {written} scenes ({left_out} with fewer than two pointed materials left out)",
        args.out.display()
    );
    Ok(())
}
