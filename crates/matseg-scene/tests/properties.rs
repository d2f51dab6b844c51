//! Property tests of the TOML files a user writes for the generators: 2D
//! and 3D recipes (`--config`, the starting point `matseg recipe --kind
//! 2d|3d` prints) and 3D camera paths.
//!
//! Whatever a file holds (arbitrary text or bytes, the default file with
//! a line deleted, repeated or replaced, a value replaced by any TOML
//! value, bytes changed), reading it gives a recipe or a one-line error
//! naming the file, never a panic. A default recipe or path written as
//! TOML reads back the same, and so does any recipe a changed file gives.

#[path = "../../../testing/properties.rs"]
mod support;

use matseg_scene::{CameraPath, Recipe2d, Recipe3d, RecipeError};
use proptest::prelude::*;
use std::path::Path;

/// The seed of the cases.
const SEED: u64 = 3;

fn config() -> ProptestConfig {
    support::config(SEED)
}

/// The three kinds of file, read from a path.
#[derive(Clone, Copy, Debug)]
enum Kind {
    TwoD,
    ThreeD,
    CameraPath,
}

const KINDS: [Kind; 3] = [Kind::TwoD, Kind::ThreeD, Kind::CameraPath];

impl Kind {
    /// The default file, as `matseg recipe` writes it.
    fn default_text(self) -> String {
        match self {
            Kind::TwoD => toml::to_string_pretty(&Recipe2d::default()),
            Kind::ThreeD => toml::to_string_pretty(&Recipe3d::default()),
            Kind::CameraPath => toml::to_string_pretty(&CameraPath::default()),
        }
        .expect("a default serialises")
    }

    /// Reads `path`; when it reads, checks that the value written as TOML
    /// reads back the same.
    fn read(self, path: &Path) -> Result<Result<(), RecipeError>, TestCaseError> {
        fn again<T: serde::Serialize + PartialEq + std::fmt::Debug>(
            path: &Path,
            value: T,
            read: impl Fn(&Path) -> Result<T, RecipeError>,
        ) -> Result<(), TestCaseError> {
            // No setting is NaN or infinite: such files are refused.
            let text = toml::to_string_pretty(&value).unwrap();
            prop_assert!(!text.contains("nan") && !text.contains("inf"), "{}", text);
            let copy = path.with_extension("again.toml");
            std::fs::write(&copy, &text).unwrap();
            let again = read(&copy).unwrap();
            prop_assert_eq!(again, value);
            Ok(())
        }
        Ok(match self {
            Kind::TwoD => match Recipe2d::from_toml_file(path) {
                Ok(r) => Ok(again(path, r, Recipe2d::from_toml_file)?),
                Err(e) => Err(e),
            },
            Kind::ThreeD => match Recipe3d::from_toml_file(path) {
                Ok(r) => Ok(again(path, r, Recipe3d::from_toml_file)?),
                Err(e) => Err(e),
            },
            Kind::CameraPath => match CameraPath::from_toml_file(path) {
                Ok(r) => Ok(again(path, r, CameraPath::from_toml_file)?),
                Err(e) => Err(e),
            },
        })
    }
}

/// Writes `bytes` as a file and reads it as each kind: a value, or one
/// line naming the file.
fn read_any(bytes: &[u8]) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("recipe.toml");
    std::fs::write(&path, bytes).unwrap();
    for kind in KINDS {
        if let Err(e) = kind.read(&path)? {
            let text = e.to_string();
            prop_assert!(!text.contains('\n'), "{:?}: {:?}", kind, text);
            prop_assert!(text.starts_with(&path.display().to_string()), "{}", text);
        }
    }
    Ok(())
}

/// TOML values of every type, and numbers at the edges of theirs.
fn toml_value() -> impl Strategy<Value = String> {
    let number = prop_oneof![
        any::<i64>().prop_map(|v| v.to_string()),
        (-3i64..20).prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| format!("{v:?}")),
        (-1.0f64..2.0).prop_map(|v| format!("{v:?}")),
        prop::sample::select(vec![
            "nan",
            "+nan",
            "-nan",
            "inf",
            "-inf",
            "0.0",
            "-0.0",
            "1e400",
            "5e-324",
            "18446744073709551615",
            "9223372036854775807",
            "-9223372036854775808",
            "0x7f",
            "1_000",
            "01",
        ])
        .prop_map(str::to_string),
    ];
    let leaf = prop_oneof![
        3 => number,
        1 => any::<bool>().prop_map(|b| b.to_string()),
        1 => any::<String>().prop_map(|s| toml::Value::String(s).to_string()),
        1 => Just("1979-05-27T07:32:00Z".to_string()),
    ];
    let nested = leaf.clone().prop_recursive(2, 12, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(|v| format!("[{}]", v.join(", "))),
            prop::collection::vec(("[a-z_]{1,8}", inner), 0..3).prop_map(|v| {
                let fields: Vec<String> = v.iter().map(|(k, x)| format!("{k} = {x}")).collect();
                format!("{{ {} }}", fields.join(", "))
            }),
        ]
    });
    prop_oneof![4 => leaf, 1 => nested]
}

