//! Network weights without Python or libtorch: PyTorch checkpoints (the
//! legacy format the registry-shipped ImageNet weights use, and the zip
//! format) read into named tensors, and safetensors written and read.

#![warn(missing_docs)]

pub mod arch;
pub mod fixtures;
pub mod pickle;
pub mod safetensors;
pub mod torch;
pub mod zip;

pub use arch::Arch;
pub use safetensors::{read_safetensors, write_safetensors};
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

    /// The type named `name` in safetensors.
    pub fn from_safetensors_name(name: &str) -> Option<Self> {
        [
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
        ]
        .into_iter()
        .find(|d| d.safetensors_name() == name)
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
