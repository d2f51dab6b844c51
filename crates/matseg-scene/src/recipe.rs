//! The 2D recipe: every probability and range of pipeline.md §1 and §2 as a
//! named field with the paper's value as default, overridable from TOML.

use matseg_extract::{check_probabilities, SoftMapRecipe};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Scene-level draws (pipeline.md §1, last paragraph).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneDraws {
    /// Smallest scene side; width and height are drawn independently.
    pub size_min: usize,
    /// Largest scene side (inclusive).
    pub size_max: usize,
    /// Fewest materials per scene.
    pub materials_min: usize,
    /// Most materials per scene (inclusive).
    pub materials_max: usize,
    /// Probability of a hard (one-hot) scene.
    pub p_hard: f64,
    /// `max_occupancy = occupancy_base + occupancy_span * U * U` ...
    pub occupancy_base: f64,
    /// ... (see `occupancy_base`).
    pub occupancy_span: f64,
    /// ... except, with this probability, `max_occupancy = fixed_occupancy`.
    pub p_fixed_occupancy: f64,
    /// See `p_fixed_occupancy`.
    pub fixed_occupancy: f64,
}

/// The scene-level draws of one 2D scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneShape {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Number of materials, K.
    pub materials: usize,
    /// One-hot annotation.
    pub hard: bool,
    /// Largest fraction of the scene one map's top side may cover.
    pub max_occupancy: f64,
}

impl SceneDraws {
    /// Draws size, K, hardness and occupancy, in that order.
    pub fn draw<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> SceneShape {
        let width = rng.random_range(self.size_min..=self.size_max);
        let height = rng.random_range(self.size_min..=self.size_max);
        let materials = rng.random_range(self.materials_min..=self.materials_max);
        let hard = rng.random_bool(self.p_hard);
        let max_occupancy = self.draw_max_occupancy(rng);
        SceneShape {
            width,
            height,
            materials,
            hard,
            max_occupancy,
        }
    }

    /// The mean number of pixels of a drawn scene: width and height are
    /// independent and uniform, so it is the square of the mean side.
    pub fn mean_pixels(&self) -> f64 {
        let side = (self.size_min + self.size_max) as f64 / 2.0;
        side * side
    }

    /// The mean number of materials of a drawn scene.
    pub fn mean_materials(&self) -> f64 {
        (self.materials_min + self.materials_max) as f64 / 2.0
    }

    /// Draws a scene's `max_occupancy`: the largest fraction of the scene
    /// the top side of one map may cover.
    pub fn draw_max_occupancy<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        let drawn =
            self.occupancy_base + self.occupancy_span * rng.random::<f64>() * rng.random::<f64>();
        if rng.random_bool(self.p_fixed_occupancy) {
            self.fixed_occupancy
        } else {
            drawn
        }
    }
}

impl Default for SceneDraws {
    fn default() -> Self {
        Self {
            size_min: 400,
            size_max: 999,
            materials_min: 1,
            materials_max: 10,
            p_hard: 0.55,
            occupancy_base: 0.04,
            occupancy_span: 0.5,
            p_fixed_occupancy: 0.1,
            fixed_occupancy: 0.1,
        }
    }
}

/// How materials and the background are drawn and composed (pipeline.md §2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompositionRecipe {
    /// Probability of shrinking the background photo by a random ratio
    /// (otherwise it is scaled so its short side fits the scene).
    pub p_background_downscale: f64,
    /// Probability that a material is a texture (otherwise a flat colour).
    pub p_texture: f64,
    /// Probability of rotating a texture by 90 degrees.
    pub p_rot90: f64,
    /// Probability of mirroring a texture left-right.
    pub p_flip_x: f64,
    /// Probability of mirroring a texture top-bottom.
    pub p_flip_y: f64,
    /// Probability of tiling a texture (otherwise it is stretched over the
    /// scene, keeping its aspect ratio, and cropped).
    pub p_tile: f64,
    /// Probability of shrinking a tiled texture first, by r ~ U(1, min side / `min_tile_side`).
    pub p_tile_shrink: f64,
    /// Smallest tile side that shrinking may produce.
    pub min_tile_side: f64,
    /// Probability of rotating a texture's hue by a random angle.
    pub p_hue_shift: f64,
    /// Probability of shadow-like shading on a material.
    pub p_shading: f64,
    /// Probability that the shading channel is H, S or V (otherwise R, G or B).
    pub p_shading_hsv: f64,
    /// Probability of shrinking the shading photo before cropping.
    pub p_shading_downscale: f64,
    /// Gaussian kernel sizes for the shading blur.
    pub shading_kernels: Vec<usize>,
    /// Probability of full-strength shading (otherwise strength ~ U(0, 1)).
    pub p_shading_full_strength: f64,
}

