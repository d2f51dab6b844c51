//! The selection the click protocol scores, grown click by click, for each
//! kind of model ([`ClickAnswer`]): matseg's own selection on a model's
//! descriptors; matseg's composition of a model's similarity maps, one per
//! click; or the model's own selection.
//!
//! Similarity maps are composed so that their scale does not matter (a
//! cosine, a probability, a logit): each click's map is stretched to 0..1
//! over the photo; a positive click takes the pixels at or above its map's
//! Otsu threshold, a negative click those at or above its own; a pixel is
//! selected when a positive click takes it and no negative click that
//! takes it is at least as similar to it as the positive clicks are.

use crate::model::{descriptors_of, ClickAnswer, Question, ScoredModel};
use crate::points::BenchError;
use matseg_query::descriptor::{Comparison, DescriptorMap};
use matseg_query::select::{otsu_threshold, Click, PixelSpace, SelectError, Selection, Selector};

/// How much softer than a positive click's a pixel's strength becomes as a
/// negative click's stretched similarity passes it: half where they are
/// equal, a quarter this much further.
const NEGATIVE_TEMPERATURE: f32 = 0.1;

/// A selection the clicks on one photo grow, whoever decides it.
pub trait ClickSelection {
    /// Adds `click` (in the photo's pixels).
    fn add(&mut self, click: Click) -> Result<(), BenchError>;

    /// The selection the clicks so far make.
    fn selection(&mut self) -> Result<Selection, BenchError>;
}

/// A photo the click protocol clicks on, with what its model answered
/// once for the whole photo (its descriptors, when it answers with them).
pub struct ClickedPhoto<'a> {
    model: &'a dyn ScoredModel,
    question: Question<'a>,
    described: Option<(DescriptorMap, Comparison)>,
}

impl<'a> ClickedPhoto<'a> {
    /// The photo `pixels` (benchmark photo `name`, from the file `path`)
    /// for `model`, described now when the model answers clicks with
    /// descriptors.
    pub fn ask(
        model: &'a dyn ScoredModel,
        name: &'a str,
        path: &'a std::path::Path,
        pixels: &'a image::RgbImage,
    ) -> Result<Self, BenchError> {
        let question = Question {
            name,
            path,
            pixels,
            points: &[],
        };
        let described = match model.click_answer() {
            ClickAnswer::Descriptors => Some(descriptors_of(
                model.answer(&question)?,
                &question,
                "the click protocol",
            )?),
            ClickAnswer::SimilarityMaps | ClickAnswer::Selection => None,
        };
        Ok(Self {
            model,
            question,
            described,
        })
    }

    /// The space matseg's own selection works in, for a model that
    /// answers with descriptors.
    pub fn space(&self) -> Option<PixelSpace<'_>> {
        self.described
            .as_ref()
            .map(|(map, comparison)| PixelSpace::new(map, *comparison))
    }

    /// A selection with no clicks yet (discs of `radius` pixels); `space`
    /// is [`ClickedPhoto::space`].
    pub fn start<'s>(
        &'s self,
        space: Option<&'s PixelSpace<'s>>,
        radius: f32,
    ) -> Result<Box<dyn ClickSelection + 's>, BenchError> {
        Ok(match (self.model.click_answer(), space) {
            (ClickAnswer::Descriptors, Some(space)) => Box::new(DescribedSelection(
                Selector::new(space, Some(self.question.pixels), radius).map_err(select_error)?,
            )),
            (ClickAnswer::Descriptors, None) => {
                return Err(BenchError::new(
                    self.question.path,
                    None,
                    "the photo's descriptors were not asked for",
                ))
            }
            (ClickAnswer::SimilarityMaps, _) => Box::new(ComposedSelection {
                photo: self,
                clicks: Vec::new(),
                maps: Vec::new(),
            }),
            (ClickAnswer::Selection, _) => Box::new(ModelSelection {
                photo: self,
                clicks: Vec::new(),
            }),
        })
    }

    /// The photo's width and height.
    fn size(&self) -> (usize, usize) {
        let (w, h) = self.question.pixels.dimensions();
        (w as usize, h as usize)
    }
}

