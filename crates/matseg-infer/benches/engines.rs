//! `cargo bench -p matseg-infer --bench engines`: the shipped model's
//! descriptor pass of a 1 MP photo on both engines in one run, libtorch
//! (matseg-net) and pure Rust (this crate): the four sizes merged, as
//! `matseg segment` describes a photo, and the main size alone. The median
//! of 7 passes after 2 warm-ups.

use image::imageops::FilterType;
use matseg_image::device::ComputeDevice;
use matseg_infer::InferNet;
use matseg_net::infer::NetModel;
use matseg_query::net::DescriptorNet;
use std::path::Path;
use std::time::Instant;

const WARM_UPS: usize = 2;
const RUNS: usize = 7;

/// The median milliseconds of `RUNS` calls of `f` after `WARM_UPS`.
fn median_ms(mut f: impl FnMut()) -> f64 {
    for _ in 0..WARM_UPS {
        f();
    }
    let mut times: Vec<f64> = (0..RUNS)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[RUNS / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let default = Path::new(matseg_model::DEFAULT_MODEL);
    let torch = NetModel::load(default, ComputeDevice::Cpu)?;
    let rust = InferNet::load(default)?;
    let coffee = matseg_image::io::read_rgb(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/photos/coffee.jpg"),
    )?;
    // 1155 x 866: one megapixel, at the photo's aspect.
    let photo = image::imageops::resize(&coffee, 1155, 866, FilterType::Triangle);
    let side = rust.inference_side().unwrap_or(700);
    println!(
        "descriptor pass of a {}x{} photo, median of {RUNS} ms",
        photo.width(),
        photo.height()
    );
    println!(
        "{:<28} {:>10} {:>10} {:>7}",
        "pass", "libtorch", "rust", "ratio"
    );
    type Pass<'a> = Box<dyn Fn(&dyn DescriptorNet) + 'a>;
    let passes: [(&str, Pass); 2] = [
        (
            "four sizes merged",
            Box::new(|net| drop(net.describe_coarse(&photo))),
        ),
        (
            "main size alone",
            Box::new(|net| drop(net.describe_frame(&photo, side))),
        ),
    ];
    for (name, pass) in passes {
        let torch_ms = median_ms(|| pass(&torch));
        let rust_ms = median_ms(|| pass(&rust));
        println!(
            "{name:<28} {torch_ms:>10.1} {rust_ms:>10.1} {:>7.2}",
            rust_ms / torch_ms
        );
    }
    Ok(())
}
