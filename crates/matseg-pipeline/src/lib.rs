//! The library layer under matseg's front ends: the `matseg` CLI, the web
//! app and the Python package call these functions with plain values and get
//! plain values back; they parse arguments, show progress and print, and
//! hold no pipeline decisions of their own.
//!
//! - [`sources`]: where photos, textures and the cache are, and the photo
//!   and texture libraries a generator or a training run draws from,
//!   resolved once per process.
//! - [`soft_maps`]: one photo's soft maps, drawn and written.
//! - [`textures`]: texture libraries extracted from photos, resumable.
//! - [`materials`]: PBR material libraries made from textures, and the
//!   default ones of the 3D generator.
//! - [`files3d`]: the photos, materials, meshes and HDRIs of 3D scenes,
//!   checked once into the asset cache, and the 3D recipe.
//! - [`material_mixes`]: new PBR materials mixed from existing ones.
//! - [`models`]: the descriptor models to score or segment with, baselines
//!   by name and trained nets by folder.
//! - [`weights`]: checkpoints converted to safetensors, and the registry's
//!   ImageNet weights fetched once into the cache.
//! - [`features`] (feature `net`): feature caches, samples run once
//!   through an encoder for fast training on them.
//! - [`train`] (feature `net`): training runs started from a configuration
//!   or resumed from their folder, with each step reported to a callback.
//! - [`segment`] (feature `net`): a model's descriptors of a photo,
//!   similarity maps of points, segmentations and their overlays.
//! - [`select`] (feature `net`): selections by positive and negative
//!   clicks, each material's mask, saved and applied to other photos.
//! - [`bench`]: the benchmark harnesses behind `matseg bench*` and
//!   `cargo bench`.
//! - [`demo`]: the pipeline on the bundled assets as an HTML report.
//! - [`frames`]: the frames of a folder or a video (through ffmpeg), one
//!   at a time; [`overlay_video`]: a tracked video's overlay, as an MP4 or
//!   an animated PNG.
//! - [`track`] (feature `net`): clicked materials followed through the
//!   frames of a video; [`track_bench`]: that scored on generated
//!   sequences with exact masks.
//! - [`point_bench`]: point benchmarks made from generated scenes, and
//!   drawn to check them.
//! - [`render`]: one scene description rendered with its annotation.
//! - [`progress`]: how a long job reports progress and warnings to its
//!   front end (matseg-image's, re-exported).
//! - [`error`]: the one error type of these jobs.
//!
//! docs/library.md walks through them with an example.

#![warn(missing_docs)]

pub mod bench;
pub mod demo;
pub mod error;
#[cfg(feature = "net")]
pub mod features;
mod files;
pub mod files3d;
pub mod frames;
pub mod material_mixes;
pub mod materials;
pub mod models;
#[cfg(feature = "infer")]
pub mod nets;
pub mod overlay_video;
pub mod point_bench;
pub mod render;
pub mod scenes;
#[cfg(feature = "infer")]
pub mod segment;
#[cfg(feature = "infer")]
pub mod select;
pub mod soft_maps;
pub mod sources;
pub mod textures;
#[cfg(feature = "infer")]
pub mod track;
#[cfg(feature = "infer")]
pub mod track_bench;
#[cfg(feature = "net")]
pub mod train;
pub mod train_summary;
pub mod weights;

pub use matseg_image::progress;
