//! The library layer under matseg's front ends: the `matseg` CLI, the web
//! app and the Python package call these functions with plain values and get
//! plain values back; they parse arguments, show progress and print, and
//! hold no pipeline decisions of their own.
//!
//! - [`sources`]: where photos, textures and the cache are, and the photo
//!   and texture libraries a generator or a training run draws from,
//!   resolved once per process.
//! - [`materials`]: PBR material libraries made from textures, and the
//!   default ones of the 3D generator.
//! - [`progress`]: how a long job reports progress and warnings to its
//!   front end.

#![warn(missing_docs)]

pub mod materials;
pub mod progress;
pub mod sources;
