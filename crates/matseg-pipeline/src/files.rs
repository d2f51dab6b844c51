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

/// Writes the folder `out` whole or not at all: `work` fills its
/// `OUT.partial` sibling, which is renamed into place when `work` succeeds
/// and removed when it fails. An existing `out` is replaced only when it
/// holds nothing but entries named in `owned` (an earlier output of the
/// same command, `what`); `out/`, `.` and the like name the folder itself.
#[cfg(feature = "net")]
pub(crate) fn replace_folder<T>(
    out: &Path,
    owned: &[&str],
    what: &str,
    work: impl FnOnce(&Path) -> Result<T, PipelineError>,
) -> Result<T, PipelineError> {
    let out = &matseg_image::io::output_folder(out)?;
    if let Some(stranger) = foreign_entry(out, owned) {
        return Err(PipelineError::file(
            out.display(),
            format!(
                "holds {stranger:?}, which no {what} output has (only an earlier {what} output is replaced): choose another --out"
            ),
        ));
    }
    let partial = matseg_image::io::partial_folder(out);
    if partial.exists() {
        std::fs::remove_dir_all(&partial)
            .map_err(|e| PipelineError::file(partial.display(), format!("cannot remove: {e}")))?;
    }
    let done = match work(&partial) {
        Ok(done) => done,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&partial);
            return Err(e);
        }
    };
    if out.exists() {
        std::fs::remove_dir_all(out)
            .map_err(|e| PipelineError::file(out.display(), format!("cannot replace: {e}")))?;
    }
    std::fs::rename(&partial, out).map_err(|e| {
        PipelineError::file(out.display(), format!("cannot rename into place: {e}"))
    })?;
    Ok(done)
}

/// The first entry of the folder `out` whose name `owned` does not list;
/// none when `out` does not exist, is empty or holds only owned entries.
/// A file at `out` is its own stranger.
#[cfg(feature = "net")]
fn foreign_entry(out: &Path, owned: &[&str]) -> Option<String> {
    if !out.exists() {
        return None;
    }
    let Ok(listing) = std::fs::read_dir(out) else {
        return Some(out.display().to_string());
    };
    let mut names: Vec<String> = listing
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect();
    names.sort();
    names.into_iter().find(|n| !owned.contains(&n.as_str()))
}
