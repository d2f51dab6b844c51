//! Reading the files out of registry packages without installing them:
//! Debian `.deb` (an `ar` archive holding `data.tar.{gz,xz}`), Python wheels
//! and other zips (`.whl`, `.zip`, `.sh3f`), and tarballs (`.tgz`,
//! `.tar.gz`, `.tar.xz`, `.tar`), e.g. npm packages. Archives are read in
//! memory; only the entries a caller wants are kept.

use flate2::read::GzDecoder;
use matseg_weights::zip::ZipArchive;
use std::io::Read;

/// One file taken out of an archive: its path inside and its bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Path inside the archive, without a leading `./`.
    pub path: String,
    /// The file's contents.
    pub bytes: Vec<u8>,
}

/// The regular files of the archive `name` (its format comes from the file
/// name) whose path `want` accepts, in archive order.
pub fn extract(
    name: &str,
    bytes: &[u8],
    want: &dyn Fn(&str) -> bool,
) -> Result<Vec<Entry>, String> {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".deb") {
        let data = deb_member(bytes, "data.tar")?;
        untar(data.0, data.1, want)
    } else if [".whl", ".zip", ".sh3f"].iter().any(|e| lower.ends_with(e)) {
        unzip(bytes, want)
    } else if lower.ends_with(".tgz") || lower.ends_with(".tar.gz") {
        untar(bytes, Compression::Gzip, want)
    } else if lower.ends_with(".tar.xz") {
        untar(bytes, Compression::Xz, want)
    } else if lower.ends_with(".tar") {
        untar(bytes, Compression::None, want)
    } else {
        Err(format!(
            "{name}: not a known archive (.deb, .whl, .zip, .sh3f, .tgz, .tar.gz, .tar.xz, .tar)"
        ))
    }
}

/// How a tar stream is compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Compression {
    None,
    Gzip,
    Xz,
}

/// The member of a `.deb` whose name starts with `prefix`, with the
/// compression its suffix names.
fn deb_member<'a>(bytes: &'a [u8], prefix: &str) -> Result<(&'a [u8], Compression), String> {
    let body = bytes
        .strip_prefix(b"!<arch>\n")
        .ok_or("not a Debian package (no ar signature)")?;
    let mut at = 0;
    while at + 60 <= body.len() {
        let header = &body[at..at + 60];
        let member = String::from_utf8_lossy(&header[..16])
            .trim_end()
            .trim_end_matches('/')
            .to_string();
        let size: usize = String::from_utf8_lossy(&header[48..58])
            .trim()
            .parse()
            .map_err(|_| format!("ar member {member}: bad size field"))?;
        let start = at + 60;
        let data = body
            .get(start..start + size)
            .ok_or_else(|| format!("ar member {member} is truncated"))?;
        if member.starts_with(prefix) {
            let compression = match member.rsplit('.').next() {
                Some("tar") => Compression::None,
                Some("gz") => Compression::Gzip,
                Some("xz") => Compression::Xz,
                _ => {
                    return Err(format!(
                        "{member}: unsupported compression (gz, xz or none)"
                    ))
                }
            };
            return Ok((data, compression));
        }
        at = start + size + size % 2;
    }
    Err(format!("no {prefix}.* member"))
}

fn untar(
    bytes: &[u8],
    compression: Compression,
    want: &dyn Fn(&str) -> bool,
) -> Result<Vec<Entry>, String> {
    let plain: Vec<u8>;
    let tar_bytes: &[u8] = match compression {
        Compression::None => bytes,
        Compression::Gzip => {
            let mut out = Vec::new();
            GzDecoder::new(bytes)
                .read_to_end(&mut out)
                .map_err(|e| format!("gzip: {e}"))?;
            plain = out;
            &plain
        }
        Compression::Xz => {
            let mut out = Vec::new();
            lzma_rs::xz_decompress(&mut std::io::BufReader::new(bytes), &mut out)
                .map_err(|e| format!("xz: {e}"))?;
            plain = out;
            &plain
        }
    };
    let mut archive = tar::Archive::new(tar_bytes);
    let mut entries = Vec::new();
    for entry in archive.entries().map_err(|e| format!("tar: {e}"))? {
        let mut entry = entry.map_err(|e| format!("tar: {e}"))?;
        if !entry.header().entry_type().is_file() {
            continue;
        }
        let path = entry
            .path()
            .map_err(|e| format!("tar: {e}"))?
            .to_string_lossy()
            .into_owned();
        let path = path.trim_start_matches("./").to_string();
        if !want(&path) {
            continue;
        }
        let mut data = Vec::with_capacity(entry.size() as usize);
        entry
            .read_to_end(&mut data)
            .map_err(|e| format!("tar: {path}: {e}"))?;
        entries.push(Entry { path, bytes: data });
    }
    Ok(entries)
}

