//! The device argument the net commands share (`train`, `segment`,
//! `eval`, `bench-net`).

use anyhow::{anyhow, bail, Result};
use matseg_image::device::ComputeDevice;

/// The nets `matseg eval` scores when none is named: the shipped model,
/// or none in a build without the net.
#[cfg(feature = "infer")]
pub const DEFAULT_NETS: &str = "default";
/// The nets `matseg eval` scores when none is named: the shipped model,
/// or none in a build without the net.
#[cfg(not(feature = "infer"))]
pub const DEFAULT_NETS: &str = "none";

/// The device named on the command line (`cpu`, `cuda`, `cuda:N`), refused
/// when this build or this machine cannot run the net there.
pub fn parse_device(name: &str) -> Result<ComputeDevice> {
    let device: ComputeDevice = name.parse().map_err(|e| anyhow!("--device {e}"))?;
    if let ComputeDevice::Cuda(index) = device {
        check_cuda(name, index)?;
    }
    Ok(device)
}

/// Whether libtorch sees CUDA GPU `index`.
#[cfg(feature = "cuda")]
fn check_cuda(name: &str, index: usize) -> Result<()> {
    if index >= tch::Cuda::device_count().max(0) as usize {
        bail!("--device {name}: libtorch sees no CUDA device {index} here");
    }
    Ok(())
}

/// A build without CUDA runs on no GPU.
#[cfg(not(feature = "cuda"))]
fn check_cuda(name: &str, _index: usize) -> Result<()> {
    bail!(
        "--device {name}: this matseg was built without CUDA; build it with `--features cuda` (docs/gpu.md)"
    )
}
