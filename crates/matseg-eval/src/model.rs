//! What a benchmark asks of a model and what the model answers, whoever
//! made it: matseg's own models describe a photo; models matseg did not
//! train answer from files or from Python, with descriptor maps or with one
//! similarity map per asked point.

use crate::points::BenchError;
use image::RgbImage;
use matseg_query::descriptor::{
    disc_pixels, resize_channels, Comparison, DescriptorMap, DescriptorModel, ResizedGrid,
};
use matseg_query::select::Click;
use std::borrow::Cow;
use std::ops::Deref;
use std::path::Path;

/// A query point's disc: centre `x`, `y` and radius, in scored pixels.
pub type Disc = (f32, f32, f32);

/// One benchmark photo as a protocol asks a model about it.
pub struct Question<'a> {
    /// The photo's name in its benchmark.
    pub name: &'a str,
    /// The photo's file.
    pub path: &'a Path,
    /// The photo at the protocol's size.
    pub pixels: &'a RgbImage,
    /// The points the protocol will query, `(x, y)` in `pixels`: what a
    /// model answering with similarity maps answers for, in order.
    pub points: &'a [(f32, f32)],
}

/// The values of a model's answer: its own, or held in memory the model
/// keeps (a numpy array the harness reads without copying).
pub enum Values {
    /// Values the harness owns.
    Owned(Vec<f32>),
    /// Values read where the model keeps them.
    Held(Box<dyn Deref<Target = [f32]> + Send + Sync>),
}

impl Deref for Values {
    type Target = [f32];

    fn deref(&self) -> &[f32] {
        match self {
            Values::Owned(values) => values,
            Values::Held(values) => values,
        }
    }
}

impl Values {
    /// The values as a vector (held ones copied).
    pub fn into_vec(self) -> Vec<f32> {
        match self {
            Values::Owned(values) => values,
            Values::Held(values) => values.to_vec(),
        }
    }
}

/// A model's answer about one photo.
pub enum Answer {
    /// A descriptor per pixel, compared as `comparison` says.
    Descriptors {
        /// The map, the photo's size.
        map: DescriptorMap,
        /// How its descriptors are pooled and compared.
        comparison: Comparison,
    },
    /// Descriptors on a grid of their own size over the photo, resized
    /// bilinearly to the photo where they are read.
    Grid {
        /// `width * height * dim` values, cell by cell.
        values: Values,
        /// The grid's width.
        width: usize,
        /// The grid's height.
        height: usize,
        /// Channels a cell.
        dim: usize,
        /// The photo's width and height.
        photo: (usize, usize),
        /// How its descriptors are pooled and compared.
        comparison: Comparison,
    },
    /// One similarity map per asked point (higher is more alike), each
    /// `width * height` values row by row.
    Similarity {
        /// The maps, in the order of the asked points.
        maps: Vec<Vec<f32>>,
        /// The photo's width.
        width: usize,
        /// The photo's height.
        height: usize,
    },
}

impl Answer {
    /// How like each disc `(x, y, r)` is each other, `[i][j]`: for
    /// descriptors, the comparison of the two discs' pooled descriptors;
    /// for similarity maps (one per disc, in order), the mean of disc `i`'s
    /// map over disc `j`.
    pub fn similarity_matrix(&self, discs: &[Disc]) -> Vec<Vec<f64>> {
        match self {
            Answer::Descriptors { map, comparison } => compared(discs, *comparison, |x, y, r| {
                map.point_descriptor(x, y, r, *comparison)
            }),
            Answer::Grid {
                values,
                width,
                height,
                dim,
                photo,
                comparison,
            } => {
                let grid = ResizedGrid::new(values, (*width, *height), *dim, *photo);
                compared(discs, *comparison, |x, y, r| {
                    grid.point_descriptor(x, y, r, *comparison)
                })
            }
            Answer::Similarity {
                maps,
                width,
                height,
            } => {
                let pixels: Vec<Vec<usize>> = discs
                    .iter()
                    .map(|&(x, y, r)| disc_pixels(*width, *height, x, y, r))
                    .collect();
                maps.iter()
                    .map(|map| {
                        pixels
                            .iter()
                            .map(|disc| {
                                disc.iter().map(|&p| map[p] as f64).sum::<f64>() / disc.len() as f64
                            })
                            .collect()
                    })
                    .collect()
            }
        }
    }

