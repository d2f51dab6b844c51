//! Soft maps (pipeline.md §1): a random photo channel through a random ramp
//! gives a map with natural-image shapes; K of them become material weights.

use matseg_image::coverage::BLOCK;
use matseg_image::levels::{look_up_step, step_level};
use matseg_image::{
    level_values, Channel, ChannelWindow, Coverage, CoveredBlur, CropWindow, LevelCounts,
    LevelTable, LibraryError, Photo, PhotoLibrary, Plane, Ramp, SparsePlane,
};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Every probability and limit of map drawing, with the paper's values as defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SoftMapRecipe {
    /// Probability of shrinking the source photo by r ~ U(1, largest ratio that
    /// still covers the scene) before cropping; otherwise it is used at native
    /// resolution (upscaled only as far as needed to cover the scene).
    pub p_downscale: f64,
    /// Probability that the channel is one of H, S, V (otherwise R, G, B).
    pub p_hsv_channel: f64,
    /// Probability of dividing the channel by its maximum (otherwise it keeps
    /// its full range, 0..1).
    pub p_normalise_by_max: f64,
    /// Draws of the high threshold before giving up on the photo.
    pub high_threshold_tries: u32,
    /// Each side of a threshold must hold more than this fraction of pixels.
    pub min_side_fraction: f64,
    /// Probability of a binary map (t_lo = t_hi) in a soft scene.
    pub p_binary: f64,
    /// Draws of the low threshold before falling back to a binary map.
    pub low_threshold_tries: u32,
    /// The ramp band must hold fewer pixels than this ratio times the smaller
    /// of the two sides (the check the original code meant to make).
    pub max_band_to_side_ratio: f64,
    /// A map whose sum (pixel-equivalents) is below this is redrawn.
    pub min_map_mass: f64,
    /// Redraws of one map before the scene fails (sources all flat, say).
    pub max_map_draws: u32,
    /// Probability of blurring all maps of a scene with one Gaussian kernel.
    pub p_blur: f64,
    /// Kernel sizes the blur draws from.
    pub blur_kernels: Vec<usize>,
    /// Probability of normalising maps to sum to 1 wherever any is non-zero
    /// (otherwise priority order: each map takes what the earlier ones left).
    pub p_sum_normalise: f64,
    /// In hard scenes a pixel whose top weight is below this is background.
    pub hard_min_weight: f64,
}

impl Default for SoftMapRecipe {
    fn default() -> Self {
        Self {
            p_downscale: 0.3,
            p_hsv_channel: 0.3,
            p_normalise_by_max: 0.5,
            high_threshold_tries: 20,
            min_side_fraction: 0.01,
            p_binary: 0.5,
            low_threshold_tries: 20,
            max_band_to_side_ratio: 1.0 / 3.0,
            min_map_mass: 100.0,
            max_map_draws: 500,
            p_blur: 0.5,
            blur_kernels: vec![3, 5, 7, 9],
            p_sum_normalise: 0.25,
            hard_min_weight: 0.1,
        }
    }
}

/// A recipe value out of its range; the message names the field and the
/// rule.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct OutOfRange(pub String);

/// Checks that each named value is a probability; the error names the first
/// that is not.
pub fn check_probabilities(values: &[(&str, f64)]) -> Result<(), OutOfRange> {
    match values.iter().find(|(_, p)| !(0.0..=1.0).contains(p)) {
        Some((name, p)) => Err(OutOfRange(format!(
            "{name} = {p} is not a probability in [0, 1]"
        ))),
        None => Ok(()),
    }
}

