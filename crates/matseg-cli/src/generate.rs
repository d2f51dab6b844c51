//! `matseg generate`.

use crate::common::{
    init_threads, load_recipe, report_skipped, BarProgress, LicenceArgs, SceneKind as Kind,
};
use anyhow::Result;
use clap::ValueEnum;
use matseg_data::{generate_with, Format, GenerateOptions, JobSlice};
use matseg_image::outputs::check_apart;
use matseg_pipeline::files3d::recipe_3d;
use matseg_pipeline::scenes::{SceneFolders, SceneRecipe, SceneSources};
use matseg_pipeline::sources::{Defaults, DEFAULT_CACHE_MB};
use matseg_scene::CameraPath;
use std::path::PathBuf;
use std::time::Instant;

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
    /// Output folder: a new or empty one, or a dataset to resume
    /// (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
    /// Number of samples in the whole dataset.
    #[arg(short = 'n', long = "samples", value_name = "N")]
    n: u64,
    /// Dataset seed: sample i depends only on (seed, i).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Folders of natural photos (maps, backgrounds, shading); default: the
    /// fetched corpus (`matseg assets fetch`), else the bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Folders of uniform textures (2d); default: the fetched corpus, else the bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    /// Folders of PBR material folders (3d); default: materials made once
    /// from the default textures into the cache ($MATSEG_CACHE/materials).
    #[arg(long, num_args = 1..)]
    materials: Vec<PathBuf>,
    /// Mesh files or folders of them, OBJ/OFF/PLY (3d); default: the fetched
    /// corpus's meshes, else the bundled ones (besides procedural shapes).
    #[arg(long, num_args = 1..)]
    meshes: Vec<PathBuf>,
    /// HDRI files or folders of them, .hdr/.exr (3d); default: the fetched
    /// corpus's HDRIs, else the bundled ones.
    #[arg(long, num_args = 1..)]
    hdris: Vec<PathBuf>,
    #[command(flatten)]
    licences: LicenceArgs,
    /// Samples per pixel (3d), overriding the recipe.
    #[arg(long)]
    spp: Option<u32>,
    /// Image side in pixels (3d), overriding the recipe.
    #[arg(long)]
    size: Option<u32>,
    /// Sequences (3d): each of the N scenes rendered as F frames along a
    /// camera path (orbit, dolly, dimming light), N x F samples in all.
    #[arg(long, value_name = "F")]
    frames: Option<u32>,
    /// TOML camera path of the sequences (3d; see docs/video.md); its
    /// `frames` unless --frames is given.
    #[arg(long, value_name = "FILE")]
    camera_path: Option<PathBuf>,
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
    /// Scene side range LO..HI (inclusive, 2d), overriding the recipe.
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
    init_threads(args.threads)?;
    // The job index comes from the job array only when the work is split.
    let index = match args.shard_index {
        Some(i) => i,
        None if args.num_shards > 1 => JobSlice::index_from_env()?.unwrap_or(0),
        None => 0,
    };
    let job = JobSlice {
        count: args.num_shards,
        index,
    };
    job.validate()?;
    let camera_path = camera_path(&args)?;
    let inputs = input_paths(&args);
    check_apart(
        &args.out,
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    let frames = camera_path.as_ref().map_or(1, |p| p.frames as u64);
    let opts = GenerateOptions {
        out: args.out.clone(),
        n: args.n.checked_mul(frames).ok_or_else(|| {
            anyhow::anyhow!("-n {} x --frames {frames}: too many samples", args.n)
        })?,
        seed: args.seed,
        format: match args.format {
            FormatArg::Folders => Format::Folders,
            FormatArg::Wds => Format::Wds,
        },
        shard_size: args.shard_size,
        job,
    };
    let licences = args.licences.filter()?;
    let recipe = match args.kind {
        Kind::TwoD => SceneRecipe::TwoD(load_recipe(
            args.config.as_deref(),
            args.size_range.as_deref(),
        )?),
        Kind::ThreeD => {
            SceneRecipe::ThreeD(recipe_3d(args.config.as_deref(), args.size, args.spp)?)
        }
    };
    let folders = SceneFolders {
        photos: args.sources,
        textures: args.textures,
        materials: args.materials,
        meshes: args.meshes,
        hdris: args.hdris,
    };
    let start = Instant::now();
    let sources = SceneSources::load(
        recipe,
        &folders,
        args.cache_mb,
        Defaults::CorpusOrBundled,
        &licences,
        &BarProgress::default(),
    )?;
    let report = sources.with_maker(camera_path.as_ref(), |maker| {
        generate_with(&opts, maker, &BarProgress::default())
    })?;
    report_skipped(&sources);
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

/// Every file and folder the run reads, the default sources included:
/// inputs the dataset must not overlap.
fn input_paths(args: &Args) -> Vec<PathBuf> {
    let defaults = Defaults::CorpusOrBundled;
    let mut inputs = defaults.or(&args.sources, "photos");
    inputs.extend(defaults.or(&args.textures, "textures"));
    inputs.extend(defaults.or(&args.meshes, "meshes"));
    inputs.extend(defaults.or(&args.hdris, "hdris"));
    inputs.extend(args.materials.iter().cloned());
    inputs.extend(args.config.clone());
    inputs.extend(args.camera_path.clone());
    inputs
}

/// The camera path of 3D sequences: the TOML file's (or the defaults), with
/// `--frames` overriding its frame count; `None` without either option.
fn camera_path(args: &Args) -> Result<Option<CameraPath>> {
    if args.frames.is_none() && args.camera_path.is_none() {
        return Ok(None);
    }
    if !matches!(args.kind, Kind::ThreeD) {
        anyhow::bail!("--frames and --camera-path make sequences of 3D scenes: add --kind 3d");
    }
    let mut path = match &args.camera_path {
        Some(file) => CameraPath::from_toml_file(file)?,
        None => CameraPath::default(),
    };
    if let Some(frames) = args.frames {
        path.frames = frames;
    }
    path.validate()
        .map_err(|e| anyhow::anyhow!("--frames: {}", e.0))?;
    Ok(Some(path))
}
