//! Property tests of the point benchmark's files: `data/NAME/data.json`
//! (material groups of points) and `group_relations.txt` (partial
//! similarities), as `Annotation::read` and `load_point_benchmark` read
//! them.
//!
//! Whatever a data folder holds (arbitrary bytes, any JSON value, a valid
//! file with bytes changed or a value replaced, relation lines of any
//! text) and whatever the image beside it is, reading gives an annotation
//! or a one-line error naming the file, never a panic, and a benchmark
//! with `skip_bad` loads with the bad image skipped. An annotation made
//! at random (numeric groups with points inside the image, relations
//! between them) passes `check`, is written and read back the same, and
//! loads into the weights its relations give; moved off the image, or
//! with a group repeated or a relation naming no group, it fails `check`.

#[path = "../../../testing/properties.rs"]
mod support;

use support::{mutate, mutation};

use image::RgbImage;
use matseg_eval::annotation::{DATA_FILE, RELATIONS_FILE};
use matseg_eval::points::{ROUND_RELATION, SQUARE_RELATION};
use matseg_eval::{load_point_benchmark, Annotation, AnnotationProblem, Group, Relation};
use matseg_query::descriptor::MAX_RADIUS;
use proptest::prelude::*;
use serde_json::Value;
use std::path::Path;

/// The seed of the cases.
const SEED: u64 = 2;

fn config() -> ProptestConfig {
    support::config(SEED)
}

// ---------------------------------------------------------------- inputs

/// Numbers: small, huge, negative, fractional.
fn json_number() -> impl Strategy<Value = Value> {
    prop_oneof![
        (0u64..64).prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<f64>().prop_map(Value::from),
        (-1e3f64..1e3).prop_map(Value::from),
    ]
}

/// Any JSON value, a few levels deep.
fn json_value() -> impl Strategy<Value = Value> {
    support::json_value(json_number(), 4, 6)
}

/// `value` with the value at a path chosen by `steps` replaced by `new`.
fn replace(value: &mut Value, steps: &[prop::sample::Index], new: Value) {
    let child = match value {
        Value::Array(items) if !items.is_empty() && !steps.is_empty() => {
            let k = steps[0].index(items.len());
            &mut items[k]
        }
        Value::Object(map) if !map.is_empty() && !steps.is_empty() => {
            let k = steps[0].index(map.len());
            map.values_mut().nth(k).expect("in range")
        }
        _ => {
            *value = new;
            return;
        }
    };
    replace(child, &steps[1..], new);
}

/// An image size and an annotation that fits it: numeric ids in the
/// order they are read in, points inside the image with radii from 0 to
/// the largest, relations of two distinct groups or more.
fn annotation() -> impl Strategy<Value = (u32, u32, Annotation)> {
    let group = (
        "[0-9]{1,6}",
        prop::option::of(any::<String>()),
        prop::collection::vec((0f64..1.0, 0f64..1.0, 0f64..=MAX_RADIUS as f64), 1..5),
    );
    (1u32..64, 1u32..64, prop::collection::vec(group, 0..6)).prop_flat_map(|(w, h, groups)| {
        let mut groups: Vec<Group> = groups
            .into_iter()
            .map(|(id, name, points)| Group {
                id,
                name,
                points: points
                    .into_iter()
                    // Scaled into the image (a product rounded up to the
                    // side is moved back inside).
                    .map(|(x, y, r)| {
                        let inside =
                            |t: f64, side: u32| (t * side as f64).min((side as f64).next_down());
                        [inside(x, w), inside(y, h), r]
                    })
                    .collect(),
            })
            .collect();
        groups.sort_by_key(|g| (g.id.parse::<u64>().unwrap_or(u64::MAX), g.id.clone()));
        groups.dedup_by(|a, b| a.id == b.id);
        let n = groups.len();
        let relation = (
            prop::sample::subsequence((0..n).collect::<Vec<_>>(), 2.min(n)..=n),
            any::<prop::sample::Index>(),
            any::<bool>(),
        );
        let relations = if n >= 2 {
            prop::collection::vec(relation, 0..4).boxed()
        } else {
            Just(Vec::new()).boxed()
        };
        (Just((w, h, groups)), relations).prop_map(|((w, h, groups), relations)| {
            let relations = relations
                .into_iter()
                .map(|(members, turn, square)| {
                    let mut ids: Vec<String> =
                        members.iter().map(|&k| groups[k].id.clone()).collect();
                    let by = turn.index(ids.len());
                    ids.rotate_left(by);
                    Relation {
                        ids,
                        weight: if square {
                            SQUARE_RELATION
                        } else {
                            ROUND_RELATION
                        },
                    }
                })
                .collect();
            (w, h, Annotation { groups, relations })
        })
    })
}

