//! The zero-shot bar a trained net must clear: torchvision's ImageNet
//! MobileNetV2 used as it is, with no training on our data (matseg-net's
//! `imagenet` baseline, on the pure-Rust engine).
//!
//! A photo is resized to the nearest sides that are multiples of 32,
//! normalised with ImageNet's mean and standard deviation and run through
//! the encoder; the outputs of `features.3`, `features.6` and `features.13`
//! (strides 4, 8 and 16; 24, 32 and 96 channels) are each resized
//! bilinearly to the photo, L2-normalised per pixel, concatenated and
//! normalised again.

use crate::encoder::MobileNetV2;
use crate::layers::{resize, rgb_planes};
use crate::model::{run, to_photo_grid};
use crate::weights::Weights;
use image::RgbImage;
use matseg_model::config::{IMAGENET_BASELINE, IMAGENET_MEAN_STD};
use matseg_model::input::nearest_multiple_of_32;
use matseg_model::ModelError;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use rayon::prelude::*;
use rten_tensor::prelude::*;
use rten_tensor::Tensor;

/// torchvision's ImageNet MobileNetV2 features as per-pixel descriptors,
/// compared by cosine.
pub struct ImagenetBaseline {
    encoder: MobileNetV2,
}

impl ImagenetBaseline {
    /// The encoder with torchvision's ImageNet weights (`tensors` named as
    /// in torchvision, e.g. from `matseg weights fetch mobilenet-v2`;
    /// `source` names them in errors).
    pub fn new(tensors: Vec<matseg_weights::Tensor>, source: &str) -> Result<Self, ModelError> {
        let weights = Weights::from_tensors(tensors, source.to_string());
        Ok(Self {
            encoder: MobileNetV2::load(&weights, "features")?,
        })
    }
}

impl DescriptorModel for ImagenetBaseline {
    fn name(&self) -> &str {
        IMAGENET_BASELINE
    }

    fn comparison(&self) -> Comparison {
        Comparison::Cosine
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        let (width, height) = (image.width() as usize, image.height() as usize);
        let grids = run(|pool| {
            let x = resize(
                pool,
                &rgb_planes(image.as_raw(), width, height, |_, level| f32::from(level)),
                nearest_multiple_of_32(height) as usize,
                nearest_multiple_of_32(width) as usize,
            );
            let taps = self.encoder.forward(pool, &imagenet_input(x));
            [&taps.s4, &taps.s8, &taps.s16].map(to_photo_grid)
        });
        let dim: usize = grids.iter().map(|g| g.dim).sum();
        let mut data = vec![0f32; width * height * dim];
        let mut offset = 0;
        for grid in &grids {
            let part = grid.pixel_map(width, height);
            data.par_chunks_mut(dim)
                .zip(part.data.par_chunks(part.dim))
                .for_each(|(pixel, values)| {
                    pixel[offset..offset + part.dim].copy_from_slice(values)
                });
            offset += part.dim;
        }
        data.par_chunks_mut(dim).for_each(|pixel| {
            let norm = pixel.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-12);
            pixel.iter_mut().for_each(|v| *v /= norm);
        });
        DescriptorMap {
            width,
            height,
            dim,
            data,
        }
    }
}

/// 0..255 levels `[1, 3, H, W]` as torchvision's ImageNet models take
/// them: scaled to 0..1, minus the mean, over the standard deviation.
fn imagenet_input(mut x: Tensor<f32>) -> Tensor<f32> {
    let plane = x.shape()[2] * x.shape()[3];
    let data = x.data_mut().expect("an operator's output is contiguous");
    for (values, &(mean, std)) in data.chunks_exact_mut(plane).zip(&IMAGENET_MEAN_STD) {
        let (mean, std) = (mean as f32, std as f32);
        values
            .iter_mut()
            .for_each(|v| *v = (*v / 255.0 - mean) / std);
    }
    x
}
