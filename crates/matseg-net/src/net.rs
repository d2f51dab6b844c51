//! The material-descriptor net (pipeline.md §8): encoder, PSP, decoder, a 1x1 conv
//! head to D channels at stride 4, bilinear up to the input size, per-pixel
//! L2 normalisation.

use crate::blocks::{l2_normalise, resize_bilinear};
use crate::colour::{cell_lab, ColourPart, COLOUR_FEATURES};
use crate::convnext::ConvNextConfig;
use crate::decoder::Decoder;
use crate::encoder::{Encoder, EncoderConfig, Taps};
use crate::psp::Psp;
use serde::{Deserialize, Serialize};
use tch::nn;
use tch::Tensor;

/// Per-channel mean subtracted from 0..255 RGB input (pipeline.md §8).
pub const INPUT_MEAN: [f64; 3] = [123.68, 116.78, 103.94];
/// Divisor of the mean-subtracted input (pipeline.md §8).
pub const INPUT_SCALE: f64 = 65.0;
/// Descriptor channels of the paper's net.
pub const DESCRIPTOR_DIM: i64 = 128;

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
    /// further part ([`ColourPart`]: a learned Gaussian kernel of L*a*b*
    /// distance, with a learned weight); the learned descriptor is then
    /// normalised on the grid as the other parts are.
    #[serde(default)]
    pub colour_features: bool,
}

/// The named configurations `--encoder` accepts.
pub const PRESETS: [&str; 3] = ["mobilenet-v2", "convnext-tiny", "convnext-base"];

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
}

/// The net with its parameters (held by the `VarStore` it was built in).
#[derive(Debug)]
pub struct MaterialNet {
    /// Its configuration.
    pub config: NetConfig,
    encoder: Encoder,
    psp: Psp,
    decoder: Decoder,
    head: nn::Conv2D,
    /// Log-weights of the head's output and the taps at strides 4, 8, 16
    /// in the descriptor, when [`NetConfig::encoder_features`].
    part_log_weights: Option<Tensor>,
    /// The colour part, when [`NetConfig::colour_features`].
    colour: Option<ColourPart>,
}

impl MaterialNet {
    /// Creates the parameters under `p` (`encoder`, `psp`, `decoder`, `head`).
    pub fn new(p: &nn::Path, config: NetConfig) -> Self {
        let encoder = Encoder::new(&(p / "encoder"), config.encoder);
        let taps = encoder.channels();
        let psp = Psp::new(&(p / "psp"), taps[3], config.psp_branch, config.psp_out);
        let decoder = Decoder::new(&(p / "decoder"), config.psp_out, config.decoder, taps);
        let head = nn::conv2d(
            p / "head",
            config.decoder[2],
            config.descriptor_dim,
            1,
            Default::default(),
        );
        let part_log_weights = config
            .encoder_features
            .then(|| p.zeros("part_log_weights", &[4]));
        let colour = config
            .colour_features
            .then(|| ColourPart::new(&(p / "colour")));
        Self {
            config,
            encoder,
            psp,
            decoder,
            head,
            part_log_weights,
            colour,
        }
    }

    /// Channels of the encoder's taps at strides 4, 8, 16 and 32.
    pub fn tap_channels(&self) -> [i64; 4] {
        self.encoder.channels()
    }

    /// Channels of the descriptors [`MaterialNet::forward_t`] returns.
    pub fn output_dim(&self) -> i64 {
        let taps = self.encoder.channels();
        let encoder_parts = match self.part_log_weights {
            Some(_) => taps[0] + taps[1] + taps[2],
            None => 0,
        };
        let colour = match self.colour {
            Some(_) => COLOUR_FEATURES,
            None => 0,
        };
        self.config.descriptor_dim + encoder_parts + colour
    }

