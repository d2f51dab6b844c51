//! Pieces shared by the commands: sources, recipes, progress bars, warnings.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use matseg_extract::material_library::{colour_map, find_materials};
use matseg_image::{LicenceFilter, PhotoLibrary, SkippedFile};
use matseg_scene::Recipe2d;
use std::path::{Path, PathBuf};

/// A library entry's name (a path below its source folder) as one file
/// name: separators become `__`.
pub fn flat_name(name: &str) -> String {
    name.replace(['/', '\\'], "__")
}

/// [`flat_name`] without the file extension.
pub fn flat_stem(name: &str) -> String {
    let flat = flat_name(name);
    match flat.rsplit_once('.') {
        Some((stem, _)) => stem.to_string(),
        None => flat,
    }
}

/// Writes a material folder: `write_maps` fills `DIR.partial/`, with a
/// `licenses.json` giving every file `licence`; the folder is renamed to
/// `dir`, and `material.json` (the `record` object plus the licence, the
/// colour spaces and the normal convention) is written last, so a folder
/// with `material.json` is complete and anything else is redone.
pub fn write_material_folder(
    dir: &Path,
    licence: &str,
    write_maps: impl FnOnce(&Path) -> std::io::Result<()>,
    mut record: serde_json::Value,
) -> Result<()> {
    // `NAME.partial` beside `dir`, appended rather than swapped for an
    // extension: material names hold dots (`Terrain.winter__Town1`), and
    // two such names must not share one partial folder when written in
    // parallel.
    let mut partial_name = dir.file_name().unwrap_or_default().to_os_string();
    partial_name.push(".partial");
    let partial = dir.with_file_name(partial_name);
    if partial.exists() {
        std::fs::remove_dir_all(&partial)?;
    }
    std::fs::create_dir_all(&partial)?;
    write_maps(&partial)
        .and_then(|()| {
            let licences = serde_json::json!({ "*": licence }).to_string();
            std::fs::write(partial.join("licenses.json"), licences)
        })
        .with_context(|| format!("{}: cannot write", partial.display()))?;
    record["licence"] = licence.into();
    record["color_space"] = serde_json::json!({"Color": "sRGB", "other maps": "linear"});
    record["normal_convention"] = "OpenGL (+Y up)".into();
    if dir.exists() {
        std::fs::remove_dir_all(dir)?;
    }
    std::fs::rename(&partial, dir)?;
    std::fs::write(
        dir.join("material.json"),
        serde_json::to_vec_pretty(&record)?,
    )
    .with_context(|| format!("{}: cannot write material.json", dir.display()))
}

/// The user's matseg cache: `$MATSEG_CACHE`, else `$XDG_CACHE_HOME/matseg`,
/// else `~/.cache/matseg`.
pub fn cache_root() -> Result<PathBuf> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(dir) = var("MATSEG_CACHE") {
        return Ok(dir);
    }
    if let Some(dir) = var("XDG_CACHE_HOME") {
        return Ok(dir.join("matseg"));
    }
    match var("HOME") {
        Some(home) => Ok(home.join(".cache/matseg")),
        None => anyhow::bail!("no cache folder: set MATSEG_CACHE"),
    }
}

/// Default bound on decoded source photos held in memory, per process.
pub const DEFAULT_CACHE_MB: usize = 2048;

/// The bundled sample assets: `$MATSEG_ASSETS`, else the repository's `assets/`.
pub fn assets_dir() -> PathBuf {
    std::env::var_os("MATSEG_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets"))
}

/// Where a command's sources come from when the user names none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Defaults {
    /// The corpus `matseg assets fetch` made, for each kind it holds; the
    /// bundled sample set otherwise (generators and training).
    CorpusOrBundled,
    /// Always the bundled sample set (the demo and the benchmarks, whose
    /// results must not depend on what a machine has fetched).
    Bundled,
}

impl Defaults {
    /// The corpus folder of `kind` when these defaults take the corpus and
    /// it holds that kind.
    pub fn corpus_folder(self, kind: &str) -> Option<PathBuf> {
        if self != Defaults::CorpusOrBundled {
            return None;
        }
        corpus_dir().map(|c| c.join(kind)).filter(|d| d.is_dir())
    }

    /// The default folders of `kind` (`photos`, `textures`, `hdris`,
    /// `meshes`); empty when there are none.
    pub fn folders(self, kind: &str) -> Vec<PathBuf> {
        let folder = self
            .corpus_folder(kind)
            .or_else(|| Some(assets_dir().join(kind)).filter(|d| d.is_dir()));
        folder.into_iter().collect()
    }

    /// `given` when the user named any, else the default folders of `kind`.
    pub fn or(self, given: &[PathBuf], kind: &str) -> Vec<PathBuf> {
        if given.is_empty() {
            self.folders(kind)
        } else {
            given.to_vec()
        }
    }
}

/// The fetched corpus (`CACHE/corpus`), when it has a catalogue.
pub fn corpus_dir() -> Option<PathBuf> {
    let dir = cache_root().ok()?.join("corpus");
    dir.join(matseg_assets::catalog::CATALOG_FILE)
        .is_file()
        .then_some(dir)
}

/// The `--licences` option of the commands that draw from source folders.
#[derive(clap::Args)]
pub struct LicenceArgs {
    /// Use only sources under these licence families (comma-separated:
    /// cc0, public-domain, mit, bsd, apache, cc-by, cc-by-sa, lgpl, gpl, unknown).
    #[arg(long)]
    licences: Option<String>,
}

impl LicenceArgs {
    /// The filter (every licence when the option is absent).
    pub fn filter(&self) -> Result<LicenceFilter> {
        Ok(LicenceFilter::parse(
            self.licences.as_deref().unwrap_or_default(),
        )?)
    }
}

