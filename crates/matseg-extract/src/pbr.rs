//! PBR materials guessed from one texture (pipeline.md §5): each property
//! map is a random image channel (or a constant), maybe inverted, blurred
//! and rescaled; normals come from the height map (OpenGL convention).

use image::{GrayImage, RgbImage};
use matseg_image::io::{encode_png_grey, encode_png_rgb};
use matseg_image::plane::round_to_u8;
use matseg_image::rgb::rotate_hue;
use matseg_image::{gaussian_blur, Plane};
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Every probability of PBR drawing, with the paper's values as defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PbrRecipe {
    /// Probability of rotating the texture's hue first.
    pub p_hue_rotation: f64,
    /// Probability of each of: a quarter turn, a left-right and a top-bottom mirror.
    pub p_turn_or_flip: f64,
    /// Probability that a map is a constant.
    pub p_constant: f64,
    /// Probability of inverting the roughness map.
    pub p_invert_roughness: f64,
    /// Probability of inverting any other map.
    pub p_invert: f64,
    /// Probability of blurring a map.
    pub p_blur: f64,
    /// Kernel sizes the blur draws from.
    pub blur_kernels: Vec<usize>,
    /// Probability of rescaling a map to a random range (height: always 0..255).
    pub p_rescale: f64,
    /// Probability of the "shiny" rule: metalness above `shiny_above` becomes
    /// 255 and the roughness there 0.
    pub p_shiny: f64,
    /// Metalness level above which a shiny material is metal.
    pub shiny_above: u8,
    /// Probability of the "non-metal" rule: metalness 0 everywhere.
    pub p_non_metal: f64,
    /// Probability of a normal strength of 16 U²; else 24 U² or 1, evenly.
    pub p_normal_16: f64,
}

impl Default for PbrRecipe {
    fn default() -> Self {
        Self {
            p_hue_rotation: 0.22,
            p_turn_or_flip: 0.5,
            p_constant: 0.14,
            p_invert_roughness: 0.6,
            p_invert: 0.3,
            p_blur: 0.11,
            blur_kernels: vec![3, 5, 7, 9],
            p_rescale: 0.8,
            p_shiny: 0.14,
            shiny_above: 160,
            p_non_metal: 0.1,
            p_normal_16: 0.76,
        }
    }
}

/// The scalar maps of a material, in drawing order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MapKind {
    /// Height (written as `Displacement`).
    Height,
    /// Roughness.
    Roughness,
    /// Metalness.
    Metalness,
    /// Ambient occlusion.
    AmbientOcclusion,
    /// Opacity.
    Opacity,
    /// Specular level.
    Specular,
}

impl MapKind {
    /// All kinds, in drawing order.
    pub const ALL: [MapKind; 6] = [
        MapKind::Height,
        MapKind::Roughness,
        MapKind::Metalness,
        MapKind::AmbientOcclusion,
        MapKind::Opacity,
        MapKind::Specular,
    ];

    /// The ambientCG-style file stem.
    pub fn file_stem(self) -> &'static str {
        match self {
            MapKind::Height => "Displacement",
            MapKind::Roughness => "Roughness",
            MapKind::Metalness => "Metalness",
            MapKind::AmbientOcclusion => "AmbientOcclusion",
            MapKind::Opacity => "Opacity",
            MapKind::Specular => "Specular",
        }
    }
}

/// Where a map's values come from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "source", rename_all = "snake_case")]
pub enum MapSource {
    /// One value everywhere.
    Constant {
        /// The value.
        value: u8,
    },
    /// The grey level (mean of R, G, B).
    Grey,
    /// An HSV component of the colour (0 = H, 1 = S, 2 = V).
    Hsv {
        /// Which component.
        component: usize,
    },
    /// A colour channel relative to the brightness, `c / (mean + 10)`.
    Relative {
        /// Which channel (0 = R, 1 = G, 2 = B).
        channel: usize,
    },
    /// A channel of a copy of the colour with its hue turned.
    TurnedChannel {
        /// The hue turn.
        degrees: f32,
        /// Which channel.
        channel: usize,
    },
}

