//! PBR material libraries made from texture libraries (pipeline.md §5): a
//! resumable parallel job, and the default libraries the 3D generator and
//! renderer take when the user names none.

use crate::error::PipelineError;
use crate::progress::Progress;
use crate::sources::{assets_dir, cache_root, Defaults, SourceError};
use matseg_data::sample_rng;
use matseg_extract::material_library::{
    is_library_entry, is_material_folder, write_material_folder, MaterialError,
};
use matseg_extract::pbr::{make_pbr, PbrRecipe};
use matseg_image::io::read_rgb;
use matseg_image::outputs::{Layout, SharedFolder, Sign};
use matseg_image::PhotoLibrary;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What [`make_library`] did.
#[derive(Clone, Debug, Default)]
pub struct LibraryReport {
    /// Materials written now.
    pub written: usize,
    /// Materials found complete.
    pub existing: usize,
    /// Materials that failed (each reported to [`Progress::warn`]).
    pub failed: usize,
    /// Megapixels of the materials written.
    pub megapixels: f64,
    /// Thread seconds spent making their maps.
    pub make_seconds: f64,
    /// Thread seconds spent encoding and writing them.
    pub write_seconds: f64,
}

/// Makes `per_texture` PBR materials from each texture under `textures`
/// into the library `out` (a folder `matseg pbr` adds to:
/// matseg_image::outputs::SharedFolder), one folder each
/// (`TEXTURE__pbrJ`), skipping complete ones,
/// on the current rayon pool. Material `j` of texture `i` depends only on
/// (`seed`, `i`, `j`). Unreadable textures and failed materials are
/// reported to `progress` and skipped; textures of which none decodes are
/// refused before anything is written.
pub fn make_library(
    textures: &[PathBuf],
    out: &Path,
    per_texture: u64,
    seed: u64,
    seamless: bool,
    progress: &dyn Progress,
) -> Result<LibraryReport, SourceError> {
    let (library, report) = PhotoLibrary::scan(textures, 0)?;
    for s in &report.skipped {
        progress.warn(&format!("{}: {}", s.path.display(), s.reason));
    }
    library.ensure_usable()?;
    let owns = |path: &Path| is_library_entry(path, COMMAND);
    let layout = Layout {
        command: COMMAND,
        sign: Sign::Marker,
        owns: &owns,
    };
    let inputs: Vec<&Path> = textures.iter().map(PathBuf::as_path).collect();
    let shared = SharedFolder::open(out, &layout, &inputs).map_err(MaterialError::from)?;
    let out = shared.dir();
    let recipe = PbrRecipe::default();
    let jobs: Vec<(usize, u64)> = (0..library.len())
        .flat_map(|i| (0..per_texture).map(move |j| (i, j)))
        .filter(|&(i, j)| !folder(out, &library, i, j).join("material.json").is_file())
        .collect();
    // Every material folder this run writes, checked before its first byte.
    let names: Vec<PathBuf> = jobs
        .iter()
        .map(|&(i, j)| folder(out, &library, i, j))
        .collect();
    shared
        .claim(names.iter().map(PathBuf::as_path), &is_material_folder)
        .map_err(MaterialError::from)?;
    progress.start(jobs.len() as u64, "materials");
    let results: Vec<Result<Timing, PipelineError>> = jobs
        .par_iter()
        .map(|&(i, j)| {
            let result = make_one(out, &library, (i, j), seed, seamless, &recipe);
            progress.advance();
            result
        })
        .collect();
    progress.finish();
    let mut total = LibraryReport {
        existing: library.len() * per_texture as usize - jobs.len(),
        ..LibraryReport::default()
    };
    for r in results {
        match r {
            Ok(one) => {
                total.written += 1;
                total.megapixels += one.megapixels;
                total.make_seconds += one.make_seconds;
                total.write_seconds += one.write_seconds;
            }
            Err(e) => {
                progress.warn(&e.to_string());
                total.failed += 1;
            }
        }
    }
    Ok(total)
}

/// The command that makes material libraries, in matseg's markers.
const COMMAND: &str = "pbr";

/// The folder of material `j` of texture `i`.
fn folder(out: &Path, library: &PhotoLibrary, i: usize, j: u64) -> PathBuf {
    out.join(format!("{}__pbr{j}", library.entries()[i].flat_stem()))
}

