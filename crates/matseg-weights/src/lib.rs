//! Network weights without Python or libtorch: PyTorch checkpoints (the
//! legacy format the registry-shipped ImageNet weights use, and the zip
//! format) read into named tensors, safetensors written and read, and
//! NumPy `.npy` arrays.

#![warn(missing_docs)]

pub mod arch;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod npy;
pub mod pickle;
pub mod safetensors;
pub mod torch;
pub mod zip;

pub use arch::Arch;
pub use npy::{read_npy, write_npy_f32};
pub use safetensors::{read_safetensors, read_safetensors_metadata, write_safetensors};
pub use torch::read_checkpoint;

/// Element types of tensors in checkpoints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DType {
    /// 32-bit float.
    F32,
    /// 64-bit float.
    F64,
    /// 16-bit float.
    F16,
    /// bfloat16.
    BF16,
    /// 64-bit integer.
    I64,
    /// 32-bit integer.
    I32,
    /// 16-bit integer.
    I16,
    /// 8-bit integer.
    I8,
    /// 8-bit unsigned integer.
    U8,
    /// Boolean (one byte).
    Bool,
}

impl DType {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            DType::F64 | DType::I64 => 8,
            DType::F32 | DType::I32 => 4,
            DType::F16 | DType::BF16 | DType::I16 => 2,
            DType::I8 | DType::U8 | DType::Bool => 1,
        }
    }

    /// The type of a PyTorch storage class (`FloatStorage`, ...).
    pub fn from_storage(class: &str) -> Option<Self> {
        Some(match class {
            "FloatStorage" => DType::F32,
            "DoubleStorage" => DType::F64,
            "HalfStorage" => DType::F16,
            "BFloat16Storage" => DType::BF16,
            "LongStorage" => DType::I64,
            "IntStorage" => DType::I32,
            "ShortStorage" => DType::I16,
            "CharStorage" => DType::I8,
            "ByteStorage" => DType::U8,
            "BoolStorage" => DType::Bool,
            _ => return None,
        })
    }

    /// The safetensors name (`F32`, ...).
    pub fn safetensors_name(self) -> &'static str {
        match self {
            DType::F32 => "F32",
            DType::F64 => "F64",
            DType::F16 => "F16",
            DType::BF16 => "BF16",
            DType::I64 => "I64",
            DType::I32 => "I32",
            DType::I16 => "I16",
            DType::I8 => "I8",
            DType::U8 => "U8",
            DType::Bool => "BOOL",
        }
    }

    /// Every type, in the order safetensors lists them.
    pub const ALL: [DType; 10] = [
        DType::F32,
        DType::F64,
        DType::F16,
        DType::BF16,
        DType::I64,
        DType::I32,
        DType::I16,
        DType::I8,
        DType::U8,
        DType::Bool,
    ];

    /// The type named `name` in safetensors.
    pub fn from_safetensors_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|d| d.safetensors_name() == name)
    }
}

/// A named tensor: row-major, little-endian element bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Parameter name (`features.0.0.weight`, ...).
    pub name: String,
    /// Element type.
    pub dtype: DType,
    /// Dimensions (empty for a scalar).
    pub shape: Vec<usize>,
    /// `product(shape) * dtype.size()` bytes.
    pub data: Vec<u8>,
}

impl Tensor {
    /// The elements as `f32`, for an `F32` tensor.
    pub fn f32_values(&self) -> Option<Vec<f32>> {
        (self.dtype == DType::F32).then(|| {
            self.data
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
                .collect()
        })
    }

    /// The elements as `f32`, for an `F32` tensor or, widened exactly, an
    /// `F16` one (the shipped weights are 16-bit).
    pub fn float_values(&self) -> Option<Vec<f32>> {
        match self.dtype {
            DType::F16 => Some(
                self.data
                    .chunks_exact(2)
                    .map(|b| f16_bits_to_f32(u16::from_le_bytes([b[0], b[1]])))
                    .collect(),
            ),
            _ => self.f32_values(),
        }
    }

    /// This tensor in 16-bit floats when it is an `F32` one (rounded to
    /// nearest, ties to even; too large values become infinite), else
    /// itself: half the bytes for shipped weights.
    pub fn to_f16(&self) -> Tensor {
        let Some(values) = self.f32_values() else {
            return self.clone();
        };
        Tensor {
            name: self.name.clone(),
            dtype: DType::F16,
            shape: self.shape.clone(),
            data: values
                .iter()
                .flat_map(|&v| f32_to_f16_bits(v).to_le_bytes())
                .collect(),
        }
    }
}

/// The value of IEEE binary16 `bits` (exact: every half is an `f32`).
pub fn f16_bits_to_f32(bits: u16) -> f32 {
    let sign = (u32::from(bits) & 0x8000) << 16;
    let exponent = u32::from(bits >> 10) & 0x1f;
    let mantissa = u32::from(bits) & 0x3ff;
    let magnitude = match exponent {
        // Zero and subnormals: mantissa * 2^-24, exact in f32.
        0 => (mantissa as f32 * f32::powi(2.0, -24)).to_bits(),
        // Infinity, and NaN with its payload in the top mantissa bits.
        0x1f => 0x7f80_0000 | (mantissa << 13),
        _ => ((exponent + 127 - 15) << 23) | (mantissa << 13),
    };
    f32::from_bits(sign | magnitude)
}

