//! The per-pixel material-descriptor net of pipeline.md §8 on libtorch (tch):
//! ConvNeXt and MobileNetV2 encoders, the PSP module, the decoder, the
//! MatSeg loss, and loading imported weights.
//!
//! libtorch comes from the project's `.venv` (scripts/torch-env.sh); this is
//! the only crate that links it.

#![warn(missing_docs)]

pub mod batch;
pub mod blocks;
pub mod checkpoint_keys;
pub mod colour;
pub mod convnext;
/// Where training batches come from (matseg-data's, re-exported).
pub use matseg_data::training as data;
pub mod decoder;
pub mod encoder;
pub mod features;
pub mod grid;
pub mod imagenet;
pub mod infer;
pub mod loader;
pub mod loss;
pub mod mobilenet_v2;
pub mod net;
pub mod optim;
pub mod plot;
pub mod psp;
pub mod train;
pub mod weights;

pub use batch::{Batch, TrainingSample};
pub use convnext::ConvNextConfig;
pub use encoder::{Encoder, EncoderConfig, Taps};
pub use loss::{matseg_loss, ImageTargets, REGION_THRESHOLD, TEMPERATURE};
pub use mobilenet_v2::{MobileNetV2, MobileNetV2Classifier};
pub use net::{normalise_input, rgb8_to_tensor, MaterialNet, NetConfig, PRESETS};
pub use weights::{load_named, load_net_adding};

use matseg_image::device::ComputeDevice;

/// The libtorch device of `device`.
pub fn torch_device(device: ComputeDevice) -> tch::Device {
    match device {
        ComputeDevice::Cpu => tch::Device::Cpu,
        ComputeDevice::Cuda(index) => tch::Device::Cuda(index),
    }
}

/// Errors of the net crate: each names the file involved.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// A file that cannot be read or written, or does not fit the net.
    #[error("{file}: {message}")]
    File {
        /// The file.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// Training data that cannot be read or generated.
    #[error("training data: {0}")]
    Data(#[from] crate::data::DataError),
    /// The net could not be scored on a validation benchmark.
    #[error("validation: {message}")]
    Validation {
        /// What is wrong.
        message: String,
    },
    /// A model's file that cannot be found or read.
    #[error(transparent)]
    Model(#[from] matseg_model::ModelError),
    /// libtorch failed.
    #[error("{file}: {source}")]
    Torch {
        /// The file involved.
        file: String,
        /// libtorch's error.
        source: tch::TchError,
    },
}
