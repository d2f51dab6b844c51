//! `matseg eval points|masks|clicks`: score models on real-photo
//! benchmarks (`clicks`: crate::eval_clicks).

use anyhow::Result;
use clap::Subcommand;
use matseg_eval::external::MapFolder;
use matseg_eval::template::{write_mask_template, write_point_template};
use matseg_eval::{
    evaluate_masks, is_point_benchmark, load_point_benchmark, scan_mask_benchmark, Described,
    MaskEvalOptions, MaskEvaluation, QueryOptions, ScoredModel,
};
use matseg_image::outputs::StagedOutput;
use matseg_image::progress::Silent;
use matseg_pipeline::models::ModelChoice;
use matseg_pipeline::point_bench::score_point_benchmark;
use std::path::PathBuf;

/// `matseg eval` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// A point benchmark in the MatSeg format: triplet accuracy (All, Soft) and top-1.
    Points(PointArgs),
    /// Photos with ground-truth masks: mean IoU at the best threshold.
    Masks(MaskArgs),
    /// Clicks a selection needs: NoC@85, NoC@90 and IoU after 1, 3, 5
    /// clicks on a mask benchmark; on a point benchmark, the balanced
    /// accuracy of the points not clicked.
    Clicks(crate::eval_clicks::Args),
    /// Generated 3D sequences: materials clicked on the first frame and
    /// followed, IoU at the best threshold on every frame.
    #[cfg(feature = "infer")]
    Track(crate::track::EvalArgs),
    /// What a tool outside matseg must answer for `--maps`: each photo at
    /// its scored size (photos/NAME.png) and the points asked about
    /// (template.json), for a point or a mask benchmark.
    MapsTemplate(TemplateArgs),
}

/// Options shared by both benchmarks.
#[derive(clap::Args)]
pub struct ModelArgs {
    /// Baselines to score (rgb, lab, texture, position: coordinates alone,
    /// and imagenet: the ImageNet MobileNetV2's features with no training;
    /// `all` for every one); repeatable.
    #[arg(long = "baseline", num_args = 1..)]
    baselines: Vec<String>,
    /// Trained nets to score: `default` (the shipped model), run folders
    /// of `matseg train` or their weights files (model.safetensors,
    /// best.safetensors), or `none`; repeatable.
    #[arg(long = "model", num_args = 1.., default_value = crate::net_args::DEFAULT_NETS)]
    nets: Vec<PathBuf>,
    /// Folders of maps a model matseg did not train computed for the
    /// benchmark's photos: NAME.npy or NAME.safetensors per photo, and an
    /// optional maps.json (docs/eval.md, "Scoring your own model");
    /// repeatable.
    #[arg(long = "maps", num_args = 1.., value_name = "DIR")]
    maps: Vec<PathBuf>,
    /// Describe photos with the nets at this longer side at most (photos
    /// are scored at --max-side all the same), instead of each run's own
    /// setting (its run.json's inference_side); several sides (`320,256`)
    /// average the descriptors of each.
    #[arg(long, value_name = "PIXELS", value_delimiter = ',')]
    net_side: Vec<u32>,
    /// Device the nets run on: cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Longer side of the evaluated images, in pixels (0: as they are).
    #[arg(long, default_value_t = matseg_eval::evaluate::DEFAULT_MAX_SIDE)]
    pub max_side: u32,
    /// Print JSON (stable field names) instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `matseg eval points`.
#[derive(clap::Args)]
pub struct PointArgs {
    /// Benchmark folder (images/, data/NAME/data.json, group_relations.txt).
    bench: PathBuf,
    #[command(flatten)]
    model: ModelArgs,
    /// Skip malformed images with a warning instead of stopping.
    #[arg(long)]
    skip_bad: bool,
}

/// Arguments of `matseg eval masks`.
#[derive(clap::Args)]
pub struct MaskArgs {
    /// Folder of NAME.jpg, NAME.mask0.png, ..., optional NAME.roi.png.
    data: PathBuf,
    #[command(flatten)]
    model: ModelArgs,
    #[command(flatten)]
    draw: MaskDrawArgs,
    /// Radius of a query point's disc, in pixels.
    #[arg(long, default_value_t = 5.0, value_parser = crate::query_args::parse_radius, allow_negative_numbers = true)]
    radius: f32,
    /// Parity mode: the best IoU over STEPS + 1 thresholds evenly spread
    /// over each similarity map's range (e.g. 100 or 1000) instead of the
    /// exact best.
    #[arg(long, value_name = "STEPS")]
    grid: Option<usize>,
}

/// Arguments of `matseg eval maps-template`.
#[derive(clap::Args)]
pub struct TemplateArgs {
    /// A point benchmark (images/, data/) or a mask benchmark folder.
    bench: PathBuf,
    /// The folder to write (a new one, or one this command wrote).
    #[arg(long)]
    out: PathBuf,
    /// Longer side of the evaluated images, in pixels (0: as they are);
    /// the same as the evaluation's --max-side.
    #[arg(long, default_value_t = matseg_eval::evaluate::DEFAULT_MAX_SIDE)]
    max_side: u32,
    /// For a mask benchmark: how query points are drawn, as `eval masks`
    /// draws them.
    #[command(flatten)]
    draw: MaskDrawArgs,
}

/// How a mask benchmark's query points are drawn.
#[derive(clap::Args)]
pub struct MaskDrawArgs {
    /// Query points per mask.
    #[arg(long, default_value_t = 10)]
    points: usize,
    /// Erode masks by this many pixels before drawing points.
    #[arg(long, default_value_t = 20)]
    erode: usize,
    /// Skip masks whose eroded area is smaller than this, in pixels.
    #[arg(long, default_value_t = 400)]
    min_area: usize,
    /// Seed of the query points.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Runs `matseg eval`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Points(args) => points(args),
        Command::Masks(args) => masks(args),
        Command::Clicks(args) => crate::eval_clicks::run(args),
        #[cfg(feature = "infer")]
        Command::Track(args) => crate::track::eval(args),
        Command::MapsTemplate(args) => maps_template(args),
    }
}

