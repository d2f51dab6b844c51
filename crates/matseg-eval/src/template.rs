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
}

/// A template written into a folder photo by photo, so no more than one
/// photo is held at a time.
struct TemplateWriter<'a> {
    photos: PathBuf,
    dir: &'a Path,
    template: Template,
}

impl<'a> TemplateWriter<'a> {
    fn new(dir: &'a Path, protocol: &'static str) -> Result<Self, BenchError> {
        let photos = dir.join(PHOTOS_FOLDER);
        std::fs::create_dir_all(&photos)
            .map_err(|e| BenchError::new(&photos, None, format!("cannot create: {e}")))?;
        Ok(Self {
            photos,
            dir,
            template: Template {
                protocol,
                images: Vec::new(),
            },
        })
    }

    /// Writes photo `name` at its scored size and lists it with `points`.
    fn add(
        &mut self,
        name: &str,
        source: &Path,
        pixels: &RgbImage,
        points: Vec<(f32, f32)>,
    ) -> Result<(), BenchError> {
        let path = self.photos.join(format!("{name}.png"));
        write(&path, &encode_png_rgb(pixels))?;
        self.template.images.push(TemplateImage {
            name: name.to_string(),
            source: source.to_path_buf(),
            width: pixels.width(),
            height: pixels.height(),
            points,
        });
        Ok(())
    }

    /// Writes `template.json`, last.
    fn finish(self) -> Result<Template, BenchError> {
        let json = serde_json::to_vec_pretty(&self.template).expect("plain JSON values");
        write(&self.dir.join(TEMPLATE_FILE), &json)?;
        Ok(self.template)
    }
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), BenchError> {
    std::fs::write(path, bytes)
        .map_err(|e| BenchError::new(path, None, format!("cannot write: {e}")))
}

/// Writes into the folder `dir` the questions of a point benchmark scored
/// at `max_side`: `photos/NAME.png` at the scored size, then
/// `template.json`.
pub fn write_point_template(
    dir: &Path,
    bench: &PointBenchmark,
    max_side: u32,
) -> Result<Template, BenchError> {
    let mut writer = TemplateWriter::new(dir, "points")?;
    for image in &bench.images {
        let queries = point_queries(image, max_side)?;
        let points = queries.discs.iter().map(|&(x, y, _)| (x, y)).collect();
        writer.add(&image.name, &image.image_path, &queries.pixels, points)?;
    }
    writer.finish()
}

/// Writes into the folder `dir` the questions of a mask benchmark scored at
/// longer side `max_side`, its query points drawn as `draws` says, as
/// [`write_point_template`] does; photos with no mask large enough to
/// query are not asked about and not listed.
pub fn write_mask_template(
    dir: &Path,
    images: &[MaskImage],
    max_side: u32,
    draws: &QueryOptions,
) -> Result<Template, BenchError> {
    let mut writer = TemplateWriter::new(dir, "masks")?;
    for (index, image) in images.iter().enumerate() {
        let queries = mask_queries(image, index, max_side, draws)?;
        if !queries.queried.is_empty() {
            writer.add(
                &image.name,
                &image.image_path,
                &queries.pixels,
                queries.asked,
            )?;
        }
    }
    writer.finish()
}
