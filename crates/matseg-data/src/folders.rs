//! The MatSeg folder layout (pipeline.md §7.1): one folder per sample holding
//! `RGB__RGB.jpg`, `mask0.png`..., `ObjectMaskOcluded.png`, our `meta.json`,
//! and `Finished.txt`, written last.

use crate::encode::EncodedSample;
use matseg_image::outputs;
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

/// The folder sample folder `dir` is staged in: `NNNNNNNN.partial`.
pub fn partial_dir(dir: &Path) -> PathBuf {
    let mut name = dir.as_os_str().to_owned();
    name.push(PARTIAL_SUFFIX);
    PathBuf::from(name)
}

/// Whether the folder `dir` holds nothing but a sample's files (complete
/// or not), matseg's staging marker aside: a sample folder this layout
/// wrote, as far as names tell.
pub fn holds_only_sample_files(dir: &Path) -> bool {
    outputs::holds_only(dir, &|name| {
        let mask = name
            .strip_prefix("mask")
            .and_then(|k| k.strip_suffix(".png"))
            .is_some_and(|k| !k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()));
        mask || [IMAGE_FILE, ROI_FILE, META_FILE, FINISHED_FILE].contains(&name)
    })
}

/// Writes a sample: files go to `NNNNNNNN.partial/` (made with matseg's
/// marker; one left without it, someone else's, is refused), which is
/// renamed into place, then the marker is taken out and `Finished.txt` is
/// written last. A reader therefore never sees a complete-looking partial
/// sample, and a crash at any point leaves a folder without
/// `Finished.txt`, which the next run replaces. An unfinished sample
/// folder is replaced only when it holds nothing but a sample's files.
pub fn write_sample(root: &Path, sample: &EncodedSample) -> io::Result<()> {
    let dir = sample_dir(root, sample.index);
    let tmp = partial_dir(&dir);
    outputs::stage_folder(&tmp, COMMAND).map_err(io::Error::other)?;
    for (name, bytes) in sample_files(sample) {
        std::fs::write(tmp.join(name), bytes)?;
    }
    if dir.exists() {
        if !holds_only_sample_files(&dir) {
            return Err(io::Error::other(format!(
                "{}: holds files that are not a sample's; move them",
                dir.display()
            )));
        }
        std::fs::remove_dir_all(&dir)?;
    }
    std::fs::rename(&tmp, &dir)?;
    outputs::unmark(&dir).map_err(io::Error::other)?;
    std::fs::write(dir.join(FINISHED_FILE), b"")
}

/// The command that writes datasets, in matseg's markers.
pub(crate) const COMMAND: &str = "generate";

/// Removes leftover `NNNNNNNN.partial/` folders of interrupted runs whose
/// index `mine` accepts and that carry matseg's marker (any other is left
/// alone).
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
            if mine(index) && outputs::is_marked(&path, COMMAND) {
                std::fs::remove_dir_all(&path)?;
            }
        }
    }
    Ok(())
}
