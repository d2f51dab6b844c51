//! A library of source photos: listed once, decoded on first use, kept in a
//! memory-bounded cache shared by all worker threads.

use crate::budget::{ByteLru, MemoryBudget};
use crate::io::{has_image_extension, read_dimensions, read_rgb};
use crate::licence::LicenceFilter;
use crate::resample::Pyramid;
use crate::sync::lock;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

/// File in a folder that maps file names to licences (`"*"` is the default).
pub const LICENSES_FILE: &str = "licenses.json";

/// Licence recorded for files no `licenses.json` mentions.
pub const UNKNOWN_LICENCE: &str = "unknown";

/// Problems with the folders a library is built from.
#[derive(Debug, thiserror::Error)]
pub enum LibraryError {
    /// A named source does not exist.
    #[error("{}: no such file or folder", .0.display())]
    Missing(PathBuf),
    /// A folder could not be listed.
    #[error("{}: cannot list folder: {reason}", path.display())]
    Unlistable {
        /// The folder.
        path: PathBuf,
        /// Why listing failed.
        reason: String,
    },
    /// A `licenses.json` is not a JSON object of strings.
    #[error("{}: invalid licence list: {reason}", path.display())]
    BadLicences {
        /// The licence file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// An image that cannot be decoded.
    #[error("{}: {reason}", path.display())]
    Undecodable {
        /// The image.
        path: PathBuf,
        /// Why decoding failed.
        reason: String,
    },
    /// A photo index beyond the listed photos.
    #[error("{label}: no photo {index} ({len} listed)")]
    NoSuchPhoto {
        /// The library's sources.
        label: String,
        /// The index asked for.
        index: usize,
        /// The photos listed.
        len: usize,
    },
    /// No readable image in any of the sources.
    #[error("{0}: no readable images (jpg, jpeg, png)")]
    Empty(String),
    /// Every image failed to decode.
    #[error("{0}: no usable image: every one failed to decode")]
    AllFailed(String),
    /// No image's licence passes the licence filter.
    #[error("{label}: no image has a licence in {filter}")]
    NoneLicensed {
        /// The sources.
        label: String,
        /// The filter, as the user wrote it.
        filter: String,
    },
}

/// One listed photo.
#[derive(Clone, Debug)]
pub struct PhotoEntry {
    /// Where it is on disk.
    pub path: PathBuf,
    /// Path relative to the source folder it was found in (for sidecars).
    pub name: String,
    /// Licence from the folder's `licenses.json`, or [`UNKNOWN_LICENCE`].
    pub licence: String,
    /// Width from the header.
    pub width: u32,
    /// Height from the header.
    pub height: u32,
}

impl PhotoEntry {
    /// [`PhotoEntry::name`] as one file name: path separators become `__`.
    pub fn flat_name(&self) -> String {
        self.name.replace(['/', '\\'], "__")
    }

    /// [`PhotoEntry::flat_name`] without the file extension.
    pub fn flat_stem(&self) -> String {
        let flat = self.flat_name();
        match flat.rsplit_once('.') {
            Some((stem, _)) => stem.to_string(),
            None => flat,
        }
    }
}

/// A decoded photo, ready for resampling.
#[derive(Debug)]
pub struct Photo {
    /// Its index in the library.
    pub index: usize,
    /// Its pixels and downscaled levels.
    pub pyramid: Pyramid,
    /// The photo turned by 90° counter-clockwise, made on first use.
    quarter_turned: OnceLock<Pyramid>,
}

impl Photo {
    /// A photo of the library at `index` with the pixels of `img`.
    pub fn new(index: usize, img: image::RgbImage) -> Self {
        Self {
            index,
            pyramid: Pyramid::new(img),
            quarter_turned: OnceLock::new(),
        }
    }

    /// The pyramid of the photo turned by 90° counter-clockwise, made on
    /// first use and kept with the photo (textures are drawn turned half
    /// the time; the copy is not counted in the cache budget).
    pub fn quarter_turned(&self) -> &Pyramid {
        self.quarter_turned
            .get_or_init(|| self.pyramid.quarter_turned())
    }
}

/// A file left out of the library, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct SkippedFile {
    /// The file.
    pub path: PathBuf,
    /// Why it was left out.
    pub reason: String,
}

/// What scanning the sources left out.
#[derive(Clone, Debug, Default)]
pub struct ScanReport {
    /// Files with an image extension whose header could not be read.
    pub skipped: Vec<SkippedFile>,
}

