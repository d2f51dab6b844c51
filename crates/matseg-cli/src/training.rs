//! Training shown as the CLI shows it (`matseg train` and the
//! demo's training run): a step bar with the recent loss and validation
//! scores, then the run's model file and its speed.

use anyhow::Result;
use indicatif::{ProgressBar, ProgressStyle};
use matseg_pipeline::train::{TrainInputs, TrainSummary, TrainingRun};
use std::path::Path;

/// Trains `run` to its planned steps with a progress bar on stderr, then
/// prints where the model is and how fast it trained on `device` (its
/// name as given).
pub fn train_with_bar(run: &mut TrainingRun, inputs: &TrainInputs, device: &str) -> Result<()> {
    let bar = ProgressBar::new(run.config().options.steps).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {per_sec} ETA {eta} {msg}")
            .expect("template"),
    );
    bar.set_position(run.step());
    let mut recent: Vec<f64> = Vec::new();
    let summary = run.train(inputs, |m| {
        if let Some(l) = m.loss {
            recent.push(l);
        }
        let tail = &recent[recent.len().saturating_sub(20)..];
        let mean = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
        let val = m
            .validation
            .map(|v| format!(" val {v:.4}"))
            .unwrap_or_default();
        let points = m
            .val_points
            .map(|v| format!(" points {v:.4}"))
            .unwrap_or_default();
        bar.set_message(format!("loss {mean:.4}{val}{points}"));
        bar.inc(1);
    })?;
    bar.finish();
    print_trained(run.dir(), run.step(), &run.model_file(), &summary, device);
    Ok(())
}

/// Prints where a run's model is and how fast this call trained on
/// `device` (its name as given).
pub fn print_trained(dir: &Path, step: u64, model: &Path, summary: &TrainSummary, device: &str) {
    println!("{}: {step} steps; model {}", dir.display(), model.display());
    println!(
        "{} steps in {:.1} s on {device}: {:.1} images/s, {:.2} Mpixel/s (checkpoints and validation included); \
         {:.1} s waiting for batches from {} loader thread(s)",
        summary.steps,
        summary.seconds,
        summary.images as f64 / summary.seconds,
        summary.pixels as f64 / summary.seconds / 1e6,
        summary.waited,
        summary.loader_threads
    );
}
