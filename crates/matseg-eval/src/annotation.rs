//! One image's annotation in a point benchmark (the MatSeg layout of
//! [`crate::points`]): material groups of points and the relations between
//! groups, read from, checked against its image and written to
//! `data/NAME/data.json` and `group_relations.txt`. The one reader, checker
//! and writer of the format: `matseg eval points`, the synthetic benchmark
//! writer and the web app's annotate page all go through it.

use crate::points::{BenchError, ROUND_RELATION, SQUARE_RELATION};
use matseg_image::outputs::write_atomic;
use matseg_query::descriptor::{check_radius, RadiusError};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// The annotation file of an image's data folder.
pub const DATA_FILE: &str = "data.json";
/// The optional relations file of an image's data folder.
pub const RELATIONS_FILE: &str = "group_relations.txt";

/// A material group: its id (`1`, `2`...), an optional name and its points
/// `[x, y, r]` in image pixels.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
pub struct Group {
    /// The material id.
    pub id: String,
    /// What the annotator called it (hand-made benchmarks often have none).
    #[serde(default)]
    pub name: Option<String>,
    /// The points, `[x, y, r]`.
    pub points: Vec<[f64; 3]>,
}

/// Groups that are partly the same material: weight [`SQUARE_RELATION`]
/// (`[...]` in `group_relations.txt`) or [`ROUND_RELATION`] (`(...)`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
pub struct Relation {
    /// The groups' ids.
    pub ids: Vec<String>,
    /// [`SQUARE_RELATION`] or [`ROUND_RELATION`].
    pub weight: f64,
}

/// One image's annotation.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
pub struct Annotation {
    /// The material groups, numeric ids in numeric order when read.
    pub groups: Vec<Group>,
    /// The partial similarities between groups.
    #[serde(default)]
    pub relations: Vec<Relation>,
}

/// The first thing wrong with an annotation of an image of a given size.
#[derive(Clone, Debug, PartialEq)]
pub enum AnnotationProblem {
    /// A group id that is not a number.
    BadId(String),
    /// A group id given to two groups.
    RepeatedGroup(String),
    /// A group with no points.
    NoPoints(String),
    /// A point's disc radius out of the range every front end accepts.
    BadRadius {
        /// The group.
        id: String,
        /// The point, `[x, y, r]`.
        point: [f64; 3],
    },
    /// A point off the image.
    Outside {
        /// The group.
        id: String,
        /// The point, `[x, y, r]`.
        point: [f64; 3],
        /// The image's width.
        width: u32,
        /// The image's height.
        height: u32,
    },
    /// A relation weight other than the two the format has.
    BadWeight {
        /// The relation's ids.
        ids: Vec<String>,
        /// Its weight.
        weight: f64,
    },
    /// A relation of fewer than two groups.
    ShortRelation(Vec<String>),
    /// A relation naming a group that does not exist, or one twice.
    UnknownInRelation {
        /// The relation's ids.
        ids: Vec<String>,
        /// The id at fault.
        id: String,
    },
}

impl AnnotationProblem {
    /// The file of a data folder the problem lies in.
    pub fn file(&self) -> &'static str {
        match self {
            Self::BadWeight { .. } | Self::ShortRelation(_) | Self::UnknownInRelation { .. } => {
                RELATIONS_FILE
            }
            _ => DATA_FILE,
        }
    }
}

impl fmt::Display for AnnotationProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BadId(id) => write!(f, "group id {id:?}: expected a number"),
            Self::RepeatedGroup(id) => write!(f, "group {id} appears twice"),
            Self::NoPoints(id) => write!(f, "group {id} has no points"),
            Self::BadRadius {
                id,
                point: [x, y, r],
            } => write!(
                f,
                "group {id}: point ({x}, {y}): {}",
                RadiusError(*r as f32)
            ),
            Self::Outside {
                id,
                point: [x, y, r],
                width,
                height,
            } => write!(
                f,
                "group {id}: point ({x}, {y}, r {r}) is outside the {width}x{height} image"
            ),
            Self::BadWeight { ids, weight } => write!(
                f,
                "relation {ids:?}: weight {weight} is neither {SQUARE_RELATION} nor {ROUND_RELATION}"
            ),
            Self::ShortRelation(ids) => write!(f, "relation {ids:?}: needs two groups or more"),
            Self::UnknownInRelation { ids, id } => {
                write!(f, "relation {ids:?}: group {id} unknown or repeated")
            }
        }
    }
}

