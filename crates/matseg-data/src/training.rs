//! Where training batches come from: a stored dataset or the 2D generator
//! (online, no disk in between), fitted to one random size per batch and
//! augmented (pipeline.md §8). Batch `s` depends only on (seed, s), so a resumed run
//! sees the very batches the interrupted one would have.

use crate::augment::augment;
use crate::{sample_rng, Dataset, Sample};
use image::imageops::{self, FilterType};
use image::{ImageBuffer, Luma, RgbImage};
use matseg_scene::{generate_2d, quantise_weights, Recipe2d, Sources};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// One training image with its ground truth, all at the same resolution.
#[derive(Clone, Debug)]
pub struct TrainingSample {
    /// Interleaved 8-bit RGB, `width * height * 3` bytes.
    pub rgb: Vec<u8>,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Per-material weights, `width * height` each (pipeline.md §7.1: mask / sum).
    pub weights: Vec<Vec<f32>>,
    /// 1 inside the ROI, 0 outside, `width * height`.
    pub roi: Vec<f32>,
}

impl TrainingSample {
    /// A stored sample as training reads it (pipeline.md §7.1).
    pub fn from_sample(sample: Sample) -> Self {
        let (width, height) = sample.image.dimensions();
        let targets = sample.targets();
        Self {
            rgb: sample.image.into_raw(),
            width: width as usize,
            height: height as usize,
            weights: targets.weights.into_iter().map(|p| p.data).collect(),
            roi: targets.roi.data,
        }
    }
}

/// Why a training sample or batch could not be had.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A stored sample could not be read.
    #[error(transparent)]
    Read(#[from] crate::ReadError),
    /// The generator could not compose a scene.
    #[error(transparent)]
    Compose(#[from] matseg_scene::ComposeError),
    /// A source of a mixture has no samples.
    #[error("a mixed source has no samples")]
    EmptyMix,
    /// A batch loader's worker ended before making its batch.
    #[error("batch {0}: its worker stopped early")]
    WorkerStopped(u64),
}

/// A batch plan that makes no batches (sides not multiples of 32, empty
/// ranges); the message says which.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidPlan(pub String);

/// Training samples by index.
pub trait SampleSource: Send + Sync {
    /// The sample with this index, at its own size.
    fn sample(&self, index: u64) -> Result<TrainingSample, DataError>;
    /// How many distinct samples there are (`None`: unbounded, generated).
    fn count(&self) -> Option<u64>;
}

/// A stored dataset (MatSeg folders or WebDataset shards).
pub struct DatasetSource(pub Dataset);

impl SampleSource for DatasetSource {
    fn sample(&self, index: u64) -> Result<TrainingSample, DataError> {
        let sample = self.0.get(index as usize)?;
        Ok(TrainingSample::from_sample(sample))
    }

    fn count(&self) -> Option<u64> {
        Some(self.0.len() as u64)
    }
}

/// The 2D generator in memory: sample `i` is what `matseg generate` with the
/// same seed and sources writes as sample `i`, read back as training reads
/// it (masks quantised to 8 bits), without the JPEG round trip.
pub struct GeneratorSource<'a> {
    /// The photo and texture libraries.
    pub sources: Sources<'a>,
    /// The scene recipe.
    pub recipe: Recipe2d,
    /// The dataset seed.
    pub seed: u64,
}

impl SampleSource for GeneratorSource<'_> {
    fn sample(&self, index: u64) -> Result<TrainingSample, DataError> {
        let scene = generate_2d(
            &mut sample_rng(self.seed, index),
            &self.recipe,
            self.sources,
        )?;
        let (w, h) = scene.image.dimensions();
        let q = quantise_weights(&scene.weights, &scene.background);
        let masks = q
            .masks
            .into_iter()
            .map(|m| image::GrayImage::from_raw(w, h, m).expect("mask size"))
            .collect();
        Ok(TrainingSample::from_sample(Sample {
            key: index.to_string(),
            image: scene.image,
            masks,
            roi: None,
            meta: None,
        }))
    }

    fn count(&self) -> Option<u64> {
        None
    }
}

