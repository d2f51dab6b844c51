//! `matseg render`: renders one scene description (JSON) with the path
//! tracer and writes the image with its exact material annotation.

use anyhow::{Context, Result};
use matseg_image::io::{encode_png_gray, encode_png_rgb, write_atomic};
use matseg_render::hdr_io::{encode_radiance, HdrImage};
use matseg_render::{render, tone_map, SceneDescription};
use matseg_scene::{colourise, quantise_fractions};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `matseg render`.
#[derive(clap::Args)]
pub struct Args {
    /// The scene description (JSON); relative paths in it are relative to its folder.
    scene: PathBuf,
    /// Output folder.
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

#[derive(Serialize)]
struct RenderReport {
    scene: String,
    width: usize,
    height: usize,
    spp: u32,
    triangles: usize,
    /// Scene material index of each mask, in mask order.
    annotated_materials: Vec<usize>,
    load_seconds: f64,
    render_seconds: f64,
    /// Process CPU time of the render (all threads), where the platform tells it.
    render_cpu_seconds: Option<f64>,
}

/// Runs `matseg render`.
pub fn run(args: Args) -> Result<()> {
    let mut description = SceneDescription::read(&args.scene)?;
    if let Some(spp) = args.spp {
        anyhow::ensure!(spp >= 1, "--spp must be at least 1");
        description.spp = spp;
    }
    description.denoise |= args.denoise;
    if let Some(w) = args.width {
        anyhow::ensure!(w >= 1, "--width must be at least 1");
        let h = (description.height as f64 * w as f64 / description.width as f64)
            .round()
            .max(1.0);
        description.width = w;
        description.height = h as u32;
    }
    let base = args.scene.parent().map(PathBuf::from).unwrap_or_default();
    let started = Instant::now();
    let scene = description
        .load(&base)
        .with_context(|| format!("{}: cannot load the scene", args.scene.display()))?;
    let load_seconds = started.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()?;
    let cpu_before = matseg_pipeline::bench::clock::process_cpu_seconds();
    let started = Instant::now();
    let out = pool
        .install(|| render(&scene))
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    let render_seconds = started.elapsed().as_secs_f64();
    let render_cpu_seconds = matseg_pipeline::bench::clock::process_cpu_seconds()
        .zip(cpu_before)
        .map(|(after, before)| after - before);

    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let write = |name: &str, bytes: Vec<u8>| {
        let path = args.out.join(name);
        write_atomic(&path, &bytes).with_context(|| path.display().to_string())
    };
    let (w, h) = (out.width, out.height);
    write(
        "image.png",
        encode_png_rgb(&tone_map(&out.radiance, w, h, description.exposure_ev)),
    )?;
    write(
        "radiance.hdr",
        encode_radiance(&HdrImage {
            width: w,
            height: h,
            pixels: out.radiance.clone(),
        }),
    )?;
    let masks = quantise_fractions(w, h, &out.fractions, &out.roi);
    for (k, mask) in masks.masks.iter().enumerate() {
        write(
            &format!("mask{k}.png"),
            encode_png_gray(w as u32, h as u32, mask),
        )?;
    }
    write("roi.png", encode_png_gray(w as u32, h as u32, &masks.roi))?;
    let planes: Vec<&[f32]> = out.fractions.iter().map(|f| f.as_slice()).collect();
    write("annotation.png", encode_png_rgb(&colourise(w, h, &planes)))?;
    let report = RenderReport {
        scene: args.scene.display().to_string(),
        width: w,
        height: h,
        spp: description.spp,
        triangles: scene.mesh.triangles.len(),
        annotated_materials: out.annotated.clone(),
        load_seconds,
        render_seconds,
        render_cpu_seconds,
    };
    write("render.json", serde_json::to_vec_pretty(&report)?)?;
    println!(
        "{}x{} at {} spp, {} triangles: {:.2} s ({} CPU s) -> {}",
        w,
        h,
        description.spp,
        report.triangles,
        render_seconds,
        render_cpu_seconds.map_or("?".into(), |s| format!("{s:.2}")),
        args.out.display()
    );
    Ok(())
}
