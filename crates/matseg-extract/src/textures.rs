//! Uniform textures from natural photos (pipeline.md §4): regions whose
//! local statistics are the same everywhere, found as squares of cells that
//! are pairwise similar in every property channel.
//!
//! The pair test follows the definition (10-bin histograms over the pair's
//! joint range, Jensen-Shannon distance per channel) without its cost: each
//! cell's values are sorted once, so a histogram over any range is ten
//! binary searches; channels are tested until the first that fails; every
//! pair is tested at most once.

use image::RgbImage;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Parameters of the extraction, with the paper's values as defaults.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TextureOptions {
    /// Cell side in pixels (40 in the paper for ~1 MP photos).
    pub cell: usize,
    /// Smallest square kept, in cells per side (6 in the paper).
    pub min_cells: usize,
    /// Two cells are similar when every channel's Jensen-Shannon distance is below this.
    pub js_max: f64,
    /// Histogram bins per channel.
    pub bins: usize,
    /// A square overlapping a kept one by more than this fraction of its
    /// own area is a near-duplicate and dropped.
    pub max_overlap: f64,
}

impl Default for TextureOptions {
    fn default() -> Self {
        Self {
            cell: 40,
            min_cells: 6,
            js_max: 0.5,
            bins: 10,
            max_overlap: 0.5,
        }
    }
}

/// A uniform square found in a photo.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TextureSquare {
    /// Left edge in pixels.
    pub x: u32,
    /// Top edge in pixels.
    pub y: u32,
    /// Side in pixels (a multiple of the cell size).
    pub side: u32,
    /// Side in cells.
    pub cells: u32,
    /// The lowest pair similarity (1 - largest channel distance) in the square.
    pub score: f64,
}

/// Jensen-Shannon distance (natural log, so in `0..=sqrt(ln 2)`) between
/// two histograms of the same bins (counts, normalised here).
pub fn js_distance(p: &[f64], q: &[f64]) -> f64 {
    let (sp, sq): (f64, f64) = (p.iter().sum(), q.iter().sum());
    if sp == 0.0 || sq == 0.0 {
        return 0.0;
    }
    let kl = |a: f64, m: f64| if a > 0.0 { a * (a / m).ln() } else { 0.0 };
    let mut divergence = 0.0;
    for (&a, &b) in p.iter().zip(q) {
        let (a, b) = (a / sp, b / sq);
        let m = (a + b) / 2.0;
        divergence += 0.5 * (kl(a, m) + kl(b, m));
    }
    divergence.max(0.0).sqrt()
}

/// Number of property channels (pipeline.md §4.1).
pub const CHANNELS: usize = 13;

/// Names of the property channels, in order (for records).
pub const CHANNEL_NAMES: [&str; CHANNELS] = [
    "R", "G", "B", "R+G+B", "dx R", "dy R", "dx G", "dy G", "dx B", "dy B", "|grad R|", "|grad G|",
    "|grad B|",
];

/// The 13 property channels of pipeline.md §4.1 at pixel `(x, y)`: R, G, B, the sum
/// R + G + B (the mean times 3: histograms over a pair's joint range do not
/// see the scale), the horizontal and vertical 3x3 Sobel derivatives of R,
/// G, B (borders replicated), and the rounded gradient magnitude of R, G, B.
pub fn pixel_properties(img: &RgbImage, x: u32, y: u32) -> [i16; CHANNELS] {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let at = |dx: i64, dy: i64| {
        let px = (x as i64 + dx).clamp(0, w - 1) as u32;
        let py = (y as i64 + dy).clamp(0, h - 1) as u32;
        img.get_pixel(px, py).0.map(|v| v as i16)
    };
    let centre = at(0, 0);
    let mut out = [0i16; CHANNELS];
    out[..3].copy_from_slice(&centre);
    out[3] = centre.iter().sum();
    let n = [
        at(-1, -1),
        at(0, -1),
        at(1, -1),
        at(-1, 0),
        at(1, 0),
        at(-1, 1),
        at(0, 1),
        at(1, 1),
    ];
    for c in 0..3 {
        let [tl, t, tr, l, r, bl, b, br] = n.map(|p| p[c]);
        let dx = tr + 2 * r + br - tl - 2 * l - bl;
        let dy = bl + 2 * b + br - tl - 2 * t - tr;
        out[4 + 2 * c] = dx;
        out[5 + 2 * c] = dy;
        // Exact in f32 (the squares stay below 2^24), so sqrt rounds correctly.
        out[10 + c] = ((dx as i32 * dx as i32 + dy as i32 * dy as i32) as f32)
            .sqrt()
            .round() as i16;
    }
    out
}

