//! docs/architecture.md lists the crates in dependency order and says what
//! the two front ends other than the CLI are built over: both claims are
//! checked here against the Cargo.toml files.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The listed folders (`crates/NAME` or `python`) in order, each with its
/// text in the layout block.
fn layout() -> Vec<(String, String)> {
    let page = std::fs::read_to_string(root().join("docs/architecture.md")).unwrap();
    let start = page.find("```\ncrates/\n").expect("the layout block") + 4;
    let block = &page[start..start + page[start..].find("```").expect("closed")];
    let mut entries: Vec<(String, String)> = Vec::new();
    for line in block.lines().skip(1) {
        let name = line.trim_start().split('/').next().unwrap_or("");
        let is_entry = !line.starts_with("    ") && line.trim_start().contains("/ ");
        if is_entry {
            let folder = if name == "python" {
                name.to_string()
            } else {
                format!("crates/{name}")
            };
            entries.push((folder, line.to_string()));
        } else if let Some((_, text)) = entries.last_mut() {
            text.push('\n');
            text.push_str(line);
        }
    }
    entries
}

/// The workspace crates `folder`'s Cargo.toml depends on (any table).
fn matseg_dependencies(folder: &str) -> BTreeSet<String> {
    let path = root().join(folder).join("Cargo.toml");
    let manifest: toml::Table = std::fs::read_to_string(&path).unwrap().parse().unwrap();
    let own = manifest["package"]["name"].as_str().unwrap().to_string();
    let mut tables: Vec<&toml::Table> = Vec::new();
    if let Some(t) = manifest.get("dependencies").and_then(|t| t.as_table()) {
        tables.push(t);
    }
    if let Some(targets) = manifest.get("target").and_then(|t| t.as_table()) {
        for target in targets.values() {
            if let Some(t) = target.get("dependencies").and_then(|t| t.as_table()) {
                tables.push(t);
            }
        }
    }
    tables
        .iter()
        .flat_map(|t| t.keys())
        .filter(|name| name.starts_with("matseg-") && **name != own)
        .cloned()
        .collect()
}

fn crate_name(folder: &str) -> String {
    folder.trim_start_matches("crates/").to_string()
}

#[test]
fn every_workspace_member_is_listed_and_depends_only_on_crates_above_it() {
    let entries = layout();
    let listed: Vec<&str> = entries.iter().map(|(f, _)| f.as_str()).collect();
    let workspace: toml::Table = std::fs::read_to_string(root().join("Cargo.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let members: BTreeSet<&str> = workspace["workspace"]["members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    assert_eq!(listed.iter().copied().collect::<BTreeSet<_>>(), members);
    for (i, folder) in listed.iter().enumerate() {
        let above: BTreeSet<String> = listed[..i].iter().map(|f| crate_name(f)).collect();
        for dependency in matseg_dependencies(folder) {
            assert!(
                above.contains(&dependency),
                "{folder} depends on {dependency}, listed below it"
            );
        }
    }
}

#[test]
fn matseg_image_is_under_every_crate_but_the_checkpoint_reader_and_the_model_description() {
    for (folder, _) in layout() {
        let dependencies = matseg_dependencies(&folder);
        match folder.as_str() {
            "crates/matseg-image" => {}
            "crates/matseg-weights" | "crates/matseg-model" => {
                assert!(dependencies.is_empty(), "{folder}: {dependencies:?}")
            }
            _ => assert!(dependencies.contains("matseg-image"), "{folder}"),
        }
    }
}

#[test]
fn the_web_app_and_python_name_every_crate_they_are_built_over() {
    for (folder, text) in layout() {
        if folder != "crates/matseg-serve" && folder != "python" {
            continue;
        }
        for dependency in matseg_dependencies(&folder) {
            // "matseg-data" or, in a list after another, "-data".
            let short = dependency.trim_start_matches("matseg");
            assert!(
                text.contains(&dependency)
                    || text.contains(&format!("{short},"))
                    || text.contains(&format!("{short} "))
                    || text.contains(&format!("{short}\n")),
                "docs/architecture.md does not say {folder} uses {dependency}"
            );
        }
    }
}
