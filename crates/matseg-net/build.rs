//! Embeds libtorch's lib folder as the rpath of this crate's tests and
//! exports it to dependents (see Cargo.toml `links`), so no binary needs
//! LD_LIBRARY_PATH. LIBTORCH comes from the workspace's .cargo/config.toml
//! (the project .venv that scripts/torch-env.sh installs). Without it the
//! build stops with what to do: install libtorch, or build without the net.

/// The two ways out, as the error says them.
const WHAT_TO_DO: &str =
    "run scripts/torch-env.sh (make test does) to install libtorch into .venv, \
     or build without the net: cargo build -p matseg-cli --no-default-features";

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    let Some(libtorch) = std::env::var_os("LIBTORCH") else {
        println!("cargo::error=LIBTORCH is not set: {WHAT_TO_DO}");
        return;
    };
    let lib = std::path::Path::new(&libtorch).join("lib");
    match lib.canonicalize() {
        Ok(lib) => {
            println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
            println!("cargo:lib_dir={}", lib.display());
        }
        Err(_) => println!(
            "cargo::error={}: no libtorch here: {WHAT_TO_DO}",
            lib.display()
        ),
    }
}
