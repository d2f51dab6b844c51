//! The click benchmark (pipeline.md §9.4): how many clicks a selection
//! needs to get a material right, by the protocol of the interactive
//! segmentation literature. On a mask benchmark, a simulated user clicks
//! first at the point of the mask farthest from its boundary, then each
//! time at the point farthest from the boundary of the largest region the
//! selection gets wrong: a positive click where it misses the mask, a
//! negative one where it spills over. Reported: the clicks needed to reach
//! IoU 0.85 and 0.90 (NoC@85, NoC@90; the most clicks when never), and the
//! mean IoU after 1, 3 and 5 clicks. On a point benchmark the next click is
//! the annotated point the selection gets most wrong, and the score is the
//! balanced accuracy of the points not clicked.

use crate::click_selection::{ClickSelection, ClickedPhoto};
use crate::evaluate::{check_cancelled, load_mask, resize_longer_side};
use crate::iou::best_iou;
use crate::masks::MaskImage;
use crate::model::ScoredModel;
use crate::points::{flatten, BenchError, PointBenchmark};
use matseg_image::io::read_rgb;
use matseg_image::progress::Progress;
use matseg_query::select::{Click, Selection};
use serde::Serialize;
use std::collections::BTreeMap;

/// The IoU a mask must reach for NoC@85 and NoC@90.
pub const NOC_TARGETS: [f64; 2] = [0.85, 0.90];

/// The clicks after which the mean IoU (masks) or balanced accuracy
/// (points) is reported.
pub const REPORTED_CLICKS: [usize; 3] = [1, 3, 5];

/// A mask's run goes on to this many clicks at least, so that the IoU
/// curve and its drops are measured over them for every mask.
pub const CURVE_CLICKS: usize = 10;

/// A drop in IoU from one click larger than this counts as ruining a
/// selection.
pub const LARGE_DROP: f64 = 0.10;

/// How a click benchmark is run.
#[derive(Clone, Debug)]
pub struct ClickOptions {
    /// Longer side of the evaluated images (0: as they are).
    pub max_side: u32,
    /// The most clicks a mask gets.
    pub max_clicks: usize,
    /// Radius of each click's disc, in evaluated pixels.
    pub radius: f32,
    /// Masks with fewer pixels than this (in the evaluated image) are left
    /// out.
    pub min_area: usize,
    /// What the targets are: each mask, or the union of two masks of a
    /// photo.
    pub targets: Targets,
}

/// What a click benchmark's targets are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Targets {
    /// Each mask of each photo.
    Masks,
    /// Each pair of masks of a photo, merged: a target of two materials
    /// (an object of two parts).
    Unions,
}

impl Default for ClickOptions {
    fn default() -> Self {
        Self {
            max_side: crate::evaluate::DEFAULT_MAX_SIDE,
            max_clicks: 20,
            radius: 5.0,
            min_area: 100,
            targets: Targets::Masks,
        }
    }
}

/// A benchmark scored by the click protocol: what `matseg eval clicks
/// --json` prints and `matseg.evaluate.clicks` returns. `R` is a mask
/// benchmark's [`ClickReport`] or a point benchmark's [`PointClickReport`].
#[derive(Serialize)]
pub struct ClickEvaluation<'a, R: Serialize> {
    /// The benchmark folder.
    pub data: &'a std::path::Path,
    /// The longer side the photos were scored at.
    pub max_side: u32,
    /// Each model's report, in the order given.
    pub models: &'a [R],
    /// Each model's report on unions of two masks, when they were scored.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unions: Option<&'a [ClickReport]>,
}

/// One mask's run: the IoU after each click.
#[derive(Clone, Debug, Serialize)]
pub struct MaskRun {
    /// Which mask of the image.
    pub mask: usize,
    /// The other mask merged with it, for a union target.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub with: Option<usize>,
    /// The IoU after click 1, 2, ...
    pub ious: Vec<f64>,
    /// Clicks to IoU 0.85 (the most clicks when never).
    pub noc85: usize,
    /// Clicks to IoU 0.90.
    pub noc90: usize,
    /// The first click's IoU at the best threshold of its similarity map
    /// (a ground-truth oracle, for comparison).
    pub one_click_oracle: f64,
}

/// One image's runs.
#[derive(Clone, Debug, Serialize)]
pub struct ImageRuns {
    /// The image.
    pub name: String,
    /// Its masks' runs.
    pub masks: Vec<MaskRun>,
}

