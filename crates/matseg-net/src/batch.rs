//! Training batches: same-size images with their soft ground truth, as the
//! net's input and the loss's targets.

use crate::loss::ImageTargets;
use crate::net::{normalise_input, rgb8_to_tensor};
use tch::{Device, Tensor};

pub use matseg_data::training::TrainingSample;

/// A batch on a device: normalised images `[B, 3, H, W]` and their targets.
#[derive(Debug)]
pub struct Batch {
    /// The net's input.
    pub images: Tensor,
    /// One per image.
    pub targets: Vec<ImageTargets>,
}

impl Batch {
    /// Stacks `samples` (all of one size; panics otherwise, as that is a
    /// caller's bug) onto `device`.
    pub fn new(samples: &[TrainingSample], device: Device) -> Self {
        let (w, h) = (samples[0].width, samples[0].height);
        let mut images = Vec::with_capacity(samples.len());
        let mut targets = Vec::with_capacity(samples.len());
        for s in samples {
            assert!(
                (s.width, s.height) == (w, h),
                "a batch's images share one size"
            );
            images.push(rgb8_to_tensor(&s.rgb, w, h));
            let planes: Vec<Tensor> = s
                .weights
                .iter()
                .map(|p| Tensor::from_slice(p).view([h as i64, w as i64]))
                .collect();
            targets.push(ImageTargets {
                weights: Tensor::stack(&planes, 0).to_device(device),
                roi: Tensor::from_slice(&s.roi)
                    .view([h as i64, w as i64])
                    .to_device(device),
            });
        }
        Self {
            images: normalise_input(&Tensor::stack(&images, 0)).to_device(device),
            targets,
        }
    }
}
