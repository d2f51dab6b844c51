//! Installing one downloaded package into the corpus: take the files the
//! manifest names, work out each one's licence, convert and check them in a
//! staging folder, then move the folder into place and write the package's
//! record last.

use crate::archive::{extract_from, visit, Entry};
use crate::benchmark_photos::benchmark_photo_of;
use crate::catalogue::{CatalogueEntry, PackageRecord, PACKAGES_DIR};
use crate::convert::convert;
use crate::dep5::Copyright;
use crate::error::AssetError;
use crate::glob::{glob_match, literal_prefix};
use crate::manifest::{Kind, PackageSpec, Registry};
use matseg_image::fingerprint::Fingerprint;
use matseg_image::library::{LICENSES_FILE, UNKNOWN_LICENCE};
use matseg_image::licence_family;
use serde_json::json;
use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};

/// A file taken from the package, before conversion.
struct Taken {
    /// Path inside the package (`ARCHIVE!PATH` inside a nested archive).
    source: String,
    /// Corpus name below the package's folder.
    name: String,
    licence: String,
    bytes: Vec<u8>,
}

/// A converted file written (and checked) in the staging folder.
struct Staged {
    /// Name below the package's corpus folder.
    name: String,
    /// Its size.
    bytes: u64,
    /// What the catalogue says of it.
    info: serde_json::Value,
    /// The name of the file it belongs to (a model's material or texture).
    part_of: Option<String>,
    source: String,
    licence: String,
}

/// Installs the package file `archive` (version `version`) of `spec` into
/// `corpus/KIND/FOLDER/`, replacing what was there, and writes its record
/// to `corpus/packages/`. Files that cannot be used are left out with a
/// warning in the record; a package that gives no file at all is an error.
pub fn install(
    spec: &PackageSpec,
    archive: &Path,
    version: &str,
    corpus: &Path,
) -> Result<PackageRecord, AssetError> {
    let label = archive.display().to_string();
    let folder = spec.folder();
    let staging_root = corpus.join(".staging");
    let staging = staging_root.join(format!("{}-{folder}", spec.kind));
    let spill = staging_root.join(format!("{}-{folder}.nested", spec.kind));
    let io = |e: std::io::Error, p: &Path| AssetError::File(format!("{}: {e}", p.display()));
    std::fs::create_dir_all(&staging_root).map_err(|e| io(e, &staging_root))?;
    let taken = take_files(spec, archive, &spill);
    let _ = std::fs::remove_file(&spill);
    let taken = taken.map_err(|e| AssetError::Archive(format!("{label}: {e}")))?;
    if staging.exists() {
        std::fs::remove_dir_all(&staging).map_err(|e| io(e, &staging))?;
    }
    std::fs::create_dir_all(&staging).map_err(|e| io(e, &staging))?;

    let mut warnings = Vec::new();
    let mut staged = Vec::new();
    // The photos staged so far, to leave out second copies.
    let mut photos: Vec<(String, Fingerprint)> = Vec::new();
    for t in taken {
        match convert(spec.kind, &t.name, t.bytes) {
            Ok(files) => {
                for converted in files {
                    let path = staging.join(&converted.name);
                    std::fs::create_dir_all(path.parent().expect("inside staging"))
                        .map_err(|e| io(e, &path))?;
                    std::fs::write(&path, &converted.bytes).map_err(|e| io(e, &path))?;
                    let info = if converted.part_of.is_none() {
                        match check(spec.kind, &path, converted.info) {
                            Ok(info) => info,
                            Err(e) => {
                                let inner = (!t.source.ends_with(&converted.name))
                                    .then(|| format!(" ({})", converted.name));
                                warnings.push(format!(
                                    "{}{}: {e}",
                                    t.source,
                                    inner.unwrap_or_default()
                                ));
                                std::fs::remove_file(&path).map_err(|e| io(e, &path))?;
                                continue;
                            }
                        }
                    } else {
                        converted.info
                    };
                    if let Some(why) = photo_left_out(&info, &mut photos, &converted.name) {
                        warnings.push(format!("{}: {why}", t.source));
                        std::fs::remove_file(&path).map_err(|e| io(e, &path))?;
                        continue;
                    }
                    staged.push(Staged {
                        name: converted.name,
                        bytes: converted.bytes.len() as u64,
                        info,
                        part_of: converted.part_of,
                        source: t.source.clone(),
                        licence: t.licence.clone(),
                    });
                }
            }
            Err(e) => warnings.push(format!("{}: {e}", t.source)),
        }
    }
    if !staged.iter().any(|s| s.part_of.is_none()) {
        let _ = std::fs::remove_dir_all(&staging);
        let why = warnings.first().map_or(
            "it holds none of the files the manifest names".to_string(),
            |w| w.clone(),
        );
        return Err(AssetError::Content(format!(
            "{label}: no usable file ({why})"
        )));
    }
    write_licence_lists(&staging, &staged)?;

    let target = corpus.join(spec.kind.name()).join(&folder);
    if target.exists() {
        std::fs::remove_dir_all(&target).map_err(|e| io(e, &target))?;
    }
    std::fs::create_dir_all(target.parent().expect("below corpus")).map_err(|e| io(e, &target))?;
    std::fs::rename(&staging, &target).map_err(|e| io(e, &target))?;

    let corpus_path = |name: &str| format!("{}/{folder}/{name}", spec.kind);
    let files = staged
        .iter()
        .map(|s| CatalogueEntry {
            path: corpus_path(&s.name),
            part_of: s.part_of.as_deref().map(corpus_path),
            kind: spec.kind,
            bytes: s.bytes,
            package: spec.name.clone(),
            registry: spec.registry,
            version: version.to_string(),
            source: s.source.clone(),
            licence: s.licence.clone(),
            family: licence_family(&s.licence).to_string(),
            info: s.info.clone(),
        })
        .collect();
    let record = PackageRecord {
        package: spec.name.clone(),
        registry: spec.registry,
        version: version.to_string(),
        kind: spec.kind,
        files,
        warnings,
        spec: Some(PackageRecord::spec_value(spec)),
    };
    let records = corpus.join(PACKAGES_DIR);
    std::fs::create_dir_all(&records).map_err(|e| io(e, &records))?;
    let path = records.join(PackageRecord::file_name(spec.kind, &folder));
    matseg_image::outputs::write_atomic(
        &path,
        &serde_json::to_vec_pretty(&record).expect("serialisable"),
    )
    .map_err(|e| io(e, &path))?;
    Ok(record)
}