/// Two sources mixed: sample `i` is `other`'s with probability
/// `fraction`, else `main`'s (a stored source's sample `i` modulo its
/// count); the choice depends only on `i`, so a resumed run
/// sees the same mixture. E.g. online 2D scenes with a share of stored 3D
/// renders.
pub struct MixedSource<'a> {
    /// The source of most samples.
    pub main: &'a dyn SampleSource,
    /// The source mixed in.
    pub other: &'a dyn SampleSource,
    /// The share of samples taken from `other`, in 0..=1.
    pub fraction: f64,
}

/// A mixture's share outside 0..=1.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("expected 0..1")]
pub struct FractionOutOfRange;

impl MixedSource<'_> {
    /// Checks that `fraction` is a share of samples (in 0..=1), as every
    /// mixture's must be.
    pub fn check_fraction(fraction: f64) -> Result<(), FractionOutOfRange> {
        if (0.0..=1.0).contains(&fraction) {
            Ok(())
        } else {
            Err(FractionOutOfRange)
        }
    }
}

/// Seed of the mixture's per-sample choice.
const MIX_STREAM: u64 = 0x6d69_7874_7572_6521;

impl MixedSource<'_> {
    /// Whether sample `index` comes from `other`.
    pub fn from_other(&self, index: u64) -> bool {
        sample_rng(MIX_STREAM, index).random_bool(self.fraction.clamp(0.0, 1.0))
    }
}

impl SampleSource for MixedSource<'_> {
    fn sample(&self, index: u64) -> Result<TrainingSample, DataError> {
        let source = if self.from_other(index) {
            self.other
        } else {
            self.main
        };
        match source.count() {
            Some(0) => Err(DataError::EmptyMix),
            Some(n) => source.sample(index % n),
            None => source.sample(index),
        }
    }

    fn count(&self) -> Option<u64> {
        // Indices are unbounded when either source is; otherwise the
        // mixture of the two is as long as the longer.
        Some(self.main.count()?.max(self.other.count()?))
    }
}

/// How batch sizes are drawn (pipeline.md §8: 2-7 images of one size, sides
/// multiples of 32, about `pixels` per batch).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BatchPlan {
    /// Smallest side (a multiple of 32).
    pub min_side: usize,
    /// Largest side (a multiple of 32).
    pub max_side: usize,
    /// Pixels per batch to aim at.
    pub pixels: usize,
    /// Fewest images per batch.
    pub min_images: usize,
    /// Most images per batch.
    pub max_images: usize,
    /// Fraction of images augmented.
    pub p_augment: f64,
}

impl BatchPlan {
    /// The paper's plan: sides 224..768, ~1 MP, 2-7 images, half augmented.
    pub const SPEC: Self = Self {
        min_side: 224,
        max_side: 768,
        pixels: 1 << 20,
        min_images: 2,
        max_images: 7,
        p_augment: 0.5,
    };

    /// Checks the plan; the message says what is wrong.
    pub fn validate(&self) -> Result<(), InvalidPlan> {
        if self.min_side < 32
            || !self.min_side.is_multiple_of(32)
            || !self.max_side.is_multiple_of(32)
        {
            return Err(InvalidPlan(format!(
                "batch sides {}..{} must be multiples of 32, at least 32",
                self.min_side, self.max_side
            )));
        }
        if self.min_side > self.max_side
            || self.min_images == 0
            || self.min_images > self.max_images
        {
            return Err(InvalidPlan(format!(
                "empty batch plan: sides {}..{}, images {}..{}",
                self.min_side, self.max_side, self.min_images, self.max_images
            )));
        }
        Ok(())
    }

    /// Draws (width, height, images) for one batch.
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> (usize, usize, usize) {
        let side = |rng: &mut R| 32 * rng.random_range(self.min_side / 32..=self.max_side / 32);
        let (w, h) = (side(rng), side(rng));
        (w, h, self.images(w, h))
    }

