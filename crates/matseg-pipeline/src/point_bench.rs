//! Point benchmarks (docs/eval.md): one made from generated 2D scenes, so
//! the evaluation runs end to end without external data, any benchmark
//! scored by several models, and any benchmark's annotations drawn on its
//! photos to check them by eye.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use crate::sources::Libraries;
use matseg_data::{sample_rng, Dataset};
use matseg_eval::overlay::draw_points;
use matseg_eval::synthetic::{annotate_points, write_point_image, SyntheticOptions};
use matseg_eval::{evaluate_points, load_point_benchmark, PointReport, ScoredModel};
use matseg_image::io::{encode_jpeg, encode_png_grey, encode_png_rgb, read_rgb};
use matseg_image::progress::Progress;
use matseg_scene::{generate_2d, Recipe2d, Scene2d};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// A point benchmark scored by several models: what `matseg eval points
/// --json` prints and the web app's evaluate page shows.
#[derive(Clone, Debug, Serialize)]
pub struct PointEvaluation {
    /// The benchmark folder.
    pub benchmark: PathBuf,
    /// The longer side the images were evaluated at.
    pub max_side: u32,
    /// Images left out, with why (with `skip_bad`).
    pub skipped: Vec<String>,
    /// Each model's scores, in the order given.
    pub models: Vec<PointReport>,
}