/// How one map was made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PbrMapRecord {
    /// The map.
    pub kind: MapKind,
    /// Its values' source.
    #[serde(flatten)]
    pub source: MapSource,
    /// Inverted (255 - v).
    pub inverted: bool,
    /// Gaussian blur kernel, if blurred.
    pub blur: Option<usize>,
    /// Rescaled to this range, if it was.
    pub range: Option<(u8, u8)>,
}

/// How a material was made: enough to make it again from its texture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PbrRecord {
    /// Hue turn of the texture, if any.
    pub hue_degrees: Option<f32>,
    /// Quarter turn, left-right and top-bottom mirror of the texture.
    pub turned: [bool; 3],
    /// The maps.
    pub maps: Vec<PbrMapRecord>,
    /// The "shiny" rule was applied.
    pub shiny: bool,
    /// The "non-metal" rule was applied.
    pub non_metal: bool,
    /// Normal strength.
    pub normal_strength: f32,
    /// Made tileable by [`PbrMaterial::make_seamless`].
    #[serde(default)]
    pub seamless: bool,
}

/// A PBR material: base colour (sRGB), scalar maps (linear, 8-bit), normals.
#[derive(Clone, Debug)]
pub struct PbrMaterial {
    /// Base colour, sRGB.
    pub colour: RgbImage,
    /// The scalar maps, in [`MapKind::ALL`] order.
    pub maps: Vec<(MapKind, GrayImage)>,
    /// Tangent-space normals, OpenGL convention (green up), 0..255 encoding.
    pub normal: RgbImage,
    /// How it was made.
    pub record: PbrRecord,
}

impl PbrMaterial {
    /// Makes every map tileable, in two passes: each map is blended with a
    /// copy shifted by half its width, the copy taking over near the left
    /// and right edges (where it is continuous) and the original in the
    /// middle (where the copy's seam lies); then the same across the height.
    /// The same blend for all maps keeps them consistent; normals are
    /// renormalised.
    pub fn make_seamless(&mut self) {
        let (w, h) = self.colour.dimensions();
        for vertical in [false, true] {
            let n = if vertical { h } else { w };
            // 1 in the middle, 0 at the edges, linear over a quarter of the side.
            let keep = |x: u32, y: u32| {
                let i = if vertical { y } else { x };
                (i.min(n - 1 - i) as f32 / (n as f32 / 4.0).max(1.0)).min(1.0)
            };
            let shifted = |x: u32, y: u32| {
                if vertical {
                    (x, (y + h / 2) % h)
                } else {
                    ((x + w / 2) % w, y)
                }
            };
            let blend = |a: f32, b: f32, k: f32| a * k + b * (1.0 - k);
            let colour = self.colour.clone();
            for (x, y, px) in self.colour.enumerate_pixels_mut() {
                let (sx, sy) = shifted(x, y);
                let other = colour.get_pixel(sx, sy).0;
                let k = keep(x, y);
                px.0 =
                    std::array::from_fn(|c| round_to_u8(blend(px.0[c] as f32, other[c] as f32, k)));
            }
            for (_, map) in &mut self.maps {
                let original = map.clone();
                for (x, y, px) in map.enumerate_pixels_mut() {
                    let (sx, sy) = shifted(x, y);
                    let other = original.get_pixel(sx, sy).0[0] as f32;
                    px.0[0] = round_to_u8(blend(px.0[0] as f32, other, keep(x, y)));
                }
            }
            let normal = self.normal.clone();
            for (x, y, px) in self.normal.enumerate_pixels_mut() {
                let (sx, sy) = shifted(x, y);
                let (a, b) = (
                    decode_normal(px.0),
                    decode_normal(normal.get_pixel(sx, sy).0),
                );
                let k = keep(x, y);
                px.0 = encode_normal(std::array::from_fn(|c| blend(a[c], b[c], k)));
            }
        }
        self.record.seamless = true;
    }

