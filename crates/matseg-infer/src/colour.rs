//! The colour part of a descriptor: each stride-4 cell's mean CIE L*a*b*
//! colour as random Fourier features (matseg-net's `colour` module, whose
//! fixed projection and phases are read from the weights).

use crate::weights::Weights;
use matseg_image::lab::srgb_to_lab;
use matseg_model::config::COLOUR_FEATURES;
use matseg_model::ModelError;
use rayon::prelude::*;

/// Pixels a side of a cell of the stride-4 grid.
const CELL: usize = 4;

/// The colour part's weights.
pub(crate) struct ColourPart {
    /// `[COLOUR_FEATURES, 3]` directions.
    projection: Vec<f32>,
    /// `[COLOUR_FEATURES]` phases.
    phase: Vec<f32>,
    /// The part's weight in the descriptor.
    weight: f32,
    /// The kernel's bandwidth in L*a*b* units.
    bandwidth: f32,
}

impl ColourPart {
    /// The part under `colour.`.
    pub(crate) fn load(weights: &Weights) -> Result<Self, ModelError> {
        let m = COLOUR_FEATURES as usize;
        Ok(Self {
            projection: weights.get("colour.projection", &[m, 3])?,
            phase: weights.get("colour.phase", &[m])?,
            weight: weights.scalar("colour.log_weight")?.exp(),
            bandwidth: weights.scalar("colour.log_bandwidth")?.exp(),
        })
    }

    /// The weighted part `[COLOUR_FEATURES, h, w]` (plane by plane) of an
    /// interleaved RGB image of `width x height` pixels, both multiples of
    /// 4: each cell's mean L*a*b* colour projected, its features of unit
    /// length times the part's weight.
    pub(crate) fn forward(&self, rgb: &[u8], width: usize, height: usize) -> Vec<f32> {
        let (w, h) = (width / CELL, height / CELL);
        let m = COLOUR_FEATURES as usize;
        // Each cell's features, cell by cell, then laid out plane by plane.
        let mut cells = vec![0f32; w * h * m];
        cells
            .par_chunks_mut(w * m)
            .enumerate()
            .for_each(|(cy, row)| {
                for (cx, features) in row.chunks_mut(m).enumerate() {
                    let lab = self.cell_lab(rgb, width, cx, cy);
                    self.features(lab, features);
                }
            });
        let mut planes = vec![0f32; w * h * m];
        for (cell, features) in cells.chunks(m).enumerate() {
            for (k, v) in features.iter().enumerate() {
                planes[k * w * h + cell] = *v;
            }
        }
        planes
    }

    /// The mean L*a*b* colour of cell `(cx, cy)`.
    fn cell_lab(&self, rgb: &[u8], width: usize, cx: usize, cy: usize) -> [f32; 3] {
        let mut sum = [0f32; 3];
        for y in cy * CELL..(cy + 1) * CELL {
            for x in cx * CELL..(cx + 1) * CELL {
                let i = (y * width + x) * 3;
                let lab = srgb_to_lab([rgb[i], rgb[i + 1], rgb[i + 2]]);
                for (s, v) in sum.iter_mut().zip(lab) {
                    *s += v;
                }
            }
        }
        sum.map(|s| s / (CELL * CELL) as f32)
    }

    /// The weighted features of one cell's colour `lab` into `out`.
    fn features(&self, lab: [f32; 3], out: &mut [f32]) {
        let scaled = lab.map(|v| v / self.bandwidth);
        for ((o, direction), phase) in out
            .iter_mut()
            .zip(self.projection.chunks_exact(3))
            .zip(&self.phase)
        {
            let angle: f32 = direction.iter().zip(scaled).map(|(d, s)| d * s).sum();
            *o = (angle + phase).cos();
        }
        let norm = out.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-12);
        out.iter_mut().for_each(|v| *v *= self.weight / norm);
    }
}
