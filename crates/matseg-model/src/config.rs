//! The shape of a net: stored in every run's `run.json` and checkpoint.

use serde::{Deserialize, Serialize};

/// Descriptor channels of the paper's net.
pub const DESCRIPTOR_DIM: i64 = 128;

/// Random Fourier features of a cell's colour in the colour part of a
/// descriptor ([`NetConfig::colour_features`]).
pub const COLOUR_FEATURES: i64 = 128;

/// Channels of MobileNetV2's features at strides 4, 8, 16 and 32 (the last
/// after its 1x1 conv to 1280 channels).
pub const MOBILENET_V2_TAP_CHANNELS: [i64; 4] = [24, 32, 96, 1280];

/// MobileNetV2's inverted-residual stages as torchvision builds them:
/// (expansion, output channels, blocks, stride of the first block).
pub const MOBILENET_V2_BLOCKS: [(i64, i64, usize, i64); 7] = [
    (1, 16, 1, 1),
    (6, 24, 2, 2),
    (6, 32, 3, 2),
    (6, 64, 4, 2),
    (6, 96, 3, 1),
    (6, 160, 3, 2),
    (6, 320, 1, 1),
];

/// MobileNetV2's stem output channels.
pub const MOBILENET_V2_STEM_CHANNELS: i64 = 32;

/// The `features` indices of MobileNetV2 whose outputs are the taps at
/// strides 4, 8 and 16 (the stride-32 tap is the last layer,
/// `features.18`).
pub const MOBILENET_V2_TAP_LAYERS: [usize; 3] = [3, 6, 13];

/// torchvision's ImageNet normalisation: (mean, standard deviation) of
/// each RGB channel in 0..1.
pub const IMAGENET_MEAN_STD: [(f64, f64); 3] = [(0.485, 0.229), (0.456, 0.224), (0.406, 0.225)];

/// The name of the ImageNet MobileNetV2 feature baseline in result tables
/// and on the command line.
pub const IMAGENET_BASELINE: &str = "imagenet";

/// ConvNeXt's LayerNorm epsilon (the reference implementation's).
pub const CONVNEXT_LAYER_NORM_EPS: f64 = 1e-6;

/// The scales of the PSP module's branches on the stride-32 features.
pub const PSP_SCALES: [f64; 4] = [1.0, 0.5, 0.25, 0.125];

/// Softmax temperature of the cosine similarities in the net's loss, and
/// of a similarity's strength when a selection is drawn.
pub const TEMPERATURE: f64 = 0.2;

/// The named configurations `--encoder` accepts.
pub const PRESETS: [&str; 3] = ["mobilenet-v2", "convnext-tiny", "convnext-base"];

/// Depths and widths of ConvNeXt's four stages.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ConvNextConfig {
    /// Blocks per stage.
    pub depths: [i64; 4],
    /// Channels per stage (strides 4, 8, 16, 32).
    pub dims: [i64; 4],
}

impl ConvNextConfig {
    /// ConvNeXt-T: 28 M parameters.
    pub const TINY: Self = Self {
        depths: [3, 3, 9, 3],
        dims: [96, 192, 384, 768],
    };
    /// ConvNeXt-B, the paper's encoder: 88 M parameters.
    pub const BASE: Self = Self {
        depths: [3, 3, 27, 3],
        dims: [128, 256, 512, 1024],
    };
}

/// Which encoder, with its shape: stored in every checkpoint's config.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum EncoderConfig {
    /// ConvNeXt with the given depths and widths.
    Convnext(ConvNextConfig),
    /// torchvision's MobileNetV2 (width 1).
    MobilenetV2,
}

impl EncoderConfig {
    /// Channels of the encoder's features at strides 4, 8, 16 and 32.
    pub fn tap_channels(self) -> [i64; 4] {
        match self {
            EncoderConfig::Convnext(c) => c.dims,
            EncoderConfig::MobilenetV2 => MOBILENET_V2_TAP_CHANNELS,
        }
    }
}

