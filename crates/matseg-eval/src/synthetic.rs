//! Point benchmarks made from generated scenes, whose soft weights are
//! exact: points where one material is pure become that material's points;
//! points where two materials mix about evenly become a mixture material
//! related to both (a `[...]` relation, weight 0.6), so the Soft subset has
//! something to score. Written in the MatSeg layout [`crate::points`] reads.

use crate::points::BenchPoint;
use image::RgbImage;
use matseg_image::io::{encode_jpeg, write_atomic};
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

/// The points of one scene, by material id, and its relation lines.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointAnnotation {
    /// Material ids ("1", "2", ...) and their points.
    pub materials: Vec<(String, Vec<BenchPoint>)>,
    /// Lines of `group_relations.txt`.
    pub relations: Vec<String>,
}

/// Picks points from the material `weights` of a scene (row-major planes of
/// one size): up to `points_per_material` pure points per material, and a
/// mixture material for every pair that mixes on enough pixels. Points stay
/// `radius` away from the border.
pub fn annotate_points<R: Rng + ?Sized>(
    rng: &mut R,
    weights: &[Plane],
    options: &SyntheticOptions,
) -> PointAnnotation {
    let Some(first) = weights.first() else {
        return PointAnnotation::default();
    };
    let (w, h) = (first.width, first.height);
    let margin = options.radius.ceil() as usize;
    let inside = |i: usize| {
        let (x, y) = (i % w, i / w);
        x >= margin && y >= margin && x + margin < w && y + margin < h
    };
    let pick = |candidates: Vec<usize>, rng: &mut R| -> Vec<BenchPoint> {
        let n = options.points_per_material.min(candidates.len());
        let mut chosen: Vec<usize> = sample(rng, candidates.len(), n)
            .into_iter()
            .map(|k| candidates[k])
            .collect();
        chosen.sort_unstable();
        chosen
            .into_iter()
            .map(|i| BenchPoint {
                x: (i % w) as f32,
                y: (i / w) as f32,
                r: options.radius,
            })
            .collect()
    };
    let mut annotation = PointAnnotation::default();
    let mut present = vec![false; weights.len()];
    for (k, plane) in weights.iter().enumerate() {
        let pure: Vec<usize> = (0..w * h)
            .filter(|&i| plane.data[i] >= options.pure && inside(i))
            .collect();
        let points = pick(pure, rng);
        if !points.is_empty() {
            present[k] = true;
            annotation.materials.push(((k + 1).to_string(), points));
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
            let id = next_id.to_string();
            next_id += 1;
            annotation.materials.push((id.clone(), pick(mixed, rng)));
            annotation.relations.push(format!("[{}, {id}]", j + 1));
            annotation.relations.push(format!("[{}, {id}]", k + 1));
        }
    }
    annotation
}

/// Writes one image of a point benchmark: `images/NAME.jpg`,
/// `data/NAME/data.json` and, with relations, `group_relations.txt`.
pub fn write_point_image(
    dir: &Path,
    name: &str,
    image: &RgbImage,
    annotation: &PointAnnotation,
) -> std::io::Result<()> {
    let data = dir.join("data").join(name);
    std::fs::create_dir_all(&data)?;
    std::fs::create_dir_all(dir.join("images"))?;
    let json: serde_json::Map<String, serde_json::Value> = annotation
        .materials
        .iter()
        .map(|(id, points)| {
            let list: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.r]).collect();
            (id.clone(), serde_json::json!({ "pt_im": list }))
        })
        .collect();
    let text = serde_json::to_string_pretty(&json).expect("JSON of numbers");
    write_atomic(&data.join("data.json"), text.as_bytes())?;
    if !annotation.relations.is_empty() {
        let lines = annotation.relations.join("\n") + "\n";
        write_atomic(&data.join("group_relations.txt"), lines.as_bytes())?;
    }
    // The image last: the reader lists data folders, then opens the image.
    write_atomic(
        &dir.join("images").join(format!("{name}.jpg")),
        &encode_jpeg(image, 95),
    )
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
        let ids: Vec<&str> = a.materials.iter().map(|(id, _)| id.as_str()).collect();
        assert_eq!(ids, ["1", "2", "3"]);
        assert_eq!(a.relations, ["[1, 3]", "[2, 3]"]);
        let xs = |k: usize| {
            a.materials[k]
                .1
                .iter()
                .map(|p| p.x as usize)
                .collect::<Vec<_>>()
        };
        assert!(xs(0).iter().all(|&x| (2..13).contains(&x)) && xs(0).len() == 5);
        assert!(xs(1).iter().all(|&x| x >= 27 && x < w - 2));
        assert!(xs(2).iter().all(|&x| (13..27).contains(&x)));
        assert!(a
            .materials
            .iter()
            .flat_map(|m| &m.1)
            .all(|p| p.y >= 2.0 && p.y < (h - 2) as f32));
    }
}
