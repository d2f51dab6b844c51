//! A minimal zip reader: the central directory, and entries stored or
//! deflated. Enough for PyTorch's zip checkpoints, Python wheels and game
//! data archives: [`ZipArchive`] reads a zip held in memory, [`ZipFile`]
//! one on disk (only the directory and the entries asked for are read, so
//! archives of gigabytes need no more memory than their largest entry).

use flate2::read::DeflateDecoder;
use std::io::{Read, Seek, SeekFrom};

/// One entry: name, compression method, sizes and where its header is.
struct Entry {
    name: String,
    method: u16,
    compressed: usize,
    size: usize,
    header: u64,
}

/// Why a zip archive or one of its entries cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ZipError {
    /// The archive ends before a structure it needs.
    #[error("zip: truncated")]
    Truncated,
    /// No end-of-central-directory record: not a zip.
    #[error("zip: no end of central directory")]
    NoDirectory,
    /// A central directory entry that cannot be parsed.
    #[error("zip: bad central directory entry")]
    BadDirectory,
    /// An entry's local header is not one.
    #[error("zip: bad local header for {0}")]
    BadLocalHeader(String),
    /// An entry whose data ends early.
    #[error("zip: {0} is truncated")]
    TruncatedEntry(String),
    /// An entry that does not inflate to its recorded size.
    #[error("zip: {name}: {problem}")]
    Corrupt {
        /// The entry.
        name: String,
        /// What went wrong.
        problem: String,
    },
    /// An entry compressed with a method other than stored or deflate.
    #[error("zip: {name}: unsupported compression method {method}")]
    Unsupported {
        /// The entry.
        name: String,
        /// Its compression method.
        method: u16,
    },
    /// No entry of that name.
    #[error("zip: no entry {0}")]
    Missing(String),
    /// The source could not be read.
    #[error("zip: {0}")]
    Io(#[from] std::io::Error),
}

/// A zip archive held in memory.
pub struct ZipArchive<'a> {
    bytes: &'a [u8],
    entries: Vec<Entry>,
}

fn u16_at(b: &[u8], at: usize) -> Result<u16, ZipError> {
    b.get(at..at + 2)
        .map(|s| u16::from_le_bytes(s.try_into().expect("2 bytes")))
        .ok_or(ZipError::Truncated)
}

fn u32_at(b: &[u8], at: usize) -> Result<u32, ZipError> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes(s.try_into().expect("4 bytes")))
        .ok_or(ZipError::Truncated)
}

/// The longest tail of a zip that can hold its end-of-central-directory
/// record (22 bytes and a comment of at most 65,535).
const MAX_END_RECORD: usize = 22 + 65_535;

/// Where the central directory is, from the end-of-central-directory record
/// found in `tail` (the last bytes of the archive): entry count, size and
/// offset.
fn directory_location(tail: &[u8]) -> Result<(usize, usize, u64), ZipError> {
    let end = (0..tail.len().saturating_sub(21))
        .rev()
        .find(|&i| tail[i..].starts_with(b"PK\x05\x06"))
        .ok_or(ZipError::NoDirectory)?;
    Ok((
        u16_at(tail, end + 10)? as usize,
        u32_at(tail, end + 12)? as usize,
        u64::from(u32_at(tail, end + 16)?),
    ))
}

/// The `count` entries of the central directory `bytes`.
fn parse_directory(bytes: &[u8], count: usize) -> Result<Vec<Entry>, ZipError> {
    let mut at = 0;
    // Each entry takes 46 bytes at least: a count that cannot fit is not
    // made room for.
    let mut entries = Vec::with_capacity(count.min(bytes.len() / 46));
    for _ in 0..count {
        if !bytes
            .get(at..)
            .is_some_and(|b| b.starts_with(b"PK\x01\x02"))
        {
            return Err(ZipError::BadDirectory);
        }
        let name_len = u16_at(bytes, at + 28)? as usize;
        let name = bytes
            .get(at + 46..at + 46 + name_len)
            .ok_or(ZipError::Truncated)?;
        entries.push(Entry {
            name: String::from_utf8_lossy(name).into_owned(),
            method: u16_at(bytes, at + 10)?,
            compressed: u32_at(bytes, at + 20)? as usize,
            size: u32_at(bytes, at + 24)? as usize,
            header: u64::from(u32_at(bytes, at + 42)?),
        });
        at += 46 + name_len + u16_at(bytes, at + 30)? as usize + u16_at(bytes, at + 32)? as usize;
    }
    Ok(entries)
}

