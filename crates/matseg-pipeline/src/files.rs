//! Folders and files the jobs write, with errors that name them; what a
//! job may do to its output is matseg_image::outputs'.

use crate::error::PipelineError;
use matseg_image::outputs::write_atomic;
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

/// Writes the output folder `out` of `command`, whose inputs are
/// `inputs`, whole or not at all (matseg_image::outputs::StagedOutput):
/// `work` fills the staging folder it is given, which is put in place
/// when `work` succeeds and removed when it fails.
#[cfg(feature = "infer")]
pub(crate) fn write_folder<T>(
    out: &Path,
    command: &str,
    inputs: &[&Path],
    work: impl FnOnce(&Path) -> Result<T, PipelineError>,
) -> Result<T, PipelineError> {
    let staged = matseg_image::outputs::StagedOutput::begin(out, command, inputs)?;
    let done = work(staged.dir())?;
    staged.finish()?;
    Ok(done)
}
