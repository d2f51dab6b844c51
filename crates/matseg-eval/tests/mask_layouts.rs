//! The mask-benchmark layouts material-mask sets come in (`images/` and
//! `masks/NAME.png`, `masks/NAME_K.png` or `masks/NAME/K.png`) read as the
//! same benchmark as matseg's own layout, and anything else is an error
//! naming the file.

use matseg_eval::baselines::ColourBaseline;
use matseg_eval::{evaluate_masks, scan_mask_benchmark, Described, MaskEvalOptions, QueryOptions};
use matseg_image::progress::Silent;
use std::path::Path;

/// Real photos of the bundled mask benchmark, with their masks.
const PHOTOS: [(&str, usize); 2] = [("balance", 2), ("bamboo", 4)];

fn real_masks() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../benchmarks/real-masks")
}

/// The name of mask `k` of photo `name` in a layout.
type MaskName<'a> = &'a dyn Fn(&str, usize) -> String;

/// A malformed benchmark: its name, how it is made in a folder, and what
/// its error says.
type Case<'a> = (&'a str, &'a dyn Fn(&Path), &'a str);

/// Copies `from` to `to`, making its folder.
fn copy(from: &Path, to: &Path) {
    std::fs::create_dir_all(to.parent().unwrap()).unwrap();
    std::fs::copy(from, to).unwrap();
}

/// The photos in the two-folder layout, mask `k` named by `mask(name, k)`.
fn two_folders(dir: &Path, mask: MaskName) {
    for (name, masks) in PHOTOS {
        copy(
            &real_masks().join(format!("{name}.jpg")),
            &dir.join(format!("images/{name}.jpg")),
        );
        for k in 0..masks {
            copy(
                &real_masks().join(format!("{name}.mask{k}.png")),
                &dir.join("masks").join(mask(name, k)),
            );
        }
    }
}

/// Three query points a mask, on photos of longer side 300.
fn options() -> MaskEvalOptions {
    MaskEvalOptions {
        max_side: 300,
        queries: QueryOptions {
            points_per_mask: 3,
            erosion: 5,
            min_area: 100,
            seed: 0,
        },
        radius: 5.0,
        grid_steps: None,
    }
}

/// The masks the rgb baseline is scored on, and its mean IoU, on the
/// benchmark in `dir`.
fn mean_iou(dir: &Path) -> (usize, f64) {
    let images = scan_mask_benchmark(dir).unwrap();
    let report = evaluate_masks(
        &Described(&ColourBaseline::RGB),
        &images,
        &options(),
        &Silent,
    )
    .unwrap();
    (report.masks, report.mean_iou.unwrap())
}

#[test]
fn every_layout_reads_as_the_same_benchmark() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat");
    for (name, masks) in PHOTOS {
        for file in std::iter::once(format!("{name}.jpg"))
            .chain((0..masks).map(|k| format!("{name}.mask{k}.png")))
        {
            copy(&real_masks().join(&file), &flat.join(&file));
        }
    }
    let expected = mean_iou(&flat);
    assert_eq!(expected.0, 5, "the masks large enough at 300 px");
    let layouts: [(&str, MaskName); 3] = [
        ("underscore-from-0", &|name, k| format!("{name}_{k}.png")),
        ("underscore-from-1", &|name, k| {
            format!("{name}_{}.png", k + 1)
        }),
        ("folders", &|name, k| format!("{name}/{}.png", k + 1)),
    ];
    for (layout, mask) in layouts {
        let root = dir.path().join(layout);
        two_folders(&root, mask);
        let images = scan_mask_benchmark(&root).unwrap();
        let names: Vec<&str> = images.iter().map(|i| i.name.as_str()).collect();
        assert_eq!(names, ["balance", "bamboo"], "{layout}");
        assert_eq!(mean_iou(&root), expected, "{layout}");
    }

    // One mask a photo, as NAME.png; a mask of 0 and 1 reads as 0 and 255.
    let single = dir.path().join("single");
    copy(
        &real_masks().join("balance.jpg"),
        &single.join("images/balance.jpg"),
    );
    let mask = image::open(real_masks().join("balance.mask1.png"))
        .unwrap()
        .into_luma8();
    let labels = image::GrayImage::from_fn(mask.width(), mask.height(), |x, y| {
        image::Luma([u8::from(mask.get_pixel(x, y)[0] >= 128)])
    });
    std::fs::create_dir_all(single.join("masks")).unwrap();
    labels.save(single.join("masks/balance.png")).unwrap();
    let images = scan_mask_benchmark(&single).unwrap();
    assert_eq!(images[0].mask_paths, [single.join("masks/balance.png")]);
    let report = evaluate_masks(
        &Described(&ColourBaseline::RGB),
        &images,
        &options(),
        &Silent,
    )
    .unwrap();
    assert_eq!(report.masks, 1, "the 0/1 mask has its material");
}

#[test]
fn anything_else_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [Case; 7] = [
        (
            "gap",
            &|root| {
                two_folders(root, &|name, k| format!("{name}_{}.png", 2 * k));
            },
            "images/balance.jpg: the masks of balance are numbered 0, 2: number them from 0 or 1 without gaps",
        ),
        (
            "orphan",
            &|root| {
                two_folders(root, &|name, k| format!("{name}_{k}.png"));
                copy(
                    &real_masks().join("balance.mask0.png"),
                    &root.join("masks/bread_0.png"),
                );
            },
            "masks/bread_0.png: no photo of this mask in",
        ),
        (
            "no-mask",
            &|root| {
                two_folders(root, &|name, k| format!("{name}_{k}.png"));
                copy(
                    &real_masks().join("balance.jpg"),
                    &root.join("images/extra.jpg"),
                );
            },
            "images/extra.jpg: no mask: expected masks/extra.png, masks/extra_1.png, ... or masks/extra/1.png, ...",
        ),
        (
            "mixed",
            &|root| {
                two_folders(root, &|name, k| format!("{name}_{k}.png"));
                copy(
                    &real_masks().join("balance.mask0.png"),
                    &root.join("masks/balance.png"),
                );
            },
            "images/balance.jpg: masks in two layouts: masks/balance.png beside numbered masks",
        ),
        (
            "no-images",
            &|root| {
                std::fs::create_dir_all(root.join("masks")).unwrap();
            },
            "images: missing: a benchmark with masks/ keeps its photos in images/",
        ),
        (
            "not-png",
            &|root| {
                two_folders(root, &|name, k| format!("{name}_{k}.png"));
                copy(
                    &real_masks().join("balance.jpg"),
                    &root.join("masks/balance_2.jpg"),
                );
            },
            "masks/balance_2.jpg: not a PNG mask",
        ),
        (
            "folder-junk",
            &|root| {
                two_folders(root, &|name, k| format!("{name}/{k}.png"));
                std::fs::write(root.join("masks/bamboo/notes.txt"), "x").unwrap();
            },
            "masks/bamboo/notes.txt: not a numbered mask",
        ),
    ];
    for (case, make, says) in cases {
        let root = dir.path().join(case);
        make(&root);
        let error = scan_mask_benchmark(&root).unwrap_err().to_string();
        assert!(error.contains(says), "{case}: {error}");
        assert!(
            error.starts_with(&root.display().to_string()),
            "{case}: {error}"
        );
    }
}