/// The offset of an entry's data from its local header (the header's
/// first 30 bytes).
fn data_offset(local_header: &[u8], name: &str) -> Result<u64, ZipError> {
    if !local_header.starts_with(b"PK\x03\x04") {
        return Err(ZipError::BadLocalHeader(name.to_string()));
    }
    Ok(30 + u64::from(u16_at(local_header, 26)?) + u64::from(u16_at(local_header, 28)?))
}

/// The uncompressed bytes of entry `e` from its stored data.
fn decode(e: &Entry, data: &[u8]) -> Result<Vec<u8>, ZipError> {
    let corrupt = |problem: String| ZipError::Corrupt {
        name: e.name.clone(),
        problem,
    };
    match e.method {
        0 => Ok(data.to_vec()),
        8 => {
            // The recorded size is only a claim: room for more than a few
            // times the compressed bytes is made as they inflate, and no
            // more than one byte past the claim is inflated.
            let mut out = Vec::with_capacity(e.size.min(data.len().saturating_mul(4)));
            DeflateDecoder::new(data)
                .take(e.size as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|err| corrupt(err.to_string()))?;
            if out.len() != e.size {
                return Err(corrupt("size mismatch".into()));
            }
            Ok(out)
        }
        method => Err(ZipError::Unsupported {
            name: e.name.clone(),
            method,
        }),
    }
}

fn find<'e>(entries: &'e [Entry], name: &str) -> Result<&'e Entry, ZipError> {
    entries
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| ZipError::Missing(name.to_string()))
}

impl<'a> ZipArchive<'a> {
    /// Reads the central directory of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Result<Self, ZipError> {
        let (count, size, offset) = directory_location(bytes)?;
        let start = offset as usize;
        let directory = bytes
            .get(start..start.saturating_add(size).min(bytes.len()))
            .ok_or(ZipError::BadDirectory)?;
        let entries = parse_directory(directory, count)?;
        Ok(Self { bytes, entries })
    }

    /// The names of the entries, in directory order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.name.as_str())
    }

    /// The uncompressed bytes of entry `name`.
    pub fn read(&self, name: &str) -> Result<Vec<u8>, ZipError> {
        let e = find(&self.entries, name)?;
        let h = e.header as usize;
        let header = self.bytes.get(h..).unwrap_or_default();
        let start = h + data_offset(header, name)? as usize;
        let data = self
            .bytes
            .get(start..start + e.compressed)
            .ok_or_else(|| ZipError::TruncatedEntry(name.to_string()))?;
        decode(e, data)
    }
}

/// A zip archive read from a seekable source (a file): the central
/// directory is read once, each entry when asked for.
pub struct ZipFile<R> {
    source: R,
    /// The source's length in bytes.
    len: u64,
    entries: Vec<Entry>,
}

impl<R: Read + Seek> ZipFile<R> {
    /// Reads the central directory of `source`.
    pub fn new(mut source: R) -> Result<Self, ZipError> {
        let len = source.seek(SeekFrom::End(0))?;
        let tail_len = len.min(MAX_END_RECORD as u64);
        let mut tail = vec![0; tail_len as usize];
        source.seek(SeekFrom::Start(len - tail_len))?;
        source.read_exact(&mut tail)?;
        let (count, size, offset) = directory_location(&tail)?;
        if offset + size as u64 > len {
            return Err(ZipError::BadDirectory);
        }
        let mut directory = vec![0; size];
        source.seek(SeekFrom::Start(offset))?;
        source.read_exact(&mut directory)?;
        let entries = parse_directory(&directory, count)?;
        Ok(Self {
            source,
            len,
            entries,
        })
    }

