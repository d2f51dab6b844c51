//! The safetensors format: an 8-byte little-endian header length, a JSON
//! header (`{"NAME": {"dtype", "shape", "data_offsets": [begin, end]}}`,
//! plus `__metadata__`), then the tensors' bytes.

use crate::{DType, Tensor, WeightsError};
use serde_json::{json, Map, Value};

/// The bytes of a safetensors file holding `tensors` (in the given order)
/// and string `metadata`.
pub fn write_safetensors(tensors: &[Tensor], metadata: &[(&str, &str)]) -> Vec<u8> {
    let mut header = Map::new();
    if !metadata.is_empty() {
        let meta: Map<String, Value> = metadata
            .iter()
            .map(|(k, v)| (k.to_string(), json!(v)))
            .collect();
        header.insert("__metadata__".into(), Value::Object(meta));
    }
    let mut offset = 0usize;
    for t in tensors {
        header.insert(
            t.name.clone(),
            json!({
                "dtype": t.dtype.safetensors_name(),
                "shape": t.shape,
                "data_offsets": [offset, offset + t.data.len()],
            }),
        );
        offset += t.data.len();
    }
    let mut text = serde_json::to_string(&Value::Object(header)).expect("JSON");
    // Pad the header with spaces so the data starts 8-byte aligned.
    while !(8 + text.len()).is_multiple_of(8) {
        text.push(' ');
    }
    let mut out = Vec::with_capacity(8 + text.len() + offset);
    out.extend_from_slice(&(text.len() as u64).to_le_bytes());
    out.extend_from_slice(text.as_bytes());
    for t in tensors {
        out.extend_from_slice(&t.data);
    }
    out
}

/// The tensors of a safetensors file, in data order. `name` is the file,
/// for messages.
pub fn read_safetensors(bytes: &[u8], name: &str) -> Result<Vec<Tensor>, WeightsError> {
    let fail = |m: String| WeightsError::new(name, m);
    let (header, data) = header(bytes, name)?;
    let mut tensors = Vec::new();
    for (key, entry) in header.iter().filter(|(k, _)| *k != "__metadata__") {
        let bad = || fail(format!("bad safetensors entry {key}"));
        let dtype = entry["dtype"]
            .as_str()
            .and_then(DType::from_safetensors_name)
            .ok_or_else(bad)?;
        let shape: Vec<usize> = entry["shape"]
            .as_array()
            .ok_or_else(bad)?
            .iter()
            .map(|v| v.as_u64().map(|v| v as usize))
            .collect::<Option<_>>()
            .ok_or_else(bad)?;
        let offsets = entry["data_offsets"].as_array().ok_or_else(bad)?;
        let (begin, end) = match offsets.as_slice() {
            [b, e] => (
                b.as_u64().ok_or_else(bad)? as usize,
                e.as_u64().ok_or_else(bad)? as usize,
            ),
            _ => return Err(bad()),
        };
        // The shape's byte count, checked: a shape whose product overflows
        // matches no data.
        let bytes = shape
            .iter()
            .try_fold(dtype.size(), |n, &d| n.checked_mul(d));
        if end < begin || end > data.len() || Some(end - begin) != bytes {
            return Err(fail(format!(
                "{key}: data offsets do not match its shape or the file"
            )));
        }
        tensors.push((
            begin,
            Tensor {
                name: key.clone(),
                dtype,
                shape,
                data: data[begin..end].to_vec(),
            },
        ));
    }
    tensors.sort_by_key(|(begin, _)| *begin);
    Ok(tensors.into_iter().map(|(_, t)| t).collect())
}

/// The string metadata (`__metadata__`) of a safetensors file, in header
/// order; empty when it has none. `name` is the file, for messages.
pub fn read_safetensors_metadata(
    bytes: &[u8],
    name: &str,
) -> Result<Vec<(String, String)>, WeightsError> {
    let (header, _) = header(bytes, name)?;
    let Some(meta) = header.get("__metadata__") else {
        return Ok(Vec::new());
    };
    let bad = || WeightsError::new(name, "bad safetensors metadata: not strings");
    meta.as_object()
        .ok_or_else(bad)?
        .iter()
        .map(|(k, v)| Ok((k.clone(), v.as_str().ok_or_else(bad)?.to_string())))
        .collect()
}

/// The parsed JSON header of a safetensors file and the data after it.
fn header<'a>(bytes: &'a [u8], name: &str) -> Result<(Map<String, Value>, &'a [u8]), WeightsError> {
    let fail = |m: String| WeightsError::new(name, m);
    let len = bytes
        .get(..8)
        .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize)
        .ok_or_else(|| fail("truncated safetensors header".into()))?;
    // A length past the end (however large) is a truncated header.
    let (text, data) = bytes[8..]
        .split_at_checked(len)
        .ok_or_else(|| fail("truncated safetensors header".into()))?;
    let header =
        serde_json::from_slice(text).map_err(|e| fail(format!("bad safetensors header: {e}")))?;
    Ok((header, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Headers whose numbers lie, found by the property tests: a length
    /// that overflows the offset arithmetic, and a shape whose byte count
    /// overflows.
    #[test]
    fn lengths_and_shapes_that_overflow_are_errors() {
        let err = read_safetensors(&u64::MAX.to_le_bytes(), "long").unwrap_err();
        assert_eq!(err.to_string(), "long: truncated safetensors header");
        let header = br#"{"":{"data_offsets":[0,0],"dtype":"F32","shape":[4611686018427387904]}}"#;
        let mut file = (header.len() as u64).to_le_bytes().to_vec();
        file.extend(header);
        let err = read_safetensors(&file, "huge").unwrap_err();
        assert!(
            err.to_string().contains("data offsets do not match"),
            "{err}"
        );
    }
}