/// Source photos with a decode-once, least-recently-used cache whose bytes
/// count against a [`MemoryBudget`] (its own, or one the process shares).
pub struct PhotoLibrary {
    label: String,
    entries: Vec<PhotoEntry>,
    cache: ByteLru<usize, Photo>,
    failed: Mutex<BTreeMap<usize, String>>,
}

impl std::fmt::Debug for PhotoLibrary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PhotoLibrary")
            .field("label", &self.label)
            .field("photos", &self.entries.len())
            .field("cached_bytes", &self.cache.bytes())
            .finish()
    }
}

impl PhotoLibrary {
    /// Lists every image under `sources` (folders are walked recursively in
    /// sorted order; files are taken as they are). Unreadable images are
    /// skipped and reported; a missing source or no image at all is an error.
    /// `budget_bytes` bounds the memory of decoded photos (one photo is always
    /// kept, however large).
    pub fn scan(
        sources: &[PathBuf],
        budget_bytes: usize,
    ) -> Result<(Self, ScanReport), LibraryError> {
        let mut entries = Vec::new();
        let mut report = ScanReport::default();
        for source in sources {
            if source.is_file() {
                let licences = read_licences(source.parent().unwrap_or(Path::new(".")))?;
                add_file(source, Path::new(""), &licences, &mut entries, &mut report);
            } else if source.is_dir() {
                walk(source, source, &mut entries, &mut report)?;
            } else {
                return Err(LibraryError::Missing(source.clone()));
            }
        }
        let label = sources
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ");
        if entries.is_empty() {
            return Err(LibraryError::Empty(label));
        }
        let lib = Self {
            label,
            entries,
            cache: ByteLru::new(MemoryBudget::new(budget_bytes)),
            failed: Mutex::new(BTreeMap::new()),
        };
        Ok((lib, report))
    }

    /// Counts the library's decoded photos against `budget` (shared with
    /// the process's other caches) instead of its own.
    pub fn sharing(mut self, budget: Arc<MemoryBudget>) -> Self {
        self.cache.share(budget);
        self
    }

    /// Keeps only the photos whose licence `filter` accepts; an error when
    /// none is left.
    pub fn retain_licences(mut self, filter: &LicenceFilter) -> Result<Self, LibraryError> {
        self.entries.retain(|e| filter.accepts(&e.licence));
        if self.entries.is_empty() {
            return Err(LibraryError::NoneLicensed {
                label: self.label.clone(),
                filter: filter.to_string(),
            });
        }
        Ok(self)
    }

    /// The sources the library was scanned from, for messages.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The listed photos, in draw order.
    pub fn entries(&self) -> &[PhotoEntry] {
        &self.entries
    }

    /// Number of listed photos.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when nothing is listed (never, for a scanned library).
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The decoded photo `index`, from the cache or decoded now.
    pub fn get(&self, index: usize) -> Result<Arc<Photo>, LibraryError> {
        if index >= self.entries.len() {
            return Err(LibraryError::NoSuchPhoto {
                label: self.label.clone(),
                index,
                len: self.entries.len(),
            });
        }
        let undecodable = |reason: &str| LibraryError::Undecodable {
            path: self.entries[index].path.clone(),
            reason: reason.to_string(),
        };
        if let Some(reason) = lock(&self.failed).get(&index) {
            return Err(undecodable(reason));
        }
        if let Some(photo) = self.cache.get(&index) {
            return Ok(photo);
        }
        // Decode outside the lock; two threads may rarely decode the same photo.
        let entry = &self.entries[index];
        let img = match read_rgb(&entry.path) {
            Ok(img) => img,
            Err(e) => {
                lock(&self.failed).insert(index, e.message.clone());
                return Err(undecodable(&e.message));
            }
        };
        let photo = Arc::new(Photo::new(index, img));
        self.cache
            .insert(index, photo.clone(), photo.pyramid.bytes());
        Ok(photo)
    }

    /// Draws photos with `draw(n)` (an index below `n`) until one decodes.
    /// Photos that fail are remembered and reported by [`Self::failures`]; the
    /// outcome depends only on the draws, so it stays deterministic.
    pub fn pick(&self, mut draw: impl FnMut(usize) -> usize) -> Result<Arc<Photo>, LibraryError> {
        loop {
            if lock(&self.failed).len() == self.entries.len() {
                return Err(LibraryError::AllFailed(self.label.clone()));
            }
            if let Ok(photo) = self.get(draw(self.entries.len())) {
                return Ok(photo);
            }
        }
    }

