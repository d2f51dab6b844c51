//! Per-pixel descriptor maps, the one interface every evaluated model
//! implements (baselines now, the trained net later), and what is derived
//! from them: point descriptors and similarity maps.

use image::RgbImage;
use rayon::prelude::*;
use std::borrow::Cow;

/// How two descriptors are compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Comparison {
    /// Cosine similarity. A point's descriptor is the normalised sum of the
    /// normalised pixel descriptors in its disc (pipeline.md §8, inference).
    Cosine,
    /// Minus the Euclidean distance. A point's descriptor is the mean of
    /// the pixel descriptors in its disc (the colour baselines).
    NegativeEuclidean,
}

impl Comparison {
    /// The similarity of two point descriptors (higher is closer).
    pub fn similarity(self, a: &[f32], b: &[f32]) -> f64 {
        match self {
            Comparison::Cosine => a.iter().zip(b).map(|(x, y)| (x * y) as f64).sum(),
            Comparison::NegativeEuclidean => -a
                .iter()
                .zip(b)
                .map(|(x, y)| ((x - y) as f64).powi(2))
                .sum::<f64>()
                .sqrt(),
        }
    }
}

/// The largest radius of a query point's disc, in pixels.
pub const MAX_RADIUS: f32 = 256.0;

/// A query point's disc radius out of its range.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("radius {0}: give a disc radius from 0 to {MAX_RADIUS} pixels")]
pub struct RadiusError(pub f32);

/// `radius`, checked: a number of pixels from 0 to [`MAX_RADIUS`] (not
/// negative, not NaN or infinite). Every front end that takes a radius
/// (the CLI, the web app, Python, the evaluations) checks it here.
pub fn check_radius(radius: f32) -> Result<f32, RadiusError> {
    if (0.0..=MAX_RADIUS).contains(&radius) {
        Ok(radius)
    } else {
        Err(RadiusError(radius))
    }
}

/// A `width x height` map of `dim`-long descriptors, pixel by pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct DescriptorMap {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Length of each descriptor.
    pub dim: usize,
    /// `width * height * dim` values: the descriptor of pixel `i` is
    /// `data[i * dim..(i + 1) * dim]`.
    pub data: Vec<f32>,
}

impl DescriptorMap {
    /// The descriptor of pixel `i` (row-major index).
    pub fn at(&self, i: usize) -> &[f32] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// The descriptor of the disc of radius `r` around `(x, y)` (pixel
    /// centres within `r`, the nearest pixel at least), pooled as
    /// `comparison` asks.
    pub fn point_descriptor(&self, x: f32, y: f32, r: f32, comparison: Comparison) -> Vec<f32> {
        pool_disc(
            (self.width, self.height, self.dim),
            (x, y, r),
            comparison,
            |i| Cow::Borrowed(self.at(i)),
        )
    }

    /// The similarity of every pixel to the point descriptor `query`
    /// (pixel descriptors are normalised first for cosine).
    pub fn similarity_map(&self, query: &[f32], comparison: Comparison) -> Vec<f32> {
        (0..self.width * self.height)
            .into_par_iter()
            .map(|i| {
                let d = self.at(i);
                let s = match comparison {
                    Comparison::Cosine => {
                        comparison.similarity(query, d) / norm(d).max(1e-12) as f64
                    }
                    Comparison::NegativeEuclidean => comparison.similarity(query, d),
                };
                s as f32
            })
            .collect()
    }
}

/// The pixels (row-major indices) of a `width x height` image whose
/// centres lie within `r` of `(x, y)`, the nearest pixel when none does:
/// the disc a query point stands for.
pub fn disc_pixels(width: usize, height: usize, x: f32, y: f32, r: f32) -> Vec<usize> {
    let (w, h) = (width as i64, height as i64);
    let (x0, x1) = ((x - r).floor() as i64, (x + r).ceil() as i64);
    let (y0, y1) = ((y - r).floor() as i64, (y + r).ceil() as i64);
    let mut disc: Vec<usize> = Vec::new();
    for py in y0.max(0)..=y1.min(h - 1) {
        for px in x0.max(0)..=x1.min(w - 1) {
            let (dx, dy) = (px as f32 - x, py as f32 - y);
            if dx * dx + dy * dy <= r * r {
                disc.push((py * w + px) as usize);
            }
        }
    }
    if disc.is_empty() {
        let px = (x.round() as i64).clamp(0, w - 1);
        let py = (y.round() as i64).clamp(0, h - 1);
        disc.push((py * w + px) as usize);
    }
    disc
}

