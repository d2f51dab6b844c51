//! Datasets on disk: determinism across threads and job splits, round trips,
//! resume, and interrupted runs.

use matseg_data::{
    encode_scene, generate_dataset, sample_rng, Dataset, Format, GenerateOptions, JobSlice,
};
use matseg_image::progress::Silent;
use matseg_image::PhotoLibrary;
use matseg_scene::{generate_2d, quantise_weights, Recipe2d, Sources};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn libraries() -> (PhotoLibrary, PhotoLibrary) {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    let scan = |sub: &str| PhotoLibrary::scan(&[assets.join(sub)], 1 << 30).unwrap().0;
    (scan("photos"), scan("textures"))
}

fn small_recipe() -> Recipe2d {
    let mut r = Recipe2d::default();
    r.scene.size_min = 48;
    r.scene.size_max = 112;
    r
}

fn options(out: &Path, n: u64, format: Format, job: JobSlice) -> GenerateOptions {
    GenerateOptions {
        out: out.to_path_buf(),
        n,
        seed: 42,
        format,
        shard_size: 3,
        job,
    }
}

fn run(opts: &GenerateOptions, threads: usize) -> matseg_data::GenerateReport {
    let (photos, textures) = libraries();
    let sources = Sources {
        photos: &photos,
        textures: &textures,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| generate_dataset(opts, &small_recipe(), sources, &Silent))
        .unwrap()
}

