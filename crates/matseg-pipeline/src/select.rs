//! Selections by clicks (pipeline.md §8.1): the materials a user clicked,
//! positive points grouped by material and negative clicks excluded from
//! all of them, each made into a selection (its soft map and its own
//! mask), written beside the similarity maps and saved as
//! `selection_K.json`; and a saved selection applied to a folder of other
//! photos, a mask each and the share of each photo it covers.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use crate::segment::{check_clicks, check_contradictions, describe, Model, MAX_POINTS};
use image::RgbImage;
use matseg_image::io::{encode_png_grey, read_rgb};
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::select::{Click, SavedSelection, Selection, Selector};
use std::path::{Path, PathBuf};

/// The clicks on a photo: the points of each material, and the negative
/// clicks no material may take.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialClicks {
    /// Each material's points, in photo pixels.
    pub materials: Vec<Vec<(f32, f32)>>,
    /// Negative clicks, in photo pixels.
    pub negatives: Vec<(f32, f32)>,
}

impl MaterialClicks {
    /// Points grouped into materials: points that share a group number
    /// are one material, and a point without one is a material of its
    /// own; materials are numbered in the order they first appear.
    pub fn group(points: &[(Option<u32>, (f32, f32))], negatives: Vec<(f32, f32)>) -> Self {
        let mut groups: Vec<Option<u32>> = Vec::new();
        let mut materials: Vec<Vec<(f32, f32)>> = Vec::new();
        for &(group, point) in points {
            match group.and_then(|g| groups.iter().position(|&h| h == Some(g))) {
                Some(k) => materials[k].push(point),
                None => {
                    groups.push(group);
                    materials.push(vec![point]);
                }
            }
        }
        Self {
            materials,
            negatives,
        }
    }

    /// Every positive point, material after material.
    pub fn points(&self) -> impl Iterator<Item = (f32, f32)> + '_ {
        self.materials.iter().flatten().copied()
    }

    /// Checks the clicks on `photo` (named `label`): a material at least,
    /// at most [`MAX_POINTS`] clicks in all, each inside the photo.
    pub fn check(&self, photo: &RgbImage, label: &str) -> Result<(), PipelineError> {
        if self.materials.is_empty() {
            let why = if self.negatives.is_empty() {
                "give at least one point"
            } else {
                "--not excludes a material from the points' selection: give a --point too"
            };
            return Err(PipelineError::setting("point", None::<&str>, why));
        }
        let points: Vec<(f32, f32)> = self.points().collect();
        let clicks = points.len() + self.negatives.len();
        if clicks > MAX_POINTS {
            return Err(PipelineError::setting(
                "point",
                None::<&str>,
                format!("{clicks} points and negative clicks: at most {MAX_POINTS} in all"),
            ));
        }
        check_clicks(photo, &points, label, "point")?;
        check_clicks(photo, &self.negatives, label, "not")?;
        check_contradictions(&points, &self.negatives)
    }
}

/// One material's selection.
pub struct MaterialSelection {
    /// Each pixel's similarity to the material's points, lowered where a
    /// negative click's material is as near (exactly the one-click map
    /// for a single point without negative clicks).
    pub soft: Vec<f32>,
    /// The material's pixels: the selection's own decision, against the
    /// negative clicks and the other materials' points.
    pub mask: Vec<bool>,
    /// The selection saved, to be applied to other photos.
    pub saved: SavedSelection,
}

