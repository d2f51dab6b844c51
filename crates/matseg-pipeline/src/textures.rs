//! A texture library (pipeline.md §4): uniform-texture crops extracted
//! from photos in parallel, with one record per photo written last, so an
//! interrupted job resumes where it stopped and the library works as a
//! texture source (`licenses.json` rebuilt from all records).

use crate::bench::clock::process_cpu_seconds;
use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use crate::progress::Progress;
use crate::sources::SourceError;
use matseg_extract::textures::{extract_textures, TextureOptions, TextureSquare, CHANNEL_NAMES};
use matseg_image::io::{encode_jpeg, read_rgb};
use matseg_image::library::PhotoEntry;
use matseg_image::outputs::{Layout, SharedFolder, Sign};
use matseg_image::PhotoLibrary;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What one photo gave: written last, so a photo with a record is done.
#[derive(Serialize, Deserialize)]
struct PhotoRecord {
    source: String,
    licence: String,
    width: u32,
    height: u32,
    options: TextureOptions,
    channels: Vec<String>,
    textures: Vec<TextureRecord>,
}

#[derive(Serialize, Deserialize)]
struct TextureRecord {
    file: String,
    #[serde(flatten)]
    square: TextureSquare,
}

/// The inputs as paths.
fn photo_paths(photos: &[PathBuf]) -> Vec<&Path> {
    photos.iter().map(PathBuf::as_path).collect()
}

/// Whether `path`, an entry of a texture library, is one `matseg
/// textures` writes in a library it made (one with `records/`): a crop
/// (`STEM__K.jpg`), the records, or the library's `licenses.json`.
fn is_library_entry(path: &Path) -> bool {
    if !path.with_file_name("records").is_dir() {
        return false;
    }
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let crop = name
        .strip_suffix(".jpg")
        .and_then(|stem| stem.rsplit_once("__"))
        .is_some_and(|(_, k)| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()));
    match name.as_ref() {
        "records" => path.is_dir(),
        LICENCES => path.is_file(),
        _ => crop && path.is_file(),
    }
}

/// The library's licence list.
const LICENCES: &str = "licenses.json";

/// The record file of a photo: its path in the sources, flattened.
fn record_path(out: &Path, entry: &PhotoEntry) -> PathBuf {
    out.join("records")
        .join(format!("{}.json", entry.flat_name()))
}

/// What a texture-library job did. Every image file found is counted once:
/// `found` = `photos` + `already` + `too_small` + `unreadable.len()`.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureReport {
    /// Textures written now.
    pub textures: usize,
    /// Image files found under the sources.
    pub found: usize,
    /// Photos processed now.
    pub photos: usize,
    /// Photos done by an earlier run.
    pub already: usize,
    /// Photos too small for the smallest square.
    pub too_small: usize,
    /// The smallest square's side, in pixels.
    pub smallest: u32,
    /// Files that could not be read (their header when the sources were
    /// listed, or their pixels), each as `FILE: problem`.
    pub unreadable: Vec<String>,
    /// CPU seconds per megapixel of the photos processed now.
    pub cpu_seconds_per_megapixel: f64,
}

