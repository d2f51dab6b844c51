//! The encoders the net can use, behind one interface: an image in, feature
//! taps at strides 4, 8, 16 and 32 out.

use crate::convnext::ConvNext;
use crate::mobilenet_v2::MobileNetV2;
pub use matseg_model::EncoderConfig;
use tch::nn;
use tch::Tensor;

/// Encoder features at strides 4, 8, 16 and 32.
#[derive(Debug)]
pub struct Taps {
    /// Stride 4.
    pub s4: Tensor,
    /// Stride 8.
    pub s8: Tensor,
    /// Stride 16.
    pub s16: Tensor,
    /// Stride 32.
    pub s32: Tensor,
}

impl Taps {
    /// From the four outputs in stride order.
    pub(crate) fn from_vec(outputs: Vec<Tensor>) -> Self {
        let [s4, s8, s16, s32]: [Tensor; 4] = outputs
            .try_into()
            .unwrap_or_else(|v: Vec<Tensor>| panic!("{} encoder taps, expected 4", v.len()));
        Self { s4, s8, s16, s32 }
    }
}

/// An encoder with its parameters.
#[derive(Debug)]
pub enum Encoder {
    /// ConvNeXt.
    Convnext(ConvNext),
    /// MobileNetV2.
    MobilenetV2(Box<MobileNetV2>),
}

impl Encoder {
    /// Creates the encoder's parameters under `p`.
    pub fn new(p: &nn::Path, config: EncoderConfig) -> Self {
        match config {
            EncoderConfig::Convnext(c) => Encoder::Convnext(ConvNext::new(p, c)),
            EncoderConfig::MobilenetV2 => Encoder::MobilenetV2(Box::new(MobileNetV2::new(p))),
        }
    }

    /// Channels at strides 4, 8, 16 and 32.
    pub fn channels(&self) -> [i64; 4] {
        match self {
            Encoder::Convnext(e) => e.channels(),
            Encoder::MobilenetV2(e) => e.channels(),
        }
    }

    /// The four taps; `train` selects batch statistics where there are any.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Taps {
        match self {
            Encoder::Convnext(e) => e.forward(x),
            Encoder::MobilenetV2(e) => e.forward_t(x, train),
        }
    }
}
