//! Point benchmarks made from generated scenes, whose soft weights are
//! exact: points where one material is pure become that material's points;
//! points where two materials mix about evenly become a mixture material
//! related to both (a `[...]` relation, weight 0.6), so the Soft subset has
//! something to score. Written in the MatSeg layout [`crate::points`] reads.

use crate::annotation::{Annotation, Group, Relation};
use crate::points::{BenchError, SQUARE_RELATION};
use image::RgbImage;
use matseg_image::io::encode_jpeg;
use matseg_image::outputs::write_atomic;
use matseg_image::Plane;
use rand::seq::index::sample;
use rand::Rng;
use std::path::Path;

/// How points are picked from a scene's weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SyntheticOptions {
    /// Points per material (fewer where fewer pixels qualify).
    pub points_per_material: usize,
    /// Radius written with each point.
    pub radius: f32,
    /// A pixel is pure material k where its weight is at least this.
    pub pure: f32,
    /// A pixel mixes materials j and k where both weights lie in this range
    /// and together reach `pure`.
    pub mixture: (f32, f32),
}

impl Default for SyntheticOptions {
    fn default() -> Self {
        Self {
            points_per_material: 5,
            radius: 2.0,
            pure: 0.99,
            mixture: (0.3, 0.7),
        }
    }
}

/// Picks points from the material `weights` of a scene (row-major planes of
/// one size): up to `points_per_material` pure points per material, and a
/// mixture material for every pair that mixes on enough pixels, related to
/// both; unnamed groups with ids `1`, `2`... Points stay `radius` away from
/// the border.
pub fn annotate_points<R: Rng + ?Sized>(
    rng: &mut R,
    weights: &[Plane],
    options: &SyntheticOptions,
) -> Annotation {
    let Some(first) = weights.first() else {
        return Annotation::default();
    };
    let (w, h) = (first.width, first.height);
    let margin = options.radius.ceil() as usize;
    let inside = |i: usize| {
        let (x, y) = (i % w, i / w);
        x >= margin && y >= margin && x + margin < w && y + margin < h
    };
    let radius = f64::from(options.radius);
    let pick = |candidates: Vec<usize>, rng: &mut R| -> Vec<[f64; 3]> {
        let n = options.points_per_material.min(candidates.len());
        let mut chosen: Vec<usize> = sample(rng, candidates.len(), n)
            .into_iter()
            .map(|k| candidates[k])
            .collect();
        chosen.sort_unstable();
        chosen
            .into_iter()
            .map(|i| [(i % w) as f64, (i / w) as f64, radius])
            .collect()
    };
    let group = |id: String, points| Group {
        id,
        name: None,
        points,
    };
    let related = |a: usize, b: usize| Relation {
        ids: vec![a.to_string(), b.to_string()],
        weight: SQUARE_RELATION,
    };
    let mut annotation = Annotation::default();
    let mut present = vec![false; weights.len()];
    for (k, plane) in weights.iter().enumerate() {
        let pure: Vec<usize> = (0..w * h)
            .filter(|&i| plane.data[i] >= options.pure && inside(i))
            .collect();
        let points = pick(pure, rng);
        if !points.is_empty() {
            present[k] = true;
            annotation.groups.push(group((k + 1).to_string(), points));
        }
    }
    let (lo, hi) = options.mixture;
    let mut next_id = weights.len() + 1;
    for j in 0..weights.len() {
        for k in j + 1..weights.len() {
            if !(present[j] && present[k]) {
                continue;
            }
            let (a, b) = (&weights[j].data, &weights[k].data);
            let mixed: Vec<usize> = (0..w * h)
                .filter(|&i| {
                    (lo..=hi).contains(&a[i])
                        && (lo..=hi).contains(&b[i])
                        && a[i] + b[i] >= options.pure
                        && inside(i)
                })
                .collect();
            if mixed.len() < options.points_per_material {
                continue;
            }
            let id = next_id;
            next_id += 1;
            annotation
                .groups
                .push(group(id.to_string(), pick(mixed, rng)));
            annotation.relations.push(related(j + 1, id));
            annotation.relations.push(related(k + 1, id));
        }
    }
    annotation
}

/// Writes one image of a point benchmark: `images/NAME.jpg`, and its
/// annotation in `data/NAME/` as [`Annotation::write`] writes it.
pub fn write_point_image(
    dir: &Path,
    name: &str,
    image: &RgbImage,
    annotation: &Annotation,
) -> Result<(), BenchError> {
    annotation.write(&dir.join("data").join(name))?;
    // The image last: the reader lists data folders, then opens the image.
    let images = dir.join("images");
    let file = images.join(format!("{name}.jpg"));
    std::fs::create_dir_all(&images)
        .and_then(|()| write_atomic(&file, &encode_jpeg(image, 95)))
        .map_err(|e| BenchError::new(&file, None, format!("cannot write: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn points_lie_where_materials_are_pure_or_mixed() {
        let (w, h) = (40, 30);
        // Material 1 on the left third, 2 on the right third, an even mix
        // of both in the middle.
        let plane =
            |f: fn(usize) -> f32| Plane::from_vec(w, h, (0..w * h).map(|i| f(i % w)).collect());
        let weights = vec![
            plane(|x| {
                if x < 13 {
                    1.0
                } else if x < 27 {
                    0.5
                } else {
                    0.0
                }
            }),
            plane(|x| {
                if x < 13 {
                    0.0
                } else if x < 27 {
                    0.5
                } else {
                    1.0
                }
            }),
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let a = annotate_points(&mut rng, &weights, &SyntheticOptions::default());
        let ids: Vec<&str> = a.groups.iter().map(|g| g.id.as_str()).collect();
        assert_eq!(ids, ["1", "2", "3"]);
        let relations: Vec<String> = a
            .relations
            .iter()
            .map(|r| crate::annotation::format_relation(&r.ids, r.weight))
            .collect();
        assert_eq!(relations, ["[1, 3]", "[2, 3]"]);
        assert_eq!(a.check(w as u32, h as u32), Ok(()));
        let xs = |k: usize| {
            a.groups[k]
                .points
                .iter()
                .map(|p| p[0] as usize)
                .collect::<Vec<_>>()
        };
        assert!(xs(0).iter().all(|&x| (2..13).contains(&x)) && xs(0).len() == 5);
        assert!(xs(1).iter().all(|&x| x >= 27 && x < w - 2));
        assert!(xs(2).iter().all(|&x| (13..27).contains(&x)));
        assert!(a
            .groups
            .iter()
            .flat_map(|g| &g.points)
            .all(|p| p[1] >= 2.0 && p[1] < (h - 2) as f64 && p[2] == 2.0));
    }
}
