//! Embeds libtorch's lib folder as the rpath of this crate's tests and
//! exports it to dependents (see Cargo.toml `links`), so no binary needs
//! LD_LIBRARY_PATH. LIBTORCH comes from the workspace's .cargo/config.toml
//! (the project .venv that scripts/torch-env.sh installs).

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    let Some(libtorch) = std::env::var_os("LIBTORCH") else {
        panic!("LIBTORCH is not set: run scripts/torch-env.sh (make test does) to install libtorch into .venv");
    };
    let lib = std::path::Path::new(&libtorch).join("lib");
    let lib = lib.canonicalize().unwrap_or_else(|_| {
        panic!(
            "{}: no libtorch here: run scripts/torch-env.sh (make test does) to install it",
            lib.display()
        )
    });
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    println!("cargo:lib_dir={}", lib.display());
}
