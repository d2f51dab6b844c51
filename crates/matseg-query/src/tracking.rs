//! Following clicked materials through the frames of a video
//! (pipeline.md §8.2).
//!
//! Each point keeps two memories of grid-cell descriptors from earlier
//! frames: cells it confidently held (its material) and cells it
//! confidently did not (everything else). A cell's score is the
//! probability that it is the point's material, from its nearest
//! neighbours in the two memories:
//! `sigmoid((max cos to positives - max cos to negatives) / T)`, the
//! clicked descriptor always among the positives and the other points'
//! positives among the negatives. Before any negative is known (the first
//! frame, or with no memory at all) the negative side is a constant prior
//! cosine, so the margin is `cos to the click - prior`.
//! After each frame, up to [`TrackOptions::samples`] cells at least
//! [`TrackOptions::confident`] sure each way are added; the first frame's
//! (the clicked one's) are kept for good and the newest
//! [`TrackOptions::memory`] frames' after it, so memory is bounded
//! whatever the video's length, and the material is still found as light
//! and viewpoint change its look.

use crate::coarse::CoarseDescriptors;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::VecDeque;

/// How points are followed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TrackOptions {
    /// Frames whose confident cells are kept (0: the clicked descriptor
    /// alone against the prior, on every frame).
    pub memory: usize,
    /// Cells added to each memory per frame and point, at most.
    pub samples: usize,
    /// The probability a cell needs to enter the positive memory (and its
    /// complement, the negative).
    pub confident: f32,
    /// The cosine standing for "not the material" before any negative is
    /// known.
    pub prior: f32,
    /// Temperature of the scores' sigmoid (the cosine scale of a decision).
    pub temperature: f32,
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            memory: 8,
            samples: 32,
            confident: 0.9,
            prior: 0.8,
            temperature: 0.05,
        }
    }
}

impl TrackOptions {
    /// The clicked descriptor alone, frame after frame: what the memory is
    /// measured against.
    pub fn first_frame_only() -> Self {
        TrackOptions {
            memory: 0,
            ..Self::default()
        }
    }
}

/// Descriptors kept frame by frame: the first frame's for good (the
/// clicked frame's, when the tracker starts there), and the newest
/// `frames` frames' after it.
#[derive(Clone, Debug, Default)]
struct Memory {
    first: Option<Vec<Vec<f32>>>,
    frames: VecDeque<Vec<Vec<f32>>>,
}

impl Memory {
    fn push(&mut self, cells: Vec<Vec<f32>>, keep: usize) {
        if cells.is_empty() {
            return;
        }
        if self.first.is_none() {
            self.first = Some(cells);
            return;
        }
        self.frames.push_back(cells);
        while self.frames.len() > keep {
            self.frames.pop_front();
        }
    }

    fn iter(&self) -> impl Iterator<Item = &Vec<f32>> {
        self.first.iter().chain(&self.frames).flatten()
    }

    fn len(&self) -> usize {
        self.first.iter().chain(&self.frames).map(Vec::len).sum()
    }
}

/// Points' materials followed frame by frame.
#[derive(Clone, Debug)]
pub struct MaterialTracker {
    clicked: Vec<Vec<f32>>,
    positives: Vec<Memory>,
    negatives: Vec<Memory>,
    options: TrackOptions,
}

impl MaterialTracker {
    /// A tracker of the materials of `clicked`, each point's unit
    /// descriptor on the frame it was clicked on.
    pub fn new(clicked: Vec<Vec<f32>>, options: TrackOptions) -> Self {
        let n = clicked.len();
        MaterialTracker {
            clicked,
            positives: vec![Memory::default(); n],
            negatives: vec![Memory::default(); n],
            options,
        }
    }

    /// Number of points followed.
    pub fn points(&self) -> usize {
        self.clicked.len()
    }

    /// Descriptors held in point `k`'s positive and negative memories.
    pub fn memory_len(&self, k: usize) -> (usize, usize) {
        (self.positives[k].len(), self.negatives[k].len())
    }