impl SoftMapRecipe {
    /// Checks ranges; the message names the offending field.
    pub fn validate(&self) -> Result<(), OutOfRange> {
        check_probabilities(&[
            ("p_downscale", self.p_downscale),
            ("p_hsv_channel", self.p_hsv_channel),
            ("p_normalise_by_max", self.p_normalise_by_max),
            ("min_side_fraction", self.min_side_fraction),
            ("p_binary", self.p_binary),
            ("p_blur", self.p_blur),
            ("p_sum_normalise", self.p_sum_normalise),
        ])?;
        if self.high_threshold_tries == 0
            || self.low_threshold_tries == 0
            || self.max_map_draws == 0
        {
            return Err(OutOfRange(
                "threshold tries and max_map_draws must be at least 1".into(),
            ));
        }
        if self.blur_kernels.is_empty() || self.blur_kernels.iter().any(|k| k % 2 == 0) {
            return Err(OutOfRange(
                "blur_kernels must be a non-empty list of odd sizes".into(),
            ));
        }
        if !(0.0..=1.0).contains(&self.hard_min_weight)
            || self.max_band_to_side_ratio < 0.0
            || self.min_map_mass < 0.0
        {
            return Err(OutOfRange(
                "hard_min_weight must be in [0, 1]; max_band_to_side_ratio and min_map_mass >= 0"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// How one map was drawn: enough to redraw it from the same photo.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapRecord {
    /// Index of the source photo in the library.
    pub photo: usize,
    /// How the photo was resized and cropped.
    pub placement: CropWindow,
    /// The channel used.
    pub channel: Channel,
    /// Whether the channel was divided by its maximum.
    pub normalised_by_max: bool,
    /// The thresholds.
    pub ramp: Ramp,
}

/// A map drawn from a photo (pipeline.md §1, steps 1-5), before combination: its
/// channel window's levels and the table that takes each level to the map's
/// value (normalisation and ramp together), with the blocks where that value
/// is positive. A map is positive on a few percent of the scene, so only
/// those blocks are ever turned into floats.
#[derive(Clone, Debug)]
pub struct RawMap {
    window: ChannelWindow,
    table: LevelTable,
    /// The level where `table` steps from 0 to 1, for a binary map.
    step: Option<u8>,
    coverage: Coverage,
}

impl RawMap {
    /// The map `table[level]` of `window`.
    pub fn new(window: ChannelWindow, table: LevelTable) -> Self {
        let coverage = window.coverage(&table);
        Self {
            window,
            step: step_level(&table),
            table,
            coverage,
        }
    }

    /// Columns `x0..x0 + run.len()` of row `y` of the map: a binary map's
    /// by comparing levels with its step, any other's through its table.
    fn map_run(&self, y: usize, x0: usize, run: &mut [f32]) {
        match self.step {
            Some(step) => look_up_step(self.window.run(y, x0, run.len()), step, run),
            None => self.window.map_run(y, x0, &self.table, run),
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.window.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.window.height
    }

    /// The blocks where the map is positive.
    pub fn coverage(&self) -> &Coverage {
        &self.coverage
    }

    /// The whole map as a float plane.
    pub fn to_plane(&self) -> Plane {
        self.window.map_levels(&self.table)
    }

    /// The map, blurred with `kernel` if any, stored on the blocks where it
    /// can be positive (elsewhere it is exactly zero, blurred or not).
    fn blurred(&self, kernel: Option<usize>) -> SparsePlane {
        let Some(kernel) = kernel else {
            return SparsePlane::from_rows(self.coverage.clone(), |y, data| {
                for (x0, x1) in self.coverage.runs(y) {
                    let start = data.len();
                    data.resize(start + (x1 - x0), 0.0);
                    self.map_run(y, x0, &mut data[start..]);
                }
            });
        };
        let stored = self.coverage.dilated(kernel / 2);
        let mut blur = CoveredBlur::new(self.width(), self.height(), kernel, &stored);
        SparsePlane::from_rows(stored.clone(), |y, data| {
            if let Some(row) = blur.row(y, |y, x0, run| self.map_run(y, x0, run)) {
                for (x0, x1) in stored.runs(y) {
                    data.extend_from_slice(&row[x0..x1]);
                }
            }
        })
    }
}

/// The most maps [`combine_maps`] takes (one bit each per block).
pub const MAX_MAPS: usize = 64;

/// How a scene's maps were combined into weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapNormalisation {
    /// Maps divided by their sum wherever any is non-zero.
    Sum,
    /// Each map multiplied by what the earlier maps left.
    Priority,
}

/// The scene-level part of combining maps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CombineRecord {
    /// Gaussian kernel applied to every map, if any.
    pub blur_kernel: Option<usize>,
    /// How the maps were normalised.
    pub normalisation: MapNormalisation,
    /// Whether the weights were made one-hot.
    pub hard: bool,
}

/// K material weight maps and the background weight: per pixel they sum to 1.
#[derive(Clone, Debug)]
pub struct CombinedMaps {
    /// One weight map per material, stored where its map (blurred) can be
    /// positive.
    pub weights: Vec<SparsePlane>,
    /// Where each weight is positive (within the stored blocks).
    pub coverage: Vec<Coverage>,
    /// Background weight, `1 - sum(weights)`.
    pub background: Plane,
    /// How they were combined.
    pub record: CombineRecord,
}

/// A scene's weights and how each map was drawn.
#[derive(Clone, Debug)]
pub struct SoftMaps {
    /// The weights.
    pub combined: CombinedMaps,
    /// How each map was drawn.
    pub maps: Vec<MapRecord>,
}

/// Failure to draw maps.
#[derive(Debug, thiserror::Error)]
pub enum SoftMapError {
    /// The photo library failed.
    #[error(transparent)]
    Library(#[from] LibraryError),
    /// No acceptable map after the allowed number of draws.
    #[error("{sources}: no usable soft map after {draws} draws (are the photos flat?)")]
    Exhausted {
        /// The photo sources.
        sources: String,
        /// Draws made.
        draws: u32,
    },
}

/// Resizes-and-crops `photo` for a `w x h` window: upscaled only as far as
/// needed to cover it; otherwise, with probability `p_downscale`, shrunk by
/// r ~ U(1, largest covering ratio), else kept at native resolution; or, with
/// `fit_by_default`, shrunk until its short side fits. The crop is uniform.
pub fn random_placement<R: Rng + ?Sized>(
    rng: &mut R,
    photo: &Photo,
    w: usize,
    h: usize,
    p_downscale: f64,
    fit_by_default: bool,
) -> CropWindow {
    let (pw, ph) = (photo.pyramid.width(), photo.pyramid.height());
    let cover = CropWindow::cover_scale(pw, ph, w, h);
    let scale = if cover >= 1.0 {
        cover
    } else if rng.random_bool(p_downscale) {
        1.0 / rng.random_range(1.0..=1.0 / cover)
    } else if fit_by_default {
        cover
    } else {
        1.0
    };
    let (rw, rh) = CropWindow::resized_size(pw, ph, scale, w, h);
    CropWindow {
        resized_w: rw,
        resized_h: rh,
        x0: rng.random_range(0..=rw - w as u32),
        y0: rng.random_range(0..=rh - h as u32),
    }
}

/// Where a `w x h` window of one channel of `photo` comes from: placed by
/// [`random_placement`] (native resolution by default), the channel one of
/// H, S, V with probability `p_hsv`, else one of R, G, B.
pub fn random_channel_placement<R: Rng + ?Sized>(
    rng: &mut R,
    photo: &Photo,
    w: usize,
    h: usize,
    p_downscale: f64,
    p_hsv: f64,
) -> (CropWindow, Channel) {
    let placement = random_placement(rng, photo, w, h, p_downscale, false);
    let channels = if rng.random_bool(p_hsv) {
        Channel::HSV
    } else {
        Channel::RGB
    };
    (placement, channels[rng.random_range(0..3)])
}

/// One attempt at a map from one photo: `None` when the photo gives no
/// acceptable threshold (the caller draws another photo). Each threshold
/// tried is one count of the window's levels at or above a level; the map
/// is one table lookup per pixel.
fn try_map_from_photo<R: Rng + ?Sized>(
    rng: &mut R,
    photo: &Photo,
    w: usize,
    h: usize,
    max_occupancy: f64,
    hard: bool,
    recipe: &SoftMapRecipe,
) -> Option<(RawMap, MapRecord)> {
    let (placement, channel) =
        random_channel_placement(rng, photo, w, h, recipe.p_downscale, recipe.p_hsv_channel);
    let window = photo.pyramid.sample_channel(&placement, w, h, channel);
    let normalised_by_max = rng.random_bool(recipe.p_normalise_by_max);
    let values = level_values(if normalised_by_max {
        window.max_level()
    } else {
        255
    });

    let n = window.levels.len() as f64;
    let min_side = recipe.min_side_fraction * n;
    let mut counts = LevelCounts::new(&window);
    let mut accepted = None;
    for _ in 0..recipe.high_threshold_tries {
        let t: f32 = rng.random();
        let level = LevelCounts::first_above(&values, t);
        // Too few above even at the most, or too many even at the least:
        // rejected without counting.
        let (least, most) = counts.bounds(level);
        if most as f64 <= min_side || least as f64 > max_occupancy * n {
            continue;
        }
        let above = counts.exact(level) as f64;
        if above > min_side && above <= max_occupancy * n {
            accepted = Some((t, above));
            break;
        }
    }
    let (high, above) = accepted?;

    let mut low = high;
    if !hard && !rng.random_bool(recipe.p_binary) {
        // Holds for a `below` count and every larger one: the low side
        // grows and the band shrinks.
        let acceptable = |below: f64| {
            let band = n - above - below;
            below > min_side && band < recipe.max_band_to_side_ratio * above.min(below)
        };
        for _ in 0..recipe.low_threshold_tries {
            let t = rng.random::<f32>() * high;
            let level = LevelCounts::first_above(&values, t);
            // The fewest pixels at or above the level leave the most below:
            // if even that fails, it fails; if the fewest below pass, it
            // passes; else the count decides.
            let (least, most) = counts.bounds(level);
            if acceptable(n - least as f64)
                && (acceptable(n - most as f64) || acceptable(n - counts.exact(level) as f64))
            {
                low = t;
                break;
            }
        }
    }
    let ramp = Ramp { low, high };
    let table: LevelTable = values.map(|v| ramp.apply(v));
    // The ramp is 1 above `high`, so the map's mass is at least `above`
    // (a sum of non-negative terms, rounded up or down alike): the whole
    // histogram is needed only when that does not settle it.
    if above < recipe.min_map_mass && window.histogram().weighted_sum(&table) < recipe.min_map_mass
    {
        return None;
    }
    let record = MapRecord {
        photo: photo.index,
        placement,
        channel: window.channel,
        normalised_by_max,
        ramp,
    };
    Some((RawMap::new(window, table), record))
}

/// Draws one soft map of size `w x h` (pipeline.md §1, steps 1-5), redrawing photos
/// until one gives an acceptable map.
pub fn draw_channel_map<R: Rng + ?Sized>(
    rng: &mut R,
    library: &PhotoLibrary,
    w: usize,
    h: usize,
    max_occupancy: f64,
    hard: bool,
    recipe: &SoftMapRecipe,
) -> Result<(RawMap, MapRecord), SoftMapError> {
    for _ in 0..recipe.max_map_draws {
        let photo = library.pick(|n| rng.random_range(0..n))?;
        if let Some(found) = try_map_from_photo(rng, &photo, w, h, max_occupancy, hard, recipe) {
            return Ok(found);
        }
    }
    Err(SoftMapError::Exhausted {
        sources: library.label().to_string(),
        draws: recipe.max_map_draws,
    })
}

/// Combines raw maps into material weights (pipeline.md §1, step 6): optional blur,
/// sum or priority normalisation, one-hot for hard scenes; returns the weights,
/// where they are positive, the background weight and the record of what was drawn.
///
/// A weight is zero wherever its map is, so every step works only on the
/// blocks where some map can be positive, with just the maps positive there.
///
/// # Panics
/// With no maps, more than [`MAX_MAPS`], or maps of different sizes.
pub fn combine_maps<R: Rng + ?Sized>(
    rng: &mut R,
    maps: Vec<RawMap>,
    hard: bool,
    recipe: &SoftMapRecipe,
) -> CombinedMaps {
    assert!((1..=MAX_MAPS).contains(&maps.len()), "1 to {MAX_MAPS} maps");
    let blur_kernel = rng
        .random_bool(recipe.p_blur)
        .then(|| recipe.blur_kernels[rng.random_range(0..recipe.blur_kernels.len())]);
    let normalisation = if rng.random_bool(recipe.p_sum_normalise) {
        MapNormalisation::Sum
    } else {
        MapNormalisation::Priority
    };
    let steps = RowSteps {
        normalisation,
        one_hot_min: hard.then_some(recipe.hard_min_weight as f32),
    };
    let (w, h) = (maps[0].width(), maps[0].height());
    assert!(
        maps.iter().all(|m| (m.width(), m.height()) == (w, h)),
        "maps of one size"
    );
    let mut weights: Vec<SparsePlane> = maps.iter().map(|m| m.blurred(blur_kernel)).collect();
    drop(maps);
    let mut coverage: Vec<Coverage> = weights.iter().map(|_| Coverage::empty(w, h)).collect();
    // The background is made row by row, each row 1 until the blocks where
    // some map is stored are combined into it while it is in cache (a
    // whole plane of ones would be one more pass over memory).
    let mut background = Vec::with_capacity(w * h);
    let mut blocks = Vec::new();
    let mut spare_rows: Vec<&mut [f32]> = Vec::with_capacity(weights.len());
    for y in 0..h {
        member_blocks(&weights, y, &mut blocks);
        background.resize((y + 1) * w, 1.0);
        let mut rows = recycled(std::mem::take(&mut spare_rows));
        rows.extend(weights.iter_mut().map(|m| m.row_mut(y)));
        combine_row(
            steps,
            &blocks,
            &mut rows,
            &mut background[y * w..],
            (y, &mut coverage),
        );
        spare_rows = recycled(rows);
    }
    let background = Plane::from_vec(w, h, background);
    CombinedMaps {
        weights,
        coverage,
        background,
        record: CombineRecord {
            blur_kernel,
            normalisation,
            hard,
        },
    }
}

/// For each block of row `y`, the maps stored there: bit `k` of
/// `blocks[b]` is set when map `k` stores block `b` (`blocks` is kept from
/// row to row).
fn member_blocks(maps: &[SparsePlane], y: usize, blocks: &mut Vec<u64>) {
    // Each map's stored blocks set its bit (maps cover a few blocks each).
    blocks.clear();
    blocks.resize(maps[0].stored().blocks_per_row(), 0);
    for (k, m) in maps.iter().enumerate() {
        for (i, &word) in m.stored().row(y).iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                blocks[i * 64 + bits.trailing_zeros() as usize] |= 1 << k;
                bits &= bits - 1;
            }
        }
    }
}

/// The indices of the set bits of `set`, in increasing order.
fn bits(mut set: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        let k = set.trailing_zeros() as usize;
        set &= set.wrapping_sub(1);
        (k < 64).then_some(k)
    })
}

