//! IoU at the best threshold (pipeline.md §9.3): the prediction `score >= t` is
//! compared with a ground-truth mask for every `t`, and the best IoU wins.

use serde::Serialize;

/// The best IoU and the threshold that gives it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BestIou {
    /// Intersection over union, in `[0, 1]`.
    pub iou: f64,
    /// The threshold: pixels with `score >= threshold` are predicted.
    pub threshold: f32,
}

/// The exact best IoU over every threshold, in O(n log n): sort the scores
/// once, then lower the threshold through each distinct score, counting the
/// mask pixels and the other pixels it admits. `None` when the mask is empty.
pub fn best_iou(scores: &[f32], truth: &[bool]) -> Option<BestIou> {
    assert_eq!(scores.len(), truth.len(), "scores and mask differ in size");
    let positives = truth.iter().filter(|&&t| t).count();
    if positives == 0 {
        return None;
    }
    let mut order: Vec<usize> = (0..scores.len()).collect();
    order.sort_unstable_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    let mut best = BestIou {
        iou: 0.0,
        threshold: f32::INFINITY,
    };
    let (mut hits, mut false_alarms) = (0usize, 0usize);
    let mut i = 0;
    while i < order.len() {
        // Admit every pixel with this score at once.
        let t = scores[order[i]];
        while i < order.len() && scores[order[i]] == t {
            if truth[order[i]] {
                hits += 1;
            } else {
                false_alarms += 1;
            }
            i += 1;
        }
        let iou = hits as f64 / (positives + false_alarms) as f64;
        if iou > best.iou {
            best = BestIou { iou, threshold: t };
        }
    }
    Some(best)
}

/// The best IoU over a fixed grid of `steps + 1` thresholds spread evenly
/// from the lowest to the highest score (parity with evaluations that sweep
/// a grid, e.g. 100 or 1000 steps). Never above [`best_iou`].
pub fn best_iou_on_grid(scores: &[f32], truth: &[bool], steps: usize) -> Option<BestIou> {
    assert_eq!(scores.len(), truth.len(), "scores and mask differ in size");
    let positives = truth.iter().filter(|&&t| t).count();
    if positives == 0 || steps == 0 {
        return None;
    }
    let lo = scores.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = scores.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut best = BestIou {
        iou: 0.0,
        threshold: f32::INFINITY,
    };
    for k in 0..=steps {
        let t = lo + (hi - lo) * (k as f32 / steps as f32);
        let (mut hits, mut predicted) = (0usize, 0usize);
        for (&s, &m) in scores.iter().zip(truth) {
            if s >= t {
                predicted += 1;
                hits += m as usize;
            }
        }
        let iou = hits as f64 / (positives + predicted - hits) as f64;
        if iou > best.iou {
            best = BestIou { iou, threshold: t };
        }
    }
    Some(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// IoU of `score >= t` by definition.
    fn iou_at(scores: &[f32], truth: &[bool], t: f32) -> f64 {
        let inter = scores
            .iter()
            .zip(truth)
            .filter(|(&s, &m)| s >= t && m)
            .count();
        let union = scores
            .iter()
            .zip(truth)
            .filter(|(&s, &m)| s >= t || m)
            .count();
        inter as f64 / union as f64
    }

    #[test]
    fn known_small_cases() {
        let scores = [0.9, 0.8, 0.7, 0.1];
        let truth = [true, false, true, false];
        // t = 0.9: 1/2; t = 0.8: 1/3; t = 0.7: 2/3; t = 0.1: 2/4.
        let b = best_iou(&scores, &truth).unwrap();
        assert_eq!((b.iou, b.threshold), (2.0 / 3.0, 0.7));
        // A perfect score map reaches 1.
        let b = best_iou(&[0.2, 0.9, 0.9, 0.1], &[false, true, true, false]).unwrap();
        assert_eq!(b.iou, 1.0);
        // Ties are admitted together: both 0.5 pixels or neither.
        let b = best_iou(&[0.5, 0.5, 0.1], &[true, false, false]).unwrap();
        assert_eq!(b.iou, 0.5);
        assert_eq!(best_iou(&[0.3], &[false]), None);
    }

    #[test]
    fn exact_equals_brute_force_and_bounds_the_grid() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let n = rng.random_range(1..60);
            // Few distinct values, so ties are common.
            let scores: Vec<f32> = (0..n)
                .map(|_| rng.random_range(0..12) as f32 / 11.0)
                .collect();
            let truth: Vec<bool> = (0..n).map(|_| rng.random_bool(0.4)).collect();
            let Some(exact) = best_iou(&scores, &truth) else {
                assert!(truth.iter().all(|&t| !t));
                continue;
            };
            let brute = scores
                .iter()
                .map(|&t| iou_at(&scores, &truth, t))
                .fold(0.0, f64::max);
            assert!((exact.iou - brute).abs() < 1e-12);
            assert!((iou_at(&scores, &truth, exact.threshold) - exact.iou).abs() < 1e-12);
            let grid = best_iou_on_grid(&scores, &truth, 1000).unwrap();
            assert!(grid.iou <= exact.iou + 1e-12);
        }
    }
}
