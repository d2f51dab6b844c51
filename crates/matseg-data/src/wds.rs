//! WebDataset tar shards (pipeline.md §7.2): `KEY.jpg`, `KEY.mask_00.png`...,
//! `KEY.roi.png`, `KEY.json` per sample; a shard is written under a temporary
//! name and renamed when complete.

use crate::encode::EncodedSample;
use matseg_image::outputs::temporary_path;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// The file of shard `shard`.
pub fn shard_path(root: &Path, shard: u64) -> PathBuf {
    root.join(format!("shard-{shard:06}.tar"))
}

/// The sample key inside shards.
pub fn sample_key(index: u64) -> String {
    format!("{index:08}")
}

/// Appends one member to a tar builder, with fixed metadata so the bytes
/// depend only on the name and content.
pub fn append_member<W: Write>(
    tar: &mut tar::Builder<W>,
    name: &str,
    data: &[u8],
) -> io::Result<()> {
    let mut header = tar::Header::new_ustar();
    header.set_size(data.len() as u64);
    header.set_mode(0o644);
    header.set_mtime(0);
    header.set_uid(0);
    header.set_gid(0);
    header.set_entry_type(tar::EntryType::Regular);
    tar.append_data(&mut header, name, data)
}

/// Appends one sample's members to a tar builder ([`append_member`]).
pub fn append_sample<W: Write>(
    tar: &mut tar::Builder<W>,
    sample: &EncodedSample,
) -> io::Result<()> {
    let key = sample_key(sample.index);
    let mut add = |name: String, data: &[u8]| append_member(tar, &name, data);
    add(format!("{key}.jpg"), &sample.jpg)?;
    for (k, mask) in sample.masks.iter().enumerate() {
        add(format!("{key}.mask_{k:02}.png"), mask)?;
    }
    add(format!("{key}.roi.png"), &sample.roi)?;
    add(format!("{key}.json"), &sample.json)
}

/// An open shard being written to `PATH.tmp`.
pub struct ShardWriter {
    path: PathBuf,
    tmp: PathBuf,
    tar: tar::Builder<io::BufWriter<std::fs::File>>,
}

impl ShardWriter {
    /// Starts shard file `path` (written as `path.tmp` until finished).
    pub fn create(path: PathBuf) -> io::Result<Self> {
        let tmp = temporary_path(&path);
        let file = std::fs::File::create(&tmp)?;
        let mut tar = tar::Builder::new(io::BufWriter::new(file));
        tar.mode(tar::HeaderMode::Deterministic);
        Ok(Self { path, tmp, tar })
    }

    /// Appends a sample.
    pub fn append(&mut self, sample: &EncodedSample) -> io::Result<()> {
        append_sample(&mut self.tar, sample)
    }

    /// Closes the archive and renames it into place.
    pub fn finish(self) -> io::Result<()> {
        let mut out = self.tar.into_inner()?;
        out.flush()?;
        out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&self.tmp, &self.path)
    }
}