/// An empty vector with `v`'s allocation, free of its borrows (so one
/// buffer of row slices serves every row, while the planes they borrow
/// are read between rows).
fn recycled<'b>(mut v: Vec<&mut [f32]>) -> Vec<&'b mut [f32]> {
    v.clear();
    v.into_iter()
        .map(|_| unreachable!("the vector is empty"))
        .collect()
}

/// What [`combine_row`] does to a block.
#[derive(Clone, Copy)]
struct RowSteps {
    normalisation: MapNormalisation,
    /// One-hot, with this minimum top weight.
    one_hot_min: Option<f32>,
}

/// All steps of [`combine_maps`] on row `y`: each block where some map is
/// stored (`blocks[b]`, as [`member_blocks`] has them) combined across its
/// member maps, whose values `maps[k]` holds stored block after stored
/// block, and the background row, which starts at 1; the blocks where each
/// weight is positive recorded in its coverage. Compiled also for AVX2,
/// picked at run time when the CPU has it (the arithmetic is the same, so
/// are the results).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn combine_row(
    steps: RowSteps,
    blocks: &[u64],
    maps: &mut [&mut [f32]],
    background: &mut [f32],
    (y, coverage): (usize, &mut [Coverage]),
) {
    let width = background.len();
    for (b, &set) in blocks.iter().enumerate() {
        if set == 0 {
            continue;
        }
        let x0 = b * BLOCK;
        let n = BLOCK.min(width - x0);
        let block = Block {
            set,
            background: &mut background[x0..x0 + n],
            y,
            x0,
        };
        // Whole blocks of one to three maps (most of them) with the count
        // fixed, so that the loops over the maps unroll.
        match (n == BLOCK).then(|| set.count_ones()) {
            Some(1) => block.combine_whole::<1>(steps, maps, coverage),
            Some(2) => block.combine_whole::<2>(steps, maps, coverage),
            Some(3) => block.combine_whole::<3>(steps, maps, coverage),
            _ => block.combine_any(steps, maps, coverage),
        }
    }
}

