//! The binary built without libtorch, as README's "Install without
//! libtorch" installs it: it links no libtorch and no CUDA, and runs the
//! inference commands on the pure-Rust engine.
#![cfg(all(feature = "infer", not(feature = "net")))]

mod common;

use common::*;
use std::process::Command;

#[test]
fn the_binary_links_no_libtorch_and_no_cuda() {
    let out = Command::new("ldd")
        .arg(env!("CARGO_BIN_EXE_matseg"))
        .output()
        .expect("ldd runs");
    let libraries = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{libraries}");
    for name in ["libtorch", "libc10", "libcuda", "libcudart", "libgomp"] {
        assert!(!libraries.contains(name), "links {name}:\n{libraries}");
    }
}

#[test]
fn segment_runs_the_shipped_model_without_libtorch_and_refuses_cuda() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("segment");
    let photo = format!("{}/coffee.jpg", assets("photos"));
    matseg_ok(&[
        "segment",
        &photo,
        "--point",
        "290,130",
        "--out",
        out.to_str().unwrap(),
    ]);
    for file in ["similarity_0.png", "mask_0.png", "overlay_0.png"] {
        assert!(out.join(file).is_file(), "no {file}");
    }
    let refused = matseg(&[
        "segment",
        &photo,
        "--point",
        "290,130",
        "--device",
        "cuda",
        "--out",
        dir.path().join("cuda").to_str().unwrap(),
    ]);
    assert_one_line_error(&refused, "built without CUDA");
}
