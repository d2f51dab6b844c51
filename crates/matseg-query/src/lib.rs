//! What a model's per-pixel descriptors answer, whatever the model (a
//! trained net, ImageNet features, colour statistics): descriptor maps and
//! the interface every model implements, point descriptors and similarity
//! maps on a coarse grid (the interactive fast path), clustering into
//! materials, selections made by positive and negative clicks, and the
//! memory that follows clicked materials through video frames. Images
//! themselves are matseg-image's.

#![warn(missing_docs)]

pub mod cluster;
pub mod coarse;
pub mod colour_features;
pub mod colours;
pub mod descriptor;
pub mod edges;
pub mod net;
pub mod ridge;
pub mod select;
pub mod tracking;

pub use cluster::{cluster_descriptors, ClusterOptions, Clustering};
