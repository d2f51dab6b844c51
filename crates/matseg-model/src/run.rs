//! A run folder as inference reads it: `run.json` beside the weights, the
//! settings inference takes from it, and where the shipped default model
//! is.

use crate::config::NetConfig;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The run's settings file.
pub const RUN_FILE: &str = "run.json";
/// The weights for inference.
pub const MODEL_FILE: &str = "model.safetensors";

/// What `--model default` names: the model shipped in the repository's
/// `models/default/`.
pub const DEFAULT_MODEL: &str = "default";

/// A model's file that cannot be found or read, naming it.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {message}")]
pub struct ModelError {
    /// The file.
    pub file: String,
    /// What is wrong.
    pub message: String,
}

/// The run folder and the weights file `model` names: a run folder and
/// its `model.safetensors`, or a weights file and the folder it is in.
pub fn run_files(model: &Path) -> (&Path, PathBuf) {
    if model.is_dir() {
        (model, model.join(MODEL_FILE))
    } else {
        (
            model.parent().unwrap_or(Path::new(".")),
            model.to_path_buf(),
        )
    }
}

/// The folder of the shipped default model: `$MATSEG_DEFAULT_MODEL` when
/// set, else `models/default/` of the checkout this was built from, else
/// `models/default/` under the current folder; `None` when none of them
/// holds a run.
pub fn default_model_dir() -> Option<PathBuf> {
    let built_from = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/default");
    std::env::var_os("MATSEG_DEFAULT_MODEL")
        .map(PathBuf::from)
        .into_iter()
        .chain([built_from, PathBuf::from("models/default")])
        .find(|dir| dir.join(RUN_FILE).is_file())
}

/// The model a `--model` argument names: [`DEFAULT_MODEL`] is the shipped
/// one ([`default_model_dir`]), anything else a run folder or weights file.
pub fn resolve_model(name: &Path) -> Result<PathBuf, ModelError> {
    if name != Path::new(DEFAULT_MODEL) {
        return Ok(name.to_path_buf());
    }
    default_model_dir().ok_or_else(|| ModelError {
        file: "models/default".into(),
        message: "the shipped default model is not here (set MATSEG_DEFAULT_MODEL to its folder, or give --model RUN)".into(),
    })
}

/// What inference reads of a run's `run.json`: the net's shape and the
/// sizes photos are described at. (Training reads the whole file.)
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct InferenceSettings {
    /// The net's shape.
    pub net: NetConfig,
    /// Photos whose longer side exceeds this many pixels are described at
    /// that size, the descriptors resized back to the photo (`None`: at
    /// their own size).
    #[serde(default)]
    pub inference_side: Option<u32>,
    /// Further longer sides photos are described at: the unit descriptors
    /// of every size are resized onto the main size's grid and added.
    #[serde(default)]
    pub extra_inference_sides: Vec<u32>,
}

impl InferenceSettings {
    /// Reads them from the text of a `run.json`; `file` names it in errors.
    pub fn parse(text: &str, file: &Path) -> Result<Self, ModelError> {
        serde_json::from_str(text).map_err(|e| ModelError {
            file: file.display().to_string(),
            message: format!("not a run config: {e}"),
        })
    }
}

/// Reads the inference settings of the run folder `dir` (its `run.json`).
pub fn read_inference_settings(dir: &Path) -> Result<InferenceSettings, ModelError> {
    let path = dir.join(RUN_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| ModelError {
        file: path.display().to_string(),
        message: if path.exists() {
            format!("cannot read: {e}")
        } else {
            format!("not a run: no {RUN_FILE} beside the weights")
        },
    })?;
    InferenceSettings::parse(&text, &path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_run_gives_its_sizes() {
        let dir = default_model_dir().expect("models/default in the checkout");
        let settings = read_inference_settings(&dir).unwrap();
        assert_eq!(settings.inference_side, Some(700));
        assert_eq!(settings.extra_inference_sides, [448, 256, 128]);
        assert_eq!(settings.net.output_dim(), 408);
        assert_eq!(resolve_model(Path::new(DEFAULT_MODEL)).unwrap(), dir);
    }

    #[test]
    fn a_folder_without_a_run_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let error = read_inference_settings(dir.path()).unwrap_err();
        assert!(error.to_string().contains("not a run"), "{error}");
        std::fs::write(dir.path().join(RUN_FILE), "{\"net\": 3}").unwrap();
        let error = read_inference_settings(dir.path()).unwrap_err();
        assert!(error.file.ends_with(RUN_FILE), "{error}");
        assert!(error.message.starts_with("not a run config"), "{error}");
    }

    #[test]
    fn a_weights_file_names_its_folder() {
        let dir = tempfile::tempdir().unwrap();
        let weights = dir.path().join("best.safetensors");
        assert_eq!(run_files(&weights), (dir.path(), weights.clone()));
        assert_eq!(
            run_files(dir.path()),
            (dir.path(), dir.path().join(MODEL_FILE))
        );
    }
}
