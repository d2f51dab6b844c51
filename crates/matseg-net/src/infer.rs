//! A trained net for inference: loading a run's weights, computing the
//! descriptor map of a photo, and the net as an evaluated model
//! ([`DescriptorModel`]) for the point and mask benchmarks.

use crate::net::{normalise_input, rgb8_to_tensor, MaterialNet};
use crate::train::{read_run_config, Trainer};
use crate::weights::load_tensors;
use crate::{torch_device, NetError};
use image::imageops::FilterType;
use image::RgbImage;
use matseg_image::device::ComputeDevice;
use matseg_model::input::net_size;
use matseg_model::RUN_FILE;
pub use matseg_model::{default_model_dir, resolve_model, run_files, DEFAULT_MODEL};
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::{Comparison, DescriptorMap, DescriptorModel};
use matseg_query::net::{DescriptorNet, PhotoGrid};
use std::path::Path;
use std::sync::{Mutex, MutexGuard, PoisonError};
use tch::{nn, Device, Tensor};

/// A trained net with its variables.
pub struct TrainedNet {
    vs: nn::VarStore,
    net: MaterialNet,
    /// The longest side the net runs at (see `RunConfig::inference_side`).
    pub inference_side: Option<u32>,
    /// Further longer sides it runs at, the descriptors of all averaged
    /// (see `RunConfig::extra_inference_sides`).
    pub extra_inference_sides: Vec<u32>,
}

impl TrainedNet {
    /// Loads `model`: a run folder, a weights file (`model.safetensors`,
    /// `best.safetensors`, in 32- or 16-bit floats) with the run's
    /// `run.json` beside it, or [`DEFAULT_MODEL`], onto `device`.
    pub fn load(model: &Path, device: ComputeDevice) -> Result<Self, NetError> {
        let model = &resolve_model(model)?;
        let (dir, weights) = run_files(model);
        if !dir.join(RUN_FILE).is_file() {
            return Err(NetError::File {
                file: model.display().to_string(),
                message: format!("not a run: no {RUN_FILE} beside the weights"),
            });
        }
        let config = read_run_config(dir)?;
        let vs = nn::VarStore::new(torch_device(device));
        let net = MaterialNet::new(&vs.root(), config.net);
        let saved = Tensor::read_safetensors(&weights).map_err(|source| NetError::Torch {
            file: weights.display().to_string(),
            source,
        })?;
        load_tensors(&vs, &saved).map_err(|e| NetError::File {
            file: weights.display().to_string(),
            message: e.to_string(),
        })?;
        Ok(Self {
            vs,
            net,
            inference_side: config.inference_side,
            extra_inference_sides: config.extra_inference_sides,
        })
    }

    /// A copy of the net `trainer` is training, as it is now.
    pub fn snapshot(trainer: &Trainer) -> Result<Self, NetError> {
        let mut vs = nn::VarStore::new(trainer.vs.device());
        let net = MaterialNet::new(&vs.root(), trainer.config.net);
        vs.copy(&trainer.vs).map_err(|source| NetError::Torch {
            file: "the net in training".into(),
            source,
        })?;
        Ok(Self {
            vs,
            net,
            inference_side: trainer.config.inference_side,
            extra_inference_sides: trainer.config.extra_inference_sides.clone(),
        })
    }

    /// The net's grid of an interleaved RGB image shrunk to fit
    /// [`TrainedNet::inference_side`], with the unit descriptors at each of
    /// [`TrainedNet::extra_inference_sides`] resized onto it and added:
    /// descriptors `[1, D, H'/4, W'/4]` on the CPU, not yet normalised.
    fn grid(&self, rgb: &[u8], width: usize, height: usize) -> Tensor {
        let photo = RgbImage::from_raw(width as u32, height as u32, rgb.to_vec())
            .expect("width * height * 3 bytes");
        let main = self.grid_at(&photo, self.inference_side);
        if self.extra_inference_sides.is_empty() {
            return main;
        }
        let (_, _, h, w) = main.size4().expect("an NCHW tensor");
        let mut sum = crate::blocks::l2_normalise(&main, 1);
        for &side in &self.extra_inference_sides {
            let other = crate::blocks::l2_normalise(&self.grid_at(&photo, Some(side)), 1);
            sum += crate::blocks::resize_bilinear(&other, h, w);
        }
        sum
    }

