//! Licence families and the `--licences` filter: licence strings as packages
//! and `licenses.json` files spell them (SPDX ids, Debian short names, free
//! text) grouped into the few families a user filters on.

use std::fmt;

/// The families a licence string falls into, from most to least permissive.
pub const FAMILIES: [&str; 10] = [
    "cc0",
    "public-domain",
    "mit",
    "bsd",
    "apache",
    "cc-by",
    "cc-by-sa",
    "lgpl",
    "gpl",
    "unknown",
];

/// The family of a licence string (case and punctuation ignored):
/// `CC0-1.0` and `Creative Commons Zero` are `cc0`; `CC-BY-SA-4.0` is
/// `cc-by-sa`; `Creative Commons Attribution 3.0` is `cc-by`; `GPL-2+` is
/// `gpl`, and so is `GPL-3+ and LGPL-3+`; `LGPL-2.1+` is `lgpl`;
/// `BSD-3-Clause (torchvision)` is `bsd`;
/// anything unrecognised is `unknown`.
pub fn licence_family(licence: &str) -> &'static str {
    let s: String = licence
        .to_ascii_lowercase()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { ' ' })
        .collect();
    let words: Vec<&str> = s.split_whitespace().collect();
    let has = |w: &str| words.contains(&w);
    let starts = |w: &str| words.first() == Some(&w);
    if has("cc0") || s.contains("creative commons zero") {
        "cc0"
    } else if s.contains("public domain") || s.contains("unlicense") {
        "public-domain"
    } else if has("cc") || s.contains("creative commons") {
        if has("sa") || s.contains("sharealike") || s.contains("share alike") {
            "cc-by-sa"
        } else {
            "cc-by"
        }
    } else if has("gpl") || has("agpl") {
        // Before LGPL: "GPL-3+ and LGPL-3+" (files under both) is GPL.
        "gpl"
    } else if has("lgpl") {
        "lgpl"
    } else if starts("mit") || has("expat") {
        "mit"
    } else if starts("bsd") || has("bsd") {
        "bsd"
    } else if starts("apache") {
        "apache"
    } else {
        "unknown"
    }
}

/// Which licence families a user accepts (`--licences cc0,public-domain`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LicenceFilter {
    families: Vec<&'static str>,
}

/// A `--licences` value naming no known family.
#[derive(Debug, thiserror::Error)]
#[error("--licences: unknown licence family '{0}' (known: {known})", known = FAMILIES.join(", "))]
pub struct UnknownFamily(pub String);

impl LicenceFilter {
    /// Parses a comma-separated list of family names; empty accepts all.
    pub fn parse(list: &str) -> Result<Self, UnknownFamily> {
        let mut families = Vec::new();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let family = FAMILIES
                .iter()
                .find(|f| f.eq_ignore_ascii_case(name))
                .ok_or_else(|| UnknownFamily(name.to_string()))?;
            if !families.contains(family) {
                families.push(*family);
            }
        }
        Ok(Self { families })
    }

    /// True when every licence is accepted.
    pub fn accepts_all(&self) -> bool {
        self.families.is_empty()
    }

    /// Whether files under `licence` may be used.
    pub fn accepts(&self, licence: &str) -> bool {
        self.accepts_all() || self.families.contains(&licence_family(licence))
    }
}

impl fmt::Display for LicenceFilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.accepts_all() {
            f.write_str("any licence")
        } else {
            f.write_str(&self.families.join(","))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn licence_strings_fall_into_their_families() {
        let cases = [
            ("CC0-1.0", "cc0"),
            ("CC0", "cc0"),
            ("public-domain", "public-domain"),
            ("Public Domain", "public-domain"),
            ("CC-BY-4.0", "cc-by"),
            ("CC-BY-3.0-USA", "cc-by"),
            ("Creative Commons Attribution 3.0 Unported license", "cc-by"),
            ("CC-BY-SA-3.0", "cc-by-sa"),
            ("GPL-2+", "gpl"),
            ("LGPL-2.1+", "lgpl"),
            ("GPL-3+ and GPL-2+ and LGPL-3+ and MIT and Expat", "gpl"),
            ("GPL-and-LGPL", "gpl"),
            ("BSD-3-Clause (torchvision)", "bsd"),
            ("Apache-2.0", "apache"),
            ("Expat", "mit"),
            ("MIT", "mit"),
            ("unknown", "unknown"),
            ("whatever-you-want", "unknown"),
        ];
        for (licence, family) in cases {
            assert_eq!(licence_family(licence), family, "{licence}");
        }
    }

    #[test]
    fn filter_accepts_only_named_families() {
        let f = LicenceFilter::parse("cc0, Public-Domain").unwrap();
        assert!(f.accepts("CC0-1.0"));
        assert!(f.accepts("public-domain"));
        assert!(!f.accepts("CC-BY-4.0"));
        assert!(!f.accepts("unknown"));
        assert_eq!(f.to_string(), "cc0,public-domain");
        let all = LicenceFilter::parse("").unwrap();
        assert!(all.accepts("GPL-2+") && all.accepts_all());
        let e = LicenceFilter::parse("cc0,beerware").unwrap_err();
        assert!(e.to_string().contains("'beerware'"), "{e}");
    }
}
