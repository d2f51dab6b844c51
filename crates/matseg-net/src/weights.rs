//! Copying imported weights (`matseg-weights` tensors, e.g. torchvision's
//! ImageNet MobileNetV2) into a net's variables, by parameter name.

use crate::NetError;
use tch::{nn, Tensor};

/// Copies `tensors` into every variable of `vs` under `prefix` (a path such
/// as `"encoder"`, or `""` for all): the variable `prefix.NAME` takes the
/// tensor `NAME`. Every such variable must be present with the same shape;
/// tensors with no variable (a classifier, BatchNorm's
/// `num_batches_tracked`) are ignored. Returns how many were copied;
/// `source` names the file in errors.
pub fn load_named(
    vs: &nn::VarStore,
    prefix: &str,
    tensors: &[matseg_weights::Tensor],
    source: &str,
) -> Result<usize, NetError> {
    let error = |message: String| NetError::File {
        file: source.to_string(),
        message,
    };
    let strip = if prefix.is_empty() {
        String::new()
    } else {
        format!("{prefix}.")
    };
    let mut copied = 0;
    let mut variables: Vec<(String, Tensor)> = vs.variables().into_iter().collect();
    variables.sort_by(|a, b| a.0.cmp(&b.0));
    for (name, mut variable) in variables {
        let Some(key) = name.strip_prefix(&strip) else {
            continue;
        };
        let tensor = tensors
            .iter()
            .find(|t| t.name == key)
            .ok_or_else(|| error(format!("no parameter {key}")))?;
        let shape: Vec<i64> = tensor.shape.iter().map(|&s| s as i64).collect();
        if shape != variable.size() {
            return Err(error(format!(
                "{key} has shape {:?}, the net expects {:?}",
                tensor.shape,
                variable.size()
            )));
        }
        let values = tensor
            .f32_values()
            .ok_or_else(|| error(format!("{key} is {:?}, not 32-bit float", tensor.dtype)))?;
        let source = Tensor::from_slice(&values)
            .view(shape.as_slice())
            .to_device(variable.device());
        tch::no_grad(|| variable.copy_(&source));
        copied += 1;
    }
    Ok(copied)
}
