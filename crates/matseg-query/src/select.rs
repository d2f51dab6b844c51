//! A selection made by clicks, positive and negative: "this material",
//! "not that one". Each click's material is its point descriptor, and
//! every cell's similarity to the positive clicks (the best of them) is
//! set against its similarity to the negative ones.
//!
//! The decision is the selection's own, never a threshold picked with the
//! truth:
//! - a cell is selected when it is at least as similar to a positive
//!   click as Otsu's threshold of the first positive click's map says
//!   (the split between that map's two modes; later clicks do not move
//!   it), and no negative click is as similar to it. Clicks after the
//!   first reach less far: their similarity is lowered with the distance
//!   from where they were clicked, so a correction takes its own
//!   neighbourhood before the far side of the photo, and they reach only
//!   the cells very like them (cosine 0.85 at least), so a click on an
//!   edge, whose disc mixes two materials, takes neither wholesale. The
//!   photo's other materials (cells spread over its descriptors by
//!   farthest-point sampling, those below the threshold) count as
//!   negative clicks the user did not have to make, so a second positive
//!   material does not bring in what lies between it and the first;
//! - from the second click on, a linear classifier of the descriptors
//!   and of the photo's colours ([`crate::colour_features`]; ridge
//!   regression, the Gram matrix factorised once per photo) is fitted on
//!   that decision (each cell) and on the clicks (each positive one
//!   weighing as 500 cells, each negative one as 150), and decides
//!   instead, each pixel by its cell's descriptor and its own colour:
//!   where the clicks and the similarities disagree it
//!   finds the direction that tells the clicked materials apart, rather
//!   than flipping every cell near one click;
//! - the decision is brought to the photo's size, made to follow the
//!   photo's edges (a guided filter on its lightness) and its uncertain
//!   pixels decided by the photo's colours (histograms of the sure pixels
//!   in and out).
//!
//! The soft map is the positive similarity, lowered by a sigmoid where a
//! negative click's material is as near: with positive clicks alone it is
//! exactly the similarity map, so one click answers as it always did.

use crate::coarse::CoarseDescriptors;
use crate::colour_features::{bin_scores, disc_features, mean_features, FEATURES};
use crate::colours::ColourBins;
use crate::descriptor::{check_radius, Comparison, DescriptorMap, RadiusError};
use crate::edges::EdgeGuide;
use crate::ridge::{Columns, Ridge, WeightedRow};
use image::RgbImage;
use rayon::prelude::*;
use std::borrow::Cow;
use std::ops::Range;
use std::sync::{Arc, OnceLock};

/// The most clicks one selection takes.
pub const MAX_CLICKS: usize = 255;

/// A click on a photo, in its pixels: the material there is wanted
/// (positive) or not (negative).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Click {
    /// Column.
    pub x: f32,
    /// Row.
    pub y: f32,
    /// Whether the material under it is wanted.
    pub positive: bool,
}

impl Click {
    /// A click that wants the material at `(x, y)`.
    pub fn positive(x: f32, y: f32) -> Self {
        Self {
            x,
            y,
            positive: true,
        }
    }

    /// A click that excludes the material at `(x, y)`.
    pub fn negative(x: f32, y: f32) -> Self {
        Self {
            x,
            y,
            positive: false,
        }
    }
}

/// Why clicks make no selection.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SelectError {
    /// No positive click: nothing to select.
    #[error("give a positive click (the material to select) before negative ones")]
    NoPositive,
    /// Too many clicks.
    #[error("{0} clicks: at most {MAX_CLICKS}")]
    TooMany(usize),
    /// A click outside the photo.
    #[error("click {x},{y}: outside the {width}x{height} photo")]
    Outside {
        /// Its column.
        x: f32,
        /// Its row.
        y: f32,
        /// The photo's width.
        width: usize,
        /// The photo's height.
        height: usize,
    },
    /// A radius out of range.
    #[error(transparent)]
    Radius(#[from] RadiusError),
    /// A saved descriptor of another length than the model's, or saved
    /// colour features of another length than [`FEATURES`].
    #[error("{kind}[{index}]: {len} values where {dim} are expected (the model's descriptors, or the colour features)")]
    WrongLength {
        /// `positive`, `negative`, `positive colours` or `negative colours`.
        kind: &'static str,
        /// Which of them.
        index: usize,
        /// Its length.
        len: usize,
        /// The model's.
        dim: usize,
    },
    /// A saved descriptor with no direction: all zeros, or so large that
    /// its length is not a finite number.
    #[error("{kind}[{index}]: its length is {length}, not a finite, non-zero number")]
    NoDirection {
        /// `positive` or `negative`.
        kind: &'static str,
        /// Which of them.
        index: usize,
        /// Its length.
        length: f32,
    },
    /// Saved colour features beyond what any colour gives.
    #[error("{kind}[{index}]: a value beyond {bound}, which no colour's features reach")]
    ColourRange {
        /// `positive colours` or `negative colours`.
        kind: &'static str,
        /// Which of them.
        index: usize,
        /// The features' largest magnitude.
        bound: f32,
    },
    /// A positive and a negative click of the same descriptor and colour:
    /// a click cannot both select and exclude.
    #[error("positive[{positive}] and negative[{negative}] are the same click (descriptor and colour): a material cannot be both selected and excluded")]
    Contradictory {
        /// The positive click.
        positive: usize,
        /// The negative click.
        negative: usize,
    },
    /// A saved descriptor with a value that is not a finite number.
    #[error("{kind}[{index}]: a value that is not a finite number")]
    NotFinite {
        /// `positive`, `negative`, `positive colours` or `negative colours`.
        kind: &'static str,
        /// Which of them.
        index: usize,
    },
    /// Saved colour features not one for each click of their kind.
    #[error("{count} {kind} for {clicks} clicks: one for each, or none at all")]
    Colours {
        /// `positive colours` or `negative colours`.
        kind: &'static str,
        /// How many were saved.
        count: usize,
        /// The clicks of that kind.
        clicks: usize,
    },
}

/// What a selection is made from: descriptors on cells (a photo's pixels,
/// or a coarse grid over it) that answer a descriptor with every cell's
/// similarity (higher is closer, 1 the same), and cell values resized to
/// the photo.
pub trait ClickSpace: Sync {
    /// The photo's width and height, in pixels.
    fn photo_size(&self) -> (usize, usize);
    /// The descriptor of the disc of `radius` photo pixels around `(x, y)`.
    fn descriptor_at(&self, x: f32, y: f32, radius: f32) -> Vec<f32>;
    /// Every cell's similarity to `descriptor`.
    fn similarities_to(&self, descriptor: &[f32]) -> Vec<f32>;
    /// How many cells there are.
    fn cells(&self) -> usize;
    /// The descriptor of cell `cell`.
    fn cell_descriptor(&self, cell: usize) -> Vec<f32>;
    /// Cell values resized to the photo, row by row.
    fn to_photo(&self, cells: Vec<f32>) -> Vec<f32>;
    /// The centre of cell `cell`, in photo pixels.
    fn cell_centre(&self, cell: usize) -> (f32, f32);
    /// The photo pixels cell `cell` covers: columns and rows (one pixel
    /// at least).
    fn cell_pixels(&self, cell: usize) -> (Range<usize>, Range<usize>);
    /// The cells a selection's classifier is fitted on (all of them, or
    /// an even subset of a large space), and their descriptors row by row.
    fn fit_rows(&self) -> (Cow<'_, [usize]>, Cow<'_, [f32]>);
    /// Every cell's descriptor's dot product with `weights`, plus `bias`.
    fn project(&self, weights: &[f32], bias: f32) -> Vec<f32>;
}

