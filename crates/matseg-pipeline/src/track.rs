//! Following clicked materials through a video (pipeline.md §8.2): the
//! points' descriptors are taken on the clicked frame, then every frame
//! from the first is described at one reduced side and scored by a
//! [`MaterialTracker`], whose memory of confident cells keeps the material
//! as light and viewpoint change. [`Tracking`] does it for frames handed
//! over one at a time (the web app, Python); [`track_to_folder`] for a
//! whole frame folder or video, streaming: one frame in memory, each
//! frame's maps written as it is done.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file, write_folder};
use crate::frames::FrameSource;
use crate::overlay_video::OverlayVideo;
use crate::progress::Progress;
use crate::segment::{check_clicks, check_contradictions, check_points, outline_disc, Model};
use image::RgbImage;
use matseg_image::io::{encode_jpeg, encode_png_grey};
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::descriptor::check_radius;
use matseg_query::tracking::{MaterialTracker, TrackOptions};
use matseg_scene::PALETTE;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The longer side frames are described at, unless a caller says otherwise.
pub const DEFAULT_TRACK_SIDE: u32 = 320;

/// The probability at which a pixel takes a point's label: the tracker's
/// own decision, its material nearer than anything else it remembers.
pub const LABEL_PROBABILITY: f32 = 0.5;

/// The most points followed at once (labels are 8-bit, 0 is "none").
pub const MAX_TRACK_POINTS: usize = 254;

/// What to follow and how.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackSettings {
    /// The clicked points, in pixels of the clicked frame.
    pub points: Vec<(f32, f32)>,
    /// Negative clicks on the clicked frame: materials followed too, so
    /// that no point's material takes them, but never labelled or
    /// reported.
    pub negatives: Vec<(f32, f32)>,
    /// The frame they were clicked on (from 0).
    pub frame: u64,
    /// Radius of each point's disc, in pixels.
    pub radius: f32,
    /// The longer side frames are described at.
    pub side: u32,
    /// The tracker's memory.
    pub options: TrackOptions,
}

impl TrackSettings {
    /// `points` clicked on the first frame, with the defaults.
    pub fn new(points: Vec<(f32, f32)>) -> Self {
        TrackSettings {
            points,
            negatives: Vec::new(),
            frame: 0,
            radius: crate::segment::DEFAULT_RADIUS,
            side: DEFAULT_TRACK_SIDE,
            options: TrackOptions::default(),
        }
    }
}

/// One frame's answer.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackedFrame {
    /// Per point, the probability of every pixel that it is the point's
    /// material (row by row, the frame's size).
    pub similarity: Vec<Vec<f32>>,
    /// Each pixel's label: `k + 1` where point `k` is the likeliest and its
    /// probability reaches [`LABEL_PROBABILITY`], else 0.
    pub labels: Vec<u8>,
    /// Per point, the share of the frame's pixels labelled with it.
    pub areas: Vec<f64>,
}

/// What describes the frames: a model of the caller's own, or one shared
/// behind a lock (the web app's), taken for one frame at a time so other
/// requests are answered between frames.
pub trait FrameDescriber {
    /// The model's descriptors of `frame` at longer side `side`.
    fn describe_frame(&self, frame: &RgbImage, side: u32) -> CoarseDescriptors;
}

impl FrameDescriber for Model {
    fn describe_frame(&self, frame: &RgbImage, side: u32) -> CoarseDescriptors {
        self.net().describe_frame(frame, side)
    }
}

/// Points followed through frames given one at a time, in order; each
/// call is handed the model that describes the frame.
pub struct Tracking {
    tracker: MaterialTracker,
    /// How many of the tracker's materials are reported: the points'
    /// (the negative clicks' follow them).
    reported: usize,
    side: u32,
    size: (u32, u32),
}