    /// The names of the entries, in directory order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.name.as_str())
    }

    /// The uncompressed bytes of entry `name`.
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>, ZipError> {
        let e = find(&self.entries, name)?;
        let truncated = |_| ZipError::TruncatedEntry(name.to_string());
        let mut header = [0u8; 30];
        self.source
            .seek(SeekFrom::Start(e.header))
            .map_err(truncated)?;
        self.source.read_exact(&mut header).map_err(truncated)?;
        let start = e.header + data_offset(&header, name)?;
        // A compressed size past the end of the source is not read (nor
        // made room for).
        if start.saturating_add(e.compressed as u64) > self.len {
            return Err(ZipError::TruncatedEntry(name.to_string()));
        }
        let mut data = vec![0; e.compressed];
        self.source
            .seek(SeekFrom::Start(start))
            .map_err(truncated)?;
        self.source.read_exact(&mut data).map_err(truncated)?;
        decode(e, &data)
    }
}

/// A zip of `entries` (name, bytes), stored without compression, with
/// correct CRCs: what wheels, `.sh3f` catalogues and `torch.save` files look
/// like to [`ZipArchive`] and to other zip readers.
pub fn write_stored(entries: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for (name, data) in entries {
        let offset = out.len() as u32;
        let mut fields = Vec::with_capacity(26);
        fields.extend([20, 0, 0, 0, 0, 0, 0, 0, 0, 0]); // version, flags, stored, time, date
        let mut crc = flate2::Crc::new();
        crc.update(data);
        fields.extend(crc.sum().to_le_bytes());
        fields.extend((data.len() as u32).to_le_bytes());
        fields.extend((data.len() as u32).to_le_bytes());
        fields.extend((name.len() as u16).to_le_bytes());
        fields.extend(0u16.to_le_bytes()); // extra
        out.extend(b"PK\x03\x04");
        out.extend(&fields);
        out.extend(name.as_bytes());
        out.extend(*data);
        central.extend(b"PK\x01\x02");
        central.extend([20, 0]);
        central.extend(&fields);
        central.extend([0; 10]); // comment length, disk, attributes
        central.extend(offset.to_le_bytes());
        central.extend(name.as_bytes());
    }
    let start = out.len() as u32;
    out.extend(&central);
    out.extend(b"PK\x05\x06\0\0\0\0");
    out.extend((entries.len() as u16).to_le_bytes());
    out.extend((entries.len() as u16).to_le_bytes());
    out.extend((central.len() as u32).to_le_bytes());
    out.extend(start.to_le_bytes());
    out.extend([0, 0]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// The offset of the central directory entry of `name` in a zip.
    fn central_entry(zip: &[u8], name: &str) -> usize {
        let start = u32::from_le_bytes(zip[zip.len() - 6..zip.len() - 2].try_into().unwrap());
        let mut at = start as usize;
        loop {
            let len = u16::from_le_bytes([zip[at + 28], zip[at + 29]]) as usize;
            if &zip[at + 46..at + 46 + len] == name.as_bytes() {
                return at;
            }
            at += 46 + len;
        }
    }

    /// Sizes that lie, found by the property tests: a compressed size past
    /// the end of the file (4 GiB were allocated to read it), an inflated
    /// size of 4 GiB (as much was reserved), and an entry count of 65,535
    /// in a directory of none.
    #[test]
    fn sizes_that_lie_are_errors_without_their_allocation() {
        let mut zip = write_stored(&[("", b""), ("0", b"")]);
        let entry = central_entry(&zip, "0");
        zip[entry + 20..entry + 24].copy_from_slice(&u32::MAX.to_le_bytes());
        let mut file = ZipFile::new(Cursor::new(&zip)).unwrap();
        assert!(matches!(file.read("0"), Err(ZipError::TruncatedEntry(_))));
        assert!(ZipArchive::new(&zip).unwrap().read("0").is_err());

        let mut zip = write_stored(&[("a", b"")]);
        let entry = central_entry(&zip, "a");
        zip[entry + 10..entry + 12].copy_from_slice(&8u16.to_le_bytes());
        zip[entry + 24..entry + 28].copy_from_slice(&u32::MAX.to_le_bytes());
        let archive = ZipArchive::new(&zip).unwrap();
        assert!(matches!(archive.read("a"), Err(ZipError::Corrupt { .. })));

        let mut zip = write_stored(&[]);
        let at = zip.len() - 12;
        zip[at..at + 2].copy_from_slice(&u16::MAX.to_le_bytes());
        assert!(matches!(ZipArchive::new(&zip), Err(ZipError::BadDirectory)));
    }
}
