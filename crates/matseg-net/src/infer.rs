//! A trained net for inference: loading a run's weights, computing the
//! descriptor map of a photo, and the net as an evaluated model
//! ([`DescriptorModel`]) for the point and mask benchmarks.

use crate::net::{normalise_input, rgb8_to_tensor, MaterialNet};
use crate::train::{read_run_config, Trainer, MODEL_FILE, RUN_FILE};
use crate::weights::load_tensors;
use crate::NetError;
use image::RgbImage;
use matseg_eval::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use tch::{nn, Device, Tensor};

/// A trained net with its variables.
pub struct TrainedNet {
    vs: nn::VarStore,
    net: MaterialNet,
}

/// The run folder and the weights file `model` names: a run folder and
/// its `model.safetensors`, or a weights file and the folder it is in.
fn run_files(model: &Path) -> (&Path, PathBuf) {
    if model.is_dir() {
        (model, model.join(MODEL_FILE))
    } else {
        (
            model.parent().unwrap_or(Path::new(".")),
            model.to_path_buf(),
        )
    }
}

impl TrainedNet {
    /// Loads `model`: a run folder, or a `model.safetensors` with the run's
    /// `run.json` beside it.
    pub fn load(model: &Path, device: Device) -> Result<Self, NetError> {
        let (dir, weights) = run_files(model);
        if !dir.join(RUN_FILE).is_file() {
            return Err(NetError::File {
                file: model.display().to_string(),
                message: format!("not a run: no {RUN_FILE} beside the weights"),
            });
        }
        let config = read_run_config(dir)?;
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

    /// A copy of the net `trainer` is training, as it is now.
    pub fn snapshot(trainer: &Trainer) -> Result<Self, NetError> {
        let mut vs = nn::VarStore::new(trainer.vs.device());
        let net = MaterialNet::new(&vs.root(), trainer.config.net);
        vs.copy(&trainer.vs).map_err(|source| NetError::Torch {
            file: "the net in training".into(),
            source,
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

impl TrainedNet {
    /// The descriptor map of `image` (see [`TrainedNet::describe`]), on the CPU.
    pub fn descriptor_map(&self, image: &RgbImage) -> DescriptorMap {
        let (width, height) = (image.width() as usize, image.height() as usize);
        let d = self.describe(image.as_raw(), width, height);
        let dim = d.size()[0] as usize;
        let data = Vec::<f32>::try_from(d.permute([1, 2, 0]).contiguous().flatten(0, -1))
            .expect("a float tensor on the CPU converts to Vec<f32>");
        DescriptorMap {
            width,
            height,
            dim,
            data,
        }
    }
}

/// A trained net as a [`DescriptorModel`]: unit descriptors compared by
/// cosine. Photos are described one at a time (libtorch parallelises
/// within each).
pub struct NetModel {
    name: String,
    net: Mutex<TrainedNet>,
}

impl NetModel {
    /// Loads `model` as [`TrainedNet::load`] does, named after its run
    /// folder.
    pub fn load(model: &Path, device: Device) -> Result<Self, NetError> {
        let name = run_files(model)
            .0
            .file_name()
            .map_or("net".into(), |n| n.to_string_lossy().into_owned());
        Ok(Self::new(name, TrainedNet::load(model, device)?))
    }

    /// `net` under the name `name` in result tables.
    pub fn new(name: impl Into<String>, net: TrainedNet) -> Self {
        Self {
            name: name.into(),
            net: Mutex::new(net),
        }
    }
}

impl DescriptorModel for NetModel {
    fn name(&self) -> &str {
        &self.name
    }

    fn comparison(&self) -> Comparison {
        Comparison::Cosine
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        self.net
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .descriptor_map(image)
    }
}
