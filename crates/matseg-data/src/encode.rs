//! A scene turned into the bytes of one sample: JPEG image, PNG masks and ROI,
//! and the JSON sidecar.

use matseg_image::io::{encode_jpeg, encode_png_grey};
use matseg_scene::{quantise_weights, QuantisedAnnotation, Scene2d, SourceRef, Sources};
use serde::{Deserialize, Serialize};

/// JPEG quality of sample images (OpenCV's default, as in the original).
pub const JPEG_QUALITY: u8 = 95;

/// Version of the sidecar layout.
pub const SIDECAR_VERSION: u32 = 1;

/// The JSON sidecar of a sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleMeta {
    /// Sidecar layout version.
    pub version: u32,
    /// Scene kind (`2d` or `3d`).
    pub kind: String,
    /// Dataset seed.
    pub seed: u64,
    /// Sample index.
    pub index: u64,
    /// Every source file used, with its role and licence.
    pub sources: Vec<SourceRef>,
    /// The distinct licences of those files, sorted.
    pub licences: Vec<String>,
    /// Every drawn parameter: a 2D scene record, or the 3D scene
    /// description (`matseg render` re-renders it).
    pub scene: serde_json::Value,
    /// In a 3D sequence, which frame of which sequence this is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<crate::maker::FrameOf>,
}

/// The encoded files of one sample.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedSample {
    /// Sample index.
    pub index: u64,
    /// The image as JPEG.
    pub jpg: Vec<u8>,
    /// One PNG per material mask.
    pub masks: Vec<Vec<u8>>,
    /// The ROI mask as PNG.
    pub roi: Vec<u8>,
    /// The sidecar as pretty JSON.
    pub json: Vec<u8>,
}

impl EncodedSample {
    /// Total encoded bytes.
    pub fn bytes(&self) -> usize {
        self.jpg.len()
            + self.masks.iter().map(Vec::len).sum::<usize>()
            + self.roi.len()
            + self.json.len()
    }
}

/// Encodes a scene as sample `index` of a dataset seeded with `seed`.
pub fn encode_scene(scene: &Scene2d, seed: u64, index: u64, sources: Sources<'_>) -> EncodedSample {
    let q = quantise_weights(&scene.weights, &scene.background);
    let record = serde_json::to_value(&scene.record).expect("record serialises");
    let meta = SampleMeta::new("2d", seed, index, scene.record.source_refs(sources), record);
    encode_sample(index, &scene.image, &q, &meta)
}

impl SampleMeta {
    /// The sidecar of sample `index` of a dataset seeded with `seed`: its
    /// kind, the files it used (their distinct licences listed apart) and
    /// its drawn scene.
    pub fn new(
        kind: &str,
        seed: u64,
        index: u64,
        sources: Vec<SourceRef>,
        scene: serde_json::Value,
    ) -> Self {
        let mut licences: Vec<String> = sources.iter().map(|r| r.licence.clone()).collect();
        licences.sort();
        licences.dedup();
        SampleMeta {
            version: SIDECAR_VERSION,
            kind: kind.into(),
            seed,
            index,
            sources,
            licences,
            scene,
            frame: None,
        }
    }
}

/// Encodes an image, its quantised annotation and its sidecar.
pub fn encode_sample(
    index: u64,
    image: &image::RgbImage,
    annotation: &QuantisedAnnotation,
    meta: &SampleMeta,
) -> EncodedSample {
    let (w, h) = image.dimensions();
    EncodedSample {
        index,
        jpg: encode_jpeg(image, JPEG_QUALITY),
        masks: annotation
            .masks
            .iter()
            .map(|m| encode_png_grey(w, h, m))
            .collect(),
        roi: encode_png_grey(w, h, &annotation.roi),
        json: serde_json::to_vec_pretty(meta).expect("sidecar serialises"),
    }
}