/// Scores each of `models` on the point benchmark in `dir`, its images
/// resized to a longer side of `max_side`; with `skip_bad`, malformed
/// images are left out (and listed) instead of failing. `progress` counts
/// the images scored, of every model, and is told which model is scored;
/// cancelled, it stops the scoring.
pub fn score_point_benchmark(
    dir: &Path,
    models: &[Box<dyn ScoredModel + '_>],
    skip_bad: bool,
    max_side: u32,
    progress: &dyn Progress,
) -> Result<PointEvaluation, PipelineError> {
    let bench = load_point_benchmark(dir, skip_bad)?;
    progress.start((models.len() * bench.images.len()) as u64, "images");
    let reports = models
        .iter()
        .enumerate()
        .map(|(i, m)| {
            progress.status(&format!("{} ({} of {})", m.name(), i + 1, models.len()));
            evaluate_points(m.as_ref(), &bench, max_side, progress)
        })
        .collect::<Result<Vec<_>, _>>()?;
    progress.finish();
    Ok(PointEvaluation {
        benchmark: dir.to_path_buf(),
        max_side,
        skipped: bench.skipped,
        models: reports,
    })
}

/// Writes a point benchmark (MatSeg layout) of `scenes` generated 2D scenes
/// (scene i from (seed, i)) with `points` points per material into `out`;
/// scenes with fewer than two pointed materials are left out. Returns the
/// scenes written and left out.
pub fn make_point_benchmark(
    out: &Path,
    scenes: u64,
    seed: u64,
    points: usize,
    libraries: &Libraries,
) -> Result<(u64, u64), PipelineError> {
    if points < 1 {
        return Err(PipelineError::Settings(
            "--points must be at least 1".into(),
        ));
    }
    let options = SyntheticOptions {
        points_per_material: points,
        ..SyntheticOptions::default()
    };
    let (mut written, mut left_out) = (0u64, 0u64);
    for_each_scene(scenes, seed, libraries, |name, rng, scene| {
        let weights: Vec<_> = scene.weights.iter().map(|w| w.to_plane()).collect();
        let annotation = annotate_points(rng, &weights, &options);
        if annotation.groups.len() < 2 {
            left_out += 1;
            return Ok(());
        }
        write_point_image(out, name, &scene.image, &annotation)
            .map_err(|e| PipelineError::file(out.display(), format!("cannot write {name}: {e}")))?;
        written += 1;
        Ok(())
    })?;
    Ok((written, left_out))
}

/// Generates `scenes` 2D scenes with the default recipe, scene i from
/// (seed, i), and hands each to `each` with its name (`sceneNNNNN`) and
/// the generator it was drawn with; one scene at least.
fn for_each_scene(
    scenes: u64,
    seed: u64,
    libraries: &Libraries,
    mut each: impl FnMut(&str, &mut ChaCha8Rng, Scene2d) -> Result<(), PipelineError>,
) -> Result<(), PipelineError> {
    if scenes < 1 {
        return Err(PipelineError::setting(
            "scenes",
            Some(scenes),
            "a benchmark needs one scene at least",
        ));
    }
    let recipe = Recipe2d::default();
    for i in 0..scenes {
        let mut rng = sample_rng(seed, i);
        let scene = generate_2d(&mut rng, &recipe, libraries.sources())?;
        each(&format!("scene{i:05}"), &mut rng, scene)?;
    }
    Ok(())
}

/// Writes a mask benchmark (the layout `matseg eval masks` and `eval
/// clicks` read: `sceneNNNNN.jpg` and a `sceneNNNNN.maskK.png` per
/// material, its weight as 8-bit grey, 128 and above inside) of `scenes`
/// generated 2D scenes (scene i from (seed, i)) into `out`. Returns the
/// scenes written.
pub fn make_mask_benchmark(
    out: &Path,
    scenes: u64,
    seed: u64,
    libraries: &Libraries,
) -> Result<u64, PipelineError> {
    create_folder(out)?;
    for_each_scene(scenes, seed, libraries, |name, _, scene| {
        let (w, h) = scene.image.dimensions();
        for (k, weight) in scene.weights.iter().enumerate() {
            let levels = weight.to_plane().to_u8();
            write_file(
                &out.join(format!("{name}.mask{k}.png")),
                &encode_png_grey(w, h, &levels),
            )?;
        }
        // The photo last: a photo with its masks is a complete image.
        write_file(
            &out.join(format!("{name}.jpg")),
            &encode_jpeg(&scene.image, 95),
        )
    })?;
    Ok(scenes)
}

/// Writes the samples of the generated dataset `data` (MatSeg folders or
/// WebDataset shards, e.g. the frames of a 3D sequence) into `out` as a
/// mask benchmark: `KEY.png` (the image, losslessly), `KEY.maskK.png`
/// (each material's weight as 8-bit grey, as training reads it: its
/// share of the masks' sum) and `KEY.roi.png` (white where a material is:
/// the background is not scored). Every sample is read before anything is
/// written, so a damaged one leaves nothing. Returns the samples written.
pub fn mask_benchmark_from_dataset(data: &Path, out: &Path) -> Result<usize, PipelineError> {
    let dataset = Dataset::open(data)?;
    for sample in dataset.iter() {
        sample?;
    }
    create_folder(out)?;
    for sample in dataset.iter() {
        let sample = sample?;
        let (w, h) = sample.image.dimensions();
        let targets = sample.targets();
        let name = &sample.key;
        for (k, weight) in targets.weights.iter().enumerate() {
            write_file(
                &out.join(format!("{name}.mask{k}.png")),
                &encode_png_grey(w, h, &weight.to_u8()),
            )?;
        }
        write_file(
            &out.join(format!("{name}.roi.png")),
            &encode_png_grey(w, h, &targets.roi.to_u8()),
        )?;
        // The image last: an image with its masks is a complete one.
        write_file(
            &out.join(format!("{name}.png")),
            &encode_png_rgb(&sample.image),
        )?;
    }
    Ok(dataset.len())
}

/// Draws each image's points of the benchmark `bench` on it into
/// `out/NAME.png` (rings in one colour per material, labelled with its id;
/// photos whose longer side is below `magnify_below` pixels magnified
/// twofold). Returns the overlays and points drawn.
pub fn draw_point_benchmark(
    bench: &Path,
    out: &Path,
    magnify_below: u32,
) -> Result<(usize, usize), PipelineError> {
    let bench = load_point_benchmark(bench, false)?;
    // Every photo is decoded once before anything is written (and again
    // to be drawn, one at a time), so an unreadable one leaves nothing.
    for image in &bench.images {
        read_rgb(&image.image_path)?;
    }
    create_folder(out)?;
    let mut points = 0;
    for image in &bench.images {
        let photo = read_rgb(&image.image_path)?;
        let scale = if photo.width().max(photo.height()) < magnify_below {
            2
        } else {
            1
        };
        let path = out.join(format!("{}.png", image.name));
        write_file(&path, &encode_png_rgb(&draw_points(&photo, image, scale)))?;
        points += image.points.iter().map(Vec::len).sum::<usize>();
    }
    Ok((bench.images.len(), points))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sources::Defaults;
    use matseg_image::LicenceFilter;

    #[test]
    fn a_generated_benchmark_reads_back_and_draws() {
        let dir = tempfile::tempdir().unwrap();
        let libraries =
            Libraries::load(&[], &[], 256, Defaults::Bundled, &LicenceFilter::default()).unwrap();
        let bench = dir.path().join("bench");
        let (written, left_out) = make_point_benchmark(&bench, 4, 1, 3, &libraries).unwrap();
        assert_eq!(written + left_out, 4);
        assert!(written >= 1, "most scenes have two materials or more");
        let read = load_point_benchmark(&bench, false).unwrap();
        assert_eq!(read.images.len() as u64, written);
        assert!(read.images[0].points.iter().all(|p| p.len() == 3));
        let drawn = dir.path().join("drawn");
        let (overlays, points) = draw_point_benchmark(&bench, &drawn, 450).unwrap();
        assert_eq!(overlays as u64, written);
        let want: usize = read
            .images
            .iter()
            .map(|i| i.points.iter().map(Vec::len).sum::<usize>())
            .sum();
        assert_eq!(points, want);
        assert!(drawn.join(format!("{}.png", read.images[0].name)).is_file());
        assert!(make_point_benchmark(&bench, 1, 1, 0, &libraries).is_err());
    }

    #[test]
    fn a_dataset_becomes_a_mask_benchmark_with_its_roi() {
        use matseg_data::folders::{FINISHED_FILE, IMAGE_FILE, ROI_FILE};
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (8u32, 6u32);
        // Material 0 on the left half, material 1 on the top right, the
        // bottom right background.
        let level = |k: usize, x: u32, y: u32| -> u8 {
            let inside = match k {
                0 => x < w / 2,
                _ => x >= w / 2 && y < h / 2,
            };
            if inside {
                255
            } else {
                0
            }
        };
        let sample = dir.path().join("data").join("00000000");
        create_folder(&sample).unwrap();
        let image = image::RgbImage::from_fn(w, h, |x, _| image::Rgb([30 * x as u8, 90, 200]));
        let file = |name: &str, bytes: &[u8]| std::fs::write(sample.join(name), bytes).unwrap();
        file(IMAGE_FILE, &encode_jpeg(&image, 95));
        for k in 0..2 {
            let levels: Vec<u8> = (0..w * h).map(|i| level(k, i % w, i / w)).collect();
            file(&format!("mask{k}.png"), &encode_png_grey(w, h, &levels));
        }
        let roi: Vec<u8> = (0..w * h)
            .map(|i| level(0, i % w, i / w).max(level(1, i % w, i / w)))
            .collect();
        file(ROI_FILE, &encode_png_grey(w, h, &roi));
        file(FINISHED_FILE, b"");

        let bench = dir.path().join("bench");
        assert_eq!(
            mask_benchmark_from_dataset(&dir.path().join("data"), &bench).unwrap(),
            1
        );
        let images = matseg_eval::scan_mask_benchmark(&bench).unwrap();
        assert_eq!(images.len(), 1);
        assert_eq!(images[0].mask_paths.len(), 2);
        let grey = |path: &Path| image::open(path).unwrap().to_luma8().into_raw();
        for (k, path) in images[0].mask_paths.iter().enumerate() {
            let want: Vec<u8> = (0..w * h).map(|i| level(k, i % w, i / w)).collect();
            assert_eq!(grey(path), want, "mask {k}");
        }
        assert_eq!(grey(images[0].roi_path.as_ref().unwrap()), roi);

        // A damaged mask: refused, and nothing written.
        file("mask1.png", b"not a png");
        let refused = dir.path().join("refused");
        assert!(mask_benchmark_from_dataset(&dir.path().join("data"), &refused).is_err());
        assert!(!refused.exists());
    }
}