/// Every file under `root` (relative path -> bytes).
fn tree(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

#[test]
fn output_is_identical_for_any_thread_count_and_job_split() {
    for format in [Format::Folders, Format::Wds] {
        let a = tempfile::tempdir().unwrap();
        let b = tempfile::tempdir().unwrap();
        let c = tempfile::tempdir().unwrap();
        run(&options(a.path(), 8, format, JobSlice::ALL), 1);
        run(&options(b.path(), 8, format, JobSlice::ALL), 2);
        for index in 0..3 {
            let report = run(
                &options(c.path(), 8, format, JobSlice { count: 3, index }),
                2,
            );
            assert!(report.generated > 0);
        }
        let ta = tree(a.path());
        assert_eq!(ta.len(), tree(b.path()).len());
        assert!(ta == tree(b.path()), "{format:?}: 1 vs 2 threads differ");
        assert!(
            ta == tree(c.path()),
            "{format:?}: one job vs three jobs differ"
        );
        let expected_units = if format == Format::Wds { 3 } else { 8 };
        let units = ta
            .keys()
            .filter(|p| p.extension().is_some_and(|e| e == "tar") || p.ends_with("Finished.txt"));
        assert_eq!(units.count(), expected_units);
    }
}

#[test]
fn folders_and_shards_read_back_to_the_generated_scenes() {
    let (photos, textures) = libraries();
    let sources = Sources {
        photos: &photos,
        textures: &textures,
    };
    let recipe = small_recipe();
    for format in [Format::Folders, Format::Wds] {
        let dir = tempfile::tempdir().unwrap();
        let opts = options(dir.path(), 5, format, JobSlice::ALL);
        generate_dataset(&opts, &recipe, sources, &Silent).unwrap();
        let ds = Dataset::open(dir.path()).unwrap();
        assert_eq!(ds.len(), 5);
        for i in 0..5u64 {
            let sample = ds.get(i as usize).unwrap();
            let scene = generate_2d(&mut sample_rng(42, i), &recipe, sources).unwrap();
            let q = quantise_weights(&scene.weights, &scene.background);
            assert_eq!(sample.key, format!("{i:08}"));
            assert_eq!(ds.key(i as usize), sample.key, "the key without reading");
            assert_eq!(sample.image.dimensions(), scene.image.dimensions());
            assert_eq!(sample.masks.len(), q.masks.len());
            for (got, want) in sample.masks.iter().zip(&q.masks) {
                assert_eq!(got.as_raw(), want, "masks are stored losslessly");
            }
            assert_eq!(sample.roi.as_ref().unwrap().as_raw(), &q.roi);
            let mean_err = sample
                .image
                .as_raw()
                .iter()
                .zip(scene.image.as_raw())
                .map(|(a, b)| (*a as f64 - *b as f64).abs())
                .sum::<f64>()
                / scene.image.as_raw().len() as f64;
            assert!(mean_err < 4.0, "JPEG error {mean_err}");
            let meta = sample.meta.unwrap();
            assert_eq!(meta["index"], i);
            assert_eq!(meta["seed"], 42);
            let encoded = encode_scene(&scene, 42, i, sources);
            let want: serde_json::Value = serde_json::from_slice(&encoded.json).unwrap();
            assert_eq!(meta, want);
            assert!(!meta["licences"].as_array().unwrap().is_empty());

            // Training targets: weights sum to 1 inside the ROI.
            let t = ds.get(i as usize).unwrap().targets();
            for p in 0..t.roi.len() {
                let total: f32 = t.weights.iter().map(|w| w.data[p]).sum();
                if t.roi.data[p] == 1.0 {
                    assert!((total - 1.0).abs() < 1e-5);
                }
            }
        }
    }
}

#[test]
fn rerun_skips_complete_samples_and_redoes_interrupted_ones() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path(), 4, Format::Folders, JobSlice::ALL);
    assert_eq!(run(&opts, 2).generated, 4);
    let before = tree(dir.path());

    // Simulate an interruption: one sample lost its marker, one left a partial folder.
    std::fs::remove_file(dir.path().join("00000002/Finished.txt")).unwrap();
    // A crash just before the rename leaves a partial folder that looks
    // whole, with the marker matseg staged it with.
    let partial = dir.path().join("00000003.partial");
    std::fs::create_dir(&partial).unwrap();
    std::fs::write(partial.join(".matseg-output"), r#"{"command": "generate"}"#).unwrap();
    for name in [
        "RGB__RGB.jpg",
        "mask0.png",
        "ObjectMaskOcluded.png",
        "Finished.txt",
    ] {
        std::fs::copy(dir.path().join("00000003").join(name), partial.join(name)).unwrap();
    }
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(ds.len(), 3, "an unfinished sample is not read as complete");
    assert_eq!(ds.incomplete(), 2);

    // Someone else's folder of a staging name, without the marker.
    let foreign = dir.path().join("00000001.partial");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();

    let report = run(&opts, 2);
    assert_eq!((report.generated, report.skipped), (1, 3));
    assert!(!partial.exists(), "the rerun removes leftovers");
    assert_eq!(std::fs::read(foreign.join("notes.txt")).unwrap(), b"mine");
    std::fs::remove_dir_all(&foreign).unwrap();
    assert!(
        tree(dir.path()) == before,
        "regenerated sample is byte-identical"
    );

    // An unfinished sample's folder holding someone else's file is
    // refused, naming it, and left as it was; so is a staging folder of a
    // sample to write that matseg did not make.
    let refusal = |opts: &GenerateOptions| {
        let (photos, textures) = libraries();
        let sources = Sources {
            photos: &photos,
            textures: &textures,
        };
        generate_dataset(opts, &small_recipe(), sources, &Silent)
            .unwrap_err()
            .to_string()
    };
    std::fs::remove_file(dir.path().join("00000002/Finished.txt")).unwrap();
    std::fs::write(dir.path().join("00000002/notes.txt"), "mine").unwrap();
    let e = refusal(&opts);
    assert!(e.contains("00000002"), "{e}");
    assert_eq!(
        std::fs::read(dir.path().join("00000002/notes.txt")).unwrap(),
        b"mine"
    );
    std::fs::remove_file(dir.path().join("00000002/notes.txt")).unwrap();
    std::fs::create_dir(dir.path().join("00000002.partial")).unwrap();
    let e = refusal(&opts);
    assert!(e.contains("00000002.partial"), "{e}");
    std::fs::remove_dir(dir.path().join("00000002.partial")).unwrap();
    run(&opts, 1);
    assert!(tree(dir.path()) == before);

    // A stale .tmp shard is ignored by readers and replaced on rerun.
    let wds = tempfile::tempdir().unwrap();
    let opts = options(wds.path(), 6, Format::Wds, JobSlice::ALL);
    run(&opts, 2);
    let complete = tree(wds.path());
    std::fs::rename(
        wds.path().join("shard-000001.tar"),
        wds.path().join("shard-000001.tar.tmp"),
    )
    .unwrap();
    assert_eq!(Dataset::open(wds.path()).unwrap().len(), 3);
    let report = run(&opts, 1);
    assert_eq!((report.generated, report.skipped), (3, 3));
    assert!(tree(wds.path()) == complete);
}