/// The shape of a net: stored with every checkpoint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetConfig {
    /// The encoder.
    pub encoder: EncoderConfig,
    /// Output channels of each PSP branch.
    pub psp_branch: i64,
    /// Output channels of the PSP module.
    pub psp_out: i64,
    /// Output channels of the three decoder steps (strides 16, 8, 4).
    pub decoder: [i64; 3],
    /// Descriptor channels of the learned head.
    pub descriptor_dim: i64,
    /// Whether the encoder's own features at strides 4, 8 and 16 join the
    /// learned descriptor: each part (the head's output and the three
    /// taps) resized to the stride-4 grid, L2-normalised, weighted by a
    /// learned factor (all 1 at first: with an ImageNet encoder, the taps
    /// are then close to the `imagenet` baseline's features), then
    /// concatenated, resized to the input and normalised again.
    #[serde(default)]
    pub encoder_features: bool,
    /// Whether each stride-4 cell's mean colour joins the descriptor as a
    /// further part (a learned Gaussian kernel of L*a*b* distance, with a
    /// learned weight); the learned descriptor is then normalised on the
    /// grid as the other parts are.
    #[serde(default)]
    pub colour_features: bool,
}

impl NetConfig {
    /// A named configuration (see [`PRESETS`]). ConvNeXt widths follow the
    /// paper's rule (PSP branches C32/2, PSP out C32, decoder C16, C8, 128:
    /// exactly the paper's 512/1024/512/256/128 for ConvNeXt-B).
    /// MobileNetV2's last features have 1280 channels but are a mobile
    /// encoder's: the head stays light (branches 128, PSP 256, decoder 128).
    pub fn preset(name: &str) -> Option<Self> {
        let convnext = |c: ConvNextConfig| {
            let [_, c8, c16, c32] = c.dims;
            Self {
                encoder: EncoderConfig::Convnext(c),
                psp_branch: c32 / 2,
                psp_out: c32,
                decoder: [c16, c8, DESCRIPTOR_DIM],
                descriptor_dim: DESCRIPTOR_DIM,
                encoder_features: false,
                colour_features: false,
            }
        };
        match name {
            "mobilenet-v2" => Some(Self {
                encoder: EncoderConfig::MobilenetV2,
                psp_branch: 128,
                psp_out: 256,
                decoder: [128, 128, 128],
                descriptor_dim: DESCRIPTOR_DIM,
                encoder_features: false,
                colour_features: false,
            }),
            "convnext-tiny" => Some(convnext(ConvNextConfig::TINY)),
            "convnext-base" => Some(convnext(ConvNextConfig::BASE)),
            _ => None,
        }
    }

    /// Channels of the net's descriptors: the head's, with
    /// [`NetConfig::encoder_features`] the taps' at strides 4, 8 and 16,
    /// with [`NetConfig::colour_features`] the colour part's.
    pub fn output_dim(&self) -> i64 {
        let taps = self.encoder.tap_channels();
        let encoder_parts = if self.encoder_features {
            taps[0] + taps[1] + taps[2]
        } else {
            0
        };
        let colour = if self.colour_features {
            COLOUR_FEATURES
        } else {
            0
        };
        self.descriptor_dim + encoder_parts + colour
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_shape_has_408_channels() {
        let mut config = NetConfig::preset("mobilenet-v2").unwrap();
        assert_eq!(config.output_dim(), 128);
        config.encoder_features = true;
        config.colour_features = true;
        assert_eq!(config.output_dim(), 128 + 24 + 32 + 96 + 128);
        let base = NetConfig::preset("convnext-base").unwrap();
        assert_eq!(
            (base.psp_branch, base.psp_out, base.decoder),
            (512, 1024, [512, 256, 128])
        );
        assert!(NetConfig::preset("resnet").is_none());
    }

    #[test]
    fn a_config_reads_back_as_written() {
        for name in PRESETS {
            let config = NetConfig::preset(name).unwrap();
            let text = serde_json::to_string(&config).unwrap();
            assert_eq!(serde_json::from_str::<NetConfig>(&text).unwrap(), config);
        }
        let old = r#"{"encoder":{"kind":"mobilenet-v2"},"psp_branch":128,"psp_out":256,"decoder":[128,128,128],"descriptor_dim":128}"#;
        let config: NetConfig = serde_json::from_str(old).unwrap();
        assert!(!config.encoder_features && !config.colour_features);
    }
}
