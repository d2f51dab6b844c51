//! Embeds libtorch's lib folder as the rpath of this crate's test and
//! bench binaries (a library's link arguments reach only those): they
//! compare the engine with libtorch (matseg-net, a dev-dependency), while
//! the library itself links no libtorch. LIBTORCH comes from the
//! workspace's .cargo/config.toml, as for matseg-net.

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    if let Some(libtorch) = std::env::var_os("LIBTORCH") {
        if let Ok(lib) = std::path::Path::new(&libtorch).join("lib").canonicalize() {
            println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
        }
    }
}
