//! A minimal zip reader: the central directory, and entries stored or
//! deflated. Enough for PyTorch's zip checkpoints and Python wheels.

use flate2::read::DeflateDecoder;
use std::io::Read;

/// One entry: name, compression method, sizes and where its header is.
struct Entry {
    name: String,
    method: u16,
    compressed: usize,
    size: usize,
    header: usize,
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

impl<'a> ZipArchive<'a> {
    /// Reads the central directory of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Result<Self, String> {
        // The end-of-central-directory record: its signature, searched from the end.
        let end = (0..bytes.len().saturating_sub(21))
            .rev()
            .find(|&i| bytes[i..].starts_with(b"PK\x05\x06"))
            .ok_or("zip: no end of central directory")?;
        let count = u16_at(bytes, end + 10)? as usize;
        let mut at = u32_at(bytes, end + 16)? as usize;
        let mut entries = Vec::with_capacity(count);
        for _ in 0..count {
            if !bytes
                .get(at..)
                .is_some_and(|b| b.starts_with(b"PK\x01\x02"))
            {
                return Err("zip: bad central directory entry".into());
            }
            let method = u16_at(bytes, at + 10)?;
            let compressed = u32_at(bytes, at + 20)? as usize;
            let size = u32_at(bytes, at + 24)? as usize;
            let name_len = u16_at(bytes, at + 28)? as usize;
            let extra_len = u16_at(bytes, at + 30)? as usize;
            let comment_len = u16_at(bytes, at + 32)? as usize;
            let header = u32_at(bytes, at + 42)? as usize;
            let name = bytes
                .get(at + 46..at + 46 + name_len)
                .ok_or("zip: truncated name")?;
            entries.push(Entry {
                name: String::from_utf8_lossy(name).into_owned(),
                method,
                compressed,
                size,
                header,
            });
            at += 46 + name_len + extra_len + comment_len;
        }
        Ok(Self { bytes, entries })
    }

    /// The names of the entries, in directory order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|e| e.name.as_str())
    }

    /// The uncompressed bytes of entry `name`.
    pub fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        let e = self
            .entries
            .iter()
            .find(|e| e.name == name)
            .ok_or_else(|| format!("zip: no entry {name}"))?;
        let h = e.header;
        if !self
            .bytes
            .get(h..)
            .is_some_and(|b| b.starts_with(b"PK\x03\x04"))
        {
            return Err(format!("zip: bad local header for {name}"));
        }
        let start =
            h + 30 + u16_at(self.bytes, h + 26)? as usize + u16_at(self.bytes, h + 28)? as usize;
        let data = self
            .bytes
            .get(start..start + e.compressed)
            .ok_or_else(|| format!("zip: {name} is truncated"))?;
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
