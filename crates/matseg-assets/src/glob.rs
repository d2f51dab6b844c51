//! Shell-style path patterns as manifests and Debian copyright files write
//! them: `*` matches any run of characters but `/`, `?` one character but `/`.

/// Whether `pattern` matches the whole of `path`.
pub fn glob_match(pattern: &str, path: &str) -> bool {
    let (p, s): (Vec<char>, Vec<char>) = (pattern.chars().collect(), path.chars().collect());
    // Classic two-pointer matching with one backtrack point per star; a star
    // never crosses a `/`, so a failed star only retries within its component.
    let (mut pi, mut si) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while si < s.len() {
        if pi < p.len() && (p[pi] == s[si] || (p[pi] == '?' && s[si] != '/')) {
            pi += 1;
            si += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, si));
            pi += 1;
        } else if let Some((sp, ss)) = star.filter(|&(_, ss)| s[ss] != '/') {
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