/// The distribution of one channel over one cell: the count of values at
/// or below each level from the lowest to the highest, so that any
/// histogram of the cell is a few lookups.
struct Cdf {
    min: i32,
    /// `at_or_below[k]`: values <= `min + k`.
    at_or_below: Vec<u32>,
}

impl Cdf {
    fn new(values: impl Iterator<Item = i16> + Clone) -> Self {
        let (min, max) = values.clone().fold((i32::MAX, i32::MIN), |(lo, hi), v| {
            (lo.min(v as i32), hi.max(v as i32))
        });
        let mut counts = vec![0u32; (max - min + 1) as usize];
        for v in values {
            counts[(v as i32 - min) as usize] += 1;
        }
        let mut total = 0;
        for c in &mut counts {
            total += *c;
            *c = total;
        }
        Self {
            min,
            at_or_below: counts,
        }
    }

    fn max(&self) -> i32 {
        self.min + self.at_or_below.len() as i32 - 1
    }

    /// Values strictly below `edge`.
    fn below(&self, edge: f32) -> u32 {
        // For integers, v < edge exactly when v <= ceil(edge) - 1.
        let t = edge.ceil() as i64 - 1;
        if t < self.min as i64 {
            0
        } else if t >= self.max() as i64 {
            *self.at_or_below.last().expect("a cell has values")
        } else {
            self.at_or_below[(t - self.min as i64) as usize]
        }
    }

    /// Counts in `bins` equal bins over `lo..=hi` (the top value in the last bin).
    fn histogram(&self, lo: f32, hi: f32, bins: usize) -> Vec<f64> {
        let total = self.below(f32::INFINITY);
        if hi <= lo {
            let mut h = vec![0.0; bins];
            h[0] = total as f64;
            return h;
        }
        let width = (hi - lo) / bins as f32;
        let mut below = 0;
        (1..=bins)
            .map(|k| {
                let upto = if k == bins {
                    total
                } else {
                    self.below(lo + width * k as f32)
                };
                let count = upto - below;
                below = upto;
                count as f64
            })
            .collect()
    }
}

/// The cells of a photo: per cell and channel, its distribution.
struct Cells {
    cols: usize,
    rows: usize,
    /// `cdfs[cell][channel]`.
    cdfs: Vec<Vec<Cdf>>,
}

impl Cells {
    fn new(img: &RgbImage, cell: usize) -> Self {
        let (cols, rows) = (img.width() as usize / cell, img.height() as usize / cell);
        let mut cdfs = Vec::with_capacity(cols * rows);
        let mut values: Vec<[i16; CHANNELS]> = Vec::with_capacity(cell * cell);
        for cy in 0..rows {
            for cx in 0..cols {
                values.clear();
                for y in cy * cell..(cy + 1) * cell {
                    for x in cx * cell..(cx + 1) * cell {
                        values.push(pixel_properties(img, x as u32, y as u32));
                    }
                }
                cdfs.push(
                    (0..CHANNELS)
                        .map(|c| Cdf::new(values.iter().map(move |p| p[c])))
                        .collect(),
                );
            }
        }
        Self { cols, rows, cdfs }
    }

