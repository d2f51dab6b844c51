//! Where a model runs, named without the tensor library: the front ends and
//! the pipeline pass a [`ComputeDevice`], and only the net maps it to its
//! backend's device.

use std::fmt;
use std::str::FromStr;

/// A processor a model can run on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ComputeDevice {
    /// The CPU (every build).
    #[default]
    Cpu,
    /// The CUDA GPU of this index.
    Cuda(usize),
}

impl ComputeDevice {
    /// Whether this is a CUDA GPU.
    pub fn is_cuda(self) -> bool {
        matches!(self, Self::Cuda(_))
    }
}

impl fmt::Display for ComputeDevice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Cpu => f.write_str("cpu"),
            Self::Cuda(index) => write!(f, "cuda:{index}"),
        }
    }
}

/// A device name that is not `cpu`, `cuda` or `cuda:N`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}: expected cpu, cuda or cuda:N")]
pub struct UnknownDevice(pub String);

impl FromStr for ComputeDevice {
    type Err = UnknownDevice;

    /// `cpu`, `cuda` (the first GPU) or `cuda:N`.
    fn from_str(name: &str) -> Result<Self, UnknownDevice> {
        match name {
            "cpu" => Ok(Self::Cpu),
            "cuda" => Ok(Self::Cuda(0)),
            _ => name
                .strip_prefix("cuda:")
                .and_then(|index| index.parse().ok())
                .map(Self::Cuda)
                .ok_or_else(|| UnknownDevice(name.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_others_are_refused() {
        for device in [
            ComputeDevice::Cpu,
            ComputeDevice::Cuda(0),
            ComputeDevice::Cuda(3),
        ] {
            assert_eq!(device.to_string().parse::<ComputeDevice>(), Ok(device));
        }
        assert_eq!("cuda".parse::<ComputeDevice>(), Ok(ComputeDevice::Cuda(0)));
        for bad in ["gpu", "cuda:", "cuda:x", "CPU", ""] {
            let e = bad.parse::<ComputeDevice>().unwrap_err();
            assert_eq!(
                e.to_string(),
                format!("{bad}: expected cpu, cuda or cuda:N")
            );
        }
    }
}
