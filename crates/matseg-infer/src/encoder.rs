//! The encoders (MobileNetV2 and ConvNeXt, named as matseg-net names their
//! parameters): an image in, feature taps at strides 4, 8, 16 and 32 out.

use crate::layers::{add, layer_norm_channels, Activation, Conv, ConvShape};
use crate::weights::Weights;
use matseg_model::config::{
    CONVNEXT_LAYER_NORM_EPS, MOBILENET_V2_BLOCKS, MOBILENET_V2_STEM_CHANNELS,
    MOBILENET_V2_TAP_CHANNELS, MOBILENET_V2_TAP_LAYERS,
};
use matseg_model::{ConvNextConfig, EncoderConfig, ModelError};
use rten::BufferPool;
use rten_tensor::Tensor;

/// Encoder features at strides 4, 8, 16 and 32.
pub(crate) struct Taps {
    pub s4: Tensor<f32>,
    pub s8: Tensor<f32>,
    pub s16: Tensor<f32>,
    pub s32: Tensor<f32>,
}

impl Taps {
    /// From the four outputs in stride order.
    fn from_vec(outputs: Vec<Tensor<f32>>) -> Self {
        let [s4, s8, s16, s32]: [Tensor<f32>; 4] = outputs
            .try_into()
            .unwrap_or_else(|v: Vec<_>| panic!("{} encoder taps, expected 4", v.len()));
        Self { s4, s8, s16, s32 }
    }
}

/// An encoder with its weights.
pub(crate) enum Encoder {
    MobilenetV2(Box<MobileNetV2>),
    Convnext(ConvNext),
}

impl Encoder {
    /// The encoder `config` describes, from the weights under `encoder.`.
    pub(crate) fn load(weights: &Weights, config: EncoderConfig) -> Result<Self, ModelError> {
        Ok(match config {
            EncoderConfig::MobilenetV2 => {
                Encoder::MobilenetV2(Box::new(MobileNetV2::load(weights, "encoder.features")?))
            }
            EncoderConfig::Convnext(c) => Encoder::Convnext(ConvNext::load(weights, c)?),
        })
    }

    /// The four taps of the net's input `x` (`[1, 3, H, W]`).
    pub(crate) fn forward(&self, pool: &BufferPool, x: &Tensor<f32>) -> Taps {
        match self {
            Encoder::MobilenetV2(e) => e.forward(pool, x),
            Encoder::Convnext(e) => e.forward(pool, x),
        }
    }
}

/// One inverted-residual block of MobileNetV2.
struct InvertedResidual {
    expand: Option<Conv>,
    depthwise: Conv,
    project: Conv,
    residual: bool,
}

/// MobileNetV2 as torchvision builds it (`PREFIX.N`: `encoder.features.N`
/// in a net, `features.N` in torchvision's checkpoints), its BatchNorms
/// folded into the convolutions.
pub(crate) struct MobileNetV2 {
    stem: Conv,
    blocks: Vec<InvertedResidual>,
    last: Conv,
}

