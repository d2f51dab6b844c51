//! Making cached samples with a net's encoder, and the digest that ties a
//! cache to the encoder's weights.

use super::record::CachedSample;
use crate::batch::TrainingSample;
use crate::colour::cell_lab;
use crate::grid::{GridTargets, GRID_STRIDE};
use crate::net::{normalise_input, rgb8_to_tensor, MaterialNet};
use sha2::{Digest, Sha256};
use tch::{nn, Device, Kind, Tensor};

/// The cached samples of `samples` (all of one size, a multiple of 32):
/// the encoder's taps in inference mode (BatchNorm's running statistics,
/// as at inference and as a frozen encoder runs in training), the cells'
/// colours and the grid targets.
pub fn encode_samples(
    net: &MaterialNet,
    samples: &[TrainingSample],
    device: Device,
) -> Vec<CachedSample> {
    let (w, h) = (samples[0].width, samples[0].height);
    let images: Vec<Tensor> = samples
        .iter()
        .map(|s| {
            assert_eq!((s.width, s.height), (w, h), "samples of one size");
            rgb8_to_tensor(&s.rgb, w, h)
        })
        .collect();
    let x = normalise_input(&Tensor::stack(&images, 0)).to_device(device);
    let (taps, lab) = tch::no_grad(|| {
        let taps = net.encode_t(&x, false);
        let grid = |n: usize| (n / GRID_STRIDE) as i64;
        let lab = cell_lab(&x, grid(h), grid(w));
        (taps, lab)
    });
    samples
        .iter()
        .enumerate()
        .map(|(b, sample)| {
            let b = b as i64;
            CachedSample::new(
                [
                    &taps.s4.get(b),
                    &taps.s8.get(b),
                    &taps.s16.get(b),
                    &taps.s32.get(b),
                ],
                &lab.get(b),
                &GridTargets::of(sample, GRID_STRIDE),
            )
        })
        .collect()
}

/// SHA-256 (hex) of the encoder's variables in `vs` (names under
/// `encoder.`, sorted; each name, shape and 32-bit values): the same
/// weights give the same digest wherever they were loaded from.
pub fn encoder_digest(vs: &nn::VarStore) -> String {
    let mut variables: Vec<(String, Tensor)> = vs
        .variables()
        .into_iter()
        .filter(|(name, _)| name.starts_with("encoder."))
        .collect();
    variables.sort_by(|a, b| a.0.cmp(&b.0));
    let mut hash = Sha256::new();
    for (name, tensor) in variables {
        hash.update((name.len() as u64).to_le_bytes());
        hash.update(name.as_bytes());
        for d in tensor.size() {
            hash.update(d.to_le_bytes());
        }
        let values = tensor
            .to_device(Device::Cpu)
            .to_kind(Kind::Float)
            .contiguous();
        let numel = values.numel();
        let mut bytes = vec![0u8; numel * 4];
        values.copy_data_u8(&mut bytes, numel);
        hash.update(&bytes);
    }
    hash.finalize().iter().map(|b| format!("{b:02x}")).collect()
}
