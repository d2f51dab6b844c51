//! Conventions the library crates keep (docs/architecture.md, "Conventions"):
//! no function of theirs answers an error as a bare `String`; each returns
//! its crate's typed error, which callers can match on.

use matseg_image::io::find_files;
use std::path::Path;

/// The signatures (from `fn` to the body or `;`, white space folded) of
/// the functions in `text` whose error type is `String`.
fn string_error_functions(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (start, _) in text.match_indices("fn ") {
        let at_item = text[..start]
            .chars()
            .next_back()
            .is_none_or(|c| c.is_whitespace() || c == ')');
        if !at_item {
            continue;
        }
        let end = text[start..]
            .find(['{', ';'])
            .map_or(text.len(), |e| start + e);
        let signature = text[start..end]
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        let returns = signature.split_once(" where ").map_or(&*signature, |s| s.0);
        if returns.contains("-> Result<") && returns.trim_end().ends_with(", String>") {
            found.push(signature);
        }
    }
    found
}

#[test]
fn the_detector_finds_string_errors_and_passes_typed_ones() {
    let text = "pub fn a(x: u8)\n    -> Result<Vec<u8>, String> {\n}\n\
                fn b() -> Result<(), MyError> {}\n\
                pub(crate) fn c<T>(t: T) -> Result<T, String>\nwhere\n    T: Copy,\n{}\n\
                let f = |s: &str| -> Result<u8, String> { Ok(1) };\n\
                fn d() -> Result<String, Error>;";
    let found = string_error_functions(text);
    assert_eq!(
        found,
        [
            "fn a(x: u8) -> Result<Vec<u8>, String>",
            "fn c<T>(t: T) -> Result<T, String> where T: Copy,"
        ]
    );
}

#[test]
fn no_library_function_returns_a_string_error() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut roots = vec![root.join("python/src")];
    for entry in std::fs::read_dir(root.join("crates")).unwrap() {
        let dir = entry.unwrap().path();
        // The CLI is the one binary: clap's value parsers answer `String`.
        if dir.file_name().unwrap() != "matseg-cli" {
            roots.push(dir.join("src"));
        }
    }
    let files = find_files(&roots, &["rs"]).unwrap();
    assert!(files.len() > 100, "{} source files", files.len());
    let offenders: Vec<String> = files
        .iter()
        .flat_map(|file| {
            let text = std::fs::read_to_string(file).unwrap();
            string_error_functions(&text)
                .into_iter()
                .map(move |s| format!("{}: {s}", file.display()))
        })
        .collect();
    assert!(offenders.is_empty(), "{offenders:#?}");
}