impl std::error::Error for AnnotationProblem {}

impl Annotation {
    /// The annotation saved in the data folder `dir`; `None` when it has no
    /// `data.json`. A file that does not parse is an error naming it (and
    /// the line, for relations).
    pub fn read(dir: &Path) -> Result<Option<Self>, BenchError> {
        let data_file = dir.join(DATA_FILE);
        if !data_file.is_file() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&data_file)
            .map_err(|e| BenchError::new(&data_file, None, format!("cannot read: {e}")))?;
        let groups = parse_groups(&text, &data_file)?;
        let relations_file = dir.join(RELATIONS_FILE);
        let mut relations = Vec::new();
        if relations_file.is_file() {
            let text = std::fs::read_to_string(&relations_file)
                .map_err(|e| BenchError::new(&relations_file, None, format!("cannot read: {e}")))?;
            for (number, line) in text.lines().enumerate() {
                relations.extend(parse_relation(line, &relations_file, number + 1)?);
            }
        }
        Ok(Some(Self { groups, relations }))
    }

    /// The first problem of the annotation on a `width x height` image:
    /// numeric, distinct group ids, each with points inside the image, and
    /// relations of two distinct known groups or more with one of the two
    /// weights. No groups at all is no problem (nothing annotated yet).
    pub fn check(&self, width: u32, height: u32) -> Result<(), AnnotationProblem> {
        let mut ids: Vec<&str> = Vec::new();
        for group in &self.groups {
            let id = group.id.as_str();
            if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
                return Err(AnnotationProblem::BadId(id.to_string()));
            }
            if ids.contains(&id) {
                return Err(AnnotationProblem::RepeatedGroup(id.to_string()));
            }
            ids.push(id);
            if group.points.is_empty() {
                return Err(AnnotationProblem::NoPoints(id.to_string()));
            }
            for &point in &group.points {
                let [x, y, r] = point;
                if check_radius(r as f32).is_err() {
                    return Err(AnnotationProblem::BadRadius {
                        id: id.to_string(),
                        point,
                    });
                }
                let inside = (0.0..width as f64).contains(&x) && (0.0..height as f64).contains(&y);
                if !inside {
                    return Err(AnnotationProblem::Outside {
                        id: id.to_string(),
                        point,
                        width,
                        height,
                    });
                }
            }
        }
        for relation in &self.relations {
            let problem_ids = || relation.ids.clone();
            if relation.weight != SQUARE_RELATION && relation.weight != ROUND_RELATION {
                return Err(AnnotationProblem::BadWeight {
                    ids: problem_ids(),
                    weight: relation.weight,
                });
            }
            if relation.ids.len() < 2 {
                return Err(AnnotationProblem::ShortRelation(problem_ids()));
            }
            for (i, id) in relation.ids.iter().enumerate() {
                if !ids.contains(&id.as_str()) || relation.ids[..i].contains(id) {
                    return Err(AnnotationProblem::UnknownInRelation {
                        ids: problem_ids(),
                        id: id.clone(),
                    });
                }
            }
        }
        Ok(())
    }

    /// Writes the annotation into the data folder `dir`: `data.json`, and
    /// `group_relations.txt` when it has relations (an old one removed when
    /// it has none), each file whole or not at all. With no groups, removes
    /// what was there, the folder included.
    pub fn write(&self, dir: &Path) -> Result<(), BenchError> {
        let failed = |file: &Path, e: std::io::Error| {
            BenchError::new(file, None, format!("cannot write: {e}"))
        };
        let data_file = dir.join(DATA_FILE);
        let relations_file = dir.join(RELATIONS_FILE);
        if self.groups.is_empty() {
            for file in [&data_file, &relations_file] {
                if file.exists() {
                    std::fs::remove_file(file).map_err(|e| failed(file, e))?;
                }
            }
            if dir.is_dir() {
                std::fs::remove_dir(dir).map_err(|e| failed(dir, e))?;
            }
            return Ok(());
        }
        std::fs::create_dir_all(dir).map_err(|e| failed(dir, e))?;
        let data: serde_json::Map<String, serde_json::Value> = self
            .groups
            .iter()
            .map(|g| {
                let entry = match &g.name {
                    Some(name) => serde_json::json!({ "name": name, "pt_im": g.points }),
                    None => serde_json::json!({ "pt_im": g.points }),
                };
                (g.id.clone(), entry)
            })
            .collect();
        let json = serde_json::to_string_pretty(&data).expect("JSON of strings and numbers");
        write_atomic(&data_file, json.as_bytes()).map_err(|e| failed(&data_file, e))?;
        if self.relations.is_empty() {
            if relations_file.exists() {
                std::fs::remove_file(&relations_file).map_err(|e| failed(&relations_file, e))?;
            }
            return Ok(());
        }
        let text: String = self
            .relations
            .iter()
            .map(|r| format_relation(&r.ids, r.weight) + "\n")
            .collect();
        write_atomic(&relations_file, text.as_bytes()).map_err(|e| failed(&relations_file, e))
    }
}