/// A model's scores on a mask benchmark by clicks.
#[derive(Clone, Debug, Serialize)]
pub struct ClickReport {
    /// The model.
    pub model: String,
    /// Mean clicks to IoU 0.85.
    pub noc85: Option<f64>,
    /// Mean clicks to IoU 0.90.
    pub noc90: Option<f64>,
    /// Mean IoU after 1, 3 and 5 clicks (keys "1", "3", "5").
    pub miou_at: BTreeMap<String, f64>,
    /// Mean IoU after each click, 1 to the most clicks (a run that ended
    /// early keeps its last IoU).
    pub miou_curve: Vec<f64>,
    /// How the protocol's clicks lowered the IoU.
    pub drops: ClickDrops,
    /// What the targets were.
    pub targets: Targets,
    /// Mean IoU of one click at the best threshold (the oracle).
    pub one_click_oracle: Option<f64>,
    /// Masks scored.
    pub masks: usize,
    /// Masks left out (smaller than the least area).
    pub skipped_masks: usize,
    /// Every image's runs.
    pub images: Vec<ImageRuns>,
}

/// How the clicks of a benchmark's runs lowered the IoU: each click after
/// the first is compared with the one before it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ClickDrops {
    /// Clicks after the first, over every run.
    pub clicks: usize,
    /// Those that lowered the IoU.
    pub lowering: usize,
    /// The mean IoU those lost (0 when none did).
    pub mean_drop: f64,
    /// The most IoU one click lost (0 when none did).
    pub largest: f64,
    /// Where it did, when one did.
    pub largest_at: Option<DropAt>,
    /// Clicks that lost more than [`LARGE_DROP`].
    pub large: usize,
    /// Runs that lost more than [`LARGE_DROP`] from one click.
    pub runs_with_large: usize,
}

/// Which click of which run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DropAt {
    /// The image.
    pub image: String,
    /// The mask (the first of a union's two).
    pub mask: usize,
    /// A union's second mask.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub with: Option<usize>,
    /// The click, from 1.
    pub click: usize,
}

impl ClickDrops {
    /// The drops of every run of `images`.
    pub fn of(images: &[ImageRuns]) -> Self {
        let mut drops = ClickDrops::default();
        let mut lost = 0.0;
        for image in images {
            for run in &image.masks {
                let mut large = false;
                for (k, pair) in run.ious.windows(2).enumerate() {
                    drops.clicks += 1;
                    let drop = pair[0] - pair[1];
                    if drop <= 0.0 {
                        continue;
                    }
                    drops.lowering += 1;
                    lost += drop;
                    if drop > LARGE_DROP {
                        drops.large += 1;
                        large = true;
                    }
                    if drop > drops.largest {
                        drops.largest = drop;
                        drops.largest_at = Some(DropAt {
                            image: image.name.clone(),
                            mask: run.mask,
                            with: run.with,
                            click: k + 2,
                        });
                    }
                }
                drops.runs_with_large += large as usize;
            }
        }
        if drops.lowering > 0 {
            drops.mean_drop = lost / drops.lowering as f64;
        }
        drops
    }
}

/// The squared Euclidean distance of each pixel of `inside` to the nearest
/// pixel not inside (beyond the image's edges counts as not inside): 0 for
/// pixels outside. Felzenszwalb and Huttenlocher's exact transform, a
/// column pass then a row pass.
pub fn distance_inside(inside: &[bool], w: usize, h: usize) -> Vec<f32> {
    const FAR: f32 = 1e20;
    let mut grid: Vec<f32> = inside.iter().map(|&i| if i { FAR } else { 0.0 }).collect();
    // The image's edge: a ring of outside pixels around it.
    let pass = |line: &[f32]| -> Vec<f32> {
        let mut padded = Vec::with_capacity(line.len() + 2);
        padded.push(0.0);
        padded.extend_from_slice(line);
        padded.push(0.0);
        let out = distance_1d(&padded);
        out[1..out.len() - 1].to_vec()
    };
    for x in 0..w {
        let column: Vec<f32> = (0..h).map(|y| grid[y * w + x]).collect();
        for (y, v) in pass(&column).into_iter().enumerate() {
            grid[y * w + x] = v;
        }
    }
    for y in 0..h {
        let row = pass(&grid[y * w..(y + 1) * w]);
        grid[y * w..(y + 1) * w].copy_from_slice(&row);
    }
    grid
}