/// One block of a row where some map is stored; see [`combine_row`].
struct Block<'r> {
    /// Bit `k` for each map stored here.
    set: u64,
    /// The block's background values, 1 until combined.
    background: &'r mut [f32],
    /// Its row.
    y: usize,
    /// Its first column.
    x0: usize,
}

impl Block<'_> {
    /// A whole block of exactly `M` member maps.
    #[inline(always)]
    fn combine_whole<const M: usize>(
        self,
        steps: RowSteps,
        maps: &mut [&mut [f32]],
        coverage: &mut [Coverage],
    ) {
        let mut members = bits(self.set);
        let keys: [usize; M] = std::array::from_fn(|_| members.next().expect("M maps"));
        let mut blocks: [&mut [f32; BLOCK]; M] = keys.map(|k| {
            next_values(&mut maps[k], BLOCK)
                .try_into()
                .expect("a whole block")
        });
        let left: &mut [f32; BLOCK] = self.background.try_into().expect("a whole block");
        combine_lanes(steps, &mut blocks, left, 0);
        for (&k, block) in keys.iter().zip(&blocks) {
            coverage[k].add_run(self.y, self.x0, &block[..]);
        }
    }

    /// Any block: a whole one in one step, one cut by the width pixel by
    /// pixel.
    fn combine_any(self, steps: RowSteps, maps: &mut [&mut [f32]], coverage: &mut [Coverage]) {
        let n = self.background.len();
        let mut members: [&mut [f32]; MAX_MAPS] = std::array::from_fn(|_| Default::default());
        let mut m = 0;
        for k in bits(self.set) {
            members[m] = next_values(&mut maps[k], n);
            m += 1;
        }
        let members = &mut members[..m];
        match <&mut [f32; BLOCK]>::try_from(&mut *self.background) {
            Ok(left) => combine_lanes(steps, members, left, 0),
            Err(_) => {
                for (x, left) in self.background.iter_mut().enumerate() {
                    combine_lanes(steps, members, std::array::from_mut(left), x);
                }
            }
        }
        for (k, block) in bits(self.set).zip(members.iter()) {
            coverage[k].add_run(self.y, self.x0, block);
        }
    }
}