/// The image file of `name` in the benchmark folder `bench`: the first of
/// `images/NAME.EXT` that exists, for each of matseg-image's image
/// extensions in lower case, then in upper case.
pub fn find_image(bench: &Path, name: &str) -> Option<PathBuf> {
    let images = bench.join("images");
    let lower = matseg_image::io::IMAGE_EXTENSIONS.map(str::to_string);
    let upper = lower.clone().map(|e| e.to_ascii_uppercase());
    lower
        .iter()
        .chain(&upper)
        .map(|ext| images.join(format!("{name}.{ext}")))
        .find(|p| p.is_file())
}

/// The images of the benchmark folder `bench`, by name (the file stem) and
/// file as [`find_image`] finds them, sorted by name.
pub fn list_images(bench: &Path) -> Result<Vec<(String, PathBuf)>, BenchError> {
    let dir = bench.join("images");
    let listing = std::fs::read_dir(&dir)
        .map_err(|e| BenchError::new(&dir, None, format!("cannot list images: {e}")))?;
    let mut names: Vec<String> = listing
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| matseg_image::io::has_image_extension(p))
        .filter_map(|p| Some(p.file_stem()?.to_str()?.to_string()))
        .collect();
    names.sort();
    names.dedup();
    Ok(names
        .into_iter()
        .filter_map(|name| find_image(bench, &name).map(|file| (name, file)))
        .collect())
}

/// The groups of the text of the `data.json` file `file`, numeric ids in
/// numeric order.
fn parse_groups(text: &str, file: &Path) -> Result<Vec<Group>, BenchError> {
    let fail = |message: String| BenchError::new(file, None, message);
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| fail(format!("bad JSON: {e}")))?;
    let object = value
        .as_object()
        .ok_or_else(|| fail("expected an object of material ids".into()))?;
    let mut groups = Vec::new();
    for (id, entry) in object {
        let list = entry
            .get("pt_im")
            .and_then(|p| p.as_array())
            .ok_or_else(|| fail(format!("material {id:?}: no \"pt_im\" list")))?;
        let points = list
            .iter()
            .enumerate()
            .map(|(k, p)| {
                p.as_array()
                    .filter(|a| a.len() == 3)
                    .and_then(|a| a.iter().map(|v| v.as_f64()).collect::<Option<Vec<_>>>())
                    .map(|c| [c[0], c[1], c[2]])
                    .ok_or_else(|| fail(format!("material {id:?}, point {k}: expected [x, y, r]")))
            })
            .collect::<Result<_, _>>()?;
        let name = entry
            .get("name")
            .and_then(|n| n.as_str())
            .map(str::to_string);
        groups.push(Group {
            id: id.clone(),
            name,
            points,
        });
    }
    groups.sort_by_key(|g| (g.id.parse::<u64>().unwrap_or(u64::MAX), g.id.clone()));
    Ok(groups)
}