    /// Writes the maps into `dir` with ambientCG names (`Color.png`,
    /// `NormalGL.png`, `Displacement.png`, `Roughness.png`, ...), as PNG.
    pub fn write_maps(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::write(dir.join("Color.png"), encode_png_rgb(&self.colour))?;
        std::fs::write(dir.join("NormalGL.png"), encode_png_rgb(&self.normal))?;
        for (kind, map) in &self.maps {
            let (w, h) = map.dimensions();
            std::fs::write(
                dir.join(format!("{}.png", kind.file_stem())),
                encode_png_grey(w, h, map.as_raw()),
            )?;
        }
        Ok(())
    }
}

/// A `size x size` preview of a material on a sphere lit from the upper
/// left: the texture wrapped in longitude and latitude, its normal map
/// bending the sphere's normals, Lambert diffuse plus a Blinn-Phong
/// highlight whose sharpness follows the roughness and whose colour follows
/// the metalness. For looking at materials, not a physically based renderer.
pub fn preview_sphere(material: &PbrMaterial, size: u32) -> RgbImage {
    let (tw, th) = material.colour.dimensions();
    let roughness = &material.maps[1].1;
    let metalness = &material.maps[2].1;
    let light = normalise([-0.5, 0.6, 0.65]);
    let half = normalise([light[0], light[1], light[2] + 1.0]);
    let to_linear = |c: u8| (c as f32 / 255.0).powf(2.2);
    RgbImage::from_fn(size, size, |px, py| {
        // Sphere coordinates: x right, y up, z towards the viewer.
        let x = (px as f32 + 0.5) / size as f32 * 2.0 - 1.0;
        let y = 1.0 - (py as f32 + 0.5) / size as f32 * 2.0;
        let r2 = x * x + y * y;
        if r2 > 1.0 {
            return image::Rgb([20, 20, 24]);
        }
        let n = [x, y, (1.0 - r2).sqrt()];
        // Texture coordinates by longitude and latitude (two turns around).
        let u = (n[0].atan2(n[2]) / std::f32::consts::PI + 1.0) * 0.5;
        let v = n[1].acos() / std::f32::consts::PI;
        let (tx, ty) = (
            ((u * 2.0 * tw as f32) as u32) % tw,
            ((v * th as f32) as u32).min(th - 1),
        );
        // Tangent frame: east and north on the sphere.
        let east = normalise([n[2], 0.0, -n[0]]);
        let north = cross(n, east);
        let t = decode_normal(material.normal.get_pixel(tx, ty).0);
        let bent = normalise(std::array::from_fn(|i| {
            t[0] * east[i] + t[1] * north[i] + t[2] * n[i]
        }));
        let diffuse = dot(bent, light).max(0.0);
        let rough = roughness.get_pixel(tx, ty).0[0] as f32 / 255.0;
        let metal = metalness.get_pixel(tx, ty).0[0] as f32 / 255.0;
        let shininess = 2.0 + (1.0 - rough).powi(2) * 200.0;
        let highlight = dot(bent, half).max(0.0).powf(shininess) * (1.0 - rough * 0.8);
        let colour = material.colour.get_pixel(tx, ty).0;
        image::Rgb(std::array::from_fn(|c| {
            let albedo = to_linear(colour[c]);
            let specular_tint = metal * albedo + (1.0 - metal) * 0.04;
            let lit =
                albedo * (1.0 - metal) * (0.08 + 0.92 * diffuse) + specular_tint * highlight * 4.0;
            (lit.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0 + 0.5) as u8
        }))
    })
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A normal stored as 8-bit RGB (`(n + 1) / 2 * 255`) as a vector in `[-1, 1]`.
pub fn decode_normal(rgb: [u8; 3]) -> [f32; 3] {
    rgb.map(|c| c as f32 / 255.0 * 2.0 - 1.0)
}

/// The unit vector along `n`, stored as 8-bit RGB (`(n + 1) / 2 * 255`, rounded).
pub fn encode_normal(n: [f32; 3]) -> [u8; 3] {
    normalise(n).map(|c| round_to_u8((c + 1.0) / 2.0 * 255.0))
}

fn normalise(v: [f32; 3]) -> [f32; 3] {
    let len = dot(v, v).sqrt().max(1e-9);
    v.map(|c| c / len)
}

/// Draws a PBR material from `texture` (pipeline.md §5).
pub fn make_pbr<R: Rng + ?Sized>(
    rng: &mut R,
    texture: &RgbImage,
    recipe: &PbrRecipe,
) -> PbrMaterial {
    let hue_degrees = rng
        .random_bool(recipe.p_hue_rotation)
        .then(|| rng.random_range(0.0..360.0f32));
    let turned = [(); 3].map(|_| rng.random_bool(recipe.p_turn_or_flip));
    let mut colour = texture.clone();
    if turned[0] {
        colour = image::imageops::rotate270(&colour);
    }
    if turned[1] {
        image::imageops::flip_horizontal_in_place(&mut colour);
    }
    if turned[2] {
        image::imageops::flip_vertical_in_place(&mut colour);
    }
    if let Some(degrees) = hue_degrees {
        for px in colour.pixels_mut() {
            let turned = rotate_hue(px.0.map(f32::from), degrees);
            px.0 = turned.map(round_to_u8);
        }
    }
    let mut maps = Vec::new();
    let mut records = Vec::new();
    for kind in MapKind::ALL {
        let (map, record) = draw_map(rng, &colour, kind, recipe);
        maps.push((kind, map));
        records.push(record);
    }
    let shiny = rng.random_bool(recipe.p_shiny);
    let non_metal = rng.random_bool(recipe.p_non_metal);
    let [_, roughness, metalness, ..] = &mut maps[..] else {
        unreachable!("six maps")
    };
    if shiny {
        for (r, m) in roughness.1.pixels_mut().zip(metalness.1.pixels_mut()) {
            if m.0[0] > recipe.shiny_above {
                m.0[0] = 255;
                r.0[0] = 0;
            }
        }
    }
    if non_metal {
        metalness.1.pixels_mut().for_each(|m| m.0[0] = 0);
    }
    let normal_strength = if rng.random_bool(recipe.p_normal_16) {
        16.0 * rng.random::<f32>().powi(2)
    } else if rng.random_bool(0.5) {
        24.0 * rng.random::<f32>().powi(2)
    } else {
        1.0
    };
    let normal = normal_map(&maps[0].1, normal_strength);
    PbrMaterial {
        colour,
        maps,
        normal,
        record: PbrRecord {
            hue_degrees,
            turned,
            maps: records,
            shiny,
            non_metal,
            normal_strength,
            seamless: false,
        },
    }
}

/// One scalar map: its source, then the optional inversion, blur and rescale.
fn draw_map<R: Rng + ?Sized>(
    rng: &mut R,
    colour: &RgbImage,
    kind: MapKind,
    recipe: &PbrRecipe,
) -> (GrayImage, PbrMapRecord) {
    let source = if rng.random_bool(recipe.p_constant) {
        let value = match (kind, rng.random_range(0..3)) {
            (MapKind::Height, _) => 0,
            (_, 0) => rng.random(),
            (_, 1) => 255,
            _ => 0,
        };
        MapSource::Constant { value }
    } else {
        match rng.random_range(0..4) {
            0 => MapSource::Grey,
            1 => MapSource::Hsv {
                component: rng.random_range(0..3),
            },
            2 => MapSource::Relative {
                channel: rng.random_range(0..3),
            },
            _ => MapSource::TurnedChannel {
                degrees: rng.random_range(0.0..360.0),
                channel: rng.random_range(0..3),
            },
        }
    };
    let mut values: Vec<f32> = colour
        .pixels()
        .map(|p| source_value(&source, p.0))
        .collect();
    if let MapSource::Relative { .. } = source {
        // c / (mean + 10) lies in 0..~25: bring it to 0..255 by its maximum.
        let max = values.iter().copied().fold(0.0f32, f32::max).max(1e-6);
        values.iter_mut().for_each(|v| *v *= 255.0 / max);
    }
    let p_invert = if kind == MapKind::Roughness {
        recipe.p_invert_roughness
    } else {
        recipe.p_invert
    };
    let inverted = rng.random_bool(p_invert);
    if inverted {
        values.iter_mut().for_each(|v| *v = 255.0 - *v);
    }
    let (w, h) = colour.dimensions();
    let blur = rng
        .random_bool(recipe.p_blur)
        .then(|| recipe.blur_kernels[rng.random_range(0..recipe.blur_kernels.len())]);
    if let Some(k) = blur {
        values = gaussian_blur(&Plane::from_vec(w as usize, h as usize, values), k).data;
    }
    let constant = matches!(source, MapSource::Constant { .. });
    let range = if constant {
        None
    } else if kind == MapKind::Height {
        Some((0, 255))
    } else if rng.random_bool(recipe.p_rescale) {
        let (a, b) = (rng.random::<u8>(), rng.random::<u8>());
        Some((a.min(b), a.max(b)))
    } else {
        None
    };
    if let Some((lo, hi)) = range {
        let (min, max) = values
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let scale = if max > min {
            (hi - lo) as f32 / (max - min)
        } else {
            0.0
        };
        values
            .iter_mut()
            .for_each(|v| *v = lo as f32 + (*v - min) * scale);
    }
    let map = GrayImage::from_raw(w, h, values.iter().map(|&v| round_to_u8(v)).collect())
        .expect("map size");
    let record = PbrMapRecord {
        kind,
        source,
        inverted,
        blur,
        range,
    };
    (map, record)
}

/// The value (0..255 scale) a source gives a pixel.
fn source_value(source: &MapSource, [r, g, b]: [u8; 3]) -> f32 {
    let rgb = [r as f32, g as f32, b as f32];
    let mean = (rgb[0] + rgb[1] + rgb[2]) / 3.0;
    match *source {
        MapSource::Constant { value } => value as f32,
        MapSource::Grey => mean,
        MapSource::Hsv { component } => {
            let level = match component {
                0 => matseg_image::Channel::H,
                1 => matseg_image::Channel::S,
                _ => matseg_image::Channel::V,
            }
            .level([r, g, b]);
            level as f32
        }
        MapSource::Relative { channel } => rgb[channel] / (mean + 10.0),
        MapSource::TurnedChannel { degrees, channel } => rotate_hue(rgb, degrees)[channel],
    }
}

/// Tangent-space normals from a height map (0..255 as 0..1) by central
/// differences (edges repeated), scaled by `strength`; OpenGL convention
/// (+x right, +y up), encoded as `(n + 1) / 2 * 255`.
pub fn normal_map(height: &GrayImage, strength: f32) -> RgbImage {
    let (w, h) = height.dimensions();
    let at = |x: i64, y: i64| {
        height
            .get_pixel(
                x.clamp(0, w as i64 - 1) as u32,
                y.clamp(0, h as i64 - 1) as u32,
            )
            .0[0] as f32
            / 255.0
    };
    RgbImage::from_fn(w, h, |x, y| {
        let (x, y) = (x as i64, y as i64);
        let dx = (at(x + 1, y) - at(x - 1, y)) / 2.0;
        // Image rows go down; OpenGL's y goes up.
        let dy_up = (at(x, y - 1) - at(x, y + 1)) / 2.0;
        image::Rgb(encode_normal([-strength * dx, -strength * dy_up, 1.0]))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn texture() -> RgbImage {
        RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb([(x * 7) as u8, (y * 9) as u8, ((x * y) % 251) as u8])
        })
    }

    #[test]
    fn normals_are_unit_vectors_and_point_up_the_slope() {
        // Height rises to the right: normals lean left (-x), none in y.
        let ramp = GrayImage::from_fn(16, 8, |x, _| image::Luma([(x * 16) as u8]));
        let n = normal_map(&ramp, 4.0);
        for p in n.pixels() {
            let v = p.0.map(|c| c as f32 / 255.0 * 2.0 - 1.0);
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((len - 1.0).abs() < 0.02, "{v:?}");
        }
        let centre = n.get_pixel(8, 4).0;
        assert!(centre[0] < 128 && (centre[1] as i32 - 128).abs() <= 1 && centre[2] > 128);
        // Height rising downwards (towards -y in OpenGL) tilts normals up (+y).
        let down = GrayImage::from_fn(8, 16, |_, y| image::Luma([(y * 16) as u8]));
        assert!(normal_map(&down, 4.0).get_pixel(4, 8).0[1] > 128);
    }

    #[test]
    fn seamless_maps_tile_without_a_step_at_the_edges() {
        let mut m = make_pbr(
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(5),
            &texture(),
            &PbrRecipe::default(),
        );
        let before = m.colour.clone();
        m.make_seamless();
        assert!(m.record.seamless);
        let (w, h) = m.colour.dimensions();
        let step = |img: &RgbImage, x0: u32, x1: u32| {
            (0..h)
                .map(|y| {
                    let (a, b) = (img.get_pixel(x0, y).0, img.get_pixel(x1, y).0);
                    (0..3)
                        .map(|c| (a[c] as f32 - b[c] as f32).abs())
                        .sum::<f32>()
                })
                .sum::<f32>()
                / h as f32
        };
        // Across the wrap (last column to first) the colour changes no more
        // than between typical neighbouring columns of the tile.
        let interior = (1..w - 1).map(|x| step(&m.colour, x - 1, x)).sum::<f32>() / (w - 2) as f32;
        assert!(
            step(&m.colour, w - 1, 0) <= 1.5 * interior + 1.0,
            "{} vs {interior}",
            step(&m.colour, w - 1, 0)
        );
        // Nor is there a step in the middle (where a shifted copy's seam would be).
        assert!(step(&m.colour, w / 2 - 1, w / 2) <= 1.5 * interior + 1.0);
        // Before, the texture's own edges did not match.
        assert!(step(&before, w - 1, 0) > 3.0 * interior);
    }

    #[test]
    fn sphere_previews_are_lit_from_the_upper_left() {
        let m = make_pbr(
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(1),
            &texture(),
            &PbrRecipe::default(),
        );
        let img = preview_sphere(&m, 64);
        assert_eq!(img.get_pixel(0, 0).0, [20, 20, 24], "outside the sphere");
        let brightness = |x, y| img.get_pixel(x, y).0.iter().map(|&c| c as u32).sum::<u32>();
        // Average over patches: the lit side is brighter than the far side.
        let patch = |cx: u32, cy: u32| {
            (0..5)
                .flat_map(|i| (0..5).map(move |j| (cx + i, cy + j)))
                .map(|(x, y)| brightness(x, y))
                .sum::<u32>()
        };
        assert!(patch(16, 16) > patch(44, 44));
    }

    #[test]
    fn materials_are_deterministic_and_follow_their_rules() {
        let recipe = PbrRecipe::default();
        let mut seen_constant = false;
        for seed in 0..40 {
            let make = || {
                make_pbr(
                    &mut rand_chacha::ChaCha8Rng::seed_from_u64(seed),
                    &texture(),
                    &recipe,
                )
            };
            let (a, b) = (make(), make());
            assert_eq!(a.colour, b.colour);
            assert_eq!(a.normal, b.normal);
            assert_eq!(a.record, b.record);
            assert_eq!(a.maps.len(), 6);
            let (w, h) = a.colour.dimensions();
            for ((kind, map), record) in a.maps.iter().zip(&a.record.maps) {
                assert_eq!(map.dimensions(), (w, h));
                assert_eq!(*kind, record.kind);
                // Roughness and metalness may be changed by the shiny and non-metal rules.
                let ruled = matches!(kind, MapKind::Roughness | MapKind::Metalness);
                if let (MapSource::Constant { value }, false) = (&record.source, ruled) {
                    let value = *value;
                    seen_constant = true;
                    let v = if record.inverted { 255 - value } else { value };
                    if record.blur.is_none() {
                        assert!(map.pixels().all(|p| p.0[0] == v), "{record:?}");
                    }
                }
            }
            let metal = &a.maps[2].1;
            if a.record.non_metal {
                assert!(metal.pixels().all(|p| p.0[0] == 0));
            } else if a.record.shiny {
                let rough = &a.maps[1].1;
                for (m, r) in metal.pixels().zip(rough.pixels()) {
                    assert!(m.0[0] <= recipe.shiny_above || (m.0[0] == 255 && r.0[0] == 0));
                }
            }
        }
        assert!(seen_constant);
    }
}
