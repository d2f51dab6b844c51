//! Where the extension built with the `torch` feature finds libtorch at
//! run time: first the `torch`
//! wheel installed beside it (`site-packages/torch/lib`, so the process
//! shares one libtorch with `import torch`), then the project .venv it was
//! built against (the lib folder matseg-net's build script exports).

fn main() {
    // Only the build with libtorch (the `torch` feature) links it.
    if std::env::var_os("CARGO_FEATURE_TORCH").is_none() {
        return;
    }
    println!("cargo:rustc-link-arg=-Wl,-rpath,$ORIGIN/../torch/lib");
    if let Ok(dir) = std::env::var("DEP_MATSEG_LIBTORCH_LIB_DIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}
