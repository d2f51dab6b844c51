//! What a tool outside matseg must answer for a benchmark: each photo at
//! the size it is scored at and the points the protocol asks about, in
//! order (`matseg eval maps-template`). A tool that writes descriptor maps
//! needs only the photos; one that writes similarity maps answers one map
//! per listed point.

use crate::evaluate::{mask_queries, point_queries};
use crate::masks::{MaskImage, QueryOptions};
use crate::points::{BenchError, PointBenchmark};
use image::RgbImage;
use matseg_image::io::encode_png_rgb;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The folder, inside a template, of the photos at their scored size.
pub const PHOTOS_FOLDER: &str = "photos";
/// The template's list of photos and points.
pub const TEMPLATE_FILE: &str = "template.json";

/// A benchmark's questions.
#[derive(Clone, Debug, Serialize)]
pub struct Template {
    /// `points` or `masks`.
    pub protocol: &'static str,
    /// Each photo asked about, in benchmark order.
    pub images: Vec<TemplateImage>,
}

/// One photo's questions.
#[derive(Clone, Debug, Serialize)]
pub struct TemplateImage {
    /// Its name: its maps are `NAME.npy` or `NAME.safetensors`.
    pub name: String,
    /// Its file in the benchmark.
    pub source: PathBuf,
    /// Its width as scored.
    pub width: u32,
    /// Its height as scored.
    pub height: u32,
    /// The points `[x, y]` asked about, in scored pixels.
    pub points: Vec<(f32, f32)>,
    /// The photo at its scored size.
    #[serde(skip)]
    pub pixels: RgbImage,
}

/// The questions of a point benchmark scored at `max_side`.
pub fn point_template(bench: &PointBenchmark, max_side: u32) -> Result<Template, BenchError> {
    let images = bench
        .images
        .iter()
        .map(|image| {
            let queries = point_queries(image, max_side)?;
            Ok(TemplateImage {
                name: image.name.clone(),
                source: image.image_path.clone(),
                width: queries.pixels.width(),
                height: queries.pixels.height(),
                points: queries.discs.iter().map(|&(x, y, _)| (x, y)).collect(),
                pixels: queries.pixels,
            })
        })
        .collect::<Result<_, BenchError>>()?;
    Ok(Template {
        protocol: "points",
        images,
    })
}

/// The questions of a mask benchmark scored at longer side `max_side`,
/// its query points drawn as `draws` says; photos with no mask large
/// enough to query are not asked about and not listed.
pub fn mask_template(
    images: &[MaskImage],
    max_side: u32,
    draws: &QueryOptions,
) -> Result<Template, BenchError> {
    let mut listed = Vec::new();
    for (index, image) in images.iter().enumerate() {
        let queries = mask_queries(image, index, max_side, draws)?;
        if queries.queried.is_empty() {
            continue;
        }
        listed.push(TemplateImage {
            name: image.name.clone(),
            source: image.image_path.clone(),
            width: queries.pixels.width(),
            height: queries.pixels.height(),
            points: queries.asked,
            pixels: queries.pixels,
        });
    }
    Ok(Template {
        protocol: "masks",
        images: listed,
    })
}

/// Writes `template` into the folder `dir`: `template.json` and
/// `photos/NAME.png`, each photo at its scored size.
pub fn write_template(dir: &Path, template: &Template) -> Result<(), BenchError> {
    let photos = dir.join(PHOTOS_FOLDER);
    std::fs::create_dir_all(&photos)
        .map_err(|e| BenchError::new(&photos, None, format!("cannot create: {e}")))?;
    for image in &template.images {
        let path = photos.join(format!("{}.png", image.name));
        std::fs::write(&path, encode_png_rgb(&image.pixels))
            .map_err(|e| BenchError::new(&path, None, format!("cannot write: {e}")))?;
    }
    let path = dir.join(TEMPLATE_FILE);
    let json = serde_json::to_vec_pretty(template).expect("plain JSON values");
    std::fs::write(&path, json)
        .map_err(|e| BenchError::new(&path, None, format!("cannot write: {e}")))
}
