//! The folders the server may read from, and the one way a request's path
//! becomes a file: relative to a named root, with no `..`, no absolute
//! part, no percent-encoded escape and no symlink that leaves the root.
//! A request's *name* (an image of a benchmark, an upload) is one plain
//! file name ([`plain_name`]), and a file made from it is checked to lie
//! under its folder once symlinks are followed ([`inside`]).

use std::path::{Component, Path, PathBuf};

/// Why a requested path is refused.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum PathError {
    /// No root of that name.
    #[error("no folder named {0:?}")]
    UnknownRoot(String),
    /// The path steps out of its root, or is absolute.
    #[error("{0:?}: outside the served folders")]
    Outside(String),
    /// Nothing there.
    #[error("{0:?}: no such file")]
    Missing(String),
}

/// Named folders (`photos`: the bundled photos, `data0`, `data1`...: the
/// folders given to `matseg serve --data`).
#[derive(Clone, Debug, Default)]
pub struct Roots {
    roots: Vec<(String, PathBuf)>,
}

impl Roots {
    /// Adds `dir` under `name` (canonicalised, so symlinks inside it are
    /// judged against where it really is); the folder as it is kept, the
    /// one form of its path the server uses from then on.
    pub fn add(&mut self, name: &str, dir: &Path) -> std::io::Result<PathBuf> {
        let dir = dir.canonicalize()?;
        self.roots.push((name.to_string(), dir.clone()));
        Ok(dir)
    }

    /// The roots, by name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &Path)> {
        self.roots.iter().map(|(n, p)| (n.as_str(), p.as_path()))
    }

    /// The file `path` (as the request gave it, percent-encoded or not)
    /// names under the root `root`.
    pub fn resolve(&self, root: &str, path: &str) -> Result<PathBuf, PathError> {
        let (_, base) = self
            .roots
            .iter()
            .find(|(n, _)| n == root)
            .ok_or_else(|| PathError::UnknownRoot(root.to_string()))?;
        let outside = || PathError::Outside(path.to_string());
        let decoded = percent_decode(path).ok_or_else(outside)?;
        let relative = Path::new(&decoded);
        if decoded.contains('\0')
            || relative
                .components()
                .any(|c| !matches!(c, Component::Normal(_)))
        {
            return Err(outside());
        }
        let file = base
            .join(relative)
            .canonicalize()
            .map_err(|_| PathError::Missing(path.to_string()))?;
        if !file.starts_with(base) {
            return Err(outside());
        }
        if !file.is_file() {
            return Err(PathError::Missing(path.to_string()));
        }
        Ok(file)
    }
}

/// `name` when it is one plain file name: not empty, no `/` or `\`, not
/// `.` or `..`, no NUL or other control character. Anything else would
/// name a file elsewhere when joined onto a folder, and is refused as
/// outside the served folders.
pub fn plain_name(name: &str) -> Result<&str, PathError> {
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && !name
            .chars()
            .any(|c| matches!(c, '/' | '\\') || c.is_control());
    if plain {
        Ok(name)
    } else {
        Err(PathError::Outside(name.to_string()))
    }
}

/// `path` when it lies under the folder `base` (canonical) once every
/// symlink of the part of it that exists is followed; `shown` names it in
/// the error. The part that does not exist yet (a folder about to be
/// made) must be plain names.
pub fn inside(base: &Path, path: &Path, shown: &str) -> Result<PathBuf, PathError> {
    let outside = || PathError::Outside(shown.to_string());
    let mut existing = path;
    let mut rest = Vec::new();
    // Entries that exist, dangling symlinks included, are followed.
    while existing.symlink_metadata().is_err() {
        let (Some(parent), Some(last)) = (existing.parent(), existing.file_name()) else {
            return Err(outside());
        };
        rest.push(last);
        existing = parent;
    }
    let mut resolved = existing.canonicalize().map_err(|_| outside())?;
    for part in rest.into_iter().rev() {
        resolved.push(part);
    }
    let plain = resolved
        .strip_prefix(base)
        .is_ok_and(|r| r.components().all(|c| matches!(c, Component::Normal(_))));
    if plain {
        Ok(resolved)
    } else {
        Err(outside())
    }
}

