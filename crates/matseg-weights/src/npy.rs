//! NumPy's `.npy` files (format versions 1 to 3): one array, read into a
//! [`Tensor`] and written from `f32` values. Arrays from any language that
//! writes `.npy` reach matseg this way (precomputed descriptor and
//! similarity maps).
//!
//! Layout: the magic `\x93NUMPY`, the version (major, minor), the header's
//! length (2 bytes little-endian in version 1, 4 in later ones), the header
//! (a Python dict literal: `{'descr': '<f4', 'fortran_order': False,
//! 'shape': (480, 640, 16), }`) and the elements, row-major.

use crate::{DType, Tensor, WeightsError};

const MAGIC: &[u8] = b"\x93NUMPY";

/// The array of an `.npy` file, named `name` (the file, also for
/// messages). Little-endian (or byte-sized) numbers in C order; a
/// Fortran-ordered or big-endian array is refused with a message saying so.
pub fn read_npy(bytes: &[u8], name: &str) -> Result<Tensor, WeightsError> {
    let fail = |m: &str| WeightsError::new(name, m);
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err(fail("not a .npy file (no \\x93NUMPY magic)"));
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes")) as usize,
            12,
        ),
        v => return Err(fail(&format!(".npy format version {v} is not known"))),
    };
    let header = bytes
        .get(start..start.saturating_add(header_len))
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| fail("the .npy header is cut short or not text"))?;
    let descr =
        quoted_value(header, "descr").ok_or_else(|| fail("the .npy header has no 'descr'"))?;
    let dtype = dtype_of(descr).ok_or_else(|| {
        fail(&format!(
            "element type '{descr}' is not read: give little-endian float32, float16, float64, int or uint8 values"
        ))
    })?;
    if value_after(header, "fortran_order").is_some_and(|v| v.starts_with("True")) {
        return Err(fail(
            "the array is in Fortran order: save it C-contiguous (numpy.ascontiguousarray)",
        ));
    }
    let shape = shape_of(header).ok_or_else(|| fail("the .npy header has no readable 'shape'"))?;
    let data = &bytes[start + header_len..];
    let size = shape
        .iter()
        .try_fold(dtype.size(), |n, &d| n.checked_mul(d));
    if size != Some(data.len()) {
        return Err(fail(&format!(
            "shape {shape:?} of {descr} needs {} bytes of data, the file has {}",
            size.map_or("too many".into(), |s| s.to_string()),
            data.len()
        )));
    }
    Ok(Tensor {
        name: name.to_string(),
        dtype,
        shape,
        data: data.to_vec(),
    })
}

/// An `.npy` file (version 1) of `values` as little-endian float32 in C
/// order with `shape`.
pub fn write_npy_f32(values: &[f32], shape: &[usize]) -> Vec<u8> {
    assert_eq!(
        values.len(),
        shape.iter().product::<usize>(),
        "values fill the shape"
    );
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let shape = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // The magic, version, length and header end on a multiple of 64 bytes,
    // the header with a newline last, as NumPy writes it.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = MAGIC.to_vec();
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    out
}

/// The element type of a NumPy type string (`<f4`, `|u1`, ...).
fn dtype_of(descr: &str) -> Option<DType> {
    let (order, kind) = descr.split_at(1.min(descr.len()));
    let little = matches!(order, "<" | "|") || (order == "=" && cfg!(target_endian = "little"));
    if !little {
        return None;
    }
    Some(match kind {
        "f4" => DType::F32,
        "f8" => DType::F64,
        "f2" => DType::F16,
        "i8" => DType::I64,
        "i4" => DType::I32,
        "i2" => DType::I16,
        "i1" => DType::I8,
        "u1" => DType::U8,
        "b1" => DType::Bool,
        _ => return None,
    })
}

/// The text after `'key':` in the header, spaces skipped.
fn value_after<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{key}'"))? + key.len() + 2;
    Some(header[at..].trim_start().strip_prefix(':')?.trim_start())
}

