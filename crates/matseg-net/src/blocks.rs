//! Small building blocks shared by the PSP module and the decoder.

pub use matseg_model::input::nearest_multiple_of_32;
use tch::nn;
use tch::Tensor;

/// A k x k convolution (same padding, no bias) + BatchNorm + GELU.
#[derive(Debug)]
pub struct ConvBnGelu {
    conv: nn::Conv2D,
    bn: nn::BatchNorm,
}

impl ConvBnGelu {
    /// Creates the block's parameters under `p` (`conv`, `bn`).
    pub fn new<'a>(
        p: impl std::borrow::Borrow<nn::Path<'a>>,
        c_in: i64,
        c_out: i64,
        k: i64,
    ) -> Self {
        let p = p.borrow();
        let config = nn::ConvConfig {
            padding: k / 2,
            bias: false,
            ..Default::default()
        };
        Self {
            conv: nn::conv2d(p / "conv", c_in, c_out, k, config),
            bn: nn::batch_norm2d(p / "bn", c_out, Default::default()),
        }
    }

    /// Applies the block; `train` selects batch statistics for BatchNorm.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        x.apply(&self.conv).apply_t(&self.bn, train).gelu("none")
    }
}

/// Bilinear resize of an NCHW tensor to `height` x `width` (half-pixel
/// centres, as PyTorch's `align_corners=False`).
pub fn resize_bilinear(x: &Tensor, height: i64, width: i64) -> Tensor {
    x.upsample_bilinear2d([height, width], false, None, None)
}

/// L2-normalises along dimension `dim` (norms below 1e-12 are taken as 1e-12).
pub fn l2_normalise(x: &Tensor, dim: i64) -> Tensor {
    let norm = x.norm_scalaropt_dim(2, [dim], true).clamp_min(1e-12);
    x / norm
}
