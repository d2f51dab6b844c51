//! A map made to follow the photo's own edges: He, Sun and Tang's guided
//! filter with the photo's lightness (CIE L*, 0..1) as the guide. Where
//! the photo is flat the output is the input smoothed; where it has an
//! edge the output takes the edge. The guide's statistics are computed
//! once per photo ([`EdgeGuide::new`]) and each map then costs a few
//! passes over the photo; large photos are filtered on a subsampled grid
//! and the filter's coefficients brought back to full size (He and Sun's
//! fast guided filter), which keeps a click's answer within milliseconds.

use image::RgbImage;
use matseg_image::lab::srgb_to_lab;
use rayon::prelude::*;

/// A photo's lightness, ready to guide any number of maps.
pub struct EdgeGuide {
    width: usize,
    height: usize,
    /// The photo's lightness at full size, 0..1.
    guide: Vec<f32>,
    /// The lightness on the filter's grid.
    low_guide: Vec<f32>,
    /// The filter's grid: one cell per `scale x scale` photo pixels.
    scale: usize,
    low_width: usize,
    low_height: usize,
    /// The window's radius on the filter's grid.
    radius: usize,
    /// The regularisation: edges weaker than about this variance of
    /// lightness are smoothed over.
    epsilon: f32,
    /// The guide's window means and variances on the filter's grid.
    mean: Vec<f32>,
    variance: Vec<f32>,
}

impl EdgeGuide {
    /// `photo`'s lightness as a guide with windows of `radius` photo
    /// pixels and regularisation `epsilon`; photos with a longer side
    /// above 512 pixels are filtered on a grid that is at most 512 cells
    /// long.
    pub fn new(photo: &RgbImage, radius: usize, epsilon: f32) -> Self {
        let (width, height) = (photo.width() as usize, photo.height() as usize);
        let guide: Vec<f32> = photo
            .as_raw()
            .par_chunks(3)
            .map(|p| srgb_to_lab([p[0], p[1], p[2]])[0] / 100.0)
            .collect();
        let scale = width.max(height).div_ceil(512).max(1);
        let (low_width, low_height) = (width.div_ceil(scale), height.div_ceil(scale));
        let radius = radius.div_ceil(scale).max(1);
        let low = block_mean(&guide, width, height, scale);
        let mean = box_mean(&low, low_width, low_height, radius);
        let squares: Vec<f32> = low.iter().map(|v| v * v).collect();
        let variance = box_mean(&squares, low_width, low_height, radius)
            .iter()
            .zip(&mean)
            .map(|(s, m)| (s - m * m).max(0.0))
            .collect();
        Self {
            width,
            height,
            guide,
            low_guide: low,
            scale,
            low_width,
            low_height,
            radius,
            epsilon,
            mean,
            variance,
        }
    }

    /// `input` (a value per photo pixel, row by row) made to follow the
    /// photo's edges.
    pub fn refine(&self, input: &[f32]) -> Vec<f32> {
        let (lw, lh, r) = (self.low_width, self.low_height, self.radius);
        let low = block_mean(input, self.width, self.height, self.scale);
        let mean_p = box_mean(&low, lw, lh, r);
        let products: Vec<f32> = self
            .low_guide
            .iter()
            .zip(&low)
            .map(|(i, p)| i * p)
            .collect();
        let corr = box_mean(&products, lw, lh, r);
        let (a, b): (Vec<f32>, Vec<f32>) = (0..lw * lh)
            .map(|i| {
                let cov = corr[i] - self.mean[i] * mean_p[i];
                let a = cov / (self.variance[i] + self.epsilon);
                (a, mean_p[i] - a * self.mean[i])
            })
            .unzip();
        let (a, b) = (box_mean(&a, lw, lh, r), box_mean(&b, lw, lh, r));
        // a and b resized bilinearly to the photo, each pixel's a * guide
        // + b made as they are.
        if self.scale == 1 {
            return self
                .guide
                .par_iter()
                .zip(a.par_iter().zip(&b))
                .map(|(i, (a, b))| a * i + b)
                .collect();
        }
        let s = self.scale as f32;
        let tap = |i: usize, n: usize| {
            let g = ((i as f32 + 0.5) / s - 0.5).clamp(0.0, (n - 1) as f32);
            let lo = g.floor() as usize;
            (lo, (lo + 1).min(n - 1), g - lo as f32)
        };
        let columns: Vec<_> = (0..self.width).map(|x| tap(x, lw)).collect();
        let mut out = vec![0f32; self.width * self.height];
        out.par_chunks_mut(self.width)
            .zip(self.guide.par_chunks(self.width))
            .enumerate()
            .for_each(|(y, (line, guide))| {
                let (y0, y1, fy) = tap(y, lh);
                let (rows_a, rows_b) = (
                    (&a[y0 * lw..(y0 + 1) * lw], &a[y1 * lw..(y1 + 1) * lw]),
                    (&b[y0 * lw..(y0 + 1) * lw], &b[y1 * lw..(y1 + 1) * lw]),
                );
                let at = |(top, bottom): (&[f32], &[f32]), (x0, x1, fx): (usize, usize, f32)| {
                    let t = top[x0] + (top[x1] - top[x0]) * fx;
                    let b = bottom[x0] + (bottom[x1] - bottom[x0]) * fx;
                    t + (b - t) * fy
                };
                for ((v, &i), &column) in line.iter_mut().zip(guide).zip(&columns) {
                    *v = at(rows_a, column) * i + at(rows_b, column);
                }
            });
        out
    }
}