/// One material's size and where its time went (thread seconds).
struct Timing {
    megapixels: f64,
    make_seconds: f64,
    write_seconds: f64,
}

/// Makes one material and writes its folder; the error names the file.
fn make_one(
    out: &Path,
    library: &PhotoLibrary,
    (i, j): (usize, u64),
    seed: u64,
    seamless: bool,
    recipe: &PbrRecipe,
) -> Result<Timing, PipelineError> {
    let entry = &library.entries()[i];
    let texture = read_rgb(&entry.path)?;
    let start = Instant::now();
    let mut rng = sample_rng(seed, ((i as u64) << 20) | j);
    let mut material = make_pbr(&mut rng, &texture, recipe);
    if seamless {
        material.make_seamless();
    }
    let make_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let json = serde_json::json!({
        "source": entry.name,
        "seed": seed,
        "record": material.record,
    });
    write_material_folder(
        &folder(out, library, i, j),
        COMMAND,
        &entry.licence,
        |d| material.write_maps(d),
        json,
    )?;
    Ok(Timing {
        megapixels: (texture.width() as f64 * texture.height() as f64) / 1e6,
        make_seconds,
        write_seconds: start.elapsed().as_secs_f64(),
    })
}

/// The default 3D material library: one seamless PBR material per bundled
/// texture, made once (seed 0) into the cache.
pub fn bundled_materials(progress: &dyn Progress) -> Result<PathBuf, SourceError> {
    let dir = cache_root()?.join("materials/bundled-textures-seed0");
    make_library(&[assets_dir().join("textures")], &dir, 1, 0, true, progress)?;
    Ok(dir)
}

/// The 3D materials when none are given: made once (seed 0) from the
/// corpus's textures when `defaults` takes the corpus and it has textures,
/// else [`bundled_materials`].
pub fn default_materials(
    defaults: Defaults,
    progress: &dyn Progress,
) -> Result<PathBuf, SourceError> {
    let Some(textures) = defaults.corpus_folder("textures") else {
        return bundled_materials(progress);
    };
    let dir = cache_root()?.join("materials/corpus-textures-seed0");
    make_library(&[textures], &dir, 1, 0, true, progress)?;
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// Progress that records what it was told.
    #[derive(Default)]
    struct Recorded {
        total: Mutex<Option<u64>>,
        advanced: Mutex<u64>,
        warnings: Mutex<Vec<String>>,
    }

    impl Progress for Recorded {
        fn start(&self, total: u64, _what: &str) {
            *self.total.lock().unwrap() = Some(total);
        }
        fn advance(&self) {
            *self.advanced.lock().unwrap() += 1;
        }
        fn finish(&self) {}
        fn warn(&self, message: &str) {
            self.warnings.lock().unwrap().push(message.to_string());
        }
    }

    #[test]
    fn a_library_is_made_once_and_resumed_with_unreadable_textures_reported() {
        let root = tempfile::tempdir().unwrap();
        let textures = root.path().join("textures");
        std::fs::create_dir_all(textures.join("stone")).unwrap();
        let texture = image::RgbImage::from_fn(48, 40, |x, y| {
            image::Rgb([(x * 5) as u8, (y * 6) as u8, ((x + y) * 2) as u8])
        });
        texture.save(textures.join("stone/wall.v2.png")).unwrap();
        std::fs::write(textures.join("broken.jpg"), b"not a jpeg").unwrap();
        let out = root.path().join("materials");

        let first = Recorded::default();
        let made =
            make_library(std::slice::from_ref(&textures), &out, 2, 7, false, &first).unwrap();
        assert_eq!((made.written, made.existing, made.failed), (2, 0, 0));
        assert_eq!(*first.total.lock().unwrap(), Some(2));
        assert_eq!(*first.advanced.lock().unwrap(), 2);
        let warnings = first.warnings.lock().unwrap();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("broken.jpg"), "{warnings:?}");
        for j in 0..2 {
            let dir = out.join(format!("stone__wall.v2__pbr{j}"));
            assert!(dir.join("material.json").is_file(), "{}", dir.display());
        }

        let again = make_library(&[textures], &out, 2, 7, false, &Recorded::default()).unwrap();
        assert_eq!((again.written, again.existing, again.failed), (0, 2, 0));
    }
}
