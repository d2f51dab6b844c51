//! Running a model over a benchmark: images resized to the evaluation size,
//! descriptor maps, point descriptors, and the dataset means of the scores.

use crate::iou::{best_iou, best_iou_on_grid};
use crate::masks::{draw_mask_points, MaskImage, QueryOptions};
use crate::model::{Disc, Question, ScoredModel};
use crate::points::{flatten, BenchError, BenchImage, PointBenchmark};
use crate::triplet::{score_image, ImageScores, PointScores};
use image::{GrayImage, RgbImage};
use matseg_image::io::{decode_grey, read_rgb};
use matseg_image::progress::Progress;
use matseg_image::Pyramid;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// The longer side, in pixels, benchmark images are evaluated at unless
/// told otherwise (pipeline.md §9.1).
pub const DEFAULT_MAX_SIDE: u32 = 700;

/// The image resized so that its longer side is `max_side` (unchanged for
/// 0), and the scale applied.
pub fn resize_longer_side(image: RgbImage, max_side: u32) -> (RgbImage, f32) {
    let longer = image.width().max(image.height());
    if max_side == 0 || longer == max_side {
        return (image, 1.0);
    }
    let scale = max_side as f32 / longer as f32;
    let w = ((image.width() as f32 * scale).round() as usize).max(1);
    let h = ((image.height() as f32 * scale).round() as usize).max(1);
    let resized = Pyramid::new(image).resize(w, h);
    (resized, scale)
}

/// Dataset scores of one model on a point benchmark.
#[derive(Clone, Debug, Serialize)]
pub struct PointReport {
    /// The model.
    pub model: String,
    /// Mean over images of each image score (images without one left out).
    pub all_by_material: Option<f64>,
    /// See [`ImageScores::all_by_point`].
    pub all_by_point: Option<f64>,
    /// See [`ImageScores::soft_by_material`].
    pub soft_by_material: Option<f64>,
    /// See [`ImageScores::soft_by_point`].
    pub soft_by_point: Option<f64>,
    /// See [`ImageScores::top1_by_material`].
    pub top1_by_material: Option<f64>,
    /// See [`ImageScores::top1_by_point`].
    pub top1_by_point: Option<f64>,
    /// What was counted.
    pub counts: PointCounts,
    /// Every image's scores.
    pub images: Vec<NamedScores>,
}

/// One image's scores, with its name.
#[derive(Clone, Debug, Serialize)]
pub struct NamedScores {
    /// The image.
    pub name: String,
    /// Its scores.
    #[serde(flatten)]
    pub scores: ImageScores,
}

/// Sizes of a point evaluation.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PointCounts {
    /// Images evaluated.
    pub images: usize,
    /// Images in the Soft subset (with relations).
    pub soft_images: usize,
    /// Points.
    pub points: usize,
    /// Triplets counted for All.
    pub triplets: u64,
    /// Triplets counted for Soft.
    pub soft_triplets: u64,
}

/// A point benchmark photo ready to be asked about.
pub struct PointQueries {
    /// The photo at the scored size.
    pub pixels: RgbImage,
    /// Its points' discs, scaled alike, in the order of [`flatten`].
    pub discs: Vec<Disc>,
    /// The material of each point (an index into the image's weights).
    pub material: Vec<usize>,
}

/// Image `image` of a point benchmark at the scored size (longer side
/// `max_side`), its points and their materials.
pub fn point_queries(image: &BenchImage, max_side: u32) -> Result<PointQueries, BenchError> {
    let (pixels, scale) = resize_longer_side(read_rgb(&image.image_path)?, max_side);
    let (points, material) = flatten(image);
    let discs = points
        .iter()
        .map(|p| (p.x * scale, p.y * scale, p.r * scale))
        .collect();
    Ok(PointQueries {
        pixels,
        discs,
        material,
    })
}