    /// The net's grid of `photo` shrunk to fit a longer side of `side`
    /// pixels (`None`: as it is) and resized to the nearest sides multiple
    /// of 32, not yet normalised.
    fn grid_at(&self, photo: &RgbImage, side: Option<u32>) -> Tensor {
        let (w, h) = net_size(photo.width(), photo.height(), side);
        // Resampled on the CPU with a triangle filter, which averages over
        // the whole footprint when shrinking (bilinear taps would alias).
        let resized = image::imageops::resize(photo, w, h, FilterType::Triangle);
        self.grid_of(&resized)
    }

    /// The net's grid of an image already at the net's size, not yet
    /// normalised.
    fn grid_of(&self, resized: &RgbImage) -> Tensor {
        let (w, h) = (resized.width() as usize, resized.height() as usize);
        let x = rgb8_to_tensor(resized.as_raw(), w, h).unsqueeze(0);
        let x = normalise_input(&x).to_device(self.vs.device());
        tch::no_grad(|| self.net.coarse_t(&x, false).to_device(Device::Cpu))
    }

    /// Unit descriptors of an interleaved RGB image on the net's stride-4
    /// grid, for querying in photo pixels: the fast path of `matseg
    /// segment`.
    pub fn describe_coarse(&self, rgb: &[u8], width: usize, height: usize) -> CoarseDescriptors {
        let d = crate::blocks::l2_normalise(&self.grid(rgb, width, height), 1);
        CoarseDescriptors {
            grid: tensor_to_map(&d.squeeze_dim(0)),
            width,
            height,
        }
    }

    /// Unit descriptors of an interleaved RGB image on the net's stride-4
    /// grid at one scale, the image shrunk to fit a longer side of `side`
    /// pixels (never enlarged): the fast path of video tracking, one net
    /// pass a frame.
    /// Frames are shrunk by area averaging (`thumbnail`), several times
    /// faster than the triangle filter of the other paths at video sizes.
    pub fn describe_coarse_at(
        &self,
        rgb: &[u8],
        width: usize,
        height: usize,
        side: u32,
    ) -> CoarseDescriptors {
        let photo =
            image::ImageBuffer::<image::Rgb<u8>, &[u8]>::from_raw(width as u32, height as u32, rgb)
                .expect("width * height * 3 bytes");
        let (w, h) = net_size(width as u32, height as u32, Some(side));
        let resized = image::imageops::thumbnail(&photo, w, h);
        let d = crate::blocks::l2_normalise(&self.grid_of(&resized), 1);
        CoarseDescriptors {
            grid: tensor_to_map(&d.squeeze_dim(0)),
            width,
            height,
        }
    }

    /// Unit descriptors `[D, height, width]` of an interleaved RGB image on
    /// the CPU: the net's grid resized to the image and normalised.
    pub fn describe(&self, rgb: &[u8], width: usize, height: usize) -> Tensor {
        unit_at(&self.grid(rgb, width, height), width, height)
    }

    /// The net alone on an interleaved RGB image whose sides are multiples
    /// of 32, at its own size and one scale (no shrinking to
    /// [`TrainedNet::inference_side`], no extra sides): unit descriptors
    /// `[D, height, width]` on the CPU, as training sees them. What an
    /// exported copy of the net (PyTorch, ONNX) must reproduce.
    pub fn describe_at_own_size(
        &self,
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Result<Tensor, NetError> {
        if !width.is_multiple_of(32) || !height.is_multiple_of(32) || width == 0 || height == 0 {
            return Err(NetError::File {
                file: "image".into(),
                message: format!(
                    "is {width}x{height}; the net alone takes sides that are multiples of 32"
                ),
            });
        }
        let photo = RgbImage::from_raw(width as u32, height as u32, rgb.to_vec())
            .expect("width * height * 3 bytes");
        Ok(unit_at(&self.grid_at(&photo, None), width, height))
    }

    /// The net, e.g. to run its encoder alone.
    pub fn net(&self) -> &MaterialNet {
        &self.net
    }

    /// Its variables.
    pub fn vs(&self) -> &nn::VarStore {
        &self.vs
    }

    /// Channels of the descriptors.
    pub fn output_dim(&self) -> i64 {
        self.net.output_dim()
    }
}

impl PixelDescriptors for TrainedNet {
    fn describe_rgb(&self, rgb: &[u8], width: usize, height: usize) -> Tensor {
        self.describe(rgb, width, height)
    }
}

/// A model that maps an interleaved RGB image to unit descriptors
/// `[D, height, width]` on the CPU: a trained net, or the ImageNet features.
pub trait PixelDescriptors {
    /// The descriptors of `rgb` (`width * height * 3` bytes).
    fn describe_rgb(&self, rgb: &[u8], width: usize, height: usize) -> Tensor;