    /// Images in a batch of `width x height` images: as many as make
    /// about [`BatchPlan::pixels`], within the plan's bounds.
    pub fn images(&self, width: usize, height: usize) -> usize {
        let images = (self.pixels as f64 / (width * height) as f64).round() as usize;
        images.clamp(self.min_images, self.max_images)
    }
}

/// Seed offset that keeps batch draws apart from sample seeds.
const BATCH_STREAM: u64 = 0x6261_7463_6865_7321;

/// The samples of batch `step`: drawn size, sample indices, fitting and
/// augmentation all from (seed, step).
pub fn batch_samples(
    source: &dyn SampleSource,
    plan: &BatchPlan,
    seed: u64,
    step: u64,
) -> Result<Vec<TrainingSample>, DataError> {
    let mut rng = sample_rng(seed ^ BATCH_STREAM, step);
    let (w, h, images) = plan.draw(&mut rng);
    let mut samples = Vec::with_capacity(images);
    for j in 0..images as u64 {
        let index = match source.count() {
            Some(n) => rng.random_range(0..n),
            None => step * plan.max_images as u64 + j,
        };
        let sample = source.sample(index)?;
        let mut fitted = fit(sample, w, h, &mut rng);
        if rng.random_bool(plan.p_augment) {
            augment(&mut fitted, &mut rng);
        }
        samples.push(fitted);
    }
    Ok(samples)
}

/// Seed offset of cached samples' fitting and augmentation.
const CACHED_STREAM: u64 = 0x6361_6368_6564_2121;

/// Sample `index` of a feature cache made from `source`: the source's
/// sample `index` (modulo its count when it is stored), fitted to `width
/// x height` as `zoom` scales it and augmented with probability `p_augment`, all drawn from
/// (seed, index) alone.
pub fn cached_view(
    source: &dyn SampleSource,
    index: u64,
    (width, height): (usize, usize),
    zoom: Zoom,
    p_augment: f64,
    seed: u64,
) -> Result<TrainingSample, DataError> {
    let mut rng = sample_rng(seed ^ CACHED_STREAM, index);
    let sample = match source.count() {
        Some(0) => return Err(DataError::EmptyMix),
        Some(n) => source.sample(index % n)?,
        None => source.sample(index)?,
    };
    let mut fitted = fit_with(sample, width, height, zoom, &mut rng);
    if rng.random_bool(p_augment) {
        augment(&mut fitted, &mut rng);
    }
    Ok(fitted)
}

/// How a sample is scaled before a window of the batch's size is cut out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Zoom {
    /// As `matseg train` fits its batches: the whole sample shrunk (or
    /// grown) to just cover the window, then up to 1.5 times more.
    #[default]
    Cover,
    /// Any scale from that to the sample's own (log-uniform): windows from
    /// the whole scene shrunk down to a crop at full resolution, so that
    /// materials are seen at the scales photos show them at too.
    Native,
}

impl Zoom {
    /// The scale factor for a `sw x sh` sample and a `width x height` window.
    fn draw(
        self,
        (sw, sh): (f64, f64),
        (width, height): (usize, usize),
        rng: &mut ChaCha8Rng,
    ) -> f64 {
        let cover = (width as f64 / sw).max(height as f64 / sh);
        match self {
            Zoom::Cover => cover * rng.random_range(1.0..1.5),
            Zoom::Native => {
                let most = (1.0 / cover).max(1.5);
                cover * rng.random_range(0.0..most.ln()).exp()
            }
        }
    }
}

/// Scales `sample` to cover `width x height` (up to 1.5x more, at random)
/// and crops a random window of that size ([`fit_with`], [`Zoom::Cover`]).
pub fn fit(
    sample: TrainingSample,
    width: usize,
    height: usize,
    rng: &mut ChaCha8Rng,
) -> TrainingSample {
    fit_with(sample, width, height, Zoom::Cover, rng)
}