/// The files with one of `extensions` under `roots` (name and folder),
/// each as its root's name and its path inside: the photo and video lists,
/// made once when the server starts.
pub fn files_under<'a>(
    roots: impl Iterator<Item = (&'a str, &'a Path)>,
    extensions: &[&str],
) -> Result<Vec<(String, PathBuf)>, matseg_image::LibraryError> {
    let mut files = Vec::new();
    for (name, dir) in roots {
        for file in matseg_image::io::find_files(&[dir.to_path_buf()], extensions)? {
            let path = file.strip_prefix(dir).unwrap_or(&file).to_path_buf();
            files.push((name.to_string(), path));
        }
    }
    Ok(files)
}

/// `text` with `%XX` escapes decoded; `None` when an escape is malformed or
/// the result is not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roots() -> (tempfile::TempDir, Roots) {
        let dir = tempfile::tempdir().unwrap();
        let served = dir.path().join("served");
        std::fs::create_dir_all(served.join("sub")).unwrap();
        std::fs::write(served.join("sub/a.jpg"), b"a").unwrap();
        std::fs::write(dir.path().join("secret.txt"), b"s").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(dir.path().join("secret.txt"), served.join("link.txt")).unwrap();
        let mut roots = Roots::default();
        roots.add("photos", &served).unwrap();
        (dir, roots)
    }

    #[test]
    fn files_inside_a_root_resolve() {
        let (_dir, roots) = roots();
        let file = roots.resolve("photos", "sub/a.jpg").unwrap();
        assert!(file.ends_with("served/sub/a.jpg"));
        assert_eq!(roots.resolve("photos", "sub%2Fa.jpg").unwrap(), file);
    }

    #[test]
    fn names_are_plain_file_names() {
        for name in ["coffee", "a b.c", ".hidden", "..a", "é"] {
            assert_eq!(plain_name(name), Ok(name), "{name}");
        }
        for name in ["", ".", "..", "a/b", "../a", "a\\b", "/etc", "a\0b", "a\nb"] {
            assert_eq!(
                plain_name(name),
                Err(PathError::Outside(name.to_string())),
                "{name:?}"
            );
        }
    }

    #[test]
    fn made_paths_must_stay_under_their_folder() {
        let (dir, roots) = roots();
        let base = roots.resolve("photos", "sub/a.jpg").unwrap();
        let base = base.parent().unwrap().parent().unwrap();
        // Not there yet: judged by the part that is.
        let made = inside(base, &base.join("data/new/data.json"), "new").unwrap();
        assert_eq!(made, base.join("data/new/data.json"));
        assert_eq!(
            inside(base, &base.join("sub/a.jpg"), "a").unwrap(),
            base.join("sub/a.jpg")
        );
        let outside = |p: &Path| inside(base, p, "x");
        assert_eq!(
            outside(&base.join("../secret.txt")),
            Err(PathError::Outside("x".into()))
        );
        assert!(outside(&dir.path().join("elsewhere/new")).is_err());
        #[cfg(unix)]
        {
            // A symlink out of the folder, to a folder or a file, or dangling.
            std::os::unix::fs::symlink(dir.path(), base.join("out")).unwrap();
            std::os::unix::fs::symlink(dir.path().join("none"), base.join("dangling")).unwrap();
            for path in [
                "out/new/data.json",
                "out",
                "link.txt",
                "dangling/new",
                "dangling",
            ] {
                assert!(outside(&base.join(path)).is_err(), "{path}");
            }
        }
    }

    #[test]
    fn escapes_are_refused() {
        let (dir, roots) = roots();
        let outside = |p: &str| PathError::Outside(p.to_string());
        for path in [
            "../secret.txt",
            "sub/../../secret.txt",
            "%2e%2e/secret.txt",
            "%2E%2E%2Fsecret.txt",
            "%zz",
        ] {
            assert_eq!(roots.resolve("photos", path), Err(outside(path)), "{path}");
        }
        let absolute = dir.path().join("secret.txt").display().to_string();
        assert_eq!(roots.resolve("photos", &absolute), Err(outside(&absolute)));
        #[cfg(unix)]
        assert_eq!(
            roots.resolve("photos", "link.txt"),
            Err(outside("link.txt"))
        );
        assert_eq!(
            roots.resolve("data0", "a.jpg"),
            Err(PathError::UnknownRoot("data0".into()))
        );
        assert_eq!(
            roots.resolve("photos", "sub/none.jpg"),
            Err(PathError::Missing("sub/none.jpg".into()))
        );
        assert_eq!(
            roots.resolve("photos", "sub"),
            Err(PathError::Missing("sub".into()))
        );
    }
}