/// A benchmark folder of one image, `a`, of `w x h` pixels (or of the
/// bytes `image`, when given).
fn benchmark(dir: &Path, w: u32, h: u32, image: Option<&[u8]>) {
    std::fs::create_dir_all(dir.join("images")).unwrap();
    let file = dir.join("images/a.png");
    match image {
        Some(bytes) => std::fs::write(file, bytes).unwrap(),
        None => RgbImage::new(w, h).save(file).unwrap(),
    }
    std::fs::create_dir_all(dir.join("data/a")).unwrap();
}

/// Reads the data folder of `a` and loads the benchmark both ways: no
/// panic, one-line errors, and with `skip_bad` every image is loaded or
/// skipped.
fn read_any(dir: &Path) -> Result<(), TestCaseError> {
    if let Err(e) = Annotation::read(&dir.join("data/a")) {
        prop_assert!(!e.to_string().contains('\n'), "{}", e);
    }
    match load_point_benchmark(dir, false) {
        Ok(bench) => prop_assert_eq!(bench.images.len(), 1),
        Err(e) => prop_assert!(!e.to_string().contains('\n'), "{}", e),
    }
    let bench = load_point_benchmark(dir, true).unwrap();
    prop_assert_eq!(bench.images.len() + bench.skipped.len(), 1);
    Ok(())
}

/// Writes the files of folder `a`: `data.json`, and the relations when given.
fn write_data(dir: &Path, data: &[u8], relations: Option<&[u8]>) {
    std::fs::write(dir.join("data/a").join(DATA_FILE), data).unwrap();
    if let Some(relations) = relations {
        std::fs::write(dir.join("data/a").join(RELATIONS_FILE), relations).unwrap();
    }
}

// ---------------------------------------------------------------- properties