/// Scales `sample` as `zoom` draws and crops a random `width x height`
/// window; weights are resampled alike and the ROI is kept where its
/// resampled value is at least 0.5.
pub fn fit_with(
    sample: TrainingSample,
    width: usize,
    height: usize,
    zoom: Zoom,
    rng: &mut ChaCha8Rng,
) -> TrainingSample {
    let (sw, sh) = (sample.width as f64, sample.height as f64);
    let scale = zoom.draw((sw, sh), (width, height), rng);
    let rw = ((sw * scale).round() as u32).max(width as u32);
    let rh = ((sh * scale).round() as u32).max(height as u32);
    let x0 = rng.random_range(0..=rw - width as u32);
    let y0 = rng.random_range(0..=rh - height as u32);
    let (w, h) = (width as u32, height as u32);

    let rgb = RgbImage::from_raw(sample.width as u32, sample.height as u32, sample.rgb)
        .expect("RGB size");
    let rgb = imageops::crop_imm(
        &imageops::resize(&rgb, rw, rh, FilterType::Triangle),
        x0,
        y0,
        w,
        h,
    )
    .to_image()
    .into_raw();
    let plane = |data: Vec<f32>| -> Vec<f32> {
        let img: ImageBuffer<Luma<f32>, Vec<f32>> =
            ImageBuffer::from_raw(sample.width as u32, sample.height as u32, data)
                .expect("plane size");
        imageops::crop_imm(
            &imageops::resize(&img, rw, rh, FilterType::Triangle),
            x0,
            y0,
            w,
            h,
        )
        .to_image()
        .into_raw()
    };
    TrainingSample {
        rgb,
        width,
        height,
        weights: sample.weights.into_iter().map(plane).collect(),
        roi: plane(sample.roi)
            .into_iter()
            .map(|v| if v >= 0.5 { 1.0 } else { 0.0 })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `count` samples (unbounded when `None`) whose width says which
    /// source made them and whose height is the index asked for.
    struct Tagged {
        tag: usize,
        count: Option<u64>,
    }

    impl SampleSource for Tagged {
        fn sample(&self, index: u64) -> Result<TrainingSample, DataError> {
            if self.count.is_some_and(|n| index >= n) {
                return Err(DataError::Read(crate::ReadError::Io {
                    path: format!("sample {index}").into(),
                    reason: "past the end".into(),
                }));
            }
            Ok(TrainingSample {
                rgb: Vec::new(),
                width: self.tag,
                height: index as usize,
                weights: Vec::new(),
                roi: Vec::new(),
            })
        }

        fn count(&self) -> Option<u64> {
            self.count
        }
    }

    #[test]
    fn a_mixture_takes_its_share_from_each_source_by_index_alone() {
        let (main, other) = (
            Tagged {
                tag: 1,
                count: None,
            },
            Tagged {
                tag: 2,
                count: Some(7),
            },
        );
        let mixture = MixedSource {
            main: &main,
            other: &other,
            fraction: 0.3,
        };
        assert_eq!(mixture.count(), None);
        let drawn: Vec<TrainingSample> = (0..2000).map(|i| mixture.sample(i).unwrap()).collect();
        let from_other = drawn.iter().filter(|s| s.width == 2).count();
        assert!((540..660).contains(&from_other), "{from_other} of 2000");
        for (i, s) in drawn.iter().enumerate() {
            // The stored source's samples wrap around its count.
            let expected = if s.width == 2 { i % 7 } else { i };
            assert_eq!(s.height, expected, "sample {i}");
            assert_eq!(mixture.from_other(i as u64), s.width == 2);
        }
        let none = MixedSource {
            fraction: 0.0,
            ..mixture
        };
        assert!((0..200).all(|i| !none.from_other(i)));
    }

    #[test]
    fn mixture_fractions_are_shares() {
        for ok in [0.0, 0.3, 1.0] {
            assert_eq!(MixedSource::check_fraction(ok), Ok(()));
        }
        for bad in [-0.1, 1.5, f64::NAN] {
            assert_eq!(MixedSource::check_fraction(bad), Err(FractionOutOfRange));
        }
    }
}
