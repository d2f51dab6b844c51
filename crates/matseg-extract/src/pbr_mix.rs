//! New PBR materials by mixing existing ones (pipeline.md §5, mixing): 2 sources
//! with p = 0.5, 3 with 0.25, ...; one weight per source for all maps
//! ("equal"), the per-pixel maximum ("max"), or a weight per source per map
//! ("flexible"). Weights sum to 1; mixed normals are renormalised.

use crate::material_library::{MaterialError, MaterialMaps};
use crate::pbr::{decode_normal, encode_normal};
use crate::soft_maps::{check_probabilities, OutOfRange};
use image::{GrayImage, RgbImage};
use matseg_image::io::{encode_png_grey, encode_png_rgb};
use matseg_image::plane::round_to_u8;
use rand::seq::index::sample;
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Probabilities of mixing, with the paper's values as defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MixRecipe {
    /// Probability of adding one more source after the first two (repeated).
    pub p_more_sources: f64,
    /// Most sources in one mix.
    pub max_sources: usize,
    /// Probability of the "equal" mode.
    pub p_equal: f64,
    /// Probability of the "max" mode (otherwise "flexible").
    pub p_max: f64,
}

impl Default for MixRecipe {
    fn default() -> Self {
        Self {
            p_more_sources: 0.5,
            max_sources: 6,
            p_equal: 0.28,
            p_max: 0.27,
        }
    }
}

/// How maps are combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MixMode {
    /// One weight per source, the same for every map.
    Equal,
    /// The per-pixel maximum of the sources (normals: mean of the sources).
    Max,
    /// A weight per source for each map.
    Flexible,
}

/// The maps every mixed material has, in this order.
pub const MIXED_MAPS: [&str; 8] = [
    "Color",
    "NormalGL",
    "Displacement",
    "Roughness",
    "Metalness",
    "AmbientOcclusion",
    "Opacity",
    "Specular",
];

/// How a mix was made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MixRecord {
    /// Indices of the sources in the list given.
    pub sources: Vec<usize>,
    /// The mode.
    pub mode: MixMode,
    /// Per map (in [`MIXED_MAPS`] order), the weight of each source (empty for max).
    pub weights: Vec<Vec<f32>>,
}

/// A mixed material: every map present.
#[derive(Clone, Debug)]
pub struct MixedMaterial {
    /// Base colour (sRGB).
    pub colour: RgbImage,
    /// Normals, OpenGL convention.
    pub normal: RgbImage,
    /// Displacement, roughness, metalness, AO, opacity, specular.
    pub maps: [GrayImage; 6],
}

impl MixedMaterial {
    /// Writes the maps into `dir` with the names of [`MIXED_MAPS`], as PNG.
    pub fn write_maps(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::write(dir.join("Color.png"), encode_png_rgb(&self.colour))?;
        std::fs::write(dir.join("NormalGL.png"), encode_png_rgb(&self.normal))?;
        for (name, map) in MIXED_MAPS[2..].iter().zip(&self.maps) {
            let (w, h) = map.dimensions();
            std::fs::write(
                dir.join(format!("{name}.png")),
                encode_png_grey(w, h, map.as_raw()),
            )?;
        }
        Ok(())
    }
}

/// Values a missing map stands for: flat, mid roughness, not metal,
/// unoccluded, opaque, mid specular.
const DEFAULT_LEVELS: [u8; 6] = [0, 128, 0, 255, 255, 128];

impl MixRecipe {
    /// Checks ranges: probabilities in [0, 1] (the two modes' together too)
    /// and room for two sources; the message names the offending field.
    pub fn validate(&self) -> Result<(), OutOfRange> {
        check_probabilities(&[
            ("p_more_sources", self.p_more_sources),
            ("p_equal", self.p_equal),
            ("p_max", self.p_max),
            ("p_equal + p_max", self.p_equal + self.p_max),
        ])?;
        if self.max_sources < 2 {
            return Err(OutOfRange(format!(
                "max_sources = {} is below 2",
                self.max_sources
            )));
        }
        Ok(())
    }
}

