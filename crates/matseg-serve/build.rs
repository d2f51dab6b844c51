//! Embeds libtorch's lib folder (exported by matseg-net's build script) as
//! the rpath of this crate's tests, so they run without LD_LIBRARY_PATH.

fn main() {
    if let Ok(dir) = std::env::var("DEP_MATSEG_LIBTORCH_LIB_DIR") {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
}