    /// Descriptors `[N, D, H/4, W/4]` on the stride-4 grid, not yet
    /// normalised, of input images `[N, 3, H, W]` prepared by
    /// [`normalise_input`]: the head's output, or with
    /// [`NetConfig::encoder_features`] or [`NetConfig::colour_features`] the
    /// weighted parts (each normalised on the grid) side by side: the
    /// learned descriptor, the encoder's taps, the colour.
    pub fn coarse_t(&self, x: &Tensor, train: bool) -> Tensor {
        let taps = self.encoder.forward_t(x, train);
        let lab = self.colour.as_ref().map(|_| {
            let (_, _, h4, w4) = taps.s4.size4().expect("an NCHW tensor");
            cell_lab(x, h4, w4)
        });
        self.coarse_from_taps(&taps, lab.as_ref(), train)
    }

    /// The encoder's taps of input images `[N, 3, H, W]` prepared by
    /// [`normalise_input`]; `train` selects batch statistics.
    pub fn encode_t(&self, x: &Tensor, train: bool) -> Taps {
        self.encoder.forward_t(x, train)
    }

    /// [`MaterialNet::coarse_t`] from the encoder's taps (and, with
    /// [`NetConfig::colour_features`], the images' cell colours
    /// [`cell_lab`] on the stride-4 grid): everything after the encoder,
    /// for training on taps computed once.
    pub fn coarse_from_taps(&self, taps: &Taps, lab: Option<&Tensor>, train: bool) -> Tensor {
        let psp = self.psp.forward_t(&taps.s32, train);
        let learned = self.decoder.forward_t(&psp, taps, train).apply(&self.head);
        if self.part_log_weights.is_none() && self.colour.is_none() {
            return learned;
        }
        let (_, _, h4, w4) = learned.size4().expect("an NCHW tensor");
        let mut parts = match &self.part_log_weights {
            Some(log_weights) => {
                let weights = log_weights.exp();
                [&learned, &taps.s4, &taps.s8, &taps.s16]
                    .iter()
                    .enumerate()
                    .map(|(i, t)| {
                        l2_normalise(&resize_bilinear(t, h4, w4), 1) * weights.get(i as i64)
                    })
                    .collect()
            }
            None => vec![l2_normalise(&learned, 1)],
        };
        if let Some(colour) = &self.colour {
            let lab = lab.expect("the colour part needs the cells' colours");
            parts.push(colour.forward_cells(lab));
        }
        Tensor::cat(&parts, 1)
    }

    /// Per-pixel L2-normalised descriptors `[N, D, H, W]` of input images
    /// `[N, 3, H, W]` prepared by [`normalise_input`]: [`MaterialNet::coarse_t`]
    /// resized to the input and normalised.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        let (_, _, h, w) = x.size4().expect("an NCHW tensor");
        l2_normalise(&resize_bilinear(&self.coarse_t(x, train), h, w), 1)
    }
}

/// The net's input from 0..255 RGB `[N, 3, H, W]` (any float kind):
/// `(x - INPUT_MEAN) / INPUT_SCALE` per channel.
pub fn normalise_input(rgb: &Tensor) -> Tensor {
    (rgb - input_mean(rgb)) / INPUT_SCALE
}

/// The 0..255 RGB `[N, 3, H, W]` of a net's input prepared by
/// [`normalise_input`] (its inverse).
pub fn denormalise_input(x: &Tensor) -> Tensor {
    x * INPUT_SCALE + input_mean(x)
}

/// [`INPUT_MEAN`] as a `[1, 3, 1, 1]` tensor of `like`'s kind and device.
fn input_mean(like: &Tensor) -> Tensor {
    Tensor::from_slice(&INPUT_MEAN)
        .to_kind(like.kind())
        .to_device(like.device())
        .view([1, 3, 1, 1])
}

/// An interleaved 8-bit RGB image as a float `[3, height, width]` tensor of
/// 0..255 values.
pub fn rgb8_to_tensor(data: &[u8], width: usize, height: usize) -> Tensor {
    assert_eq!(data.len(), width * height * 3, "RGB buffer size");
    Tensor::from_slice(data)
        .view([height as i64, width as i64, 3])
        .permute([2, 0, 1])
        .to_kind(tch::Kind::Float)
}
