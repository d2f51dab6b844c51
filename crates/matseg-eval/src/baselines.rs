//! Baselines that need no training: colour (RGB, CIE Lab) and colour plus
//! local texture statistics. They set the floor a trained net must beat.
//! `position` (a pixel's coordinates, nothing else) is a reference: how
//! far a benchmark can be scored by nearness alone, since points of one
//! material often lie close together.

use image::RgbImage;
use matseg_image::lab::srgb_to_lab;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};

/// Names accepted by [`baseline`], in table order.
pub const BASELINES: [&str; 4] = ["rgb", "lab", "texture", "position"];

/// The baseline called `name`, if there is one.
pub fn baseline(name: &str) -> Option<Box<dyn DescriptorModel>> {
    match name {
        "rgb" => Some(Box::new(ColourBaseline::RGB)),
        "lab" => Some(Box::new(ColourBaseline::LAB)),
        "texture" => Some(Box::new(TextureBaseline::default())),
        "position" => Some(Box::new(PositionBaseline)),
        _ => None,
    }
}

/// The colour space of a [`ColourBaseline`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourSpace {
    /// R, G, B on 0..1 (each 8-bit level divided by 255 in `f32`, as
    /// `numpy.float32(v) / 255` computes it, so a copy of the baseline
    /// outside matseg gives the same values bit for bit).
    Rgb,
    /// CIE L*a*b* (D65): distances are CIE76 colour differences.
    Lab,
}

/// Mean colour in the point's disc; similarity = minus the distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColourBaseline {
    /// The space colours are compared in.
    pub space: ColourSpace,
}

impl ColourBaseline {
    /// The `rgb` baseline.
    pub const RGB: Self = Self {
        space: ColourSpace::Rgb,
    };
    /// The `lab` baseline.
    pub const LAB: Self = Self {
        space: ColourSpace::Lab,
    };
}

impl DescriptorModel for ColourBaseline {
    fn name(&self) -> &str {
        match self.space {
            ColourSpace::Rgb => "rgb",
            ColourSpace::Lab => "lab",
        }
    }

    fn comparison(&self) -> Comparison {
        Comparison::NegativeEuclidean
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        let data = match self.space {
            ColourSpace::Rgb => image.as_raw().iter().map(|&v| v as f32 / 255.0).collect(),
            ColourSpace::Lab => image.pixels().flat_map(|p| srgb_to_lab(p.0)).collect(),
        };
        DescriptorMap {
            width: image.width() as usize,
            height: image.height() as usize,
            dim: 3,
            data,
        }
    }
}

/// Colour and local texture: per pixel, over a square window, the mean and
/// standard deviation of L*, a*, b* and the mean gradient magnitude of L*.
/// Each feature is divided by its standard deviation over the image, so
/// they weigh alike; similarity = minus the distance.
pub struct TextureBaseline {
    /// Half the window side, in pixels.
    pub radius: usize,
}

impl Default for TextureBaseline {
    fn default() -> Self {
        Self { radius: 7 }
    }
}

impl DescriptorModel for TextureBaseline {
    fn name(&self) -> &str {
        "texture"
    }

    fn comparison(&self) -> Comparison {
        Comparison::NegativeEuclidean
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let lab: Vec<[f32; 3]> = image.pixels().map(|p| srgb_to_lab(p.0)).collect();
        let gradient: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let l = |x: usize, y: usize| lab[y * w + x][0];
                let dx = l((x + 1).min(w - 1), y) - l(x.saturating_sub(1), y);
                let dy = l(x, (y + 1).min(h - 1)) - l(x, y.saturating_sub(1));
                (dx * dx + dy * dy).sqrt() / 2.0
            })
            .collect();
        let channels: [Vec<f32>; 4] = [
            lab.iter().map(|p| p[0]).collect(),
            lab.iter().map(|p| p[1]).collect(),
            lab.iter().map(|p| p[2]).collect(),
            gradient,
        ];
        // Features: means of the four channels, standard deviations of L, a, b.
        let mut features: Vec<Vec<f32>> = Vec::with_capacity(7);
        for (c, values) in channels.iter().enumerate() {
            let (mean, std) = box_mean_std(values, w, h, self.radius);
            features.push(mean);
            if c < 3 {
                features.push(std);
            }
        }
        for f in &mut features {
            let scale = 1.0 / spread(f).max(1e-6);
            f.iter_mut().for_each(|v| *v *= scale);
        }
        let dim = features.len();
        let mut data = vec![0f32; w * h * dim];
        for (k, f) in features.iter().enumerate() {
            for (i, &v) in f.iter().enumerate() {
                data[i * dim + k] = v;
            }
        }
        DescriptorMap {
            width: w,
            height: h,
            dim,
            data,
        }
    }
}

