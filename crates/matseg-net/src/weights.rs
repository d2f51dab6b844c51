//! Copying named tensors into a net's variables: imported weights
//! (`matseg-weights` tensors, e.g. torchvision's ImageNet MobileNetV2) and
//! our own checkpoints alike.

use crate::NetError;
use tch::{nn, Tensor};

/// Copies into every variable of `vs` under `prefix` (a path such as
/// `"encoder"`, or `""` for all) the tensor `lookup` gives for its name
/// without the prefix; in name order, so the first problem reported is
/// always the same. Every such variable must be found, with its shape.
/// Returns how many were copied.
fn copy_by_name(
    vs: &nn::VarStore,
    prefix: &str,
    lookup: impl Fn(&str) -> Option<Result<Tensor, String>>,
) -> Result<usize, String> {
    let strip = if prefix.is_empty() {
        String::new()
    } else {
        format!("{prefix}.")
    };
    let mut variables: Vec<(String, Tensor)> = vs.variables().into_iter().collect();
    variables.sort_by(|a, b| a.0.cmp(&b.0));
    let mut copied = 0;
    for (name, mut variable) in variables {
        let Some(key) = name.strip_prefix(&strip) else {
            continue;
        };
        let source = lookup(key).ok_or_else(|| format!("no parameter {key}"))??;
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
    Ok(copied)
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
    copy_by_name(vs, prefix, |key| {
        tensors.iter().find(|t| t.name == key).map(float_tensor)
    })
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
    let variables = vs.variables();
    let kept = variables
        .keys()
        .filter(|name| name.starts_with(new_part) && !tensors.iter().any(|t| &t.name == *name))
        .count();
    let copied = copy_by_name(vs, "", |key| match tensors.iter().find(|t| t.name == key) {
        Some(tensor) => Some(float_tensor(tensor)),
        None if key.starts_with(new_part) => Some(Ok(variables[key].shallow_clone())),
        None => None,
    })
    .map_err(|message| NetError::File {
        file: source.to_string(),
        message,
    })?;
    Ok((copied - kept, kept))
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
pub fn load_tensors(vs: &nn::VarStore, named: &[(String, Tensor)]) -> Result<(), String> {
    copy_by_name(vs, "", |key| {
        named
            .iter()
            .find(|(n, _)| n == key)
            .map(|(_, t)| Ok(t.shallow_clone()))
    })
    .map(|_| ())
    .map_err(|e| format!("{e}: a checkpoint of another net"))
}
