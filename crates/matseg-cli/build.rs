//! With the `net` feature, embeds libtorch's lib folder (exported by
//! matseg-net's build script) as the binary's rpath, so `matseg` runs
//! without LD_LIBRARY_PATH. With `cuda`, also links libtorch_cuda, whose
//! static initialisers register torch's CUDA back end (the linker would
//! otherwise drop it, as no symbol of it is used directly).

fn main() {
    let Ok(dir) = std::env::var("DEP_MATSEG_LIBTORCH_LIB_DIR") else {
        return;
    };
    println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    if std::env::var_os("CARGO_FEATURE_CUDA").is_some() {
        println!("cargo:rustc-link-search=native={dir}");
        println!("cargo:rustc-link-arg=-Wl,--no-as-needed,-ltorch_cuda,-lc10_cuda,--as-needed");
        // libtorch_cuda's CUDA libraries (cuBLAS, cuDNN...) need not be
        // here at link time: its own RPATH finds them where it runs.
        println!("cargo:rustc-link-arg=-Wl,--allow-shlib-undefined");
    }
}
