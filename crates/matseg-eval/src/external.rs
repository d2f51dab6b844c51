//! Models matseg did not train, scored from their outputs: arrays of
//! descriptor or similarity maps, from files in a folder (`matseg eval
//! points|masks|clicks --maps DIR`) or handed over by Python
//! (`matseg.evaluate`). Both go through [`answer_from_array`], so a map is
//! checked, resized and compared the same way whichever way it came.
//!
//! A folder holds one file per benchmark photo, `NAME.npy` or
//! `NAME.safetensors` (one tensor), and optionally `maps.json`:
//!
//! ```text
//! {"name": "dinov2-vits14", "kind": "descriptors", "comparison": "cosine"}
//! ```
//!
//! `kind` is `descriptors` (the default: an `(h, w, d)` map at any size,
//! resized bilinearly to the scored photo; `comparison` is `cosine`, the
//! default, or `euclidean`) or `similarity` (a `(k, h, w)` map per point
//! the protocol asks about, in the order `matseg eval maps-template`
//! lists them). `name` defaults to the folder's name.

use crate::model::{Answer, Question, ScoredModel, Values};
use crate::points::BenchError;
use matseg_query::descriptor::{resize_channels, Comparison, DescriptorMap};
use matseg_weights::{read_npy, read_safetensors, DType, Tensor};
use serde::Deserialize;
use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// A `kind` or `comparison` of maps that is not known.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MapKindError(String);

/// What a model's arrays are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// `(h, w, d)` descriptor maps, compared as said.
    Descriptors(Comparison),
    /// `(k, h, w)` similarity maps, one per asked point.
    Similarity,
}

impl MapKind {
    /// The kind named by `kind` (`descriptors`, `similarity`) and
    /// `comparison` (`cosine`, `euclidean`; descriptors only).
    pub fn parse(kind: Option<&str>, comparison: Option<&str>) -> Result<Self, MapKindError> {
        let comparison = match comparison {
            None | Some("cosine") => Comparison::Cosine,
            Some("euclidean") => Comparison::NegativeEuclidean,
            Some(other) => {
                return Err(MapKindError(format!(
                    "comparison \"{other}\": give \"cosine\" or \"euclidean\""
                )))
            }
        };
        match kind {
            None | Some("descriptors") => Ok(MapKind::Descriptors(comparison)),
            Some("similarity") => Ok(MapKind::Similarity),
            Some(other) => Err(MapKindError(format!(
                "kind \"{other}\": give \"descriptors\" or \"similarity\""
            ))),
        }
    }
}

/// `values` of `shape`, a model's answer about `question` coming from
/// `source` (a file, or the model's name), checked and resized to the
/// question's photo: `(h, w, d)` descriptors or `(k, h, w)` similarity maps
/// (`k` the asked points), finite values only.
pub fn answer_from_array(
    values: Values,
    shape: &[usize],
    kind: MapKind,
    question: &Question,
    source: &Path,
) -> Result<Answer, BenchError> {
    let (width, height) = (
        question.pixels.width() as usize,
        question.pixels.height() as usize,
    );
    Ok(match kind {
        MapKind::Descriptors(comparison) => {
            let (h, w, dim) = checked(&values, shape, question, source, DESCRIPTORS)?;
            Answer::Grid {
                values,
                width: w,
                height: h,
                dim,
                photo: (width, height),
                comparison,
            }
        }
        MapKind::Similarity => {
            let asked = question.points.len();
            let wanted = format!("({asked}, h, w): a similarity map per asked point");
            let (k, h, w) = checked(&values, shape, question, source, &wanted)?;
            if k != asked {
                return Err(wrong_shape(shape, question, source, &wanted));
            }
            Answer::Similarity {
                maps: values
                    .chunks_exact(h * w)
                    .map(|map| resize_channels(Cow::Borrowed(map), (w, h), 1, (width, height)))
                    .collect(),
                width,
                height,
            }
        }
    })
}

/// What a descriptor answer's shape must be.
const DESCRIPTORS: &str = "(h, w, d) descriptors";

/// `values` of `shape` `(h, w, d)`, a model's descriptors of `question`'s
/// photo coming from `source`, checked (finite, no side empty) and kept at
/// their own size.
pub fn descriptor_grid(
    values: Values,
    shape: &[usize],
    question: &Question,
    source: &Path,
) -> Result<DescriptorMap, BenchError> {
    let (height, width, dim) = checked(&values, shape, question, source, DESCRIPTORS)?;
    Ok(DescriptorMap {
        width,
        height,
        dim,
        data: values.into_vec(),
    })
}

/// The three sides of `shape`, checked against `values` (as many, all
/// finite) and none of them 0.
fn checked(
    values: &[f32],
    shape: &[usize],
    question: &Question,
    source: &Path,
    wanted: &str,
) -> Result<(usize, usize, usize), BenchError> {
    let fail = |m: String| BenchError::new(source, None, m);
    let &[a, b, c] = shape else {
        return Err(wrong_shape(shape, question, source, wanted));
    };
    if values.len() != a * b * c {
        return Err(fail(format!("{} values for shape {shape:?}", values.len())));
    }
    if a == 0 || b == 0 || c == 0 {
        return Err(wrong_shape(shape, question, source, wanted));
    }
    if let Some(i) = first_not_finite(values) {
        return Err(fail(format!(
            "value {} at index {i} for photo {}: every value must be finite",
            values[i], question.name
        )));
    }
    Ok((a, b, c))
}

