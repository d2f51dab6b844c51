//! Scoring tracking on generated sequences (`matseg eval track`,
//! pipeline.md §9.4): a dataset of 3D sequences (`matseg generate --kind 3d
//! --frames F`) whose frames carry exact masks. In each sequence every
//! main-object material large enough is clicked once on the first frame,
//! at the pure pixel deepest inside it, and followed alone through the
//! frames; each frame is scored by IoU at the best threshold (as `eval
//! masks`) inside the ROI, with the memory and with the clicked descriptor
//! alone, so the memory's gain is measured on the same clicks.
//!
//! Any [`FrameDescriber`] can be scored: matseg's nets, and models written
//! in Python (`matseg.evaluate.track`).

use crate::error::PipelineError;
use crate::segment::Model;
use image::RgbImage;
use matseg_data::{Dataset, FrameOf, Sample};
use matseg_eval::iou::best_iou;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::tracking::{MaterialTracker, TrackOptions};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// How the benchmark is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackBenchSettings {
    /// The longer side frames are described at.
    pub side: u32,
    /// The tracker's memory (scored against [`TrackOptions::first_frame_only`]).
    pub options: TrackOptions,
    /// Radius of the clicked disc, in pixels.
    pub radius: f32,
    /// A material is clicked when its pure pixels (mask 255) cover at
    /// least this share of the first frame's ROI.
    pub min_share: f64,
}

impl Default for TrackBenchSettings {
    fn default() -> Self {
        TrackBenchSettings {
            side: crate::track::DEFAULT_TRACK_SIDE,
            options: TrackOptions::default(),
            radius: crate::segment::DEFAULT_RADIUS,
            min_share: 0.02,
        }
    }
}

/// One clicked material followed through its sequence.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackedQuery {
    /// The sequence.
    pub sequence: u64,
    /// The material (mask index).
    pub material: usize,
    /// The click on the first frame, in pixels.
    pub point: [f32; 2],
    /// Per frame, the IoU with the memory (`None`: the material is out of
    /// view on that frame).
    pub memory: Vec<Option<f64>>,
    /// Per frame, the IoU with the clicked descriptor alone.
    pub first_frame_only: Vec<Option<f64>>,
}

/// One method's scores over the benchmark.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackScores {
    /// Mean over the queries of each query's mean IoU over its frames.
    pub mean_iou: f64,
    /// The same on frames after the clicked one.
    pub mean_iou_after_first: f64,
    /// The lowest IoU of any query on any frame.
    pub worst_frame_iou: f64,
    /// Mean IoU at each distance from the clicked frame (0, 1, ...).
    pub by_distance: Vec<f64>,
}

/// What the tracking benchmark asks of a model: each frame's unit
/// descriptors on a grid over it (any stride), compared by cosine.
pub trait FrameDescriber {
    /// Its name in the report.
    fn name(&self) -> &str;

    /// The descriptors of `frame` (frame `index` of sequence `sequence`,
    /// from the file `path`), described at longer side `side` at most.
    fn describe_frame(
        &self,
        frame: &RgbImage,
        side: u32,
        frame_of: (u64, usize),
        path: &Path,
    ) -> Result<CoarseDescriptors, PipelineError>;
}

impl FrameDescriber for Model {
    fn name(&self) -> &str {
        matseg_query::descriptor::DescriptorModel::name(self)
    }

    fn describe_frame(
        &self,
        frame: &RgbImage,
        side: u32,
        _: (u64, usize),
        _: &Path,
    ) -> Result<CoarseDescriptors, PipelineError> {
        Ok(self.net().describe_frame(frame, side))
    }
}

/// The benchmark's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackBenchReport {
    /// The model scored.
    pub model: String,
    /// The dataset folder.
    pub benchmark: String,
    /// Sequences scored.
    pub sequences: usize,
    /// Materials clicked.
    pub queries: usize,
    /// Frames scored (over all sequences).
    pub frames: usize,
    /// The side frames were described at.
    pub side: u32,
    /// The tracker's settings.
    pub tracker: TrackOptions,
    /// With the memory.
    pub with_memory: TrackScores,
    /// With the clicked descriptor alone.
    pub first_frame_only: TrackScores,
    /// Every query.
    pub per_query: Vec<TrackedQuery>,
}

