//! PyTorch checkpoints (`torch.save` of a state dict) to named tensors, in
//! both on-disk formats:
//!
//! - legacy (before PyTorch 1.6, and what the registry-shipped ImageNet
//!   weights use): five pickles in a row (magic number, protocol version,
//!   system info, the object, the list of storage keys), then each storage
//!   as a little-endian `i64` element count and its raw bytes;
//! - zip: `ARCHIVE/data.pkl` holds the object, `ARCHIVE/data/KEY` each
//!   storage's raw bytes.
//!
//! In the object, a tensor is `torch._utils._rebuild_tensor_v2(storage,
//! offset, size, stride, ...)` and a storage a persistent id
//! `("storage", torch.FloatStorage, KEY, LOCATION, NUMEL)`.

use crate::pickle::{read_pickle, Value};
use crate::zip::ZipArchive;
use crate::{DType, Tensor, WeightsError};
use std::collections::HashMap;

/// The number PyTorch writes first in a legacy checkpoint.
const LEGACY_MAGIC: [u8; 10] = [0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19];

/// The tensors of a checkpoint file's bytes, in the state dict's order.
/// `name` is the file, for messages.
pub fn read_checkpoint(bytes: &[u8], name: &str) -> Result<Vec<Tensor>, WeightsError> {
    let fail = |m: String| WeightsError::new(name, m);
    if bytes.starts_with(b"PK\x03\x04") {
        let archive = ZipArchive::new(bytes).map_err(|e| fail(e.to_string()))?;
        let pickle_name = archive
            .names()
            .find(|n| n.ends_with("/data.pkl") || *n == "data.pkl")
            .ok_or_else(|| fail("zip checkpoint without data.pkl".into()))?
            .to_string();
        let prefix = pickle_name.trim_end_matches("data.pkl").to_string();
        let object = archive
            .read(&pickle_name)
            .map_err(|e| fail(e.to_string()))?;
        let (object, _) = read_pickle(&object).map_err(|e| fail(format!("data.pkl: {e}")))?;
        let storage = |key: &str| {
            archive
                .read(&format!("{prefix}data/{key}"))
                .map_err(|e| e.to_string())
        };
        tensors(&object, &|key| storage(key)).map_err(|e| fail(e.0))
    } else {
        read_legacy(bytes).map_err(|e| fail(e.0))
    }
}

/// What is wrong inside a checkpoint (the file itself is named by the
/// [`WeightsError`] it becomes).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct CheckpointProblem(String);

impl From<String> for CheckpointProblem {
    fn from(message: String) -> Self {
        Self(message)
    }
}

impl From<&str> for CheckpointProblem {
    fn from(message: &str) -> Self {
        Self(message.to_string())
    }
}

fn read_legacy(bytes: &[u8]) -> Result<Vec<Tensor>, CheckpointProblem> {
    let mut pos = 0;
    let mut next = |what: &str| -> Result<Value, String> {
        let (v, used) = read_pickle(&bytes[pos..]).map_err(|e| format!("{what}: {e}"))?;
        pos += used;
        Ok(v)
    };
    match next("magic number")? {
        Value::Bytes(b) if b == LEGACY_MAGIC => {}
        _ => return Err("not a PyTorch checkpoint (no magic number, not a zip)".into()),
    }
    let protocol = next("protocol version")?;
    if protocol.int() != Some(1001) {
        return Err(format!("unsupported legacy protocol {protocol:?}").into());
    }
    next("system info")?;
    let object = next("state dict")?;
    let keys = next("storage keys")?;
    let keys: Vec<String> = keys
        .items()
        .ok_or("storage keys are not a list")?
        .iter()
        .map(|k| {
            k.str()
                .map(str::to_string)
                .ok_or("a storage key is not a string")
        })
        .collect::<Result<_, _>>()?;
    // Each storage: its element count, then its bytes (element size from the
    // storage type, which the object names).
    let element_sizes = storage_types(&object)?;
    let mut storages: HashMap<String, Vec<u8>> = HashMap::new();
    for key in keys {
        let size = element_sizes
            .get(&key)
            .ok_or_else(|| format!("storage {key} is listed but never used"))?
            .size();
        let header = bytes
            .get(pos..pos + 8)
            .ok_or_else(|| format!("truncated before storage {key}"))?;
        let count = i64::from_le_bytes(header.try_into().expect("8 bytes"));
        let len = usize::try_from(count)
            .ok()
            .and_then(|count| count.checked_mul(size))
            .ok_or_else(|| format!("storage {key}: bad size {count}"))?;
        let left = bytes.len() - pos - 8;
        if len > left {
            return Err(format!("truncated: storage {key} needs {len} bytes, {left} left").into());
        }
        let data = &bytes[pos + 8..pos + 8 + len];
        storages.insert(key, data.to_vec());
        pos += 8 + len;
    }
    tensors(&object, &|key| {
        storages
            .get(key)
            .cloned()
            .ok_or_else(|| format!("storage {key} is missing"))
    })
}