/// Why a staged photo (its catalogue `info`, its corpus `name`) is left
/// out, if it is: it is a photo of the project's benchmark, or the same
/// photo as one staged before it (`photos`, to which it is added when kept).
fn photo_left_out(
    info: &serde_json::Value,
    photos: &mut Vec<(String, Fingerprint)>,
    name: &str,
) -> Option<String> {
    let print = info["fingerprint"]
        .as_str()
        .and_then(Fingerprint::from_hex)?;
    if let Some(benchmark) = benchmark_photo_of(&print) {
        return Some(format!(
            "the same photo as benchmarks/real-dev/images/{benchmark}: a benchmark photo is never \
             a generator source"
        ));
    }
    if let Some((first, _)) = photos.iter().find(|(_, p)| p.same_photo(&print)) {
        return Some(format!("the same photo as {first}, kept once"));
    }
    photos.push((name.to_string(), print));
    None
}

/// The files `spec` takes from the package file `archive`, with their
/// corpus names and licences. The package is streamed; a nested archive is
/// copied to the file `spill` and read from there.
fn take_files(spec: &PackageSpec, archive: &Path, spill: &Path) -> Result<Vec<Taken>, AssetError> {
    let copyright = format!("usr/share/doc/{}/copyright", spec.name);
    let metadata = |p: &str| match spec.registry {
        Registry::Deb => p == copyright,
        Registry::Npm => p == "package/package.json",
        Registry::Pypi => false,
    };
    let nested_in = |p: &str| spec.nested.iter().find(|n| glob_match(&n.archive, p));
    let want = |p: &str| spec.taken_by(p).is_some() || nested_in(p).is_some() || metadata(p);
    let file_name = archive
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    let file =
        std::fs::File::open(archive).map_err(|e| AssetError::File(format!("cannot read: {e}")))?;
    // Files of the package itself, and (outer path, file) of nested archives.
    let mut entries = Vec::new();
    let mut inner_entries = Vec::new();
    visit(
        file_name,
        BufReader::new(file),
        &want,
        &mut |path, reader| {
            let taken = spec.taken_by(path).is_some();
            let mut bytes = Vec::new();
            if let Some(nested) = nested_in(path) {
                let io = |e: std::io::Error| AssetError::File(format!("{}: {e}", spill.display()));
                let mut copy = std::fs::File::create(spill).map_err(io)?;
                std::io::copy(reader, &mut copy)
                    .map_err(|e| AssetError::Archive(format!("{path}: {e}")))?;
                drop(copy);
                let inner_take = |p: &str| nested.takes(p) && !spec.skips(p);
                let inner = BufReader::new(std::fs::File::open(spill).map_err(io)?);
                let inner = extract_from(path, inner, &inner_take)
                    .map_err(|e| AssetError::Archive(format!("{path}: {e}")))?;
                inner_entries.extend(inner.into_iter().map(|e| (path.to_string(), e)));
                if taken {
                    bytes = std::fs::read(spill).map_err(io)?;
                }
            } else {
                reader
                    .read_to_end(&mut bytes)
                    .map_err(|e| AssetError::Archive(format!("{path}: {e}")))?;
            }
            if taken || metadata(path) {
                entries.push(Entry {
                    path: path.to_string(),
                    bytes,
                });
            }
            Ok(())
        },
    )?;
    let package_licence = package_licence(spec, &entries, &copyright);
    let licence_of = |path: &str| -> String {
        spec.manifest_licence(path)
            .map(String::from)
            .or_else(|| package_licence(path))
            .unwrap_or_else(|| UNKNOWN_LICENCE.to_string())
    };
    let mut taken = Vec::new();
    for (outer, inner) in inner_entries {
        let nested = nested_in(&outer).expect("taken from a nested archive");
        let pattern = nested
            .take
            .iter()
            .find(|t| glob_match(t, &inner.path))
            .expect("taken");
        taken.push(Taken {
            source: format!("{outer}!{}", inner.path),
            name: inner.path[literal_prefix(pattern).len()..].to_string(),
            licence: licence_of(&outer),
            bytes: inner.bytes,
        });
    }
    for Entry { path, bytes } in entries {
        if let Some(pattern) = spec.taken_by(&path) {
            taken.push(Taken {
                name: path[literal_prefix(pattern).len()..].to_string(),
                licence: licence_of(&path),
                source: path,
                bytes,
            });
        }
    }
    Ok(taken)
}