/// Scores `model` on the sequences in `root`.
pub fn eval_track(
    model: &dyn FrameDescriber,
    root: &Path,
    settings: &TrackBenchSettings,
) -> Result<TrackBenchReport, PipelineError> {
    let sequences = read_sequences(root)?;
    let mut per_query = Vec::new();
    let mut frames = 0;
    for (&sequence, indices) in &sequences {
        let dataset = &indices.0;
        let first = dataset.get(indices.1[0])?;
        let clicks = clicks(&first, settings);
        if clicks.is_empty() {
            continue;
        }
        let describe = |sample: &Sample, f: usize| {
            let path = root.join(dataset.key(indices.1[f]));
            model.describe_frame(&sample.image, settings.side, (sequence, f), &path)
        };
        let first_map = describe(&first, 0)?;
        let start = |options| {
            clicks
                .iter()
                .map(|&(_, x, y)| {
                    MaterialTracker::new(
                        vec![first_map.point_descriptor(x, y, settings.radius)],
                        options,
                    )
                })
                .collect::<Vec<_>>()
        };
        let mut with_memory = start(settings.options);
        for tracker in &mut with_memory {
            tracker.step(&first_map);
        }
        let mut alone = start(TrackOptions::first_frame_only());
        let mut queries: Vec<TrackedQuery> = clicks
            .iter()
            .map(|&(material, x, y)| TrackedQuery {
                sequence,
                material,
                point: [x, y],
                memory: Vec::new(),
                first_frame_only: Vec::new(),
            })
            .collect();
        for (f, &i) in indices.1.iter().enumerate() {
            let sample = if f == 0 {
                first.clone()
            } else {
                dataset.get(i)?
            };
            let map = if f == 0 {
                first_map.clone()
            } else {
                describe(&sample, f)?
            };
            frames += 1;
            for (q, query) in queries.iter_mut().enumerate() {
                let truth = truth_in_roi(&sample, query.material);
                let score = |tracker: &mut MaterialTracker| {
                    let margins = tracker.step(&map).remove(0);
                    let similarity = map.resize_to_photo(&margins);
                    let (scores, mask): (Vec<f32>, Vec<bool>) = truth
                        .iter()
                        .filter_map(|&(j, t)| Some((similarity[j], t?)))
                        .unzip();
                    best_iou(&scores, &mask).map(|b| b.iou)
                };
                query.memory.push(score(&mut with_memory[q]));
                query.first_frame_only.push(score(&mut alone[q]));
            }
        }
        per_query.extend(queries);
    }
    if per_query.is_empty() {
        return Err(PipelineError::file(
            root.display(),
            "no material large enough to click on any sequence's first frame",
        ));
    }
    Ok(TrackBenchReport {
        model: model.name().to_string(),
        benchmark: root.display().to_string(),
        sequences: sequences.len(),
        queries: per_query.len(),
        frames,
        side: settings.side,
        tracker: settings.options,
        with_memory: summarise(per_query.iter().map(|q| q.memory.as_slice())),
        first_frame_only: summarise(per_query.iter().map(|q| q.first_frame_only.as_slice())),
        per_query,
    })
}

/// The sequences of the dataset at `root`: per sequence, the dataset and
/// its samples' indices in frame order. Every sample must be a frame of a
/// sequence, and every sequence complete.
#[allow(clippy::type_complexity)]
fn read_sequences(root: &Path) -> Result<BTreeMap<u64, (Dataset, Vec<usize>)>, PipelineError> {
    let dataset = Dataset::open(root)?;
    let mut frames: BTreeMap<u64, Vec<(u32, u32, usize)>> = BTreeMap::new();
    for i in 0..dataset.len() {
        let sample = dataset.get(i)?;
        let frame: FrameOf = sample
            .meta
            .as_ref()
            .and_then(|m| serde_json::from_value(m.get("frame")?.clone()).ok())
            .ok_or_else(|| {
                PipelineError::file(
                    root.join(dataset.key(i)).display(),
                    "not a frame of a sequence (its meta.json has no \"frame\"; make sequences with `matseg generate --kind 3d --frames F`)",
                )
            })?;
        frames
            .entry(frame.sequence)
            .or_default()
            .push((frame.frame, frame.frames, i));
    }
    let mut sequences = BTreeMap::new();
    for (sequence, mut list) in frames {
        list.sort();
        let expected = list[0].1 as usize;
        let numbered = list
            .iter()
            .enumerate()
            .all(|(f, &(frame, _, _))| frame as usize == f);
        if list.len() != expected || !numbered {
            return Err(PipelineError::file(
                root.display(),
                format!(
                    "sequence {sequence} has {} of its {expected} frames: generate the rest (the same command resumes)",
                    list.len()
                ),
            ));
        }
        sequences.insert(
            sequence,
            (dataset.clone(), list.iter().map(|l| l.2).collect()),
        );
    }
    Ok(sequences)
}

/// Per pixel, its index and, inside the ROI, whether it is `material`
/// (mask at least 128); `None` outside the ROI.
fn truth_in_roi(sample: &Sample, material: usize) -> Vec<(usize, Option<bool>)> {
    let mask = sample.masks.get(material);
    (0..sample.image.as_raw().len() / 3)
        .map(|j| {
            let inside = sample.roi.as_ref().is_none_or(|r| r.as_raw()[j] >= 128);
            let is = mask.is_some_and(|m| m.as_raw()[j] >= 128);
            (j, inside.then_some(is))
        })
        .collect()
}