/// Floats at the edges: not numbers, infinite, the smallest, the largest.
fn edge_float() -> impl Strategy<Value = String> {
    prop::sample::select(vec![
        "nan",
        "-nan",
        "inf",
        "-inf",
        "-0.0",
        "5e-324",
        "1.7976931348623157e308",
    ])
    .prop_map(str::to_string)
}

/// A change to a file's lines or bytes.
#[derive(Clone, Debug)]
enum Edit {
    /// The value of a `key = value` line replaced.
    Value(prop::sample::Index, String),
    /// A line removed.
    Delete(prop::sample::Index),
    /// A line written twice.
    Repeat(prop::sample::Index),
    /// A line replaced by any text.
    Replace(prop::sample::Index, String),
    /// Any text inserted as a line.
    Insert(prop::sample::Index, String),
    /// A byte changed.
    Byte(prop::sample::Index, u8),
}

fn edit() -> impl Strategy<Value = Edit> {
    let index = any::<prop::sample::Index>;
    let line = || {
        prop_oneof![
            any::<String>(),
            "\\[[a-z_. ]{0,12}\\]",
            "[a-z_]{1,10} ?= ?[0-9a-z.\"]{0,6}"
        ]
    };
    prop_oneof![
        4 => (index(), toml_value()).prop_map(|(i, v)| Edit::Value(i, v)),
        1 => index().prop_map(Edit::Delete),
        1 => index().prop_map(Edit::Repeat),
        1 => (index(), line()).prop_map(|(i, l)| Edit::Replace(i, l)),
        1 => (index(), line()).prop_map(|(i, l)| Edit::Insert(i, l)),
        1 => (index(), any::<u8>()).prop_map(|(i, b)| Edit::Byte(i, b)),
    ]
}

fn apply(text: &str, edits: &[Edit]) -> Vec<u8> {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut bytes = None;
    for edit in edits {
        match edit {
            Edit::Value(i, value) => {
                let keyed: Vec<usize> = (0..lines.len())
                    .filter(|&k| lines[k].contains(" = "))
                    .collect();
                if !keyed.is_empty() {
                    let k = keyed[i.index(keyed.len())];
                    let key = lines[k].split(" = ").next().unwrap_or_default().to_string();
                    lines[k] = format!("{key} = {value}");
                }
            }
            Edit::Delete(i) if !lines.is_empty() => {
                lines.remove(i.index(lines.len()));
            }
            Edit::Repeat(i) if !lines.is_empty() => {
                let k = i.index(lines.len());
                lines.insert(k, lines[k].clone());
            }
            Edit::Replace(i, line) if !lines.is_empty() => {
                let k = i.index(lines.len());
                lines[k] = line.clone();
            }
            Edit::Insert(i, line) => {
                let k = i.index(lines.len() + 1);
                lines.insert(k, line.clone());
            }
            Edit::Byte(i, b) => bytes = Some((*i, *b)),
            _ => {}
        }
    }
    let mut out = (lines.join("\n") + "\n").into_bytes();
    if let Some((i, b)) = bytes {
        let k = i.index(out.len());
        out[k] = b;
    }
    out
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn files_of_arbitrary_text_never_panic(text in any::<String>()) {
        read_any(text.as_bytes())?;
    }

    #[test]
    fn files_of_arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
        read_any(&bytes)?;
    }

    #[test]
    fn default_files_changed_never_panic(
        kind in prop::sample::select(KINDS.to_vec()),
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        read_any(&apply(&kind.default_text(), &edits))?;
    }

    #[test]
    fn an_edge_float_in_any_field_reads_or_is_named(
        kind in prop::sample::select(KINDS.to_vec()),
        which in any::<prop::sample::Index>(),
        value in edge_float(),
    ) {
        read_any(&apply(&kind.default_text(), &[Edit::Value(which, value)]))?;
    }

    #[test]
    fn a_value_of_a_default_file_replaced_reads_or_is_named(
        kind in prop::sample::select(KINDS.to_vec()),
        which in any::<prop::sample::Index>(),
        value in toml_value(),
    ) {
        read_any(&apply(&kind.default_text(), &[Edit::Value(which, value)]))?;
    }
}

#[test]
fn default_files_read_back_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("default.toml");
    std::fs::write(&path, Kind::TwoD.default_text()).unwrap();
    assert_eq!(
        Recipe2d::from_toml_file(&path).unwrap(),
        Recipe2d::default()
    );
    std::fs::write(&path, Kind::ThreeD.default_text()).unwrap();
    assert_eq!(
        Recipe3d::from_toml_file(&path).unwrap(),
        Recipe3d::default()
    );
    std::fs::write(&path, Kind::CameraPath.default_text()).unwrap();
    assert_eq!(
        CameraPath::from_toml_file(&path).unwrap(),
        CameraPath::default()
    );
    // An empty file is every default.
    std::fs::write(&path, "").unwrap();
    assert_eq!(
        Recipe2d::from_toml_file(&path).unwrap(),
        Recipe2d::default()
    );
    assert_eq!(
        Recipe3d::from_toml_file(&path).unwrap(),
        Recipe3d::default()
    );
    assert_eq!(
        CameraPath::from_toml_file(&path).unwrap(),
        CameraPath::default()
    );
}