    /// Decodes the photos in order until one decodes (it stays cached), so
    /// that a library whose every file is unusable (truncated, corrupt
    /// past its header) is refused before anything is made from it; the
    /// ones that fail on the way are remembered as [`Self::pick`] does.
    pub fn ensure_usable(&self) -> Result<(), LibraryError> {
        if (0..self.entries.len()).any(|i| self.get(i).is_ok()) {
            Ok(())
        } else {
            Err(LibraryError::AllFailed(self.label.clone()))
        }
    }

    /// Photos that failed to decode so far.
    pub fn failures(&self) -> Vec<SkippedFile> {
        lock(&self.failed)
            .iter()
            .map(|(&i, reason)| SkippedFile {
                path: self.entries[i].path.clone(),
                reason: reason.clone(),
            })
            .collect()
    }

    /// Bytes of decoded photos held now.
    pub fn cached_bytes(&self) -> usize {
        self.cache.bytes()
    }
}

/// The licence of a file or folder from the `licenses.json` beside it (by
/// file name, else its `"*"` entry), or, for a folder, from the one inside it
/// (`"*"` entry); [`UNKNOWN_LICENCE`] when none says.
pub fn licence_of(path: &Path) -> String {
    let inside = path.is_dir().then(|| read_licences(path).ok()).flatten();
    let from_inside = inside.and_then(|l| l.get("*").cloned());
    from_inside.unwrap_or_else(|| {
        let licences = path
            .parent()
            .and_then(|d| read_licences(d).ok())
            .unwrap_or_default();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        licence_in(&licences, name)
    })
}

/// The licence a folder's `licenses.json` gives `file_name`: its own entry,
/// else the `"*"` entry, else [`UNKNOWN_LICENCE`].
fn licence_in(licences: &BTreeMap<String, String>, file_name: &str) -> String {
    licences
        .get(file_name)
        .or_else(|| licences.get("*"))
        .cloned()
        .unwrap_or_else(|| UNKNOWN_LICENCE.to_string())
}

