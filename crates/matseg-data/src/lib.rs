//! Datasets on disk: per-sample seeds, sidecars, the MatSeg folder layout,
//! WebDataset tar shards, the resumable parallel writer and the reader.

#![warn(missing_docs)]

pub mod augment;
pub mod encode;
pub mod folders;
pub mod generate;
pub mod maker;
pub mod reader;
pub mod seed;
pub mod training;
pub mod wds;

pub use encode::{encode_sample, encode_scene, EncodedSample, SampleMeta};
pub use generate::{
    generate_dataset, generate_with, DatasetManifest, Format, GenerateError, GenerateOptions,
    GenerateReport, JobError, JobSlice,
};
pub use maker::{FrameOf, Generator2d, Generator3d, SampleError, SampleMaker};
pub use reader::{
    decode_encoded, index_tar, read_tar_member, Dataset, ReadError, Sample, TarMember,
    TrainingTargets,
};
pub use seed::sample_rng;