impl Default for CompositionRecipe {
    fn default() -> Self {
        Self {
            p_background_downscale: 0.5,
            p_texture: 0.91,
            p_rot90: 0.5,
            p_flip_x: 0.5,
            p_flip_y: 0.5,
            p_tile: 0.75,
            p_tile_shrink: 0.6,
            min_tile_side: 100.0,
            p_hue_shift: 0.12,
            p_shading: 0.75,
            p_shading_hsv: 0.4,
            p_shading_downscale: 0.3,
            shading_kernels: (5..=21).step_by(2).collect(),
            p_shading_full_strength: 0.5,
        }
    }
}

/// Everything that decides a 2D scene, besides the seed and the sources.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Recipe2d {
    /// Scene size, material count, hardness, occupancy.
    pub scene: SceneDraws,
    /// Soft map drawing (pipeline.md §1).
    pub maps: SoftMapRecipe,
    /// Background, textures and shading (pipeline.md §2).
    pub composition: CompositionRecipe,
}

/// A recipe file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum RecipeError {
    /// Unreadable file.
    #[error("{}: cannot read: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// Not valid TOML for a recipe or a camera path (unknown key, wrong
    /// type...), at a line and column of the file.
    #[error("{}:{line}:{column}: invalid {what}: {reason}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the file was read as (`recipe`, `camera path`).
        what: &'static str,
        /// The line at fault, from 1.
        line: usize,
        /// The column at fault, from 1.
        column: usize,
        /// The parser's message, on one line.
        reason: String,
    },
    /// Values out of range.
    #[error("{origin}: invalid recipe: {reason}")]
    Invalid {
        /// Where the recipe came from.
        origin: String,
        /// What is wrong.
        reason: String,
    },
}

/// Largest scene side accepted (memory per scene grows with its area).
pub const MAX_SCENE_SIDE: usize = 8192;

impl Recipe2d {
    /// Reads a TOML recipe; keys left out keep their defaults.
    pub fn from_toml_file(path: &Path) -> Result<Self, RecipeError> {
        let recipe: Self = read_toml(path, "recipe")?;
        recipe.validate(&path.display().to_string())?;
        Ok(recipe)
    }

    /// Checks every range; `origin` names the recipe in the error.
    pub fn validate(&self, origin: &str) -> Result<(), RecipeError> {
        let invalid = |reason: String| RecipeError::Invalid {
            origin: origin.to_string(),
            reason,
        };
        let s = &self.scene;
        if s.size_min < 16 || s.size_min > s.size_max || s.size_max > MAX_SCENE_SIDE {
            return Err(invalid(format!(
                "scene size range {}..{} must satisfy 16 <= min <= max <= {MAX_SCENE_SIDE}",
                s.size_min, s.size_max
            )));
        }
        if s.materials_min < 1
            || s.materials_min > s.materials_max
            || s.materials_max > PALETTE_LIMIT
        {
            return Err(invalid(format!(
                "material count range {}..{} must satisfy 1 <= min <= max <= {PALETTE_LIMIT}",
                s.materials_min, s.materials_max
            )));
        }
        let c = &self.composition;
        check_probabilities(&[
            ("scene.p_hard", s.p_hard),
            ("scene.p_fixed_occupancy", s.p_fixed_occupancy),
            (
                "composition.p_background_downscale",
                c.p_background_downscale,
            ),
            ("composition.p_texture", c.p_texture),
            ("composition.p_rot90", c.p_rot90),
            ("composition.p_flip_x", c.p_flip_x),
            ("composition.p_flip_y", c.p_flip_y),
            ("composition.p_tile", c.p_tile),
            ("composition.p_tile_shrink", c.p_tile_shrink),
            ("composition.p_hue_shift", c.p_hue_shift),
            ("composition.p_shading", c.p_shading),
            ("composition.p_shading_hsv", c.p_shading_hsv),
            ("composition.p_shading_downscale", c.p_shading_downscale),
            (
                "composition.p_shading_full_strength",
                c.p_shading_full_strength,
            ),
        ])
        .map_err(|e| invalid(e.0))?;
        let occ_max = s.occupancy_base + s.occupancy_span;
        if s.occupancy_base <= 0.0
            || s.occupancy_span < 0.0
            || occ_max > 1.0
            || !(0.0..=1.0).contains(&s.fixed_occupancy)
        {
            return Err(invalid("occupancy must stay within (0, 1]".into()));
        }
        if c.min_tile_side < 1.0 {
            return Err(invalid(
                "composition.min_tile_side must be at least 1".into(),
            ));
        }
        if c.shading_kernels.is_empty() || c.shading_kernels.iter().any(|k| k % 2 == 0) {
            return Err(invalid(
                "composition.shading_kernels must be a non-empty list of odd sizes".into(),
            ));
        }
        self.maps
            .validate()
            .map_err(|reason| invalid(format!("maps: {reason}")))
    }
}

/// Most materials a scene may have (one palette colour each in previews).
pub const PALETTE_LIMIT: usize = crate::annotation::PALETTE.len();