impl Tracking {
    /// Starts following the materials under `settings.points` on `clicked`
    /// (the frame they were clicked on); `label` names that frame in errors.
    pub fn start(
        model: &dyn FrameDescriber,
        clicked: &RgbImage,
        settings: &TrackSettings,
        label: &str,
    ) -> Result<Self, PipelineError> {
        if settings.points.is_empty() {
            return Err(PipelineError::setting(
                "point",
                None::<&str>,
                "give at least one point",
            ));
        }
        let clicks = settings.points.len() + settings.negatives.len();
        if clicks > MAX_TRACK_POINTS {
            return Err(PipelineError::setting(
                "point",
                None::<&str>,
                format!("{clicks} points and negative clicks: at most {MAX_TRACK_POINTS} in all"),
            ));
        }
        check_points(clicked, &settings.points, label)?;
        check_clicks(clicked, &settings.negatives, label, "not")?;
        check_contradictions(&settings.points, &settings.negatives)?;
        check_radius(settings.radius).map_err(|e| PipelineError::Settings(e.to_string()))?;
        if !(16..=4096).contains(&settings.side) {
            return Err(PipelineError::setting(
                "side",
                Some(settings.side),
                "must be in 16..4096",
            ));
        }
        check_options(&settings.options)?;
        let map = model.describe_frame(clicked, settings.side);
        let queries = settings
            .points
            .iter()
            .chain(&settings.negatives)
            .map(|&(x, y)| map.point_descriptor(x, y, settings.radius))
            .collect();
        // The clicked frame seeds the memory: what the clicks confidently
        // are and are not there.
        let mut tracker = MaterialTracker::new(queries, settings.options);
        tracker.step(&map);
        Ok(Tracking {
            tracker,
            reported: settings.points.len(),
            side: settings.side,
            size: clicked.dimensions(),
        })
    }

    /// The frame's similarity maps, labels and areas; the memory learns
    /// from it. Frames must have the clicked frame's size.
    pub fn step(
        &mut self,
        model: &dyn FrameDescriber,
        frame: &RgbImage,
    ) -> Result<TrackedFrame, PipelineError> {
        if frame.dimensions() != self.size {
            let ((w, h), (w0, h0)) = (frame.dimensions(), self.size);
            return Err(PipelineError::file(
                "frame",
                format!("is {w}x{h}, the clicked frame {w0}x{h0}: all frames must have one size"),
            ));
        }
        let map = model.describe_frame(frame, self.side);
        let margins = self.tracker.step(&map);
        let mut similarity: Vec<Vec<f32>> = margins
            .iter()
            .map(|m| {
                let p: Vec<f32> = m.iter().map(|&m| self.tracker.probability(m)).collect();
                map.resize_to_photo(&p)
            })
            .collect();
        // The negative clicks' materials take their pixels from the
        // points', then go unreported.
        let mut labels = label_pixels(&similarity, LABEL_PROBABILITY);
        for l in labels.iter_mut().filter(|l| **l as usize > self.reported) {
            *l = 0;
        }
        similarity.truncate(self.reported);
        let mut counts = vec![0u64; similarity.len()];
        for &l in &labels {
            if l > 0 {
                counts[l as usize - 1] += 1;
            }
        }
        let pixels = labels.len().max(1) as f64;
        Ok(TrackedFrame {
            areas: counts.iter().map(|&c| c as f64 / pixels).collect(),
            similarity,
            labels,
        })
    }
}

/// Refuses tracker settings that decide nothing: a confidence outside
/// (0.5, 1), a prior outside [-1, 1], a temperature that is not positive.
fn check_options(options: &TrackOptions) -> Result<(), PipelineError> {
    let TrackOptions {
        confident,
        prior,
        temperature,
        ..
    } = *options;
    if !(confident > 0.5 && confident < 1.0) {
        return Err(PipelineError::setting(
            "confident",
            Some(confident),
            "must be above 0.5 and below 1",
        ));
    }
    if !(-1.0..=1.0).contains(&prior) {
        return Err(PipelineError::setting(
            "prior",
            Some(prior),
            "must be a cosine, in -1..1",
        ));
    }
    if !(temperature > 0.0 && temperature.is_finite()) {
        return Err(PipelineError::setting(
            "temperature",
            Some(temperature),
            "must be above 0",
        ));
    }
    Ok(())
}