/// The licence the package itself gives a path: its DEP-5 copyright file
/// (Debian) or its `package.json` `license` (npm).
fn package_licence(
    spec: &PackageSpec,
    entries: &[Entry],
    copyright: &str,
) -> impl Fn(&str) -> Option<String> {
    let dep5 = entries
        .iter()
        .find(|e| e.path == copyright)
        .and_then(|e| Copyright::parse(&String::from_utf8_lossy(&e.bytes)));
    let npm = (spec.registry == Registry::Npm)
        .then(|| entries.iter().find(|e| e.path == "package/package.json"))
        .flatten()
        .and_then(|e| serde_json::from_slice::<serde_json::Value>(&e.bytes).ok())
        .and_then(|v| v.get("license").and_then(|l| l.as_str()).map(String::from));
    move |path: &str| {
        dep5.as_ref()
            .and_then(|c| c.licence_of(path))
            .map(String::from)
            .or_else(|| npm.clone())
    }
}

/// A staged file that does not read as matseg reads it; its message leaves
/// the file out (the warning names where it came from).
#[derive(Debug, thiserror::Error)]
enum Unreadable {
    /// A mesh the mesh reader refuses.
    #[error("{}", .0.message)]
    Mesh(matseg_render::mesh_io::MeshError),
    /// An HDRI the HDR reader refuses.
    #[error("{}", .0.message)]
    Hdri(matseg_render::hdr_io::HdrError),
}

/// Checks a staged file of kind `kind` by reading it as matseg will:
/// meshes through the mesh reader, HDRIs through the HDR reader (any EXR
/// compression, DWAB included). The catalogue's information for it.
fn check(
    kind: Kind,
    path: &Path,
    info: serde_json::Value,
) -> Result<serde_json::Value, Unreadable> {
    match kind {
        Kind::Meshes => matseg_render::mesh_io::read_mesh(path)
            .map(|m| json!({ "vertices": m.positions.len(), "triangles": m.triangles.len() }))
            .map_err(Unreadable::Mesh),
        Kind::Hdris => matseg_render::hdr_io::read_hdr(path)
            .map(|img| {
                let (max, mean) = img.luminance_stats();
                json!({ "width": img.width, "height": img.height, "max_luminance": max, "mean_luminance": mean })
            })
            .map_err(Unreadable::Hdri),
        _ => Ok(info),
    }
}

/// One `licenses.json` per staged folder, naming each file's licence, so
/// the photo library and the 3D sidecars find them.
fn write_licence_lists(staging: &Path, staged: &[Staged]) -> Result<(), AssetError> {
    let mut lists: BTreeMap<PathBuf, BTreeMap<String, String>> = BTreeMap::new();
    for s in staged {
        let path = staging.join(&s.name);
        let dir = path.parent().expect("inside staging").to_path_buf();
        let file = path
            .file_name()
            .expect("a file")
            .to_string_lossy()
            .into_owned();
        lists
            .entry(dir)
            .or_default()
            .insert(file, s.licence.clone());
    }
    for (dir, list) in lists {
        let path = dir.join(LICENSES_FILE);
        let text = serde_json::to_vec_pretty(&list).expect("serialisable");
        std::fs::write(&path, text)
            .map_err(|e| AssetError::File(format!("{}: {e}", path.display())))?;
    }
    Ok(())
}
