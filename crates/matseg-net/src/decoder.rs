//! The decoder (pipeline.md §8): three steps from the PSP output at stride 32 to
//! stride 4; each is conv3x3 + BN + GELU, bilinear x2 (to the skip's exact
//! size), plus the skip: conv1x1 + BN + GELU of the encoder tap.

use crate::blocks::{resize_bilinear, ConvBnGelu};
use crate::encoder::Taps;
use tch::nn;
use tch::Tensor;

/// One decoder step.
#[derive(Debug)]
struct Step {
    conv: ConvBnGelu,
    skip: ConvBnGelu,
}

/// The three decoder steps.
#[derive(Debug)]
pub struct Decoder {
    steps: Vec<Step>,
}

impl Decoder {
    /// Parameters under `p` (`steps.I.conv`, `steps.I.skip`): `c_in` channels
    /// from the PSP, `widths` out of the three steps, `taps` the encoder's
    /// channels at strides 4, 8, 16 (and 32, unused here).
    pub fn new(p: &nn::Path, c_in: i64, widths: [i64; 3], taps: [i64; 4]) -> Self {
        let s = p / "steps";
        let skips = [taps[2], taps[1], taps[0]];
        let mut c = c_in;
        let steps = widths
            .iter()
            .zip(skips)
            .enumerate()
            .map(|(i, (&width, skip))| {
                let step = &s / i;
                let out = Step {
                    conv: ConvBnGelu::new(&step / "conv", c, width, 3),
                    skip: ConvBnGelu::new(&step / "skip", skip, width, 1),
                };
                c = width;
                out
            })
            .collect();
        Self { steps }
    }

    /// From the PSP output at stride 32 to features at stride 4.
    pub fn forward_t(&self, psp: &Tensor, taps: &Taps, train: bool) -> Tensor {
        let skips = [&taps.s16, &taps.s8, &taps.s4];
        let mut x = psp.shallow_clone();
        for (step, skip) in self.steps.iter().zip(skips) {
            let (_, _, h, w) = skip.size4().expect("an NCHW tensor");
            x = resize_bilinear(&step.conv.forward_t(&x, train), h, w)
                + step.skip.forward_t(skip, train);
        }
        x
    }
}
