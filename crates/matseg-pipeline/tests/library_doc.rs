//! docs/library.md shows the example it names, as it is.

#[test]
fn the_library_page_shows_the_example_verbatim() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let page = std::fs::read_to_string(root.join("../../docs/library.md")).unwrap();
    let example = std::fs::read_to_string(root.join("examples/library.rs")).unwrap();
    let start = page.find("```rust\n").expect("a Rust block") + "```rust\n".len();
    let block = &page[start..start + page[start..].find("```\n").expect("closed")];
    assert!(block.starts_with("fn main()"), "{block}");
    assert!(
        example.ends_with(block),
        "docs/library.md differs from examples/library.rs"
    );
}