/// The 1-D squared distance transform of `f` (lower envelope of parabolas).
fn distance_1d(f: &[f32]) -> Vec<f32> {
    let n = f.len();
    let mut d = vec![0f32; n];
    let mut v = vec![0usize; n];
    let mut z = vec![0f32; n + 1];
    let mut k = 0usize;
    z[0] = f32::NEG_INFINITY;
    z[1] = f32::INFINITY;
    let meet = |q: usize, p: usize| {
        ((f[q] + (q * q) as f32) - (f[p] + (p * p) as f32)) / (2.0 * q as f32 - 2.0 * p as f32)
    };
    for q in 1..n {
        let mut s = meet(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = meet(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f32::INFINITY;
    }
    k = 0;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f32 {
            k += 1;
        }
        let dq = q as f32 - v[k] as f32;
        *out = dq * dq + f[v[k]];
    }
    d
}

/// The pixel of `region` farthest from its boundary, or `None` when it is
/// empty. Of several as far, the one nearest their middle (then the first
/// in row order).
pub fn farthest_inside(region: &[bool], w: usize, h: usize) -> Option<(usize, usize)> {
    let distances = distance_inside(region, w, h);
    let far = distances.iter().copied().fold(0f32, f32::max);
    if far <= 0.0 {
        return None;
    }
    let ties: Vec<usize> = (0..distances.len())
        .filter(|&i| distances[i] == far)
        .collect();
    let n = ties.len() as f64;
    let (mx, my) = ties.iter().fold((0.0, 0.0), |(x, y), &i| {
        (x + (i % w) as f64 / n, y + (i / w) as f64 / n)
    });
    let off = |i: usize| ((i % w) as f64 - mx).powi(2) + ((i / w) as f64 - my).powi(2);
    let best = ties
        .into_iter()
        .min_by(|&a, &b| off(a).total_cmp(&off(b)).then(a.cmp(&b)))?;
    Some((best % w, best / w))
}

/// The 4-connected regions of `set`: each pixel's region number (0 for
/// pixels outside it, regions from 1) and each region's area (index 0
/// unused).
pub fn regions(set: &[bool], w: usize, h: usize) -> (Vec<u32>, Vec<usize>) {
    let mut label = vec![0u32; set.len()];
    let mut areas = vec![0usize];
    let mut stack = Vec::new();
    for start in 0..set.len() {
        if !set[start] || label[start] != 0 {
            continue;
        }
        let id = areas.len() as u32;
        areas.push(0);
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            areas[id as usize] += 1;
            let (x, y) = (i % w, i / w);
            let neighbours = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in neighbours.into_iter().flatten() {
                if set[j] && label[j] == 0 {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
    }
    (label, areas)
}

/// The next click on a mask: at the point farthest from the boundary of
/// the largest region the selection gets wrong, positive where it misses
/// `truth`, negative where it spills over; `None` when nothing is wrong.
/// Pixels outside `scored` (the ROI) are neither.
pub fn next_click(
    truth: &[bool],
    selected: &[bool],
    scored: &[bool],
    w: usize,
    h: usize,
) -> Option<Click> {
    let missed: Vec<bool> = (0..truth.len())
        .map(|i| scored[i] && truth[i] && !selected[i])
        .collect();
    let spilled: Vec<bool> = (0..truth.len())
        .map(|i| scored[i] && !truth[i] && selected[i])
        .collect();
    let largest = |set: &[bool]| {
        let (label, areas) = regions(set, w, h);
        let (id, &area) = areas
            .iter()
            .enumerate()
            .skip(1)
            .max_by_key(|(i, a)| (**a, usize::MAX - i))?;
        let region: Vec<bool> = label.iter().map(|&l| l as usize == id).collect();
        Some((area, region))
    };
    let (positive, region) = match (largest(&missed), largest(&spilled)) {
        (Some((a, r)), Some((b, _))) if a >= b => (true, r),
        (_, Some((_, r))) => (false, r),
        (Some((_, r)), None) => (true, r),
        (None, None) => return None,
    };
    let (x, y) = farthest_inside(&region, w, h)?;
    Some(Click {
        x: x as f32,
        y: y as f32,
        positive,
    })
}

/// The IoU of `selected` with `truth` over the `scored` pixels (1 when
/// both are empty).
pub fn iou(selected: &[bool], truth: &[bool], scored: &[bool]) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    for i in 0..truth.len() {
        if scored[i] {
            both += (selected[i] && truth[i]) as usize;
            either += (selected[i] || truth[i]) as usize;
        }
    }
    if either == 0 {
        1.0
    } else {
        both as f64 / either as f64
    }
}

/// The clicks `ious` took to reach `target` (`most` when they never did).
pub fn clicks_to(ious: &[f64], target: f64, most: usize) -> usize {
    ious.iter()
        .position(|&v| v >= target)
        .map_or(most, |k| k + 1)
}

/// One mask's run on a photo: clicks until IoU 0.90 (and
/// [`CURVE_CLICKS`] clicks at least, for the reported means and the
/// curve) or the most clicks.
fn mask_run(
    selector: &mut dyn ClickSelection,
    truth: &[bool],
    scored: &[bool],
    (w, h): (usize, usize),
    options: &ClickOptions,
) -> Result<(Vec<f64>, Selection), BenchError> {
    let region: Vec<bool> = (0..truth.len()).map(|i| truth[i] && scored[i]).collect();
    let (x, y) = farthest_inside(&region, w, h).expect("a mask of some area");
    let mut click = Click::positive(x as f32, y as f32);
    let mut ious = Vec::new();
    let mut first = None;
    loop {
        selector.add(click)?;
        let selection = selector.selection()?;
        ious.push(iou(&selection.mask, truth, scored));
        let last = *ious.last().expect("one at least");
        if first.is_none() {
            first = Some(selection.clone());
        }
        if ious.len() >= options.max_clicks
            || (last >= NOC_TARGETS[1] && ious.len() >= CURVE_CLICKS)
        {
            break;
        }
        match next_click(truth, &selection.mask, scored, w, h) {
            Some(next) => click = next,
            // Nothing left wrong: every later click would find the same.
            None => {
                let done = ious.len().max(CURVE_CLICKS).min(options.max_clicks);
                ious.resize(done, last);
                break;
            }
        }
    }
    Ok((ious, first.expect("one click at least")))
}

/// Scores `model` by clicks on the photos and masks of a mask benchmark:
/// each mask, or each union of two masks of a photo (`options.targets`);
/// a target with a mask smaller than `options.min_area` is left out.
pub fn evaluate_clicks(
    model: &dyn ScoredModel,
    images: &[MaskImage],
    options: &ClickOptions,
    progress: &dyn Progress,
) -> Result<ClickReport, BenchError> {
    let mut report = ClickReport {
        model: model.name().to_string(),
        noc85: None,
        noc90: None,
        miou_at: BTreeMap::new(),
        miou_curve: Vec::new(),
        drops: ClickDrops::default(),
        targets: options.targets,
        one_click_oracle: None,
        masks: 0,
        skipped_masks: 0,
        images: Vec::new(),
    };
    for image in images {
        check_cancelled(progress, &image.image_path)?;
        let photo = read_rgb(&image.image_path)?;
        let (w0, h0) = photo.dimensions();
        let (pixels, _) = resize_longer_side(photo, options.max_side);
        let (w, h) = (pixels.width() as usize, pixels.height() as usize);
        let inside = |path: &std::path::Path| -> Result<Vec<bool>, BenchError> {
            let mask = load_mask(path, w0, h0)?;
            let mask = image::imageops::resize(
                &mask,
                w as u32,
                h as u32,
                image::imageops::FilterType::Nearest,
            );
            Ok(mask.as_raw().iter().map(|&v| v >= 128).collect())
        };
        let scored = match &image.roi_path {
            Some(path) => inside(path)?,
            None => vec![true; w * h],
        };
        let photo = ClickedPhoto::ask(model, &image.name, &image.image_path, &pixels)?;
        let space = photo.space();
        let masks = image
            .mask_paths
            .iter()
            .map(|path| inside(path))
            .collect::<Result<Vec<_>, _>>()?;
        let large: Vec<bool> = masks
            .iter()
            .map(|truth| (0..w * h).filter(|&i| truth[i] && scored[i]).count() >= options.min_area)
            .collect();
        let mut runs = Vec::new();
        for (k, with) in targets(masks.len(), options.targets) {
            if !large[k] || with.is_some_and(|o| !large[o]) {
                report.skipped_masks += 1;
                continue;
            }
            let truth: Vec<bool> = match with {
                None => masks[k].clone(),
                Some(o) => (0..w * h).map(|i| masks[k][i] || masks[o][i]).collect(),
            };
            let mut selection = photo.start(space.as_ref(), options.radius)?;
            let (ious, first) = mask_run(selection.as_mut(), &truth, &scored, (w, h), options)?;
            let scores: Vec<f32> = (0..w * h)
                .filter(|&i| scored[i])
                .map(|i| first.soft[i])
                .collect();
            let truths: Vec<bool> = (0..w * h)
                .filter(|&i| scored[i])
                .map(|i| truth[i])
                .collect();
            let oracle = best_iou(&scores, &truths).map_or(0.0, |b| b.iou);
            runs.push(MaskRun {
                mask: k,
                with,
                noc85: clicks_to(&ious, NOC_TARGETS[0], options.max_clicks),
                noc90: clicks_to(&ious, NOC_TARGETS[1], options.max_clicks),
                ious,
                one_click_oracle: oracle,
            });
        }
        progress.advance();
        report.masks += runs.len();
        report.images.push(ImageRuns {
            name: image.name.clone(),
            masks: runs,
        });
    }
    let all: Vec<&MaskRun> = report.images.iter().flat_map(|i| &i.masks).collect();
    let mean = |f: &dyn Fn(&MaskRun) -> f64| {
        (!all.is_empty()).then(|| all.iter().map(|s| f(s)).sum::<f64>() / all.len() as f64)
    };
    report.noc85 = mean(&|s| s.noc85 as f64);
    report.noc90 = mean(&|s| s.noc90 as f64);
    report.one_click_oracle = mean(&|s| s.one_click_oracle);
    let after = |s: &MaskRun, k: usize| s.ious[(k - 1).min(s.ious.len() - 1)];
    for k in REPORTED_CLICKS {
        if let Some(m) = mean(&|s| after(s, k)) {
            report.miou_at.insert(k.to_string(), m);
        }
    }
    report.miou_curve = (1..=options.max_clicks)
        .filter_map(|k| mean(&|s| after(s, k)))
        .collect();
    report.drops = ClickDrops::of(&report.images);
    Ok(report)
}

/// The targets of a photo of `masks` masks: each mask (its index, no
/// second), or each pair of masks.
fn targets(masks: usize, targets: Targets) -> Vec<(usize, Option<usize>)> {
    match targets {
        Targets::Masks => (0..masks).map(|k| (k, None)).collect(),
        Targets::Unions => (0..masks)
            .flat_map(|a| (a + 1..masks).map(move |b| (a, Some(b))))
            .collect(),
    }
}

/// One target material's run on a point benchmark image: the
/// balanced accuracy of the points not clicked, after each click.
#[derive(Clone, Debug, Serialize)]
pub struct PointRun {
    /// The image.
    pub image: String,
    /// The target material's group number in the image.
    pub group: usize,
    /// Balanced accuracy after click 1, 2, ... (the reported clicks).
    pub balanced_accuracy: Vec<f64>,
}

/// A model's scores on a point benchmark by clicks.
#[derive(Clone, Debug, Serialize)]
pub struct PointClickReport {
    /// The model.
    pub model: String,
    /// Mean balanced accuracy of the points not clicked, after 1, 3 and 5
    /// clicks (keys "1", "3", "5").
    pub balanced_accuracy_at: BTreeMap<String, f64>,
    /// Every run.
    pub runs: Vec<PointRun>,
}

/// Scores `model` by clicks on a point benchmark: each material of each
/// image in turn is the target; the first click is its point farthest from
/// every other material's points, each next click the annotated point the
/// selection gets most wrong (a target point with the least strength, or
/// another material's point with the most); materials partly the same as
/// the target (relations) are not scored.
pub fn evaluate_point_clicks(
    model: &dyn ScoredModel,
    bench: &PointBenchmark,
    options: &ClickOptions,
    progress: &dyn Progress,
) -> Result<PointClickReport, BenchError> {
    let most = *REPORTED_CLICKS.iter().max().expect("reported clicks");
    let mut runs = Vec::new();
    for image in &bench.images {
        check_cancelled(progress, &image.image_path)?;
        let (pixels, scale) = resize_longer_side(read_rgb(&image.image_path)?, options.max_side);
        let photo = ClickedPhoto::ask(model, &image.name, &image.image_path, &pixels)?;
        let space = photo.space();
        let (w, h) = (pixels.width() as f32, pixels.height() as f32);
        let (points, material) = flatten(image);
        let at = |i: usize| {
            (
                (points[i].x * scale).clamp(0.0, w - 1.0),
                (points[i].y * scale).clamp(0.0, h - 1.0),
            )
        };
        for target in 0..image.points.len() {
            // Materials partly the same as the target are not scored.
            let scored: Vec<usize> = (0..points.len())
                .filter(|&i| material[i] == target || image.weights[target][material[i]] == 0.0)
                .collect();
            let Some(first) = scored
                .iter()
                .copied()
                .filter(|&i| material[i] == target)
                .max_by(|&a, &b| {
                    nearest_other(a, &scored, &material, &at)
                        .total_cmp(&nearest_other(b, &scored, &material, &at))
                        .then(b.cmp(&a))
                })
            else {
                continue;
            };
            let mut selector = photo.start(space.as_ref(), options.radius)?;
            let mut clicked = vec![first];
            let (x, y) = at(first);
            selector.add(Click::positive(x, y))?;
            let mut accuracies = Vec::new();
            while clicked.len() <= most {
                let selection = selector.selection()?;
                let value = |i: usize| {
                    let (x, y) = at(i);
                    let p = y as usize * selection.width + x as usize;
                    (selection.mask[p], selection.soft[p])
                };
                let remaining: Vec<usize> = scored
                    .iter()
                    .copied()
                    .filter(|i| !clicked.contains(i))
                    .collect();
                accuracies.push(balanced_accuracy(&remaining, &material, target, &value));
                if clicked.len() == most {
                    break;
                }
                // The point the selection gets most wrong.
                let wrong = remaining
                    .iter()
                    .copied()
                    .filter(|&i| value(i).0 != (material[i] == target))
                    .max_by(|&a, &b| {
                        let wrongness = |i: usize| {
                            let soft = value(i).1;
                            if material[i] == target {
                                -soft
                            } else {
                                soft
                            }
                        };
                        wrongness(a).total_cmp(&wrongness(b)).then(b.cmp(&a))
                    });
                match wrong {
                    Some(i) => {
                        let (x, y) = at(i);
                        let click = Click {
                            x,
                            y,
                            positive: material[i] == target,
                        };
                        selector.add(click)?;
                        clicked.push(i);
                    }
                    None => {
                        let last = *accuracies.last().expect("one at least");
                        accuracies.resize(most, last);
                        break;
                    }
                }
            }
            runs.push(PointRun {
                image: image.name.clone(),
                group: target,
                balanced_accuracy: accuracies,
            });
        }
        progress.advance();
    }
    let mut balanced_accuracy_at = BTreeMap::new();
    for k in REPORTED_CLICKS {
        let values: Vec<f64> = runs
            .iter()
            .filter_map(|s| s.balanced_accuracy.get(k - 1).copied())
            .collect();
        if !values.is_empty() {
            balanced_accuracy_at.insert(
                k.to_string(),
                values.iter().sum::<f64>() / values.len() as f64,
            );
        }
    }
    Ok(PointClickReport {
        model: model.name().to_string(),
        balanced_accuracy_at,
        runs,
    })
}

/// The distance from point `i` to the nearest scored point of another
/// material (infinite when there is none).
fn nearest_other(
    i: usize,
    scored: &[usize],
    material: &[usize],
    at: &dyn Fn(usize) -> (f32, f32),
) -> f32 {
    let (x, y) = at(i);
    scored
        .iter()
        .filter(|&&j| material[j] != material[i])
        .map(|&j| {
            let (u, v) = at(j);
            (u - x).hypot(v - y)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The balanced accuracy over `points` (the mean of the share of the
/// target's points selected and the share of the others' left out; one
/// side alone when the other has no points).
fn balanced_accuracy(
    points: &[usize],
    material: &[usize],
    target: usize,
    value: &dyn Fn(usize) -> (bool, f32),
) -> f64 {
    let share = |of_target: bool| {
        let group: Vec<usize> = points
            .iter()
            .copied()
            .filter(|&i| (material[i] == target) == of_target)
            .collect();
        (!group.is_empty()).then(|| {
            group.iter().filter(|&&i| value(i).0 == of_target).count() as f64 / group.len() as f64
        })
    };
    match (share(true), share(false)) {
        (Some(a), Some(b)) => (a + b) / 2.0,
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ClickAnswer, Described, Question};
    use matseg_image::progress::Silent;

    #[test]
    fn distances_are_exact_to_the_boundary_and_the_edge() {
        // A 7 x 5 block inside a 9 x 7 image.
        let (w, h) = (9, 7);
        let inside: Vec<bool> = (0..w * h)
            .map(|i| (1..8).contains(&(i % w)) && (1..6).contains(&(i / w)))
            .collect();
        let d = distance_inside(&inside, w, h);
        assert_eq!(
            d[3 * w + 4],
            9.0,
            "the centre is 3 from the block's top and bottom"
        );
        assert_eq!(d[w + 1], 1.0);
        assert_eq!(d[0], 0.0);
        // The image's edge counts as boundary.
        let all = vec![true; 5 * 3];
        let d = distance_inside(&all, 5, 3);
        assert_eq!(d[5 + 2], 4.0);
        assert_eq!(farthest_inside(&all, 5, 3), Some((2, 1)));
        assert_eq!(farthest_inside(&[false; 4], 2, 2), None);
    }

    #[test]
    fn the_clicker_clicks_the_largest_wrong_region_at_its_middle() {
        // A 10 x 6 truth: columns 0..6. The selection misses columns 4..6
        // (a 2 x 6 region) and spills into columns 6..9 (3 x 6, larger).
        let (w, h) = (10, 6);
        let truth: Vec<bool> = (0..w * h).map(|i| i % w < 6).collect();
        let selected: Vec<bool> = (0..w * h)
            .map(|i| i % w < 4 || (6..9).contains(&(i % w)))
            .collect();
        let scored = vec![true; w * h];
        let click = next_click(&truth, &selected, &scored, w, h).unwrap();
        assert_eq!(
            click,
            Click {
                x: 7.0,
                y: 2.0,
                positive: false
            }
        );
        // With the spill gone, the miss is clicked, positively.
        let selected: Vec<bool> = (0..w * h).map(|i| i % w < 4).collect();
        let click = next_click(&truth, &selected, &scored, w, h).unwrap();
        assert_eq!((click.positive, click.x), (true, 4.0));
        assert_eq!(next_click(&truth, &truth, &scored, w, h), None);
        assert_eq!(iou(&selected, &truth, &scored), 4.0 / 6.0);
    }

    #[test]
    fn clicks_needed_count_from_one_and_never_is_the_most() {
        assert_eq!(clicks_to(&[0.5, 0.86, 0.95], 0.85, 20), 2);
        assert_eq!(clicks_to(&[0.5, 0.86, 0.95], 0.90, 20), 3);
        assert_eq!(clicks_to(&[0.5; 20], 0.85, 20), 20);
        // A perfect predictor needs one click; a constant one never gets there.
        assert_eq!(clicks_to(&[1.0], 0.90, 20), 1);
        assert_eq!(clicks_to(&[0.3; 20], 0.90, 20), 20);
    }

    #[test]
    fn regions_are_four_connected() {
        let (w, h) = (4, 3);
        let set = [
            true, false, false, true, //
            true, false, true, true, //
            false, true, false, false,
        ];
        let (label, areas) = regions(&set, w, h);
        assert_eq!(areas.len() - 1, 3);
        assert_eq!(label[0], label[4]);
        assert_ne!(label[4], label[9], "diagonal neighbours are apart");
        assert_eq!(areas[label[3] as usize], 3);
    }

    /// A model whose descriptors are one unit vector left of column
    /// `split` and another right of it (`split` 0: the same everywhere).
    struct Halves {
        split: u32,
    }

    impl matseg_query::descriptor::DescriptorModel for Halves {
        fn name(&self) -> &str {
            "halves"
        }
        fn comparison(&self) -> matseg_query::descriptor::Comparison {
            matseg_query::descriptor::Comparison::Cosine
        }
        fn describe(&self, image: &image::RgbImage) -> matseg_query::descriptor::DescriptorMap {
            let (w, h) = (image.width() as usize, image.height() as usize);
            let data = (0..w * h)
                .flat_map(|i| {
                    if (i % w) < self.split as usize {
                        [1.0, 0.0]
                    } else {
                        [0.0, 1.0]
                    }
                })
                .collect();
            matseg_query::descriptor::DescriptorMap {
                width: w,
                height: h,
                dim: 2,
                data,
            }
        }
    }

    /// A mask benchmark of one 40 x 30 photo, grey on the left and white
    /// on the right, whose one mask is the left 16 columns.
    fn halves_benchmark(dir: &std::path::Path) -> Vec<MaskImage> {
        let photo = image::RgbImage::from_fn(40, 30, |x, _| {
            image::Rgb(if x < 16 {
                [90, 90, 90]
            } else {
                [250, 250, 250]
            })
        });
        photo.save(dir.join("p.png")).unwrap();
        let mask =
            image::GrayImage::from_fn(40, 30, |x, _| image::Luma([if x < 16 { 255 } else { 0 }]));
        mask.save(dir.join("p.mask0.png")).unwrap();
        crate::masks::scan_mask_benchmark(dir).unwrap()
    }

    #[test]
    fn a_perfect_model_needs_one_click_and_a_constant_one_never_gets_there() {
        let dir = tempfile::tempdir().unwrap();
        let images = halves_benchmark(dir.path());
        let options = ClickOptions {
            max_side: 0,
            ..ClickOptions::default()
        };
        let perfect = evaluate_clicks(
            &Described(&Halves { split: 16 }),
            &images,
            &options,
            &Silent,
        )
        .unwrap();
        assert_eq!((perfect.noc85, perfect.noc90), (Some(1.0), Some(1.0)));
        assert_eq!(perfect.miou_at["1"], 1.0);
        assert_eq!(perfect.miou_curve, vec![1.0; 20]);
        assert_eq!(perfect.drops.clicks, 9, "runs go on to 10 clicks");
        assert_eq!((perfect.drops.lowering, perfect.drops.largest), (0, 0.0));
        let constant =
            evaluate_clicks(&Described(&Halves { split: 0 }), &images, &options, &Silent).unwrap();
        assert_eq!(constant.noc85, Some(20.0), "{:?}", constant.images);
        assert!(constant.miou_at["5"] < 0.85);
        assert_eq!(constant.miou_curve.len(), 20);
        let ious = &constant.images[0].masks[0].ious;
        assert_eq!(constant.miou_curve[..ious.len()], ious[..]);
        assert_eq!(constant.drops.clicks, ious.len() - 1);
    }

    /// A model answering clicks with a similarity map per click (`1` on
    /// the clicked side of column 16, `0` on the other) or with its own
    /// selection (the side of its first positive click, or values out of
    /// range when `broken`), counting the points it is asked about.
    struct Clicked {
        answer: ClickAnswer,
        broken: bool,
        asked: std::sync::Mutex<Vec<usize>>,
    }

    impl Clicked {
        fn new(answer: ClickAnswer, broken: bool) -> Self {
            Self {
                answer,
                broken,
                asked: Default::default(),
            }
        }

        fn side_of(x: f32, w: usize, h: usize) -> Vec<f32> {
            let left = x < 16.0;
            (0..w * h)
                .map(|i| if ((i % w) < 16) == left { 1.0 } else { 0.0 })
                .collect()
        }
    }

    impl ScoredModel for Clicked {
        fn name(&self) -> &str {
            "clicked"
        }
        fn answer(&self, question: &Question) -> Result<crate::Answer, BenchError> {
            self.asked.lock().unwrap().push(question.points.len());
            let (w, h) = question.pixels.dimensions();
            let (w, h) = (w as usize, h as usize);
            Ok(crate::Answer::Similarity {
                maps: question
                    .points
                    .iter()
                    .map(|&(x, _)| Self::side_of(x, w, h))
                    .collect(),
                width: w,
                height: h,
            })
        }
        fn click_answer(&self) -> ClickAnswer {
            self.answer
        }
        fn select(&self, question: &Question, clicks: &[Click]) -> Result<Vec<f32>, BenchError> {
            let (w, h) = question.pixels.dimensions();
            let first = clicks.iter().find(|c| c.positive).unwrap();
            let map = Self::side_of(first.x, w as usize, h as usize);
            Ok(match self.broken {
                true => map.iter().map(|v| v * 2.0).collect(),
                false => map,
            })
        }
    }

    #[test]
    fn similarity_and_selecting_models_are_scored_by_clicks() {
        let dir = tempfile::tempdir().unwrap();
        let images = halves_benchmark(dir.path());
        let options = ClickOptions {
            max_side: 0,
            ..ClickOptions::default()
        };
        for answer in [ClickAnswer::SimilarityMaps, ClickAnswer::Selection] {
            let model = Clicked::new(answer, false);
            let report = evaluate_clicks(&model, &images, &options, &Silent).unwrap();
            assert_eq!((report.noc85, report.noc90), (Some(1.0), Some(1.0)));
            assert_eq!(report.miou_curve, vec![1.0; 20], "{answer:?}");
            assert_eq!(report.one_click_oracle, Some(1.0));
            let asked = model.asked.lock().unwrap().clone();
            match answer {
                // One map, for the one click: nothing is left wrong after it.
                ClickAnswer::SimilarityMaps => assert_eq!(asked, vec![1]),
                _ => assert!(asked.is_empty(), "{asked:?}"),
            }
        }
        let broken = Clicked::new(ClickAnswer::Selection, true);
        let error = evaluate_clicks(&broken, &images, &options, &Silent)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains(
                "photo p: clicked's selection has the value 2: give a mask or soft map in 0..1"
            ),
            "{error}"
        );
    }

    #[test]
    fn drops_count_every_click_that_lowers_the_iou() {
        let run = |mask, ious: &[f64]| MaskRun {
            mask,
            with: None,
            ious: ious.to_vec(),
            noc85: 20,
            noc90: 20,
            one_click_oracle: 0.0,
        };
        let images = [ImageRuns {
            name: "a".into(),
            masks: vec![
                run(0, &[0.5, 0.7, 0.55, 0.6]),
                run(1, &[0.9, 0.95, 0.6, 0.65, 0.64]),
            ],
        }];
        let drops = ClickDrops::of(&images);
        assert_eq!(drops.clicks, 7);
        assert_eq!(drops.lowering, 3);
        assert!((drops.mean_drop - (0.15 + 0.35 + 0.01) / 3.0).abs() < 1e-12);
        assert!((drops.largest - 0.35).abs() < 1e-12);
        assert_eq!(
            drops.largest_at,
            Some(DropAt {
                image: "a".into(),
                mask: 1,
                with: None,
                click: 3
            })
        );
        assert_eq!((drops.large, drops.runs_with_large), (2, 2));
    }

    #[test]
    fn unions_are_every_pair_of_a_photos_masks() {
        assert_eq!(targets(2, Targets::Masks), [(0, None), (1, None)]);
        assert_eq!(
            targets(3, Targets::Unions),
            [(0, Some(1)), (0, Some(2)), (1, Some(2))]
        );
        assert!(targets(1, Targets::Unions).is_empty());
    }
}