/// The IEEE binary16 bits nearest to `x` (ties to even).
pub fn f32_to_f16_bits(x: f32) -> u16 {
    let bits = x.to_bits();
    let sign = ((bits >> 16) & 0x8000) as u16;
    let exponent = ((bits >> 23) & 0xff) as i32;
    let mantissa = bits & 0x7f_ffff;
    if exponent == 0xff {
        // Infinity stays infinite; NaN stays NaN (quiet).
        return sign | 0x7c00 | if mantissa != 0 { 0x200 } else { 0 };
    }
    let e = exponent - 127 + 15;
    if e >= 0x1f {
        return sign | 0x7c00;
    }
    // The bits kept, and how many low bits are dropped and rounded away.
    let (kept, dropped) = if e <= 0 {
        if e < -10 {
            return sign;
        }
        // A subnormal half: the implicit one becomes explicit.
        ((mantissa | 0x80_0000), (14 - e) as u32)
    } else {
        (((e as u32) << 23) | mantissa, 13)
    };
    let mut half = kept >> dropped;
    let rest = kept & ((1 << dropped) - 1);
    let midpoint = 1 << (dropped - 1);
    if rest > midpoint || (rest == midpoint && half & 1 == 1) {
        // A carry out of the mantissa moves to the next exponent (or to
        // infinity), as it should.
        half += 1;
    }
    sign | half as u16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_round_to_the_nearest_binary16() {
        for (x, bits) in [
            (1.0f32, 0x3c00u16),
            (-2.0, 0xc000),
            (0.1, 0x2e66),
            (1.0 / 3.0, 0x3555),
            (65504.0, 0x7bff),
            (65520.0, 0x7c00),
            (f32::INFINITY, 0x7c00),
            (0.0, 0x0000),
            (-0.0, 0x8000),
            (5.960_464_5e-8, 0x0001),
            (6.097_555e-5, 0x03ff),
            (6.103_515_6e-5, 0x0400),
            (1e-9, 0x0000),
            // 1 + 2^-11 is halfway between 1 and the next half: ties to even.
            (1.000_488_3, 0x3c00),
            (1.001_464_8, 0x3c02),
        ] {
            assert_eq!(f32_to_f16_bits(x), bits, "{x}");
        }
        assert_eq!(f32_to_f16_bits(f32::NAN) & 0x7c00, 0x7c00);
        assert_ne!(f32_to_f16_bits(f32::NAN) & 0x3ff, 0);
    }

    #[test]
    fn every_half_widens_to_the_float_it_rounds_from() {
        for bits in 0..=u16::MAX {
            let x = f16_bits_to_f32(bits);
            if x.is_nan() {
                assert_eq!(bits & 0x7c00, 0x7c00, "{bits:#06x}");
                assert_ne!(bits & 0x3ff, 0, "{bits:#06x}");
            } else {
                assert_eq!(f32_to_f16_bits(x), bits, "{bits:#06x} -> {x}");
            }
        }
        for (bits, x) in [
            (0x3c00u16, 1.0f32),
            (0xc000, -2.0),
            (0x0001, 5.960_464_5e-8),
        ] {
            assert_eq!(f16_bits_to_f32(bits), x);
        }
        assert_eq!(f16_bits_to_f32(0x8000).to_bits(), (-0.0f32).to_bits());
        assert_eq!(f16_bits_to_f32(0x7bff), 65504.0);
    }

    #[test]
    fn float_values_read_f32_and_f16_alike() {
        let t = Tensor {
            name: "w".into(),
            dtype: DType::F32,
            shape: vec![3],
            data: [0.5f32, -1.0, 0.1]
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect(),
        };
        let half = t.to_f16();
        assert_eq!(t.float_values().unwrap(), [0.5, -1.0, 0.1]);
        assert_eq!(half.float_values().unwrap(), [0.5, -1.0, 0.099_975_586]);
        assert_eq!(half.f32_values(), None);
    }

    #[test]
    fn only_f32_tensors_are_halved() {
        let t = Tensor {
            name: "w".into(),
            dtype: DType::F32,
            shape: vec![2],
            data: [1.0f32, -2.0]
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect(),
        };
        let h = t.to_f16();
        assert_eq!(
            (h.dtype, &h.shape, &h.data),
            (DType::F16, &t.shape, &vec![0x00, 0x3c, 0x00, 0xc0])
        );
        let counter = Tensor {
            name: "n".into(),
            dtype: DType::I64,
            shape: vec![],
            data: 7i64.to_le_bytes().to_vec(),
        };
        assert_eq!(counter.to_f16(), counter);
    }
}

/// A weights file problem: one line naming the file.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {message}")]
pub struct WeightsError {
    /// The file.
    pub file: String,
    /// What is wrong.
    pub message: String,
}

impl WeightsError {
    /// An error about `file`.
    pub fn new(file: &str, message: impl Into<String>) -> Self {
        Self {
            file: file.to_string(),
            message: message.into(),
        }
    }
}