/// A pixel's coordinates as its descriptor: points are as similar as they
/// are near.
pub struct PositionBaseline;

impl DescriptorModel for PositionBaseline {
    fn name(&self) -> &str {
        "position"
    }

    fn comparison(&self) -> Comparison {
        Comparison::NegativeEuclidean
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        let (w, h) = (image.width() as usize, image.height() as usize);
        DescriptorMap {
            width: w,
            height: h,
            dim: 2,
            data: (0..w * h)
                .flat_map(|i| [(i % w) as f32, (i / w) as f32])
                .collect(),
        }
    }
}

/// Standard deviation of all values.
fn spread(values: &[f32]) -> f32 {
    let n = values.len().max(1) as f64;
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / n;
    let var = values
        .iter()
        .map(|&v| (v as f64 - mean).powi(2))
        .sum::<f64>()
        / n;
    var.sqrt() as f32
}

/// Mean and standard deviation of `values` over the square window of
/// half-side `r` around each pixel (clipped at the borders), by summed-area
/// tables.
fn box_mean_std(values: &[f32], w: usize, h: usize, r: usize) -> (Vec<f32>, Vec<f32>) {
    let stride = w + 1;
    let mut sum = vec![0f64; stride * (h + 1)];
    let mut sq = vec![0f64; stride * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            let v = values[y * w + x] as f64;
            let i = (y + 1) * stride + x + 1;
            sum[i] = v + sum[i - 1] + sum[i - stride] - sum[i - stride - 1];
            sq[i] = v * v + sq[i - 1] + sq[i - stride] - sq[i - stride - 1];
        }
    }
    let rect = |t: &[f64], x0: usize, y0: usize, x1: usize, y1: usize| {
        t[y1 * stride + x1] - t[y0 * stride + x1] - t[y1 * stride + x0] + t[y0 * stride + x0]
    };
    let mut mean = Vec::with_capacity(w * h);
    let mut std = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
            let n = ((x1 - x0) * (y1 - y0)) as f64;
            let m = rect(&sum, x0, y0, x1, y1) / n;
            let var = (rect(&sq, x0, y0, x1, y1) / n - m * m).max(0.0);
            mean.push(m as f32);
            std.push(var.sqrt() as f32);
        }
    }
    (mean, std)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_statistics_match_a_direct_count() {
        let (w, h) = (5, 4);
        let values: Vec<f32> = (0..w * h).map(|i| ((i * 7) % 11) as f32).collect();
        let (mean, std) = box_mean_std(&values, w, h, 1);
        // Pixel (0, 0): window x 0..2, y 0..2.
        let window = [values[0], values[1], values[5], values[6]];
        let m = window.iter().sum::<f32>() / 4.0;
        let v = window.iter().map(|x| (x - m).powi(2)).sum::<f32>() / 4.0;
        assert!((mean[0] - m).abs() < 1e-5 && (std[0] - v.sqrt()).abs() < 1e-4);
    }

    #[test]
    fn position_similarity_is_minus_the_distance_in_pixels() {
        let map = PositionBaseline.describe(&RgbImage::new(10, 8));
        let c = PositionBaseline.comparison();
        let a = map.point_descriptor(1.0, 1.0, 0.0, c);
        let b = map.point_descriptor(4.0, 5.0, 0.0, c);
        assert_eq!(a, [1.0, 1.0]);
        assert_eq!(c.similarity(&a, &b), -5.0);
    }

    #[test]
    fn texture_features_separate_flat_from_striped_regions() {
        // Left half flat grey, right half grey stripes of the same mean.
        let img = RgbImage::from_fn(40, 20, |x, _| {
            let v = if x < 20 {
                128
            } else if x % 2 == 0 {
                88
            } else {
                168
            };
            image::Rgb([v, v, v])
        });
        let t = TextureBaseline { radius: 3 };
        let map = t.describe(&img);
        let c = t.comparison();
        let flat = map.point_descriptor(5.0, 10.0, 2.0, c);
        let flat2 = map.point_descriptor(10.0, 10.0, 2.0, c);
        let striped = map.point_descriptor(32.0, 10.0, 2.0, c);
        assert!(c.similarity(&flat, &flat2) > c.similarity(&flat, &striped));
    }
}
