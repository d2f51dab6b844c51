//! A model's weights file as the engine reads it: every tensor widened to
//! 32-bit floats, found by name, its shape checked against the net's.

use matseg_model::ModelError;
use std::collections::HashMap;
use std::path::Path;

/// The tensors of one weights file.
pub(crate) struct Weights {
    /// The file, for errors.
    file: String,
    tensors: HashMap<String, matseg_weights::Tensor>,
}

impl Weights {
    /// The tensors of the safetensors file `path`.
    pub(crate) fn read(path: &Path) -> Result<Self, ModelError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| ModelError {
            file: file.clone(),
            message: format!("cannot read: {e}"),
        })?;
        Self::parse(&bytes, file)
    }

    /// The tensors of a safetensors file's bytes; `file` names it in errors.
    pub(crate) fn parse(bytes: &[u8], file: String) -> Result<Self, ModelError> {
        let tensors = matseg_weights::read_safetensors(bytes, &file).map_err(|e| ModelError {
            file: e.file,
            message: e.message,
        })?;
        Ok(Self::from_tensors(tensors, file))
    }

    /// Tensors already read; `file` names them in errors.
    pub(crate) fn from_tensors(tensors: Vec<matseg_weights::Tensor>, file: String) -> Self {
        Self {
            tensors: tensors.into_iter().map(|t| (t.name.clone(), t)).collect(),
            file,
        }
    }

    /// An error about this file.
    pub(crate) fn error(&self, message: String) -> ModelError {
        ModelError {
            file: self.file.clone(),
            message,
        }
    }

    /// The values of the tensor `name`, which must have `shape`.
    pub(crate) fn get(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>, ModelError> {
        let tensor = self.tensors.get(name).ok_or_else(|| {
            self.error(format!(
                "has no tensor {name}: not weights of the net its run.json describes"
            ))
        })?;
        if tensor.shape != shape {
            return Err(self.error(format!(
                "{name} is {:?}, the net's run.json makes it {shape:?}",
                tensor.shape
            )));
        }
        tensor
            .float_values()
            .ok_or_else(|| self.error(format!("{name} is {:?}, not floats", tensor.dtype)))
    }

    /// The one value of the tensor `name` of shape `[1]`.
    pub(crate) fn scalar(&self, name: &str) -> Result<f32, ModelError> {
        Ok(self.get(name, &[1])?[0])
    }
}