impl ClickSpace for CoarseDescriptors {
    fn photo_size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn descriptor_at(&self, x: f32, y: f32, radius: f32) -> Vec<f32> {
        self.point_descriptor(x, y, radius)
    }

    fn similarities_to(&self, descriptor: &[f32]) -> Vec<f32> {
        self.cell_similarity(descriptor)
    }

    fn cells(&self) -> usize {
        self.grid.width * self.grid.height
    }

    fn cell_descriptor(&self, cell: usize) -> Vec<f32> {
        self.grid.at(cell).to_vec()
    }

    fn to_photo(&self, cells: Vec<f32>) -> Vec<f32> {
        self.resize_to_photo(&cells)
    }

    fn cell_centre(&self, cell: usize) -> (f32, f32) {
        let (gw, gh) = (self.grid.width, self.grid.height);
        (
            ((cell % gw) as f32 + 0.5) * self.width as f32 / gw as f32,
            ((cell / gw) as f32 + 0.5) * self.height as f32 / gh as f32,
        )
    }

    fn cell_pixels(&self, cell: usize) -> (Range<usize>, Range<usize>) {
        let (gw, gh) = (self.grid.width, self.grid.height);
        // The pixels whose nearest cell it is.
        let span = |c: usize, cells: usize, pixels: usize| {
            let start = (c * pixels / cells).min(pixels - 1);
            start..((c + 1) * pixels / cells).clamp(start + 1, pixels)
        };
        (
            span(cell % gw, gw, self.width),
            span(cell / gw, gh, self.height),
        )
    }

    fn fit_rows(&self) -> (Cow<'_, [usize]>, Cow<'_, [f32]>) {
        let cells = even_subset(self.grid.width, self.grid.height);
        if cells.len() == self.grid.width * self.grid.height {
            return (Cow::Owned(cells), Cow::Borrowed(&self.grid.data));
        }
        let rows = cells
            .iter()
            .flat_map(|&c| self.grid.at(c))
            .copied()
            .collect();
        (Cow::Owned(cells), Cow::Owned(rows))
    }

    fn project(&self, weights: &[f32], bias: f32) -> Vec<f32> {
        self.cell_similarity(weights)
            .into_iter()
            .map(|p| p + bias)
            .collect()
    }
}

/// A descriptor map of the photo's own size, compared as its model
/// compares. Distances (colour statistics) become similarities on the
/// photo's own scale: `1 - d / (2 s)`, `s` the mean distance of the
/// pixels to their mean descriptor.
pub struct PixelSpace<'a> {
    map: &'a DescriptorMap,
    comparison: Comparison,
    spread: f32,
    /// The pixels a classifier is fitted on and their descriptors,
    /// gathered at the first fit.
    fit: OnceLock<(Vec<usize>, Vec<f32>)>,
}

impl<'a> PixelSpace<'a> {
    /// The map `map`, compared as `comparison` says.
    pub fn new(map: &'a DescriptorMap, comparison: Comparison) -> Self {
        let spread = match comparison {
            Comparison::Cosine => 1.0,
            Comparison::NegativeEuclidean => mean_spread(map),
        };
        Self {
            map,
            comparison,
            spread,
            fit: OnceLock::new(),
        }
    }
}

/// The mean distance of a map's descriptors to their mean (1 when they
/// are all alike).
fn mean_spread(map: &DescriptorMap) -> f32 {
    let n = map.width * map.height;
    if n == 0 {
        return 1.0;
    }
    let mut mean = vec![0f64; map.dim];
    for i in 0..n {
        for (m, &v) in mean.iter_mut().zip(map.at(i)) {
            *m += v as f64;
        }
    }
    let mean: Vec<f32> = mean.iter().map(|m| (m / n as f64) as f32).collect();
    let total: f64 = (0..n)
        .map(|i| -Comparison::NegativeEuclidean.similarity(&mean, map.at(i)))
        .sum();
    let spread = (total / n as f64) as f32;
    if spread > 0.0 {
        spread
    } else {
        1.0
    }
}

impl ClickSpace for PixelSpace<'_> {
    fn photo_size(&self) -> (usize, usize) {
        (self.map.width, self.map.height)
    }

    fn descriptor_at(&self, x: f32, y: f32, radius: f32) -> Vec<f32> {
        self.map.point_descriptor(x, y, radius, self.comparison)
    }

    fn similarities_to(&self, descriptor: &[f32]) -> Vec<f32> {
        let map = self.map.similarity_map(descriptor, self.comparison);
        match self.comparison {
            Comparison::Cosine => map,
            Comparison::NegativeEuclidean => map
                .into_iter()
                .map(|s| 1.0 + s / (2.0 * self.spread))
                .collect(),
        }
    }

    fn cells(&self) -> usize {
        self.map.width * self.map.height
    }

    fn cell_descriptor(&self, cell: usize) -> Vec<f32> {
        let (x, y) = (
            (cell % self.map.width) as f32,
            (cell / self.map.width) as f32,
        );
        self.map.point_descriptor(x, y, 0.0, self.comparison)
    }

    fn to_photo(&self, cells: Vec<f32>) -> Vec<f32> {
        cells
    }

    fn cell_centre(&self, cell: usize) -> (f32, f32) {
        (
            (cell % self.map.width) as f32 + 0.5,
            (cell / self.map.width) as f32 + 0.5,
        )
    }

    fn cell_pixels(&self, cell: usize) -> (Range<usize>, Range<usize>) {
        let (x, y) = (cell % self.map.width, cell / self.map.width);
        (x..x + 1, y..y + 1)
    }

    fn fit_rows(&self) -> (Cow<'_, [usize]>, Cow<'_, [f32]>) {
        let (cells, rows) = self.fit.get_or_init(|| {
            let cells = even_subset(self.map.width, self.map.height);
            let rows = cells
                .iter()
                .flat_map(|&c| self.map.at(c))
                .copied()
                .collect();
            (cells, rows)
        });
        (Cow::Borrowed(cells), Cow::Borrowed(rows))
    }

    fn project(&self, weights: &[f32], bias: f32) -> Vec<f32> {
        (0..self.map.width * self.map.height)
            .into_par_iter()
            .map(|i| {
                self.map
                    .at(i)
                    .iter()
                    .zip(weights)
                    .map(|(a, b)| a * b)
                    .sum::<f32>()
                    + bias
            })
            .collect()
    }
}