impl MobileNetV2 {
    /// The encoder whose layers are named `prefix.N`.
    pub(crate) fn load(weights: &Weights, prefix: &str) -> Result<Self, ModelError> {
        let f = |i: usize| format!("{prefix}.{i}");
        let stem_channels = MOBILENET_V2_STEM_CHANNELS as usize;
        let stem = Conv::folded(
            weights,
            &format!("{}.0", f(0)),
            &format!("{}.1", f(0)),
            ConvShape {
                stride: 2,
                ..ConvShape::same(3, stem_channels, 3)
            },
            Activation::Relu6,
        )?;
        let mut blocks = Vec::new();
        let mut c_in = stem_channels;
        for (expansion, c_out, repeats, first_stride) in MOBILENET_V2_BLOCKS {
            let (expansion, c_out) = (expansion as usize, c_out as usize);
            for i in 0..repeats {
                let stride = if i == 0 { first_stride as usize } else { 1 };
                let p = format!("{}.conv", f(blocks.len() + 1));
                let hidden = c_in * expansion;
                // torchvision numbers the sub-layers consecutively, so
                // everything after an expansion layer shifts by one.
                let (expand, next) = if expansion == 1 {
                    (None, 0)
                } else {
                    let shape = ConvShape::same(c_in, hidden, 1);
                    let conv = Conv::folded(
                        weights,
                        &format!("{p}.0.0"),
                        &format!("{p}.0.1"),
                        shape,
                        Activation::Relu6,
                    )?;
                    (Some(conv), 1)
                };
                let depthwise = Conv::folded(
                    weights,
                    &format!("{p}.{next}.0"),
                    &format!("{p}.{next}.1"),
                    ConvShape {
                        stride,
                        groups: hidden,
                        ..ConvShape::same(hidden, hidden, 3)
                    },
                    Activation::Relu6,
                )?;
                let project = Conv::folded(
                    weights,
                    &format!("{p}.{}", next + 1),
                    &format!("{p}.{}", next + 2),
                    ConvShape::same(hidden, c_out, 1),
                    Activation::None,
                )?;
                blocks.push(InvertedResidual {
                    expand,
                    depthwise,
                    project,
                    residual: stride == 1 && c_in == c_out,
                });
                c_in = c_out;
            }
        }
        let last = Conv::folded(
            weights,
            &format!("{}.0", f(blocks.len() + 1)),
            &format!("{}.1", f(blocks.len() + 1)),
            ConvShape::same(c_in, MOBILENET_V2_TAP_CHANNELS[3] as usize, 1),
            Activation::Relu6,
        )?;
        Ok(Self { stem, blocks, last })
    }

    /// The four taps of an input `[1, 3, H, W]`.
    pub(crate) fn forward(&self, pool: &BufferPool, x: &Tensor<f32>) -> Taps {
        let mut outputs = Vec::with_capacity(4);
        let mut x = self.stem.forward(pool, x);
        for (i, block) in self.blocks.iter().enumerate() {
            let expanded = block.expand.as_ref().map(|e| e.forward(pool, &x));
            let hidden = block
                .depthwise
                .forward(pool, expanded.as_ref().unwrap_or(&x));
            let y = block.project.forward(pool, &hidden);
            x = if block.residual { add(pool, &x, &y) } else { y };
            if MOBILENET_V2_TAP_LAYERS.contains(&(i + 1)) {
                outputs.push(x.clone());
            }
        }
        outputs.push(self.last.forward(pool, &x));
        Taps::from_vec(outputs)
    }
}

/// LayerNorm over the channels, with its scale and bias.
struct ChannelNorm {
    scale: Vec<f32>,
    bias: Vec<f32>,
}

impl ChannelNorm {
    fn load(weights: &Weights, name: &str, channels: usize) -> Result<Self, ModelError> {
        Ok(Self {
            scale: weights.get(&format!("{name}.weight"), &[channels])?,
            bias: weights.get(&format!("{name}.bias"), &[channels])?,
        })
    }

    fn apply(&self, x: &mut Tensor<f32>) {
        layer_norm_channels(x, &self.scale, &self.bias, CONVNEXT_LAYER_NORM_EPS as f32);
    }
}

/// One ConvNeXt block: 7x7 depthwise conv, LayerNorm, 4x MLP with GELU
/// (as 1x1 convolutions), layer scale (folded into the second), residual.
struct ConvNextBlock {
    depthwise: Conv,
    norm: ChannelNorm,
    expand: Conv,
    project: Conv,
}

