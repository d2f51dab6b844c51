//! A trained model for inference: its weights and its run's settings
//! loaded, photos shrunk to the sizes it describes them at, the sizes'
//! descriptors merged, and the result as the query crate's maps.

use crate::layers::{normalise_pixels, resize};
use crate::net::Net;
use crate::weights::Weights;
use image::imageops::FilterType;
use image::RgbImage;
use matseg_model::input::net_size;
use matseg_model::{
    read_inference_settings, resolve_model, run_files, InferenceSettings, ModelError, RUN_FILE,
};
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::net::{DescriptorNet, PhotoGrid};
use rten::BufferPool;
use rten_tensor::prelude::*;
use rten_tensor::Tensor;
use std::path::Path;

/// A trained net on the pure-Rust engine, with the sizes its run describes
/// photos at: a [`DescriptorNet`].
pub struct InferNet {
    net: Net,
    /// The longest side the net sees a photo at (`None`: as it is).
    inference_side: Option<u32>,
    /// Further longer sides it sees photos at, the unit descriptors of all
    /// added on the main size's grid.
    extra_inference_sides: Vec<u32>,
}

impl InferNet {
    /// Loads `model`: a run folder, a weights file (`model.safetensors`,
    /// `best.safetensors`, in 32- or 16-bit floats) with the run's
    /// `run.json` beside it, or [`matseg_model::DEFAULT_MODEL`]: the shipped model's
    /// folder where one is found ([`matseg_model::default_model_dir`]),
    /// else, in a build with the `embed-model` feature, the copy built in.
    pub fn load(model: &Path) -> Result<Self, ModelError> {
        #[cfg(feature = "embed-model")]
        if model == Path::new(matseg_model::DEFAULT_MODEL)
            && matseg_model::default_model_dir().is_none()
        {
            return Self::built_in();
        }
        let model = &resolve_model(model)?;
        let (dir, weights) = run_files(model);
        if !dir.join(RUN_FILE).is_file() {
            return Err(ModelError {
                file: model.display().to_string(),
                message: format!("not a run: no {RUN_FILE} beside the weights"),
            });
        }
        let settings = read_inference_settings(dir)?;
        Self::from_parts(&Weights::read(&weights)?, settings)
    }

    /// The net `settings` describes with the weights of a safetensors
    /// file's bytes; `file` names them in errors.
    pub fn from_bytes(
        weights: &[u8],
        file: &str,
        settings: InferenceSettings,
    ) -> Result<Self, ModelError> {
        Self::from_parts(&Weights::parse(weights, file.to_string())?, settings)
    }

    /// The shipped model as it was built into this binary.
    #[cfg(feature = "embed-model")]
    pub fn built_in() -> Result<Self, ModelError> {
        const WEIGHTS: &[u8] = include_bytes!("../../../models/default/model.safetensors");
        const RUN: &str = include_str!("../../../models/default/run.json");
        let name = "the built-in default model";
        let settings = InferenceSettings::parse(RUN, Path::new(name))?;
        Self::from_bytes(WEIGHTS, name, settings)
    }

    fn from_parts(weights: &Weights, settings: InferenceSettings) -> Result<Self, ModelError> {
        Ok(Self {
            net: Net::load(weights, settings.net)?,
            inference_side: settings.inference_side,
            extra_inference_sides: settings.extra_inference_sides,
        })
    }

    /// The net's grid of `photo` at its main size with the extra sizes'
    /// unit grids added (`[1, D, h, w]`), not yet normalised.
    fn merged_grid(&self, pool: &BufferPool, photo: &RgbImage) -> Tensor<f32> {
        let mut main = self.grid_at(pool, photo, self.inference_side);
        if self.extra_inference_sides.is_empty() {
            return main;
        }
        let (h, w) = (main.shape()[2], main.shape()[3]);
        normalise_pixels(&mut main, 1.0);
        for &side in &self.extra_inference_sides {
            let mut other = self.grid_at(pool, photo, Some(side));
            normalise_pixels(&mut other, 1.0);
            main = crate::layers::add(pool, &main, &resize(pool, &other, h, w));
        }
        main
    }

    /// The net's grid of `photo` shrunk to fit a longer side of `side`
    /// (`None`: as it is) and resized to sides that are multiples of 32,
    /// with a triangle filter (which averages over the whole footprint
    /// when shrinking).
    fn grid_at(&self, pool: &BufferPool, photo: &RgbImage, side: Option<u32>) -> Tensor<f32> {
        let (w, h) = net_size(photo.width(), photo.height(), side);
        let resized = image::imageops::resize(photo, w, h, FilterType::Triangle);
        self.grid_of(pool, &resized)
    }

    /// The net's grid of an image already at the net's size.
    fn grid_of(&self, pool: &BufferPool, resized: &RgbImage) -> Tensor<f32> {
        let (w, h) = (resized.width() as usize, resized.height() as usize);
        self.net.coarse(pool, resized.as_raw(), w, h)
    }
}

/// Runs `f` in rten's thread pool with a pool of buffers for its operators.
///
/// A caller that is itself a worker of a rayon pool (an evaluation
/// describing photos in parallel) waits on a plain thread that hands `f`
/// over: a rayon worker waiting for another pool runs its own pool's jobs
/// meanwhile, so it would start one net pass after another inside the
/// first (each holding its memory), and one needing a lock the first holds
/// would never end.
pub(crate) fn run<R: Send>(f: impl FnOnce(&BufferPool) -> R + Send) -> R {
    let pass = || rten::thread_pool().run(|| f(&BufferPool::new()));
    if rayon::current_thread_index().is_none() {
        return pass();
    }
    std::thread::scope(|scope| match scope.spawn(pass).join() {
        Ok(result) => result,
        Err(panic) => std::panic::resume_unwind(panic),
    })
}

/// A `[1, D, h, w]` grid with its channels interleaved, cell by cell.
pub(crate) fn to_photo_grid(grid: &Tensor<f32>) -> PhotoGrid {
    let s = grid.shape();
    let (dim, height, width) = (s[1], s[2], s[3]);
    let values = grid.view().permuted(&[0, 2, 3, 1]).to_tensor().into_data();
    PhotoGrid {
        values,
        width,
        height,
        dim,
    }
}

impl DescriptorNet for InferNet {
    fn output_dim(&self) -> usize {
        self.net.output_dim()
    }

    fn inference_side(&self) -> Option<u32> {
        self.inference_side
    }

    fn set_inference_sides(&mut self, main: Option<u32>, extra: Vec<u32>) {
        self.inference_side = main;
        self.extra_inference_sides = extra;
    }

    fn photo_grid(&self, photo: &RgbImage) -> PhotoGrid {
        run(|pool| to_photo_grid(&self.merged_grid(pool, photo)))
    }

    fn own_size_grid(&self, photo: &RgbImage) -> PhotoGrid {
        run(|pool| to_photo_grid(&self.grid_of(pool, photo)))
    }

    fn describe_frame(&self, photo: &RgbImage, side: u32) -> CoarseDescriptors {
        let (w, h) = net_size(photo.width(), photo.height(), Some(side));
        let resized = image::imageops::thumbnail(photo, w, h);
        let grid = run(|pool| to_photo_grid(&self.grid_of(pool, &resized)));
        grid.into_coarse(photo.width() as usize, photo.height() as usize)
    }
}
