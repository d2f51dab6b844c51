//! The whole net on one image at its own size: encoder, PSP module,
//! decoder and head, and the descriptor's parts (matseg-net's
//! `MaterialNet::coarse_t`, in inference mode).

use crate::colour::ColourPart;
use crate::encoder::{Encoder, Taps};
use crate::layers::{
    adaptive_average_pool, normalise_pixels, resize, rgb_planes, Activation, Conv, ConvShape,
};
use crate::weights::Weights;
use matseg_model::config::PSP_SCALES;
use matseg_model::input::{INPUT_MEAN, INPUT_SCALE};
use matseg_model::{ModelError, NetConfig};
use rten::ops;
use rten::BufferPool;
use rten_tensor::prelude::*;
use rten_tensor::Tensor;

/// A conv3x3 or conv1x1 + BatchNorm + GELU block of the PSP module or the
/// decoder (`P.conv`, `P.bn`).
fn conv_bn_gelu(
    weights: &Weights,
    p: &str,
    c_in: i64,
    c_out: i64,
    k: usize,
) -> Result<Conv, ModelError> {
    Conv::folded(
        weights,
        &format!("{p}.conv"),
        &format!("{p}.bn"),
        ConvShape::same(c_in as usize, c_out as usize, k),
        Activation::Gelu,
    )
}

/// One decoder step: its conv on the coarser features, its skip on the
/// encoder's tap.
struct Step {
    conv: Conv,
    skip: Conv,
}

/// The net with its weights.
pub(crate) struct Net {
    config: NetConfig,
    encoder: Encoder,
    psp_branches: Vec<Conv>,
    psp_fuse: Conv,
    steps: Vec<Step>,
    head: Conv,
    /// Weights of the head's output and the taps at strides 4, 8, 16 in
    /// the descriptor, with [`NetConfig::encoder_features`].
    part_weights: Option<Vec<f32>>,
    colour: Option<ColourPart>,
}

impl Net {
    /// The net `config` describes, from `weights`.
    pub(crate) fn load(weights: &Weights, config: NetConfig) -> Result<Self, ModelError> {
        let taps = config.encoder.tap_channels();
        let encoder = Encoder::load(weights, config.encoder)?;
        let psp_branches = (0..PSP_SCALES.len())
            .map(|i| {
                let p = format!("psp.branches.{i}");
                conv_bn_gelu(weights, &p, taps[3], config.psp_branch, 3)
            })
            .collect::<Result<_, _>>()?;
        let branches = config.psp_branch * PSP_SCALES.len() as i64;
        let psp_fuse = conv_bn_gelu(weights, "psp.fuse", branches, config.psp_out, 3)?;
        let mut c = config.psp_out;
        let mut steps = Vec::with_capacity(3);
        for (i, (&width, skip)) in config
            .decoder
            .iter()
            .zip([taps[2], taps[1], taps[0]])
            .enumerate()
        {
            let p = format!("decoder.steps.{i}");
            steps.push(Step {
                conv: conv_bn_gelu(weights, &format!("{p}.conv"), c, width, 3)?,
                skip: conv_bn_gelu(weights, &format!("{p}.skip"), skip, width, 1)?,
            });
            c = width;
        }
        let head = Conv::with_bias(
            weights,
            "head",
            ConvShape::same(c as usize, config.descriptor_dim as usize, 1),
            Activation::None,
        )?;
        let part_weights = if config.encoder_features {
            let logs = weights.get("part_log_weights", &[4])?;
            Some(logs.iter().map(|l| l.exp()).collect())
        } else {
            None
        };
        let colour = if config.colour_features {
            Some(ColourPart::load(weights)?)
        } else {
            None
        };
        Ok(Self {
            config,
            encoder,
            psp_branches,
            psp_fuse,
            steps,
            head,
            part_weights,
            colour,
        })
    }

    /// Channels of the descriptors.
    pub(crate) fn output_dim(&self) -> usize {
        self.config.output_dim() as usize
    }

    /// Descriptors `[1, D, H/4, W/4]` on the stride-4 grid, not yet
    /// normalised, of an interleaved RGB image whose sides are multiples
    /// of 32.
    pub(crate) fn coarse(
        &self,
        pool: &BufferPool,
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Tensor<f32> {
        let x = input_tensor(rgb, width, height);
        let taps = self.encoder.forward(pool, &x);
        let learned = self.head.forward(pool, &self.decode(pool, &taps));
        if self.part_weights.is_none() && self.colour.is_none() {
            return learned;
        }
        let (h4, w4) = (learned.shape()[2], learned.shape()[3]);
        let mut parts = match &self.part_weights {
            Some(weights) => [&learned, &taps.s4, &taps.s8, &taps.s16]
                .iter()
                .zip(weights)
                .map(|(t, &weight)| {
                    let mut part = resize(pool, t, h4, w4);
                    normalise_pixels(&mut part, weight);
                    part
                })
                .collect(),
            None => {
                let mut part = learned;
                normalise_pixels(&mut part, 1.0);
                vec![part]
            }
        };
        if let Some(colour) = &self.colour {
            let planes = colour.forward(rgb, width, height);
            parts.push(Tensor::from_data(
                &[1, planes.len() / (h4 * w4), h4, w4],
                planes,
            ));
        }
        let views: Vec<_> = parts.iter().map(|t| t.view()).collect();
        ops::concat(pool, &views, 1).expect("parts on one grid")
    }

    /// The PSP module and the decoder: from the encoder's taps to features
    /// at stride 4.
    fn decode(&self, pool: &BufferPool, taps: &Taps) -> Tensor<f32> {
        let s32 = &taps.s32;
        let (h, w) = (s32.shape()[2], s32.shape()[3]);
        let branches: Vec<Tensor<f32>> = self
            .psp_branches
            .iter()
            .zip(PSP_SCALES)
            .map(|(branch, scale)| {
                if scale == 1.0 {
                    return branch.forward(pool, s32);
                }
                let side = |n: usize| ((n as f64 * scale).round() as usize).max(1);
                let pooled = adaptive_average_pool(pool, s32, side(h), side(w));
                resize(pool, &branch.forward(pool, &pooled), h, w)
            })
            .collect();
        let views: Vec<_> = branches.iter().map(|t| t.view()).collect();
        let cat = ops::concat(pool, &views, 1).expect("branches on one grid");
        let mut x = self.psp_fuse.forward(pool, &cat);
        for (step, skip) in self.steps.iter().zip([&taps.s16, &taps.s8, &taps.s4]) {
            let (sh, sw) = (skip.shape()[2], skip.shape()[3]);
            let up = resize(pool, &step.conv.forward(pool, &x), sh, sw);
            x = crate::layers::add(pool, &up, &step.skip.forward(pool, skip));
        }
        x
    }
}

/// The net's input `[1, 3, H, W]` of an interleaved RGB image:
/// `(level - INPUT_MEAN) / INPUT_SCALE` per channel.
fn input_tensor(rgb: &[u8], width: usize, height: usize) -> Tensor<f32> {
    rgb_planes(rgb, width, height, |c, level| {
        ((f64::from(level) - INPUT_MEAN[c]) / INPUT_SCALE) as f32
    })
}
