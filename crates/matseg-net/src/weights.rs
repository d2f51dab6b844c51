//! Copying named tensors into a net's variables: imported weights
//! (`matseg-weights` tensors, e.g. torchvision's ImageNet MobileNetV2) and
//! our own checkpoints alike.

use crate::NetError;
use tch::{nn, Tensor};

/// Saved tensors that do not fit the variables (or optimizer slots) they
/// are copied into.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TensorMismatch {
    /// A variable with no tensor of its name.
    #[error("no parameter {0}")]
    NoParameter(String),
    /// A tensor of another shape than its variable's.
    #[error("{name} has shape {found:?}, the net expects {expected:?}")]
    Shape {
        /// The tensor.
        name: String,
        /// Its shape.
        found: Vec<i64>,
        /// The variable's.
        expected: Vec<i64>,
    },
    /// A tensor of integers or another non-float type.
    #[error("{name} is {dtype}, not a 32- or 16-bit float")]
    NotFloat {
        /// The tensor.
        name: String,
        /// Its type.
        dtype: String,
    },
    /// A checkpoint whose tensors are another net's.
    #[error("{0}: a checkpoint of another net")]
    OtherNet(Box<TensorMismatch>),
    /// An optimizer slot the saved state lacks.
    #[error("optimizer state has no {0}")]
    NoOptimizerState(String),
    /// An optimizer slot saved with another shape.
    #[error("optimizer state {name} has shape {found:?}")]
    OptimizerShape {
        /// The slot.
        name: String,
        /// The saved shape.
        found: Vec<i64>,
    },
}

/// Copies into every variable of `vs` under `prefix` (a path such as
/// `"encoder"`, or `""` for all) the tensor `lookup` gives for its name
/// without the prefix; in name order, so the first problem reported is
/// always the same. Every such variable must be found, with its shape,
/// except those whose name starts with `fresh_part`, which keep their
/// values when `lookup` has none. Returns how many were copied and how
/// many kept.
fn copy_by_name(
    vs: &nn::VarStore,
    prefix: &str,
    fresh_part: Option<&str>,
    lookup: impl Fn(&str) -> Option<Result<Tensor, TensorMismatch>>,
) -> Result<(usize, usize), TensorMismatch> {
    let strip = if prefix.is_empty() {
        String::new()
    } else {
        format!("{prefix}.")
    };
    let mut variables: Vec<(String, Tensor)> = vs.variables().into_iter().collect();
    variables.sort_by(|a, b| a.0.cmp(&b.0));
    let (mut copied, mut kept) = (0, 0);
    for (name, mut variable) in variables {
        let Some(key) = name.strip_prefix(&strip) else {
            continue;
        };
        let source = match lookup(key) {
            Some(source) => source?,
            None if fresh_part.is_some_and(|part| key.starts_with(part)) => {
                kept += 1;
                continue;
            }
            None => return Err(TensorMismatch::NoParameter(key.to_string())),
        };
        if source.size() != variable.size() {
            return Err(TensorMismatch::Shape {
                name: key.to_string(),
                found: source.size(),
                expected: variable.size(),
            });
        }
        let source = source.to_device(variable.device());
        tch::no_grad(|| variable.copy_(&source));
        copied += 1;
    }
    Ok((copied, kept))
}

/// Copies imported `tensors` into every variable of `vs` under `prefix`:
/// the variable `prefix.NAME` takes the tensor `NAME`. Tensors with no
/// variable (a classifier, BatchNorm's `num_batches_tracked`) are ignored.
/// Returns how many were copied; `source` names the file in errors.
pub fn load_named(
    vs: &nn::VarStore,
    prefix: &str,
    tensors: &[matseg_weights::Tensor],
    source: &str,
) -> Result<usize, NetError> {
    copy_by_name(vs, prefix, None, |key| {
        tensors.iter().find(|t| t.name == key).map(float_tensor)
    })
    .map(|(copied, _)| copied)
    .map_err(|e| NetError::File {
        file: source.to_string(),
        message: e.to_string(),
    })
}

/// Copies a whole net's imported `tensors` (a run's weights file) into
/// every variable of `vs`, as [`load_named`] does, except that variables
/// under `new_part` (e.g. `colour.`) that the file lacks keep their initial
/// values: a net trained without that part continues with it. Returns how
/// many were copied and how many kept.
pub fn load_net_adding(
    vs: &nn::VarStore,
    tensors: &[matseg_weights::Tensor],
    new_part: &str,
    source: &str,
) -> Result<(usize, usize), NetError> {
    copy_by_name(vs, "", Some(new_part), |key| {
        tensors.iter().find(|t| t.name == key).map(float_tensor)
    })
    .map_err(|e| NetError::File {
        file: source.to_string(),
        message: e.to_string(),
    })
}

/// An imported tensor's values as a float tensor of its shape.
fn float_tensor(tensor: &matseg_weights::Tensor) -> Result<Tensor, TensorMismatch> {
    let shape: Vec<i64> = tensor.shape.iter().map(|&s| s as i64).collect();
    tensor
        .float_values()
        .map(|values| Tensor::from_slice(&values).view(shape.as_slice()))
        .ok_or_else(|| TensorMismatch::NotFloat {
            name: tensor.name.clone(),
            dtype: format!("{:?}", tensor.dtype),
        })
}

/// Copies a checkpoint's `named` tensors into all variables of `vs`; the
/// error says the checkpoint is of another net when one is missing or
/// misshapen.
pub(crate) fn load_tensors(
    vs: &nn::VarStore,
    named: &[(String, Tensor)],
) -> Result<(), TensorMismatch> {
    copy_by_name(vs, "", None, |key| {
        named
            .iter()
            .find(|(n, _)| n == key)
            .map(|(_, t)| Ok(t.shallow_clone()))
    })
    .map(|_| ())
    .map_err(|e| TensorMismatch::OtherNet(Box::new(e)))
}