/// The most rows a selection's classifier is fitted on (cells beyond this
/// are subsampled evenly): about the cells of the net's stride-4 grid
/// over a 700 px photo.
const FIT_ROWS: usize = 32_768;

/// The cells of a `w x h` grid a classifier is fitted on: all of them when
/// there are [`FIT_ROWS`] at most, else every `step`-th cell of every
/// `step`-th row, `step` the least that keeps them within.
fn even_subset(w: usize, h: usize) -> Vec<usize> {
    let mut step = 1;
    while w.div_ceil(step) * h.div_ceil(step) > FIT_ROWS {
        step += 1;
    }
    (0..h)
        .step_by(step)
        .flat_map(|y| (0..w).step_by(step).map(move |x| y * w + x))
        .collect()
}

/// A selection: how strongly each pixel belongs to it, and the pixels in
/// it, row by row over the photo.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// The photo's width.
    pub width: usize,
    /// The photo's height.
    pub height: usize,
    /// Each pixel's strength, at most 1 (positive clicks alone: its
    /// similarity to the nearest of them, exactly the one-click map;
    /// lowered where a negative click's material is as near or nearer).
    pub soft: Vec<f32>,
    /// Whether each pixel is selected: the selection's own decision.
    pub mask: Vec<bool>,
}

impl Selection {
    /// The share of the photo selected, 0..1.
    pub fn area(&self) -> f64 {
        let selected = self.mask.iter().filter(|&&m| m).count();
        selected as f64 / self.mask.len().max(1) as f64
    }
}

/// How much a click other than the first loses of its similarity to a
/// cell the photo's longer side away from it.
const REACH: f32 = 0.2;

/// How like a click after the first a cell must be for the click to take
/// it (or, a negative click, to leave it out), as a cosine similarity (or
/// Otsu's threshold of the first click's map, when higher): a correcting
/// click is often on an edge or a small patch, where its disc mixes two
/// materials and is somewhat like much of the photo; at 0.85 it takes its
/// own material, not all that (BENCHMARKS.md, "Clicks that make a
/// selection worse").
const CORRECTION_LEVEL: f32 = 0.85;

/// The share of the photo a positive click weighs as when the classifier
/// is fitted: 500 of the 23,000 cells of the net's grid over a 700 px
/// photo.
const CLICK_SHARE: f64 = 500.0 / 23_000.0;

/// The share a negative click weighs as: less than a positive one, so that
/// a negative click on an edge, whose disc is partly the material wanted,
/// does not turn the classifier away from much of that material.
const NEGATIVE_CLICK_SHARE: f64 = 150.0 / 23_000.0;

/// The classifier's regularisation of its squared weights, as a share of
/// the cells fitted (10 of 23,000).
const RIDGE_SHARE: f64 = 10.0 / 23_000.0;

/// How many of the photo's materials a selection sets the clicks against.
const PROTOTYPES: usize = 12;

/// How wide a negative click's reach is: the soft map falls to half where
/// a pixel is as similar to a negative click as to the positive ones, and
/// to a quarter of its similarity this much closer to the negative.
const NEGATIVE_TEMPERATURE: f32 = 0.1;

/// The selection `clicks` make on `space` (discs of `radius` photo
/// pixels), its edges made to follow `photo`'s when given (the photo the
/// space describes, at its size).
pub fn select(
    space: &dyn ClickSpace,
    photo: Option<&RgbImage>,
    clicks: &[Click],
    radius: f32,
) -> Result<Selection, SelectError> {
    let mut selector = Selector::new(space, photo, radius)?;
    if clicks.len() > MAX_CLICKS {
        return Err(SelectError::TooMany(clicks.len()));
    }
    for &click in clicks {
        selector.add(click)?;
    }
    selector.selection()
}

/// One query of a selection: a descriptor wanted or not, and every
/// cell's similarity to it.
struct Query {
    positive: bool,
    descriptor: Vec<f32>,
    similarities: Vec<f32>,
    /// The similarities lowered with the distance from where it was
    /// clicked (see [`Selector::reach`]); none for a saved descriptor.
    near: Option<Vec<f32>>,
    /// The colour features of the click's disc, when the selection has
    /// the photo or the saved selection kept them.
    colour: Option<Vec<f32>>,
}

/// Clicks added one at a time to a selection, each click's similarities
/// computed once: what a run of many clicks (the click benchmark) keeps.
pub struct Selector<'a> {
    space: &'a dyn ClickSpace,
    photo: Option<&'a RgbImage>,
    radius: f32,
    queries: Vec<Query>,
    /// What the selection needs of the photo whatever the clicks.
    prep: Arc<PhotoPrep>,
}

/// What a selection needs of its photo whatever the clicks, each part made
/// the first time a selection needs it and kept: the photo's materials
/// (cells spread over its descriptors, each with every cell's similarity
/// to it), the classifier's factorised Gram matrix (of the descriptors
/// and the colours, or of the descriptors alone for clicks without their
/// colours), the fitted cells' colour features, and the photo's edges and
/// colours. Share one between the selections of one photo (the web app
/// keeps one per described photo) and a click costs only its own work.
#[derive(Default)]
pub struct PhotoPrep {
    prototypes: OnceLock<Vec<(usize, Vec<f32>)>>,
    ridge: OnceLock<Ridge>,
    colour_ridge: OnceLock<Ridge>,
    colour_rows: OnceLock<Vec<f32>>,
    guides: OnceLock<(EdgeGuide, ColourBins)>,
}

impl PhotoPrep {
    /// The most bytes a photo's preparation holds: a `width x height`
    /// photo, `cells` cells of `dim` values.
    pub fn bytes_at_most(width: usize, height: usize, cells: usize, dim: usize) -> usize {
        let pixels = width * height;
        let factor = |side: usize| 8 * side * side;
        // The photo's lightness (4 bytes a pixel), its colours' bins (2),
        // the guide's grid (at most 512 x 512 cells, 3 values of 4 bytes),
        // the materials' maps, the fitted cells' colours and the two
        // factorised Gram matrices.
        6 * pixels
            + 512 * 512 * 12
            + PROTOTYPES * 4 * cells
            + FEATURES * 4 * cells.min(FIT_ROWS)
            + factor(dim + 1)
            + factor(dim + FEATURES + 1)
    }

    /// Every part made now for `space` and `photo` (as a selection would
    /// be given them), so that no click waits for one: what the web app
    /// does as soon as it has described a photo.
    pub fn prepare(&self, space: &dyn ClickSpace, photo: Option<&RgbImage>) {
        self.prototypes(space);
        let (cells, rows) = space.fit_rows();
        let descriptors = Columns {
            values: &rows,
            width: rows.len() / cells.len().max(1),
        };
        match photo.filter(|p| fits(p, space)) {
            Some(photo) => {
                let bins = &self.guides(photo).1;
                let colours = self.colour_rows(space, bins, &cells);
                self.colour_ridge(&[descriptors, colours]);
            }
            None => {
                self.ridge(&[descriptors]);
            }
        }
    }