/// The `group_relations.txt` line of ids with `weight`: `[1, 2]` for
/// [`SQUARE_RELATION`], `(1, 2)` otherwise.
pub fn format_relation(ids: &[String], weight: f64) -> String {
    let (open, close) = if weight == SQUARE_RELATION {
        ('[', ']')
    } else {
        ('(', ')')
    };
    format!("{open}{}{close}", ids.join(", "))
}

/// Line `number` of the `group_relations.txt` file `file`: the relation,
/// `None` for a blank line.
fn parse_relation(line: &str, file: &Path, number: usize) -> Result<Option<Relation>, BenchError> {
    let fail = |message: String| BenchError::new(file, Some(number), message);
    let line = line.trim();
    if line.is_empty() {
        return Ok(None);
    }
    let (inner, weight) =
        if let Some(inner) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            (inner, SQUARE_RELATION)
        } else if let Some(inner) = line.strip_prefix('(').and_then(|l| l.strip_suffix(')')) {
            (inner, ROUND_RELATION)
        } else {
            return Err(fail(format!(
                "{line:?}: a relation is a list of ids in [...] or (...)"
            )));
        };
    let ids: Vec<String> = inner
        .split(',')
        .map(|id| {
            id.trim()
                .trim_matches(|c| c == '"' || c == '\'')
                .to_string()
        })
        .filter(|id| !id.is_empty())
        .collect();
    if ids.len() < 2 {
        return Err(fail(format!(
            "{line:?}: a relation needs at least two material ids"
        )));
    }
    Ok(Some(Relation { ids, weight }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn annotation() -> Annotation {
        let group = |id: &str, name: Option<&str>, points: Vec<[f64; 3]>| Group {
            id: id.into(),
            name: name.map(str::to_string),
            points,
        };
        Annotation {
            groups: vec![
                group("1", Some("rust"), vec![[10.0, 5.0, 3.0], [20.0, 8.0, 3.0]]),
                group("2", Some(""), vec![[1.0, 1.0, 0.0]]),
                group("3", None, vec![[30.0, 9.0, 5.0]]),
            ],
            relations: vec![
                Relation {
                    ids: vec!["1".into(), "2".into()],
                    weight: SQUARE_RELATION,
                },
                Relation {
                    ids: vec!["2".into(), "3".into()],
                    weight: ROUND_RELATION,
                },
            ],
        }
    }

    #[test]
    fn an_annotation_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("data/a");
        assert_eq!(Annotation::read(&data).unwrap(), None);
        annotation().write(&data).unwrap();
        assert_eq!(Annotation::read(&data).unwrap(), Some(annotation()));
        assert_eq!(
            std::fs::read_to_string(data.join(RELATIONS_FILE)).unwrap(),
            "[1, 2]\n(2, 3)\n"
        );
        let json = std::fs::read_to_string(data.join(DATA_FILE)).unwrap();
        assert!(json.contains("\"name\": \"rust\"") && json.contains("\"name\": \"\""));
        assert_eq!(json.matches("\"name\"").count(), 2, "no name: no key");
        let mut fewer = annotation();
        fewer.relations.clear();
        fewer.write(&data).unwrap();
        assert!(!data.join(RELATIONS_FILE).exists());
        assert_eq!(Annotation::read(&data).unwrap(), Some(fewer));
        Annotation::default().write(&data).unwrap();
        assert!(!data.exists(), "no groups: nothing left");
    }

    /// A coordinate the property tests found read back one unit in the
    /// last place off, before JSON floats were parsed exactly.
    #[test]
    fn coordinates_read_back_to_the_last_bit() {
        let dir = tempfile::tempdir().unwrap();
        let a = Annotation {
            groups: vec![Group {
                id: "0".into(),
                name: None,
                points: vec![[0.983_489_336_938_522_9, 0.0, 0.0]],
            }],
            relations: Vec::new(),
        };
        a.write(dir.path()).unwrap();
        assert_eq!(Annotation::read(dir.path()).unwrap(), Some(a));
    }

    #[test]
    fn bad_annotations_are_named() {
        let problem = |a: &Annotation| a.check(40, 10).unwrap_err().to_string();
        assert_eq!(annotation().check(40, 10), Ok(()));
        let mut outside = annotation();
        outside.groups[0].points[0] = [40.0, 5.0, 3.0];
        assert_eq!(
            problem(&outside),
            "group 1: point (40, 5, r 3) is outside the 40x10 image"
        );
        let mut empty = annotation();
        empty.groups[1].points.clear();
        assert_eq!(problem(&empty), "group 2 has no points");
        let mut twice = annotation();
        twice.groups[2].id = "1".into();
        assert_eq!(problem(&twice), "group 1 appears twice");
        let mut unknown = annotation();
        unknown.relations[0].ids[1] = "7".into();
        let error = unknown.check(40, 10).unwrap_err();
        assert_eq!(error.file(), RELATIONS_FILE);
        assert!(error.to_string().contains("group 7 unknown"));
        let mut weight = annotation();
        weight.relations[0].weight = 0.5;
        assert!(problem(&weight).contains("weight 0.5"));
        let mut named = annotation();
        named.groups[0].id = "a".into();
        assert!(problem(&named).contains("expected a number"));
        assert_eq!(Annotation::default().check(1, 1), Ok(()));
    }

    #[test]
    fn relations_parse_with_their_weights() {
        let file = Path::new("r.txt");
        let ids = |ids: &[&str]| ids.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            parse_relation(" [1, 2,3] ", file, 1).unwrap(),
            Some(Relation {
                ids: ids(&["1", "2", "3"]),
                weight: SQUARE_RELATION
            })
        );
        assert_eq!(
            parse_relation("(\"4\",5)", file, 1).unwrap(),
            Some(Relation {
                ids: ids(&["4", "5"]),
                weight: ROUND_RELATION
            })
        );
        assert_eq!(parse_relation("   ", file, 1).unwrap(), None);
        assert!(parse_relation("1, 2", file, 3)
            .unwrap_err()
            .to_string()
            .starts_with("r.txt:3: \"1, 2\": a relation is a list of ids in [...] or (...)"));
        assert!(parse_relation("[1]", file, 1)
            .unwrap_err()
            .to_string()
            .contains("at least two"));
        assert!(parse_relation("[1, 2)", file, 1).is_err());
    }

    #[test]
    fn groups_parse_in_numeric_id_order() {
        let file = Path::new("data.json");
        let text = r#"{"10": {"pt_im": [[1, 2, 3]]}, "2": {"pt_im": [[4.5, 5, 1], [0, 0, 0]], "other": 1}}"#;
        let groups = parse_groups(text, file).unwrap();
        let ids: Vec<&str> = groups.iter().map(|g| g.id.as_str()).collect();
        assert_eq!(ids, ["2", "10"]);
        assert_eq!(groups[0].points, [[4.5, 5.0, 1.0], [0.0, 0.0, 0.0]]);
        assert_eq!(groups[1].name, None);
        let error = |text: &str| parse_groups(text, file).unwrap_err().to_string();
        assert!(error(r#"{"1": {"pt": []}}"#).contains("pt_im"));
        assert!(error(r#"{"1": {"pt_im": [[1, 2]]}}"#).contains("[x, y, r]"));
        assert!(error("[1").starts_with("data.json: bad JSON"));
    }

    #[test]
    fn images_are_found_by_name_in_one_extension_order() {
        let dir = tempfile::tempdir().unwrap();
        let images = dir.path().join("images");
        std::fs::create_dir_all(&images).unwrap();
        for file in ["a.png", "a.jpg", "b.PNG", "c.txt", "d.Jpeg"] {
            std::fs::write(images.join(file), b"").unwrap();
        }
        assert_eq!(find_image(dir.path(), "a"), Some(images.join("a.jpg")));
        assert_eq!(find_image(dir.path(), "b"), Some(images.join("b.PNG")));
        assert_eq!(find_image(dir.path(), "c"), None);
        let listed = list_images(dir.path()).unwrap();
        let names: Vec<&str> = listed.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            ["a", "b"],
            "one entry a name, as find_image reads it"
        );
    }
}
