//! The material-descriptor net (pipeline.md §8): encoder, PSP, decoder, a 1x1 conv
//! head to D channels at stride 4, bilinear up to the input size, per-pixel
//! L2 normalisation.

use crate::blocks::{l2_normalise, resize_bilinear};
use crate::colour::{cell_lab, ColourPart};
use crate::decoder::Decoder;
use crate::encoder::{Encoder, Taps};
use crate::psp::Psp;
pub use matseg_model::input::{INPUT_MEAN, INPUT_SCALE};
pub use matseg_model::{NetConfig, DESCRIPTOR_DIM, PRESETS};
use tch::nn;
use tch::Tensor;

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
        self.config.output_dim()
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