impl ConvNextBlock {
    fn load(weights: &Weights, p: &str, dim: usize) -> Result<Self, ModelError> {
        let depthwise = Conv::with_bias(
            weights,
            &format!("{p}.dwconv"),
            ConvShape {
                groups: dim,
                ..ConvShape::same(dim, dim, 7)
            },
            Activation::None,
        )?;
        let linear = |name: &str, c_in: usize, c_out: usize| {
            Ok::<_, ModelError>((
                weights.get(&format!("{p}.{name}.weight"), &[c_out, c_in])?,
                weights.get(&format!("{p}.{name}.bias"), &[c_out])?,
            ))
        };
        let (w1, b1) = linear("pwconv1", dim, 4 * dim)?;
        let (mut w2, mut b2) = linear("pwconv2", 4 * dim, dim)?;
        let gamma = weights.get(&format!("{p}.gamma"), &[dim])?;
        for (o, g) in gamma.iter().enumerate() {
            w2[o * 4 * dim..(o + 1) * 4 * dim]
                .iter_mut()
                .for_each(|v| *v *= g);
            b2[o] *= g;
        }
        Ok(Self {
            depthwise,
            norm: ChannelNorm::load(weights, &format!("{p}.norm"), dim)?,
            expand: Conv::new(w1, b1, ConvShape::same(dim, 4 * dim, 1), Activation::Gelu),
            project: Conv::new(w2, b2, ConvShape::same(4 * dim, dim, 1), Activation::None),
        })
    }

    fn forward(&self, pool: &BufferPool, x: &Tensor<f32>) -> Tensor<f32> {
        let mut y = self.depthwise.forward(pool, x);
        self.norm.apply(&mut y);
        let y = self.project.forward(pool, &self.expand.forward(pool, &y));
        add(pool, x, &y)
    }
}

/// A patchifying convolution with its LayerNorm: before it (between
/// stages) or after it (the stem).
struct Downsample {
    conv: Conv,
    norm: ChannelNorm,
    norm_first: bool,
}

/// ConvNeXt (`encoder.downsample_layers.I`, `encoder.stages.I.J`).
pub(crate) struct ConvNext {
    downsample: Vec<Downsample>,
    stages: Vec<Vec<ConvNextBlock>>,
}

impl ConvNext {
    fn load(weights: &Weights, config: ConvNextConfig) -> Result<Self, ModelError> {
        let dims = config.dims.map(|d| d as usize);
        let mut downsample = Vec::with_capacity(4);
        let mut stages = Vec::with_capacity(4);
        for i in 0..4 {
            let d = format!("encoder.downsample_layers.{i}");
            let patch = |c_in: usize, k: usize, name: &str| {
                let shape = ConvShape {
                    stride: k,
                    valid: true,
                    ..ConvShape::same(c_in, dims[i], k)
                };
                Conv::with_bias(weights, name, shape, Activation::None)
            };
            downsample.push(if i == 0 {
                Downsample {
                    conv: patch(3, 4, &format!("{d}.0"))?,
                    norm: ChannelNorm::load(weights, &format!("{d}.1"), dims[0])?,
                    norm_first: false,
                }
            } else {
                Downsample {
                    norm: ChannelNorm::load(weights, &format!("{d}.0"), dims[i - 1])?,
                    conv: patch(dims[i - 1], 2, &format!("{d}.1"))?,
                    norm_first: true,
                }
            });
            let blocks = (0..config.depths[i] as usize)
                .map(|j| ConvNextBlock::load(weights, &format!("encoder.stages.{i}.{j}"), dims[i]))
                .collect::<Result<_, _>>()?;
            stages.push(blocks);
        }
        Ok(Self { downsample, stages })
    }

    fn forward(&self, pool: &BufferPool, x: &Tensor<f32>) -> Taps {
        let mut outputs = Vec::with_capacity(4);
        let mut x = x.clone();
        for (down, blocks) in self.downsample.iter().zip(&self.stages) {
            if down.norm_first {
                down.norm.apply(&mut x);
                x = down.conv.forward(pool, &x);
            } else {
                x = down.conv.forward(pool, &x);
                down.norm.apply(&mut x);
            }
            for block in blocks {
                x = block.forward(pool, &x);
            }
            outputs.push(x.clone());
        }
        Taps::from_vec(outputs)
    }
}
