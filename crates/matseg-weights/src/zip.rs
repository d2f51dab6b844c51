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

/// A zip archive held in memory.
pub struct ZipArchive<'a> {
    bytes: &'a [u8],
    entries: Vec<Entry>,
}

fn u16_at(b: &[u8], at: usize) -> Result<u16, String> {
    b.get(at..at + 2)
        .map(|s| u16::from_le_bytes(s.try_into().expect("2 bytes")))
        .ok_or_else(|| "zip: truncated".to_string())
}

fn u32_at(b: &[u8], at: usize) -> Result<u32, String> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes(s.try_into().expect("4 bytes")))
        .ok_or_else(|| "zip: truncated".to_string())
}

/// The longest tail of a zip that can hold its end-of-central-directory
/// record (22 bytes and a comment of at most 65,535).
const MAX_END_RECORD: usize = 22 + 65_535;

/// Where the central directory is, from the end-of-central-directory record
/// found in `tail` (the last bytes of the archive): entry count, size and
/// offset.
fn directory_location(tail: &[u8]) -> Result<(usize, usize, u64), String> {
    let end = (0..tail.len().saturating_sub(21))
        .rev()
        .find(|&i| tail[i..].starts_with(b"PK\x05\x06"))
        .ok_or("zip: no end of central directory")?;
    Ok((
        u16_at(tail, end + 10)? as usize,
        u32_at(tail, end + 12)? as usize,
        u64::from(u32_at(tail, end + 16)?),
    ))
}

/// The `count` entries of the central directory `bytes`.
fn parse_directory(bytes: &[u8], count: usize) -> Result<Vec<Entry>, String> {
    let mut at = 0;
    let mut entries = Vec::with_capacity(count);
    for _ in 0..count {
        if !bytes
            .get(at..)
            .is_some_and(|b| b.starts_with(b"PK\x01\x02"))
        {
            return Err("zip: bad central directory entry".into());
        }
        let name_len = u16_at(bytes, at + 28)? as usize;
        let name = bytes
            .get(at + 46..at + 46 + name_len)
            .ok_or("zip: truncated name")?;
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
fn data_offset(local_header: &[u8], name: &str) -> Result<u64, String> {
    if !local_header.starts_with(b"PK\x03\x04") {
        return Err(format!("zip: bad local header for {name}"));
    }
    Ok(30 + u64::from(u16_at(local_header, 26)?) + u64::from(u16_at(local_header, 28)?))
}

/// The uncompressed bytes of entry `e` from its stored data.
fn decode(e: &Entry, data: &[u8]) -> Result<Vec<u8>, String> {
    let name = &e.name;
    match e.method {
        0 => Ok(data.to_vec()),
        8 => {
            let mut out = Vec::with_capacity(e.size);
            DeflateDecoder::new(data)
                .read_to_end(&mut out)
                .map_err(|err| format!("zip: {name}: {err}"))?;
            if out.len() != e.size {
                return Err(format!("zip: {name}: size mismatch"));
            }
            Ok(out)
        }
        m => Err(format!("zip: {name}: unsupported compression method {m}")),
    }
}

fn find<'e>(entries: &'e [Entry], name: &str) -> Result<&'e Entry, String> {
    entries
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| format!("zip: no entry {name}"))
}

impl<'a> ZipArchive<'a> {
    /// Reads the central directory of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Result<Self, String> {
        let (count, size, offset) = directory_location(bytes)?;
        let start = offset as usize;
        let directory = bytes
            .get(start..start.saturating_add(size).min(bytes.len()))
            .ok_or("zip: bad central directory entry")?;
        let entries = parse_directory(directory, count)?;
        Ok(Self { bytes, entries })
    }

    /// The names of the entries, in directory order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.name.as_str())
    }

    /// The uncompressed bytes of entry `name`.
    pub fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        let e = find(&self.entries, name)?;
        let h = e.header as usize;
        let header = self.bytes.get(h..).unwrap_or_default();
        let start = h + data_offset(header, name)? as usize;
        let data = self
            .bytes
            .get(start..start + e.compressed)
            .ok_or_else(|| format!("zip: {name} is truncated"))?;
        decode(e, data)
    }
}

/// A zip archive read from a seekable source (a file): the central
/// directory is read once, each entry when asked for.
pub struct ZipFile<R> {
    source: R,
    entries: Vec<Entry>,
}

impl<R: Read + Seek> ZipFile<R> {
    /// Reads the central directory of `source`.
    pub fn new(mut source: R) -> Result<Self, String> {
        let io = |e: std::io::Error| format!("zip: {e}");
        let len = source.seek(SeekFrom::End(0)).map_err(io)?;
        let tail_len = len.min(MAX_END_RECORD as u64);
        let mut tail = vec![0; tail_len as usize];
        source.seek(SeekFrom::Start(len - tail_len)).map_err(io)?;
        source.read_exact(&mut tail).map_err(io)?;
        let (count, size, offset) = directory_location(&tail)?;
        if offset + size as u64 > len {
            return Err("zip: bad central directory entry".into());
        }
        let mut directory = vec![0; size];
        source.seek(SeekFrom::Start(offset)).map_err(io)?;
        source.read_exact(&mut directory).map_err(io)?;
        let entries = parse_directory(&directory, count)?;
        Ok(Self { source, entries })
    }

    /// The names of the entries, in directory order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.name.as_str())
    }

    /// The uncompressed bytes of entry `name`.
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>, String> {
        let e = find(&self.entries, name)?;
        let truncated = |_| format!("zip: {name} is truncated");
        let mut header = [0u8; 30];
        self.source
            .seek(SeekFrom::Start(e.header))
            .map_err(truncated)?;
        self.source.read_exact(&mut header).map_err(truncated)?;
        let start = e.header + data_offset(&header, name)?;
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
