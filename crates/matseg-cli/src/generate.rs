//! `matseg generate`.

use crate::common::{init_threads, load_recipe, progress_bar, Libraries, DEFAULT_CACHE_MB};
use anyhow::{bail, Result};
use clap::ValueEnum;
use matseg_data::{generate_dataset, Format, GenerateOptions, JobSlice};
use std::path::PathBuf;
use std::time::Instant;

/// Scene kinds `generate` can make.
#[derive(Clone, Copy, ValueEnum)]
pub enum Kind {
    /// Textures mixed by soft maps over a photo background (SPEC section 2).
    #[value(name = "2d")]
    TwoD,
}

/// Output layouts, as command-line values.
#[derive(Clone, Copy, ValueEnum)]
pub enum FormatArg {
    /// One MatSeg folder per sample (RGB__RGB.jpg, mask0.png, ..., Finished.txt).
    Folders,
    /// WebDataset tar shards with a JSON sidecar per sample.
    Wds,
}

/// Arguments of `matseg generate`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene kind.
    #[arg(long, value_enum, default_value = "2d")]
    kind: Kind,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Number of samples in the whole dataset.
    #[arg(short = 'n', long = "samples", value_name = "N")]
    n: u64,
    /// Dataset seed: sample i depends only on (seed, i).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Folders of natural photos (maps, backgrounds, shading); default: bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Folders of uniform textures; default: bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    /// Output layout.
    #[arg(long, value_enum, default_value = "folders")]
    format: FormatArg,
    /// Samples per tar shard (wds only).
    #[arg(long, default_value_t = 1000)]
    shard_size: u64,
    /// Split the work into this many jobs (e.g. a job array).
    #[arg(long, default_value_t = 1)]
    num_shards: u64,
    /// This job's index; default (when --num-shards > 1): SLURM_ARRAY_TASK_ID
    /// or JOB_COMPLETION_INDEX, else 0.
    #[arg(long)]
    shard_index: Option<u64>,
    /// Scene side range LO..HI (inclusive), overriding the recipe.
    #[arg(long)]
    size_range: Option<String>,
    /// TOML recipe overriding any probability or range (see docs/recipe.md).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Memory bound for decoded source photos, in MiB.
    #[arg(long, default_value_t = DEFAULT_CACHE_MB)]
    cache_mb: usize,
}

/// Runs `matseg generate` with the parsed arguments.
pub fn run(args: Args) -> Result<()> {
    let Kind::TwoD = args.kind;
    init_threads(args.threads)?;
    let recipe = load_recipe(args.config.as_deref(), args.size_range.as_deref())?;
    // The job index comes from the job array only when the work is split.
    let index = match args.shard_index {
        Some(i) => i,
        None if args.num_shards > 1 => JobSlice::index_from_env()
            .map_err(anyhow::Error::msg)?
            .unwrap_or(0),
        None => 0,
    };
    let job = JobSlice {
        count: args.num_shards,
        index,
    };
    if let Err(e) = job.validate() {
        bail!("{e}");
    }
    let libs = Libraries::load(&args.sources, &args.textures, args.cache_mb)?;
    let opts = GenerateOptions {
        out: args.out.clone(),
        n: args.n,
        seed: args.seed,
        format: match args.format {
            FormatArg::Folders => Format::Folders,
            FormatArg::Wds => Format::Wds,
        },
        shard_size: args.shard_size,
        job,
    };
    let bar = progress_bar(opts.samples_in_job(), "samples");
    let start = Instant::now();
    let report = generate_dataset(&opts, &recipe, libs.sources(), &|k| bar.inc(k))?;
    bar.finish_and_clear();
    libs.report_skipped();
    let secs = start.elapsed().as_secs_f64();
    eprintln!(
        "{}: {} samples generated, {} already complete, {:.1} MB written in {:.1} s ({:.1} samples/s)",
        args.out.display(),
        report.generated,
        report.skipped,
        report.bytes as f64 / 1e6,
        secs,
        report.generated as f64 / secs.max(1e-9)
    );
    Ok(())
}