/// A click selection's error, named as the click protocol's.
pub fn select_error(e: SelectError) -> BenchError {
    BenchError::new(std::path::Path::new("clicks"), None, e.to_string())
}

/// matseg's own selection on a model's descriptors.
struct DescribedSelection<'a>(Selector<'a>);

impl ClickSelection for DescribedSelection<'_> {
    fn add(&mut self, click: Click) -> Result<(), BenchError> {
        self.0.add(click).map_err(select_error)
    }

    fn selection(&mut self) -> Result<Selection, BenchError> {
        self.0.selection().map_err(select_error)
    }
}

/// A model's similarity maps, one asked for each click, composed by
/// matseg (the module's doc).
struct ComposedSelection<'a> {
    photo: &'a ClickedPhoto<'a>,
    clicks: Vec<Click>,
    /// Each click's map, stretched to 0..1, with its Otsu threshold.
    maps: Vec<(Vec<f32>, f32)>,
}

impl ClickSelection for ComposedSelection<'_> {
    fn add(&mut self, click: Click) -> Result<(), BenchError> {
        let question = Question {
            points: &[(click.x, click.y)],
            ..self.photo.question
        };
        let mut maps = match self.photo.model.answer(&question)? {
            crate::model::Answer::Similarity { maps, .. } if maps.len() == 1 => maps,
            _ => {
                return Err(BenchError::new(
                    question.path,
                    None,
                    format!(
                        "photo {}: the click protocol asked {} for one similarity map",
                        question.name,
                        self.photo.model.name()
                    ),
                ))
            }
        };
        let map = stretched(maps.remove(0));
        let threshold = otsu_threshold(&map);
        self.maps.push((map, threshold));
        self.clicks.push(click);
        Ok(())
    }

    fn selection(&mut self) -> Result<Selection, BenchError> {
        let (width, height) = self.photo.size();
        let side = |positive: bool| -> Vec<(&[f32], f32)> {
            self.clicks
                .iter()
                .zip(&self.maps)
                .filter(|(c, _)| c.positive == positive)
                .map(|(_, (map, threshold))| (&map[..], *threshold))
                .collect()
        };
        let (positive, negative) = (side(true), side(false));
        if positive.is_empty() {
            return Err(select_error(SelectError::NoPositive));
        }
        // Per pixel: the highest similarity of one side's clicks, and
        // whether one of them takes it.
        let best = |side: &[(&[f32], f32)], i: usize| {
            side.iter()
                .fold((f32::NEG_INFINITY, false), |(best, taken), (map, t)| {
                    (best.max(map[i]), taken || map[i] >= *t)
                })
        };
        let (soft, mask) = (0..width * height)
            .map(|i| {
                let (p, wanted) = best(&positive, i);
                let (n, refused) = best(&negative, i);
                let soft = match negative.is_empty() {
                    true => p,
                    false => p / (1.0 + ((n - p) / NEGATIVE_TEMPERATURE).exp()),
                };
                (soft, wanted && !(refused && n >= p))
            })
            .unzip();
        Ok(Selection {
            width,
            height,
            soft,
            mask,
        })
    }
}

/// `map` stretched linearly to 0..1 over its lowest and highest values (all
/// 0 when it is flat).
fn stretched(mut map: Vec<f32>) -> Vec<f32> {
    let (low, high) = map
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let range = high - low;
    for v in &mut map {
        *v = if range > 0.0 { (*v - low) / range } else { 0.0 };
    }
    map
}

/// A model's own selection, asked again after each click.
struct ModelSelection<'a> {
    photo: &'a ClickedPhoto<'a>,
    clicks: Vec<Click>,
}