/// The next `n` values of `map`, taken off it.
#[inline(always)]
fn next_values<'m>(map: &mut &'m mut [f32], n: usize) -> &'m mut [f32] {
    let (values, rest) = std::mem::take(map).split_at_mut(n);
    *map = rest;
    values
}

/// The `LANES` values of `row` from `x`.
#[inline(always)]
fn lanes_at<const LANES: usize>(row: &mut [f32], x: usize) -> &mut [f32; LANES] {
    (&mut row[x..x + LANES])
        .try_into()
        .expect("a step of LANES")
}

/// The steps of [`combine_maps`] on `LANES` pixels from `x` of each member
/// map's values (`maps`, in map order) and of the background (`left`,
/// which starts at 1): normalisation, one-hot if hard, then `left = 1 -
/// sum(maps)` clamped to `[0, 1]`. Each pixel's arithmetic is branch-free
/// and in map order.
#[inline(always)]
fn combine_lanes<const LANES: usize, R: AsMut<[f32]>>(
    steps: RowSteps,
    maps: &mut [R],
    left: &mut [f32; LANES],
    x: usize,
) {
    match steps.normalisation {
        // Divides the maps by their sum wherever it is positive (dividing
        // by 1 elsewhere keeps every lane a plain store).
        MapNormalisation::Sum => {
            let mut total = [0f32; LANES];
            for m in maps.iter_mut() {
                let m: &mut [f32; LANES] = lanes_at(m.as_mut(), x);
                for j in 0..LANES {
                    total[j] += m[j];
                }
            }
            for m in maps.iter_mut() {
                let m: &mut [f32; LANES] = lanes_at(m.as_mut(), x);
                for j in 0..LANES {
                    m[j] /= if total[j] > 0.0 { total[j] } else { 1.0 };
                }
            }
        }
        // Each map keeps its share of what the earlier maps left.
        MapNormalisation::Priority => {
            let mut remaining = [1f32; LANES];
            for m in maps.iter_mut() {
                let m: &mut [f32; LANES] = lanes_at(m.as_mut(), x);
                for j in 0..LANES {
                    m[j] *= remaining[j];
                    remaining[j] = (remaining[j] - m[j]).max(0.0);
                }
            }
        }
    }
    if let Some(min) = steps.one_hot_min {
        // One-hot of the arg-max (the first map wins ties); pixels whose
        // top weight is below `min`, or zero, become background. `best`
        // holds map indices as floats, updated by arithmetic (exact for
        // small whole numbers) so that the lanes stay equal-width.
        let (mut top, mut best) = ([f32::MIN; LANES], [0f32; LANES]);
        for (k, m) in maps.iter_mut().enumerate() {
            let (k, m): (f32, &mut [f32; LANES]) = (k as f32, lanes_at(m.as_mut(), x));
            for j in 0..LANES {
                let above = f32::from(u8::from(m[j] > top[j]));
                best[j] += (k - best[j]) * above;
                top[j] = top[j].max(m[j]);
            }
        }
        for (k, m) in maps.iter_mut().enumerate() {
            let (k, m): (f32, &mut [f32; LANES]) = (k as f32, lanes_at(m.as_mut(), x));
            for j in 0..LANES {
                let won = best[j] == k && top[j] >= min && top[j] > 0.0;
                m[j] = if won { 1.0 } else { 0.0 };
            }
        }
    }
    // In registers while the maps are subtracted.
    let mut rest = *left;
    for m in maps.iter_mut() {
        let m: &mut [f32; LANES] = lanes_at(m.as_mut(), x);
        for j in 0..LANES {
            rest[j] -= m[j];
        }
    }
    for (l, r) in left.iter_mut().zip(rest) {
        *l = r.clamp(0.0, 1.0);
    }
}