    /// The photo's materials: [`PROTOTYPES`] cells chosen one at a time,
    /// each the cell least like all chosen before (the first the one
    /// least like the photo's middle cell), with their similarity maps.
    fn prototypes(&self, space: &dyn ClickSpace) -> &[(usize, Vec<f32>)] {
        self.prototypes.get_or_init(|| {
            let cells = space.cells();
            let of_cell = |cell: usize| space.similarities_to(&space.cell_descriptor(cell));
            let mut closest = of_cell(cells / 2);
            let mut chosen: Vec<(usize, Vec<f32>)> = Vec::new();
            while chosen.len() < PROTOTYPES.min(cells) {
                let (next, _) = closest
                    .iter()
                    .enumerate()
                    .min_by(|(i, a), (j, b)| a.total_cmp(b).then(i.cmp(j)))
                    .expect("cells");
                let map = of_cell(next);
                for (c, &s) in closest.iter_mut().zip(&map) {
                    *c = c.max(s);
                }
                chosen.push((next, map));
            }
            chosen
        })
    }

    /// The classifier's factorised Gram matrix of the space's fitted
    /// rows ([`ClickSpace::fit_rows`]), their descriptors alone.
    fn ridge(&self, blocks: &[Columns<'_>; 1]) -> &Ridge {
        self.ridge.get_or_init(|| ridge_of(blocks))
    }

    /// The classifier's factorised Gram matrix of the space's fitted
    /// rows, their descriptors and their colours.
    fn colour_ridge(&self, blocks: &[Columns<'_>; 2]) -> &Ridge {
        self.colour_ridge.get_or_init(|| ridge_of(blocks))
    }

    /// The colour features of each of `cells` (the fitted cells): the
    /// mean of its pixels' ([`FEATURES`] values a cell).
    fn colour_rows(
        &self,
        space: &dyn ClickSpace,
        bins: &ColourBins,
        cells: &[usize],
    ) -> Columns<'_> {
        let rows = self.colour_rows.get_or_init(|| {
            let width = space.photo_size().0;
            cells
                .par_iter()
                .flat_map_iter(|&cell| {
                    let (xs, ys) = space.cell_pixels(cell);
                    mean_features(bins, width, xs, ys)
                })
                .collect()
        });
        Columns {
            values: rows,
            width: FEATURES,
        }
    }

    /// The photo's edges and colours.
    fn guides(&self, photo: &RgbImage) -> &(EdgeGuide, ColourBins) {
        self.guides.get_or_init(|| {
            (
                EdgeGuide::new(photo, GUIDE_RADIUS, GUIDE_EPSILON),
                ColourBins::new(photo),
            )
        })
    }
}

/// The factorised Gram matrix of `blocks`, regularised as a share of the
/// rows fitted, whatever the photo's size and however finely it is
/// described.
fn ridge_of(blocks: &[Columns<'_>]) -> Ridge {
    let fitted = blocks
        .first()
        .map_or(0, |b| b.values.len() / b.width.max(1));
    Ridge::new(blocks, RIDGE_SHARE * fitted as f64)
}

/// 1 where `score` is above 0, else 0: a classifier's decision.
fn step(score: f32) -> f32 {
    if score > 0.0 {
        1.0
    } else {
        0.0
    }
}

/// `best` (when there is one) raised to `map` where `map` is higher, or
/// `map` itself.
fn raised(best: Option<Vec<f32>>, map: &[f32]) -> Vec<f32> {
    match best {
        None => map.to_vec(),
        Some(mut best) => {
            for (b, &m) in best.iter_mut().zip(map) {
                *b = b.max(m);
            }
            best
        }
    }
}

/// Whether `photo` is of `space`'s photo size.
fn fits(photo: &RgbImage, space: &dyn ClickSpace) -> bool {
    let (width, height) = space.photo_size();
    photo.dimensions() == (width as u32, height as u32)
}

impl<'a> Selector<'a> {
    /// No clicks yet on `space`, with discs of `radius` and `photo` to
    /// follow the edges of (when given at the space's size).
    pub fn new(
        space: &'a dyn ClickSpace,
        photo: Option<&'a RgbImage>,
        radius: f32,
    ) -> Result<Self, SelectError> {
        Self::with_prep(space, photo, radius, Arc::default())
    }

    /// As [`Selector::new`], sharing `prep`, the preparation of this same
    /// photo and space by earlier selections.
    pub fn with_prep(
        space: &'a dyn ClickSpace,
        photo: Option<&'a RgbImage>,
        radius: f32,
        prep: Arc<PhotoPrep>,
    ) -> Result<Self, SelectError> {
        check_radius(radius)?;
        let photo = photo.filter(|p| fits(p, space));
        Ok(Self {
            space,
            photo,
            radius,
            queries: Vec::new(),
            prep,
        })
    }

    /// Adds `click`.
    pub fn add(&mut self, click: Click) -> Result<(), SelectError> {
        let (width, height) = self.space.photo_size();
        if !(0.0..width as f32).contains(&click.x) || !(0.0..height as f32).contains(&click.y) {
            return Err(SelectError::Outside {
                x: click.x,
                y: click.y,
                width,
                height,
            });
        }
        let at = (click.x, click.y);
        let descriptor = self.space.descriptor_at(click.x, click.y, self.radius);
        let colour = self.photo.map(|photo| {
            let bins = &self.prep.guides(photo).1;
            disc_features(bins, self.space.photo_size(), at, self.radius)
        });
        self.push(descriptor, colour, click.positive, Some(at))
    }

    /// Adds a descriptor wanted (`positive`) or not, with its colour
    /// features when known: a click made on another photo of the same
    /// model.
    pub fn add_descriptor(
        &mut self,
        descriptor: Vec<f32>,
        colour: Option<Vec<f32>>,
        positive: bool,
    ) -> Result<(), SelectError> {
        self.push(descriptor, colour, positive, None)
    }

    /// Adds a query clicked `at` (or not clicked on this photo).
    fn push(
        &mut self,
        descriptor: Vec<f32>,
        colour: Option<Vec<f32>>,
        positive: bool,
        at: Option<(f32, f32)>,
    ) -> Result<(), SelectError> {
        if self.queries.len() >= MAX_CLICKS {
            return Err(SelectError::TooMany(self.queries.len() + 1));
        }
        let similarities = self.space.similarities_to(&descriptor);
        let near = at.map(|at| self.lowered(&similarities, at));
        self.queries.push(Query {
            positive,
            descriptor,
            similarities,
            near,
            colour: colour.filter(|c| c.len() == FEATURES),
        });
        Ok(())
    }

    /// `similarities` lowered with each cell's distance from `(x, y)`:
    /// [`REACH`] at the photo's longer side away.
    fn lowered(&self, similarities: &[f32], (x, y): (f32, f32)) -> Vec<f32> {
        let (w, h) = self.space.photo_size();
        let scale = REACH / w.max(h).max(1) as f32;
        (0..similarities.len())
            .into_par_iter()
            .map(|cell| {
                let (cx, cy) = self.space.cell_centre(cell);
                similarities[cell] - scale * ((cx - x).powi(2) + (cy - y).powi(2)).sqrt()
            })
            .collect()
    }

    /// The clicks' descriptors (and colours, when every click has them),
    /// to apply the selection to other photos.
    pub fn saved(&self, model: &str) -> SavedSelection {
        let of = |positive: bool| -> Vec<&Query> {
            self.queries
                .iter()
                .filter(|q| q.positive == positive)
                .collect()
        };
        let descriptors =
            |queries: &[&Query]| queries.iter().map(|q| q.descriptor.clone()).collect();
        let coloured = self.queries.iter().all(|q| q.colour.is_some());
        let colours = |queries: &[&Query]| match coloured {
            true => queries.iter().filter_map(|q| q.colour.clone()).collect(),
            false => Vec::new(),
        };
        let (positive, negative) = (of(true), of(false));
        SavedSelection {
            model: model.to_string(),
            radius: self.radius,
            positive: descriptors(&positive),
            negative: descriptors(&negative),
            positive_colours: colours(&positive),
            negative_colours: colours(&negative),
        }
    }

    /// The best similarity of every cell to the clicks of one kind.
    fn best(&self, positive: bool) -> Option<Vec<f32>> {
        self.queries
            .iter()
            .filter(|q| q.positive == positive)
            .fold(None, |best, q| Some(raised(best, &q.similarities)))
    }

    /// The best similarity of every cell to the clicks of one kind, each
    /// click but the first positive one (query `first`) lowered with the
    /// distance from where it was clicked ([`Selector::lowered`]) and
    /// reaching only the cells at least `level` like it (none elsewhere):
    /// a correcting click takes its own neighbourhood more readily than
    /// the far side of the photo, and only what is its own material, not
    /// whatever is somewhat like it.
    fn reach(&self, positive: bool, first: usize, level: f32) -> Option<Vec<f32>> {
        let mut best: Option<Vec<f32>> = None;
        for (k, query) in self.queries.iter().enumerate() {
            if query.positive != positive {
                continue;
            }
            if k == first {
                best = Some(raised(best, &query.similarities));
                continue;
            }
            let near = query.near.as_ref().unwrap_or(&query.similarities);
            let best = best.get_or_insert_with(|| vec![f32::NEG_INFINITY; near.len()]);
            for (b, &n) in best.iter_mut().zip(near) {
                if n >= level {
                    *b = b.max(n);
                }
            }
        }
        best
    }

    /// The decision, at the photo's size, of a linear classifier fitted
    /// on `prior` (each cell's decision by similarity, weight 1 a cell)
    /// and on the clicks ([`CLICK_SHARE`] of the photo each positive one,
    /// [`NEGATIVE_CLICK_SHARE`] each negative one): where the
    /// clicks and the similarities disagree, it finds the direction that
    /// tells the clicked materials apart. Its columns are the descriptors
    /// and, when every click has its colour, the colour features, which
    /// then decide each pixel by its own colour.
    fn fitted(&self, prior: &[f32]) -> Vec<f32> {
        let (cells, rows) = self.space.fit_rows();
        let dim = rows.len() / cells.len().max(1);
        let descriptors = Columns {
            values: &rows,
            width: dim,
        };
        let targets: Vec<f32> = cells.iter().map(|&c| prior[c] - 0.5).collect();
        let coloured = self.queries.iter().all(|q| q.colour.is_some());
        let bins = self
            .photo
            .filter(|_| coloured)
            .map(|photo| &self.prep.guides(photo).1);
        // Each click's row: its descriptor, then its colour's features.
        let values: Vec<Cow<'_, [f32]>> = self
            .queries
            .iter()
            .map(|q| match (bins, &q.colour) {
                (Some(_), Some(colour)) => Cow::Owned([&q.descriptor[..], colour].concat()),
                _ => Cow::Borrowed(&q.descriptor[..]),
            })
            .collect();
        // The clicks weigh as shares of the photo, whatever its size and
        // however finely it is described.
        let clicks: Vec<WeightedRow<'_>> = values
            .iter()
            .zip(&self.queries)
            .map(|(values, q)| WeightedRow {
                values,
                weight: match q.positive {
                    true => CLICK_SHARE,
                    false => NEGATIVE_CLICK_SHARE,
                } * cells.len() as f64,
                target: if q.positive { 0.5 } else { -0.5 },
            })
            .collect();
        match bins {
            Some(bins) => {
                let blocks = [descriptors, self.prep.colour_rows(self.space, bins, &cells)];
                let weights = self
                    .prep
                    .colour_ridge(&blocks)
                    .fit(&blocks, &targets, &clicks);
                let by_colour = bin_scores(&weights[dim..dim + FEATURES]);
                let by_cell = self
                    .space
                    .to_photo(self.space.project(&weights[..dim], weights[dim + FEATURES]));
                by_cell
                    .par_iter()
                    .zip(bins.bins())
                    .map(|(&s, &bin)| step(s + by_colour[bin as usize]))
                    .collect()
            }
            None => {
                let blocks = [descriptors];
                let weights = self.prep.ridge(&blocks).fit(&blocks, &targets, &clicks);
                let decision = self
                    .space
                    .project(&weights[..dim], weights[dim])
                    .into_iter()
                    .map(step)
                    .collect();
                self.space.to_photo(decision)
            }
        }
    }

    /// The selection the clicks make.
    pub fn selection(&self) -> Result<Selection, SelectError> {
        let (width, height) = self.space.photo_size();
        let positive = self.best(true).ok_or(SelectError::NoPositive)?;
        let negative = self.best(false);
        // The first positive click's map sets how similar is enough, so
        // that later clicks move the selection where they are, not its
        // threshold everywhere.
        let first = self
            .queries
            .iter()
            .position(|q| q.positive)
            .ok_or(SelectError::NoPositive)?;
        let threshold = otsu_threshold(&self.queries[first].similarities);
        let level = threshold.max(CORRECTION_LEVEL);
        let near_positive = self
            .reach(true, first, level)
            .ok_or(SelectError::NoPositive)?;
        let near_negative = self.reach(false, first, level);
        // The photo's materials unlike the positive clicks count, for the
        // decision, as negative clicks the user did not have to make.
        let mut against = near_negative;
        for (cell, map) in self.prep.prototypes(self.space) {
            if near_positive[*cell] < threshold {
                against = Some(raised(against, map));
            }
        }
        let soft: Vec<f32> = match &negative {
            None => positive.clone(),
            Some(negative) => positive
                .iter()
                .zip(negative)
                .map(|(&p, &n)| {
                    let away = 1.0 / (1.0 + ((n - p) / NEGATIVE_TEMPERATURE).exp());
                    p * away
                })
                .collect(),
        };
        let prior: Vec<f32> = (0..near_positive.len())
            .map(|i| {
                let p = near_positive[i];
                let beaten = against.as_ref().is_some_and(|n| n[i] >= p);
                if p >= threshold && !beaten {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        let decision = if self.queries.len() > 1 {
            self.fitted(&prior)
        } else {
            self.space.to_photo(prior)
        };
        let soft = self.space.to_photo(soft);
        let guides = self.photo.map(|p| self.prep.guides(p));
        let mask = match guides {
            Some((edges, colours)) => {
                let mut strength = edges.refine(&decision);
                strength.par_iter_mut().for_each(|d| *d = d.clamp(0.0, 1.0));
                colours.decide(&strength)
            }
            None => decision.iter().map(|&d| d >= 0.5).collect(),
        };
        Ok(Selection {
            width,
            height,
            soft,
            mask,
        })
    }
}

/// A selection saved to be applied to other photos: the descriptors of
/// its positive and negative clicks, and the model that made them (the
/// descriptors mean nothing to another model). `selection.json` holds it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SavedSelection {
    /// The model's name (`default`, a run folder, a weights file).
    pub model: String,
    /// The radius of the clicks' discs, in pixels of the clicked photo.
    pub radius: f32,
    /// The descriptors of the material wanted.
    pub positive: Vec<Vec<f32>>,
    /// The descriptors of the materials excluded.
    pub negative: Vec<Vec<f32>>,
    /// The colour features of each positive click (none when a click had
    /// none; older selections have none): the classifier's colour columns.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub positive_colours: Vec<Vec<f32>>,
    /// The colour features of each negative click, as `positive_colours`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub negative_colours: Vec<Vec<f32>>,
}

impl SavedSelection {
    /// Checks that the selection can be applied with descriptors of `dim`
    /// values: a positive descriptor at least, at most [`MAX_CLICKS`] in
    /// all, each of `dim` finite values.
    pub fn check(&self, dim: usize) -> Result<(), SelectError> {
        self.validate()?;
        check_values("positive", &self.positive, dim)?;
        check_values("negative", &self.negative, dim)?;
        for (kind, list) in [
            ("positive colours", &self.positive_colours),
            ("negative colours", &self.negative_colours),
        ] {
            check_values(kind, list, FEATURES)?;
        }
        Ok(())
    }

    /// Checks what needs no model: a positive descriptor at least, at most
    /// [`MAX_CLICKS`] in all, a radius in range, every value finite, every
    /// descriptor with a direction (a finite, non-zero length), colour
    /// features one per click (or none) within the range colours give, and
    /// no positive click equal to a negative one (descriptor and colour).
    pub fn validate(&self) -> Result<(), SelectError> {
        if self.positive.is_empty() {
            return Err(SelectError::NoPositive);
        }
        check_radius(self.radius)?;
        let count = self.positive.len() + self.negative.len();
        if count > MAX_CLICKS {
            return Err(SelectError::TooMany(count));
        }
        let colours = [&self.positive_colours, &self.negative_colours];
        if colours.iter().any(|c| !c.is_empty()) {
            for (kind, list, descriptors) in [
                ("positive colours", colours[0], &self.positive),
                ("negative colours", colours[1], &self.negative),
            ] {
                if list.len() != descriptors.len() {
                    return Err(SelectError::Colours {
                        kind,
                        count: list.len(),
                        clicks: descriptors.len(),
                    });
                }
                check_colour_range(kind, list)?;
            }
        }
        for (kind, list) in [("positive", &self.positive), ("negative", &self.negative)] {
            check_direction(kind, list)?;
        }
        // The same click, descriptor and colour, both wanted and not.
        let click = |list: &[Vec<f32>], colours: &[Vec<f32>], k: usize| {
            (list[k].clone(), colours.get(k).cloned())
        };
        for positive in 0..self.positive.len() {
            let wanted = click(&self.positive, &self.positive_colours, positive);
            if let Some(negative) = (0..self.negative.len())
                .find(|&n| click(&self.negative, &self.negative_colours, n) == wanted)
            {
                return Err(SelectError::Contradictory { positive, negative });
            }
        }
        Ok(())
    }

    /// The selection applied to the photo `space` describes (`photo` to
    /// follow the edges of), the descriptors checked first.
    pub fn apply(
        &self,
        space: &dyn ClickSpace,
        photo: Option<&RgbImage>,
        dim: usize,
    ) -> Result<Selection, SelectError> {
        self.check(dim)?;
        let mut selector = Selector::new(space, photo, self.radius)?;
        for (list, colours, positive) in [
            (&self.positive, &self.positive_colours, true),
            (&self.negative, &self.negative_colours, false),
        ] {
            for (k, d) in list.iter().enumerate() {
                selector.add_descriptor(d.clone(), colours.get(k).cloned(), positive)?;
            }
        }
        selector.selection()
    }
}

/// Checks that each of `list` (the `kind` of a saved selection) has only
/// finite values and a finite, non-zero length.
fn check_direction(kind: &'static str, list: &[Vec<f32>]) -> Result<(), SelectError> {
    for (index, d) in list.iter().enumerate() {
        if d.iter().any(|v| !v.is_finite()) {
            return Err(SelectError::NotFinite { kind, index });
        }
        let length = d.iter().map(|v| v * v).sum::<f32>().sqrt();
        if !length.is_finite() || length == 0.0 {
            return Err(SelectError::NoDirection {
                kind,
                index,
                length,
            });
        }
    }
    Ok(())
}

/// Checks that each of `list` (the `kind` of a saved selection's colour
/// features) has only finite values within the features' range.
fn check_colour_range(kind: &'static str, list: &[Vec<f32>]) -> Result<(), SelectError> {
    let bound = crate::colour_features::largest_feature();
    for (index, d) in list.iter().enumerate() {
        if d.iter().any(|v| !v.is_finite()) {
            return Err(SelectError::NotFinite { kind, index });
        }
        if d.iter().any(|v| v.abs() > bound * 1.001) {
            return Err(SelectError::ColourRange { kind, index, bound });
        }
    }
    Ok(())
}

/// Checks that each of `list` (the `kind` of a saved selection) holds
/// `dim` finite values.
fn check_values(kind: &'static str, list: &[Vec<f32>], dim: usize) -> Result<(), SelectError> {
    for (index, d) in list.iter().enumerate() {
        if d.len() != dim {
            return Err(SelectError::WrongLength {
                kind,
                index,
                len: d.len(),
                dim,
            });
        }
        if d.iter().any(|v| !v.is_finite()) {
            return Err(SelectError::NotFinite { kind, index });
        }
    }
    Ok(())
}

/// Otsu's threshold of `values`: the value that best splits them into two
/// groups (most variance between the groups), over 256 bins of their
/// range.
pub fn otsu_threshold(values: &[f32]) -> f32 {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return lo;
    }
    const BINS: usize = 256;
    let mut counts = [0u64; BINS];
    let bin = |v: f32| (((v - lo) / (hi - lo)) * (BINS - 1) as f32).round() as usize;
    for &v in values.iter().filter(|v| v.is_finite()) {
        counts[bin(v).min(BINS - 1)] += 1;
    }
    let total: u64 = counts.iter().sum();
    let sum_all: f64 = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * c as f64)
        .sum();
    let (mut below, mut sum_below) = (0u64, 0f64);
    let (mut best, mut best_between) = (0usize, -1f64);
    for (i, &c) in counts.iter().enumerate() {
        below += c;
        sum_below += i as f64 * c as f64;
        let above = total - below;
        if below == 0 || above == 0 {
            continue;
        }
        let mean_below = sum_below / below as f64;
        let mean_above = (sum_all - sum_below) / above as f64;
        let between = below as f64 * above as f64 * (mean_below - mean_above).powi(2);
        if between > best_between {
            best_between = between;
            best = i;
        }
    }
    // The threshold lies between bin `best` (below) and the next.
    lo + (best as f32 + 0.5) / (BINS - 1) as f32 * (hi - lo)
}

/// The guided filter's window radius, in photo pixels.
const GUIDE_RADIUS: usize = 4;

/// The guided filter's regularisation (on colours in 0..1): edges weaker
/// than about this variance are smoothed over.
const GUIDE_EPSILON: f32 = 0.01;

#[cfg(test)]
mod tests {
    use super::*;

    /// A 40 x 20 map whose left half is one material and right half
    /// another (2-d unit descriptors), as a pixel space.
    fn halves() -> DescriptorMap {
        let (w, h) = (40, 20);
        let data = (0..w * h)
            .flat_map(|i| {
                if i % w < w / 2 {
                    [1.0, 0.0]
                } else {
                    [0.6, 0.8]
                }
            })
            .collect();
        DescriptorMap {
            width: w,
            height: h,
            dim: 2,
            data,
        }
    }

    #[test]
    fn one_click_gives_the_similarity_map_and_its_own_mask() {
        let map = halves();
        let space = PixelSpace::new(&map, Comparison::Cosine);
        let selection = select(&space, None, &[Click::positive(5.0, 5.0)], 0.0).unwrap();
        let query = map.point_descriptor(5.0, 5.0, 0.0, Comparison::Cosine);
        assert_eq!(
            selection.soft,
            map.similarity_map(&query, Comparison::Cosine)
        );
        assert!((0..map.width * map.height).all(|i| selection.mask[i] == (i % 40 < 20)));
        assert!((selection.area() - 0.5).abs() < 1e-9);
    }

    #[test]
    fn a_negative_click_never_enlarges_the_selection_at_its_own_pixel() {
        let map = halves();
        let space = PixelSpace::new(&map, Comparison::Cosine);
        let both = select(
            &space,
            None,
            &[Click::positive(5.0, 5.0), Click::positive(30.0, 5.0)],
            0.0,
        )
        .unwrap();
        assert!(both.mask.iter().all(|&m| m), "both materials");
        let not_right = select(
            &space,
            None,
            &[
                Click::positive(5.0, 5.0),
                Click::positive(30.0, 5.0),
                Click::negative(30.0, 10.0),
            ],
            0.0,
        )
        .unwrap();
        let at = 10 * 40 + 30;
        assert!(!not_right.mask[at]);
        assert!(not_right.soft[at] <= both.soft[at] * 0.5 + 1e-6);
        assert!(not_right.mask[5 * 40 + 5]);
    }

    #[test]
    fn bad_clicks_are_refused() {
        let map = halves();
        let space = PixelSpace::new(&map, Comparison::Cosine);
        let refused =
            |clicks: &[Click], radius: f32| select(&space, None, clicks, radius).unwrap_err();
        assert_eq!(
            refused(&[Click::negative(1.0, 1.0)], 5.0),
            SelectError::NoPositive
        );
        assert_eq!(refused(&[], 5.0), SelectError::NoPositive);
        assert!(matches!(
            refused(&[Click::positive(40.0, 1.0)], 5.0),
            SelectError::Outside { .. }
        ));
        assert!(matches!(
            refused(&[Click::positive(1.0, 1.0)], -1.0),
            SelectError::Radius(_)
        ));
        let many = vec![Click::positive(1.0, 1.0); MAX_CLICKS + 1];
        assert_eq!(refused(&many, 5.0), SelectError::TooMany(MAX_CLICKS + 1));
    }

    #[test]
    fn saved_selections_without_a_direction_or_contradicting_themselves_are_refused() {
        let saved = SavedSelection {
            model: "m".into(),
            radius: 5.0,
            positive: vec![vec![0.6, 0.8]],
            negative: vec![vec![1.0, 0.0]],
            positive_colours: Vec::new(),
            negative_colours: Vec::new(),
        };
        assert_eq!(saved.check(2), Ok(()));
        let with = |f: &dyn Fn(&mut SavedSelection)| {
            let mut s = saved.clone();
            f(&mut s);
            s.validate().unwrap_err()
        };
        assert!(matches!(
            with(&|s| s.positive[0] = vec![0.0, 0.0]),
            SelectError::NoDirection {
                kind: "positive",
                ..
            }
        ));
        for huge in [1e30, 3e38] {
            assert!(matches!(
                with(&|s| s.negative[0] = vec![huge, 1.0]),
                SelectError::NoDirection {
                    kind: "negative",
                    ..
                }
            ));
        }
        assert!(matches!(
            with(&|s| s.positive[0][1] = f32::NAN),
            SelectError::NotFinite { .. }
        ));
        assert!(matches!(
            with(&|s| s.negative = s.positive.clone()),
            SelectError::Contradictory {
                positive: 0,
                negative: 0
            }
        ));
        assert!(matches!(with(&|s| s.radius = -1.0), SelectError::Radius(_)));
        let colours = vec![vec![0.01; FEATURES]];
        assert!(matches!(
            with(&|s| {
                s.positive_colours = vec![vec![1e30; FEATURES]];
                s.negative_colours = colours.clone();
            }),
            SelectError::ColourRange {
                kind: "positive colours",
                ..
            }
        ));
        // The same descriptor of another colour is another click.
        let mut two_colours = saved.clone();
        two_colours.negative = two_colours.positive.clone();
        two_colours.positive_colours = vec![vec![0.02; FEATURES]];
        two_colours.negative_colours = colours;
        assert_eq!(two_colours.validate(), Ok(()));
    }

    #[test]
    fn the_colours_tell_apart_what_the_descriptors_do_not() {
        // The map's two halves; the photo red up to column 25 and blue
        // beyond, so the right half's material is red on its first five
        // columns. Clicked: the left half, a red pixel of the right half,
        // not a blue one.
        let map = halves();
        let (w, h) = (map.width, map.height);
        let photo = RgbImage::from_fn(w as u32, h as u32, |x, _| {
            image::Rgb(if x < 25 { [200, 40, 30] } else { [30, 60, 200] })
        });
        let space = PixelSpace::new(&map, Comparison::Cosine);
        let clicks = [
            Click::positive(5.5, 5.5),
            Click::negative(35.5, 5.5),
            Click::positive(22.5, 5.5),
        ];
        let with_colours = select(&space, Some(&photo), &clicks, 0.0).unwrap();
        for y in 0..h {
            assert!(with_colours.mask[y * w + 3], "the left half stays in");
            assert!(with_colours.mask[y * w + 22], "red of the right half in");
            assert!(!with_colours.mask[y * w + 35], "blue goes out");
        }
        // Without the photo, the descriptors alone cannot split the right
        // half.
        let without = select(&space, None, &clicks, 0.0).unwrap();
        assert_eq!(without.mask[5 * w + 22], without.mask[5 * w + 35]);
        // Saved, the clicks keep their colours through JSON, and a saved
        // selection applied uses them.
        let mut selector = Selector::new(&space, Some(&photo), 0.0).unwrap();
        for &click in &clicks {
            selector.add(click).unwrap();
        }
        let saved = selector.saved("test");
        assert_eq!(saved.positive_colours.len(), 2);
        assert_eq!(saved.negative_colours[0].len(), FEATURES);
        let json = serde_json::to_string(&saved).unwrap();
        assert_eq!(
            serde_json::from_str::<SavedSelection>(&json).unwrap(),
            saved
        );
        let plain = SavedSelection {
            positive_colours: Vec::new(),
            negative_colours: Vec::new(),
            ..saved.clone()
        };
        let old_json = serde_json::to_string(&plain).unwrap();
        assert!(!old_json.contains("colours"), "{old_json}");
        assert_eq!(
            serde_json::from_str::<SavedSelection>(&old_json).unwrap(),
            plain
        );
        let mut by_hand = Selector::new(&space, Some(&photo), 0.0).unwrap();
        for (k, d) in saved.positive.iter().enumerate() {
            by_hand
                .add_descriptor(d.clone(), Some(saved.positive_colours[k].clone()), true)
                .unwrap();
        }
        by_hand
            .add_descriptor(
                saved.negative[0].clone(),
                Some(saved.negative_colours[0].clone()),
                false,
            )
            .unwrap();
        assert_eq!(
            saved.apply(&space, Some(&photo), 2).unwrap().mask,
            by_hand.selection().unwrap().mask
        );
        // Colours not one a click are refused.
        let short = SavedSelection {
            negative_colours: Vec::new(),
            ..saved
        };
        assert!(matches!(
            short.check(2),
            Err(SelectError::Colours {
                count: 0,
                clicks: 1,
                ..
            })
        ));
    }

    #[test]
    fn otsu_splits_two_modes_between_them() {
        let values: Vec<f32> = (0..100).map(|i| if i < 60 { 0.1 } else { 0.9 }).collect();
        let t = otsu_threshold(&values);
        assert!(t > 0.1 && t < 0.9, "{t}");
        assert_eq!(otsu_threshold(&[0.5; 10]), 0.5);
    }

    /// The third material of [`bands`] far from the others: as near to A
    /// as to B, and little like either (cosine 0.3).
    const APART: [f32; 4] = [0.3015, 0.3015, 0.9045, 0.0];

    /// The third material of [`bands`] somewhat like B (cosine 0.75) and
    /// hardly like A: the target of a correcting click on B.
    const NEAR_B: [f32; 4] = [0.05, 0.75, 0.66, 0.0];

    /// A 64 x 16 map of four materials in vertical bands 16 pixels wide
    /// (4-d descriptors, each pixel a little off its material's own): A,
    /// a background D, B, and `third`; and a photo of one colour a
    /// material.
    fn bands(third: [f32; 4]) -> (DescriptorMap, RgbImage) {
        let (w, h) = (64, 16);
        let centres = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 0.0],
            third,
        ];
        let data = (0..w * h)
            .flat_map(|i| {
                let centre = centres[(i % w) / 16];
                let wobble = 0.05 * (i as f32 * 0.7).sin();
                let v = [centre[0] + wobble, centre[1], centre[2] - wobble, centre[3]];
                let norm = v.iter().map(|a| a * a).sum::<f32>().sqrt();
                v.map(|a| a / norm)
            })
            .collect();
        let colours = [[200, 40, 40], [90, 70, 50], [40, 160, 60], [60, 60, 200]];
        let photo = RgbImage::from_fn(w as u32, h as u32, |x, _| {
            image::Rgb(colours[x as usize / 16])
        });
        (
            DescriptorMap {
                width: w,
                height: h,
                dim: 4,
                data,
            },
            photo,
        )
    }

