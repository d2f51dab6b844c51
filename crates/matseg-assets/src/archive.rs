//! Reading the files out of registry packages without installing them:
//! Debian `.deb` (an `ar` archive holding `data.tar.{gz,xz}`), Python wheels
//! and other zips (`.whl`, `.zip`, `.sh3f`), and tarballs (`.tgz`,
//! `.tar.gz`, `.tar.xz`, `.tar`), e.g. npm packages. Archives are streamed
//! from any seekable source (a file, or bytes in memory): a package of
//! gigabytes needs no more memory than the entries a caller keeps.

use crate::error::AssetError;
use flate2::read::GzDecoder;
use matseg_weights::zip::ZipFile;
use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};

/// One file taken out of an archive: its path inside and its bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Path inside the archive, without a leading `./`.
    pub path: String,
    /// The file's contents.
    pub bytes: Vec<u8>,
}

/// What [`visit`] calls with each wanted file: its path inside the archive
/// and a reader of its contents.
pub type OnEntry<'a> = dyn FnMut(&str, &mut dyn Read) -> Result<(), AssetError> + 'a;

/// The regular files of the archive `name` (its format comes from the file
/// name) held in `bytes` whose path `want` accepts, in archive order.
pub fn extract(
    name: &str,
    bytes: &[u8],
    want: &dyn Fn(&str) -> bool,
) -> Result<Vec<Entry>, AssetError> {
    extract_from(name, Cursor::new(bytes), want)
}

/// [`extract`] from any seekable source (a file).
pub fn extract_from<R: Read + Seek + Send>(
    name: &str,
    source: R,
    want: &dyn Fn(&str) -> bool,
) -> Result<Vec<Entry>, AssetError> {
    let mut entries = Vec::new();
    visit(name, source, want, &mut |path, reader| {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .map_err(|e| AssetError::Archive(format!("{path}: {e}")))?;
        entries.push(Entry {
            path: path.to_string(),
            bytes,
        });
        Ok(())
    })?;
    Ok(entries)
}

/// Calls `on_entry` with each regular file of the archive `name` (its
/// format comes from the file name), read from `source`, whose path `want`
/// accepts, in archive order. Compressed tar streams are decompressed as
/// they are read (xz on a second thread).
pub fn visit<R: Read + Seek + Send>(
    name: &str,
    mut source: R,
    want: &dyn Fn(&str) -> bool,
    on_entry: &mut OnEntry<'_>,
) -> Result<(), AssetError> {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".deb") {
        let (size, compression) = deb_member(&mut source, "data.tar")?;
        untar(source.take(size), compression, want, on_entry)
    } else if [".whl", ".zip", ".sh3f"].iter().any(|e| lower.ends_with(e)) {
        unzip(source, want, on_entry)
    } else if lower.ends_with(".tgz") || lower.ends_with(".tar.gz") {
        untar(source, Compression::Gzip, want, on_entry)
    } else if lower.ends_with(".tar.xz") {
        untar(source, Compression::Xz, want, on_entry)
    } else if lower.ends_with(".tar") {
        untar(source, Compression::None, want, on_entry)
    } else {
        Err(AssetError::Archive(format!(
            "{name}: not a known archive (.deb, .whl, .zip, .sh3f, .tgz, .tar.gz, .tar.xz, .tar)"
        )))
    }
}

/// How a tar stream is compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Compression {
    None,
    Gzip,
    Xz,
}