#[test]
fn other_settings_in_the_same_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    run(&options(dir.path(), 2, Format::Folders, JobSlice::ALL), 1);
    let (photos, textures) = libraries();
    let sources = Sources {
        photos: &photos,
        textures: &textures,
    };
    let mut opts = options(dir.path(), 2, Format::Folders, JobSlice::ALL);
    opts.seed = 43;
    let err = generate_dataset(&opts, &small_recipe(), sources, &Silent)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("dataset.json: holds a dataset made with other settings (seed differs)"),
        "{err}"
    );

    let opts = options(
        dir.path(),
        2,
        Format::Folders,
        JobSlice { count: 2, index: 2 },
    );
    let err = generate_dataset(&opts, &small_recipe(), sources, &Silent)
        .unwrap_err()
        .to_string();
    assert_eq!(err, "shard index 2 is not below the number of shards 2");
}

#[test]
fn reading_a_folder_without_samples_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let err = Dataset::open(dir.path()).unwrap_err().to_string();
    assert!(
        err.ends_with("no complete samples (MatSeg folders with Finished.txt, or .tar shards)"),
        "{err}"
    );
}

#[test]
fn a_job_counts_the_samples_of_its_own_units() {
    let dir = tempfile::tempdir().unwrap();
    let folders = options(
        dir.path(),
        5,
        Format::Folders,
        JobSlice { count: 2, index: 1 },
    );
    assert_eq!(folders.samples_in_job(), 2, "samples 1 and 3");
    // Shards of 3: job 0 of 2 owns shards 0 and 2, i.e. samples 0-2 and 6.
    let shards = options(dir.path(), 7, Format::Wds, JobSlice { count: 2, index: 0 });
    assert_eq!(shards.samples_in_job(), 4);
    assert_eq!(
        options(dir.path(), 7, Format::Wds, JobSlice::ALL).samples_in_job(),
        7
    );
}

#[test]
fn a_sample_missing_a_mask_its_sidecar_lists_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path(), 2, Format::Folders, JobSlice::ALL);
    run(&opts, 1);
    let sample = dir.path().join("00000001");
    let masks = std::fs::read_dir(&sample)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with("mask")
        })
        .count();
    assert!(masks >= 1);
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(ds.get(1).unwrap().masks.len(), masks);
    // mask0 lost: the other masks must not move up to take its place.
    std::fs::remove_file(sample.join("mask0.png")).unwrap();
    let e = Dataset::open(dir.path())
        .unwrap()
        .get(1)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("00000001") && e.contains("mask0.png is missing"),
        "{e}"
    );
    // A mask beyond the listed ones.
    std::fs::copy(sample.join("RGB__RGB.jpg"), sample.join("mask0.png")).unwrap();
    std::fs::copy(
        sample.join("ObjectMaskOcluded.png"),
        sample.join(format!("mask{masks}.png")),
    )
    .unwrap();
    let e = Dataset::open(dir.path())
        .unwrap()
        .get(1)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&format!("mask{masks}.png beyond")), "{e}");
}
