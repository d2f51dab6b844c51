//! MobileNetV2 (Sandler et al. 2018) as torchvision builds it, so that
//! torchvision's ImageNet checkpoint (the registry package of docs/assets.md,
//! imported by `matseg weights`) loads by parameter name: `features.0` is the
//! stride-2 stem, `features.1..=17` the inverted-residual blocks,
//! `features.18` the 1x1 conv to 1280 channels, `classifier.1` the ImageNet
//! classifier.

use crate::encoder::Taps;
use tch::nn;
use tch::Tensor;

/// Channels of the taps at strides 4, 8, 16 and 32.
pub use matseg_model::config::MOBILENET_V2_TAP_CHANNELS as TAP_CHANNELS;
use matseg_model::config::{
    MOBILENET_V2_BLOCKS as INVERTED_RESIDUALS, MOBILENET_V2_STEM_CHANNELS as STEM_CHANNELS,
    MOBILENET_V2_TAP_LAYERS as TAP_LAYERS,
};
/// Channels of the last 1x1 conv (`features.18`).
const LAST_CHANNELS: i64 = TAP_CHANNELS[3];
/// ImageNet classes of the classifier.
pub const IMAGENET_CLASSES: i64 = 1000;

/// Conv (no bias) + BatchNorm + ReLU6, named `P.0` and `P.1`.
#[derive(Debug)]
struct ConvBnRelu6 {
    conv: nn::Conv2D,
    bn: nn::BatchNorm,
}

impl ConvBnRelu6 {
    fn new(p: nn::Path, c_in: i64, c_out: i64, k: i64, stride: i64, groups: i64) -> Self {
        let config = nn::ConvConfig {
            stride,
            padding: k / 2,
            groups,
            bias: false,
            ..Default::default()
        };
        Self {
            conv: nn::conv2d(&p / 0, c_in, c_out, k, config),
            bn: nn::batch_norm2d(&p / 1, c_out, Default::default()),
        }
    }

    fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        x.apply(&self.conv).apply_t(&self.bn, train).clamp(0.0, 6.0)
    }
}

/// An inverted-residual block: optional 1x1 expansion, 3x3 depthwise conv,
/// linear 1x1 projection, residual when shapes allow.
#[derive(Debug)]
struct InvertedResidual {
    expand: Option<ConvBnRelu6>,
    depthwise: ConvBnRelu6,
    project: nn::Conv2D,
    project_bn: nn::BatchNorm,
    residual: bool,
}

impl InvertedResidual {
    fn new(p: nn::Path, c_in: i64, c_out: i64, stride: i64, expansion: i64) -> Self {
        let conv = &p / "conv";
        let hidden = c_in * expansion;
        // torchvision numbers the sub-layers consecutively, so everything
        // after an expansion layer shifts by one.
        let (expand, next) = if expansion == 1 {
            (None, 0)
        } else {
            (Some(ConvBnRelu6::new(&conv / 0, c_in, hidden, 1, 1, 1)), 1)
        };
        let no_bias = nn::ConvConfig {
            bias: false,
            ..Default::default()
        };
        Self {
            expand,
            depthwise: ConvBnRelu6::new(&conv / next, hidden, hidden, 3, stride, hidden),
            project: nn::conv2d(&conv / (next + 1), hidden, c_out, 1, no_bias),
            project_bn: nn::batch_norm2d(&conv / (next + 2), c_out, Default::default()),
            residual: stride == 1 && c_in == c_out,
        }
    }

    fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        let hidden = match &self.expand {
            Some(expand) => expand.forward_t(x, train),
            None => x.shallow_clone(),
        };
        let y = self
            .depthwise
            .forward_t(&hidden, train)
            .apply(&self.project)
            .apply_t(&self.project_bn, train);
        if self.residual {
            x + y
        } else {
            y
        }
    }
}

/// MobileNetV2's `features` as an encoder (width multiplier 1):
/// `features.0` is `stem`, `features.1..=17` are `blocks`, `features.18` is
/// `last`.
#[derive(Debug)]
pub struct MobileNetV2 {
    stem: ConvBnRelu6,
    blocks: Vec<InvertedResidual>,
    last: ConvBnRelu6,
}

impl MobileNetV2 {
    /// Creates the parameters under `p` (`p/features/...`).
    pub fn new(p: &nn::Path) -> Self {
        let f = p / "features";
        let stem = ConvBnRelu6::new(&f / 0, 3, STEM_CHANNELS, 3, 2, 1);
        let mut blocks = Vec::new();
        let mut c_in = STEM_CHANNELS;
        for (t, c, n, s) in INVERTED_RESIDUALS {
            for i in 0..n {
                let stride = if i == 0 { s } else { 1 };
                let index = blocks.len() + 1;
                blocks.push(InvertedResidual::new(&f / index, c_in, c, stride, t));
                c_in = c;
            }
        }
        let last = ConvBnRelu6::new(&f / (blocks.len() + 1), c_in, LAST_CHANNELS, 1, 1, 1);
        Self { stem, blocks, last }
    }

    /// Channels at strides 4, 8, 16 and 32.
    pub fn channels(&self) -> [i64; 4] {
        TAP_CHANNELS
    }

    /// The taps at strides 4, 8, 16 and 32.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Taps {
        let mut outputs = Vec::with_capacity(4);
        let mut x = self.stem.forward_t(x, train);
        for (i, block) in self.blocks.iter().enumerate() {
            x = block.forward_t(&x, train);
            if TAP_LAYERS.contains(&(i + 1)) {
                outputs.push(x.shallow_clone());
            }
        }
        outputs.push(self.last.forward_t(&x, train));
        Taps::from_vec(outputs)
    }
}

/// MobileNetV2 with torchvision's ImageNet classifier: used to check that
/// imported ImageNet weights are wired correctly.
#[derive(Debug)]
pub struct MobileNetV2Classifier {
    /// The feature layers.
    pub encoder: MobileNetV2,
    classifier: nn::Linear,
}

pub use matseg_model::config::IMAGENET_MEAN_STD;

impl MobileNetV2Classifier {
    /// Creates the parameters under `p` (`features...`, `classifier.1`).
    pub fn new(p: &nn::Path) -> Self {
        Self {
            encoder: MobileNetV2::new(p),
            classifier: nn::linear(
                p / "classifier" / 1,
                LAST_CHANNELS,
                IMAGENET_CLASSES,
                Default::default(),
            ),
        }
    }

    /// ImageNet logits `[N, 1000]` of images preprocessed with
    /// [`IMAGENET_MEAN_STD`] (inference mode: dropout is the identity).
    pub fn logits(&self, x: &Tensor) -> Tensor {
        let features = self.encoder.forward_t(x, false).s32;
        features
            .adaptive_avg_pool2d([1, 1])
            .flatten(1, -1)
            .apply(&self.classifier)
    }
}