    /// The pair's similarity, `1 - max distance`, or `None` as soon as one
    /// channel's distance reaches `js_max`.
    fn similarity(&self, a: usize, b: usize, options: &TextureOptions) -> Option<f64> {
        let mut worst: f64 = 0.0;
        for (ca, cb) in self.cdfs[a].iter().zip(&self.cdfs[b]) {
            let lo = ca.min.min(cb.min) as f32;
            let hi = ca.max().max(cb.max()) as f32;
            let (ha, hb) = (
                ca.histogram(lo, hi, options.bins),
                cb.histogram(lo, hi, options.bins),
            );
            let d = js_distance(&ha, &hb);
            if d >= options.js_max {
                return None;
            }
            worst = worst.max(d);
        }
        Some(1.0 - worst)
    }
}

/// Finds the uniform squares of a photo (pipeline.md §4.2-4.3): from every start
/// cell, the largest square of pairwise-similar cells (every pair tested),
/// kept when at least `min_cells` a side; squares inside or overlapping a
/// larger kept one are dropped.
pub fn find_squares(img: &RgbImage, options: &TextureOptions) -> Vec<TextureSquare> {
    let cells = Cells::new(img, options.cell);
    let mut cache: HashMap<(usize, usize), Option<f64>> = HashMap::new();
    let mut pair = |a: usize, b: usize| -> Option<f64> {
        let key = (a.min(b), a.max(b));
        *cache
            .entry(key)
            .or_insert_with(|| cells.similarity(key.0, key.1, options))
    };
    let mut found = Vec::new();
    for cy in 0..cells.rows {
        for cx in 0..cells.cols {
            let index = |x: usize, y: usize| y * cells.cols + x;
            let mut members = vec![index(cx, cy)];
            let mut score = 1.0f64;
            let mut side = 1;
            // Grow by one row and one column while every new cell is
            // similar to every cell already in (and to the other new ones).
            'grow: while cx + side < cells.cols && cy + side < cells.rows {
                let new: Vec<usize> = (0..=side)
                    .map(|i| index(cx + side, cy + i))
                    .chain((0..side).map(|i| index(cx + i, cy + side)))
                    .collect();
                let mut step_score = score;
                for (k, &n) in new.iter().enumerate() {
                    for &m in members.iter().chain(&new[..k]) {
                        match pair(n, m) {
                            Some(s) => step_score = step_score.min(s),
                            None => break 'grow,
                        }
                    }
                }
                members.extend(new);
                score = step_score;
                side += 1;
            }
            if side >= options.min_cells {
                found.push(TextureSquare {
                    x: (cx * options.cell) as u32,
                    y: (cy * options.cell) as u32,
                    side: (side * options.cell) as u32,
                    cells: side as u32,
                    score,
                });
            }
        }
    }
    prune(found, options.max_overlap)
}

/// Keeps the largest squares first (then the best scored); drops any square
/// that lies inside a kept one or overlaps it by more than `max_overlap` of
/// its own area.
fn prune(mut squares: Vec<TextureSquare>, max_overlap: f64) -> Vec<TextureSquare> {
    squares.sort_by(|a, b| b.side.cmp(&a.side).then(b.score.total_cmp(&a.score)));
    let mut kept: Vec<TextureSquare> = Vec::new();
    for s in squares {
        let area = (s.side as f64).powi(2);
        let clash = kept.iter().any(|k| {
            let ix = (s.x + s.side).min(k.x + k.side) as f64 - s.x.max(k.x) as f64;
            let iy = (s.y + s.side).min(k.y + k.side) as f64 - s.y.max(k.y) as f64;
            ix > 0.0 && iy > 0.0 && ix * iy > max_overlap * area
        });
        if !clash {
            kept.push(s);
        }
    }
    kept
}

/// True when a crop is too uniform to be a texture (pipeline.md §4.4): one of its
/// four quadrants has a grey-level standard deviation below 3.5, or below 6
/// with a mean above 245.
pub fn too_uniform(crop: &RgbImage) -> bool {
    let (w, h) = (crop.width(), crop.height());
    let quadrants = [(0, 0), (w / 2, 0), (0, h / 2), (w / 2, h / 2)];
    quadrants.iter().any(|&(x0, y0)| {
        let grey: Vec<f64> = (y0..y0 + h / 2)
            .flat_map(|y| (x0..x0 + w / 2).map(move |x| (x, y)))
            .map(|(x, y)| {
                crop.get_pixel(x, y)
                    .0
                    .iter()
                    .map(|&v| v as f64)
                    .sum::<f64>()
                    / 3.0
            })
            .collect();
        let n = grey.len().max(1) as f64;
        let mean = grey.iter().sum::<f64>() / n;
        let std = (grey.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / n).sqrt();
        std < 3.5 || (std < 6.0 && mean > 245.0)
    })
}

