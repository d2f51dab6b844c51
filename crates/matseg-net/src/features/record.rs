//! One cached sample: its tensors as 16-bit floats, written and read as a
//! safetensors file, and a batch of them as the net's input.

use super::CacheManifest;
use crate::encoder::Taps;
use crate::grid::GridTargets;
use crate::loss::ImageTargets;
use matseg_weights::{read_safetensors, write_safetensors, DType, Tensor as Stored};
use tch::{Device, Kind, Tensor};

/// The tensors of one sample, in the order they are stored.
const NAMES: [&str; 7] = ["s4", "s8", "s16", "s32", "lab", "weights", "roi"];

/// Bytes that are not a cached sample of the cache's manifest.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CacheMismatch {
    /// Not a safetensors file.
    #[error("not a cached sample ({0})")]
    NotASample(String),
    /// A tensor missing.
    #[error("not a cached sample: no {0} tensor")]
    NoTensor(&'static str),
    /// A tensor of another type or shape than the manifest says.
    #[error("{name} is {dtype} {shape:?}, the cache's manifest says F16 {expected:?}")]
    Layout {
        /// The tensor.
        name: &'static str,
        /// Its type.
        dtype: String,
        /// Its shape.
        shape: Vec<usize>,
        /// The shape the manifest gives it.
        expected: Vec<usize>,
    },
}

/// One cached sample: 16-bit float tensors (little-endian bytes).
#[derive(Clone, Debug, PartialEq)]
pub struct CachedSample {
    /// `s4`, `s8`, `s16`, `s32` (`[C, h, w]`, the encoder's taps), `lab`
    /// (`[3, h4, w4]`), `weights` (`[K, h4, w4]`), `roi` (`[h4, w4]`).
    tensors: Vec<Stored>,
}

/// `tensor` on the CPU as a stored 16-bit tensor named `name`.
fn stored(name: &str, tensor: &Tensor) -> Stored {
    let half = tensor
        .to_device(Device::Cpu)
        .to_kind(Kind::Half)
        .contiguous();
    let numel = half.numel();
    let mut data = vec![0u8; numel * 2];
    half.copy_data_u8(&mut data, numel);
    Stored {
        name: name.to_string(),
        dtype: DType::F16,
        shape: half.size().iter().map(|&d| d as usize).collect(),
        data,
    }
}

impl CachedSample {
    /// A sample from one image's taps (each `[C, h, w]`), cell colours
    /// `[3, h4, w4]` and grid targets.
    pub fn new(taps: [&Tensor; 4], lab: &Tensor, targets: &GridTargets) -> Self {
        let (h, w) = (targets.height as i64, targets.width as i64);
        let planes: Vec<Tensor> = targets
            .weights
            .iter()
            .map(|p| Tensor::from_slice(p).view([h, w]))
            .collect();
        let weights = Tensor::stack(&planes, 0);
        let roi = Tensor::from_slice(&targets.roi).view([h, w]);
        let mut tensors: Vec<Stored> = NAMES[..4]
            .iter()
            .zip(taps)
            .map(|(name, t)| stored(name, t))
            .collect();
        tensors.push(stored("lab", lab));
        tensors.push(stored("weights", &weights));
        tensors.push(stored("roi", &roi));
        Self { tensors }
    }

    /// The sample as a safetensors file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        write_safetensors(&self.tensors, &[])
    }

    /// Reads a sample written by [`CachedSample::to_bytes`], checking
    /// every tensor's type and shape against `manifest`; `name` (the
    /// shard and member) is in the message of what is wrong.
    pub fn from_bytes(
        bytes: &[u8],
        manifest: &CacheManifest,
        name: &str,
    ) -> Result<Self, CacheMismatch> {
        let mut found =
            read_safetensors(bytes, name).map_err(|e| CacheMismatch::NotASample(e.to_string()))?;
        let (gw, gh) = manifest.grid();
        let mut tensors = Vec::with_capacity(NAMES.len());
        for (i, want) in NAMES.iter().enumerate() {
            let at = found
                .iter()
                .position(|t| t.name == *want)
                .ok_or(CacheMismatch::NoTensor(want))?;
            let t = found.swap_remove(at);
            let shape = match i {
                0..=3 => {
                    let stride = 4 << i;
                    vec![
                        manifest.taps[i] as usize,
                        manifest.height / stride,
                        manifest.width / stride,
                    ]
                }
                4 => vec![3, gh, gw],
                5 => vec![t.shape.first().copied().unwrap_or(0).max(1), gh, gw],
                _ => vec![gh, gw],
            };
            if t.dtype != DType::F16 || t.shape != shape {
                return Err(CacheMismatch::Layout {
                    name: want,
                    dtype: format!("{:?}", t.dtype),
                    shape: t.shape,
                    expected: shape,
                });
            }
            tensors.push(t);
        }
        Ok(Self { tensors })
    }

    /// The tensors as stored, taken out of the sample: `s4`, `s8`, `s16`,
    /// `s32`, `lab`, `weights`, `roi`, each 16-bit floats with its shape.
    pub fn into_stored(self) -> Vec<Stored> {
        self.tensors
    }

    /// Materials in the sample.
    pub fn materials(&self) -> usize {
        self.tensors[5].shape[0]
    }

    /// Tensor `i` (in [`NAMES`] order) as 32-bit floats on the CPU.
    fn tensor(&self, i: usize) -> Tensor {
        let t = &self.tensors[i];
        let shape: Vec<i64> = t.shape.iter().map(|&d| d as i64).collect();
        Tensor::from_data_size(&t.data, &shape, Kind::Half).to_kind(Kind::Float)
    }
}

/// A batch of cached samples as the net takes them.
#[derive(Debug)]
pub struct CachedBatch {
    /// The encoder's taps, `[B, C, h, w]` each.
    pub taps: Taps,
    /// Cell colours, `[B, 3, h4, w4]`.
    pub lab: Tensor,
    /// One per sample, on the grid.
    pub targets: Vec<ImageTargets>,
}

impl CachedBatch {
    /// Stacks `samples` (of one cache) onto `device`.
    pub fn new(samples: &[CachedSample], device: Device) -> Self {
        let stack = |i: usize| {
            let parts: Vec<Tensor> = samples.iter().map(|s| s.tensor(i)).collect();
            Tensor::stack(&parts, 0).to_device(device)
        };
        Self {
            taps: Taps::from_vec((0..4).map(stack).collect()),
            lab: stack(4),
            targets: samples
                .iter()
                .map(|s| ImageTargets {
                    weights: s.tensor(5).to_device(device),
                    roi: s.tensor(6).to_device(device),
                })
                .collect(),
        }
    }
}
