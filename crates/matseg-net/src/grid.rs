//! The ground truth on the net's stride-4 grid, where its descriptors are
//! made before they are resized to the image: each cell's exact share of
//! the ROI, and each material's exact share of the ROI's part of the cell.
//! The loss on the grid against these targets weighs every image pixel as
//! the loss at full size does, where the descriptors are constant over a
//! cell; it costs a sixteenth.

use crate::batch::TrainingSample;
use crate::loss::ImageTargets;
use tch::{Device, Tensor};

/// Pixels a side of one cell of the net's descriptor grid.
pub const GRID_STRIDE: usize = 4;

/// One image's ground truth on a grid of cells.
#[derive(Clone, Debug, PartialEq)]
pub struct GridTargets {
    /// Cells across.
    pub width: usize,
    /// Cells down.
    pub height: usize,
    /// Per material, `width * height` cell values: the mean of its
    /// weight over the cell's ROI pixels (0 in a cell with none).
    pub weights: Vec<Vec<f32>>,
    /// The share of each cell's pixels inside the ROI, `width * height`.
    pub roi: Vec<f32>,
}

impl GridTargets {
    /// The targets of `sample` on cells of `stride` x `stride` pixels;
    /// its sides must be multiples of `stride` (a caller's bug otherwise).
    pub fn of(sample: &TrainingSample, stride: usize) -> Self {
        let (w, h) = (sample.width, sample.height);
        assert!(
            w.is_multiple_of(stride) && h.is_multiple_of(stride),
            "{w}x{h} is not a whole number of {stride}-pixel cells"
        );
        let (gw, gh) = (w / stride, h / stride);
        let cell_sums = |plane: &dyn Fn(usize) -> f32| -> Vec<f32> {
            let mut sums = vec![0.0f32; gw * gh];
            for y in 0..h {
                let row = (y / stride) * gw;
                for x in 0..w {
                    sums[row + x / stride] += plane(y * w + x);
                }
            }
            sums
        };
        let roi_sums = cell_sums(&|i| sample.roi[i]);
        let weights = sample
            .weights
            .iter()
            .map(|weight| {
                cell_sums(&|i| weight[i] * sample.roi[i])
                    .iter()
                    .zip(&roi_sums)
                    .map(|(&s, &r)| if r > 0.0 { s / r } else { 0.0 })
                    .collect()
            })
            .collect();
        let area = (stride * stride) as f32;
        Self {
            width: gw,
            height: gh,
            weights,
            roi: roi_sums.iter().map(|&r| r / area).collect(),
        }
    }

    /// The targets as the loss takes them, on `device`.
    pub fn to_image_targets(&self, device: Device) -> ImageTargets {
        let (h, w) = (self.height as i64, self.width as i64);
        let planes: Vec<Tensor> = self
            .weights
            .iter()
            .map(|p| Tensor::from_slice(p).view([h, w]))
            .collect();
        ImageTargets {
            weights: Tensor::stack(&planes, 0).to_device(device),
            roi: Tensor::from_slice(&self.roi).view([h, w]).to_device(device),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_hold_the_exact_shares_of_their_pixels() {
        // 8x4 pixels, 2x1 cells of 4: the left cell is half ROI, and in
        // its ROI pixels material 0 has weight 1 on 3 of 8 and 0.5 on the
        // rest; the right cell is all ROI, material 1 everywhere.
        let (w, h) = (8, 4);
        let mut roi = vec![1.0f32; w * h];
        let mut first = vec![0.0f32; w * h];
        let mut second = vec![0.0f32; w * h];
        let mut in_roi = 0;
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if x < 4 {
                    if y < 2 {
                        roi[i] = 0.0;
                        first[i] = 1.0;
                        continue;
                    }
                    first[i] = if in_roi < 3 { 1.0 } else { 0.5 };
                    second[i] = 1.0 - first[i];
                    in_roi += 1;
                } else {
                    second[i] = 1.0;
                }
            }
        }
        let sample = TrainingSample {
            rgb: vec![0; w * h * 3],
            width: w,
            height: h,
            weights: vec![first, second],
            roi,
        };
        let grid = GridTargets::of(&sample, 4);
        assert_eq!((grid.width, grid.height), (2, 1));
        assert_eq!(grid.roi, [0.5, 1.0]);
        let share = (3.0 + 5.0 * 0.5) / 8.0;
        assert_eq!(grid.weights[0], [share, 0.0]);
        assert_eq!(grid.weights[1], [1.0 - share, 1.0]);
    }
}