/// The mean of each `scale x scale` block of `values` (a `w x h` grid;
/// blocks at the right and bottom borders are clipped).
fn block_mean(values: &[f32], w: usize, h: usize, scale: usize) -> Vec<f32> {
    if scale == 1 {
        return values.to_vec();
    }
    let (lw, lh) = (w.div_ceil(scale), h.div_ceil(scale));
    let mut out = vec![0f32; lw * lh];
    out.par_chunks_mut(lw).enumerate().for_each(|(ly, line)| {
        let rows = ly * scale..((ly + 1) * scale).min(h);
        for (lx, v) in line.iter_mut().enumerate() {
            let columns = lx * scale..((lx + 1) * scale).min(w);
            let mut sum = 0f32;
            for y in rows.clone() {
                sum += values[y * w + columns.start..y * w + columns.end]
                    .iter()
                    .sum::<f32>();
            }
            *v = sum / (rows.len() * columns.len()) as f32;
        }
    });
    out
}

/// The mean of `values` (a `w x h` grid) over the square window of
/// `radius` around each cell, clipped at the borders: running sums, so
/// each cell costs the same whatever the radius.
pub fn box_mean(values: &[f32], w: usize, h: usize, radius: usize) -> Vec<f32> {
    // Along each row, then along each column of the result.
    let mut rows = vec![0f32; w * h];
    rows.par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, out)| running_mean(|k| values[y * w + k], w, radius, |k, v| out[k] = v));
    let mut transposed = vec![0f32; w * h];
    transposed
        .par_chunks_mut(h)
        .enumerate()
        .for_each(|(x, out)| running_mean(|k| rows[k * w + x], h, radius, |k, v| out[k] = v));
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, line)| {
        for (x, v) in line.iter_mut().enumerate() {
            *v = transposed[x * h + y];
        }
    });
    out
}

/// The running mean over windows of `radius` along a line of `len`
/// values read by `at`, each written by `put`.
fn running_mean(
    at: impl Fn(usize) -> f32,
    len: usize,
    radius: usize,
    mut put: impl FnMut(usize, f32),
) {
    let mut sum = 0f64;
    let (mut lo, mut hi) = (0usize, 0usize);
    for k in 0..len {
        let (want_lo, want_hi) = (k.saturating_sub(radius), (k + radius + 1).min(len));
        while hi < want_hi {
            sum += at(hi) as f64;
            hi += 1;
        }
        while lo < want_lo {
            sum -= at(lo) as f64;
            lo += 1;
        }
        put(k, (sum / (hi - lo) as f64) as f32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A photo black on the left, white on the right.
    fn edge(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, _| {
            if x < w / 2 {
                image::Rgb([0, 0, 0])
            } else {
                image::Rgb([255, 255, 255])
            }
        })
    }

    #[test]
    fn a_decision_that_spills_over_an_edge_comes_back_to_it() {
        for (w, h) in [(20, 10), (1600, 40)] {
            let photo = edge(w, h);
            let (w, h) = (w as usize, h as usize);
            let spill = w / 2 + 2;
            let decision: Vec<f32> = (0..w * h)
                .map(|i| if i % w < spill { 1.0 } else { 0.0 })
                .collect();
            let guide = EdgeGuide::new(&photo, 4, 0.01);
            let filtered = guide.refine(&decision);
            for y in 0..h {
                let row = &filtered[y * w..(y + 1) * w];
                assert!(row[w / 4] > 0.9, "inside stays ({w})");
                assert!(row[w / 2 + 1] < 0.5, "the spill past the edge goes ({w})");
                assert!(row[w - 2] < 0.1, "outside stays out ({w})");
            }
            // A constant input is left as it is.
            let flat = guide.refine(&vec![0.7; w * h]);
            assert!(flat.iter().all(|v| (v - 0.7).abs() < 1e-3));
        }
    }

    #[test]
    fn box_means_average_their_clipped_window() {
        let values: Vec<f32> = (0..12).map(|v| v as f32).collect();
        let mean = box_mean(&values, 4, 3, 1);
        // The corner averages its 2x2 window, the middle its 3x3.
        assert_eq!(mean[0], (0.0 + 1.0 + 4.0 + 5.0) / 4.0);
        assert_eq!(
            mean[5],
            (0..3)
                .flat_map(|y| (0..3).map(move |x| (y * 4 + x) as f32))
                .sum::<f32>()
                / 9.0
        );
        assert_eq!(block_mean(&values, 4, 3, 2), vec![2.5, 4.5, 8.5, 10.5]);
    }
}