    /// Each point's margin for every cell of `frame` (row by row on its
    /// grid): its highest cosine to the point's positives minus its highest
    /// to the negatives (or the prior), which [`MaterialTracker::probability`]
    /// turns into a probability; then the memories updated from them. Call
    /// once a frame, in order. Margins keep their order where probabilities
    /// would round to 0 or 1.
    pub fn step(&mut self, frame: &CoarseDescriptors) -> Vec<Vec<f32>> {
        let scores: Vec<Vec<f32>> = (0..self.points()).map(|k| self.score(k, frame)).collect();
        if self.options.memory > 0 {
            self.remember(frame, &scores);
        }
        scores
    }

    /// The probability that a cell of this margin is the point's
    /// material: `sigmoid(margin / temperature)`.
    pub fn probability(&self, margin: f32) -> f32 {
        1.0 / (1.0 + (-margin / self.options.temperature.max(1e-6)).exp())
    }

    /// The margin a cell needs to be remembered as the point's material
    /// (its negative: as not), from [`TrackOptions::confident`].
    fn sure_margin(&self) -> f32 {
        let c = self.options.confident.clamp(0.5, 1.0 - 1e-6);
        self.options.temperature * (c / (1.0 - c)).ln()
    }

    /// Point `k`'s margin for every cell.
    fn score(&self, k: usize, frame: &CoarseDescriptors) -> Vec<f32> {
        let mut positives: Vec<&[f32]> = vec![&self.clicked[k]];
        positives.extend(self.positives[k].iter().map(Vec::as_slice));
        let mut negatives: Vec<&[f32]> = self.negatives[k].iter().map(Vec::as_slice).collect();
        for (other, memory) in self.positives.iter().enumerate() {
            if other != k {
                negatives.push(&self.clicked[other]);
                negatives.extend(memory.iter().map(Vec::as_slice));
            }
        }
        let best_positive = nearest(frame, &positives);
        let best_negative = if negatives.is_empty() {
            vec![self.options.prior; best_positive.len()]
        } else {
            nearest(frame, &negatives)
        };
        best_positive
            .iter()
            .zip(&best_negative)
            .map(|(p, n)| p - n)
            .collect()
    }

    /// Adds to each point's memories the cells it holds (probability at
    /// least `confident`, and no other point higher) and the cells it
    /// surely does not (at most `1 - confident`), up to `samples` of each
    /// spread evenly over the grid.
    fn remember(&mut self, frame: &CoarseDescriptors, margins: &[Vec<f32>]) {
        let grid = &frame.grid;
        let sure = self.sure_margin();
        for (k, mine) in margins.iter().enumerate() {
            let held: Vec<usize> = (0..mine.len())
                .filter(|&i| mine[i] >= sure && margins.iter().all(|other| other[i] <= mine[i]))
                .collect();
            let not: Vec<usize> = (0..mine.len()).filter(|&i| mine[i] <= -sure).collect();
            let pick = |cells: &[usize]| -> Vec<Vec<f32>> {
                spread(cells, self.options.samples)
                    .map(|i| grid.at(i).to_vec())
                    .collect()
            };
            let (held, not) = (pick(&held), pick(&not));
            self.positives[k].push(held, self.options.memory);
            self.negatives[k].push(not, self.options.memory);
        }
    }
}

/// Up to `n` of `cells`, evenly spaced through them.
fn spread(cells: &[usize], n: usize) -> impl Iterator<Item = usize> + '_ {
    let step = cells.len().div_ceil(n.max(1)).max(1);
    cells.iter().copied().step_by(step)
}

