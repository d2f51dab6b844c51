//! Known architectures: the parameters a checkpoint of each must have, so
//! that importing the wrong file is an error instead of a silent mismatch.

use crate::Tensor;

/// A checkpoint that is not of the architecture it was checked against.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("not a {arch} checkpoint: {problem}")]
pub struct ArchMismatch {
    /// The architecture's name.
    pub arch: &'static str,
    /// The first missing or misshapen parameter.
    pub problem: String,
}

/// Architectures whose checkpoints can be checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arch {
    /// torchvision's MobileNetV2 (ImageNet classifier, 3.5 M parameters).
    MobilenetV2,
}

impl Arch {
    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Arch::MobilenetV2 => "mobilenet-v2",
        }
    }

    /// Parameters that must be present, with their shapes.
    fn required(self) -> &'static [(&'static str, &'static [usize])] {
        match self {
            Arch::MobilenetV2 => &[
                ("features.0.0.weight", &[32, 3, 3, 3]),
                ("features.1.conv.0.0.weight", &[32, 1, 3, 3]),
                ("features.18.0.weight", &[1280, 320, 1, 1]),
                ("classifier.1.weight", &[1000, 1280]),
                ("classifier.1.bias", &[1000]),
            ],
        }
    }

    /// Checks that `tensors` hold this architecture's parameters; the error
    /// names the first missing or misshapen one.
    pub fn check(self, tensors: &[Tensor]) -> Result<(), ArchMismatch> {
        for (name, shape) in self.required() {
            match tensors.iter().find(|t| t.name == *name) {
                None => {
                    return Err(ArchMismatch {
                        arch: self.name(),
                        problem: format!("no parameter {name}"),
                    })
                }
                Some(t) if t.shape != *shape => {
                    return Err(ArchMismatch {
                        arch: self.name(),
                        problem: format!("{name} has shape {:?}, expected {shape:?}", t.shape),
                    })
                }
                Some(_) => {}
            }
        }
        Ok(())
    }
}