/// Each pixel's label among `similarity` maps: `k + 1` for the highest
/// map `k` where it reaches `threshold`, else 0.
pub fn label_pixels(similarity: &[Vec<f32>], threshold: f32) -> Vec<u8> {
    let pixels = similarity.first().map_or(0, Vec::len);
    (0..pixels)
        .into_par_iter()
        .map(|j| {
            let (best, s) = similarity
                .iter()
                .enumerate()
                .map(|(k, m)| (k, m[j]))
                .fold((0, f32::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
            if s >= threshold {
                best as u8 + 1
            } else {
                0
            }
        })
        .collect()
}

/// `frame` with each point's material tinted in its palette colour, as
/// strongly as it is likely (three quarters at most); the clicked points'
/// discs outlined on the clicked frame.
pub fn track_overlay(
    frame: &RgbImage,
    tracked: &TrackedFrame,
    discs: &[(f32, f32)],
    radius: f32,
) -> RgbImage {
    let mut overlay = frame.clone();
    overlay.par_chunks_mut(3).enumerate().for_each(|(j, p)| {
        let (k, s) = tracked
            .similarity
            .iter()
            .enumerate()
            .map(|(k, m)| (k, m[j]))
            .fold((0, f32::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        let a = s.clamp(0.0, 1.0) * 0.75;
        let c = PALETTE[k % PALETTE.len()];
        for (v, &colour) in p.iter_mut().zip(&c) {
            *v = (*v as f32 * (1.0 - a) + colour as f32 * a).round() as u8;
        }
    });
    for &point in discs {
        outline_disc(&mut overlay, point, radius);
    }
    overlay
}

/// The files [`track_to_folder`] writes besides the labels, the
/// similarity maps and `track.json`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackFiles {
    /// The overlay as H.264 `overlay.mp4` where ffmpeg runs; when false
    /// (or without ffmpeg), the animated `overlay.png` preview.
    pub mp4: bool,
    /// Each frame as `frames/NNNNNN.jpg` (quality [`FRAME_JPEG_QUALITY`]),
    /// what the web app scrubs through.
    pub frames: bool,
}

impl Default for TrackFiles {
    fn default() -> Self {
        TrackFiles {
            mp4: true,
            frames: false,
        }
    }
}

/// The JPEG quality of the frames [`TrackFiles::frames`] keeps.
pub const FRAME_JPEG_QUALITY: u8 = 90;

/// What [`track_to_folder`] did, as written to `track.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackReport {
    /// The frame folder or video.
    pub source: String,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
    /// Frames followed.
    pub frames: u64,
    /// The frame the points were clicked on.
    pub clicked_frame: u64,
    /// The points.
    pub points: Vec<[f32; 2]>,
    /// The negative clicks (left out when there are none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub negatives: Vec<[f32; 2]>,
    /// Their discs' radius.
    pub radius: f32,
    /// The side frames were described at.
    pub side: u32,
    /// The tracker's settings.
    pub tracker: TrackOptions,
    /// The overlay's file name in the folder.
    pub overlay: String,
    /// Per frame, per point, the share of the frame labelled with it.
    pub areas: Vec<Vec<f64>>,
    /// Median seconds a frame spent on decoding, describing and tracking
    /// (writing its files aside), frames after the first.
    pub median_track_seconds: f64,
    /// Median seconds a frame spent in all, its files written.
    pub median_frame_seconds: f64,
}

/// Follows `settings.points`, clicked on frame `settings.frame` of
/// `source`, through every frame, and writes into `out`:
/// `labels/NNNNNN.png` (0: none, k: point k - 1), `similarity/K/NNNNNN.png`
/// per point (its probability, 0..1 to grey), the overlay
/// (`overlay.mp4`, or an animated `overlay.png` preview), `track.json`,
/// and the frames themselves when `files` asks. The folder is written
/// whole or not at all, as matseg_image::outputs says: refused when it
/// overlaps the source, or holds anything but an earlier track output,
/// which it replaces whole.
pub fn track_to_folder(
    model: &dyn FrameDescriber,
    source: &FrameSource,
    settings: &TrackSettings,
    out: &Path,
    files: TrackFiles,
    progress: &dyn Progress,
) -> Result<TrackReport, PipelineError> {
    write_folder(out, "track", &[&source.path], |dir| {
        track_into(model, source, settings, dir, files, progress)
    })
}

/// [`track_to_folder`]'s work, into the folder `dir`.
fn track_into(
    model: &dyn FrameDescriber,
    source: &FrameSource,
    settings: &TrackSettings,
    dir: &Path,
    files: TrackFiles,
    progress: &dyn Progress,
) -> Result<TrackReport, PipelineError> {
    let label = source.path.display().to_string();
    // A first pass up to the clicked frame.
    let clicked = source.frame(settings.frame)?;
    let mut tracking = Tracking::start(
        model,
        &clicked,
        settings,
        &format!("frame {} of {label}", settings.frame),
    )?;
    drop(clicked);
    create_folder(&dir.join("labels"))?;
    if files.frames {
        create_folder(&dir.join("frames"))?;
    }
    for k in 0..settings.points.len() {
        create_folder(&dir.join("similarity").join(k.to_string()))?;
    }
    let size = (source.width, source.height);
    let mut overlay = OverlayVideo::create(dir, size, source.fps, source.frame_count(), files.mp4)?;
    progress.start(source.frame_count(), "frames");
    let (mut areas, mut track_seconds, mut frame_seconds) = (Vec::new(), Vec::new(), Vec::new());
    let mut started = Instant::now();
    for (i, frame) in source.frames()?.enumerate() {
        if progress.cancelled() {
            return Err(PipelineError::file(
                label,
                format!("cancelled at frame {i}"),
            ));
        }
        let frame = frame?;
        let tracked = tracking
            .step(model, &frame)
            .map_err(|e| PipelineError::file(format!("frame {i} of {label}"), e.to_string()))?;
        track_seconds.push(started.elapsed().as_secs_f64());
        let name = format!("{i:06}.png");
        if files.frames {
            write_file(
                &dir.join("frames").join(format!("{i:06}.jpg")),
                &encode_jpeg(&frame, FRAME_JPEG_QUALITY),
            )?;
        }
        write_file(
            &dir.join("labels").join(&name),
            &encode_png_grey(size.0, size.1, &tracked.labels),
        )?;
        for (k, similarity) in tracked.similarity.iter().enumerate() {
            write_file(
                &dir.join("similarity").join(k.to_string()).join(&name),
                &encode_png_grey(size.0, size.1, &crate::segment::similarity_grey(similarity)),
            )?;
        }
        let discs: &[(f32, f32)] = if i as u64 == settings.frame {
            &settings.points
        } else {
            &[]
        };
        overlay.push(&track_overlay(&frame, &tracked, discs, settings.radius))?;
        areas.push(tracked.areas);
        frame_seconds.push(started.elapsed().as_secs_f64());
        progress.advance();
        started = Instant::now();
    }
    let overlay = overlay.finish()?;
    progress.finish();
    let report = TrackReport {
        source: label,
        width: size.0,
        height: size.1,
        fps: source.fps,
        frames: areas.len() as u64,
        clicked_frame: settings.frame,
        points: settings.points.iter().map(|&(x, y)| [x, y]).collect(),
        negatives: settings.negatives.iter().map(|&(x, y)| [x, y]).collect(),
        radius: settings.radius,
        side: settings.side,
        tracker: settings.options,
        overlay: overlay
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        areas,
        median_track_seconds: median_after_first(&track_seconds),
        median_frame_seconds: median_after_first(&frame_seconds),
    };
    write_file(
        &dir.join("track.json"),
        &serde_json::to_vec_pretty(&report).expect("a report serialises"),
    )?;
    Ok(report)
}

/// The median of `values` after the first (all of them when there is one).
fn median_after_first(values: &[f64]) -> f64 {
    let mut rest: Vec<f64> = values
        .iter()
        .skip(usize::from(values.len() > 1))
        .copied()
        .collect();
    if rest.is_empty() {
        return 0.0;
    }
    rest.sort_by(f64::total_cmp);
    rest[rest.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_take_the_nearest_point_that_reaches_the_threshold() {
        let maps = vec![vec![0.9, 0.5, 0.45, 0.1], vec![0.7, 0.95, 0.46, 0.2]];
        assert_eq!(label_pixels(&maps, LABEL_PROBABILITY), vec![1, 2, 0, 0]);
        assert_eq!(median_after_first(&[9.0, 1.0, 3.0, 2.0]), 2.0);
        assert_eq!(median_after_first(&[4.0]), 4.0);
    }

    #[test]
    fn tracker_settings_that_decide_nothing_are_refused() {
        assert!(check_options(&TrackOptions::default()).is_ok());
        let with = |f: fn(&mut TrackOptions)| {
            let mut options = TrackOptions::default();
            f(&mut options);
            check_options(&options).unwrap_err().to_string()
        };
        assert_eq!(
            with(|o| o.confident = 0.5),
            "confident 0.5: must be above 0.5 and below 1"
        );
        assert_eq!(
            with(|o| o.prior = 1.5),
            "prior 1.5: must be a cosine, in -1..1"
        );
        assert_eq!(
            with(|o| o.temperature = 0.0),
            "temperature 0: must be above 0"
        );
        assert_eq!(
            with(|o| o.temperature = f32::NAN),
            "temperature NaN: must be above 0"
        );
    }
}
