//! A trained net for inference: loading a run's weights and computing the
//! descriptor map of a photo.

use crate::net::{normalise_input, rgb8_to_tensor, MaterialNet};
use crate::train::{read_run_config, MODEL_FILE, RUN_FILE};
use crate::weights::load_tensors;
use crate::NetError;
use std::path::Path;
use tch::{nn, Device, Tensor};

/// A trained net with its variables.
pub struct TrainedNet {
    vs: nn::VarStore,
    net: MaterialNet,
}

impl TrainedNet {
    /// Loads `model`: a run folder, or a `model.safetensors` with the run's
    /// `run.json` beside it.
    pub fn load(model: &Path, device: Device) -> Result<Self, NetError> {
        let (dir, weights) = if model.is_dir() {
            (model.to_path_buf(), model.join(MODEL_FILE))
        } else {
            let dir = model.parent().unwrap_or(Path::new(".")).to_path_buf();
            (dir, model.to_path_buf())
        };
        if !dir.join(RUN_FILE).is_file() {
            return Err(NetError::File {
                file: model.display().to_string(),
                message: format!("not a run: no {RUN_FILE} beside the weights"),
            });
        }
        let config = read_run_config(&dir)?;
        let vs = nn::VarStore::new(device);
        let net = MaterialNet::new(&vs.root(), config.net);
        let saved = Tensor::read_safetensors(&weights).map_err(|source| NetError::Torch {
            file: weights.display().to_string(),
            source,
        })?;
        load_tensors(&vs, &saved).map_err(|message| NetError::File {
            file: weights.display().to_string(),
            message,
        })?;
        Ok(Self { vs, net })
    }

    /// Unit descriptors `[D, height, width]` of an interleaved RGB image,
    /// computed at the nearest size with sides multiple of 32 and resized
    /// back (then re-normalised).
    pub fn describe(&self, rgb: &[u8], width: usize, height: usize) -> Tensor {
        let round32 = |n: usize| ((n as f64 / 32.0).round() as i64).max(1) * 32;
        let x = rgb8_to_tensor(rgb, width, height).unsqueeze(0);
        let x = crate::blocks::resize_bilinear(&x, round32(height), round32(width));
        tch::no_grad(|| {
            let d = self
                .net
                .forward_t(&normalise_input(&x).to_device(self.vs.device()), false);
            let d = crate::blocks::resize_bilinear(&d, height as i64, width as i64);
            crate::blocks::l2_normalise(&d, 1)
                .squeeze_dim(0)
                .to_device(Device::Cpu)
        })
    }
}
