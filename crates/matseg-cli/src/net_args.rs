//! The device argument the net commands share (`train`, `segment`,
//! `eval`, `bench-net`).

use anyhow::{bail, Result};
use tch::Device;

/// The device named on the command line.
pub fn parse_device(name: &str) -> Result<Device> {
    match name {
        "cpu" => Ok(Device::Cpu),
        "cuda" if !cfg!(feature = "cuda") => bail!(
            "--device cuda: this matseg was built without CUDA; build it with `--features cuda` (docs/gpu.md)"
        ),
        "cuda" if tch::Cuda::is_available() => Ok(Device::Cuda(0)),
        "cuda" => bail!("--device cuda: libtorch sees no CUDA device here"),
        other => bail!("--device {other}: expected cpu or cuda"),
    }
}