/// The clicks on a first frame: per material whose pure pixels cover
/// `settings.min_share` of the ROI, the pure pixel farthest from any other
/// (ties: the first in row order), as (material, x, y).
pub fn clicks(first: &Sample, settings: &TrackBenchSettings) -> Vec<(usize, f32, f32)> {
    let (w, h) = first.image.dimensions();
    let roi_pixels = first.roi.as_ref().map_or((w * h) as usize, |r| {
        r.as_raw().iter().filter(|&&v| v >= 128).count()
    });
    let mut out = Vec::new();
    for (k, mask) in first.masks.iter().enumerate() {
        let pure: Vec<bool> = mask.as_raw().iter().map(|&v| v == 255).collect();
        let count = pure.iter().filter(|&&p| p).count();
        if count == 0 || (count as f64) < settings.min_share * roi_pixels as f64 {
            continue;
        }
        let depth = chessboard_depth(&pure, w as usize, h as usize);
        let (best, _) = depth
            .iter()
            .enumerate()
            .fold((0, 0u32), |a, (j, &d)| if d > a.1 { (j, d) } else { a });
        out.push((k, (best % w as usize) as f32, (best / w as usize) as f32));
    }
    out
}

/// Per pixel, how many steps (8-neighbour) it is from the nearest pixel
/// outside `inside` or the image's edge: 0 outside, 1 on the border.
fn chessboard_depth(inside: &[bool], w: usize, h: usize) -> Vec<u32> {
    let mut d: Vec<u32> = inside
        .iter()
        .map(|&i| if i { u32::MAX / 2 } else { 0 })
        .collect();
    let at = |x: isize, y: isize, d: &[u32]| -> u32 {
        if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
            0
        } else {
            d[y as usize * w + x as usize]
        }
    };
    for y in 0..h as isize {
        for x in 0..w as isize {
            let j = y as usize * w + x as usize;
            if d[j] > 0 {
                let n = [(-1, -1), (0, -1), (1, -1), (-1, 0)]
                    .iter()
                    .map(|&(dx, dy)| at(x + dx, y + dy, &d))
                    .min()
                    .unwrap_or(0);
                d[j] = d[j].min(n + 1);
            }
        }
    }
    for y in (0..h as isize).rev() {
        for x in (0..w as isize).rev() {
            let j = y as usize * w + x as usize;
            if d[j] > 0 {
                let n = [(1, 1), (0, 1), (-1, 1), (1, 0)]
                    .iter()
                    .map(|&(dx, dy)| at(x + dx, y + dy, &d))
                    .min()
                    .unwrap_or(0);
                d[j] = d[j].min(n + 1);
            }
        }
    }
    d
}

/// A method's scores from each query's per-frame IoUs.
fn summarise<'a>(queries: impl Iterator<Item = &'a [Option<f64>]>) -> TrackScores {
    let mean = |v: &[f64]| {
        if v.is_empty() {
            0.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let (mut per_query, mut after_first, mut worst) = (Vec::new(), Vec::new(), 1f64);
    let mut by_distance: Vec<Vec<f64>> = Vec::new();
    for frames in queries {
        let seen: Vec<f64> = frames.iter().flatten().copied().collect();
        let later: Vec<f64> = frames.iter().skip(1).flatten().copied().collect();
        per_query.push(mean(&seen));
        if !later.is_empty() {
            after_first.push(mean(&later));
        }
        worst = seen.iter().copied().fold(worst, f64::min);
        for (d, iou) in frames.iter().enumerate() {
            if by_distance.len() <= d {
                by_distance.push(Vec::new());
            }
            by_distance[d].extend(iou);
        }
    }
    TrackScores {
        mean_iou: mean(&per_query),
        mean_iou_after_first: mean(&after_first),
        worst_frame_iou: worst,
        by_distance: by_distance.iter().map(|v| mean(v)).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_deepest_pixel_is_the_centre_of_a_square() {
        // A 7x5 image whose pixels x in 1..=5, y in 0..=4 are inside.
        let inside: Vec<bool> = (0..35).map(|j| (1..=5).contains(&(j % 7))).collect();
        let d = chessboard_depth(&inside, 7, 5);
        assert_eq!(d[0], 0);
        assert_eq!(d[7 + 1], 1);
        assert_eq!(d[2 * 7 + 3], 3);
        assert_eq!(*d.iter().max().unwrap(), 3);
    }

    #[test]
    fn scores_average_queries_and_keep_the_worst_frame() {
        let a = vec![Some(1.0), Some(0.5), None];
        let b = vec![Some(0.8), Some(0.6), Some(0.4)];
        let s = summarise([a.as_slice(), b.as_slice()].into_iter());
        assert!((s.mean_iou - (0.75 + 0.6) / 2.0).abs() < 1e-12);
        assert!((s.mean_iou_after_first - (0.5 + 0.5) / 2.0).abs() < 1e-12);
        assert_eq!(s.worst_frame_iou, 0.4);
        assert_eq!(s.by_distance.len(), 3);
        assert!((s.by_distance[1] - 0.55).abs() < 1e-12);
        assert!((s.by_distance[2] - 0.4).abs() < 1e-12);
    }
}
