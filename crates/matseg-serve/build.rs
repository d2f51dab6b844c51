//! Embeds libtorch's lib folder as the rpath of this crate's test
//! binaries (a library's link arguments reach only those): in a
//! workspace build with the CLI's `net` feature, matseg-pipeline links
//! libtorch into them (this crate itself needs none). LIBTORCH comes from
//! the workspace's .cargo/config.toml, as for matseg-net.

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    if let Some(libtorch) = std::env::var_os("LIBTORCH") {
        if let Ok(lib) = std::path::Path::new(&libtorch).join("lib").canonicalize() {
            println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
        }
    }
}