/// A storage reference: its key and element type.
struct StorageRef {
    key: String,
    dtype: DType,
}

fn storage_ref(v: &Value) -> Result<StorageRef, CheckpointProblem> {
    let Value::Persistent(id) = v else {
        return Err("a tensor's storage is not a persistent id".into());
    };
    let items = id.items().ok_or("storage id is not a tuple")?;
    match items {
        [Value::Str(tag), Value::Global(_, class), Value::Str(key), ..] if tag == "storage" => {
            Ok(StorageRef {
                key: key.clone(),
                dtype: DType::from_storage(class)
                    .ok_or_else(|| format!("unsupported storage type {class}"))?,
            })
        }
        _ => Err(format!("unexpected storage id {items:?}").into()),
    }
}

/// Storage key to element type, for every tensor in `object`.
fn storage_types(object: &Value) -> Result<HashMap<String, DType>, CheckpointProblem> {
    let mut types = HashMap::new();
    for (_, tensor) in state_dict(object)? {
        let r = storage_ref(rebuild_args(tensor)?.storage)?;
        types.insert(r.key, r.dtype);
    }
    Ok(types)
}

/// The `(name, tensor call)` entries of a state dict: a plain dict or an
/// `OrderedDict` (possibly with its `_metadata` attached by `BUILD`).
fn state_dict(object: &Value) -> Result<Vec<(&str, &Value)>, CheckpointProblem> {
    let entries: &[(Value, Value)] = match object {
        Value::Dict(d) => d,
        Value::Build(inner, _) => return state_dict(inner),
        Value::Call(callable, args) if matches!(&**callable, Value::Global(m, n) if m == "collections" && n == "OrderedDict") => {
            match args.last() {
                Some(Value::Dict(d)) => d,
                _ => &[],
            }
        }
        _ => return Err("the checkpoint is not a state dict (a dict of tensors)".into()),
    };
    entries
        .iter()
        .map(|(k, v)| Ok((k.str().ok_or("a state dict key is not a string")?, v)))
        .collect()
}

/// The arguments of a `_rebuild_tensor_v2` call: a strided view of a storage.
struct TensorView<'a> {
    storage: &'a Value,
    offset: i64,
    shape: Vec<i64>,
    stride: Vec<i64>,
}

/// Reads a storage's bytes by key.
type StorageReader<'a> = dyn Fn(&str) -> Result<Vec<u8>, String> + 'a;

/// The view a `_rebuild_tensor_v2` call makes.
fn rebuild_args(tensor: &Value) -> Result<TensorView<'_>, CheckpointProblem> {
    let Value::Call(callable, args) = tensor else {
        return Err("a state dict value is not a tensor".into());
    };
    match (&**callable, args.as_slice()) {
        (Value::Global(m, n), [storage, offset, size, stride, ..])
            if m == "torch._utils" && n == "_rebuild_tensor_v2" =>
        {
            let ints = |v: &Value| -> Result<Vec<i64>, String> {
                v.items()
                    .ok_or("tensor size or stride is not a tuple")?
                    .iter()
                    .map(|i| {
                        i.int()
                            .ok_or_else(|| "a size or stride is not an integer".to_string())
                    })
                    .collect()
            };
            Ok(TensorView {
                storage,
                offset: offset.int().ok_or("tensor offset is not an integer")?,
                shape: ints(size)?,
                stride: ints(stride)?,
            })
        }
        (other, _) => Err(format!("unsupported tensor constructor {other:?}").into()),
    }
}

/// The number of elements of the view `shape`, `stride` at `offset` of a
/// storage of `elements` elements, once checked that every element lies in
/// the storage and that there are no more of them than it holds (a view
/// that repeats elements, such as an expanded one, could otherwise make a
/// tensor of any size out of a few bytes).
fn view_elements(
    shape: &[i64],
    stride: &[i64],
    offset: i64,
    elements: usize,
) -> Result<i64, CheckpointProblem> {
    if shape.len() != stride.len() || shape.iter().any(|&d| d < 0) {
        return Err(format!("size {shape:?} and stride {stride:?} make no view").into());
    }
    let too_many = || format!("a view of size {shape:?} has more elements than the storage");
    let count = shape
        .iter()
        .try_fold(1i64, |n, &d| n.checked_mul(d))
        .ok_or_else(too_many)?;
    if count == 0 {
        return Ok(0);
    }
    if !usize::try_from(count).is_ok_and(|count| count <= elements) {
        return Err(too_many().into());
    }
    // The first and last elements the view reaches (a reach that
    // overflows is past the end).
    let past_end = || {
        format!(
            "a view of offset {offset}, size {shape:?} and stride {stride:?} reads past the end"
        )
    };
    let (mut first, mut last) = (offset, offset);
    for (&d, &s) in shape.iter().zip(stride) {
        let reach = (d - 1).checked_mul(s).ok_or_else(past_end)?;
        let bound = if reach < 0 { &mut first } else { &mut last };
        *bound = bound.checked_add(reach).ok_or_else(past_end)?;
    }
    if first < 0 || !usize::try_from(last).is_ok_and(|last| last < elements) {
        return Err(past_end().into());
    }
    Ok(count)
}