/// Moves `source` (a `.deb`) to the start of its member whose name starts
/// with `prefix`; that member's size and the compression its suffix names.
fn deb_member<R: Read + Seek>(
    source: &mut R,
    prefix: &str,
) -> Result<(u64, Compression), AssetError> {
    let archive = AssetError::Archive;
    let io = |e: std::io::Error| archive(format!("cannot read: {e}"));
    let len = source.seek(SeekFrom::End(0)).map_err(io)?;
    source.seek(SeekFrom::Start(0)).map_err(io)?;
    let mut magic = [0u8; 8];
    if source.read_exact(&mut magic).is_err() || &magic != b"!<arch>\n" {
        return Err(archive("not a Debian package (no ar signature)".into()));
    }
    let mut at = 8u64;
    while at + 60 <= len {
        let mut header = [0u8; 60];
        source.read_exact(&mut header).map_err(io)?;
        let member = String::from_utf8_lossy(&header[..16])
            .trim_end()
            .trim_end_matches('/')
            .to_string();
        let size: u64 = String::from_utf8_lossy(&header[48..58])
            .trim()
            .parse()
            .map_err(|_| archive(format!("ar member {member}: bad size field")))?;
        let start = at + 60;
        if start + size > len {
            return Err(archive(format!("ar member {member} is truncated")));
        }
        if member.starts_with(prefix) {
            let compression = match member.rsplit('.').next() {
                Some("tar") => Compression::None,
                Some("gz") => Compression::Gzip,
                Some("xz") => Compression::Xz,
                _ => {
                    return Err(archive(format!(
                        "{member}: unsupported compression (gz, xz or none)"
                    )))
                }
            };
            return Ok((size, compression));
        }
        at = start + size + size % 2;
        source.seek(SeekFrom::Start(at)).map_err(io)?;
    }
    Err(archive(format!("no {prefix}.* member")))
}

/// The wanted files of a tar stream compressed with `compression`.
fn untar<R: Read + Send>(
    source: R,
    compression: Compression,
    want: &dyn Fn(&str) -> bool,
    on_entry: &mut OnEntry<'_>,
) -> Result<(), AssetError> {
    let xz = |e: String| AssetError::Archive(format!("xz: {e}"));
    match compression {
        Compression::None => read_tar(source, "tar", want, on_entry),
        Compression::Gzip => read_tar(GzDecoder::new(source), "gzip", want, on_entry),
        Compression::Xz => std::thread::scope(|scope| {
            let (plain, mut sink) = std::io::pipe().map_err(|e| xz(e.to_string()))?;
            let decompress = scope.spawn(move || {
                lzma_rs::xz_decompress(&mut BufReader::with_capacity(1 << 20, source), &mut sink)
            });
            let read = read_tar(plain, "xz", want, on_entry);
            match decompress.join().expect("the xz thread does not panic") {
                // The reader closed the pipe: it stopped at the end-of-archive
                // blocks (padding left unread) or on an error of its own,
                // which is the one to report.
                Err(lzma_rs::error::Error::IoError(e))
                    if e.kind() == std::io::ErrorKind::BrokenPipe =>
                {
                    read
                }
                Err(e) => Err(xz(e.to_string())),
                Ok(()) => read,
            }
        }),
    }
}

/// The wanted files of the plain tar stream `reader`; `format` names the
/// outer format in errors.
fn read_tar(
    reader: impl Read,
    format: &str,
    want: &dyn Fn(&str) -> bool,
    on_entry: &mut OnEntry<'_>,
) -> Result<(), AssetError> {
    let mut archive = tar::Archive::new(reader);
    let error = |e: std::io::Error| AssetError::Archive(format!("{format}: {e}"));
    for entry in archive.entries().map_err(error)? {
        let mut entry = entry.map_err(error)?;
        if !entry.header().entry_type().is_file() {
            continue;
        }
        let path = entry.path().map_err(error)?.to_string_lossy().into_owned();
        let path = path.trim_start_matches("./").to_string();
        if want(&path) {
            on_entry(&path, &mut entry)?;
        }
    }
    Ok(())
}

fn unzip<R: Read + Seek>(
    source: R,
    want: &dyn Fn(&str) -> bool,
    on_entry: &mut OnEntry<'_>,
) -> Result<(), AssetError> {
    let mut archive = ZipFile::new(source)?;
    let names: Vec<String> = archive
        .names()
        .filter(|n| !n.ends_with('/') && want(n))
        .map(String::from)
        .collect();
    for name in names {
        let bytes = archive.read(&name)?;
        on_entry(&name, &mut bytes.as_slice())?;
    }
    Ok(())
}