/// Scores `model` on every image of `bench`, evaluated with the longer side
/// resized to `max_side` (points scaled alike). Each image scored is a step
/// of `progress` (the caller starts and finishes it); when `progress` is
/// cancelled, the images not yet begun are not scored and the answer is an
/// error saying so.
pub fn evaluate_points(
    model: &dyn ScoredModel,
    bench: &PointBenchmark,
    max_side: u32,
    progress: &dyn Progress,
) -> Result<PointReport, BenchError> {
    let mut counts = PointCounts::default();
    let mut images = Vec::new();
    let score = |image: &BenchImage| -> Result<(NamedScores, usize), BenchError> {
        check_cancelled(progress, &image.image_path)?;
        let PointQueries {
            pixels,
            discs,
            material,
        } = point_queries(image, max_side)?;
        let asked: Vec<(f32, f32)> = discs.iter().map(|&(x, y, _)| (x, y)).collect();
        let answer = model.answer(&Question {
            name: &image.name,
            path: &image.image_path,
            pixels: &pixels,
            points: &asked,
        })?;
        let similarity = answer.similarity_matrix(&discs);
        let scores = score_image(
            &PointScores {
                material: &material,
                weight: &|a, b| image.weights[a][b],
                similarity: &|i, j| similarity[i][j],
            },
            image.has_relations,
        );
        let named = NamedScores {
            name: image.name.clone(),
            scores,
        };
        progress.advance();
        Ok((named, discs.len()))
    };
    // Images are scored in parallel when the model allows it, and gathered
    // in benchmark order.
    let scored: Vec<(NamedScores, usize)> = if model.parallel() {
        bench
            .images
            .par_iter()
            .map(score)
            .collect::<Result<_, _>>()?
    } else {
        bench.images.iter().map(score).collect::<Result<_, _>>()?
    };
    for ((named, points), image) in scored.into_iter().zip(&bench.images) {
        counts.images += 1;
        counts.soft_images += image.has_relations as usize;
        counts.points += points;
        counts.triplets += named.scores.triplets;
        counts.soft_triplets += named.scores.soft_triplets;
        images.push(named);
    }
    let mean_of = |f: fn(&ImageScores) -> Option<f64>| {
        let values: Vec<f64> = images.iter().filter_map(|i| f(&i.scores)).collect();
        (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
    };
    Ok(PointReport {
        model: model.name().to_string(),
        all_by_material: mean_of(|s| s.all_by_material),
        all_by_point: mean_of(|s| s.all_by_point),
        soft_by_material: mean_of(|s| s.soft_by_material),
        soft_by_point: mean_of(|s| s.soft_by_point),
        top1_by_material: mean_of(|s| s.top1_by_material),
        top1_by_point: mean_of(|s| s.top1_by_point),
        counts,
        images,
    })
}

/// How a mask benchmark is scored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaskEvalOptions {
    /// Longer side of the evaluated images (0: as they are).
    pub max_side: u32,
    /// Query point draws.
    pub queries: QueryOptions,
    /// Radius of a query point's disc, in evaluated pixels.
    pub radius: f32,
    /// `Some(steps)`: best IoU over a grid of thresholds (parity mode)
    /// instead of the exact best.
    pub grid_steps: Option<usize>,
}

/// Scores of one model on a mask benchmark.
#[derive(Clone, Debug, Serialize)]
pub struct MaskReport {
    /// The model.
    pub model: String,
    /// Mean IoU at the best threshold over all queries.
    pub mean_iou: Option<f64>,
    /// Images evaluated.
    pub images: usize,
    /// Masks queried.
    pub masks: usize,
    /// Masks skipped (eroded area too small).
    pub skipped_masks: usize,
    /// Queries scored.
    pub queries: usize,
    /// Every image's mean IoU.
    pub per_image: Vec<NamedIou>,
}

/// A mask benchmark scored by several models: what `matseg eval masks
/// --json` prints and `matseg.evaluate.masks` returns.
#[derive(Serialize)]
pub struct MaskEvaluation<'a> {
    /// The benchmark folder.
    pub data: &'a Path,
    /// The longer side the photos were scored at.
    pub max_side: u32,
    /// How the best threshold was found: `exact` or `grid of N steps`.
    pub threshold: String,
    /// Each model's scores, in the order given.
    pub models: &'a [MaskReport],
}

impl<'a> MaskEvaluation<'a> {
    /// The evaluation of `models` on `data` scored with `options`.
    pub fn new(data: &'a Path, options: &MaskEvalOptions, models: &'a [MaskReport]) -> Self {
        Self {
            data,
            max_side: options.max_side,
            threshold: options
                .grid_steps
                .map_or("exact".to_string(), |s| format!("grid of {s} steps")),
            models,
        }
    }
}

/// One image's mean IoU over its queries (`None` when none of its masks
/// was queried).
#[derive(Clone, Debug, Serialize)]
pub struct NamedIou {
    /// The image.
    pub name: String,
    /// Its mean IoU.
    pub mean_iou: Option<f64>,
}

pub(crate) fn load_mask(path: &Path, w: u32, h: u32) -> Result<GrayImage, BenchError> {
    let bytes = std::fs::read(path).map_err(|e| BenchError {
        path: path.to_path_buf(),
        line: None,
        message: format!("cannot read: {e}"),
    })?;
    let mut mask = decode_grey(&bytes, path)?;
    // A mask of 0 and 1 (a label PNG) is read as 0 and 255.
    if mask.iter().all(|&v| v <= 1) {
        mask.iter_mut().for_each(|v| *v *= 255);
    }
    if mask.dimensions() == (w, h) {
        Ok(mask)
    } else {
        Err(BenchError {
            path: path.to_path_buf(),
            line: None,
            message: format!("mask is {:?}, the photo {}x{}", mask.dimensions(), w, h),
        })
    }
}

/// An error naming `photo` when `progress` was cancelled before it.
pub(crate) fn check_cancelled(progress: &dyn Progress, photo: &Path) -> Result<(), BenchError> {
    match progress.cancelled() {
        true => Err(BenchError::new(
            photo,
            None,
            "not scored: the evaluation was cancelled",
        )),
        false => Ok(()),
    }
}