/// Draws a mix of `library` materials: an error when there are fewer than
/// two, or the recipe is out of range.
pub fn mix_materials<R: Rng + ?Sized>(
    rng: &mut R,
    library: &[MaterialMaps],
    recipe: &MixRecipe,
) -> Result<(MixedMaterial, MixRecord), MaterialError> {
    recipe.validate()?;
    if library.len() < 2 {
        return Err(MaterialError::TooFewToMix(library.len()));
    }
    let mut count = 2;
    while count < recipe.max_sources.min(library.len()) && rng.random_bool(recipe.p_more_sources) {
        count += 1;
    }
    let sources: Vec<usize> = sample(rng, library.len(), count).into_vec();
    let mode = if rng.random_bool(recipe.p_equal) {
        MixMode::Equal
    } else if rng.random_bool(recipe.p_max / (1.0 - recipe.p_equal)) {
        MixMode::Max
    } else {
        MixMode::Flexible
    };
    let draw_weights = |rng: &mut R| {
        let w: Vec<f32> = (0..count).map(|_| rng.random::<f32>() + 1e-3).collect();
        let total: f32 = w.iter().sum();
        w.into_iter().map(|v| v / total).collect::<Vec<f32>>()
    };
    let weights: Vec<Vec<f32>> = match mode {
        MixMode::Equal => {
            let w = draw_weights(rng);
            vec![w; MIXED_MAPS.len()]
        }
        MixMode::Flexible => (0..MIXED_MAPS.len()).map(|_| draw_weights(rng)).collect(),
        MixMode::Max => Vec::new(),
    };
    let first = &library[sources[0]].colour;
    let (w, h) = first.dimensions();
    let members: Vec<&MaterialMaps> = sources.iter().map(|&i| &library[i]).collect();
    // Each source's channels as planes of the first source's size.
    let resize_rgb =
        |img: &RgbImage| image::imageops::resize(img, w, h, image::imageops::FilterType::Triangle);
    let resize_grey =
        |img: &GrayImage| image::imageops::resize(img, w, h, image::imageops::FilterType::Triangle);
    let colours: Vec<RgbImage> = members.iter().map(|m| resize_rgb(&m.colour)).collect();
    let normals: Vec<RgbImage> = members
        .iter()
        .map(|m| match &m.normal {
            Some(n) => resize_rgb(n),
            None => RgbImage::from_pixel(w, h, image::Rgb([128, 128, 255])),
        })
        .collect();
    let combine = |values: &[f32], map: usize| -> f32 {
        match mode {
            MixMode::Max => values.iter().copied().fold(f32::MIN, f32::max),
            _ => values.iter().zip(&weights[map]).map(|(v, w)| v * w).sum(),
        }
    };
    let colour = RgbImage::from_fn(w, h, |x, y| {
        image::Rgb(std::array::from_fn(|c| {
            let values: Vec<f32> = colours
                .iter()
                .map(|i| i.get_pixel(x, y).0[c] as f32)
                .collect();
            round_to_u8(combine(&values, 0))
        }))
    });
    let normal = RgbImage::from_fn(w, h, |x, y| {
        let mut n = [0f32; 3];
        for (k, img) in normals.iter().enumerate() {
            let weight = match mode {
                MixMode::Max => 1.0 / count as f32,
                _ => weights[1][k],
            };
            for (c, v) in n.iter_mut().enumerate() {
                *v += weight * decode_normal(img.get_pixel(x, y).0)[c];
            }
        }
        image::Rgb(encode_normal(n))
    });
    let maps: [GrayImage; 6] = std::array::from_fn(|k| {
        let planes: Vec<GrayImage> = members
            .iter()
            .map(|m| {
                let map = [
                    &m.height,
                    &m.roughness,
                    &m.metalness,
                    &m.ambient_occlusion,
                    &m.opacity,
                    &m.specular,
                ][k];
                match map {
                    Some(g) => resize_grey(g),
                    None => GrayImage::from_pixel(w, h, image::Luma([DEFAULT_LEVELS[k]])),
                }
            })
            .collect();
        GrayImage::from_fn(w, h, |x, y| {
            let values: Vec<f32> = planes
                .iter()
                .map(|p| p.get_pixel(x, y).0[0] as f32)
                .collect();
            image::Luma([round_to_u8(combine(&values, k + 2))])
        })
    });
    Ok((
        MixedMaterial {
            colour,
            normal,
            maps,
        },
        MixRecord {
            sources,
            mode,
            weights,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn flat(level: u8, normal: [u8; 3]) -> MaterialMaps {
        MaterialMaps {
            dir: "mem".into(),
            colour: RgbImage::from_pixel(4, 3, image::Rgb([level; 3])),
            normal: Some(RgbImage::from_pixel(4, 3, image::Rgb(normal))),
            height: Some(GrayImage::from_pixel(4, 3, image::Luma([level]))),
            roughness: None,
            metalness: None,
            ambient_occlusion: None,
            opacity: None,
            specular: None,
        }
    }

    #[test]
    fn too_few_materials_and_bad_recipes_are_errors_not_panics() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let one = vec![flat(0, [128, 128, 255])];
        let error = mix_materials(&mut rng, &one, &MixRecipe::default()).unwrap_err();
        assert_eq!(
            error.to_string(),
            "mixing needs two materials or more; 1 given"
        );
        let two = vec![flat(0, [128, 128, 255]), flat(200, [255, 128, 128])];
        let greedy = MixRecipe {
            p_equal: 0.75,
            p_max: 0.5,
            ..MixRecipe::default()
        };
        let error = mix_materials(&mut rng, &two, &greedy).unwrap_err();
        assert_eq!(
            error.to_string(),
            "mix recipe: p_equal + p_max = 1.25 is not a probability in [0, 1]"
        );
        assert!(mix_materials(&mut rng, &two, &MixRecipe::default()).is_ok());
    }

    #[test]
    fn mixes_weigh_sources_by_their_mode_and_keep_normals_unit() {
        let library = vec![
            flat(0, [128, 128, 255]),
            flat(200, [255, 128, 128]),
            flat(100, [128, 255, 128]),
        ];
        let mut seen = [false; 3];
        for seed in 0..60 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let (m, record) = mix_materials(&mut rng, &library, &MixRecipe::default()).unwrap();
            seen[record.mode as usize] = true;
            let levels: Vec<f32> = record
                .sources
                .iter()
                .map(|&i| [0.0, 200.0, 100.0][i])
                .collect();
            let got = m.colour.get_pixel(0, 0).0[0] as f32;
            match record.mode {
                MixMode::Max => assert_eq!(got, levels.iter().copied().fold(0.0, f32::max)),
                _ => {
                    for w in &record.weights {
                        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
                    }
                    let want: f32 = levels
                        .iter()
                        .zip(&record.weights[0])
                        .map(|(l, w)| l * w)
                        .sum();
                    assert!((got - want).abs() <= 0.5 + 1e-3, "{got} vs {want}");
                }
            }
            let n = m
                .normal
                .get_pixel(1, 1)
                .0
                .map(|c| c as f32 / 255.0 * 2.0 - 1.0);
            assert!(((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 0.02);
            // Missing maps stand for their defaults: roughness 128 everywhere.
            assert!(m.maps[1].pixels().all(|p| p.0[0] == 128));
        }
        assert_eq!(seen, [true; 3], "every mode should be drawn");
    }
}