/// Each material's selection on the photo `map` describes (discs of
/// `radius`; `model` names the model in the saved selections). Clicks
/// must have been checked ([`MaterialClicks::check`]).
pub fn select_materials(
    map: &CoarseDescriptors,
    photo: &RgbImage,
    clicks: &MaterialClicks,
    radius: f32,
    model: &str,
) -> Result<Vec<MaterialSelection>, PipelineError> {
    let failed = |e: matseg_query::select::SelectError| PipelineError::Settings(e.to_string());
    let mut selections = Vec::with_capacity(clicks.materials.len());
    for (k, points) in clicks.materials.iter().enumerate() {
        let mut selector = Selector::new(map, Some(photo), radius).map_err(failed)?;
        for &(x, y) in points {
            selector.add(Click::positive(x, y)).map_err(failed)?;
        }
        for &(x, y) in &clicks.negatives {
            selector.add(Click::negative(x, y)).map_err(failed)?;
        }
        let Selection { soft, mask, .. } = selector.selection().map_err(failed)?;
        let others = clicks
            .materials
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != k)
            .flat_map(|(_, p)| p);
        let mut against_others = false;
        for &(x, y) in others {
            selector.add(Click::negative(x, y)).map_err(failed)?;
            against_others = true;
        }
        let mask = if against_others {
            selector.selection().map_err(failed)?.mask
        } else {
            mask
        };
        selections.push(MaterialSelection {
            soft,
            mask,
            saved: selector.saved(model),
        });
    }
    Ok(selections)
}

/// A mask as 8-bit grey: 255 selected, 0 not.
pub fn mask_grey(mask: &[bool]) -> Vec<u8> {
    mask.iter().map(|&m| if m { 255 } else { 0 }).collect()
}

/// Writes material `k`'s `mask_K.png` and `selection_K.json` into `out`.
pub fn write_selection(
    photo: &RgbImage,
    k: usize,
    selection: &MaterialSelection,
    out: &Path,
) -> Result<(), PipelineError> {
    let (w, h) = photo.dimensions();
    write_file(
        &out.join(format!("mask_{k}.png")),
        &encode_png_grey(w, h, &mask_grey(&selection.mask)),
    )?;
    write_file(
        &out.join(format!("selection_{k}.json")),
        &serde_json::to_vec(&selection.saved).expect("a selection serialises"),
    )
}

/// Reads a saved selection (`selection.json`, `selection_K.json`) and
/// checks what needs no model (SavedSelection::validate).
pub fn read_selection(file: &Path) -> Result<SavedSelection, PipelineError> {
    let bytes = std::fs::read(file)
        .map_err(|e| PipelineError::file(file.display(), format!("cannot read: {e}")))?;
    let saved: SavedSelection = serde_json::from_slice(&bytes).map_err(|e| {
        PipelineError::file(
            file.display(),
            format!("not a saved selection (model, radius, positive, negative): {e}"),
        )
    })?;
    saved
        .validate()
        .map_err(|e| PipelineError::file(file.display(), e.to_string()))?;
    Ok(saved)
}

/// One photo's share of a selection applied to it.
#[derive(Clone, Debug, PartialEq)]
pub struct AppliedArea {
    /// The photo, as given.
    pub photo: PathBuf,
    /// Its mask's file name in `masks/`.
    pub mask: String,
    /// The photo's width and height.
    pub size: (u32, u32),
    /// Pixels selected.
    pub pixels: u64,
}

impl AppliedArea {
    /// The share of the photo selected, 0..1.
    pub fn share(&self) -> f64 {
        self.pixels as f64 / (self.size.0 as f64 * self.size.1 as f64).max(1.0)
    }
}

/// Applies `saved` with `model` to each of `photos` and writes into the
/// new folder `dir` (a staged output, matseg_image::outputs):
/// `masks/NAME.png` per photo (NAME its file name's stem; 255 where
/// selected), `areas.csv` (each photo's size, pixels selected and share)
/// and the selection as `selection.json`. Photos are checked first (each
/// decodes, names unique), before any is described. `advance` is called
/// after each photo.
pub fn apply_to_folder(
    model: &Model,
    saved: &SavedSelection,
    photos: &[PathBuf],
    dir: &Path,
    advance: &mut dyn FnMut(&AppliedArea),
) -> Result<Vec<AppliedArea>, PipelineError> {
    let names = mask_names(photos)?;
    for photo in photos {
        matseg_image::io::read_rgb(photo)?;
    }
    create_folder(&dir.join("masks"))?;
    let mut areas = Vec::with_capacity(photos.len());
    for (file, name) in photos.iter().zip(names) {
        let photo = read_rgb(file)?;
        let map = describe(model, &photo);
        let selection = saved
            .apply(&map, Some(&photo), map.grid.dim)
            .map_err(|e| PipelineError::Settings(format!("selection: {e}")))?;
        let (w, h) = photo.dimensions();
        write_file(
            &dir.join("masks").join(&name),
            &encode_png_grey(w, h, &mask_grey(&selection.mask)),
        )?;
        let area = AppliedArea {
            photo: file.clone(),
            mask: name,
            size: (w, h),
            pixels: selection.mask.iter().filter(|&&m| m).count() as u64,
        };
        advance(&area);
        areas.push(area);
    }
    write_file(&dir.join("areas.csv"), areas_csv(&areas).as_bytes())?;
    write_file(
        &dir.join("selection.json"),
        &serde_json::to_vec(saved).expect("a selection serialises"),
    )?;
    Ok(areas)
}