/// Builds every tensor of the state dict, reading storages through `storage`
/// and copying strided views into contiguous row-major data.
fn tensors(object: &Value, storage: &StorageReader<'_>) -> Result<Vec<Tensor>, CheckpointProblem> {
    let mut cache: HashMap<String, Vec<u8>> = HashMap::new();
    let mut out = Vec::new();
    for (name, tensor) in state_dict(object)? {
        let TensorView {
            storage: storage_value,
            offset,
            shape,
            stride,
        } = rebuild_args(tensor).map_err(|e| format!("{name}: {e}"))?;
        let r = storage_ref(storage_value).map_err(|e| format!("{name}: {e}"))?;
        if !cache.contains_key(&r.key) {
            let data = storage(&r.key)?;
            cache.insert(r.key.clone(), data);
        }
        let data = &cache[&r.key];
        let size = r.dtype.size();
        let count = view_elements(&shape, &stride, offset, data.len() / size)
            .map_err(|e| format!("{name}: storage {}: {}", r.key, e.0))?;
        let mut bytes = Vec::with_capacity(count as usize * size);
        // Walk the elements in row-major order through the strides (every
        // one inside the storage, as checked).
        let mut index = vec![0i64; shape.len()];
        for _ in 0..count {
            let at = offset + index.iter().zip(&stride).map(|(i, s)| i * s).sum::<i64>();
            let start = usize::try_from(at).map_err(|_| format!("{name}: negative offset"))? * size;
            let element = data
                .get(start..start + size)
                .ok_or_else(|| format!("{name}: reads past the end of storage {}", r.key))?;
            bytes.extend_from_slice(element);
            for d in (0..shape.len()).rev() {
                index[d] += 1;
                if index[d] < shape[d] {
                    break;
                }
                index[d] = 0;
            }
        }
        out.push(Tensor {
            name: name.to_string(),
            dtype: r.dtype,
            shape: shape.iter().map(|&s| s as usize).collect(),
            data: bytes,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{legacy, zipped, Storage};

    /// Checkpoints found by the property tests: a view of 2^30 elements
    /// over an empty storage (as much was reserved: 4 GiB), a storage of
    /// 2^62 elements (its byte count overflowed), and views whose sizes
    /// or strides overflow, repeat elements or reach outside the storage.
    #[test]
    fn views_and_storages_that_lie_are_errors() {
        let empty = [Storage {
            key: "0",
            values: vec![],
        }];
        let err = read_checkpoint(&zipped(&empty, &[("w", 0, 0, vec![1 << 30], vec![])]), "z")
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "z: w: storage 0: size [1073741824] and stride [] make no view"
        );

        let three = [Storage {
            key: "0",
            values: vec![1.0, 2.0, 3.0],
        }];
        let mut file = legacy(&three, &[("w", 0, 0, vec![3], vec![1])]);
        let at = file.len() - 8 - 12;
        file[at..at + 8].copy_from_slice(&(1i64 << 62).to_le_bytes());
        let err = read_checkpoint(&file, "l").unwrap_err();
        assert_eq!(
            err.to_string(),
            "l: storage 0: bad size 4611686018427387904"
        );

        for (shape, stride, problem) in [
            (
                vec![i32::MAX, i32::MAX, i32::MAX],
                vec![1, 1, 1],
                "more elements",
            ),
            (vec![3, 2], vec![0, 1], "more elements"),
            (vec![2], vec![i32::MAX], "reads past the end"),
            (vec![2], vec![-1], "reads past the end"),
            (vec![-1], vec![1], "make no view"),
        ] {
            let views = [("w", 0, 0, shape, stride)];
            let err = read_checkpoint(&zipped(&three, &views), "z").unwrap_err();
            assert!(err.to_string().contains(problem), "{err}");
        }
        let views = [("w", 0, 2, vec![3], vec![-1])];
        let reversed = read_checkpoint(&zipped(&three, &views), "z").unwrap();
        assert_eq!(reversed[0].f32_values().unwrap(), [3.0, 2.0, 1.0]);
    }
}