/// Texture sources: a folder of PBR material folders (from `matseg pbr`,
/// ambientCG, MatSeg or MatSynth) stands for the colour maps of its
/// materials; anything else (a texture library, image files) for itself.
fn texture_sources(given: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut sources = Vec::new();
    for path in given {
        let materials = if path.is_dir() {
            find_materials(path).map_err(anyhow::Error::msg)?
        } else {
            Vec::new()
        };
        if materials.is_empty() {
            sources.push(path.clone());
        }
        for dir in materials {
            sources.extend(colour_map(&dir).map_err(anyhow::Error::msg)?);
        }
    }
    Ok(sources)
}

/// Photo and texture libraries from the given folders, or the bundled ones.
pub struct Libraries {
    pub photos: PhotoLibrary,
    pub textures: PhotoLibrary,
    scan_skipped: Vec<SkippedFile>,
}

impl Libraries {
    /// Scans `photos` and `textures` (the `defaults` when empty), keeps the
    /// files whose licence `licences` accepts, and prints a warning for each
    /// unreadable file.
    pub fn load(
        photos: &[PathBuf],
        textures: &[PathBuf],
        cache_mb: usize,
        defaults: Defaults,
        licences: &LicenceFilter,
    ) -> Result<Self> {
        let budget = cache_mb.saturating_mul(1 << 20);
        let (photos, r1) = PhotoLibrary::scan(&defaults.or(photos, "photos"), budget / 2)?;
        let photos = photos.retain_licences(licences)?;
        let textures = texture_sources(&defaults.or(textures, "textures"))?;
        let (textures, r2) = PhotoLibrary::scan(&textures, budget / 2)?;
        let textures = textures.retain_licences(licences)?;
        let scan_skipped: Vec<SkippedFile> = r1.skipped.into_iter().chain(r2.skipped).collect();
        for s in &scan_skipped {
            eprintln!("warning: skipped {}: {}", s.path.display(), s.reason);
        }
        Ok(Self {
            photos,
            textures,
            scan_skipped,
        })
    }

    /// The scene sources.
    pub fn sources(&self) -> matseg_scene::Sources<'_> {
        matseg_scene::Sources {
            photos: &self.photos,
            textures: &self.textures,
        }
    }

    /// Prints files that failed to decode during the run and the total count.
    pub fn report_skipped(&self) {
        let late: Vec<SkippedFile> = self
            .photos
            .failures()
            .into_iter()
            .chain(self.textures.failures())
            .collect();
        for s in &late {
            eprintln!("warning: skipped {}: {}", s.path.display(), s.reason);
        }
        let total = self.scan_skipped.len() + late.len();
        if total > 0 {
            eprintln!("warning: {total} unreadable source file(s) skipped");
        }
    }
}

/// The recipe from `--config` (defaults otherwise), with an optional size range.
pub fn load_recipe(config: Option<&Path>, size_range: Option<&str>) -> Result<Recipe2d> {
    let mut recipe = match config {
        Some(path) => Recipe2d::from_toml_file(path)?,
        None => Recipe2d::default(),
    };
    if let Some(range) = size_range {
        let (lo, hi) = parse_range(range).with_context(|| format!("--size-range {range}"))?;
        recipe.scene.size_min = lo;
        recipe.scene.size_max = hi;
        recipe.validate(&format!("--size-range {range}"))?;
    }
    Ok(recipe)
}

/// Parses `LO..HI` (inclusive) or a single `N`.
pub fn parse_range(text: &str) -> Result<(usize, usize)> {
    let parse = |s: &str| {
        s.trim()
            .parse::<usize>()
            .with_context(|| format!("'{s}' is not a whole number"))
    };
    match text.split_once("..") {
        Some((lo, hi)) => {
            let hi = hi.strip_prefix('=').unwrap_or(hi);
            let (lo, hi) = (parse(lo)?, parse(hi)?);
            if lo > hi {
                bail!("empty range: {lo} > {hi}");
            }
            Ok((lo, hi))
        }
        None => {
            let n = parse(text)?;
            Ok((n, n))
        }
    }
}

/// A progress bar with rate and ETA on stderr (hidden when not a terminal).
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {what} ({{per_sec}}, ETA {{eta}}) {{msg}}"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}

/// Sets the global rayon thread count when given.
pub fn init_threads(threads: Option<usize>) -> Result<()> {
    if let Some(t) = threads {
        if t == 0 {
            bail!("--threads must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_folders_with_dots_in_their_names_keep_their_own_partial_folder() {
        let root = std::env::temp_dir().join(format!("matseg-folders-{}", std::process::id()));
        let names = ["Terrain.winter__Town1__pbr0", "Terrain.winter__airport__pbr0"];
        for name in names {
            let dir = root.join(name);
            write_material_folder(
                &dir,
                "CC0",
                |partial| {
                    assert_eq!(partial, root.join(format!("{name}.partial")));
                    std::fs::write(partial.join("basecolor.png"), name)
                },
                serde_json::json!({ "name": name }),
            )
            .unwrap();
        }
        for name in names {
            let dir = root.join(name);
            assert_eq!(std::fs::read_to_string(dir.join("basecolor.png")).unwrap(), name);
            assert!(dir.join("material.json").is_file());
            assert!(!root.join(format!("{name}.partial")).exists());
        }
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn ranges_parse_and_reject_nonsense() {
        assert_eq!(parse_range("400..999").unwrap(), (400, 999));
        assert_eq!(parse_range("400..=999").unwrap(), (400, 999));
        assert_eq!(parse_range("512").unwrap(), (512, 512));
        assert!(parse_range("999..400").is_err());
        assert!(parse_range("a..b").is_err());
    }
}
