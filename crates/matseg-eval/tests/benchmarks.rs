//! Benchmarks on disk: the point-benchmark reader and its errors, and whole
//! evaluations whose scores are known (flat colours, which the colour
//! baselines separate perfectly).

use image::RgbImage;
use matseg_eval::baselines::ColourBaseline;
use matseg_eval::points::BenchPoint;
use matseg_eval::synthetic::{annotate_points, write_point_image, SyntheticOptions};
use matseg_eval::{
    evaluate_masks, evaluate_points, load_point_benchmark, scan_mask_benchmark, Annotation,
    Described, MaskEvalOptions, QueryOptions,
};
use matseg_image::progress::Silent;
use matseg_image::Plane;
use rand::SeedableRng;
use std::path::Path;

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

/// A 20x10 image and its data folder.
fn add_image(dir: &Path, name: &str, json: &str, relations: Option<&str>) {
    std::fs::create_dir_all(dir.join("images")).unwrap();
    RgbImage::new(20, 10)
        .save(dir.join("images").join(format!("{name}.png")))
        .unwrap();
    write(&dir.join("data").join(name).join("data.json"), json);
    if let Some(r) = relations {
        write(&dir.join("data").join(name).join("group_relations.txt"), r);
    }
}

const TWO: &str = r#"{"1": {"pt_im": [[1, 1, 1], [2, 2, 1]]}, "2": {"pt_im": [[10, 5, 2]]}, "3": {"pt_im": [[15, 5, 2]]}}"#;

#[test]
fn the_reader_builds_weights_from_ids_and_relations() {
    let dir = tempfile::tempdir().unwrap();
    add_image(dir.path(), "a", TWO, Some("[1, 2]\n\n(2, 3)\n"));
    add_image(dir.path(), "b", TWO, None);
    let bench = load_point_benchmark(dir.path(), false).unwrap();
    assert_eq!(bench.images.len(), 2);
    let a = &bench.images[0];
    assert_eq!(a.name, "a");
    assert_eq!(a.material_ids, ["1", "2", "3"]);
    assert_eq!(
        a.points[0][1],
        BenchPoint {
            x: 2.0,
            y: 2.0,
            r: 1.0
        }
    );
    assert_eq!(a.weights[0], [1.0, 0.6, 0.0]);
    assert_eq!(a.weights[1], [0.6, 1.0, 0.3]);
    assert!(a.has_relations && !bench.images[1].has_relations);
}

#[test]
fn malformed_benchmarks_name_the_file_and_line() {
    let cases = [
        ("[1, 2]\n1, 3\n", "group_relations.txt:2", "[...] or (...)"),
        (
            "(1, 9)\n",
            "group_relations.txt",
            "relation [\"1\", \"9\"]: group 9 unknown or repeated",
        ),
    ];
    for (relations, location, problem) in cases {
        let dir = tempfile::tempdir().unwrap();
        add_image(dir.path(), "a", TWO, Some(relations));
        let err = load_point_benchmark(dir.path(), false)
            .unwrap_err()
            .to_string();
        assert!(err.contains(location) && err.contains(problem), "{err}");
        assert_eq!(err.lines().count(), 1);
    }
    let dir = tempfile::tempdir().unwrap();
    add_image(dir.path(), "a", r#"{"1": {"pt_im": [[25, 1, 1]]}}"#, None);
    let err = load_point_benchmark(dir.path(), false)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("data.json") && err.contains("outside the 20x10 image"),
        "{err}"
    );

    // A data folder without its image; with --skip-bad it is skipped and counted.
    write(&dir.path().join("data/b/data.json"), TWO);
    std::fs::write(dir.path().join("data/a/data.json"), TWO).unwrap();
    let err = load_point_benchmark(dir.path(), false)
        .unwrap_err()
        .to_string();
    assert!(err.contains("no image images/b.jpg"), "{err}");
    let bench = load_point_benchmark(dir.path(), true).unwrap();
    assert_eq!((bench.images.len(), bench.skipped.len()), (1, 1));
}

/// Three flat colour bands: materials 1 and 2 pure, and their even mix.
fn bands() -> (RgbImage, Vec<Plane>) {
    let (w, h) = (90, 40);
    let (c1, c2) = ([200.0f32, 30.0, 30.0], [20.0f32, 60.0, 220.0]);
    let weight = |x: u32| {
        if x < 30 {
            1.0
        } else if x < 60 {
            0.5
        } else {
            0.0
        }
    };
    let img = RgbImage::from_fn(w, h, |x, _| {
        let a = weight(x);
        image::Rgb([0, 1, 2].map(|c| (a * c1[c] + (1.0 - a) * c2[c]).round() as u8))
    });
    let plane = |f: &dyn Fn(u32) -> f32| {
        Plane::from_vec(
            w as usize,
            h as usize,
            (0..w * h).map(|i| f(i % w)).collect(),
        )
    };
    (
        img,
        vec![plane(&|x| weight(x)), plane(&|x| 1.0 - weight(x))],
    )
}