    /// The pixels of band `band` of [`bands`].
    fn band(band: usize) -> impl Fn(usize) -> bool {
        move |i| (i % 64) / 16 == band
    }

    #[test]
    fn a_second_positive_material_never_takes_what_lies_nearer_a_third() {
        let (map, photo) = bands(NEAR_B);
        let space = PixelSpace::new(&map, Comparison::Cosine);
        let (a, b) = (Click::positive(8.0, 8.0), Click::positive(40.0, 8.0));
        let near = |x: f32| {
            map.similarity_map(
                &map.point_descriptor(x, 8.0, 0.0, Comparison::Cosine),
                Comparison::Cosine,
            )
        };
        let (to_a, to_b, to_c) = (near(8.0), near(40.0), near(56.0));
        for photo in [None, Some(&photo)] {
            let selection = select(&space, photo, &[a, b], 0.0).unwrap();
            for i in 0..map.width * map.height {
                if selection.mask[i] {
                    assert!(to_a[i].max(to_b[i]) >= to_c[i], "pixel {i} is nearer C");
                }
                assert_eq!(selection.mask[i], band(0)(i) || band(2)(i), "pixel {i}");
            }
        }
    }

    #[test]
    fn a_negative_click_never_adds_a_pixel() {
        for third in [APART, NEAR_B] {
            let (map, photo) = bands(third);
            let space = PixelSpace::new(&map, Comparison::Cosine);
            let starts = [
                vec![Click::positive(8.0, 8.0)],
                vec![Click::positive(8.0, 8.0), Click::positive(40.0, 8.0)],
                vec![Click::positive(15.0, 8.0), Click::positive(56.0, 3.0)],
            ];
            for photo in [None, Some(&photo)] {
                for start in &starts {
                    let before = select(&space, photo, start, 0.0).unwrap();
                    for x in [2.0, 14.0, 17.0, 30.0, 47.0, 60.0] {
                        let mut clicks = start.clone();
                        clicks.push(Click::negative(x, 8.0));
                        let after = select(&space, photo, &clicks, 0.0).unwrap();
                        let added = (0..after.mask.len())
                            .filter(|&i| after.mask[i] && !before.mask[i])
                            .count();
                        assert_eq!(added, 0, "{start:?} then a negative click at {x}");
                    }
                }
            }
        }
    }

    #[test]
    fn two_materials_apart_are_selected_as_the_union_of_their_own_selections() {
        let (map, photo) = bands(APART);
        let space = PixelSpace::new(&map, Comparison::Cosine);
        let (a, b) = (Click::positive(8.0, 8.0), Click::positive(40.0, 8.0));
        for photo in [None, Some(&photo)] {
            let one = |clicks: &[Click]| select(&space, photo, clicks, 0.0).unwrap().mask;
            let (only_a, only_b, both) = (one(&[a]), one(&[b]), one(&[a, b]));
            let union: Vec<bool> = only_a.iter().zip(&only_b).map(|(&x, &y)| x || y).collect();
            assert_eq!(both, union);
            assert_eq!(only_a.iter().filter(|&&m| m).count(), 16 * 16);
        }
    }
}
