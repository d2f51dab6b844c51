//! Folders and files the jobs write, with errors that name them.

use crate::error::PipelineError;
use matseg_image::io::write_atomic;
use std::path::Path;

/// Creates `dir` and its parents.
pub(crate) fn create_folder(dir: &Path) -> Result<(), PipelineError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| PipelineError::file(dir.display(), format!("cannot create: {e}")))
}

/// Writes `bytes` to `path` through a temporary file.
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), PipelineError> {
    write_atomic(path, bytes)
        .map_err(|e| PipelineError::file(path.display(), format!("cannot write: {e}")))
}
