//! Reading PBR material folders in the namings found in the wild: ours and
//! ambientCG's (`Color`, `NormalGL`/`NormalDX`, `Roughness`, `Metalness`,
//! `Displacement`, `AmbientOcclusion`, `Opacity`, also as `NAME_1K_Color.jpg`),
//! MatSeg's (`OriginColor`, `Normal`, `Height`, `Metallic`, `Specular`) and
//! MatSynth's (`basecolor`, `diffuse`, `normal`, `height`, `displacement`,
//! `roughness`, `metallic`, `opacity`, `specular`); and writing our own
//! folders so that an interrupted write is never taken for a material.

use crate::pbr::MapKind;
use image::{GrayImage, RgbImage};
use matseg_image::outputs;
use std::path::{Path, PathBuf};

/// What went wrong reading or writing a material folder; the message names
/// the folder or file.
#[derive(Debug, thiserror::Error)]
pub enum MaterialError {
    /// A folder could not be listed.
    #[error("{}: cannot list: {source}", path.display())]
    List {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A material folder without a colour map.
    #[error("{}: no colour map (Color, basecolor, OriginColor, ...)", dir.display())]
    NoColourMap {
        /// The folder.
        dir: PathBuf,
    },
    /// A map that does not decode.
    #[error(transparent)]
    Image(#[from] matseg_image::ImageIoError),
    /// A folder or file that could not be written.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The folder or file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Fewer materials than a mix needs.
    #[error("mixing needs two materials or more; {0} given")]
    TooFewToMix(usize),
    /// A mix recipe value out of its range.
    #[error("mix recipe: {0}")]
    MixRecipe(#[from] crate::OutOfRange),
    /// A library folder, or a name in it, that is not matseg's to write.
    #[error(transparent)]
    Output(#[from] matseg_image::outputs::OutputError),
}

/// The maps of one material; only the colour is required.
#[derive(Clone, Debug)]
pub struct MaterialMaps {
    /// The folder it was read from.
    pub dir: PathBuf,
    /// Base colour (sRGB).
    pub colour: RgbImage,
    /// Normals, OpenGL convention (DirectX normals are converted).
    pub normal: Option<RgbImage>,
    /// Height / displacement.
    pub height: Option<GrayImage>,
    /// Roughness.
    pub roughness: Option<GrayImage>,
    /// Metalness.
    pub metalness: Option<GrayImage>,
    /// Ambient occlusion.
    pub ambient_occlusion: Option<GrayImage>,
    /// Opacity.
    pub opacity: Option<GrayImage>,
    /// Specular level.
    pub specular: Option<GrayImage>,
}

/// What a file holds, from its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Colour,
    NormalGl,
    NormalDx,
    Scalar(MapKind),
}

/// The role of a map file from its stem: the whole stem, or the part after
/// the last underscore (`Bricks076_1K_Color`), case-insensitive.
fn role(stem: &str) -> Option<Role> {
    let lower = stem.to_lowercase();
    let token = lower.rsplit('_').next().unwrap_or(&lower);
    [lower.as_str(), token].iter().find_map(|name| {
        Some(match *name {
            "color" | "basecolor" | "albedo" | "diffuse" | "origincolor" => Role::Colour,
            "normalgl" | "normal" => Role::NormalGl,
            "normaldx" => Role::NormalDx,
            "displacement" | "height" => Role::Scalar(MapKind::Height),
            "roughness" => Role::Scalar(MapKind::Roughness),
            "metalness" | "metallic" => Role::Scalar(MapKind::Metalness),
            "ambientocclusion" | "ao" | "occlusion" => Role::Scalar(MapKind::AmbientOcclusion),
            "opacity" | "alpha" => Role::Scalar(MapKind::Opacity),
            "specular" => Role::Scalar(MapKind::Specular),
            _ => return None,
        })
    })
}

/// The image files of a material folder, sorted.
fn map_files(dir: &Path) -> Result<Vec<PathBuf>, MaterialError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| MaterialError::List {
            path: dir.to_path_buf(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| matseg_image::io::has_image_extension(p))
        .collect();
    files.sort();
    Ok(files)
}

/// The first of `files` named for `wanted`.
fn find_role(files: &[PathBuf], wanted: Role) -> Option<&PathBuf> {
    files.iter().find(|p| {
        p.file_stem()
            .and_then(|s| s.to_str())
            .and_then(role)
            .is_some_and(|r| r == wanted)
    })
}

/// The colour map of the material in `dir`, if it has one.
pub fn colour_map(dir: &Path) -> Result<Option<PathBuf>, MaterialError> {
    Ok(find_role(&map_files(dir)?, Role::Colour).cloned())
}

/// Reads the material in `dir`. An error names the folder (no colour map)
/// or the file (unreadable).
pub fn read_material(dir: &Path) -> Result<MaterialMaps, MaterialError> {
    let files = map_files(dir)?;
    let find = |wanted: Role| find_role(&files, wanted);
    let open = |p: &PathBuf| matseg_image::io::read_image(p).map_err(MaterialError::Image);
    let grey = |kind: MapKind| -> Result<Option<GrayImage>, MaterialError> {
        find(Role::Scalar(kind))
            .map(|p| open(p).map(|i| i.to_luma8()))
            .transpose()
    };
    let colour = find(Role::Colour)
        .ok_or_else(|| MaterialError::NoColourMap {
            dir: dir.to_path_buf(),
        })
        .and_then(|p| open(p).map(|i| i.to_rgb8()))?;
    let normal = match (find(Role::NormalGl), find(Role::NormalDx)) {
        (Some(p), _) => Some(open(p)?.to_rgb8()),
        (None, Some(p)) => {
            // DirectX normals point y down: flip green for OpenGL.
            let mut n = open(p)?.to_rgb8();
            n.pixels_mut().for_each(|px| px.0[1] = 255 - px.0[1]);
            Some(n)
        }
        (None, None) => None,
    };
    Ok(MaterialMaps {
        dir: dir.to_path_buf(),
        colour,
        normal,
        height: grey(MapKind::Height)?,
        roughness: grey(MapKind::Roughness)?,
        metalness: grey(MapKind::Metalness)?,
        ambient_occlusion: grey(MapKind::AmbientOcclusion)?,
        opacity: grey(MapKind::Opacity)?,
        specular: grey(MapKind::Specular)?,
    })
}

/// Every material folder below `root` (a folder holding a colour map),
/// sorted by path.
pub fn find_materials(root: &Path) -> Result<Vec<PathBuf>, MaterialError> {
    let mut found = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let entries = std::fs::read_dir(&dir).map_err(|source| MaterialError::List {
            path: dir.clone(),
            source,
        })?;
        let mut has_colour = false;
        for entry in entries.filter_map(|e| e.ok()) {
            let path = entry.path();
            if path.is_dir() {
                if !is_partial(&path) {
                    stack.push(path);
                }
            } else if matseg_image::io::has_image_extension(&path)
                && path.file_stem().and_then(|s| s.to_str()).and_then(role) == Some(Role::Colour)
            {
                has_colour = true;
            }
        }
        if has_colour {
            found.push(dir);
        }
    }
    found.sort();
    Ok(found)
}

/// Writes a material folder for `command` (`pbr`, `pbr-mix`):
/// `write_maps` fills `DIR.partial.PID/` (made with matseg's marker), then
/// a `licenses.json` giving every file `licence` and `material.json` (the
/// `record` object plus the licence, the colour spaces and the normal
/// convention) go beside the maps, and the folder is renamed to `dir`: a
/// folder with `material.json` is complete, and an incomplete one is
/// redone when it holds nothing but a material's files
/// ([`is_material_folder`]); anything else there is refused, never
/// removed. Processes writing the same library at once do not clash: each
/// has its own partial folders, and the first complete folder stands.
pub fn write_material_folder(
    dir: &Path,
    command: &str,
    licence: &str,
    write_maps: impl FnOnce(&Path) -> std::io::Result<()>,
    mut record: serde_json::Value,
) -> Result<(), MaterialError> {
    // `NAME.partial.PID` beside `dir`, appended rather than swapped for an
    // extension: material names hold dots (`Terrain.winter__Town1`), and
    // two such names must not share one partial folder when written in
    // parallel; nor must two processes making the same library (jobs of a
    // cluster starting on one cache) share one.
    let mut partial_name = dir.file_name().unwrap_or_default().to_os_string();
    partial_name.push(format!("{PARTIAL_SUFFIX}.{}", std::process::id()));
    let partial = dir.with_file_name(partial_name);
    let failed = |path: &Path| {
        let path = path.to_path_buf();
        move |source| MaterialError::Write { path, source }
    };
    if dir.exists() && !is_material_folder(dir) {
        return Err(foreign(dir).into());
    }
    outputs::stage_folder(&partial, command)?;
    record["licence"] = licence.into();
    record["color_space"] = serde_json::json!({"Color": "sRGB", "other maps": "linear"});
    record["normal_convention"] = "OpenGL (+Y up)".into();
    let json = serde_json::to_vec_pretty(&record).expect("a JSON value serialises");
    let written = write_maps(&partial)
        .and_then(|()| {
            let licences = serde_json::json!({ "*": licence }).to_string();
            std::fs::write(partial.join("licenses.json"), licences)?;
            std::fs::write(partial.join(MATERIAL_RECORD), json)
        })
        .map_err(failed(&partial));
    if let Err(e) = written.and_then(|()| Ok(outputs::unmark(&partial)?)) {
        let _ = std::fs::remove_dir_all(&partial);
        return Err(e);
    }
    // The rename completes the folder. A complete one already there was
    // made by another process from the same inputs: it stands.
    if dir.join(MATERIAL_RECORD).is_file() {
        return std::fs::remove_dir_all(&partial).map_err(failed(&partial));
    }
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(failed(dir))?;
    }
    match std::fs::rename(&partial, dir) {
        Err(_) if dir.join(MATERIAL_RECORD).is_file() => {
            std::fs::remove_dir_all(&partial).map_err(failed(&partial))
        }
        renamed => renamed.map_err(failed(dir)),
    }
}

/// Whether `dir` is a folder holding nothing but a material's files (its
/// maps, `licenses.json`, `material.json`): one a material library's
/// command wrote, whole or in part, as far as names tell.
pub fn is_material_folder(dir: &Path) -> bool {
    outputs::holds_only(dir, &|name| {
        name == MATERIAL_RECORD
            || name == "licenses.json"
            || matseg_image::io::has_image_extension(Path::new(name))
    })
}

/// Whether `path`, an entry of a material library, is one the library's
/// `command` writes: a material folder ([`is_material_folder`]) or a
/// staging folder of its own (with matseg's marker).
pub fn is_library_entry(path: &Path, command: &str) -> bool {
    is_material_folder(path) || (is_partial(path) && outputs::is_marked(path, command))
}

/// The refusal of a material folder that holds what no material has.
fn foreign(dir: &Path) -> outputs::OutputError {
    outputs::OutputError::new(
        dir,
        "holds files that are not a material's and was not made by matseg: move it or choose another --out",
    )
}

/// The record a complete material folder holds (written inside the
/// partial folder, so a folder with this name is complete).
pub const MATERIAL_RECORD: &str = "material.json";

/// What a folder being written is named after: `NAME.partial.PID`. Such
/// folders are never materials.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// Whether `dir` is a folder being written (or left by an interrupted
/// writer), not a material.
fn is_partial(dir: &Path) -> bool {
    dir.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.contains(&format!("{PARTIAL_SUFFIX}.")) || n.ends_with(PARTIAL_SUFFIX))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_folders_with_dots_in_their_names_keep_their_own_partial_folder() {
        let root = tempfile::tempdir().unwrap();
        let names = [
            "Terrain.winter__Town1__pbr0",
            "Terrain.winter__airport__pbr0",
        ];
        for name in names {
            write_material_folder(
                &root.path().join(name),
                "pbr",
                "CC0",
                |partial| {
                    let own = format!("{name}.partial.{}", std::process::id());
                    assert_eq!(partial, root.path().join(own));
                    std::fs::write(partial.join("Color.png"), name)
                },
                serde_json::json!({ "name": name }),
            )
            .unwrap();
        }
        for name in names {
            let dir = root.path().join(name);
            assert_eq!(
                std::fs::read_to_string(dir.join("Color.png")).unwrap(),
                name
            );
            let record: serde_json::Value =
                serde_json::from_slice(&std::fs::read(dir.join("material.json")).unwrap()).unwrap();
            assert_eq!(record["name"], name);
            assert_eq!(record["licence"], "CC0");
            let left: Vec<_> = std::fs::read_dir(root.path())
                .unwrap()
                .filter_map(|e| e.ok())
                .filter(|e| is_partial(&e.path()))
                .collect();
            assert!(left.is_empty(), "partial folders left: {left:?}");
        }
    }

