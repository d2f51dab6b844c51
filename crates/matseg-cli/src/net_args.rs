//! Arguments the net commands share (`train`, `segment`, `eval`,
//! `bench-net`): the device and the encoder preset.

use anyhow::{bail, Context, Result};
use matseg_net::{NetConfig, PRESETS};
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

/// The net preset named by `--encoder`.
pub fn preset(encoder: &str) -> Result<NetConfig> {
    NetConfig::preset(encoder).with_context(|| {
        format!(
            "--encoder {encoder}: expected one of {}",
            PRESETS.join(", ")
        )
    })
}
