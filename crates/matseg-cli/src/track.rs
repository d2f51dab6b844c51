//! `matseg track`: the material under each point, clicked on one frame,
//! followed through every frame of a video or a frame folder
//! (pipeline.md §8.2).

use crate::common::BarProgress;
use crate::net_args::parse_device;
use crate::query_args::{parse_point, parse_radius};
use anyhow::Result;
use matseg_pipeline::frames::FrameSource;
use matseg_pipeline::segment::{load_model, Model, DEFAULT_RADIUS};
use matseg_pipeline::track::{track_to_folder, TrackFiles, TrackSettings, DEFAULT_TRACK_SIDE};
use matseg_pipeline::track_bench::{eval_track, TrackBenchSettings};
use matseg_query::tracking::TrackOptions;
use std::path::PathBuf;

/// Arguments of `matseg track`.
#[derive(clap::Args)]
pub struct Args {
    /// A video file (MP4, WebM, MKV...: decoded by ffmpeg) or a folder of
    /// PNG/JPEG frames in name order.
    video: PathBuf,
    /// A point `X,Y` in pixels of the clicked frame; repeat for several materials.
    #[arg(long = "point", required = true, value_parser = parse_point, allow_hyphen_values = true)]
    points: Vec<(f32, f32)>,
    /// A negative click `X,Y` on the clicked frame: its material is kept
    /// out of every point's through the whole video; repeat for several.
    #[arg(long = "not", value_parser = parse_point, allow_hyphen_values = true)]
    not: Vec<(f32, f32)>,
    /// The frame the points are clicked on (from 0).
    #[arg(long, default_value_t = 0)]
    frame: u64,
    #[command(flatten)]
    tracking: TrackingArgs,
    /// Radius of each point's disc in pixels.
    #[arg(long, default_value_t = DEFAULT_RADIUS, value_parser = parse_radius, allow_negative_numbers = true)]
    radius: f32,
    /// Write the overlay as an animated PNG preview even where ffmpeg could encode an MP4.
    #[arg(long)]
    preview: bool,
    /// Output folder; written whole, replacing only an earlier track
    /// output (docs/outputs.md).
    #[arg(long)]
    out: PathBuf,
}

/// The model, where it runs and how it follows a material: what `matseg
/// track` and `matseg eval track` share.
#[derive(clap::Args)]
pub struct TrackingArgs {
    /// The model: `default` (the shipped one), a run folder or its weights file.
    #[arg(long, default_value = "default")]
    model: PathBuf,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Longer side frames are described at, in pixels (one net pass a frame).
    #[arg(long, default_value_t = DEFAULT_TRACK_SIDE)]
    side: u32,
    #[command(flatten)]
    tracker: TrackerArgs,
}

impl TrackingArgs {
    /// The model, loaded on its device.
    fn load(&self) -> Result<Model> {
        Ok(load_model(&self.model, parse_device(&self.device)?)?)
    }
}

/// The tracker's settings (docs/video.md).
#[derive(clap::Args)]
pub struct TrackerArgs {
    /// Frames whose confident cells each point remembers (0: the clicked
    /// descriptor alone on every frame).
    #[arg(long, default_value_t = TrackOptions::default().memory)]
    memory: usize,
    /// Cells remembered per frame and point, each way, at most.
    #[arg(long, default_value_t = TrackOptions::default().samples)]
    samples: usize,
    /// The probability a cell needs to be remembered as the material (its
    /// complement: as not).
    #[arg(long, default_value_t = TrackOptions::default().confident)]
    confident: f32,
    /// The cosine standing for "not the material" before anything else is remembered.
    #[arg(long, default_value_t = TrackOptions::default().prior)]
    prior: f32,
    /// Temperature of the probability (the cosine scale of a decision).
    #[arg(long, default_value_t = TrackOptions::default().temperature)]
    temperature: f32,
}

impl TrackerArgs {
    fn options(&self) -> TrackOptions {
        TrackOptions {
            memory: self.memory,
            samples: self.samples,
            confident: self.confident,
            prior: self.prior,
            temperature: self.temperature,
        }
    }
}

/// Runs `matseg track`.
pub fn run(args: Args) -> Result<()> {
    let source = FrameSource::open(&args.video)?;
    let net = args.tracking.load()?;
    let settings = TrackSettings {
        points: args.points,
        negatives: args.not,
        frame: args.frame,
        radius: args.radius,
        side: args.tracking.side,
        options: args.tracking.tracker.options(),
    };
    let report = track_to_folder(
        &net,
        &source,
        &settings,
        &args.out,
        TrackFiles {
            mp4: !args.preview,
            frames: false,
        },
        &BarProgress::default(),
    )?;
    println!(
        "{}: {} frames, labels/, similarity/, {} and track.json",
        args.out.display(),
        report.frames,
        report.overlay
    );
    eprintln!(
        "{}x{} frames: {:.0} ms a frame to decode, describe and track, {:.0} ms with its files written (medians after the first)",
        report.width,
        report.height,
        1e3 * report.median_track_seconds,
        1e3 * report.median_frame_seconds
    );
    Ok(())
}

/// Arguments of `matseg eval track`.
#[derive(clap::Args)]
pub struct EvalArgs {
    /// A dataset of sequences from `matseg generate --kind 3d --frames F`.
    bench: PathBuf,
    #[command(flatten)]
    tracking: TrackingArgs,
    /// Print JSON (stable field names, every query's per-frame IoUs) instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `matseg eval track`.
pub fn eval(args: EvalArgs) -> Result<()> {
    let tracking = &args.tracking;
    let net = load_model(&tracking.model, parse_device(&tracking.device)?)?;
    let settings = TrackBenchSettings {
        side: args.tracking.side,
        options: args.tracking.tracker.options(),
        ..TrackBenchSettings::default()
    };
    let report = eval_track(&net, &args.bench, &settings)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: {} sequences, {} clicked materials, {} frames (side {})",
        report.benchmark, report.sequences, report.queries, report.frames, report.side
    );
    println!("| method | mean IoU | after the clicked frame | worst frame |");
    println!("|---|---|---|---|");
    for (name, s) in [
        (
            format!("memory {}", report.tracker.memory),
            &report.with_memory,
        ),
        ("first frame only".to_string(), &report.first_frame_only),
    ] {
        println!(
            "| {name} | {:.4} | {:.4} | {:.4} |",
            s.mean_iou, s.mean_iou_after_first, s.worst_frame_iou
        );
    }
    let row = |s: &matseg_pipeline::track_bench::TrackScores| {
        s.by_distance
            .iter()
            .map(|v| format!("{v:.3}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!(
        "by distance from the clicked frame, memory: {}",
        row(&report.with_memory)
    );
    println!(
        "by distance from the clicked frame, first frame only: {}",
        row(&report.first_frame_only)
    );
    Ok(())
}
