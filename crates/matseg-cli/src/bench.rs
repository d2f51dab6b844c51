//! `matseg bench`: generator throughput at the paper's scene-size distribution.

use crate::common::load_libraries;
use crate::cpu_time::process_cpu_seconds;
use anyhow::Result;
use matseg_data::{encode_scene, generate_dataset, sample_rng, Format, GenerateOptions, JobSlice};
use matseg_extract::make_soft_maps;
use matseg_image::LicenceFilter;
use matseg_pipeline::sources::{Defaults, DEFAULT_CACHE_MB};
use matseg_scene::{generate_2d, Recipe2d, Scene2d};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `matseg bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Scenes per measurement. A scene's cost varies by about two thirds
    /// of the mean from one scene to the next (size, K, which photos are
    /// upscaled), so a row of n scenes is within about 67%/sqrt(n) of the
    /// distribution's mean: 2% for the default, 10% for 40 scenes.
    #[arg(long, default_value_t = 1000)]
    scenes: u64,
    /// Threads for the parallel measurement (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of the scenes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Folders of natural photos to measure with; default: bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Folders of textures to measure with; default: bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    /// Memory bound for decoded source photos, in MiB.
    #[arg(long, default_value_t = DEFAULT_CACHE_MB)]
    cache_mb: usize,
    /// Where the end-to-end rows write (and then delete) their datasets;
    /// default: the system's temporary folder. The disk's cost is part of
    /// those rows.
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Measure only generation in memory, one thread (no soft-maps row,
    /// encoding or disk): a run to profile, see
    /// scripts/bench-unchanged-share.sh.
    #[arg(long)]
    in_memory_only: bool,
}

/// Wall-clock and process CPU time, read together.
#[derive(Clone, Copy)]
struct Clock {
    wall: Instant,
    cpu: Option<f64>,
}

impl Clock {
    fn now() -> Self {
        Self {
            wall: Instant::now(),
            cpu: process_cpu_seconds(),
        }
    }

    /// Wall seconds and CPU seconds since `self`; CPU seconds are wall
    /// seconds times `threads` where the platform gives no CPU time.
    fn elapsed(self, threads: usize) -> (f64, f64) {
        let wall = self.wall.elapsed().as_secs_f64();
        let cpu = match (self.cpu, process_cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => wall * threads as f64,
        };
        (wall, cpu)
    }
}

struct Row {
    name: String,
    threads: usize,
    scenes: u64,
    wall: f64,
    cpu: f64,
    bytes: u64,
}

impl Row {
    /// A row measured on one thread: `(wall, cpu)` seconds over `scenes`.
    fn one_thread(name: &str, scenes: u64, (wall, cpu): (f64, f64), bytes: u64) -> Self {
        Self {
            name: name.into(),
            threads: 1,
            scenes,
            wall,
            cpu,
            bytes,
        }
    }
}

/// The in-memory row's name, in the whole table and alone.
const IN_MEMORY: &str = "generate in memory (no encoding)";

/// Runs `matseg bench`: measures each row and prints the table.
pub fn run(args: Args) -> Result<()> {
    anyhow::ensure!(args.scenes >= 1, "--scenes must be at least 1");
    let libs = load_libraries(
        &args.sources,
        &args.textures,
        args.cache_mb,
        Defaults::Bundled,
        &LicenceFilter::default(),
    )?;
    let recipe = Recipe2d::default();
    let sources = libs.sources();
    let threads = args.threads.unwrap_or_else(num_threads);

    // Warm the photo cache so every row measures steady-state generation.
    for i in 0..8.max(libs.photos.len() as u64 / 4) {
        generate_2d(&mut sample_rng(args.seed ^ 0xdead, i), &recipe, sources)?;
    }

    let mut rows = Vec::new();
    let mut sample = Sample::default();
    if args.in_memory_only {
        let start = Clock::now();
        for i in 0..args.scenes {
            sample.add(&generate_2d(
                &mut sample_rng(args.seed, i),
                &recipe,
                sources,
            )?);
        }
        rows.push(Row::one_thread(IN_MEMORY, args.scenes, start.elapsed(1), 0));
        sample.print(&recipe, libs.photos.len(), libs.textures.len());
        print_table(&rows);
        return Ok(());
    }
    let start = Clock::now();
    for i in 0..args.scenes {
        let mut rng = sample_rng(args.seed, i);
        let shape = recipe.scene.draw(&mut rng);
        make_soft_maps(
            &mut rng,
            sources.photos,
            shape.width,
            shape.height,
            shape.materials,
            shape.hard,
            shape.max_occupancy,
            &recipe.maps,
        )?;
    }
    rows.push(Row::one_thread(
        "soft maps only (pipeline.md §1)",
        args.scenes,
        start.elapsed(1),
        0,
    ));
    let (mut gen, mut enc) = ((0.0, 0.0), (0.0, 0.0));
    let mut bytes = 0u64;
    let add = |total: &mut (f64, f64), (wall, cpu): (f64, f64)| {
        total.0 += wall;
        total.1 += cpu;
    };
    for i in 0..args.scenes {
        let t = Clock::now();
        let scene = generate_2d(&mut sample_rng(args.seed, i), &recipe, sources)?;
        add(&mut gen, t.elapsed(1));
        let t = Clock::now();
        let encoded = encode_scene(&scene, args.seed, i, sources);
        add(&mut enc, t.elapsed(1));
        sample.add(&scene);
        bytes += encoded.bytes() as u64;
    }
    rows.push(Row::one_thread(IN_MEMORY, args.scenes, gen, 0));
    rows.push(Row::one_thread(
        "encode only (JPEG + PNG masks + JSON)",
        args.scenes,
        enc,
        bytes,
    ));

    for (t, format) in [
        (1, Format::Folders),
        (threads, Format::Folders),
        (threads, Format::Wds),
    ] {
        let dir = args
            .dir
            .clone()
            .unwrap_or_else(std::env::temp_dir)
            .join(format!(
                "matseg-bench-{}-{t}-{format:?}",
                std::process::id()
            ));
        let opts = GenerateOptions {
            out: dir.clone(),
            n: args.scenes,
            seed: args.seed,
            format,
            shard_size: args.scenes,
            job: JobSlice::ALL,
        };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build()?;
        let start = Clock::now();
        let report = pool.install(|| generate_dataset(&opts, &recipe, sources, &|_| {}))?;
        let (wall, cpu) = start.elapsed(t);
        let _ = std::fs::remove_dir_all(&dir);
        rows.push(Row {
            name: format!(
                "end to end, {} to disk",
                if format == Format::Wds {
                    "wds shard"
                } else {
                    "folders"
                }
            ),
            threads: t,
            scenes: args.scenes,
            wall,
            cpu,
            bytes: report.bytes,
        });
    }

    sample.print(&recipe, libs.photos.len(), libs.textures.len());
    print_table(&rows);
    Ok(())
}

/// The measured scenes' sizes and materials, to compare with the means of
/// the distribution they are drawn from.
#[derive(Default)]
struct Sample {
    scenes: u64,
    pixels: u64,
    materials: u64,
}

impl Sample {
    /// Counts one generated scene.
    fn add(&mut self, scene: &Scene2d) {
        self.scenes += 1;
        self.pixels += u64::from(scene.image.width()) * u64::from(scene.image.height());
        self.materials += scene.weights.len() as u64;
    }

    /// Prints the sample's means beside the distribution's.
    fn print(&self, recipe: &Recipe2d, photos: usize, textures: usize) {
        let n = self.scenes.max(1) as f64;
        println!(
            "scenes: {} per row, mean {:.3} MP and {:.2} materials (the paper's 2D distribution's means: {:.3} MP, {:.2}); {photos} photos, {textures} textures",
            self.scenes,
            self.pixels as f64 / n / 1e6,
            self.materials as f64 / n,
            recipe.scene.mean_pixels() / 1e6,
            recipe.scene.mean_materials(),
        );
    }
}

/// Prints the measured rows as a table.
fn print_table(rows: &[Row]) {
    println!(
        "| {:<40} | {:>7} | {:>9} | {:>13} | {:>13} | {:>8} |",
        "measure", "threads", "wall s", "CPU s / scene", "scenes/s/core", "MB/s"
    );
    println!(
        "|{:-<42}|{:->9}|{:->11}|{:->15}|{:->15}|{:->10}|",
        "", "", "", "", "", ""
    );
    for r in rows {
        let cpu_per_scene = r.cpu / r.scenes as f64;
        println!(
            "| {:<40} | {:>7} | {:>9.2} | {:>13.4} | {:>13.1} | {:>8} |",
            r.name,
            r.threads,
            r.wall,
            cpu_per_scene,
            1.0 / cpu_per_scene,
            if r.bytes > 0 {
                format!("{:.1}", r.bytes as f64 / 1e6 / r.wall)
            } else {
                "-".into()
            }
        );
    }
    if process_cpu_seconds().is_none() {
        println!("(no process CPU clock here: CPU seconds are wall seconds times threads)");
    }
}

fn num_threads() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}