    /// The similarity map of asked point `i` (disc radius `r`), `width *
    /// height` values: computed from descriptors, or the model's own. A
    /// grid is resized for each call: ask [`Answer::at_photo_size`]'s
    /// answer for several maps.
    pub fn map_of(&self, i: usize, (x, y): (f32, f32), r: f32) -> Cow<'_, [f32]> {
        let similarity_to_point = |map: &DescriptorMap, comparison: Comparison| {
            let query = map.point_descriptor(x, y, r, comparison);
            Cow::Owned(map.similarity_map(&query, comparison))
        };
        match self {
            Answer::Descriptors { map, comparison } => similarity_to_point(map, *comparison),
            Answer::Grid {
                values,
                width,
                height,
                dim,
                photo,
                comparison,
            } => similarity_to_point(
                &photo_map(Cow::Borrowed(values), (*width, *height), *dim, *photo),
                *comparison,
            ),
            Answer::Similarity { maps, .. } => Cow::Borrowed(&maps[i]),
        }
    }

    /// The answer with its descriptors at the photo's size (a grid
    /// resized), for reading many maps of it.
    pub fn at_photo_size(self) -> Answer {
        match self {
            Answer::Grid {
                values,
                width,
                height,
                dim,
                photo,
                comparison,
            } => {
                // Owned values of the photo's size are kept, not copied.
                let map = match values {
                    Values::Owned(owned) => {
                        photo_map(Cow::Owned(owned), (width, height), dim, photo)
                    }
                    Values::Held(held) => {
                        photo_map(Cow::Borrowed(&held), (width, height), dim, photo)
                    }
                };
                Answer::Descriptors { map, comparison }
            }
            other => other,
        }
    }
}

/// How like each disc's descriptor (`pool(x, y, r)`) is each other's,
/// `[i][j]`, as `comparison` compares them.
fn compared(
    discs: &[Disc],
    comparison: Comparison,
    pool: impl Fn(f32, f32, f32) -> Vec<f32>,
) -> Vec<Vec<f64>> {
    let pooled: Vec<Vec<f32>> = discs.iter().map(|&(x, y, r)| pool(x, y, r)).collect();
    pooled
        .iter()
        .map(|a| pooled.iter().map(|b| comparison.similarity(a, b)).collect())
        .collect()
}

/// A `grid` of `dim` channels resized to the photo's size as
/// [`resize_channels`] resizes it.
fn photo_map(
    grid: Cow<'_, [f32]>,
    grid_size: (usize, usize),
    dim: usize,
    photo: (usize, usize),
) -> DescriptorMap {
    DescriptorMap {
        width: photo.0,
        height: photo.1,
        dim,
        data: resize_channels(grid, grid_size, dim, photo),
    }
}

/// What a model answers when the click protocol clicks on a photo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClickAnswer {
    /// Descriptors of the photo, asked once; matseg's own selection
    /// decides on them.
    Descriptors,
    /// A similarity map for each click, asked click by click; matseg
    /// composes them into a selection.
    SimilarityMaps,
    /// Its own selection for all the clicks so far, asked after each
    /// click ([`ScoredModel::select`]).
    Selection,
}

/// A model as the benchmarks score it.
pub trait ScoredModel: Sync {
    /// Its name in tables and JSON.
    fn name(&self) -> &str;

    /// Its answer about `question`'s photo, or the problem (naming the
    /// photo or the file at fault).
    fn answer(&self, question: &Question) -> Result<Answer, BenchError>;

    /// Whether photos may be asked about from several threads at once.
    fn parallel(&self) -> bool {
        true
    }

    /// What it answers in the click protocol.
    fn click_answer(&self) -> ClickAnswer {
        ClickAnswer::Descriptors
    }

    /// Its selection for `clicks` on `question`'s photo, `width * height`
    /// values in 0..=1, row by row (a pixel at 0.5 or more is selected),
    /// when it answers clicks with [`ClickAnswer::Selection`].
    fn select(&self, question: &Question, clicks: &[Click]) -> Result<Vec<f32>, BenchError> {
        let _ = clicks;
        Err(BenchError::new(
            question.path,
            None,
            format!("{} does not select from clicks", self.name()),
        ))
    }
}

/// A borrowed scored model, where an owned one (a box) is asked for.
impl<M: ScoredModel + ?Sized> ScoredModel for &M {
    fn name(&self) -> &str {
        (**self).name()
    }

    fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
        (**self).answer(question)
    }

    fn parallel(&self) -> bool {
        (**self).parallel()
    }

    fn click_answer(&self) -> ClickAnswer {
        (**self).click_answer()
    }

    fn select(&self, question: &Question, clicks: &[Click]) -> Result<Vec<f32>, BenchError> {
        (**self).select(question, clicks)
    }
}

/// A [`DescriptorModel`] (matseg's nets and baselines) as a scored model:
/// `Described(&model)`, `Described(boxed)`.
pub struct Described<D>(pub D);

impl<D> ScoredModel for Described<D>
where
    D: Deref + Sync,
    D::Target: DescriptorModel,
{
    fn name(&self) -> &str {
        self.0.name()
    }

    fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
        Ok(Answer::Descriptors {
            map: self.0.describe(question.pixels),
            comparison: self.0.comparison(),
        })
    }
}

/// The descriptor map of `answer`, or an error saying `protocol` needs one
/// (similarity maps answer only the points they were asked about).
pub fn descriptors_of(
    answer: Answer,
    question: &Question,
    protocol: &str,
) -> Result<(DescriptorMap, Comparison), BenchError> {
    match answer.at_photo_size() {
        Answer::Descriptors { map, comparison } => Ok((map, comparison)),
        Answer::Grid { .. } | Answer::Similarity { .. } => Err(BenchError::new(
            question.path,
            None,
            format!("{protocol} needs a model that describes photos; this one answered with similarity maps"),
        )),
    }
}
