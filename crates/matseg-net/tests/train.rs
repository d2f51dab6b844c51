//! Training runs: checkpoints resume exactly, the metrics log stays one line
//! per step, batches follow the plan, and a checkpoint of another net is
//! refused.

mod common;

use matseg_image::device::ComputeDevice;
use matseg_net::colour::COLOUR_PART;
use matseg_net::data::{batch_samples, BatchPlan, GeneratorSource};
use matseg_net::infer::{PixelDescriptors, TrainedNet};
use matseg_net::train::{
    self, RunConfig, StepMetrics, TrainOptions, Trainer, TrainingData, Validation,
};
use matseg_net::{load_net_adding, NetError};
use matseg_query::descriptor::Comparison;
use matseg_scene::Recipe2d;
use std::path::Path;
use tch::Device;

fn source() -> GeneratorSource<'static> {
    let mut recipe = Recipe2d::default();
    recipe.scene.size_min = 64;
    recipe.scene.size_max = 128;
    common::generator(recipe, 5)
}

const PLAN: BatchPlan = BatchPlan {
    min_side: 64,
    max_side: 96,
    pixels: 3 * 64 * 64,
    min_images: 2,
    max_images: 3,
    p_augment: 0.5,
};

fn config(steps: u64) -> RunConfig {
    RunConfig {
        net: common::tiny_net(false),
        options: TrainOptions {
            steps,
            lr: 1e-3,
            warmup: 2,
            decay: 0,
            weight_decay: 4e-5,
            plan: PLAN,
            seed: 11,
            checkpoint_every: 3,
            validation_batches: 1,
            lr_scales: Vec::new(),
        },
        init: "scratch".into(),
        data: "generator".into(),
        mix: None,
        inference_side: None,
        extra_inference_sides: Vec::new(),
        features: None,
    }
}

/// A 64x48 colour gradient.
fn photo() -> image::RgbImage {
    image::RgbImage::from_fn(64, 48, |x, y| {
        image::Rgb([(x * 4) as u8, (y * 5) as u8, 90])
    })
}

/// A score that depends on every weight: the mean first descriptor
/// component of [`photo`] under a snapshot of the net.
fn first_component(trainer: &Trainer) -> Result<f64, NetError> {
    let map = TrainedNet::snapshot(trainer)?.descriptor_map(&photo());
    let firsts: Vec<f32> = map.data.iter().step_by(map.dim).copied().collect();
    Ok(firsts.iter().map(|&v| v as f64).sum::<f64>() / firsts.len() as f64)
}

/// `m` with its wall-clock timings cleared, which differ run to run.
fn untimed(m: &StepMetrics) -> StepMetrics {
    StepMetrics {
        seconds: 0.0,
        data_seconds: 0.0,
        ..m.clone()
    }
}

fn train_to(trainer: &mut Trainer, steps: u64, dir: &Path) -> Vec<StepMetrics> {
    trainer.config.options.steps = steps;
    let source = source();
    let mut seen = Vec::new();
    let validation = Validation {
        samples: Some(&source),
        points: Some(&first_component),
    };
    train::run(
        trainer,
        TrainingData::Samples(&source),
        validation,
        dir,
        2,
        |m| seen.push(m.clone()),
    )
    .unwrap();
    seen
}

