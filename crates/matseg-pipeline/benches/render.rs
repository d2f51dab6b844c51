//! `cargo bench -p matseg-pipeline --bench render`: the path tracer on the
//! reference scene at 384x384 and 16 spp, the median of 3 renders
//! (`matseg bench-render` takes other sizes and writes the scene).

use matseg_pipeline::bench::render::RenderBench;
use matseg_pipeline::progress::Progress;

/// Making the bundled materials the first time is not reported.
struct Quiet;

impl Progress for Quiet {
    fn start(&self, _: u64, _: &str) {}
    fn advance(&self) {}
    fn finish(&self) {}
    fn warn(&self, message: &str) {
        eprintln!("warning: skipped {message}");
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let bench = RenderBench {
        size: 384,
        spp: 16,
        repeats: 3,
        threads: 0,
        write_scene: None,
    };
    println!("{:#?}", bench.run(&Quiet)?);
    Ok(())
}
