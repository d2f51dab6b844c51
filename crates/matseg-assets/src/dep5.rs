//! Debian's machine-readable copyright files (DEP-5): which licence each
//! file of a package is under.
//!
//! The `Files:` patterns name paths in the *source* tree, while a binary
//! package installs them elsewhere (`16.04/x.jpg` lands in
//! `usr/share/backgrounds/x.jpg`). A pattern therefore applies to an
//! installed path when it matches a whole trailing part of it (`nature/*.jpg`
//! matches `usr/share/backgrounds/mate/nature/Dune.jpg`), or when its last
//! component has no wildcard and equals the file's name. As in DEP-5, `*`
//! and `?` match slashes too (`data/trak/*` covers `data/trak/trak5/x.jpg`),
//! and the last stanza that applies wins.

use crate::glob::glob_match_across;

/// One `Files:` stanza: its patterns and its licence's short name.
#[derive(Clone, Debug, PartialEq)]
struct Stanza {
    patterns: Vec<String>,
    licence: String,
}

/// A parsed copyright file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Copyright {
    stanzas: Vec<Stanza>,
}

impl Copyright {
    /// Parses the `Files:`/`License:` stanzas; `None` when the file is not
    /// in the machine-readable format (old free-text copyright files).
    pub fn parse(text: &str) -> Option<Self> {
        if !text.starts_with("Format:") {
            return None;
        }
        let mut stanzas = Vec::new();
        for paragraph in text.split("\n\n") {
            let mut files: Option<Vec<String>> = None;
            let mut licence = None;
            let mut in_files = false;
            for line in paragraph.lines() {
                if let Some(rest) = line.strip_prefix("Files:") {
                    files = Some(rest.split_whitespace().map(String::from).collect());
                    in_files = true;
                } else if line.starts_with([' ', '\t']) && in_files {
                    if let Some(f) = files.as_mut() {
                        f.extend(line.split_whitespace().map(String::from));
                    }
                } else {
                    in_files = false;
                    if let Some(rest) = line.strip_prefix("License:") {
                        licence = Some(rest.trim().to_string());
                    }
                }
            }
            if let (Some(patterns), Some(licence)) = (files, licence) {
                stanzas.push(Stanza { patterns, licence });
            }
        }
        Some(Self { stanzas })
    }

    /// The licence of the installed file `path` (see the module doc), or
    /// `None` when no stanza applies.
    pub fn licence_of(&self, path: &str) -> Option<&str> {
        let file_name = path.rsplit('/').next().unwrap_or(path);
        self.stanzas
            .iter()
            .rev()
            .find(|s| s.patterns.iter().any(|p| applies(p, path, file_name)))
            .map(|s| s.licence.as_str())
    }
}

fn applies(pattern: &str, path: &str, file_name: &str) -> bool {
    let suffix_match = std::iter::once(path)
        .chain(path.match_indices('/').map(|(i, _)| &path[i + 1..]))
        .any(|tail| glob_match_across(pattern, tail));
    let last = pattern.rsplit('/').next().unwrap_or(pattern);
    suffix_match || (!last.contains(['*', '?']) && last == file_name)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: wallpapers

Files: *
Copyright: someone
License: GPL-2+

Files: 16.04/aitzgorri.jpg
       16.04/friends.jpg
Copyright: Aitzol
License: CC-BY-4.0

Files: nature/*.jpg
Copyright: x
License: CC-BY-SA-3.0

Files: debian/*
Copyright: packager
License: CC0-1.0

License: GPL-2+
 The full text.
";

    #[test]
    fn last_applying_stanza_wins_on_installed_paths() {
        let c = Copyright::parse(TEXT).unwrap();
        assert_eq!(
            c.licence_of("usr/share/backgrounds/aitzgorri.jpg"),
            Some("CC-BY-4.0")
        );
        assert_eq!(
            c.licence_of("usr/share/backgrounds/friends.jpg"),
            Some("CC-BY-4.0")
        );
        assert_eq!(
            c.licence_of("usr/share/backgrounds/mate/nature/Dune.jpg"),
            Some("CC-BY-SA-3.0")
        );
        // `debian/*` must not capture installed files by their name alone.
        assert_eq!(
            c.licence_of("usr/share/backgrounds/other.png"),
            Some("GPL-2+")
        );
        assert_eq!(
            c.licence_of("usr/share/backgrounds/mate/nature/x.png"),
            Some("GPL-2+")
        );
    }

    #[test]
    fn free_text_copyright_is_not_parsed() {
        assert_eq!(Copyright::parse("This package was debianized by ..."), None);
        let only_header = Copyright::parse("Format: x\n").unwrap();
        assert_eq!(only_header.licence_of("a/b.jpg"), None);
    }
}