/// Archives of the supported formats built in memory (a `.deb` with
/// gzipped members, tarballs, stored zips), for tests across the workspace:
/// the reader is only trusted on files it did not write.
#[cfg(any(test, feature = "fixtures"))]
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

    /// Xz of `bytes`.
    pub fn xz(bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        lzma_rs::xz_compress(&mut std::io::Cursor::new(bytes), &mut out).unwrap();
        out
    }

    /// A `.deb`: `debian-binary`, `control.tar.gz` and `data.tar.gz` of `files`.
    pub fn deb(files: &[(&str, &[u8])]) -> Vec<u8> {
        deb_with("data.tar.gz", gzip(&tar(files)))
    }

    /// A `.deb` whose data member is `data.tar.xz`, as Debian's large
    /// packages are.
    pub fn deb_xz(files: &[(&str, &[u8])]) -> Vec<u8> {
        deb_with("data.tar.xz", xz(&tar(files)))
    }

    fn deb_with(data_name: &str, data: Vec<u8>) -> Vec<u8> {
        let members: [(&str, Vec<u8>); 3] = [
            ("debian-binary", b"2.0\n".to_vec()),
            (
                "control.tar.gz",
                gzip(&tar(&[("./control", b"Package: x\n")])),
            ),
            (data_name, data),
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
        let got = extract("p.tar.xz", &xz(&tar(&FILES)), &under_share).unwrap();
        assert_eq!(
            got,
            extract("p.tgz", &gzip(&tar(&FILES)), &under_share).unwrap()
        );
        assert_eq!(got.len(), 2);
        assert_eq!(
            extract("p.deb", &deb_xz(&FILES), &under_share).unwrap(),
            got
        );
        // The reader may stop before the decompressor is done (an error in
        // the consumer): the error is the consumer's, and nothing hangs.
        let mut calls = 0;
        let e = visit(
            "p.deb",
            Cursor::new(deb_xz(&FILES)),
            &|_| true,
            &mut |path, _| {
                calls += 1;
                Err(AssetError::Content(format!("{path}: refused")))
            },
        )
        .unwrap_err();
        assert_eq!(
            (calls, e.to_string()),
            (1, "usr/share/a.jpg: refused".into())
        );
        // So with an archive larger than the pipe's buffer, whose decompressor
        // then finds the pipe closed.
        let big = vec![7u8; 1 << 20];
        let files: Vec<(&str, &[u8])> = vec![("a.bin", &big), ("b.bin", &big)];
        let e = visit(
            "p.deb",
            Cursor::new(deb_xz(&files)),
            &|_| true,
            &mut |path, _| Err(AssetError::Content(format!("{path}: refused"))),
        )
        .unwrap_err();
        assert_eq!(e.to_string(), "a.bin: refused");
        let whole = xz(&tar(&FILES));
        let e = extract("p.tar.xz", &whole[..whole.len() / 2], &under_share)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("xz: "), "{e}");
    }

    #[test]
    fn archives_on_disk_stream_like_archives_in_memory() {
        let dir = tempfile::tempdir().unwrap();
        let zipped = zip(&[("a/b.png", b"one"), ("a/c.txt", b"two"), ("d/", b"")]);
        for (name, bytes) in [("p.zip", zipped), ("p.deb", deb_xz(&FILES))] {
            let path = dir.path().join(name);
            std::fs::write(&path, &bytes).unwrap();
            let mut from_file = Vec::new();
            let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
            visit(name, file, &|_| true, &mut |p, r| {
                let mut b = Vec::new();
                r.read_to_end(&mut b).unwrap();
                from_file.push(Entry {
                    path: p.into(),
                    bytes: b,
                });
                Ok(())
            })
            .unwrap();
            assert_eq!(
                from_file,
                extract(name, &bytes, &|_| true).unwrap(),
                "{name}"
            );
            assert!(!from_file.is_empty());
        }
    }

    #[test]
    fn broken_archives_are_named_errors() {
        let e = extract("p.deb", b"not an archive", &|_| true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a Debian package"), "{e}");
        let mut truncated = deb(&FILES);
        truncated.truncate(truncated.len() - 10);
        let e = extract("p.deb", &truncated, &|_| true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        let e = extract("p.tgz", b"\x1f\x8b garbage", &|_| true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("gzip"), "{e}");
        let e = extract("p.rar", b"", &|_| true).unwrap_err().to_string();
        assert!(e.contains("not a known archive"), "{e}");
    }
}
