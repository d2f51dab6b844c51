//! Copying named tensors into a net's variables: imported weights
//! (`matseg-weights` tensors, e.g. torchvision's ImageNet MobileNetV2) and
//! our own checkpoints alike.

use crate::NetError;
use tch::{nn, Tensor};

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
    lookup: impl Fn(&str) -> Option<Result<Tensor, String>>,
) -> Result<(usize, usize), String> {
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
            None => return Err(format!("no parameter {key}")),
        };
        if source.size() != variable.size() {
            return Err(format!(
                "{key} has shape {:?}, the net expects {:?}",
                source.size(),
                variable.size()
            ));
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
    .map_err(|message| NetError::File {
        file: source.to_string(),
        message,
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
    .map_err(|message| NetError::File {
        file: source.to_string(),
        message,
    })
}

/// An imported tensor's values as a float tensor of its shape.
fn float_tensor(tensor: &matseg_weights::Tensor) -> Result<Tensor, String> {
    let shape: Vec<i64> = tensor.shape.iter().map(|&s| s as i64).collect();
    tensor
        .float_values()
        .map(|values| Tensor::from_slice(&values).view(shape.as_slice()))
        .ok_or_else(|| {
            format!(
                "{} is {:?}, not a 32- or 16-bit float",
                tensor.name, tensor.dtype
            )
        })
}

/// Copies a checkpoint's `named` tensors into all variables of `vs`; the
/// error says the checkpoint is of another net when one is missing or
/// misshapen.
pub(crate) fn load_tensors(vs: &nn::VarStore, named: &[(String, Tensor)]) -> Result<(), String> {
    copy_by_name(vs, "", None, |key| {
        named
            .iter()
            .find(|(n, _)| n == key)
            .map(|(_, t)| Ok(t.shallow_clone()))
    })
    .map(|_| ())
    .map_err(|e| format!("{e}: a checkpoint of another net"))
}
