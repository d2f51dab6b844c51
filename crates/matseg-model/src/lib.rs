//! What a trained matseg model is, shared by the engines that run it
//! (libtorch in `matseg-net`, pure Rust in `matseg-infer`): the net's shape
//! ([`NetConfig`]), a run folder's files and its inference settings
//! ([`run`]), and how a photo is prepared for the net ([`input`]).
//!
//! Nothing here links a deep learning library.

#![warn(missing_docs)]

pub mod config;
pub mod input;
pub mod run;

pub use config::{ConvNextConfig, EncoderConfig, NetConfig, DESCRIPTOR_DIM, PRESETS};
pub use run::{
    default_model_dir, read_inference_settings, resolve_model, run_files, InferenceSettings,
    ModelError, DEFAULT_MODEL, MODEL_FILE, RUN_FILE,
};
