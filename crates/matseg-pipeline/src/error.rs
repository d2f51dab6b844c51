//! What can go wrong in a pipeline job: each variant carries the error of
//! the crate that found it, whose message names the file (or the setting)
//! and the problem in one line.

use crate::sources::SourceError;
use matseg_eval::BenchError;
use matseg_extract::material_library::MaterialError;
use matseg_image::ImageIoError;

/// Why a setting that needs the net is refused in a build without it.
#[cfg(not(feature = "net"))]
pub const NO_NET: &str = "this matseg was built without the net (cargo feature `net`)";

/// Why a pipeline job failed.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// Sources could not be resolved or scanned.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// A material folder could not be read or written.
    #[error(transparent)]
    Material(#[from] MaterialError),
    /// A benchmark could not be read or scored.
    #[error(transparent)]
    Bench(#[from] BenchError),
    /// An image could not be read or written.
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// An output refused (it overlaps an input, or holds what matseg did
    /// not write) or that could not be put in place.
    #[error(transparent)]
    Output(#[from] matseg_image::outputs::OutputError),
    /// A registry package could not be fetched or installed.
    #[error(transparent)]
    Asset(#[from] matseg_assets::AssetError),
    /// A weights file could not be read.
    #[error(transparent)]
    Weights(#[from] matseg_weights::WeightsError),
    /// A recipe file that cannot be read or holds values out of range.
    #[error(transparent)]
    Recipe(#[from] matseg_scene::RecipeError),
    /// A 2D scene could not be composed.
    #[error(transparent)]
    Compose(#[from] matseg_scene::ComposeError),
    /// Soft maps could not be drawn.
    #[error(transparent)]
    SoftMaps(#[from] matseg_extract::SoftMapError),
    /// A 3D scene could not be loaded or rendered.
    #[error(transparent)]
    Render(#[from] matseg_render::SceneError),
    /// A dataset could not be written.
    #[error(transparent)]
    Generate(#[from] matseg_data::GenerateError),
    /// A dataset could not be read.
    #[error(transparent)]
    Dataset(#[from] matseg_data::ReadError),
    /// The net failed: a model or checkpoint that does not load, training
    /// data that cannot be read, libtorch.
    #[cfg(feature = "net")]
    #[error(transparent)]
    Net(#[from] matseg_net::NetError),
    /// A trained model whose files cannot be found, read or run.
    #[error(transparent)]
    Model(#[from] matseg_model::ModelError),
    /// A file or folder that cannot be read, written or used.
    #[error("{file}: {message}")]
    File {
        /// The file or folder.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// A setting out of its range, or that does not fit the others.
    #[error("{name}{}: {message}", value.as_ref().map(|v| format!(" {v}")).unwrap_or_default())]
    Setting {
        /// The setting, as the job's configuration names it, in words
        /// (`mix fraction`; a front end may spell it its own way, as the
        /// CLI's `--mix-fraction`).
        name: String,
        /// The value given, when one is at fault.
        value: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// Settings that do not go together; the message names them.
    #[error("{0}")]
    Settings(String),
}

impl PipelineError {
    /// A problem with `file` (a path or a label).
    pub fn file(file: impl std::fmt::Display, message: impl Into<String>) -> Self {
        Self::File {
            file: file.to_string(),
            message: message.into(),
        }
    }

    /// A problem with the setting `name` (its value `value`).
    pub fn setting(
        name: impl Into<String>,
        value: Option<impl std::fmt::Display>,
        message: impl Into<String>,
    ) -> Self {
        Self::Setting {
            name: name.into(),
            value: value.map(|v| v.to_string()),
            message: message.into(),
        }
    }
}