/// Per cell of `frame`, its highest cosine with any of `queries` (unit
/// vectors of the grid's length): one matrix product.
fn nearest(frame: &CoarseDescriptors, queries: &[&[f32]]) -> Vec<f32> {
    let grid = &frame.grid;
    let (cells, dim, q) = (grid.width * grid.height, grid.dim, queries.len());
    let bank: Vec<f32> = queries.iter().flat_map(|v| v.iter().copied()).collect();
    // Rows of cells at a time, so the products stay in cache and run in
    // parallel.
    const ROWS: usize = 256;
    let mut best = vec![f32::NEG_INFINITY; cells];
    best.par_chunks_mut(ROWS)
        .enumerate()
        .for_each(|(chunk, out)| {
            let start = chunk * ROWS;
            let rows = out.len();
            let mut product = vec![0f32; rows * q];
            // product[rows x q] = cells[rows x dim] * bank^T[dim x q].
            unsafe {
                matrixmultiply::sgemm(
                    rows,
                    dim,
                    q,
                    1.0,
                    grid.data[start * dim..].as_ptr(),
                    dim as isize,
                    1,
                    bank.as_ptr(),
                    1,
                    dim as isize,
                    0.0,
                    product.as_mut_ptr(),
                    q as isize,
                    1,
                );
            }
            for (o, row) in out.iter_mut().zip(product.chunks_exact(q)) {
                *o = row.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            }
        });
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptor::DescriptorMap;

    /// A grid of one row of 2-d unit descriptors at these angles (degrees).
    fn frame(angles: &[f32]) -> CoarseDescriptors {
        CoarseDescriptors {
            grid: DescriptorMap {
                width: angles.len(),
                height: 1,
                dim: 2,
                data: angles.iter().flat_map(|&a| at(a)).collect(),
            },
            width: angles.len(),
            height: 1,
        }
    }

    /// A unit 2-d vector at `deg` degrees.
    fn at(deg: f32) -> Vec<f32> {
        let r = deg.to_radians();
        vec![r.cos(), r.sin()]
    }

    fn sigmoid(x: f32) -> f32 {
        1.0 / (1.0 + (-x).exp())
    }

    #[test]
    fn without_memory_a_cell_is_scored_by_its_cosine_against_the_prior() {
        let options = TrackOptions::first_frame_only();
        let mut tracker = MaterialTracker::new(vec![at(0.0)], options);
        let margins = tracker.step(&frame(&[0.0, 30.0, 90.0]));
        let want = |deg: f32| sigmoid((deg.to_radians().cos() - 0.8) / options.temperature);
        for (&m, deg) in margins[0].iter().zip([0.0f32, 30.0, 90.0]) {
            assert!(
                (m - (deg.to_radians().cos() - 0.8)).abs() < 1e-6,
                "{m} at {deg}"
            );
            assert!(
                (tracker.probability(m) - want(deg)).abs() < 1e-5,
                "{m} at {deg}"
            );
        }
        tracker.step(&frame(&[0.0, 30.0, 90.0]));
        assert_eq!(tracker.memory_len(0), (0, 0));
    }

    #[test]
    fn the_memory_follows_a_material_whose_look_drifts() {
        // The material turns 10 degrees a frame from the click; the other
        // stays at 120 degrees (cells: 4 of each).
        let mut with = MaterialTracker::new(vec![at(0.0)], TrackOptions::default());
        let mut without = MaterialTracker::new(vec![at(0.0)], TrackOptions::first_frame_only());
        let mut last = (Vec::new(), Vec::new());
        for f in 0..6 {
            let a = 10.0 * f as f32;
            let cells = [a, a, a, a, 120.0, 120.0, 120.0, 120.0];
            last = (
                with.step(&frame(&cells)).remove(0),
                without.step(&frame(&cells)).remove(0),
            );
        }
        // At 50 degrees off the click the cosine (0.64) is under the prior:
        // alone, the click calls its own material "not"; the memory still
        // holds it, and still rejects the other.
        let p = |m: f32| with.probability(m);
        assert!(p(last.1[0]) < 0.5, "{:?}", last.1);
        assert!(p(last.0[0]) > 0.9 && p(last.0[4]) < 0.1, "{:?}", last.0);
        let (positives, negatives) = with.memory_len(0);
        assert!(positives > 0 && negatives > 0);
    }

    #[test]
    fn memories_are_bounded_and_other_points_are_negatives() {
        let options = TrackOptions {
            memory: 2,
            samples: 3,
            ..TrackOptions::default()
        };
        let mut tracker = MaterialTracker::new(vec![at(0.0), at(90.0)], options);
        let cells: Vec<f32> = (0..20).map(|i| if i < 10 { 0.0 } else { 90.0 }).collect();
        for _ in 0..5 {
            tracker.step(&frame(&cells));
        }
        // The first frame's three cells each way, kept for good, and the
        // newest two frames' after it.
        assert_eq!(tracker.memory_len(0), (9, 9));
        // A cell halfway between the clicks leans to neither.
        let halfway = tracker.score(0, &frame(&[45.0]))[0];
        assert!(halfway.abs() < 1e-4, "{halfway}");
        assert_eq!(
            spread(&[1, 2, 3, 4, 5, 6, 7], 3).collect::<Vec<_>>(),
            [1, 4, 7]
        );
    }
}