#[test]
fn a_resumed_run_takes_exactly_the_same_steps() {
    let dir = tempfile::tempdir().unwrap();
    let copy = tempfile::tempdir().unwrap();
    tch::manual_seed(3);
    let mut trainer = Trainer::new(config(6), Device::Cpu);
    train::write_run_config(dir.path(), &trainer.config).unwrap();
    let early = train_to(&mut trainer, 3, dir.path());
    assert_eq!(early.len(), 3);
    assert!(
        early[2].validation.is_some() && early[2].val_points.is_some(),
        "validation at the checkpoint"
    );
    assert!(early[..2]
        .iter()
        .all(|m| m.validation.is_none() && m.val_points.is_none()));
    for f in std::fs::read_dir(dir.path()).unwrap() {
        let f = f.unwrap().path();
        std::fs::copy(&f, copy.path().join(f.file_name().unwrap())).unwrap();
    }
    let at_3 = std::fs::read(copy.path().join(train::MODEL_FILE)).unwrap();
    let straight = train_to(&mut trainer, 6, dir.path());
    // best.safetensors holds the weights of the checkpoint that scored best.
    let best = std::fs::read(dir.path().join(train::BEST_MODEL_FILE)).unwrap();
    let at_6 = std::fs::read(dir.path().join(train::MODEL_FILE)).unwrap();
    assert_ne!(at_3, at_6);
    let (score_3, score_6) = (early[2].val_points, straight[2].val_points);
    assert_eq!(best, if score_6 > score_3 { at_6 } else { at_3 });

    let mut resumed = Trainer::resume(copy.path(), Device::Cpu).unwrap();
    assert_eq!(resumed.step, 3);
    let again = train_to(&mut resumed, 6, copy.path());
    assert_eq!(straight.len(), 3);
    for (a, b) in straight.iter().zip(&again) {
        assert_eq!(untimed(a), untimed(b), "step {}", a.step);
    }
    assert!(straight.iter().any(|m| m.loss.is_some()));
    assert!(straight
        .iter()
        .all(|m| m.seconds > 0.0 && (0.0..=m.seconds).contains(&m.data_seconds)));

    let log = std::fs::read_to_string(copy.path().join(train::METRICS_FILE)).unwrap();
    let steps: Vec<u64> = log
        .lines()
        .map(|l| serde_json::from_str::<StepMetrics>(l).unwrap().step)
        .collect();
    assert_eq!(steps, [0, 1, 2, 3, 4, 5]);
    assert!(copy.path().join(train::PLOT_FILE).is_file());
    assert!(copy.path().join(train::MODEL_FILE).is_file());
}

#[test]
fn a_checkpoint_of_another_net_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let trainer = Trainer::new(config(1), Device::Cpu);
    trainer.save(dir.path()).unwrap();
    let mut other = config(1);
    other.net.descriptor_dim = 16;
    train::write_run_config(dir.path(), &other).unwrap();
    let err = Trainer::resume(dir.path(), Device::Cpu)
        .err()
        .unwrap()
        .to_string();
    assert!(err.ends_with("checkpoint.safetensors: head.bias has shape [8], the net expects [16]: a checkpoint of another net"), "{err}");
}

#[test]
fn batches_follow_the_plan_and_keep_the_ground_truth_consistent() {
    let source = source();
    for step in 0..6 {
        let batch = batch_samples(&source, &PLAN, 1, step).unwrap();
        assert!((2..=3).contains(&batch.len()));
        let (w, h) = (batch[0].width, batch[0].height);
        assert!([64, 96].contains(&w) && [64, 96].contains(&h));
        for s in &batch {
            assert_eq!((s.width, s.height), (w, h));
            assert_eq!(s.rgb.len(), w * h * 3);
            for i in 0..w * h {
                let sum: f32 = s.weights.iter().map(|p| p[i]).sum();
                assert!(sum <= 1.0 + 1e-4, "weights sum {sum}");
                assert!(s.roi[i] == 0.0 || s.roi[i] == 1.0);
                if s.roi[i] == 1.0 {
                    assert!(sum > 0.45, "ROI pixel with weight sum {sum}");
                }
            }
        }
        // The same step draws the same batch.
        let again = batch_samples(&source, &PLAN, 1, step).unwrap();
        assert_eq!(batch[0].rgb, again[0].rgb);
    }
}

#[test]
fn a_snapshot_describes_like_the_saved_model() {
    let dir = tempfile::tempdir().unwrap();
    tch::manual_seed(5);
    let trainer = Trainer::new(config(1), Device::Cpu);
    train::write_run_config(dir.path(), &trainer.config).unwrap();
    trainer.save(dir.path()).unwrap();
    let live = TrainedNet::snapshot(&trainer)
        .unwrap()
        .descriptor_map(&photo());
    let saved = TrainedNet::load(dir.path(), ComputeDevice::Cpu)
        .unwrap()
        .descriptor_map(&photo());
    assert_eq!((live.width, live.height, live.dim), (64, 48, 8));
    assert_eq!(live, saved);
    for i in 0..live.width * live.height {
        let n: f32 = live.at(i).iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-4, "pixel {i}: |d|^2 = {n}");
    }
}

