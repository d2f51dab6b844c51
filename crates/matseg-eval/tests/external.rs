//! Models matseg did not train, scored from map files: the rgb baseline
//! written as files scores what the built-in one scores, similarity maps
//! score as the descriptors they come from, and bad files are refused
//! naming them.

use image::{GrayImage, Luma, Rgb, RgbImage};
use matseg_eval::baselines::ColourBaseline;
use matseg_eval::external::MapFolder;
use matseg_eval::synthetic::{annotate_points, write_point_image, SyntheticOptions};
use matseg_eval::{
    evaluate_masks, evaluate_points, load_point_benchmark, scan_mask_benchmark, Described,
    MaskEvalOptions, QueryOptions, ScoredModel,
};
use matseg_image::progress::Silent;
use matseg_image::Plane;
use matseg_query::descriptor::{Comparison, DescriptorModel};
use matseg_weights::write_npy_f32;
use rand::{Rng, SeedableRng};
use std::path::Path;

const W: usize = 64;
const H: usize = 40;

/// Photo `seed`: a reddish material left, a bluish one right, mixed in a
/// band between (so points have relations), with per-pixel noise; and the
/// two materials' weights.
fn scene(seed: u64) -> (RgbImage, Vec<Plane>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let left: Vec<f32> = (0..W * H)
        .map(|i| (((40 - (i % W) as i32) as f32) / 16.0).clamp(0.0, 1.0))
        .collect();
    let photo = RgbImage::from_fn(W as u32, H as u32, |x, y| {
        let a = left[y as usize * W + x as usize];
        let mut noise = || rng.random_range(-20.0f32..20.0);
        let mix = |p: f32, q: f32, n: f32| (a * p + (1.0 - a) * q + n).clamp(0.0, 255.0) as u8;
        Rgb([
            mix(200.0, 40.0, noise()),
            mix(60.0, 90.0, noise()),
            mix(50.0, 210.0, noise()),
        ])
    });
    let right = left.iter().map(|a| 1.0 - a).collect();
    let plane = |data| Plane {
        width: W,
        height: H,
        data,
    };
    (photo, vec![plane(left), plane(right)])
}

/// A point benchmark and a mask benchmark of the same three photos, and a
/// map folder of the rgb baseline's descriptors as files: R, G, B / 255 at
/// the photo's size, compared by Euclidean distance.
fn benchmarks(root: &Path) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    std::fs::create_dir_all(root.join("masks")).unwrap();
    std::fs::create_dir_all(root.join("rgb-files")).unwrap();
    for seed in 0..3 {
        let name = format!("scene{seed}");
        let (photo, weights) = scene(seed);
        let annotation = annotate_points(&mut rng, &weights, &SyntheticOptions::default());
        write_point_image(&root.join("points"), &name, &photo, &annotation).unwrap();
        // The photo as the benchmark holds it (a JPEG), for both benchmarks.
        let jpeg = root
            .join("points")
            .join("images")
            .join(format!("{name}.jpg"));
        let photo = matseg_image::io::read_rgb(&jpeg).unwrap();
        photo
            .save(root.join("masks").join(format!("{name}.png")))
            .unwrap();
        for (k, plane) in weights.iter().enumerate() {
            let mask = GrayImage::from_fn(W as u32, H as u32, |x, y| {
                Luma([if plane.data[y as usize * W + x as usize] > 0.5 {
                    255
                } else {
                    0
                }])
            });
            mask.save(root.join("masks").join(format!("{name}.mask{k}.png")))
                .unwrap();
        }
        let values: Vec<f32> = photo.as_raw().iter().map(|&v| v as f32 / 255.0).collect();
        std::fs::write(
            root.join("rgb-files").join(format!("{name}.npy")),
            write_npy_f32(&values, &[H, W, 3]),
        )
        .unwrap();
    }
    std::fs::write(
        root.join("rgb-files").join("maps.json"),
        r#"{"name": "rgb as files", "comparison": "euclidean"}"#,
    )
    .unwrap();
}

fn mask_options() -> MaskEvalOptions {
    MaskEvalOptions {
        max_side: 0,
        queries: QueryOptions {
            points_per_mask: 4,
            erosion: 3,
            min_area: 50,
            seed: 1,
        },
        radius: 2.0,
        grid_steps: None,
    }
}

#[test]
fn the_rgb_baseline_as_files_scores_what_the_built_in_one_scores() {
    let dir = tempfile::tempdir().unwrap();
    benchmarks(dir.path());
    let files = MapFolder::open(&dir.path().join("rgb-files")).unwrap();
    assert_eq!(files.name(), "rgb as files");
    let builtin = Described(&ColourBaseline::RGB);

    let bench = load_point_benchmark(&dir.path().join("points"), false).unwrap();
    let ours = evaluate_points(&builtin, &bench, 0, &Silent).unwrap();
    let theirs = evaluate_points(&files, &bench, 0, &Silent).unwrap();
    assert_eq!(theirs.model, "rgb as files");
    assert!(ours.counts.triplets > 100 && ours.counts.soft_triplets > 0);
    assert_eq!(ours.counts.triplets, theirs.counts.triplets);
    for (a, b) in ours.images.iter().zip(&theirs.images) {
        for (x, y) in [
            (a.scores.all_by_point, b.scores.all_by_point),
            (a.scores.all_by_material, b.scores.all_by_material),
            (a.scores.soft_by_point, b.scores.soft_by_point),
            (a.scores.top1_by_material, b.scores.top1_by_material),
        ] {
            assert!(
                (x.unwrap() - y.unwrap()).abs() < 1e-6,
                "{}: {x:?} {y:?}",
                a.name
            );
        }
    }
    // Not a benchmark every model aces.
    assert!(ours.all_by_point.unwrap() < 1.0);

    let images = scan_mask_benchmark(&dir.path().join("masks")).unwrap();
    let ours = evaluate_masks(&builtin, &images, &mask_options(), &Silent).unwrap();
    let theirs = evaluate_masks(&files, &images, &mask_options(), &Silent).unwrap();
    assert_eq!((ours.queries, theirs.queries), (24, 24));
    assert!((ours.mean_iou.unwrap() - theirs.mean_iou.unwrap()).abs() < 1e-6);
    assert!(ours.mean_iou.unwrap() < 1.0);
}

