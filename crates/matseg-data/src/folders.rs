//! The MatSeg folder layout (pipeline.md §7.1): one folder per sample holding
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

/// The file of material mask `k`.
pub fn mask_file(k: usize) -> String {
    format!("mask{k}.png")
}

/// A sample's files in its folder, name and bytes, in the order they are
/// written (`Finished.txt` aside).
pub fn sample_files(sample: &EncodedSample) -> Vec<(String, &[u8])> {
    let mut files = vec![(IMAGE_FILE.to_string(), sample.jpg.as_slice())];
    files.extend(
        sample
            .masks
            .iter()
            .enumerate()
            .map(|(k, mask)| (mask_file(k), mask.as_slice())),
    );
    files.push((ROI_FILE.to_string(), &sample.roi));
    files.push((META_FILE.to_string(), &sample.json));
    files
}

/// Suffix of the folder a sample is written into before it is renamed.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// Writes a sample: files go to `NNNNNNNN.partial/`, which is renamed into
/// place, and `Finished.txt` is written last, into the final folder. A reader
/// therefore never sees a complete-looking partial sample, and a crash at any
/// point leaves a folder without `Finished.txt`, which the next run replaces.
pub fn write_sample(root: &Path, sample: &EncodedSample) -> io::Result<()> {
    let dir = sample_dir(root, sample.index);
    let tmp = root.join(format!("{:08}{PARTIAL_SUFFIX}", sample.index));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp)?;
    }
    std::fs::create_dir_all(&tmp)?;
    for (name, bytes) in sample_files(sample) {
        std::fs::write(tmp.join(name), bytes)?;
    }
    if dir.exists() {
        std::fs::remove_dir_all(&dir)?;
    }
    std::fs::rename(&tmp, &dir)?;
    std::fs::write(dir.join(FINISHED_FILE), b"")
}

/// Removes leftover `NNNNNNNN.partial/` folders of interrupted runs whose
/// index `mine` accepts.
pub fn remove_stale_partials(root: &Path, mine: &dyn Fn(u64) -> bool) -> io::Result<()> {
    for entry in std::fs::read_dir(root)? {
        let path = entry?.path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        if let Some(index) = name
            .strip_suffix(PARTIAL_SUFFIX)
            .and_then(|i| i.parse().ok())
        {
            if mine(index) {
                std::fs::remove_dir_all(&path)?;
            }
        }
    }
    Ok(())
}