#[test]
fn flat_colours_score_one_with_the_rgb_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let (img, weights) = bands();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let annotation = annotate_points(&mut rng, &weights, &SyntheticOptions::default());
    let pairs: Vec<&[String]> = annotation.relations.iter().map(|r| &r.ids[..]).collect();
    assert_eq!(pairs, [["1", "3"], ["2", "3"]]);
    write_point_image(dir.path(), "bands", &img, &annotation).unwrap();
    let bench = load_point_benchmark(dir.path(), false).unwrap();
    let report = evaluate_points(
        &Described(&ColourBaseline::RGB),
        &bench,
        0,
        &matseg_image::progress::Silent,
    )
    .unwrap();
    assert_eq!(report.counts.points, 15);
    assert_eq!(report.all_by_point, Some(1.0));
    assert_eq!(report.soft_by_material, Some(1.0));
    assert_eq!(report.top1_by_point, Some(1.0));
}

#[test]
fn flat_colour_masks_are_found_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (img, weights) = bands();
    img.save(dir.path().join("bands.png")).unwrap();
    for (k, w) in weights.iter().enumerate() {
        let mask: Vec<u8> = w
            .data
            .iter()
            .map(|&v| if v == 1.0 { 255 } else { 0 })
            .collect();
        image::GrayImage::from_raw(90, 40, mask)
            .unwrap()
            .save(dir.path().join(format!("bands.mask{k}.png")))
            .unwrap();
    }
    let images = scan_mask_benchmark(dir.path()).unwrap();
    assert_eq!(images[0].mask_paths.len(), 2);
    let options = MaskEvalOptions {
        max_side: 0,
        queries: QueryOptions {
            points_per_mask: 4,
            erosion: 3,
            min_area: 50,
            seed: 1,
        },
        radius: 1.0,
        grid_steps: None,
    };
    let report =
        evaluate_masks(&Described(&ColourBaseline::RGB), &images, &options, &Silent).unwrap();
    assert_eq!((report.masks, report.queries), (2, 8));
    assert_eq!(report.mean_iou, Some(1.0));
    let grid = MaskEvalOptions {
        grid_steps: Some(100),
        ..options
    };
    assert!(
        evaluate_masks(&Described(&ColourBaseline::RGB), &images, &grid, &Silent)
            .unwrap()
            .mean_iou
            .unwrap()
            <= 1.0
    );
}

#[test]
fn written_and_hand_made_benchmarks_read_through_the_one_reader() {
    // Written by the synthetic benchmark writer: read back as written.
    let dir = tempfile::tempdir().unwrap();
    let (img, weights) = bands();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let annotation = annotate_points(&mut rng, &weights, &SyntheticOptions::default());
    write_point_image(dir.path(), "bands", &img, &annotation).unwrap();
    let folder = dir.path().join("data/bands");
    assert_eq!(Annotation::read(&folder).unwrap(), Some(annotation.clone()));
    let bench = load_point_benchmark(dir.path(), false).unwrap();
    assert_eq!(bench.images[0].material_ids, ["1", "2", "3"]);

    // Made by hand: the development benchmark shipped with the project.
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../benchmarks/real-dev");
    let bench = load_point_benchmark(&real, false).unwrap();
    assert!(bench.images.len() >= 40 && bench.skipped.is_empty());
    for image in &bench.images {
        let read = Annotation::read(&real.join("data").join(&image.name))
            .unwrap()
            .unwrap();
        let ids: Vec<&str> = read.groups.iter().map(|g| g.id.as_str()).collect();
        assert_eq!(ids, image.material_ids, "{}", image.name);
        assert_eq!(read.relations.is_empty(), !image.has_relations);
    }

    // A malformed annotation: the checker's message is the reader's.
    let mut outside = annotation.clone();
    outside.groups[1].points[0] = [90.0, 3.0, 2.0];
    let problem = outside.check(90, 40).unwrap_err().to_string();
    assert_eq!(
        problem,
        "group 2: point (90, 3, r 2) is outside the 90x40 image"
    );
    outside.write(&folder).unwrap();
    let error = load_point_benchmark(dir.path(), false)
        .unwrap_err()
        .to_string();
    assert_eq!(
        error,
        format!("{}: {problem}", folder.join("data.json").display())
    );
}
