//! The MatSeg loss (pipeline.md §8).
//!
//! For every image of the batch and every material in it, the material's
//! descriptor is the mean of the (normalised) pixel descriptors where its
//! ground-truth weight exceeds 0.5, re-normalised; a material with no such
//! pixel has no descriptor and drops out. All materials of all images form
//! one list, so other images' materials are negatives. Per pixel,
//! p = softmax over the list of cos(pixel, material) / 0.2, and the loss is
//! `-(1 / (B H W)) * sum over pixels of ROI * sum_m target_m * log p_m`,
//! with the pixel's soft ground-truth weights as targets (0 for other
//! images' materials). Batches with fewer than two materials give no loss.

use crate::blocks::l2_normalise;
use tch::{Kind, Tensor};

pub use matseg_model::config::TEMPERATURE;
/// A pixel belongs to a material's region where its weight exceeds this.
pub const REGION_THRESHOLD: f64 = 0.5;

/// One image's ground truth at the descriptors' resolution.
#[derive(Debug)]
pub struct ImageTargets {
    /// Soft weights per material, `[K, H, W]`.
    pub weights: Tensor,
    /// 1 inside the ROI, 0 outside, `[H, W]`.
    pub roi: Tensor,
}

/// The loss of normalised descriptors `[B, D, H, W]` against one
/// [`ImageTargets`] per image; `None` when the batch has fewer than two
/// materials with a region.
pub fn matseg_loss(descriptors: &Tensor, targets: &[ImageTargets]) -> Option<Tensor> {
    let (b, d, h, w) = descriptors.size4().expect("descriptors [B, D, H, W]");
    assert_eq!(b as usize, targets.len(), "one target per image");
    let kind = descriptors.kind();
    let n = h * w;
    // One unbind: selecting each image from the batch tensor would make
    // the backward pass fill a batch-sized zero gradient per image.
    let flat: Vec<Tensor> = descriptors.reshape([b, d, n]).unbind(0);
    let weights: Vec<Tensor> = targets
        .iter()
        .map(|t| t.weights.to_kind(kind).reshape([-1, n]))
        .collect();

    // Material descriptors (each image's in one matrix product), and which
    // rows of the list each image owns.
    let mut materials = Vec::new();
    let mut owned: Vec<Vec<i64>> = Vec::with_capacity(targets.len());
    for (desc, wts) in flat.iter().zip(&weights) {
        let region = wts.gt(REGION_THRESHOLD).to_kind(kind);
        let counts =
            Vec::<f64>::try_from(region.sum_dim_intlist(1, false, Kind::Double)).expect("counts");
        let (mine, sizes): (Vec<i64>, Vec<f64>) = counts
            .iter()
            .enumerate()
            .filter(|(_, &count)| count > 0.0)
            .map(|(k, &count)| (k as i64, count))
            .unzip();
        if !mine.is_empty() {
            let rows = Tensor::from_slice(&mine).to_device(desc.device());
            let sizes = Tensor::from_slice(&sizes)
                .to_kind(kind)
                .to_device(desc.device());
            let means = desc.matmul(&region.index_select(0, &rows).tr()) / sizes;
            materials.push(l2_normalise(&means, 0).tr());
        }
        owned.push(mine);
    }
    if owned.iter().map(Vec::len).sum::<usize>() < 2 {
        return None;
    }
    let materials = Tensor::cat(&materials, 0);

    let mut total = Tensor::zeros([], (kind, descriptors.device()));
    let mut first_row = 0i64;
    for ((desc, wts), (mine, t)) in flat.iter().zip(&weights).zip(owned.iter().zip(targets)) {
        if mine.is_empty() {
            continue;
        }
        let log_p = (materials.matmul(desc) / TEMPERATURE).log_softmax(0, kind);
        let rows = Tensor::arange_start(
            first_row,
            first_row + mine.len() as i64,
            (Kind::Int64, desc.device()),
        );
        let own = Tensor::from_slice(mine).to_device(desc.device());
        let cross = (log_p.index_select(0, &rows) * wts.index_select(0, &own))
            .sum_dim_intlist(0, false, kind);
        let roi = t.roi.to_kind(kind).reshape([n]);
        total -= (cross * roi).sum(kind);
        first_row += mine.len() as i64;
    }
    Some(total / (b * n) as f64)
}
