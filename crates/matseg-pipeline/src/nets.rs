//! Trained nets loaded for inference, on the engine that runs them best
//! where they are asked to run: the pure-Rust engine (matseg-infer) on the
//! CPU, libtorch (matseg-net, in a build with the `net` feature) on CUDA.
//! BENCHMARKS.md, "Inference without libtorch", has the measurements
//! behind the CPU's choice.

use crate::error::PipelineError;
use matseg_eval::{evaluate_points, Described, PointBenchmark};
use matseg_image::device::ComputeDevice;
use matseg_image::progress::Silent;
use matseg_infer::InferNet;
use matseg_model::{run_files, DEFAULT_MODEL};
use matseg_query::descriptor::DescriptorModel;
use matseg_query::net::{DescriptorNet, NamedNet};
use std::path::Path;

/// The name a net is reported under: `default` for the shipped model,
/// else its run folder's name.
pub fn net_name(model: &Path) -> String {
    if model == Path::new(DEFAULT_MODEL) {
        return DEFAULT_MODEL.to_string();
    }
    run_files(model)
        .0
        .file_name()
        .map_or("net".into(), |n| n.to_string_lossy().into_owned())
}

/// The environment variable that picks the engine of nets on the CPU:
/// `rust` (the default) or `libtorch` (in a build with it), to compare
/// the two with the same commands (BENCHMARKS.md, "Inference without
/// libtorch").
pub const ENGINE_VARIABLE: &str = "MATSEG_ENGINE";

/// The engine a model runs on.
enum Engine {
    /// matseg-infer, on the CPU.
    Rust,
    /// libtorch (matseg-net), on its device.
    #[cfg(feature = "net")]
    Libtorch,
}

/// The engine for `device`: libtorch on CUDA, the pure-Rust one on the CPU
/// unless [`ENGINE_VARIABLE`] asks for libtorch; refused where this build
/// has no libtorch.
fn engine(device: ComputeDevice) -> Result<Engine, PipelineError> {
    let asked = std::env::var(ENGINE_VARIABLE);
    let libtorch = match asked.as_deref() {
        Err(_) | Ok("rust") => matches!(device, ComputeDevice::Cuda(_)),
        Ok("libtorch") => true,
        Ok(other) => {
            return Err(PipelineError::setting(
                ENGINE_VARIABLE,
                Some(other),
                "the engines are rust and libtorch",
            ))
        }
    };
    match libtorch {
        false => Ok(Engine::Rust),
        #[cfg(feature = "net")]
        true => Ok(Engine::Libtorch),
        #[cfg(not(feature = "net"))]
        true => Err(match device {
            ComputeDevice::Cuda(_) => PipelineError::setting(
                "device",
                Some(device),
                "this build runs nets on the CPU only (CUDA needs the build with libtorch, docs/gpu.md)",
            ),
            ComputeDevice::Cpu => PipelineError::setting(
                ENGINE_VARIABLE,
                Some("libtorch"),
                "this build has no libtorch (cargo feature `net`)",
            ),
        }),
    }
}

/// Loads `model` (`default`, a run folder, or a weights file with its
/// run's `run.json` beside it) to describe photos on `device`.
pub fn load_net(model: &Path, device: ComputeDevice) -> Result<NamedNet, PipelineError> {
    let net: Box<dyn DescriptorNet> = match engine(device)? {
        Engine::Rust => Box::new(InferNet::load(model)?),
        #[cfg(feature = "net")]
        Engine::Libtorch => Box::new(matseg_net::infer::NetModel::load(model, device)?),
    };
    Ok(NamedNet::new(net_name(model), net))
}

/// The ImageNet MobileNetV2 feature baseline on the engine for `device`,
/// with the registry's weights (fetched into the cache the first time).
pub fn imagenet_baseline(device: ComputeDevice) -> Result<Box<dyn DescriptorModel>, PipelineError> {
    let engine = engine(device)?;
    let path = crate::weights::imagenet_weights(matseg_weights::Arch::MobilenetV2, None)?.path;
    let label = path.display().to_string();
    let (tensors, _) = crate::weights::read_weights(&path)?;
    Ok(match engine {
        Engine::Rust => Box::new(matseg_infer::ImagenetBaseline::new(tensors, &label)?),
        #[cfg(feature = "net")]
        Engine::Libtorch => {
            use matseg_net::imagenet::{ImagenetBaseline, ImagenetFeatures};
            let device = matseg_net::torch_device(device);
            let features = ImagenetFeatures::new(&tensors, &label, device)?;
            Box::new(ImagenetBaseline::imagenet(features))
        }
    })
}

/// The score `matseg train --val-points` records for a checkpoint: the
/// model's triplet accuracy (All, by material) on `bench` with photos at
/// `max_side`.
pub fn point_score(
    model: &dyn DescriptorModel,
    bench: &PointBenchmark,
    max_side: u32,
) -> Result<f64, PipelineError> {
    let report = evaluate_points(&Described(model), bench, max_side, &Silent)?;
    report
        .all_by_material
        .ok_or_else(|| PipelineError::Settings("the point benchmark has no triplets".into()))
}
