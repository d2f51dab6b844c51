//! Datasets on disk: per-sample seeds, sidecars, the MatSeg folder layout,
//! WebDataset tar shards, the resumable parallel writer and the reader.

#![warn(missing_docs)]

pub mod encode;
pub mod folders;
pub mod generate;
pub mod reader;
pub mod seed;
pub mod wds;

pub use encode::{encode_scene, EncodedSample, SampleMeta};
pub use generate::{
    generate_dataset, DatasetManifest, Format, GenerateError, GenerateOptions, GenerateReport,
    JobSlice,
};
pub use reader::{Dataset, ReadError, Sample, TrainingTargets};
pub use seed::sample_rng;