/// The models `args` choose.
pub fn models(args: &ModelArgs) -> Result<Vec<Box<dyn ScoredModel>>> {
    let choice = ModelChoice {
        baselines: args.baselines.clone(),
        nets: args.nets.clone(),
        net_sides: args.net_side.clone(),
        device: crate::net_args::parse_device(&args.device)?,
    };
    let mut models: Vec<Box<dyn ScoredModel>> = matseg_pipeline::models::models(&choice)?
        .into_iter()
        .map(|m| Box::new(Described(m)) as Box<dyn ScoredModel>)
        .collect();
    for dir in &args.maps {
        models.push(Box::new(MapFolder::open(dir)?));
    }
    if models.is_empty() {
        anyhow::bail!("no model to score: give --model, --baseline or --maps");
    }
    Ok(models)
}

/// A score with four decimals, `-` when there is none.
pub fn score(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.4}"))
}

fn points(args: PointArgs) -> Result<()> {
    let models = models(&args.model)?;
    let evaluation = score_point_benchmark(
        &args.bench,
        &models,
        args.skip_bad,
        args.model.max_side,
        &Silent,
    )?;
    for problem in &evaluation.skipped {
        eprintln!("warning: skipped {problem}");
    }
    if args.model.json {
        println!("{}", serde_json::to_string_pretty(&evaluation)?);
        return Ok(());
    }
    let reports = &evaluation.models;
    let c = &reports[0].counts;
    println!(
        "{}: {} images ({} with relations), {} points; longer side {} px; {} skipped",
        args.bench.display(),
        c.images,
        c.soft_images,
        c.points,
        args.model.max_side,
        evaluation.skipped.len()
    );
    println!(
        "| model | All by material | All by point | Soft by material | Soft by point | Top-1 by material | Top-1 by point | triplets | soft triplets |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in reports {
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.model,
            score(r.all_by_material),
            score(r.all_by_point),
            score(r.soft_by_material),
            score(r.soft_by_point),
            score(r.top1_by_material),
            score(r.top1_by_point),
            r.counts.triplets,
            r.counts.soft_triplets
        );
    }
    Ok(())
}

impl MaskDrawArgs {
    /// The query draws these arguments ask for.
    fn queries(&self) -> QueryOptions {
        QueryOptions {
            points_per_mask: self.points,
            erosion: self.erode,
            min_area: self.min_area,
            seed: self.seed,
        }
    }
}

fn masks(args: MaskArgs) -> Result<()> {
    let models = models(&args.model)?;
    let images = scan_mask_benchmark(&args.data)?;
    let options = MaskEvalOptions {
        max_side: args.model.max_side,
        queries: args.draw.queries(),
        radius: args.radius,
        grid_steps: args.grid,
    };
    let reports = models
        .iter()
        .map(|m| evaluate_masks(m.as_ref(), &images, &options, &Silent))
        .collect::<Result<Vec<_>, _>>()?;
    if args.model.json {
        let evaluation = MaskEvaluation::new(&args.data, &options, &reports);
        println!("{}", serde_json::to_string_pretty(&evaluation)?);
        return Ok(());
    }
    let r0 = &reports[0];
    println!(
        "{}: {} images, {} masks queried ({} too small), {} queries; longer side {} px; threshold {}",
        args.data.display(),
        r0.images,
        r0.masks,
        r0.skipped_masks,
        r0.queries,
        args.model.max_side,
        args.grid.map_or("exact".to_string(), |s| format!("on a grid of {s} steps"))
    );
    println!("| model | mean IoU at best threshold |");
    println!("|---|---|");
    for r in &reports {
        println!("| {} | {} |", r.model, score(r.mean_iou));
    }
    Ok(())
}

fn maps_template(args: TemplateArgs) -> Result<()> {
    let staged = StagedOutput::begin(&args.out, "eval maps-template", &[&args.bench])?;
    let template = if is_point_benchmark(&args.bench) {
        let bench = load_point_benchmark(&args.bench, false)?;
        write_point_template(staged.dir(), &bench, args.max_side)?
    } else {
        let images = scan_mask_benchmark(&args.bench)?;
        write_mask_template(staged.dir(), &images, args.max_side, &args.draw.queries())?
    };
    staged.finish()?;
    println!(
        "{}: {} photos of the {} benchmark {} at their scored size, {} points to answer",
        args.out.display(),
        template.images.len(),
        template.protocol,
        args.bench.display(),
        template
            .images
            .iter()
            .map(|i| i.points.len())
            .sum::<usize>()
    );
    Ok(())
}
