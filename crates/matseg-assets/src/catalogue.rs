//! The corpus catalogue: one record per fetched package (written last, so a
//! package with a record is complete) and `catalog.json`, every corpus file
//! with its kind, size, source package and version, and licence.

use crate::error::AssetError;
use crate::manifest::{Kind, PackageSpec, Registry};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The catalogue's file name in the corpus folder.
pub const CATALOGUE_FILE: &str = "catalog.json";

/// The folder of per-package records in the corpus folder.
pub const PACKAGES_DIR: &str = "packages";

/// One corpus file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CatalogueEntry {
    /// Path relative to the corpus folder (`photos/mate-backgrounds/Dune.jpg`).
    pub path: String,
    /// What it is.
    pub kind: Kind,
    /// Size in bytes.
    pub bytes: u64,
    /// The package it came from.
    pub package: String,
    /// That package's registry.
    pub registry: Registry,
    /// That package's version.
    pub version: String,
    /// The file's path inside the package (`ARCHIVE!PATH` inside a nested archive).
    pub source: String,
    /// Its licence, as the package states it.
    pub licence: String,
    /// The licence's family (`cc0`, `cc-by`, ...; see `matseg_image::licence`).
    pub family: String,
    /// Sizes, counts, statistics (kind-specific).
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub info: serde_json::Value,
    /// The corpus path of the file this one belongs to (a model's material
    /// library or texture); absent for a file of its own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub part_of: Option<String>,
}

/// What fetching one package produced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PackageRecord {
    /// The package's name.
    pub package: String,
    /// Its registry.
    pub registry: Registry,
    /// Its version.
    pub version: String,
    /// The kind of its files.
    pub kind: Kind,
    /// The corpus files made from it.
    pub files: Vec<CatalogueEntry>,
    /// Files left out, each with why.
    pub warnings: Vec<String>,
    /// The manifest's entry it was installed by: a package whose entry has
    /// changed since (other files taken, other licences) is installed again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec: Option<serde_json::Value>,
}

impl PackageRecord {
    /// The record's file name: `KIND-FOLDER.json`.
    pub fn file_name(kind: Kind, folder: &str) -> String {
        format!("{kind}-{folder}.json")
    }

    /// `spec` as its record keeps it.
    pub fn spec_value(spec: &PackageSpec) -> serde_json::Value {
        serde_json::to_value(spec).expect("a manifest entry serialises")
    }

    /// Whether the record at `path` is complete and was installed by `spec`
    /// as the manifest now gives it.
    pub fn is_current(path: &std::path::Path, spec: &PackageSpec) -> bool {
        std::fs::read(path)
            .ok()
            .and_then(|bytes| serde_json::from_slice::<PackageRecord>(&bytes).ok())
            .is_some_and(|record| record.spec == Some(Self::spec_value(spec)))
    }
}

/// The whole catalogue.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Catalogue {
    /// Every corpus file, sorted by path.
    pub files: Vec<CatalogueEntry>,
}

impl Catalogue {
    /// The catalogue of every package record under `corpus`.
    pub fn from_records(corpus: &Path) -> Result<Self, AssetError> {
        let dir = corpus.join(PACKAGES_DIR);
        let mut files = Vec::new();
        if dir.is_dir() {
            let listing = std::fs::read_dir(&dir)
                .map_err(|e| AssetError::File(format!("{}: {e}", dir.display())))?;
            for entry in listing.filter_map(Result::ok) {
                let path = entry.path();
                if path.extension().is_some_and(|e| e == "json") {
                    files.extend(read_record(&path)?.files);
                }
            }
        }
        files.sort_by(|a, b| a.path.cmp(&b.path));
        Ok(Self { files })
    }

    /// Reads `catalog.json` from `corpus`.
    pub fn read(corpus: &Path) -> Result<Self, AssetError> {
        let path = corpus.join(CATALOGUE_FILE);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| AssetError::File(format!("{}: cannot read: {e}", path.display())))?;
        serde_json::from_str(&text)
            .map_err(|e| AssetError::File(format!("{}: invalid catalogue: {e}", path.display())))
    }

    /// Writes `catalog.json` into `corpus` (atomically).
    pub fn write(&self, corpus: &Path) -> Result<(), AssetError> {
        let path = corpus.join(CATALOGUE_FILE);
        let text = serde_json::to_vec_pretty(self).expect("serialisable");
        matseg_image::outputs::write_atomic(&path, &text)
            .map_err(|e| AssetError::File(format!("{}: cannot write: {e}", path.display())))
    }

    /// Per (kind, licence family): the count of files of their own and
    /// the bytes of all files (those belonging to them included).
    pub fn summary(&self) -> BTreeMap<(Kind, String), (usize, u64)> {
        let mut out = BTreeMap::new();
        for f in &self.files {
            let e = out.entry((f.kind, f.family.clone())).or_insert((0, 0));
            e.0 += usize::from(f.part_of.is_none());
            e.1 += f.bytes;
        }
        out
    }
}

/// Reads one package record.
pub fn read_record(path: &Path) -> Result<PackageRecord, AssetError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| AssetError::File(format!("{}: cannot read: {e}", path.display())))?;
    serde_json::from_str(&text)
        .map_err(|e| AssetError::File(format!("{}: invalid package record: {e}", path.display())))
}
