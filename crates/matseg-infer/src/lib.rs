//! The trained net's descriptors in pure Rust, without libtorch: the
//! engine under `matseg segment`, `apply`, `serve`, `track` and `eval` on
//! the CPU in every build (libtorch runs them on CUDA), and under the
//! Python package.
//!
//! It reads what `matseg train` writes (a run folder's `run.json` and
//! `model.safetensors`, 16- or 32-bit) and computes what matseg-net's
//! `TrainedNet` computes in inference mode: BatchNorm folded into the
//! convolutions, each operator rten's (`rten::ops`, called as functions
//! on the weights; no ONNX export, no graph). Its descriptors agree with
//! libtorch's to a cosine of 0.9999 per cell (tests/equality.rs). The
//! `imagenet` baseline (torchvision's ImageNet MobileNetV2 features) runs
//! on the same engine ([`ImagenetBaseline`]).

#![warn(missing_docs)]

mod colour;
mod encoder;
mod imagenet;
mod layers;
mod model;
mod net;
mod weights;

pub use imagenet::ImagenetBaseline;
pub use model::InferNet;