fn unzip(bytes: &[u8], want: &dyn Fn(&str) -> bool) -> Result<Vec<Entry>, String> {
    let archive = ZipArchive::new(bytes)?;
    let names: Vec<String> = archive
        .names()
        .filter(|n| !n.ends_with('/') && want(n))
        .map(String::from)
        .collect();
    names
        .into_iter()
        .map(|path| archive.read(&path).map(|bytes| Entry { path, bytes }))
        .collect()
}

/// Archives of the supported formats built in memory (a `.deb` with
/// gzipped members, tarballs, stored zips), for tests across the workspace:
/// the reader is only trusted on files it did not write.
pub mod fixtures {
    use flate2::write::GzEncoder;
    use std::io::Write;

    /// A tar of `files` (path, bytes).
    pub fn tar(files: &[(&str, &[u8])]) -> Vec<u8> {
        let mut builder = tar::Builder::new(Vec::new());
        for (path, bytes) in files {
            let mut header = tar::Header::new_gnu();
            header.set_size(bytes.len() as u64);
            header.set_mode(0o644);
            header.set_cksum();
            builder.append_data(&mut header, path, *bytes).unwrap();
        }
        builder.into_inner().unwrap()
    }

    /// Gzip of `bytes`.
    pub fn gzip(bytes: &[u8]) -> Vec<u8> {
        let mut e = GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    }

    /// A `.deb`: `debian-binary`, `control.tar.gz` and `data.tar.gz` of `files`.
    pub fn deb(files: &[(&str, &[u8])]) -> Vec<u8> {
        let members: [(&str, Vec<u8>); 3] = [
            ("debian-binary", b"2.0\n".to_vec()),
            (
                "control.tar.gz",
                gzip(&tar(&[("./control", b"Package: x\n")])),
            ),
            ("data.tar.gz", gzip(&tar(files))),
        ];
        let mut out = b"!<arch>\n".to_vec();
        for (name, data) in members {
            out.extend(
                format!(
                    "{name:<16}{:<12}{:<6}{:<6}{:<8}{:<10}`\n",
                    0,
                    0,
                    0,
                    100644,
                    data.len()
                )
                .bytes(),
            );
            out.extend(&data);
            if data.len() % 2 == 1 {
                out.push(b'\n');
            }
        }
        out
    }

    /// A zip of `files`, stored (no compression).
    pub fn zip(files: &[(&str, &[u8])]) -> Vec<u8> {
        matseg_weights::zip::write_stored(files)
    }
}

#[cfg(test)]
mod tests {
    use super::fixtures::*;
    use super::*;

    const FILES: [(&str, &[u8]); 3] = [
        ("./usr/share/a.jpg", b"one"),
        ("./usr/share/doc/x/copyright", b"two"),
        ("./usr/bin/tool", b"three"),
    ];

    fn under_share(p: &str) -> bool {
        p.starts_with("usr/share/")
    }

    #[test]
    fn every_format_gives_the_wanted_files() {
        let expected = vec![
            Entry {
                path: "usr/share/a.jpg".into(),
                bytes: b"one".to_vec(),
            },
            Entry {
                path: "usr/share/doc/x/copyright".into(),
                bytes: b"two".to_vec(),
            },
        ];
        let tar_bytes = tar(&FILES);
        assert_eq!(
            extract("p.deb", &deb(&FILES), &under_share).unwrap(),
            expected
        );
        assert_eq!(
            extract("p.tgz", &gzip(&tar_bytes), &under_share).unwrap(),
            expected
        );
        assert_eq!(
            extract("p.tar", &tar_bytes, &under_share).unwrap(),
            expected
        );
        let zipped = zip(&[
            ("usr/share/a.jpg", b"one"),
            ("usr/share/doc/x/copyright", b"two"),
            ("usr/bin/tool", b"x"),
        ]);
        assert_eq!(extract("p.whl", &zipped, &under_share).unwrap(), expected);
    }

    #[test]
    fn xz_tarballs_read_like_gzip_ones() {
        let mut xz = Vec::new();
        lzma_rs::xz_compress(&mut std::io::Cursor::new(tar(&FILES)), &mut xz).unwrap();
        let got = extract("p.tar.xz", &xz, &under_share).unwrap();
        assert_eq!(
            got,
            extract("p.tgz", &gzip(&tar(&FILES)), &under_share).unwrap()
        );
        assert_eq!(got.len(), 2);
    }

    #[test]
    fn broken_archives_are_named_errors() {
        let e = extract("p.deb", b"not an archive", &|_| true).unwrap_err();
        assert!(e.contains("not a Debian package"), "{e}");
        let mut truncated = deb(&FILES);
        truncated.truncate(truncated.len() - 10);
        let e = extract("p.deb", &truncated, &|_| true).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
        let e = extract("p.tgz", b"\x1f\x8b garbage", &|_| true).unwrap_err();
        assert!(e.contains("gzip"), "{e}");
        let e = extract("p.rar", b"", &|_| true).unwrap_err();
        assert!(e.contains("not a known archive"), "{e}");
    }
}
