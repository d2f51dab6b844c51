//! The MatSeg folder layout (SPEC 7.1): one folder per sample holding
//! `RGB__RGB.jpg`, `mask0.png`..., `ObjectMaskOcluded.png`, our `meta.json`,
//! and `Finished.txt`, written last.

use crate::encode::EncodedSample;
use std::io;
use std::path::{Path, PathBuf};

/// The image file.
pub const IMAGE_FILE: &str = "RGB__RGB.jpg";
/// The ROI file (spelled as the original reader expects).
pub const ROI_FILE: &str = "ObjectMaskOcluded.png";
/// The completion marker.
pub const FINISHED_FILE: &str = "Finished.txt";
/// Our sidecar (ignored by the original reader).
pub const META_FILE: &str = "meta.json";

/// The folder of sample `index`.
pub fn sample_dir(root: &Path, index: u64) -> PathBuf {
    root.join(format!("{index:08}"))
}

/// True when sample `index` has been written completely.
pub fn is_complete(root: &Path, index: u64) -> bool {
    sample_dir(root, index).join(FINISHED_FILE).is_file()
}

/// Writes a sample: files go to a temporary folder that is renamed into place
/// after `Finished.txt`, so a reader never takes a partial sample as complete.
/// A stale partial folder from an interrupted run is replaced.
pub fn write_sample(root: &Path, sample: &EncodedSample) -> io::Result<()> {
    let dir = sample_dir(root, sample.index);
    let tmp = root.join(format!("{:08}.partial", sample.index));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp)?;
    }
    std::fs::create_dir_all(&tmp)?;
    std::fs::write(tmp.join(IMAGE_FILE), &sample.jpg)?;
    for (k, mask) in sample.masks.iter().enumerate() {
        std::fs::write(tmp.join(format!("mask{k}.png")), mask)?;
    }
    std::fs::write(tmp.join(ROI_FILE), &sample.roi)?;
    std::fs::write(tmp.join(META_FILE), &sample.json)?;
    std::fs::write(tmp.join(FINISHED_FILE), b"")?;
    if dir.exists() {
        std::fs::remove_dir_all(&dir)?;
    }
    std::fs::rename(&tmp, &dir)
}
