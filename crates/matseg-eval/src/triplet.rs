//! The triplet metric (pipeline.md §9.2) and top-1, for one image's points.
//!
//! For an anchor `a` and another point `p`, every other point `q` whose
//! ground-truth weight to `a` differs from `p`'s is a triplet: it is correct
//! when the predicted similarities order `p` and `q` as the weights do, half
//! correct when the predictions tie, wrong otherwise (ground-truth ties are
//! never triplets). The pair `(a, p)` scores the mean over its triplets, the
//! anchor the mean over its pairs.

use serde::Serialize;

/// One image's scores; `None` where nothing could be scored.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ImageScores {
    /// All triplets: mean over anchors.
    pub all_by_point: Option<f64>,
    /// All triplets: mean over materials of the mean over their anchors.
    pub all_by_material: Option<f64>,
    /// Soft subset (only `p` partially similar to the anchor): by anchor.
    pub soft_by_point: Option<f64>,
    /// Soft subset: by material.
    pub soft_by_material: Option<f64>,
    /// Top-1 (the most similar other point has the highest weight): by anchor.
    pub top1_by_point: Option<f64>,
    /// Top-1: by material.
    pub top1_by_material: Option<f64>,
    /// Triplets counted for All.
    pub triplets: u64,
    /// Triplets counted for Soft.
    pub soft_triplets: u64,
}

/// The points of one image as the metric sees them.
#[derive(Clone, Copy)]
pub struct PointScores<'a> {
    /// The material of each point (an index into the weight table).
    pub material: &'a [usize],
    /// Ground-truth weight between two materials: 1 on the diagonal,
    /// a partial similarity (0 < w < 1) for related materials, else 0.
    pub weight: &'a dyn Fn(usize, usize) -> f64,
    /// Predicted similarity of point `i` to point `j` (higher is closer).
    pub similarity: &'a dyn Fn(usize, usize) -> f64,
}

/// Running means of scores grouped by material.
struct Tally {
    by_point: (f64, u64),
    by_material: Vec<(f64, u64)>,
}

impl Tally {
    fn new(materials: usize) -> Self {
        Self {
            by_point: (0.0, 0),
            by_material: vec![(0.0, 0); materials],
        }
    }

    fn add(&mut self, material: usize, score: f64) {
        self.by_point.0 += score;
        self.by_point.1 += 1;
        self.by_material[material].0 += score;
        self.by_material[material].1 += 1;
    }

    fn by_point(&self) -> Option<f64> {
        mean(self.by_point)
    }

    fn by_material(&self) -> Option<f64> {
        let means: Vec<f64> = self.by_material.iter().filter_map(|&m| mean(m)).collect();
        mean((means.iter().sum(), means.len() as u64))
    }
}

fn mean((sum, n): (f64, u64)) -> Option<f64> {
    (n > 0).then(|| sum / n as f64)
}

/// 1 when `d_pred` orders like `d_truth` (a non-zero difference), 0.5 when
/// the prediction ties, 0 otherwise.
fn agreement(d_truth: f64, d_pred: f64) -> f64 {
    if d_pred == 0.0 {
        0.5
    } else if (d_pred > 0.0) == (d_truth > 0.0) {
        1.0
    } else {
        0.0
    }
}

/// Scores one image. `soft` says whether the image takes part in the Soft
/// subset (it has relations).
pub fn score_image(points: &PointScores<'_>, soft: bool) -> ImageScores {
    let n = points.material.len();
    let materials = points.material.iter().max().map_or(0, |&m| m + 1);
    let (mut all, mut partial, mut top1) = (
        Tally::new(materials),
        Tally::new(materials),
        Tally::new(materials),
    );
    let (mut triplets, mut soft_triplets) = (0u64, 0u64);
    let w = |i: usize, j: usize| (points.weight)(points.material[i], points.material[j]);
    let s = points.similarity;
    for a in 0..n {
        let (mut all_sum, mut all_pairs) = (0.0, 0u64);
        let (mut soft_sum, mut soft_pairs) = (0.0, 0u64);
        for p in (0..n).filter(|&p| p != a) {
            let (wp, sp) = (w(a, p), s(a, p));
            let (mut sum, mut count) = (0.0, 0u64);
            for q in (0..n).filter(|&q| q != a && q != p) {
                let wq = w(a, q);
                if wq != wp {
                    sum += agreement(wp - wq, sp - s(a, q));
                    count += 1;
                }
            }
            if count == 0 {
                continue;
            }
            triplets += count;
            all_sum += sum / count as f64;
            all_pairs += 1;
            if soft && wp > 0.0 && wp < 1.0 {
                soft_triplets += count;
                soft_sum += sum / count as f64;
                soft_pairs += 1;
            }
        }
        let m = points.material[a];
        if all_pairs > 0 {
            all.add(m, all_sum / all_pairs as f64);
        }
        if soft_pairs > 0 {
            partial.add(m, soft_sum / soft_pairs as f64);
        }
        if let Some(score) = top1_score(a, n, &w, s) {
            top1.add(m, score);
        }
    }
    ImageScores {
        all_by_point: all.by_point(),
        all_by_material: all.by_material(),
        soft_by_point: partial.by_point(),
        soft_by_material: partial.by_material(),
        top1_by_point: top1.by_point(),
        top1_by_material: top1.by_material(),
        triplets,
        soft_triplets,
    }
}