    /// The descriptor map of `image`.
    fn descriptor_map(&self, image: &RgbImage) -> DescriptorMap {
        let d = self.describe_rgb(
            image.as_raw(),
            image.width() as usize,
            image.height() as usize,
        );
        tensor_to_map(&d)
    }
}

/// A grid `[1, D, h, w]` resized to `width x height` and normalised:
/// unit descriptors `[D, height, width]`.
fn unit_at(grid: &Tensor, width: usize, height: usize) -> Tensor {
    let d = crate::blocks::resize_bilinear(grid, height as i64, width as i64);
    crate::blocks::l2_normalise(&d, 1).squeeze_dim(0)
}

/// A `[D, H, W]` float tensor on the CPU as a [`DescriptorMap`].
fn tensor_to_map(d: &Tensor) -> DescriptorMap {
    let (dim, height, width) = d.size3().expect("a [D, H, W] tensor");
    let data = Vec::<f32>::try_from(d.permute([1, 2, 0]).contiguous().flatten(0, -1))
        .expect("a float tensor on the CPU converts to Vec<f32>");
    DescriptorMap {
        width: width as usize,
        height: height as usize,
        dim: dim as usize,
        data,
    }
}

/// A [`PixelDescriptors`] model as an evaluated [`DescriptorModel`]: unit
/// descriptors compared by cosine. Photos are described one at a time
/// (libtorch parallelises within each).
pub struct TorchModel<T> {
    name: String,
    model: Mutex<T>,
}

impl<T> TorchModel<T> {
    /// `model` under the name `name` in result tables.
    pub fn new(name: impl Into<String>, model: T) -> Self {
        Self {
            name: name.into(),
            model: Mutex::new(model),
        }
    }

    /// The model, held until the guard is dropped (a panic of an earlier
    /// holder does not keep it from the next).
    pub fn lock(&self) -> MutexGuard<'_, T> {
        matseg_image::sync::lock(&self.model)
    }

    /// The model, to change its settings before it is used.
    pub fn model_mut(&mut self) -> &mut T {
        self.model.get_mut().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A trained net as an evaluated model.
pub type NetModel = TorchModel<TrainedNet>;

impl NetModel {
    /// Loads `model` as [`TrainedNet::load`] does, named after its run
    /// folder (`default` for the shipped model).
    pub fn load(model: &Path, device: ComputeDevice) -> Result<Self, NetError> {
        if model == Path::new(DEFAULT_MODEL) {
            return Ok(Self::new(DEFAULT_MODEL, TrainedNet::load(model, device)?));
        }
        let name = run_files(model)
            .0
            .file_name()
            .map_or("net".into(), |n| n.to_string_lossy().into_owned());
        Ok(Self::new(name, TrainedNet::load(model, device)?))
    }
}

impl<T: PixelDescriptors + Send> DescriptorModel for TorchModel<T> {
    fn name(&self) -> &str {
        &self.name
    }

    fn comparison(&self) -> Comparison {
        Comparison::Cosine
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        self.lock().descriptor_map(image)
    }
}

/// The trained net on libtorch as the queries use it (on CUDA, or on the
/// CPU where asked; the pure-Rust engine of matseg-infer is the CPU's
/// default).
impl DescriptorNet for NetModel {
    fn output_dim(&self) -> usize {
        self.lock().output_dim() as usize
    }

    fn inference_side(&self) -> Option<u32> {
        self.lock().inference_side
    }

    fn set_inference_sides(&mut self, main: Option<u32>, extra: Vec<u32>) {
        let net = self.model_mut();
        net.inference_side = main;
        net.extra_inference_sides = extra;
    }

    fn photo_grid(&self, photo: &RgbImage) -> PhotoGrid {
        let grid = self.lock().grid(
            photo.as_raw(),
            photo.width() as usize,
            photo.height() as usize,
        );
        photo_grid(&grid)
    }

    fn own_size_grid(&self, photo: &RgbImage) -> PhotoGrid {
        photo_grid(&self.lock().grid_at(photo, None))
    }

    fn describe_frame(&self, photo: &RgbImage, side: u32) -> CoarseDescriptors {
        self.lock().describe_coarse_at(
            photo.as_raw(),
            photo.width() as usize,
            photo.height() as usize,
            side,
        )
    }
}

/// A grid `[1, D, h, w]` as a [`PhotoGrid`].
fn photo_grid(grid: &Tensor) -> PhotoGrid {
    let map = tensor_to_map(&grid.squeeze_dim(0));
    PhotoGrid {
        values: map.data,
        width: map.width,
        height: map.height,
        dim: map.dim,
    }
}