    #[test]
    fn a_folder_another_writer_completed_stands_and_partials_are_no_materials() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("brick");
        let write = |text: &'static str| {
            write_material_folder(
                &dir,
                "pbr",
                "CC0",
                move |p| std::fs::write(p.join("Color.png"), text),
                serde_json::json!({"name": "brick"}),
            )
        };
        write("first").unwrap();
        // A second writer of the same material (another process, the same
        // inputs) leaves the complete folder as it is.
        write("second").unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("Color.png")).unwrap(),
            "first"
        );
        // An interrupted writer's folder is not taken for a material.
        let stale = root.path().join("tile.partial.12345");
        std::fs::create_dir_all(&stale).unwrap();
        std::fs::write(stale.join("Color.png"), "x").unwrap();
        assert_eq!(find_materials(root.path()).unwrap(), vec![dir]);
    }

    #[test]
    fn a_folder_of_a_materials_name_is_replaced_only_when_it_holds_a_materials_files() {
        let root = tempfile::tempdir().unwrap();
        let write = |dir: &Path| {
            write_material_folder(
                dir,
                "pbr",
                "CC0",
                |p| std::fs::write(p.join("Color.png"), "new"),
                serde_json::json!({}),
            )
        };
        // An incomplete material (no material.json): redone.
        let half = root.path().join("brick__pbr0");
        std::fs::create_dir(&half).unwrap();
        std::fs::write(half.join("Color.png"), "half").unwrap();
        write(&half).unwrap();
        assert_eq!(
            std::fs::read_to_string(half.join("Color.png")).unwrap(),
            "new"
        );
        // Someone's folder of that name: refused, kept as it was.
        let mine = root.path().join("tile__pbr0");
        std::fs::create_dir(&mine).unwrap();
        std::fs::write(mine.join("notes.txt"), "mine").unwrap();
        let e = write(&mine).unwrap_err().to_string();
        assert!(e.contains("tile__pbr0"), "{e}");
        assert_eq!(
            std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
            "mine"
        );
        assert!(!is_library_entry(&mine, "pbr"));
        assert!(is_library_entry(&half, "pbr"));
    }

    #[test]
    fn names_map_to_roles_in_every_convention() {
        for (stem, want) in [
            ("Color", Role::Colour),
            ("Bricks076_1K_Color", Role::Colour),
            ("basecolor", Role::Colour),
            ("OriginColor", Role::Colour),
            ("NormalGL", Role::NormalGl),
            ("Rock_2K_NormalDX", Role::NormalDx),
            ("Normal", Role::NormalGl),
            ("Height", Role::Scalar(MapKind::Height)),
            ("Displacement", Role::Scalar(MapKind::Height)),
            ("Metallic", Role::Scalar(MapKind::Metalness)),
            ("Metalness", Role::Scalar(MapKind::Metalness)),
            ("AmbientOcclusion", Role::Scalar(MapKind::AmbientOcclusion)),
            ("specular", Role::Scalar(MapKind::Specular)),
            ("opacity", Role::Scalar(MapKind::Opacity)),
        ] {
            assert_eq!(role(stem), Some(want), "{stem}");
        }
        assert_eq!(role("preview"), None);
    }
}
