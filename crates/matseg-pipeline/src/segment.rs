//! Inference (pipeline.md §8): where else in a photo is the material under
//! these points? A model ([`Model::load`]) describes the photo once
//! ([`describe`]); each point's similarity map and the segmentation by
//! nearest point, or by clustering the descriptors with no points, are
//! answered from that description, and drawn as images over the photo.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use crate::select::{select_materials, write_selection, MaterialClicks};
use image::RgbImage;
use matseg_image::io::{encode_png_grey, encode_png_rgb};
use matseg_model::config::TEMPERATURE;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::check_radius;
use matseg_query::{cluster_descriptors, ClusterOptions};
use matseg_scene::{blend_annotation_colour, PALETTE};
use std::path::Path;
use std::time::Instant;

pub use crate::nets::load_net as load_model;
/// A trained model, loaded by [`load_model`]: `default`, a run folder or
/// a weights file, on a device.
pub use matseg_query::net::NamedNet as Model;

/// Radius of a query point's disc, in pixels, unless a caller says otherwise.
pub const DEFAULT_RADIUS: f32 = 5.0;

/// The most points of one segmentation (labels are 8-bit).
pub const MAX_POINTS: usize = 255;

/// The model's descriptors of `photo`, on a coarse grid that answers any
/// number of points.
pub fn describe(model: &Model, photo: &RgbImage) -> CoarseDescriptors {
    model.net().describe_coarse(photo)
}

/// Checks that there are at most [`MAX_POINTS`] points and each lies
/// inside `photo` (named `label` in the message).
pub fn check_points(
    photo: &RgbImage,
    points: &[(f32, f32)],
    label: &str,
) -> Result<(), PipelineError> {
    check_clicks(photo, points, label, "point")
}

/// Checks that there are at most [`MAX_POINTS`] clicks and each lies
/// inside `photo` (named `label` in the message), the clicks named
/// `name` (the argument that gave them: `point`, `not`).
pub fn check_clicks(
    photo: &RgbImage,
    points: &[(f32, f32)],
    label: &str,
    name: &str,
) -> Result<(), PipelineError> {
    let (w, h) = (photo.width() as f32, photo.height() as f32);
    if points.len() > MAX_POINTS {
        return Err(PipelineError::setting(
            name,
            None::<&str>,
            format!(
                "{} clicks: at most {MAX_POINTS} (labels.png is 8-bit)",
                points.len()
            ),
        ));
    }
    for &(x, y) in points {
        if !(0.0..w).contains(&x) || !(0.0..h).contains(&y) {
            return Err(PipelineError::setting(
                name,
                Some(format!("{x},{y}")),
                format!("outside {label} ({w}x{h})"),
            ));
        }
    }
    Ok(())
}

/// Refuses a negative click on the pixel of a positive one: a click
/// cannot both select and exclude a material.
pub fn check_contradictions(
    points: &[(f32, f32)],
    negatives: &[(f32, f32)],
) -> Result<(), PipelineError> {
    let pixel = |(x, y): (f32, f32)| (x.floor() as i64, y.floor() as i64);
    for &negative in negatives {
        if let Some(&(x, y)) = points.iter().find(|&&p| pixel(p) == pixel(negative)) {
            return Err(PipelineError::setting(
                "not",
                Some(format!("{},{}", negative.0, negative.1)),
                format!(
                    "on the pixel of --point {x},{y}: a click cannot both select and exclude a material"
                ),
            ));
        }
    }
    Ok(())
}

/// Each point's answer, and the segmentation of several points.
pub struct PointMaps {
    /// Per point, the cosine similarity of every pixel to the point's
    /// descriptor (row-major, the photo's size).
    pub similarity: Vec<Vec<f32>>,
    /// With two points or more, each pixel's nearest point (its label).
    pub labels: Option<Vec<u32>>,
    /// Seconds spent on the points' descriptors and similarity maps.
    pub seconds: f64,
}

/// The similarity maps of `points` (pixels, inside the photo; discs of
/// `radius`) and, for several points, the nearest-point segmentation.
pub fn query_points(map: &CoarseDescriptors, points: &[(f32, f32)], radius: f32) -> PointMaps {
    let started = Instant::now();
    let similarity: Vec<Vec<f32>> = points
        .iter()
        .map(|&(x, y)| map.similarity_map(&map.point_descriptor(x, y, radius)))
        .collect();
    let seconds = started.elapsed().as_secs_f64();
    let labels = (points.len() > 1).then(|| CoarseDescriptors::nearest_of(&similarity));
    PointMaps {
        similarity,
        labels,
        seconds,
    }
}

/// The segmentation of the photo into the clusters of its descriptors
/// (spherical k-means on the grid; each pixel takes its nearest centre):
/// the labels and the number of clusters.
pub fn cluster(map: &CoarseDescriptors, options: &ClusterOptions) -> (Vec<u32>, usize) {
    let clustering = cluster_descriptors(&map.grid, options);
    (
        map.nearest_query(&clustering.centres),
        clustering.centres.len(),
    )
}

