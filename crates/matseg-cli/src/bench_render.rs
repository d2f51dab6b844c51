//! `matseg bench-render`: the path tracer's speed on the fixed reference
//! scene (`matseg_pipeline::bench::render`) at 384x384 and 16 spp by
//! default; `--write-scene` saves the scene for
//! `scripts/bench-render-cycles.py`.

use crate::common::BarProgress;
use anyhow::Result;
use matseg_pipeline::bench::render::RenderBench;
use std::path::PathBuf;

/// Arguments of `matseg bench-render`.
#[derive(clap::Args)]
pub struct Args {
    /// Image side in pixels.
    #[arg(long, default_value_t = 384)]
    size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Timed renders (the median is reported).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Also write the scene (scene.json, object_K.obj, image.png) into
    /// this folder, written whole (docs/outputs.md).
    #[arg(long)]
    write_scene: Option<PathBuf>,
    /// Print JSON instead of a table row.
    #[arg(long)]
    json: bool,
}

/// Runs `matseg bench-render`.
pub fn run(args: Args) -> Result<()> {
    let bench = RenderBench {
        size: args.size,
        spp: args.spp,
        repeats: args.repeats,
        threads: args.threads.unwrap_or(0),
        write_scene: args.write_scene,
    };
    let r = bench.run(&BarProgress::default())?;
    if args.json {
        println!("{}", serde_json::to_value(r)?);
    } else {
        println!("| size | spp | triangles | threads | load s | render s (wall) | CPU s / image | images/hour/core | peak RSS MiB |");
        println!("|---|---|---|---|---|---|---|---|---|");
        println!(
            "| {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.0} | {} |",
            r.size,
            r.spp,
            r.triangles,
            r.threads,
            r.load_seconds,
            r.render_seconds,
            r.render_cpu_seconds,
            r.images_per_hour_per_core,
            r.peak_rss_mib.map_or("?".into(), |p| format!("{p:.0}"))
        );
    }
    Ok(())
}