/// Bilinear taps of `n` output pixels over `grid` input ones, pixel
/// centres at half pixels in both (edges clamped): for each output pixel
/// the lower input index, the upper one and the upper one's weight.
pub fn bilinear_taps(n: usize, grid: usize) -> Vec<(usize, usize, f32)> {
    let scale = grid as f32 / n as f32;
    (0..n)
        .map(|i| {
            let g = ((i as f32 + 0.5) * scale - 0.5).clamp(0.0, (grid - 1) as f32);
            let lo = g.floor() as usize;
            (lo, (lo + 1).min(grid - 1), g - lo as f32)
        })
        .collect()
}

/// `values`, `dim` channels per pixel of a `width x height` grid (row by
/// row, channels interleaved), resized bilinearly to `to_width x
/// to_height` (half-pixel centres, as a net's output is resized to its
/// photo). The same size gives the values back unchanged (owned values
/// without a copy).
pub fn resize_channels(
    values: Cow<'_, [f32]>,
    (width, height): (usize, usize),
    dim: usize,
    (to_width, to_height): (usize, usize),
) -> Vec<f32> {
    if (width, height) == (to_width, to_height) {
        return values.into_owned();
    }
    let (columns, rows) = (
        bilinear_taps(to_width, width),
        bilinear_taps(to_height, height),
    );
    let mut out = vec![0f32; to_width * to_height * dim];
    out.par_chunks_mut(to_width * dim)
        .zip(&rows)
        .for_each(|(line, &(y0, y1, fy))| {
            let row = |y: usize| &values[y * width * dim..(y + 1) * width * dim];
            let (top, bottom) = (row(y0), row(y1));
            for (pixel, &(x0, x1, fx)) in line.chunks_mut(dim).zip(&columns) {
                for (c, v) in pixel.iter_mut().enumerate() {
                    let (a, b) = (x0 * dim + c, x1 * dim + c);
                    let t = top[a] + (top[b] - top[a]) * fx;
                    let d = bottom[a] + (bottom[b] - bottom[a]) * fx;
                    *v = t + (d - t) * fy;
                }
            }
        });
    out
}

/// The disc of radius `r` around `(x, y)` on a `width x height` map of
/// `dim`-long descriptors (pixel centres within `r`, the nearest pixel at
/// least), pooled as `comparison` asks; `at(i)` is pixel `i`'s descriptor.
fn pool_disc<'a>(
    (width, height, dim): (usize, usize, usize),
    (x, y, r): (f32, f32, f32),
    comparison: Comparison,
    at: impl Fn(usize) -> Cow<'a, [f32]>,
) -> Vec<f32> {
    let disc = disc_pixels(width, height, x, y, r);
    let mut sum = vec![0f64; dim];
    for &i in &disc {
        let d = at(i);
        let scale = match comparison {
            Comparison::Cosine => 1.0 / norm(&d).max(1e-12) as f64,
            Comparison::NegativeEuclidean => 1.0,
        };
        for (s, &v) in sum.iter_mut().zip(d.iter()) {
            *s += v as f64 * scale;
        }
    }
    let count = disc.len();
    let pooled: Vec<f32> = sum.iter().map(|&s| (s / count as f64) as f32).collect();
    match comparison {
        Comparison::Cosine => {
            let n = norm(&pooled).max(1e-12);
            pooled.iter().map(|v| v / n).collect()
        }
        Comparison::NegativeEuclidean => pooled,
    }
}

/// A grid of descriptors seen at a photo's size: each pixel's descriptor
/// computed when asked, as [`resize_channels`] computes it (the same
/// arithmetic, so the same values bit for bit), so that pooling a few
/// discs reads a few pixels rather than resizing every channel.
pub struct ResizedGrid<'a> {
    values: &'a [f32],
    width: usize,
    dim: usize,
    to_width: usize,
    to_height: usize,
    columns: Vec<(usize, usize, f32)>,
    rows: Vec<(usize, usize, f32)>,
}

impl<'a> ResizedGrid<'a> {
    /// `values`, `dim` channels per cell of a `width x height` grid (as
    /// [`resize_channels`] takes them), seen at `to_width x to_height`.
    pub fn new(
        values: &'a [f32],
        (width, height): (usize, usize),
        dim: usize,
        (to_width, to_height): (usize, usize),
    ) -> Self {
        Self {
            values,
            width,
            dim,
            to_width,
            to_height,
            columns: bilinear_taps(to_width, width),
            rows: bilinear_taps(to_height, height),
        }
    }

    /// The descriptor of photo pixel `i` (row-major index).
    pub fn pixel(&self, i: usize) -> Vec<f32> {
        let (x0, x1, fx) = self.columns[i % self.to_width];
        let (y0, y1, fy) = self.rows[i / self.to_width];
        let at = |x: usize, y: usize| {
            let start = (y * self.width + x) * self.dim;
            &self.values[start..start + self.dim]
        };
        let (ta, tb, ba, bb) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        (0..self.dim)
            .map(|c| {
                let t = ta[c] + (tb[c] - ta[c]) * fx;
                let d = ba[c] + (bb[c] - ba[c]) * fx;
                t + (d - t) * fy
            })
            .collect()
    }