proptest! {
    #![proptest_config(config())]

    #[test]
    fn annotations_round_trip_and_pass_their_check((w, h, annotation) in annotation()) {
        prop_assert_eq!(annotation.check(w, h), Ok(()));
        let dir = tempfile::tempdir().unwrap();
        benchmark(dir.path(), w, h, None);
        let folder = dir.path().join("data/a");
        annotation.write(&folder).unwrap();
        let read = Annotation::read(&folder).unwrap();
        if annotation.groups.is_empty() {
            prop_assert_eq!(read, None);
            return Ok(());
        }
        prop_assert_eq!(read.as_ref(), Some(&annotation));

        // The benchmark's weights: 1 within a group, the heaviest relation
        // naming both groups between two, 0 otherwise.
        let bench = load_point_benchmark(dir.path(), false).unwrap();
        let image = &bench.images[0];
        let ids: Vec<&str> = annotation.groups.iter().map(|g| g.id.as_str()).collect();
        prop_assert_eq!(&image.material_ids, &ids);
        for (i, a) in ids.iter().enumerate() {
            for (j, b) in ids.iter().enumerate() {
                let want = if i == j {
                    1.0
                } else {
                    annotation
                        .relations
                        .iter()
                        .filter(|r| r.ids.iter().any(|id| id == a) && r.ids.iter().any(|id| id == b))
                        .map(|r| r.weight)
                        .fold(0.0, f64::max)
                };
                prop_assert_eq!(image.weights[i][j], want);
            }
        }
        prop_assert_eq!(image.has_relations, !annotation.relations.is_empty());
    }

    #[test]
    fn annotations_moved_or_renamed_fail_their_check(
        (w, h, annotation) in annotation(),
        which in any::<prop::sample::Index>(),
        change in 0..5,
    ) {
        prop_assume!(!annotation.groups.is_empty());
        let mut bad = annotation.clone();
        let g = which.index(bad.groups.len());
        let problem = match change {
            0 => {
                bad.groups[g].points[0][0] = w as f64;
                "outside"
            }
            1 => {
                bad.groups[g].points[0][1] = -0.5;
                "outside"
            }
            2 => {
                let copy = bad.groups[g].clone();
                bad.groups.push(copy);
                "twice"
            }
            3 => {
                bad.groups[g].points.clear();
                "no points"
            }
            _ => {
                let id = format!("{}9", bad.groups.iter().map(|g| g.id.as_str()).collect::<String>());
                bad.relations.push(Relation { ids: vec![bad.groups[g].id.clone(), id], weight: SQUARE_RELATION });
                "unknown"
            }
        };
        let err = bad.check(w, h).unwrap_err();
        prop_assert!(err.to_string().contains(problem), "{}", err);
        let in_relations = matches!(err, AnnotationProblem::UnknownInRelation { .. });
        prop_assert_eq!(err.file() == RELATIONS_FILE, in_relations);
    }

    #[test]
    fn data_files_of_arbitrary_bytes_never_panic(
        data in prop::collection::vec(any::<u8>(), 0..256),
        relations in prop::option::of(prop::collection::vec(any::<u8>(), 0..128)),
    ) {
        let dir = tempfile::tempdir().unwrap();
        benchmark(dir.path(), 20, 10, None);
        write_data(dir.path(), &data, relations.as_deref());
        read_any(dir.path())?;
    }

    #[test]
    fn data_files_of_any_json_never_panic(data in json_value(), lines in prop::collection::vec(any::<String>(), 0..5)) {
        let dir = tempfile::tempdir().unwrap();
        benchmark(dir.path(), 20, 10, None);
        let relations = lines.join("\n");
        write_data(dir.path(), data.to_string().as_bytes(), Some(relations.as_bytes()));
        read_any(dir.path())?;
    }

    #[test]
    fn relation_lines_of_any_shape_never_panic(
        lines in prop::collection::vec(
            (prop::sample::select(vec!["[", "(", "", " ["]), prop::collection::vec("[0-9 \"',]{0,4}", 0..5), prop::sample::select(vec!["]", ")", "", "] "])),
            0..6,
        ),
    ) {
        let dir = tempfile::tempdir().unwrap();
        benchmark(dir.path(), 20, 10, None);
        let text: String = lines
            .iter()
            .map(|(open, ids, close)| format!("{open}{}{close}\n", ids.join(",")))
            .collect();
        write_data(dir.path(), br#"{"1": {"pt_im": [[1, 1, 1]]}, "2": {"pt_im": [[2, 2, 2]]}}"#, Some(text.as_bytes()));
        read_any(dir.path())?;
    }

    #[test]
    fn damaged_data_files_never_panic(
        (w, h, annotation) in annotation(),
        m in mutation(),
        in_relations in any::<bool>(),
    ) {
        prop_assume!(!annotation.groups.is_empty());
        let dir = tempfile::tempdir().unwrap();
        benchmark(dir.path(), w, h, None);
        let folder = dir.path().join("data/a");
        annotation.write(&folder).unwrap();
        let file = folder.join(if in_relations && !annotation.relations.is_empty() { RELATIONS_FILE } else { DATA_FILE });
        let bytes = std::fs::read(&file).unwrap();
        std::fs::write(&file, mutate(&bytes, &m)).unwrap();
        read_any(dir.path())?;
    }

    #[test]
    fn data_files_with_a_value_replaced_never_panic(
        (w, h, annotation) in annotation(),
        steps in prop::collection::vec(any::<prop::sample::Index>(), 0..6),
        new in json_value(),
    ) {
        prop_assume!(!annotation.groups.is_empty());
        let dir = tempfile::tempdir().unwrap();
        benchmark(dir.path(), w, h, None);
        let folder = dir.path().join("data/a");
        annotation.write(&folder).unwrap();
        let file = folder.join(DATA_FILE);
        let mut json: Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
        replace(&mut json, &steps, new);
        std::fs::write(&file, json.to_string()).unwrap();
        read_any(dir.path())?;
    }

    #[test]
    fn images_of_arbitrary_bytes_are_errors_naming_them(
        (_, _, annotation) in annotation(),
        bytes in prop::collection::vec(any::<u8>(), 0..256),
        png_start in any::<bool>(),
    ) {
        prop_assume!(!annotation.groups.is_empty());
        let dir = tempfile::tempdir().unwrap();
        // Half of them start as a PNG does, so the decoder reads further.
        let mut image = if png_start { b"\x89PNG\r\n\x1a\n".to_vec() } else { Vec::new() };
        image.extend(bytes);
        benchmark(dir.path(), 1, 1, Some(&image));
        annotation.write(&dir.path().join("data/a")).unwrap();
        if let Err(e) = load_point_benchmark(dir.path(), false) {
            // A decoder's message may end in a newline (image errors keep
            // it); no other is allowed.
            prop_assert!(!e.to_string().contains('\n'), "{}", e);
            prop_assert!(e.path.starts_with(dir.path()), "{}", e);
        }
        read_any(dir.path())?;
    }
}