fn read_licences(dir: &Path) -> Result<BTreeMap<String, String>, LibraryError> {
    let path = dir.join(LICENSES_FILE);
    if !path.is_file() {
        return Ok(BTreeMap::new());
    }
    let text = std::fs::read_to_string(&path).map_err(|e| LibraryError::BadLicences {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    serde_json::from_str(&text).map_err(|e| LibraryError::BadLicences {
        path,
        reason: e.to_string(),
    })
}

fn add_file(
    path: &Path,
    root: &Path,
    licences: &BTreeMap<String, String>,
    entries: &mut Vec<PhotoEntry>,
    report: &mut ScanReport,
) {
    let file_name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    let name = path
        .strip_prefix(root)
        .unwrap_or(path)
        .to_string_lossy()
        .into_owned();
    let licence = licence_in(licences, file_name);
    match read_dimensions(path) {
        Ok((width, height)) if width > 0 && height > 0 => entries.push(PhotoEntry {
            path: path.to_path_buf(),
            name,
            licence,
            width,
            height,
        }),
        Ok(_) => report.skipped.push(SkippedFile {
            path: path.to_path_buf(),
            reason: "image has no pixels".into(),
        }),
        Err(e) => report.skipped.push(SkippedFile {
            path: path.to_path_buf(),
            reason: e.message,
        }),
    }
}

fn walk(
    dir: &Path,
    root: &Path,
    entries: &mut Vec<PhotoEntry>,
    report: &mut ScanReport,
) -> Result<(), LibraryError> {
    let listing = std::fs::read_dir(dir).map_err(|e| LibraryError::Unlistable {
        path: dir.to_path_buf(),
        reason: e.to_string(),
    })?;
    let mut paths: Vec<PathBuf> = listing.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    let licences = read_licences(dir)?;
    for path in paths {
        if path.is_dir() {
            walk(&path, root, entries, report)?;
        } else if has_image_extension(&path) {
            add_file(&path, root, &licences, entries, report);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    fn write_png(path: &Path, w: u32, h: u32) {
        RgbImage::from_pixel(w, h, image::Rgb([10, 20, 30]))
            .save(path)
            .unwrap();
    }

    #[test]
    fn scan_lists_sorted_skips_corrupt_and_reads_licences() {
        let dir = tempfile::tempdir().unwrap();
        write_png(&dir.path().join("b.png"), 64, 64);
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        write_png(&dir.path().join("sub/a.png"), 64, 48);
        std::fs::write(dir.path().join("c.jpg"), b"definitely not a jpeg").unwrap();
        std::fs::write(dir.path().join("notes.txt"), b"ignored").unwrap();
        std::fs::write(dir.path().join(LICENSES_FILE), r#"{"b.png": "CC0-1.0"}"#).unwrap();

        let (lib, report) = PhotoLibrary::scan(&[dir.path().to_path_buf()], 1 << 30).unwrap();
        let names: Vec<_> = lib.entries().iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, vec!["b.png", "sub/a.png"]);
        assert_eq!(lib.entries()[0].licence, "CC0-1.0");
        assert_eq!(lib.entries()[1].licence, UNKNOWN_LICENCE);
        assert_eq!(report.skipped.len(), 1);
        assert!(report.skipped[0].path.ends_with("c.jpg"));
    }

    #[test]
    fn empty_and_missing_sources_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let err = PhotoLibrary::scan(&[dir.path().to_path_buf()], 1).unwrap_err();
        assert!(matches!(err, LibraryError::Empty(_)), "{err}");
        let err = PhotoLibrary::scan(&[dir.path().join("nope")], 1).unwrap_err();
        assert!(
            err.to_string().ends_with("nope: no such file or folder"),
            "{err}"
        );
    }

    #[test]
    fn cache_stays_within_budget_and_pick_skips_broken_files() {
        let dir = tempfile::tempdir().unwrap();
        for i in 0..4 {
            write_png(&dir.path().join(format!("{i}.png")), 64, 64);
        }
        let (lib, _) =
            PhotoLibrary::scan(&[dir.path().to_path_buf()], 64 * 64 * 3 * 2 + 10).unwrap();
        // Corrupt one file after the scan: it is found at decode time.
        std::fs::write(dir.path().join("0.png"), b"truncated").unwrap();
        for i in 1..4 {
            lib.get(i).unwrap();
            assert!(lib.cached_bytes() <= 64 * 64 * 3 * 2 + 10);
        }
        let mut draws = [0usize, 0, 2].into_iter();
        let photo = lib.pick(|_| draws.next().unwrap()).unwrap();
        assert_eq!(photo.index, 2);
        let failures = lib.failures();
        assert_eq!(failures.len(), 1);
        assert!(failures[0].path.ends_with("0.png"));
    }

    #[test]
    fn a_panic_while_the_failures_are_held_does_not_stop_the_next_photo() {
        let dir = tempfile::tempdir().unwrap();
        write_png(&dir.path().join("a.png"), 64, 64);
        write_png(&dir.path().join("b.png"), 64, 64);
        let (lib, _) = PhotoLibrary::scan(&[dir.path().to_path_buf()], 1 << 30).unwrap();
        std::fs::write(dir.path().join("b.png"), b"truncated").unwrap();
        let panicked = std::thread::scope(|s| {
            s.spawn(|| {
                let _held = lib.failed.lock();
                panic!("a decoder gives up");
            })
            .join()
        });
        assert!(panicked.is_err() && lib.failed.is_poisoned());
        assert_eq!(lib.get(0).unwrap().index, 0);
        assert!(lib.get(1).is_err());
        assert_eq!(lib.failures().len(), 1);
        let beyond = lib.get(2).unwrap_err().to_string();
        assert!(beyond.ends_with("no photo 2 (2 listed)"), "{beyond}");
    }

    #[test]
    fn libraries_sharing_a_budget_stay_within_it_together() {
        let dir = tempfile::tempdir().unwrap();
        for i in 0..4 {
            write_png(&dir.path().join(format!("{i}.png")), 64, 64);
        }
        // A decoded 64 x 64 photo's pyramid: the photo and its half size.
        let one = 64 * 64 * 3 + 32 * 32 * 3;
        let budget = MemoryBudget::new(2 * one + 10);
        let scan = || {
            let (lib, _) = PhotoLibrary::scan(&[dir.path().to_path_buf()], 0).unwrap();
            lib.sharing(budget.clone())
        };
        let (a, b) = (scan(), scan());
        a.get(0).unwrap();
        assert_eq!(budget.held(), one);
        a.get(1).unwrap();
        assert_eq!(budget.held(), 2 * one);
        // Each library keeps one photo whatever the budget says...
        b.get(0).unwrap();
        assert_eq!(budget.held(), 3 * one);
        // ...and gives back its least recently used ones while the shared
        // budget is passed.
        a.get(2).unwrap();
        assert_eq!(a.cached_bytes(), one);
        assert_eq!(budget.held(), 2 * one);
        drop(a);
        assert_eq!(budget.held(), one);
    }
}