/// A recipe of any kind from a TOML file; errors name the file.
pub(crate) fn read_toml<T: serde::de::DeserializeOwned + serde::Serialize>(
    path: &Path,
    what: &'static str,
) -> Result<T, RecipeError> {
    let text = std::fs::read_to_string(path).map_err(|e| RecipeError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let parse_error = |e: toml::de::Error| {
        let (line, column) = line_and_column(&text, e.span().map_or(0, |s| s.start));
        RecipeError::Parse {
            path: path.to_path_buf(),
            what,
            line,
            column,
            reason: e.message().replace('\n', " "),
        }
    };
    let read: T = toml::from_str(&text).map_err(parse_error)?;
    // What was read, as the settings hold it (a number too large for its
    // setting's precision is infinite there).
    let held = toml::Table::try_from(&read).ok();
    if let Some(key) = held.as_ref().and_then(|t| non_finite(t, "")) {
        return Err(RecipeError::Invalid {
            origin: path.display().to_string(),
            reason: format!("{key}: not a finite number (nan, inf, or too large)"),
        });
    }
    Ok(read)
}

/// The key of the first NaN or infinite number in `table` (TOML allows
/// them; no setting means them), as `section.key`.
fn non_finite(table: &toml::Table, prefix: &str) -> Option<String> {
    table.iter().find_map(|(key, value)| {
        let key = format!("{prefix}{key}");
        match value {
            toml::Value::Float(f) if !f.is_finite() => Some(format!("{key} = {f}")),
            toml::Value::Table(inner) => non_finite(inner, &format!("{key}.")),
            toml::Value::Array(items) => items.iter().find_map(|item| match item {
                toml::Value::Float(f) if !f.is_finite() => Some(format!("{key} = [.. {f} ..]")),
                toml::Value::Table(inner) => non_finite(inner, &format!("{key}.")),
                _ => None,
            }),
            _ => None,
        }
    })
}

/// The line and column (from 1, columns in characters) of byte `offset`
/// of `text`.
fn line_and_column(text: &str, offset: usize) -> (usize, usize) {
    let mut end = offset.min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let before = &text[..end];
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (
        before.matches('\n').count() + 1,
        before[line_start..].chars().count() + 1,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_spec_values_and_valid() {
        let r = Recipe2d::default();
        r.validate("default").unwrap();
        assert_eq!((r.scene.size_min, r.scene.size_max), (400, 999));
        assert_eq!((r.scene.materials_min, r.scene.materials_max), (1, 10));
        assert_eq!(r.scene.p_hard, 0.55);
        assert_eq!(
            r.composition.shading_kernels,
            vec![5, 7, 9, 11, 13, 15, 17, 19, 21]
        );
        assert_eq!(r.maps.blur_kernels, vec![3, 5, 7, 9]);
    }

    /// The distribution's means equal the means over every equally likely
    /// draw (each side and K uniform on their ranges, sides independent),
    /// for the paper's ranges and a small recipe's.
    #[test]
    fn mean_pixels_and_materials_are_the_draws_means() {
        let small = SceneDraws {
            size_min: 3,
            size_max: 6,
            materials_min: 2,
            materials_max: 2,
            ..SceneDraws::default()
        };
        for d in [SceneDraws::default(), small] {
            let sides = d.size_min..=d.size_max;
            let n = sides.clone().count() as f64;
            let pixels: f64 = sides
                .clone()
                .flat_map(|w| sides.clone().map(move |h| (w * h) as f64))
                .sum::<f64>()
                / (n * n);
            assert_eq!(d.mean_pixels(), pixels);
            let ks = d.materials_min..=d.materials_max;
            let k = ks.clone().sum::<usize>() as f64 / ks.count() as f64;
            assert_eq!(d.mean_materials(), k);
        }
        assert_eq!(SceneDraws::default().mean_pixels(), 699.5 * 699.5);
    }

    #[test]
    fn toml_overrides_keep_other_defaults_and_errors_name_the_file() {
        let dir = tempdir();
        let ok = dir.join("ok.toml");
        std::fs::write(
            &ok,
            "[scene]\nsize_min = 64\nsize_max = 128\n[maps]\np_blur = 0.0\n",
        )
        .unwrap();
        let r = Recipe2d::from_toml_file(&ok).unwrap();
        assert_eq!(
            (r.scene.size_min, r.scene.size_max, r.maps.p_blur),
            (64, 128, 0.0)
        );
        assert_eq!(r.scene.p_hard, 0.55);

        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "[scene]\nsize_mni = 64\n").unwrap();
        let err = Recipe2d::from_toml_file(&bad).unwrap_err().to_string();
        assert!(
            err.starts_with(&format!(
                "{}:2:1: invalid recipe: unknown field",
                bad.display()
            )),
            "{err}"
        );
        assert!(!err.contains('\n'));

        let range = dir.join("range.toml");
        std::fs::write(&range, "[composition]\np_tile = 1.5\n").unwrap();
        let err = Recipe2d::from_toml_file(&range).unwrap_err().to_string();
        assert!(
            err.contains("composition.p_tile = 1.5 is not a probability"),
            "{err}"
        );
    }

    fn tempdir() -> PathBuf {
        let dir = std::env::temp_dir().join(format!("matseg-recipe-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }
}
