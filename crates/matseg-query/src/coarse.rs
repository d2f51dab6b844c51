//! Unit descriptors on a grid coarser than their photo (a net's stride-4
//! output), queried in photo pixels: the fast path of interactive use.
//!
//! A point's descriptor pools the grid cells whose centres fall in its
//! disc (mapped onto the grid; the nearest cell at least); a similarity map
//! is the cosine on the grid, resized bilinearly to the photo (half-pixel
//! centres). On a 1 MP photo that reads a sixteenth of the values a
//! full-resolution map would, so each new point costs milliseconds.

use crate::descriptor::{bilinear_taps, Comparison, DescriptorMap};
use rayon::prelude::*;

/// Unit descriptors on a grid laid over a `width x height` photo.
#[derive(Clone, Debug, PartialEq)]
pub struct CoarseDescriptors {
    /// The grid's descriptors, unit length (cosine comparison).
    pub grid: DescriptorMap,
    /// The photo's width in pixels.
    pub width: usize,
    /// The photo's height in pixels.
    pub height: usize,
}

impl CoarseDescriptors {
    /// Grid coordinates of photo pixel coordinates (pixel centres at whole
    /// numbers in both).
    fn to_grid(&self, x: f32, y: f32) -> (f32, f32) {
        let sx = self.grid.width as f32 / self.width as f32;
        let sy = self.grid.height as f32 / self.height as f32;
        ((x + 0.5) * sx - 0.5, (y + 0.5) * sy - 0.5)
    }

    /// The unit descriptor of the disc of radius `r` photo pixels around
    /// `(x, y)`: the normalised sum of the grid cells inside it.
    pub fn point_descriptor(&self, x: f32, y: f32, r: f32) -> Vec<f32> {
        let (gx, gy) = self.to_grid(x, y);
        let scale = self.grid.width as f32 / self.width as f32;
        self.grid
            .point_descriptor(gx, gy, r * scale, Comparison::Cosine)
    }

    /// The cosine of `query` with every cell, resized bilinearly to the
    /// photo: `width * height` values, row by row.
    pub fn similarity_map(&self, query: &[f32]) -> Vec<f32> {
        self.resize_to_photo(&self.cell_similarity(query))
    }

    /// The cosine of `query` with every cell of the grid, row by row.
    pub fn cell_similarity(&self, query: &[f32]) -> Vec<f32> {
        (0..self.grid.width * self.grid.height)
            .into_par_iter()
            .map(|i| dot(query, self.grid.at(i)))
            .collect()
    }

    /// Each photo pixel's nearest descriptor among `queries` (the index of
    /// the one of highest resized cosine), e.g. several points' or cluster
    /// centres': a hard segmentation of `width * height` labels.
    pub fn nearest_query(&self, queries: &[Vec<f32>]) -> Vec<u32> {
        let maps: Vec<Vec<f32>> = queries.iter().map(|q| self.similarity_map(q)).collect();
        Self::nearest_of(&maps)
    }

    /// Each pixel's label among similarity `maps` already computed (of
    /// equal length): the index of the highest.
    pub fn nearest_of(maps: &[Vec<f32>]) -> Vec<u32> {
        let pixels = maps.first().map_or(0, Vec::len);
        (0..pixels)
            .into_par_iter()
            .map(|j| {
                (0..maps.len())
                    .max_by(|&a, &b| maps[a][j].total_cmp(&maps[b][j]))
                    .unwrap_or(0) as u32
            })
            .collect()
    }

    /// A grid of values (one per cell) resized bilinearly to the photo.
    pub fn resize_to_photo(&self, cells: &[f32]) -> Vec<f32> {
        let (gw, gh) = (self.grid.width, self.grid.height);
        let (columns, rows) = (
            bilinear_taps(self.width, gw),
            bilinear_taps(self.height, gh),
        );
        let mut out = vec![0f32; self.width * self.height];
        out.par_chunks_mut(self.width)
            .zip(&rows)
            .for_each(|(line, &(y0, y1, fy))| {
                let (top, bottom) = (
                    &cells[y0 * gw..(y0 + 1) * gw],
                    &cells[y1 * gw..(y1 + 1) * gw],
                );
                for (v, &(x0, x1, fx)) in line.iter_mut().zip(&columns) {
                    let t = top[x0] + (top[x1] - top[x0]) * fx;
                    let b = bottom[x0] + (bottom[x1] - bottom[x0]) * fx;
                    *v = t + (b - t) * fy;
                }
            });
        out
    }
}

/// The dot product, in eight f32 lanes (which the compiler vectorises).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            lanes[k] += x[k] * y[k];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4x2 grid over an 8x4 photo: the left half's cells point along x,
    /// the right half's along y (2-d descriptors).
    fn halves() -> CoarseDescriptors {
        let data = (0..8)
            .flat_map(|i| if i % 4 < 2 { [1.0, 0.0] } else { [0.0, 1.0] })
            .collect();
        CoarseDescriptors {
            grid: DescriptorMap {
                width: 4,
                height: 2,
                dim: 2,
                data,
            },
            width: 8,
            height: 4,
        }
    }

    #[test]
    fn points_pool_the_cells_under_their_disc() {
        let map = halves();
        assert_eq!(map.point_descriptor(1.0, 1.0, 1.0), [1.0, 0.0]);
        assert_eq!(map.point_descriptor(6.5, 2.0, 1.0), [0.0, 1.0]);
        // A disc over the boundary pools both halves.
        let mixed = map.point_descriptor(3.5, 1.5, 2.0);
        assert!((mixed[0] - mixed[1]).abs() < 1e-6, "{mixed:?}");
    }

    #[test]
    fn similarity_maps_are_the_grids_cosines_resized_bilinearly() {
        let map = halves();
        let s = map.similarity_map(&[1.0, 0.0]);
        assert_eq!(s.len(), 32);
        // Photo pixel x sits at grid x (x + 0.5) / 2 - 0.5: pixels 0-2 lie
        // over the left cells (1), 5-7 over the right ones (0), 3 and 4
        // between cells 1 and 2 (0.75 and 0.25).
        let row: Vec<f32> = s[8..16].to_vec();
        assert_eq!(row, [1.0, 1.0, 1.0, 0.75, 0.25, 0.0, 0.0, 0.0]);
        assert!(s.chunks(8).all(|r| r == row));
    }

    #[test]
    fn pixels_take_the_nearest_query() {
        let labels = halves().nearest_query(&[vec![0.0, 1.0], vec![1.0, 0.0]]);
        assert_eq!(&labels[..8], [1, 1, 1, 1, 0, 0, 0, 0]);
    }

    #[test]
    fn dot_products_match_the_plain_sum_past_the_lanes() {
        let a: Vec<f32> = (0..19).map(|i| i as f32 * 0.5).collect();
        let b: Vec<f32> = (0..19).map(|i| 3.0 - i as f32).collect();
        let plain: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        assert!((dot(&a, &b) - plain).abs() < 1e-3);
    }
}