/// Draws `k` soft maps for a `w x h` scene and combines them (all of pipeline.md §1).
#[allow(clippy::too_many_arguments)]
pub fn make_soft_maps<R: Rng + ?Sized>(
    rng: &mut R,
    library: &PhotoLibrary,
    w: usize,
    h: usize,
    k: usize,
    hard: bool,
    max_occupancy: f64,
    recipe: &SoftMapRecipe,
) -> Result<SoftMaps, SoftMapError> {
    let mut raw = Vec::with_capacity(k);
    let mut maps = Vec::with_capacity(k);
    for _ in 0..k {
        let (map, record) = draw_channel_map(rng, library, w, h, max_occupancy, hard, recipe)?;
        raw.push(map);
        maps.push(record);
    }
    Ok(SoftMaps {
        combined: combine_maps(rng, raw, hard, recipe),
        maps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_image::gaussian_blur;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// pipeline.md §1 step 6 pixel by pixel on whole planes: the reference the
    /// block-sparse [`combine_maps`] must equal bit for bit.
    fn reference(maps: &[Plane], record: &CombineRecord, min: f32) -> (Vec<Plane>, Plane) {
        let mut maps: Vec<Plane> = match record.blur_kernel {
            Some(k) => maps.iter().map(|m| gaussian_blur(m, k)).collect(),
            None => maps.to_vec(),
        };
        let mut background = Plane::new(maps[0].width, maps[0].height, 1.0);
        for i in 0..background.len() {
            let mut v: Vec<f32> = maps.iter().map(|m| m.data[i]).collect();
            match record.normalisation {
                MapNormalisation::Sum => {
                    let total = v.iter().fold(0.0f32, |t, &x| t + x);
                    v.iter_mut()
                        .for_each(|x| *x /= if total > 0.0 { total } else { 1.0 });
                }
                MapNormalisation::Priority => {
                    let mut remaining = 1.0f32;
                    for x in v.iter_mut() {
                        *x *= remaining;
                        remaining = (remaining - *x).max(0.0);
                    }
                }
            }
            if record.hard {
                let (mut best, mut top) = (0, f32::MIN);
                for (k, &x) in v.iter().enumerate() {
                    if x > top {
                        (best, top) = (k, x);
                    }
                }
                for (k, x) in v.iter_mut().enumerate() {
                    *x = f32::from(u8::from(k == best && top >= min && top > 0.0));
                }
            }
            let rest = v.iter().fold(1.0f32, |b, &x| b - x);
            background.data[i] = rest.clamp(0.0, 1.0);
            for (m, x) in maps.iter_mut().zip(v) {
                m.data[i] = x;
            }
        }
        (maps, background)
    }

    /// A map that is zero but for a few rectangles of random levels (at
    /// most `reach` wide and high), so that whole blocks and rows are
    /// empty; with a ramp table (or, for `k == 2`, a table that is not
    /// monotone).
    fn sparse_map(
        rng: &mut ChaCha8Rng,
        (w, h): (usize, usize),
        reach: (usize, usize),
        k: usize,
    ) -> RawMap {
        let mut levels = vec![0u8; w * h];
        for _ in 0..rng.random_range(1..4) {
            let (x0, y0) = (rng.random_range(0..w), rng.random_range(0..h));
            let (x1, y1) = (
                (x0 + rng.random_range(1..=reach.0)).min(w),
                (y0 + rng.random_range(1..=reach.1)).min(h),
            );
            for y in y0..y1 {
                for x in x0..x1 {
                    levels[y * w + x] = rng.random_range(0..=255);
                }
            }
        }
        let table: LevelTable = if k == 2 {
            std::array::from_fn(|l| if l % 3 == 1 { 0.5 } else { 0.0 })
        } else {
            let low: f32 = rng.random_range(0.0..0.5);
            let ramp = Ramp {
                low,
                high: low + rng.random_range(0.0..0.5),
            };
            level_values(255).map(|v| ramp.apply(v))
        };
        let window = ChannelWindow {
            width: w,
            height: h,
            channel: Channel::R,
            levels,
        };
        RawMap::new(window, table)
    }

    #[test]
    fn sparse_combination_equals_the_whole_plane_reference() {
        let mut drawn = [false; 4];
        for seed in 0..80u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let (w, h) = (rng.random_range(20..90), rng.random_range(10..60));
            // Every fourth scene's maps overlap widely, so that whole
            // blocks hold four or more of them.
            let reach = if seed % 4 == 3 { (w, h) } else { (29, 11) };
            let maps: Vec<RawMap> = (0..rng.random_range(1..7))
                .map(|k| sparse_map(&mut rng, (w, h), reach, k))
                .collect();
            let planes: Vec<Plane> = maps.iter().map(RawMap::to_plane).collect();
            let hard = seed % 2 == 0;
            let recipe = SoftMapRecipe::default();
            let combined = combine_maps(&mut rng, maps, hard, &recipe);
            let record = &combined.record;
            drawn[usize::from(record.blur_kernel.is_some()) * 2
                + usize::from(record.normalisation == MapNormalisation::Sum)] = true;
            let (weights, background) = reference(&planes, record, recipe.hard_min_weight as f32);
            assert_eq!(combined.background, background, "seed {seed}");
            for (k, (got, want)) in combined.weights.iter().zip(&weights).enumerate() {
                assert_eq!(&got.to_plane(), want, "seed {seed}, map {k}");
                assert_eq!(
                    combined.coverage[k],
                    Coverage::of(want),
                    "seed {seed}, map {k}"
                );
            }
        }
        assert!(
            drawn.iter().all(|&d| d),
            "every blur and normalisation case"
        );
    }
}