#[test]
fn the_coarse_grid_answers_points_like_the_full_map() {
    tch::manual_seed(6);
    let trainer = Trainer::new(config(1), Device::Cpu);
    let net = TrainedNet::snapshot(&trainer).unwrap();
    // A 70x50 photo runs at 64x64 (sides to multiples of 32): a 16x16 grid.
    let photo = image::RgbImage::from_fn(70, 50, |x, y| {
        image::Rgb([(x * 3) as u8, (y * 5) as u8, if x < 35 { 40 } else { 200 }])
    });
    let coarse = net.describe_coarse(photo.as_raw(), 70, 50);
    assert_eq!((coarse.width, coarse.height), (70, 50));
    assert_eq!((coarse.grid.width, coarse.grid.height), (16, 16));
    for i in 0..16 * 16 {
        let n: f32 = coarse.grid.at(i).iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-4, "cell {i}: |d|^2 = {n}");
    }
    // Resizing the cosine instead of the descriptors changes a map little,
    // and a point pooled from the grid is close to one pooled from pixels.
    let full = net.descriptor_map(&photo);
    for (x, y) in [(10.0, 10.0), (60.0, 40.0)] {
        let query = full.point_descriptor(x, y, 4.0, Comparison::Cosine);
        let fast = coarse.similarity_map(&query);
        let exact = full.similarity_map(&query, Comparison::Cosine);
        let mean_error = fast
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .sum::<f32>()
            / fast.len() as f32;
        assert!(mean_error < 0.02, "({x}, {y}): mean error {mean_error}");
        let pooled = Comparison::Cosine.similarity(&query, &coarse.point_descriptor(x, y, 4.0));
        assert!(pooled > 0.99, "({x}, {y}): cosine {pooled}");
    }
    // With a longest side of 32 px the net runs at 32x32: an 8x8 grid,
    // queried in the photo's pixels all the same.
    let mut small = net;
    small.inference_side = Some(32);
    let coarse = small.describe_coarse(photo.as_raw(), 70, 50);
    assert_eq!((coarse.grid.width, coarse.grid.height), (8, 8));
    assert_eq!(
        coarse
            .similarity_map(&coarse.point_descriptor(5.0, 5.0, 3.0))
            .len(),
        70 * 50
    );
    assert_eq!(small.descriptor_map(&photo).width, 70);
}

#[test]
fn the_learning_rate_warms_up_and_decays_linearly() {
    let mut config = config(10);
    config.options.decay = 4;
    let trainer = Trainer::new(config, Device::Cpu);
    let lrs: Vec<f64> = (0..10).map(|s| trainer.lr(s) / 1e-3).collect();
    let expected = [0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.75, 0.5, 0.25];
    for (got, want) in lrs.iter().zip(expected) {
        assert!((got - want).abs() < 1e-12, "{lrs:?}");
    }
}

#[test]
fn a_net_without_a_colour_part_continues_with_a_fresh_one() {
    let dir = tempfile::tempdir().unwrap();
    let plain = Trainer::new(config(1), Device::Cpu);
    let weights = dir.path().join("plain.safetensors");
    plain.save_weights(&weights).unwrap();
    let bytes = std::fs::read(&weights).unwrap();
    let tensors = matseg_weights::read_safetensors(&bytes, "plain").unwrap();
    let mut coloured = config(1);
    coloured.net.colour_features = true;
    let trainer = Trainer::new(coloured, Device::Cpu);
    let fresh_projection = trainer.vs.variables()["colour.projection"].copy();
    let (copied, fresh) = load_net_adding(&trainer.vs, &tensors, COLOUR_PART, "plain").unwrap();
    assert_eq!((copied, fresh), (tensors.len(), 4));
    // The plain net's weights are taken, the colour part keeps its own.
    let variables = trainer.vs.variables();
    assert_eq!(variables["head.bias"], plain.vs.variables()["head.bias"]);
    assert_eq!(variables["colour.projection"], fresh_projection);
    // Any other variable the file lacks is still an error.
    let without_head: Vec<_> = tensors
        .into_iter()
        .filter(|t| t.name != "head.bias")
        .collect();
    let err = load_net_adding(&trainer.vs, &without_head, COLOUR_PART, "plain")
        .unwrap_err()
        .to_string();
    assert_eq!(err, "plain: no parameter head.bias");
}
