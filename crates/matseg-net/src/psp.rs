//! The pyramid pooling module on the stride-32 features (pipeline.md §8): branches
//! at scales 1, 1/2, 1/4 and 1/8 (average pooling, conv3x3 + BN + GELU,
//! bilinear back), concatenated, then conv3x3 + BN + GELU.

use crate::blocks::{resize_bilinear, ConvBnGelu};
use tch::nn;
use tch::Tensor;

pub use matseg_model::config::PSP_SCALES;

/// The pyramid pooling module.
#[derive(Debug)]
pub struct Psp {
    branches: Vec<ConvBnGelu>,
    fuse: ConvBnGelu,
}

impl Psp {
    /// Parameters under `p` (`branches.I`, `fuse`): `c_in` channels in,
    /// `branch` per branch, `c_out` out.
    pub fn new(p: &nn::Path, c_in: i64, branch: i64, c_out: i64) -> Self {
        let b = p / "branches";
        Self {
            branches: (0..PSP_SCALES.len())
                .map(|i| ConvBnGelu::new(&b / i, c_in, branch, 3))
                .collect(),
            fuse: ConvBnGelu::new(p / "fuse", branch * PSP_SCALES.len() as i64, c_out, 3),
        }
    }

    /// Applies the module to `[N, c_in, h, w]`, giving `[N, c_out, h, w]`.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        let (_, _, h, w) = x.size4().expect("an NCHW tensor");
        let outputs: Vec<Tensor> = self
            .branches
            .iter()
            .zip(PSP_SCALES)
            .map(|(branch, scale)| {
                if scale == 1.0 {
                    return branch.forward_t(x, train);
                }
                let side = |n: i64| ((n as f64 * scale).round() as i64).max(1);
                let pooled = x.adaptive_avg_pool2d([side(h), side(w)]);
                resize_bilinear(&branch.forward_t(&pooled, train), h, w)
            })
            .collect();
        self.fuse.forward_t(&Tensor::cat(&outputs, 1), train)
    }
}