impl ClickSelection for ModelSelection<'_> {
    fn add(&mut self, click: Click) -> Result<(), BenchError> {
        self.clicks.push(click);
        Ok(())
    }

    fn selection(&mut self) -> Result<Selection, BenchError> {
        let (width, height) = self.photo.size();
        let question = &self.photo.question;
        let soft = self.photo.model.select(question, &self.clicks)?;
        let fail = |m: String| {
            BenchError::new(
                question.path,
                None,
                format!(
                    "photo {}: {}'s selection {m}",
                    question.name,
                    self.photo.model.name()
                ),
            )
        };
        if soft.len() != width * height {
            return Err(fail(format!(
                "has {} values; expected {height} x {width}",
                soft.len()
            )));
        }
        if let Some(v) = soft.iter().find(|v| !(0.0..=1.0).contains(*v)) {
            return Err(fail(format!(
                "has the value {v}: give a mask or soft map in 0..1"
            )));
        }
        let mask = soft.iter().map(|&v| v >= 0.5).collect();
        Ok(Selection {
            width,
            height,
            soft,
            mask,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Answer;

    /// Similarity falling linearly with the distance from the clicked
    /// column, on a scale of its own (0 to 10).
    struct Ramp;

    impl ScoredModel for Ramp {
        fn name(&self) -> &str {
            "ramp"
        }
        fn answer(&self, question: &Question) -> Result<Answer, BenchError> {
            let (w, h) = question.pixels.dimensions();
            let (w, h) = (w as usize, h as usize);
            let maps = question
                .points
                .iter()
                .map(|&(cx, _)| {
                    (0..w * h)
                        .map(|i| 10.0 - ((i % w) as f32 - cx).abs() / 4.0)
                        .collect()
                })
                .collect();
            Ok(Answer::Similarity {
                maps,
                width: w,
                height: h,
            })
        }
        fn click_answer(&self) -> ClickAnswer {
            ClickAnswer::SimilarityMaps
        }
    }

    #[test]
    fn a_negative_click_takes_back_what_is_nearer_to_it() {
        let pixels = image::RgbImage::new(40, 3);
        let photo = ClickedPhoto::ask(&Ramp, "p", std::path::Path::new("p.png"), &pixels).unwrap();
        assert!(photo.space().is_none());
        let mut selection = photo.start(None, 5.0).unwrap();
        assert!(selection.selection().is_err(), "no positive click yet");
        selection.add(Click::positive(2.0, 1.0)).unwrap();
        let alone = selection.selection().unwrap();
        selection.add(Click::negative(30.0, 1.0)).unwrap();
        let corrected = selection.selection().unwrap();
        let columns =
            |s: &Selection| -> Vec<usize> { (0..40).filter(|&x| s.mask[40 + x]).collect() };
        // Alone, the click takes the nearer part of the photo, the part
        // above its map's Otsu threshold.
        let taken = columns(&alone);
        assert_eq!(taken, (0..=19).collect::<Vec<_>>());
        // Stretched, the positive map is 1 - |x - 2| / 37 and the negative
        // one 1 - |x - 30| / 30: the negative click takes back the columns
        // where its map is at least as high (x >= 17.46), and softens the
        // rest the nearer they come.
        assert_eq!(columns(&corrected), (0..=17).collect::<Vec<_>>());
        assert!(corrected.soft[40 + 2] > 0.99);
        let factor = |x: usize| corrected.soft[40 + x] / alone.soft[40 + x];
        let (p, n) = (1.0 - 15.0 / 37.0, 1.0 - 13.0 / 30.0);
        assert!((factor(17) - 1.0 / (1.0 + ((n - p) / 0.1f32).exp())).abs() < 1e-5);
        assert!(factor(10) > factor(17));
    }

    #[test]
    fn a_map_is_stretched_to_its_range_and_a_flat_one_to_zero() {
        assert_eq!(stretched(vec![-1.0, 0.0, 3.0]), vec![0.0, 0.25, 1.0]);
        assert_eq!(stretched(vec![2.0, 2.0]), vec![0.0, 0.0]);
    }
}
