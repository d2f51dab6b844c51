//! The zero-shot bar a trained net must clear: torchvision's ImageNet
//! MobileNetV2 used as it is, with no training on our data.
//!
//! A photo is normalised with ImageNet's mean and standard deviation and run
//! through the encoder; the outputs of `features.3`, `features.6` and
//! `features.13` (strides 4, 8 and 16; 24, 32 and 96 channels) are each
//! resized bilinearly to the photo, L2-normalised per pixel, concatenated
//! and normalised again. Points are then pooled and compared by cosine, as
//! for the net.

use crate::blocks::{l2_normalise, nearest_multiple_of_32, resize_bilinear};
use crate::infer::{PixelDescriptors, TorchModel};
use crate::mobilenet_v2::{MobileNetV2, IMAGENET_MEAN_STD, TAP_CHANNELS};
use crate::net::rgb8_to_tensor;
use crate::weights::load_named;
use crate::NetError;
use tch::{nn, Device, Tensor};

pub use matseg_model::config::IMAGENET_BASELINE;

/// Channels of the descriptor: the three taps side by side.
pub const IMAGENET_DIM: i64 = TAP_CHANNELS[0] + TAP_CHANNELS[1] + TAP_CHANNELS[2];

/// ImageNet MobileNetV2 features as per-pixel descriptors.
pub struct ImagenetFeatures {
    vs: nn::VarStore,
    encoder: MobileNetV2,
}

impl ImagenetFeatures {
    /// The encoder with torchvision's ImageNet weights (`tensors` named as
    /// in torchvision, e.g. from `matseg weights fetch mobilenet-v2`;
    /// `source` names them in errors).
    pub fn new(
        tensors: &[matseg_weights::Tensor],
        source: &str,
        device: Device,
    ) -> Result<Self, NetError> {
        let vs = nn::VarStore::new(device);
        let encoder = MobileNetV2::new(&vs.root());
        load_named(&vs, "", tensors, source)?;
        Ok(Self { vs, encoder })
    }

    /// The three taps `[N, C, H/s, W/s]` (strides s = 4, 8, 16) of 0..255
    /// RGB images `[N, 3, H, W]` whose sides are multiples of 32, in
    /// inference mode, on the encoder's device.
    pub fn taps(&self, rgb: &Tensor) -> [Tensor; 3] {
        let x = imagenet_input(&rgb.to_device(self.vs.device()));
        let taps = tch::no_grad(|| self.encoder.forward_t(&x, false));
        [taps.s4, taps.s8, taps.s16]
    }

    /// Unit descriptors `[IMAGENET_DIM, height, width]` of an interleaved
    /// RGB image on the CPU: computed at the nearest size with sides
    /// multiple of 32, each tap resized to `height` x `width` and
    /// normalised, then concatenated and normalised again.
    pub fn describe(&self, rgb: &[u8], width: usize, height: usize) -> Tensor {
        let x = rgb8_to_tensor(rgb, width, height).unsqueeze(0);
        let x = resize_bilinear(
            &x,
            nearest_multiple_of_32(height),
            nearest_multiple_of_32(width),
        );
        tch::no_grad(|| {
            let parts: Vec<Tensor> = self
                .taps(&x)
                .iter()
                .map(|t| l2_normalise(&resize_bilinear(t, height as i64, width as i64), 1))
                .collect();
            l2_normalise(&Tensor::cat(&parts, 1), 1)
                .squeeze_dim(0)
                .to_device(Device::Cpu)
        })
    }
}

/// `[N, 3, H, W]` 0..255 RGB as torchvision's ImageNet models expect it:
/// scaled to 0..1, minus the mean, over the standard deviation, per channel.
fn imagenet_input(rgb: &Tensor) -> Tensor {
    let (mean, std): (Vec<f64>, Vec<f64>) = IMAGENET_MEAN_STD.iter().copied().unzip();
    let per_channel = |v: Vec<f64>| {
        Tensor::from_slice(&v)
            .to_kind(rgb.kind())
            .to_device(rgb.device())
            .view([1, 3, 1, 1])
    };
    (rgb / 255.0 - per_channel(mean)) / per_channel(std)
}

impl PixelDescriptors for ImagenetFeatures {
    fn describe_rgb(&self, rgb: &[u8], width: usize, height: usize) -> Tensor {
        self.describe(rgb, width, height)
    }
}

/// The ImageNet features as an evaluated model, compared by cosine.
pub type ImagenetBaseline = TorchModel<ImagenetFeatures>;

impl ImagenetBaseline {
    /// The baseline named [`IMAGENET_BASELINE`] over `features`.
    pub fn imagenet(features: ImagenetFeatures) -> Self {
        Self::new(IMAGENET_BASELINE, features)
    }
}