/// The uniform, not too uniform, squares of a photo, with their crops.
pub fn extract_textures(
    img: &RgbImage,
    options: &TextureOptions,
) -> Vec<(TextureSquare, RgbImage)> {
    find_squares(img, options)
        .into_iter()
        .map(|s| {
            let crop = image::imageops::crop_imm(img, s.x, s.y, s.side, s.side).to_image();
            (s, crop)
        })
        .filter(|(_, crop)| !too_uniform(crop))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn js_distance_of_identical_and_disjoint_histograms() {
        assert_eq!(js_distance(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]), 0.0);
        let d = js_distance(&[5.0, 0.0], &[0.0, 7.0]);
        assert!((d - 2f64.ln().sqrt()).abs() < 1e-12);
        // Hand value: p = (1/2, 1/2), q = (1, 0): JSD = 0.5 * (ln(4/3)... ).
        let (p, q) = ([0.5, 0.5], [1.0, 0.0]);
        let m = [0.75, 0.25];
        let kl = |a: &[f64; 2]| {
            a.iter()
                .zip(&m)
                .filter(|(x, _)| **x > 0.0)
                .map(|(x, y)| x * (x / y).ln())
                .sum::<f64>()
        };
        let want = (0.5 * (kl(&p) + kl(&q))).sqrt();
        assert!((js_distance(&p, &q) - want).abs() < 1e-12);
    }

    #[test]
    fn histograms_from_cumulative_counts_match_direct_counts() {
        let values: Vec<i16> = (0..200).map(|i| ((i * 37) % 101) as i16 - 20).collect();
        let cdf = Cdf::new(values.iter().copied());
        assert_eq!((cdf.min, cdf.max()), (-20, 80));
        for (lo, hi) in [(-23.0f32, 90.0f32), (-20.0, 80.0), (0.5, 33.3)] {
            let h = cdf.histogram(lo, hi, 10);
            let width = (hi - lo) / 10.0;
            for (k, &count) in h.iter().enumerate() {
                let edge = |j: usize| lo + width * j as f32;
                let direct = values
                    .iter()
                    .filter(|&&v| {
                        let above_lower = k == 0 || (v as f32) >= edge(k);
                        let below_upper = k == 9 || (v as f32) < edge(k + 1);
                        above_lower && below_upper
                    })
                    .count();
                assert_eq!(count as usize, direct, "bin {k} of {lo}..{hi}");
            }
        }
    }

    #[test]
    fn pixel_properties_of_a_ramp() {
        // R rises by 10 per column, G by 5 per row, B is flat.
        let img = RgbImage::from_fn(5, 4, |x, y| image::Rgb([10 * x as u8, 5 * y as u8, 7]));
        let p = pixel_properties(&img, 2, 1);
        assert_eq!(&p[..4], &[20, 5, 7, 32]);
        // Sobel: (1 + 2 + 1) times the difference across two pixels.
        assert_eq!(&p[4..10], &[80, 0, 0, 40, 0, 0]);
        assert_eq!(&p[10..], &[80, 40, 0]);
        // At the border the edge pixel is repeated: half the difference.
        assert_eq!(pixel_properties(&img, 0, 0)[4], 40);
    }

    #[test]
    fn crops_with_a_flat_quadrant_are_too_uniform() {
        let flat = RgbImage::from_pixel(20, 20, image::Rgb([120, 120, 120]));
        assert!(too_uniform(&flat));
        let noisy = RgbImage::from_fn(20, 20, |x, y| {
            let v = ((x * 73 + y * 151) % 97) as u8 + 60;
            image::Rgb([v, v, v])
        });
        assert!(!too_uniform(&noisy));
    }
}
