//! `cargo bench -p matseg-pipeline --bench generator`: the 2D generator's
//! throughput on the bundled assets (200 scenes a row; `matseg bench
//! --scenes N` measures any count, or other sources).

use matseg_image::LicenceFilter;
use matseg_pipeline::bench::generator::GeneratorBench;
use matseg_pipeline::sources::{Defaults, Libraries, DEFAULT_CACHE_MB};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let all = LicenceFilter::default();
    let libraries = Libraries::load(&[], &[], DEFAULT_CACHE_MB, Defaults::Bundled, &all)?;
    let bench = GeneratorBench {
        scenes: 200,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        seed: 1,
        dir: std::env::temp_dir(),
        in_memory_only: false,
    };
    print!("{}", bench.run(&libraries)?.text());
    Ok(())
}