/// The values at the pixels inside `roi` (all of them without one).
fn in_roi<T: Copy>(values: &[T], roi: Option<&[bool]>) -> Vec<T> {
    match roi {
        Some(roi) => values
            .iter()
            .zip(roi)
            .filter(|(_, &inside)| inside)
            .map(|(&v, _)| v)
            .collect(),
        None => values.to_vec(),
    }
}

/// A mask benchmark photo ready to be asked about: the photo at the scored
/// size, its region of interest, each queried mask (restricted to the
/// region: outside it nothing is predicted and nothing is true) with the
/// range of its query points in `asked`, and the masks too small to query.
pub struct MaskQueries {
    /// The photo at the scored size.
    pub pixels: RgbImage,
    /// Its region of interest, when it has one.
    pub roi: Option<Vec<bool>>,
    /// Each queried mask inside the region, and its points in `asked`.
    pub queried: Vec<(Vec<bool>, std::ops::Range<usize>)>,
    /// Every query point `(x, y)` of the photo, mask after mask.
    pub asked: Vec<(f32, f32)>,
    /// Masks left out (eroded area too small).
    pub skipped: usize,
}

/// The queries of photo `index` of a mask benchmark scored at longer side
/// `max_side`: its masks read and its query points drawn as `queries`
/// says, before any model is asked (a model answering
/// with similarity maps answers for these points).
pub fn mask_queries(
    image: &MaskImage,
    index: usize,
    max_side: u32,
    queries: &QueryOptions,
) -> Result<MaskQueries, BenchError> {
    let photo = read_rgb(&image.image_path)?;
    let (w0, h0) = photo.dimensions();
    let (pixels, _) = resize_longer_side(photo, max_side);
    let (w, h) = pixels.dimensions();
    let inside = |path: &Path| -> Result<Vec<bool>, BenchError> {
        let mask = load_mask(path, w0, h0)?;
        let mask = image::imageops::resize(&mask, w, h, image::imageops::FilterType::Nearest);
        Ok(mask.as_raw().iter().map(|&v| v >= 128).collect())
    };
    let roi = image.roi_path.as_deref().map(inside).transpose()?;
    let (mut queried, mut asked, mut skipped) = (Vec::new(), Vec::new(), 0);
    for (k, path) in image.mask_paths.iter().enumerate() {
        let truth = inside(path)?;
        let points = draw_mask_points(&truth, w as usize, h as usize, queries, index, k);
        if points.is_empty() {
            skipped += 1;
            continue;
        }
        let range = asked.len()..asked.len() + points.len();
        asked.extend(points.iter().map(|&(x, y)| (x as f32, y as f32)));
        queried.push((in_roi(&truth, roi.as_deref()), range));
    }
    Ok(MaskQueries {
        pixels,
        roi,
        queried,
        asked,
        skipped,
    })
}

/// Scores `model` on the photos and masks of a mask benchmark. Each photo
/// scored is a step of `progress`, and a cancelled `progress` stops the
/// scoring as [`evaluate_points`] does.
pub fn evaluate_masks(
    model: &dyn ScoredModel,
    images: &[MaskImage],
    options: &MaskEvalOptions,
    progress: &dyn Progress,
) -> Result<MaskReport, BenchError> {
    let mut report = MaskReport {
        model: model.name().to_string(),
        mean_iou: None,
        images: 0,
        masks: 0,
        skipped_masks: 0,
        queries: 0,
        per_image: Vec::new(),
    };
    let mut total = 0.0;
    for (index, image) in images.iter().enumerate() {
        check_cancelled(progress, &image.image_path)?;
        let MaskQueries {
            pixels,
            roi,
            queried,
            asked,
            skipped,
        } = mask_queries(image, index, options.max_side, &options.queries)?;
        report.skipped_masks += skipped;
        report.masks += queried.len();
        let (mut sum, mut count) = (0.0, 0usize);
        // A photo with no queried mask is not asked about.
        if !queried.is_empty() {
            let answer = model
                .answer(&Question {
                    name: &image.name,
                    path: &image.image_path,
                    pixels: &pixels,
                    points: &asked,
                })?
                .at_photo_size();
            for (truth, range) in queried {
                for i in range {
                    let map = answer.map_of(i, asked[i], options.radius);
                    let scores = in_roi(&map, roi.as_deref());
                    let best = match options.grid_steps {
                        Some(steps) => best_iou_on_grid(&scores, &truth, steps),
                        None => best_iou(&scores, &truth),
                    };
                    if let Some(best) = best {
                        sum += best.iou;
                        count += 1;
                    }
                }
            }
        }
        progress.advance();
        report.images += 1;
        report.queries += count;
        total += sum;
        report.per_image.push(NamedIou {
            name: image.name.clone(),
            mean_iou: (count > 0).then(|| sum / count as f64),
        });
    }
    report.mean_iou = (report.queries > 0).then(|| total / report.queries as f64);
    Ok(report)
}