    /// As [`DescriptorMap::point_descriptor`] on the resized map.
    pub fn point_descriptor(&self, x: f32, y: f32, r: f32, comparison: Comparison) -> Vec<f32> {
        pool_disc(
            (self.to_width, self.to_height, self.dim),
            (x, y, r),
            comparison,
            |i| Cow::Owned(self.pixel(i)),
        )
    }
}

fn norm(v: &[f32]) -> f32 {
    v.iter().map(|x| x * x).sum::<f32>().sqrt()
}

/// A model that gives every pixel of a photo a material descriptor.
pub trait DescriptorModel: Send + Sync {
    /// Short name for tables (`rgb`, `lab`, ...).
    fn name(&self) -> &str;
    /// How its descriptors are pooled and compared.
    fn comparison(&self) -> Comparison;
    /// The descriptor map of `image`.
    fn describe(&self, image: &RgbImage) -> DescriptorMap;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_resized_grid_pools_what_the_resized_map_pools() {
        // A 5 x 3 grid of 4 channels seen at 23 x 11, and at its own size.
        let values: Vec<f32> = (0..5 * 3 * 4)
            .map(|i| ((i * 37 % 11) as f32 - 5.0) / 3.0)
            .collect();
        for to in [(23, 11), (5, 3)] {
            let map = DescriptorMap {
                width: to.0,
                height: to.1,
                dim: 4,
                data: resize_channels(Cow::Borrowed(&values), (5, 3), 4, to),
            };
            let grid = ResizedGrid::new(&values, (5, 3), 4, to);
            for i in 0..to.0 * to.1 {
                assert_eq!(grid.pixel(i), map.at(i), "pixel {i} at {to:?}");
            }
            for comparison in [Comparison::Cosine, Comparison::NegativeEuclidean] {
                for (x, y, r) in [(0.0, 0.0, 0.0), (4.2, 2.7, 3.0), (20.0, 9.5, 6.0)] {
                    assert_eq!(
                        grid.point_descriptor(x, y, r, comparison),
                        map.point_descriptor(x, y, r, comparison)
                    );
                }
            }
        }
    }

    #[test]
    fn radii_are_pixels_from_zero_to_the_most() {
        for r in [0.0, 0.5, 5.0, MAX_RADIUS] {
            assert_eq!(check_radius(r), Ok(r));
        }
        for r in [
            -1.0,
            -0.0001,
            MAX_RADIUS + 0.5,
            1e9,
            f32::NAN,
            f32::INFINITY,
        ] {
            let refused = check_radius(r).unwrap_err();
            assert!(
                refused.to_string().starts_with(&format!("radius {r}: ")),
                "{refused}"
            );
        }
    }

    fn map() -> DescriptorMap {
        // 3x2 pixels, 2-d descriptors.
        DescriptorMap {
            width: 3,
            height: 2,
            dim: 2,
            data: vec![1., 0., 0., 2., 3., 0., 0., 1., 1., 1., 2., 0.],
        }
    }

    #[test]
    fn point_descriptors_pool_the_disc() {
        let m = map();
        // Radius 0: the pixel itself.
        assert_eq!(
            m.point_descriptor(1.0, 0.0, 0.0, Comparison::NegativeEuclidean),
            vec![0.0, 2.0]
        );
        // Radius 1 around (1, 0): pixels (1,0), (0,0), (2,0), (1,1).
        let mean = m.point_descriptor(1.0, 0.0, 1.0, Comparison::NegativeEuclidean);
        assert_eq!(
            mean,
            vec![(0.0 + 1.0 + 3.0 + 1.0) / 4.0, (2.0 + 0.0 + 0.0 + 1.0) / 4.0]
        );
        // Cosine: normalised pixels (0,1), (1,0), (1,0), (0.707, 0.707) summed, normalised.
        let c = m.point_descriptor(1.0, 0.0, 1.0, Comparison::Cosine);
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let (a, b) = (2.0 + s, 1.0 + s);
        let n = (a * a + b * b).sqrt();
        assert!((c[0] - a / n).abs() < 1e-6 && (c[1] - b / n).abs() < 1e-6);
    }

    #[test]
    fn similarity_maps_compare_every_pixel() {
        let m = map();
        let e = m.similarity_map(&[1.0, 0.0], Comparison::NegativeEuclidean);
        assert_eq!(e[0], 0.0);
        assert!((e[1] - -(5f32).sqrt()).abs() < 1e-6);
        let c = m.similarity_map(&[1.0, 0.0], Comparison::Cosine);
        assert_eq!((c[0], c[1], c[2]), (1.0, 0.0, 1.0));
        assert!((c[4] - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-6);
    }
}