/// A similarity map as 8-bit grey: cosine in [0, 1] to 0..255, negative
/// similarity black.
pub fn similarity_grey(similarity: &[f32]) -> Vec<u8> {
    similarity
        .iter()
        .map(|s| (s.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect()
}

/// `photo` painted red where `similarity` is high, with the query points'
/// discs outlined in white. The red's strength is the training softmax's
/// weight of the point's material relative to a perfect match,
/// `exp((s - 1) / T)`, so the map reads as the net was taught to read it
/// (cosine 1: full red; 0.8: 37%; 0.5: 8%).
pub fn similarity_overlay(
    photo: &RgbImage,
    similarity: &[f32],
    points: &[(f32, f32)],
    radius: f32,
) -> RgbImage {
    let mut overlay = photo.clone();
    for (p, &s) in overlay.pixels_mut().zip(similarity) {
        let a = (((s - 1.0) as f64 / TEMPERATURE).exp() as f32).clamp(0.0, 1.0);
        p.0 = [
            (p.0[0] as f32 * (1.0 - a) + 255.0 * a) as u8,
            (p.0[1] as f32 * (1.0 - a)) as u8,
            (p.0[2] as f32 * (1.0 - a)) as u8,
        ];
    }
    for &point in points {
        outline_disc(&mut overlay, point, radius);
    }
    overlay
}

/// `photo` with each pixel's label colour (the annotation palette) blended
/// over it, two parts colour to one part photo.
pub fn segmentation_overlay(photo: &RgbImage, labels: &[u32]) -> RgbImage {
    let mut segmentation = photo.clone();
    for (p, &label) in segmentation.pixels_mut().zip(labels) {
        blend_annotation_colour(&mut p.0, PALETTE[label as usize % PALETTE.len()]);
    }
    segmentation
}

/// Writes into `out`, for each material `K` of `clicks`:
/// `similarity_K.png` (grey: its similarity, lowered near negative
/// clicks), `overlay_K.png`, `mask_K.png` (its selection's own mask) and
/// `selection_K.json` (its clicks' descriptors, for `matseg apply`; `model`
/// names the model); for several materials `segmentation.png` and
/// `labels.png` (each pixel's nearest material). Every file atomically.
/// Clicks must have been checked ([`MaterialClicks::check`]). Returns the
/// seconds spent on the selections (not drawing or writing them).
pub fn write_point_maps(
    photo: &RgbImage,
    map: &CoarseDescriptors,
    clicks: &MaterialClicks,
    radius: f32,
    model: &str,
    out: &Path,
) -> Result<f64, PipelineError> {
    check_radius(radius).map_err(|e| PipelineError::Settings(e.to_string()))?;
    create_folder(out)?;
    let (w, h) = photo.dimensions();
    let started = Instant::now();
    let selections = select_materials(map, photo, clicks, radius, model)?;
    let seconds = started.elapsed().as_secs_f64();
    for (k, (selection, points)) in selections.iter().zip(&clicks.materials).enumerate() {
        let grey = similarity_grey(&selection.soft);
        write_file(
            &out.join(format!("similarity_{k}.png")),
            &encode_png_grey(w, h, &grey),
        )?;
        let overlay = similarity_overlay(photo, &selection.soft, points, radius);
        write_file(
            &out.join(format!("overlay_{k}.png")),
            &encode_png_rgb(&overlay),
        )?;
        write_selection(photo, k, selection, out)?;
    }
    if selections.len() > 1 {
        let soft: Vec<Vec<f32>> = selections.into_iter().map(|s| s.soft).collect();
        write_segmentation(photo, &CoarseDescriptors::nearest_of(&soft), out)?;
    }
    Ok(seconds)
}

/// Writes into `out` the segmentation of `photo` into the clusters of its
/// descriptors (`segmentation.png`, `labels.png`); returns the number of
/// clusters.
pub fn write_clusters(
    photo: &RgbImage,
    map: &CoarseDescriptors,
    options: &ClusterOptions,
    out: &Path,
) -> Result<usize, PipelineError> {
    create_folder(out)?;
    let (labels, clusters) = cluster(map, options);
    write_segmentation(photo, &labels, out)?;
    Ok(clusters)
}

/// Writes `segmentation.png` ([`segmentation_overlay`]) and `labels.png`
/// (8-bit grey, pixel value = label).
fn write_segmentation(photo: &RgbImage, labels: &[u32], out: &Path) -> Result<(), PipelineError> {
    let segmentation = segmentation_overlay(photo, labels);
    write_file(
        &out.join("segmentation.png"),
        &encode_png_rgb(&segmentation),
    )?;
    let grey: Vec<u8> = labels.iter().map(|&l| l as u8).collect();
    write_file(
        &out.join("labels.png"),
        &encode_png_grey(photo.width(), photo.height(), &grey),
    )
}

/// Draws the outline of the disc of `radius` (at least 3) around `point`
/// in white.
pub(crate) fn outline_disc(img: &mut RgbImage, (x, y): (f32, f32), radius: f32) {
    let r = radius.max(3.0);
    for k in 0..64 {
        let t = k as f32 / 64.0 * std::f32::consts::TAU;
        let (px, py) = ((x + r * t.cos()).round(), (y + r * t.sin()).round());
        if px >= 0.0 && py >= 0.0 && (px as u32) < img.width() && (py as u32) < img.height() {
            img.put_pixel(px as u32, py as u32, image::Rgb([255, 255, 255]));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_query::descriptor::DescriptorMap;

    /// A 4x2 photo whose left half is one material and right half another,
    /// described on a 2x1 grid of unit descriptors.
    fn halves() -> (RgbImage, CoarseDescriptors) {
        let photo = RgbImage::from_fn(4, 2, |x, _| image::Rgb([60 * x as u8, 100, 200]));
        let grid = DescriptorMap {
            width: 2,
            height: 1,
            dim: 2,
            data: vec![1.0, 0.0, 0.0, 1.0],
        };
        let map = CoarseDescriptors {
            grid,
            width: 4,
            height: 2,
        };
        (photo, map)
    }

    #[test]
    fn points_find_their_own_half() {
        let (_, map) = halves();
        let maps = query_points(&map, &[(0.5, 0.5), (3.5, 1.5)], 0.5);
        let first = &maps.similarity[0];
        assert!(first[0] > 0.99 && first[3] < 0.01, "{first:?}");
        assert_eq!(maps.labels.unwrap(), vec![0, 0, 1, 1, 0, 0, 1, 1]);
        assert!(query_points(&map, &[(0.5, 0.5)], 0.5).labels.is_none());
    }

    #[test]
    fn overlays_paint_where_the_material_is() {
        let (photo, map) = halves();
        let maps = query_points(&map, &[(0.5, 0.5)], 0.5);
        assert_eq!(
            similarity_grey(&[-0.5, 0.0, 0.5, 1.0, 2.0]),
            vec![0, 0, 128, 255, 255]
        );
        let overlay = similarity_overlay(&photo, &maps.similarity[0], &[(0.5, 0.5)], 0.5);
        // Full red where the similarity is 1.
        assert_eq!(overlay.get_pixel(0, 1).0, [255, 0, 0]);
        // Far from the point, exp(-1 / T) of red: the photo nearly as it is.
        let far = overlay.get_pixel(3, 0).0;
        assert!(far[1] >= 99 && far[2] >= 198, "{far:?}");
        // The point's disc is outlined in white on a photo large enough.
        let big = RgbImage::new(16, 16);
        let outlined = similarity_overlay(&big, &[0.0; 256], &[(8.0, 8.0)], 5.0);
        assert_eq!(outlined.get_pixel(13, 8).0, [255, 255, 255]);
        // Inside, cosine 0 on black: exp(-1 / T) of full red, 255 * 0.0067.
        assert_eq!(outlined.get_pixel(8, 8).0, [1, 0, 0]);
        let segmentation = segmentation_overlay(&photo, &[0, 0, 1, 1, 0, 0, 1, 1]);
        let c = PALETTE[1];
        let p = photo.get_pixel(2, 0).0;
        let want: Vec<u8> = (0..3)
            .map(|i| ((p[i] as u16 + 2 * c[i] as u16) / 3) as u8)
            .collect();
        assert_eq!(segmentation.get_pixel(2, 0).0.to_vec(), want);
    }

    #[test]
    fn points_outside_the_photo_are_refused() {
        let (photo, _) = halves();
        assert!(check_points(&photo, &[(3.9, 1.9)], "p.jpg").is_ok());
        let outside = check_points(&photo, &[(4.0, 0.0)], "p.jpg").unwrap_err();
        assert_eq!(outside.to_string(), "point 4,0: outside p.jpg (4x2)");
        let many = vec![(0.0, 0.0); MAX_POINTS + 1];
        assert!(check_points(&photo, &many, "p.jpg").is_err());
    }

    #[test]
    fn point_maps_are_written_with_the_segmentation() {
        let (photo, map) = halves();
        let dir = tempfile::tempdir().unwrap();
        let clicks = MaterialClicks::group(&[(None, (0.5, 0.5)), (None, (3.5, 1.5))], vec![]);
        write_point_maps(&photo, &map, &clicks, 0.5, "m", dir.path()).unwrap();
        let labels = image::open(dir.path().join("labels.png"))
            .unwrap()
            .to_luma8();
        assert_eq!(labels.as_raw(), &vec![0, 0, 1, 1, 0, 0, 1, 1]);
        let mask = image::open(dir.path().join("mask_1.png"))
            .unwrap()
            .to_luma8();
        assert_eq!(mask.as_raw(), &vec![0, 0, 255, 255, 0, 0, 255, 255]);
        for name in [
            "similarity_0.png",
            "overlay_1.png",
            "segmentation.png",
            "selection_0.json",
        ] {
            assert!(dir.path().join(name).is_file(), "{name}");
        }
    }
}