/// The quoted string value of `key`.
fn quoted_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let value = value_after(header, key)?;
    let quote = value.chars().next().filter(|c| *c == '\'' || *c == '"')?;
    let rest = &value[1..];
    Some(&rest[..rest.find(quote)?])
}

/// The `shape` tuple: `()`, `(5,)`, `(480, 640, 16)`.
fn shape_of(header: &str) -> Option<Vec<usize>> {
    let value = value_after(header, "shape")?.strip_prefix('(')?;
    let inside = &value[..value.find(')')?];
    inside
        .split(',')
        .map(str::trim)
        .filter(|d| !d.is_empty())
        .map(|d| d.trim_end_matches('L').parse().ok())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_arrays_read_back_with_their_shape_and_values() {
        let values: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
        for shape in [vec![24], vec![4, 6], vec![2, 3, 4]] {
            let bytes = write_npy_f32(&values, &shape);
            assert_eq!(bytes.len() % 16, 0, "header padded to 64, then 24 floats");
            let t = read_npy(&bytes, "a.npy").unwrap();
            assert_eq!(t.shape, shape);
            assert_eq!(t.dtype, DType::F32);
            assert_eq!(t.f32_values().unwrap(), values);
        }
    }

    #[test]
    fn numpy_headers_of_other_types_and_versions_are_read() {
        // What numpy.save writes for np.arange(6, dtype='<f8').reshape(2, 3),
        // in format version 2, and for a uint8 scalar array.
        let mut v2 = MAGIC.to_vec();
        let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }      \n";
        v2.extend_from_slice(&[2, 0]);
        v2.extend_from_slice(&(header.len() as u32).to_le_bytes());
        v2.extend_from_slice(header.as_bytes());
        v2.extend((0..6).flat_map(|i| (i as f64).to_le_bytes()));
        let t = read_npy(&v2, "b.npy").unwrap();
        assert_eq!((t.dtype, t.shape.clone()), (DType::F64, vec![2, 3]));
        let mut scalar = MAGIC.to_vec();
        let header = "{'descr': '|u1', 'fortran_order': False, 'shape': (), }\n";
        scalar.extend_from_slice(&[1, 0]);
        scalar.extend_from_slice(&(header.len() as u16).to_le_bytes());
        scalar.extend_from_slice(header.as_bytes());
        scalar.push(7);
        let t = read_npy(&scalar, "c.npy").unwrap();
        assert_eq!(
            (t.dtype, t.shape.clone(), t.data.clone()),
            (DType::U8, vec![], vec![7])
        );
    }

    #[test]
    fn malformed_files_are_refused_with_a_message_naming_them() {
        let good = write_npy_f32(&[1.0, 2.0, 3.0, 4.0], &[2, 2]);
        let text = |bytes: &[u8]| read_npy(bytes, "m.npy").unwrap_err().to_string();
        assert!(
            text(b"PNG....").contains("not a .npy file"),
            "{}",
            text(b"PNG")
        );
        assert!(text(&good[..good.len() - 1]).contains("needs 16 bytes of data, the file has 15"));
        // The header with `from` replaced by `to` (of the same length).
        let swap = |from: &str, to: &str| {
            let mut bytes = good.clone();
            let at = bytes
                .windows(from.len())
                .position(|w| w == from.as_bytes())
                .unwrap();
            bytes[at..at + to.len()].copy_from_slice(to.as_bytes());
            bytes
        };
        for (from, to, says) in [
            ("<f4", ">f4", "element type '>f4'"),
            ("<f4", "<c8", "element type '<c8'"),
            ("False", "True ", "Fortran order"),
        ] {
            let message = read_npy(&swap(from, to), "m.npy").unwrap_err().to_string();
            assert!(
                message.starts_with("m.npy: ") && message.contains(says),
                "{message}"
            );
        }
    }
}