/// Extracts the textures of `photos` (files or folders, walked
/// recursively) into the library `out`, skipping photos an earlier run
/// finished; files that cannot be read are skipped and listed in the
/// report, and photos of which none decodes are refused before anything
/// is written. `out` is a folder `matseg textures` adds to
/// (matseg_image::outputs::SharedFolder): new, or a texture library, never
/// overlapping the photos.
pub fn make_texture_library(
    photos: &[PathBuf],
    out: &Path,
    options: &TextureOptions,
    progress: &dyn Progress,
) -> Result<TextureReport, PipelineError> {
    if options.cell < 4 || options.min_cells < 1 {
        return Err(PipelineError::Settings(
            "--cell must be at least 4 and --min-cells at least 1".into(),
        ));
    }
    let (library, report) = PhotoLibrary::scan(photos, 0).map_err(SourceError::from)?;
    library.ensure_usable().map_err(SourceError::from)?;
    let mut unreadable: Vec<String> = report
        .skipped
        .iter()
        .map(|s| format!("{}: {}", s.path.display(), s.reason))
        .collect();
    let library_layout = Layout {
        command: "textures",
        sign: Sign::Marker,
        owns: &is_library_entry,
    };
    let folder = SharedFolder::open(out, &library_layout, &photo_paths(photos))?;
    let out = folder.dir();
    let records = out.join("records");
    create_folder(&records)?;
    let smallest = (options.cell * options.min_cells) as u32;
    let todo: Vec<usize> = (0..library.len())
        .filter(|&i| !record_path(out, &library.entries()[i]).is_file())
        .collect();
    // The headers tell which photos cannot hold the smallest square.
    let (too_small, todo): (Vec<usize>, Vec<usize>) = todo.into_iter().partition(|&i| {
        let entry = &library.entries()[i];
        entry.width.min(entry.height) < smallest
    });
    progress.start(todo.len() as u64, "photos");
    let (start, cpu) = (Instant::now(), process_cpu_seconds());
    let results: Vec<Result<(usize, u64), PipelineError>> = todo
        .par_iter()
        .map(|&i| {
            let outcome = extract_one(out, &library, i, options);
            progress.advance();
            outcome
        })
        .collect();
    progress.finish();
    let (mut textures, mut pixels, mut failed) = (0usize, 0u64, 0usize);
    for r in results {
        match r {
            Ok((n, px)) => {
                textures += n;
                pixels += px;
            }
            Err(e) => {
                failed += 1;
                unreadable.push(e.to_string());
            }
        }
    }
    write_licences(out)?;
    let seconds = match (cpu, process_cpu_seconds()) {
        (Some(a), Some(b)) => b - a,
        _ => start.elapsed().as_secs_f64(),
    };
    Ok(TextureReport {
        textures,
        found: library.len() + report.skipped.len(),
        photos: todo.len() - failed,
        already: library.len() - todo.len() - too_small.len(),
        too_small: too_small.len(),
        smallest,
        unreadable,
        cpu_seconds_per_megapixel: if pixels > 0 {
            seconds / (pixels as f64 / 1e6)
        } else {
            0.0
        },
    })
}

/// Extracts the textures of photo `i`, writes the crops and then the
/// record; returns the texture count and the photo's pixels.
fn extract_one(
    out: &Path,
    library: &PhotoLibrary,
    i: usize,
    options: &TextureOptions,
) -> Result<(usize, u64), PipelineError> {
    let entry = &library.entries()[i];
    let img = read_rgb(&entry.path)?;
    let stem = entry.flat_stem();
    let mut textures = Vec::new();
    for (k, (square, crop)) in extract_textures(&img, options).into_iter().enumerate() {
        let file = format!("{stem}__{k}.jpg");
        write_file(&out.join(&file), &encode_jpeg(&crop, 95))?;
        textures.push(TextureRecord { file, square });
    }
    let record = PhotoRecord {
        source: entry.name.clone(),
        licence: entry.licence.clone(),
        width: img.width(),
        height: img.height(),
        options: *options,
        channels: CHANNEL_NAMES.iter().map(|c| c.to_string()).collect(),
        textures,
    };
    let n = record.textures.len();
    let json = serde_json::to_vec_pretty(&record).expect("JSON");
    let path = record_path(out, entry);
    write_file(&path, &json)?;
    Ok((n, img.width() as u64 * img.height() as u64))
}

/// `licenses.json` for the library (each crop with its photo's licence),
/// rebuilt from all records, so the library works as `--textures`.
fn write_licences(out: &Path) -> Result<(), PipelineError> {
    let records = out.join("records");
    let unreadable = |path: &Path, e: String| PipelineError::file(path.display(), e);
    let mut licences = BTreeMap::new();
    let listing = std::fs::read_dir(&records)
        .map_err(|e| unreadable(&records, format!("cannot list: {e}")))?;
    for entry in listing {
        let path = entry
            .map_err(|e| unreadable(&records, format!("cannot list: {e}")))?
            .path();
        if path.extension().is_some_and(|e| e == "json") {
            let bytes =
                std::fs::read(&path).map_err(|e| unreadable(&path, format!("cannot read: {e}")))?;
            let record: PhotoRecord = serde_json::from_slice(&bytes)
                .map_err(|e| unreadable(&path, format!("bad record: {e}")))?;
            for t in record.textures {
                licences.insert(t.file, record.licence.clone());
            }
        }
    }
    write_file(
        &out.join(LICENCES),
        &serde_json::to_vec_pretty(&licences).expect("JSON"),
    )
}