#[test]
fn similarity_maps_and_coarse_descriptors_are_scored_at_the_photo_size() {
    let dir = tempfile::tempdir().unwrap();
    benchmarks(dir.path());
    let images = scan_mask_benchmark(&dir.path().join("masks")).unwrap();
    // The points each photo is asked about, from the template the tools
    // answer; each point's map: minus the rgb distance to its disc's mean.
    let options = mask_options();
    let template = matseg_eval::template::write_mask_template(
        &dir.path().join("template"),
        &images,
        options.max_side,
        &options.queries,
    )
    .unwrap();
    let sims = dir.path().join("similarity");
    std::fs::create_dir_all(&sims).unwrap();
    for image in &template.images {
        let photo = image::open(dir.path().join("masks").join(format!("{}.png", image.name)))
            .unwrap()
            .to_rgb8();
        let map = ColourBaseline::RGB.describe(&photo);
        let mut values = Vec::new();
        for &(x, y) in &image.points {
            let query = map.point_descriptor(x, y, options.radius, Comparison::NegativeEuclidean);
            values.extend(map.similarity_map(&query, Comparison::NegativeEuclidean));
        }
        std::fs::write(
            sims.join(format!("{}.npy", image.name)),
            write_npy_f32(&values, &[image.points.len(), H, W]),
        )
        .unwrap();
    }
    std::fs::write(sims.join("maps.json"), r#"{"kind": "similarity"}"#).unwrap();
    let builtin = evaluate_masks(&Described(&ColourBaseline::RGB), &images, &options, &Silent);
    let files = evaluate_masks(&MapFolder::open(&sims).unwrap(), &images, &options, &Silent);
    assert_eq!(files.as_ref().unwrap().model, "similarity");
    assert_eq!(builtin.unwrap().mean_iou, files.unwrap().mean_iou);

    // Descriptors on a grid a quarter of the photo's size, resized up:
    // the two materials are still told apart.
    let coarse = dir.path().join("coarse");
    std::fs::create_dir_all(&coarse).unwrap();
    for image in &template.images {
        let values: Vec<f32> = (0..(H / 4) * (W / 4))
            .flat_map(|i| {
                if i % (W / 4) < 8 {
                    [1.0, 0.0]
                } else {
                    [0.0, 1.0]
                }
            })
            .collect();
        std::fs::write(
            coarse.join(format!("{}.npy", image.name)),
            write_npy_f32(&values, &[H / 4, W / 4, 2]),
        )
        .unwrap();
    }
    let report = evaluate_masks(
        &MapFolder::open(&coarse).unwrap(),
        &images,
        &options,
        &Silent,
    )
    .unwrap();
    assert!(report.mean_iou.unwrap() > 0.9, "{:?}", report.mean_iou);
}

#[test]
fn missing_and_malformed_map_files_are_errors_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    benchmarks(dir.path());
    let images = scan_mask_benchmark(&dir.path().join("masks")).unwrap();
    let maps = dir.path().join("rgb-files");
    let run = || {
        let folder = MapFolder::open(&maps)?;
        evaluate_masks(&folder, &images, &mask_options(), &Silent)
    };
    std::fs::remove_file(maps.join("scene1.npy")).unwrap();
    let missing = run().unwrap_err().to_string();
    assert!(
        missing.contains(
            "scene1.npy: missing: the maps of photo scene1 are scene1.npy or scene1.safetensors"
        ),
        "{missing}"
    );
    for (bytes, says) in [
        (
            write_npy_f32(&[0.5; W * H], &[H, W]),
            "shape [40, 64] for photo scene1 (64x40): expected (h, w, d) descriptors",
        ),
        (
            write_npy_f32(&[f32::NAN; 12], &[2, 2, 3]),
            "value NaN at index 0 for photo scene1",
        ),
        (b"not numpy".to_vec(), "not a .npy file"),
    ] {
        std::fs::write(maps.join("scene1.npy"), bytes).unwrap();
        let message = run().unwrap_err().to_string();
        assert!(
            message.contains("scene1.npy: ") && message.contains(says),
            "{message}"
        );
    }
    std::fs::write(maps.join("maps.json"), r#"{"comparison": "manhattan"}"#).unwrap();
    let message = run().unwrap_err().to_string();
    assert!(
        message.contains("maps.json: comparison \"manhattan\""),
        "{message}"
    );
    std::fs::write(maps.join("maps.json"), r#"{"kind": "similarity"}"#).unwrap();
    std::fs::write(
        maps.join("scene0.npy"),
        write_npy_f32(&[0.5; W * H * 3], &[H, W, 3]),
    )
    .unwrap();
    let message = run().unwrap_err().to_string();
    assert!(
        message
            .contains("scene0.npy: shape [40, 64, 3] for photo scene0 (64x40): expected (8, h, w)"),
        "{message}"
    );
}