/// Top-1 for anchor `a`: the share of the most similar other points (all of
/// them when the prediction ties) that have the highest weight to `a`.
/// `None` when the other points all have the same weight (nothing to rank).
fn top1_score(
    a: usize,
    n: usize,
    w: &dyn Fn(usize, usize) -> f64,
    s: &dyn Fn(usize, usize) -> f64,
) -> Option<f64> {
    let others: Vec<usize> = (0..n).filter(|&p| p != a).collect();
    let best_w = others.iter().map(|&p| w(a, p)).fold(f64::MIN, f64::max);
    if others.iter().all(|&p| w(a, p) == best_w) {
        return None;
    }
    let best_s = others.iter().map(|&p| s(a, p)).fold(f64::MIN, f64::max);
    let nearest: Vec<usize> = others.into_iter().filter(|&p| s(a, p) == best_s).collect();
    let hits = nearest.iter().filter(|&&p| w(a, p) == best_w).count();
    Some(hits as f64 / nearest.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two points each of materials 0, 1, 2; materials 0 and 1 related at 0.6.
    const MATERIAL: [usize; 6] = [0, 0, 1, 1, 2, 2];

    fn weight(a: usize, b: usize) -> f64 {
        if a == b {
            1.0
        } else if a.min(b) == 0 && a.max(b) == 1 {
            0.6
        } else {
            0.0
        }
    }

    fn score(similarity: &dyn Fn(usize, usize) -> f64) -> ImageScores {
        let points = PointScores {
            material: &MATERIAL,
            weight: &|a, b| weight(a, b),
            similarity,
        };
        score_image(&points, true)
    }

    #[test]
    fn a_perfect_predictor_scores_one() {
        let s = score(&|i, j| weight(MATERIAL[i], MATERIAL[j]));
        assert_eq!(s.all_by_point, Some(1.0));
        assert_eq!(s.all_by_material, Some(1.0));
        assert_eq!(s.soft_by_point, Some(1.0));
        assert_eq!(s.top1_by_point, Some(1.0));
        // Anchor 0: p = 1 (w 1) has 4 q with other weights; p = 2, 3 (0.6)
        // have 3 each (1, 4, 5); p = 4, 5 (0) have 3 each (1, 2, 3).
        // Anchors of material 2: p of weight 1 has 4 q; the other four p
        // (weight 0) have 1 q each. 2 * (4 + 12) + 2 * (4 + 12) + 2 * 8 = 80.
        assert_eq!(s.triplets, 80);
        // Soft: anchors 0..4 have two partial p with 3 q each.
        assert_eq!(s.soft_triplets, 4 * 2 * 3);
    }

    #[test]
    fn an_inverted_predictor_scores_zero() {
        let s = score(&|i, j| -weight(MATERIAL[i], MATERIAL[j]));
        assert_eq!(s.all_by_point, Some(0.0));
        assert_eq!(s.soft_by_material, Some(0.0));
        assert_eq!(s.top1_by_point, Some(0.0));
    }

    #[test]
    fn a_constant_predictor_scores_one_half_by_the_tie_rule() {
        let s = score(&|_, _| 0.3);
        assert_eq!(s.all_by_point, Some(0.5));
        assert_eq!(s.soft_by_point, Some(0.5));
        // Top-1 with all points tied: the share of maximal-weight points.
        // Anchors of materials 0 and 1: 1 of 5; of material 2: 1 of 5.
        assert!((s.top1_by_point.unwrap() - 0.2).abs() < 1e-12);
    }

    #[test]
    fn a_mixed_predictor_gets_the_hand_computed_fraction() {
        // Exact for same-material pairs, but blind to the relation: it says
        // 0 for materials 0-1 (as for unrelated ones).
        let s = score(&|i, j| if MATERIAL[i] == MATERIAL[j] { 1.0 } else { 0.0 });
        // Anchor 0: p = 1: 4 q, all right -> 1. p = 2 (w 0.6, s 0): q = 1
        // right; q = 4, 5 tie -> (1 + 0.5 + 0.5) / 3 = 2/3; same for p = 3.
        // p = 4 (w 0, s 0): q = 1 right, q = 2, 3 tie -> 2/3; same for p = 5.
        // Anchor score = (1 + 4 * 2/3) / 5 = 11/15 (anchors 0 to 3 alike).
        // Anchors 4, 5: p same: 4 q right -> 1; p other (w 0): its only q is
        // the same-material point, right -> 1. Score 1.
        let expected = (4.0 * 11.0 / 15.0 + 2.0) / 6.0;
        assert!((s.all_by_point.unwrap() - expected).abs() < 1e-12);
        // By material: (11/15 + 11/15 + 1) / 3 = the same here.
        assert!((s.all_by_material.unwrap() - expected).abs() < 1e-12);
        // Soft: only p = 2, 3 for anchors 0, 1 (and p = 0, 1 for 2, 3): 2/3.
        assert!((s.soft_by_point.unwrap() - 2.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn images_without_relations_have_no_soft_score_and_ties_never_count() {
        let material = [0, 0, 1];
        let s = score_image(
            &PointScores {
                material: &material,
                weight: &|a, b| if a == b { 1.0 } else { 0.0 },
                similarity: &|i, j| -((i as f64) - (j as f64)).abs(),
            },
            false,
        );
        assert_eq!(s.soft_by_point, None);
        assert_eq!(s.soft_triplets, 0);
        // Anchor 0: p = 1 (w 1) vs q = 2 (w 0): s(0,1) = -1 > s(0,2) = -2, right.
        // p = 2 vs q = 1: right. Anchor 1: p = 0 vs q = 2: s equal (-1, -1): 0.5.
        // p = 2 vs q = 0: 0.5. Anchor 2: every other point has weight 0: no triplet.
        assert_eq!(s.triplets, 4);
        assert_eq!(s.all_by_point, Some(0.75));
        assert_eq!(s.all_by_material, Some(0.75));
    }
}
