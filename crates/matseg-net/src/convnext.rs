//! ConvNeXt (Liu et al. 2022) as a feature encoder: a 4x4 stride-4 stem and
//! three 2x2 stride-2 downsamplings between four stages of blocks
//! (7x7 depthwise conv, LayerNorm, 4x MLP with GELU, layer scale, residual).
//!
//! Parameter names follow the authors' release (`downsample_layers.I.J`,
//! `stages.I.J.{dwconv,norm,pwconv1,pwconv2,gamma}`), so their ImageNet
//! checkpoints, converted to safetensors, load by name.

use crate::encoder::Taps;
pub use matseg_model::ConvNextConfig;
use tch::nn;
use tch::Tensor;

use matseg_model::config::CONVNEXT_LAYER_NORM_EPS as LAYER_NORM_EPS;
/// Initial layer-scale value of the reference implementation.
const LAYER_SCALE_INIT: f64 = 1e-6;

/// LayerNorm over the channels of an NCHW tensor.
#[derive(Debug)]
struct ChannelNorm(nn::LayerNorm);

impl ChannelNorm {
    fn new(p: nn::Path, channels: i64) -> Self {
        let config = nn::LayerNormConfig {
            eps: LAYER_NORM_EPS,
            ..Default::default()
        };
        Self(nn::layer_norm(p, vec![channels], config))
    }

    fn forward(&self, x: &Tensor) -> Tensor {
        x.permute([0, 2, 3, 1]).apply(&self.0).permute([0, 3, 1, 2])
    }
}

/// One ConvNeXt block.
#[derive(Debug)]
struct Block {
    dwconv: nn::Conv2D,
    norm: nn::LayerNorm,
    pwconv1: nn::Linear,
    pwconv2: nn::Linear,
    gamma: Tensor,
}

impl Block {
    fn new(p: nn::Path, dim: i64) -> Self {
        let dw = nn::ConvConfig {
            padding: 3,
            groups: dim,
            ..Default::default()
        };
        let norm = nn::LayerNormConfig {
            eps: LAYER_NORM_EPS,
            ..Default::default()
        };
        Self {
            dwconv: nn::conv2d(&p / "dwconv", dim, dim, 7, dw),
            norm: nn::layer_norm(&p / "norm", vec![dim], norm),
            pwconv1: nn::linear(&p / "pwconv1", dim, 4 * dim, Default::default()),
            pwconv2: nn::linear(&p / "pwconv2", 4 * dim, dim, Default::default()),
            gamma: p.var("gamma", &[dim], nn::Init::Const(LAYER_SCALE_INIT)),
        }
    }

    fn forward(&self, x: &Tensor) -> Tensor {
        let y = x
            .apply(&self.dwconv)
            .permute([0, 2, 3, 1])
            .apply(&self.norm)
            .apply(&self.pwconv1)
            .gelu("none")
            .apply(&self.pwconv2)
            * &self.gamma;
        x + y.permute([0, 3, 1, 2])
    }
}

/// The stem (stage 0) or a downsampling layer between stages.
#[derive(Debug)]
enum Downsample {
    /// 4x4 stride-4 conv, then LayerNorm.
    Stem(nn::Conv2D, ChannelNorm),
    /// LayerNorm, then 2x2 stride-2 conv.
    Between(ChannelNorm, nn::Conv2D),
}

impl Downsample {
    fn forward(&self, x: &Tensor) -> Tensor {
        match self {
            Downsample::Stem(conv, norm) => norm.forward(&x.apply(conv)),
            Downsample::Between(norm, conv) => norm.forward(x).apply(conv),
        }
    }
}

/// A ConvNeXt feature encoder (no classifier head).
#[derive(Debug)]
pub struct ConvNext {
    downsample: Vec<Downsample>,
    stages: Vec<Vec<Block>>,
    config: ConvNextConfig,
}

impl ConvNext {
    /// Creates the encoder's parameters under `p`.
    pub fn new(p: &nn::Path, config: ConvNextConfig) -> Self {
        let d = p / "downsample_layers";
        let s = p / "stages";
        let dims = config.dims;
        let mut downsample = Vec::with_capacity(4);
        let mut stages = Vec::with_capacity(4);
        for i in 0..4 {
            let layer = &d / i;
            downsample.push(if i == 0 {
                let stem = nn::ConvConfig {
                    stride: 4,
                    ..Default::default()
                };
                Downsample::Stem(
                    nn::conv2d(&layer / 0, 3, dims[0], 4, stem),
                    ChannelNorm::new(&layer / 1, dims[0]),
                )
            } else {
                let down = nn::ConvConfig {
                    stride: 2,
                    ..Default::default()
                };
                Downsample::Between(
                    ChannelNorm::new(&layer / 0, dims[i - 1]),
                    nn::conv2d(&layer / 1, dims[i - 1], dims[i], 2, down),
                )
            });
            let stage = &s / i;
            stages.push(
                (0..config.depths[i])
                    .map(|j| Block::new(&stage / j, dims[i]))
                    .collect(),
            );
        }
        Self {
            downsample,
            stages,
            config,
        }
    }

    /// Channels at strides 4, 8, 16 and 32.
    pub fn channels(&self) -> [i64; 4] {
        self.config.dims
    }

    /// The four stage outputs (LayerNorm has no batch statistics, so there
    /// is no train/eval difference).
    pub fn forward(&self, x: &Tensor) -> Taps {
        let mut outputs = Vec::with_capacity(4);
        let mut x = x.shallow_clone();
        for (down, blocks) in self.downsample.iter().zip(&self.stages) {
            x = down.forward(&x);
            for block in blocks {
                x = block.forward(&x);
            }
            outputs.push(x.shallow_clone());
        }
        Taps::from_vec(outputs)
    }
}
