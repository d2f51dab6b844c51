//! Shell-style path patterns as manifests and Debian copyright files write
//! them: `*` matches any run of characters but `/`, `?` one character but `/`.

/// Whether `pattern` matches the whole of `path`, its wildcards staying
/// within one path component (manifests).
pub fn glob_match(pattern: &str, path: &str) -> bool {
    matches(pattern, path, false)
}

/// Whether `pattern` matches the whole of `path`, `*` and `?` matching `/`
/// too, as in Debian copyright files (DEP-5: "both match a slash").
pub fn glob_match_across(pattern: &str, path: &str) -> bool {
    matches(pattern, path, true)
}

fn matches(pattern: &str, path: &str, across: bool) -> bool {
    let (p, s): (Vec<char>, Vec<char>) = (pattern.chars().collect(), path.chars().collect());
    let wild_takes = |c: char| across || c != '/';
    // Classic two-pointer matching with one backtrack point per star; unless
    // `across`, a star never crosses a `/`, so a failed star only retries
    // within its component.
    let (mut pi, mut si) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while si < s.len() {
        if pi < p.len() && (p[pi] == s[si] || (p[pi] == '?' && wild_takes(s[si]))) {
            pi += 1;
            si += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, si));
            pi += 1;
        } else if let Some((sp, ss)) = star.filter(|&(_, ss)| wild_takes(s[ss])) {
            pi = sp + 1;
            si = ss + 1;
            star = Some((sp, ss + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// The directories of `pattern` before its first wildcard, with the
/// trailing `/`: the part a taken file's corpus name leaves out.
pub fn literal_prefix(pattern: &str) -> &str {
    let first_wild = pattern.find(['*', '?']).unwrap_or(pattern.len());
    match pattern[..first_wild].rfind('/') {
        Some(i) => &pattern[..=i],
        None => "",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stars_stay_within_a_component() {
        assert!(glob_match("*.jpg", "a.jpg"));
        assert!(!glob_match("*.jpg", "d/a.jpg"));
        assert!(glob_match("usr/share/*/a?.png", "usr/share/x/ab.png"));
        assert!(!glob_match("usr/share/*/a?.png", "usr/share/x/y/ab.png"));
        assert!(glob_match("MATE-Stripes-*.png", "MATE-Stripes-Dark.png"));
        assert!(glob_match("*", "anything"));
        assert!(!glob_match("*", "a/b"));
        assert!(glob_match("a*b*c", "axxbyyc"));
        assert!(!glob_match("a*b*c", "axxbyy"));
        assert!(glob_match("exact", "exact") && !glob_match("exact", "exactly"));
    }

    #[test]
    fn copyright_stars_cross_slashes() {
        assert!(glob_match_across(
            "data/trak/*",
            "data/trak/trak5/brick.jpg"
        ));
        assert!(!glob_match("data/trak/*", "data/trak/trak5/brick.jpg"));
        assert!(glob_match_across("*.jpg", "a/b/c.jpg"));
        assert!(glob_match_across("a?b", "a/b"));
        assert!(!glob_match_across("data/trak/*", "data/trakx/a.jpg"));
    }

    #[test]
    fn literal_prefix_is_the_directory_before_wildcards() {
        assert_eq!(
            literal_prefix("usr/share/backgrounds/*.jpg"),
            "usr/share/backgrounds/"
        );
        assert_eq!(literal_prefix("hdri/*.exr.js"), "hdri/");
        assert_eq!(literal_prefix("a/b/file.pth"), "a/b/");
        assert_eq!(literal_prefix("*.png"), "");
    }
}