/// The index of the first value that is NaN or infinite: checked a block
/// at a time without stopping inside one (which vectorises), then looked
/// for in the block that has one.
fn first_not_finite(values: &[f32]) -> Option<usize> {
    const BLOCK: usize = 4096;
    values.chunks(BLOCK).enumerate().find_map(|(b, block)| {
        let finite = block.iter().fold(true, |all, v| all & v.is_finite());
        match finite {
            true => None,
            false => block
                .iter()
                .position(|v| !v.is_finite())
                .map(|i| b * BLOCK + i),
        }
    })
}

/// The error for an answer of `shape` where `wanted` was expected.
fn wrong_shape(shape: &[usize], question: &Question, source: &Path, wanted: &str) -> BenchError {
    let (width, height) = question.pixels.dimensions();
    BenchError::new(
        source,
        None,
        format!(
            "shape {shape:?} for photo {} ({width}x{height}): expected {wanted}",
            question.name
        ),
    )
}

/// `maps.json` of a map folder.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FolderSettings {
    name: Option<String>,
    kind: Option<String>,
    comparison: Option<String>,
}

/// A folder of precomputed maps, one file per benchmark photo, as a
/// scored model.
pub struct MapFolder {
    dir: PathBuf,
    name: String,
    kind: MapKind,
}

/// The file that names the folder's model and what its maps are.
pub const SETTINGS_FILE: &str = "maps.json";

impl MapFolder {
    /// Opens `dir`, reading its `maps.json` when there is one.
    pub fn open(dir: &Path) -> Result<Self, BenchError> {
        if !dir.is_dir() {
            return Err(BenchError::new(dir, None, "not a folder of maps"));
        }
        let settings_path = dir.join(SETTINGS_FILE);
        let settings = match std::fs::read(&settings_path) {
            Ok(bytes) => serde_json::from_slice::<FolderSettings>(&bytes).map_err(|e| {
                BenchError::new(&settings_path, None, format!("not valid settings: {e}"))
            })?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => FolderSettings {
                name: None,
                kind: None,
                comparison: None,
            },
            Err(e) => {
                return Err(BenchError::new(
                    &settings_path,
                    None,
                    format!("cannot read: {e}"),
                ))
            }
        };
        let kind = MapKind::parse(settings.kind.as_deref(), settings.comparison.as_deref())
            .map_err(|m| BenchError::new(&settings_path, None, m.to_string()))?;
        let name = settings.name.unwrap_or_else(|| {
            std::fs::canonicalize(dir)
                .ok()
                .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
                .unwrap_or_else(|| "maps".into())
        });
        Ok(Self {
            dir: dir.to_path_buf(),
            name,
            kind,
        })
    }

    /// What its maps are.
    pub fn kind(&self) -> MapKind {
        self.kind
    }

    /// The array of photo `name`: `NAME.npy` or `NAME.safetensors`.
    fn read(&self, name: &str) -> Result<(PathBuf, Tensor), BenchError> {
        let npy = self.dir.join(format!("{name}.npy"));
        let safetensors = self.dir.join(format!("{name}.safetensors"));
        let (path, tensor) = if npy.is_file() {
            let bytes = read_bytes(&npy)?;
            (npy.clone(), read_npy(&bytes, &npy.display().to_string()))
        } else if safetensors.is_file() {
            let bytes = read_bytes(&safetensors)?;
            let tensors = read_safetensors(&bytes, &safetensors.display().to_string());
            let one = tensors.and_then(|mut t| match t.len() {
                1 => Ok(t.remove(0)),
                n => Err(matseg_weights::WeightsError::new(
                    &safetensors.display().to_string(),
                    format!("holds {n} tensors; a map file holds one"),
                )),
            });
            (safetensors.clone(), one)
        } else {
            return Err(BenchError::new(
                &npy,
                None,
                format!(
                    "missing: the maps of photo {name} are {name}.npy or {name}.safetensors in {}",
                    self.dir.display()
                ),
            ));
        };
        let tensor = tensor.map_err(|e| BenchError::new(&path, None, e.message))?;
        Ok((path, tensor))
    }
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, BenchError> {
    std::fs::read(path).map_err(|e| BenchError::new(path, None, format!("cannot read: {e}")))
}

/// A tensor's elements as `f32`: float32 as they are, float16 widened,
/// float64 rounded; other types are refused.
pub fn float_elements(tensor: &Tensor) -> Option<Vec<f32>> {
    match tensor.dtype {
        DType::F64 => Some(
            tensor
                .data
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
                .collect(),
        ),
        _ => tensor.float_values(),
    }
}

impl ScoredModel for MapFolder {
    fn name(&self) -> &str {
        &self.name
    }

    fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
        let (path, tensor) = self.read(question.name)?;
        let values = float_elements(&tensor).ok_or_else(|| {
            BenchError::new(
                &path,
                None,
                format!(
                    "element type {:?}: give float32, float16 or float64 maps",
                    tensor.dtype
                ),
            )
        })?;
        answer_from_array(
            Values::Owned(values),
            &tensor.shape,
            self.kind,
            question,
            &path,
        )
    }
}
