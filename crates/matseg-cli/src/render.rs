//! `matseg render`: renders one scene description (JSON) with the path
//! tracer and writes the image with its exact material annotation
//! (`matseg_pipeline::render`).

use anyhow::Result;
use matseg_image::outputs::StagedOutput;
use matseg_pipeline::render::{render_scene_file, RenderOverrides};
use std::path::PathBuf;

/// Arguments of `matseg render`.
#[derive(clap::Args)]
pub struct Args {
    /// The scene description (JSON); relative paths in it are relative to its folder.
    scene: PathBuf,
    /// Output folder; written whole, replacing only an earlier render
    /// output (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Samples per pixel (default: the scene's).
    #[arg(long)]
    spp: Option<u32>,
    /// Render at this width instead (height follows the scene's aspect ratio).
    #[arg(long)]
    width: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Denoise the image (whatever the scene says).
    #[arg(long)]
    denoise: bool,
}

/// Runs `matseg render`.
pub fn run(args: Args) -> Result<()> {
    let overrides = RenderOverrides {
        spp: args.spp,
        width: args.width,
        threads: args.threads,
        denoise: args.denoise,
    };
    let staged = StagedOutput::begin(&args.out, "render", &[&args.scene])?;
    let r = render_scene_file(&args.scene, &overrides, staged.dir())?;
    staged.finish()?;
    println!(
        "{}x{} at {} spp, {} triangles: {:.2} s ({} CPU s) -> {}",
        r.width,
        r.height,
        r.spp,
        r.triangles,
        r.render_seconds,
        r.render_cpu_seconds
            .map_or("?".into(), |s| format!("{s:.2}")),
        args.out.display()
    );
    Ok(())
}
