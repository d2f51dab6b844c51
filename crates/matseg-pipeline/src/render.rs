//! One scene description rendered by the path tracer and written with its
//! exact material annotation (`matseg render`).

use crate::bench::clock::process_cpu_seconds;
use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use matseg_image::io::{encode_png_grey, encode_png_rgb};
use matseg_render::hdr_io::{encode_radiance, HdrImage};
use matseg_render::{render, tone_map, SceneDescription};
use matseg_scene::{colourise, quantise_fractions};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Overrides of the scene's own settings.
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderOverrides {
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Width (the height follows the scene's aspect ratio).
    pub width: Option<u32>,
    /// Worker threads (0 or `None`: all cores).
    pub threads: Option<usize>,
    /// Denoise the image whatever the scene says.
    pub denoise: bool,
}

/// What a render did, as written to `render.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RenderReport {
    /// The scene file.
    pub scene: String,
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Samples per pixel.
    pub spp: u32,
    /// Triangles in the scene.
    pub triangles: usize,
    /// Scene material index of each mask, in mask order.
    pub annotated_materials: Vec<usize>,
    /// Seconds to load the scene.
    pub load_seconds: f64,
    /// Wall seconds of the render.
    pub render_seconds: f64,
    /// Process CPU time of the render (all threads), where the platform tells it.
    pub render_cpu_seconds: Option<f64>,
}

/// Renders the scene file `scene` (relative paths in it are relative to
/// its folder) and writes into `out` the image (`image.png`, and
/// `radiance.hdr`), each material's mask, the ROI, the colour annotation
/// and `render.json`.
pub fn render_scene_file(
    scene: &Path,
    overrides: &RenderOverrides,
    out: &Path,
) -> Result<RenderReport, PipelineError> {
    let mut description = SceneDescription::read(scene)?;
    if let Some(spp) = overrides.spp {
        if spp < 1 {
            return Err(PipelineError::Settings("--spp must be at least 1".into()));
        }
        description.spp = spp;
    }
    description.denoise |= overrides.denoise;
    if let Some(w) = overrides.width {
        if w < 1 {
            return Err(PipelineError::Settings("--width must be at least 1".into()));
        }
        let h = (description.height as f64 * w as f64 / description.width as f64)
            .round()
            .max(1.0);
        description.width = w;
        description.height = h as u32;
    }
    let base = scene.parent().map(PathBuf::from).unwrap_or_default();
    let started = Instant::now();
    let loaded = description.load(&base)?;
    let load_seconds = started.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(overrides.threads.unwrap_or(0))
        .build()
        .map_err(|e| PipelineError::Settings(format!("threads: {e}")))?;
    let cpu_before = process_cpu_seconds();
    let started = Instant::now();
    let rendered = pool.install(|| render(&loaded))?;
    let render_seconds = started.elapsed().as_secs_f64();
    let render_cpu_seconds = process_cpu_seconds()
        .zip(cpu_before)
        .map(|(after, before)| after - before);

    create_folder(out)?;
    let write = |name: &str, bytes: Vec<u8>| write_file(&out.join(name), &bytes);
    let (w, h) = (rendered.width, rendered.height);
    write(
        "image.png",
        encode_png_rgb(&tone_map(&rendered.radiance, w, h, description.exposure_ev)),
    )?;
    write(
        "radiance.hdr",
        encode_radiance(&HdrImage {
            width: w,
            height: h,
            pixels: rendered.radiance.clone(),
        }),
    )?;
    let masks = quantise_fractions(w, h, &rendered.fractions, &rendered.roi);
    for (k, mask) in masks.masks.iter().enumerate() {
        write(
            &format!("mask{k}.png"),
            encode_png_grey(w as u32, h as u32, mask),
        )?;
    }
    write("roi.png", encode_png_grey(w as u32, h as u32, &masks.roi))?;
    let planes: Vec<&[f32]> = rendered.fractions.iter().map(|f| f.as_slice()).collect();
    write("annotation.png", encode_png_rgb(&colourise(w, h, &planes)))?;
    let report = RenderReport {
        scene: scene.display().to_string(),
        width: w,
        height: h,
        spp: description.spp,
        triangles: loaded.mesh.triangles.len(),
        annotated_materials: rendered.annotated.clone(),
        load_seconds,
        render_seconds,
        render_cpu_seconds,
    };
    write(
        "render.json",
        serde_json::to_vec_pretty(&report).expect("a report serialises"),
    )?;
    Ok(report)
}