/// Each photo's mask name, `STEM.png`; two photos of one stem are
/// refused (their masks would overwrite each other).
fn mask_names(photos: &[PathBuf]) -> Result<Vec<String>, PipelineError> {
    let mut seen = std::collections::HashMap::new();
    photos
        .iter()
        .map(|photo| {
            let stem = photo
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .ok_or_else(|| PipelineError::file(photo.display(), "not a photo file"))?;
            let name = format!("{stem}.png");
            if let Some(first) = seen.insert(name.clone(), photo) {
                return Err(PipelineError::file(
                    photo.display(),
                    format!(
                        "its mask would be masks/{name}, as {}'s: rename one of them",
                        first.display()
                    ),
                ));
            }
            Ok(name)
        })
        .collect()
}

/// `areas.csv`: a header, then per photo its path, mask, width, height,
/// pixels selected and share of the photo (6 decimals).
pub fn areas_csv(areas: &[AppliedArea]) -> String {
    let mut csv = String::from("photo,mask,width,height,pixels,share\n");
    for a in areas {
        csv.push_str(&format!(
            "{},{},{},{},{},{:.6}\n",
            csv_field(&a.photo.display().to_string()),
            csv_field(&format!("masks/{}", a.mask)),
            a.size.0,
            a.size.1,
            a.pixels,
            a.share()
        ));
    }
    csv
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_query::descriptor::DescriptorMap;

    /// A 40x20 photo whose left half is one material and right half
    /// another, described on a 4x2 grid of unit descriptors.
    fn halves() -> (RgbImage, CoarseDescriptors) {
        let photo = RgbImage::from_fn(40, 20, |x, _| {
            if x < 20 {
                image::Rgb([30, 30, 30])
            } else {
                image::Rgb([220, 220, 220])
            }
        });
        let data = (0..8)
            .flat_map(|i| if i % 4 < 2 { [1.0, 0.0] } else { [0.0, 1.0] })
            .collect();
        let grid = DescriptorMap {
            width: 4,
            height: 2,
            dim: 2,
            data,
        };
        let map = CoarseDescriptors {
            grid,
            width: 40,
            height: 20,
        };
        (photo, map)
    }

    #[test]
    fn points_group_by_number_and_plain_points_stand_alone() {
        let points = [
            (Some(2), (1.0, 1.0)),
            (None, (2.0, 2.0)),
            (Some(2), (3.0, 3.0)),
            (Some(1), (4.0, 4.0)),
            (None, (5.0, 5.0)),
        ];
        let clicks = MaterialClicks::group(&points, vec![(6.0, 6.0)]);
        assert_eq!(
            clicks.materials,
            vec![
                vec![(1.0, 1.0), (3.0, 3.0)],
                vec![(2.0, 2.0)],
                vec![(4.0, 4.0)],
                vec![(5.0, 5.0)]
            ]
        );
        assert_eq!(clicks.negatives, vec![(6.0, 6.0)]);
    }

    #[test]
    fn malformed_clicks_are_refused_naming_the_argument() {
        let (photo, _) = halves();
        let only_not = MaterialClicks::group(&[], vec![(1.0, 1.0)]);
        let e = only_not.check(&photo, "p.png").unwrap_err().to_string();
        assert!(e.starts_with("point: --not excludes"), "{e}");
        let outside = MaterialClicks::group(&[(None, (1.0, 1.0))], vec![(40.0, 1.0)]);
        assert_eq!(
            outside.check(&photo, "p.png").unwrap_err().to_string(),
            "not 40,1: outside p.png (40x20)"
        );
        let many: Vec<_> = (0..300).map(|_| (None, (1.0, 1.0))).collect();
        let e = MaterialClicks::group(&many, vec![])
            .check(&photo, "p.png")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("point: 300 points"), "{e}");
    }

    #[test]
    fn each_material_is_selected_against_the_others_and_the_negatives() {
        let (photo, map) = halves();
        let two = MaterialClicks::group(&[(None, (5.0, 5.0)), (None, (35.0, 5.0))], vec![]);
        let selections = select_materials(&map, &photo, &two, 2.0, "m").unwrap();
        assert!(selections[0].mask[40 * 10 + 5] && !selections[0].mask[40 * 10 + 35]);
        assert!(selections[1].mask[40 * 10 + 35] && !selections[1].mask[40 * 10 + 5]);
        // One point and no negative: the similarity map as it is.
        let one = MaterialClicks::group(&[(None, (5.0, 5.0))], vec![]);
        let alone = select_materials(&map, &photo, &one, 2.0, "m").unwrap();
        assert_eq!(
            alone[0].soft,
            map.similarity_map(&map.point_descriptor(5.0, 5.0, 2.0))
        );
        // Two points of one material and a negative click: the saved
        // selection holds all three.
        let both = MaterialClicks::group(
            &[(Some(1), (5.0, 5.0)), (Some(1), (6.0, 15.0))],
            vec![(35.0, 5.0)],
        );
        let s = &select_materials(&map, &photo, &both, 2.0, "m").unwrap()[0];
        assert!(s.mask[40 * 10 + 5] && !s.mask[40 * 10 + 35]);
        assert_eq!((s.saved.positive.len(), s.saved.negative.len()), (2, 1));
    }

    #[test]
    fn a_negative_click_takes_a_like_material_out_of_the_selection() {
        // Three stripes over a 60 x 20 photo: a, then b (cosine 0.8 to a),
        // then c (unlike both), on a 6 x 2 grid.
        let photo = RgbImage::from_fn(60, 20, |x, _| image::Rgb([40 * (x / 20) as u8, 90, 90]));
        let stripe = |column: usize| match column / 2 {
            0 => [1.0, 0.0, 0.0],
            1 => [0.8, 0.6, 0.0],
            _ => [0.0, 0.0, 1.0],
        };
        let data = (0..12).flat_map(|i| stripe(i % 6)).collect();
        let map = CoarseDescriptors {
            grid: DescriptorMap {
                width: 6,
                height: 2,
                dim: 3,
                data,
            },
            width: 60,
            height: 20,
        };
        let at = |x: usize| 60 * 10 + x;
        let one = MaterialClicks::group(&[(None, (5.0, 5.0))], vec![]);
        let s = &select_materials(&map, &photo, &one, 2.0, "m").unwrap()[0];
        assert!(
            s.mask[at(5)] && s.mask[at(30)] && !s.mask[at(55)],
            "a and b"
        );
        let not_b = MaterialClicks::group(&[(None, (5.0, 5.0))], vec![(30.0, 15.0)]);
        let s = &select_materials(&map, &photo, &not_b, 2.0, "m").unwrap()[0];
        assert!(
            s.mask[at(5)] && !s.mask[at(30)] && !s.mask[at(55)],
            "a alone"
        );
    }

    #[test]
    fn areas_are_written_as_csv() {
        let area = AppliedArea {
            photo: PathBuf::from("a, \"b\".jpg"),
            mask: "a, \"b\".png".into(),
            size: (4, 2),
            pixels: 2,
        };
        assert_eq!(
            areas_csv(&[area]),
            "photo,mask,width,height,pixels,share\n\"a, \"\"b\"\".jpg\",\"masks/a, \"\"b\"\".png\",4,2,2,0.250000\n"
        );
    }
}
