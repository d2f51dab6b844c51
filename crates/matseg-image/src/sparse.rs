//! A float plane stored only on some blocks and zero everywhere else: the
//! type of a 2D scene's material weights, each positive on a few percent of
//! the scene, so that making, blending and quantising them never touches
//! (or zeroes) the rest of the plane.

use crate::coverage::{Coverage, Runs};
use crate::plane::Plane;

/// A `width x height` plane whose values are kept only on the blocks of
/// [`SparsePlane::stored`] (those of a [`Coverage`]); every other value is
/// exactly zero. Each row's stored blocks lie one after another in memory,
/// so a run of consecutive stored blocks is one slice.
#[derive(Clone, Debug, PartialEq)]
pub struct SparsePlane {
    stored: Coverage,
    /// Where each row's values start in `data`; one more entry than rows.
    starts: Vec<usize>,
    data: Vec<f32>,
}

impl SparsePlane {
    /// Zeros on the blocks `stored` covers.
    pub fn zeros(stored: Coverage) -> Self {
        let starts = row_starts(&stored);
        let data = vec![0.0; starts[stored.height()]];
        Self {
            stored,
            starts,
            data,
        }
    }

    /// The plane stored on the blocks `stored` covers, its values made row
    /// by row: `row(y, data)` appends row `y`'s stored runs, left to right,
    /// to `data` (nothing is zeroed first).
    ///
    /// # Panics
    /// When a row appends other than its stored count of values.
    pub fn from_rows(stored: Coverage, mut row: impl FnMut(usize, &mut Vec<f32>)) -> Self {
        let starts = row_starts(&stored);
        // Room for every value at once: growing would copy them over again.
        let mut data = Vec::with_capacity(starts[stored.height()]);
        for y in 0..stored.height() {
            row(y, &mut data);
            assert_eq!(data.len(), starts[y + 1], "row {y}'s stored values");
        }
        Self {
            stored,
            starts,
            data,
        }
    }

    /// A plane stored whole (every block), taking `plane`'s values as they are.
    pub fn dense(plane: Plane) -> Self {
        let (w, h) = (plane.width, plane.height);
        Self {
            stored: Coverage::full(w, h),
            starts: (0..=h).map(|y| y * w).collect(),
            data: plane.data,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.stored.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.stored.height()
    }

    /// The blocks whose values are kept (the rest are zero).
    pub fn stored(&self) -> &Coverage {
        &self.stored
    }

    /// Row `y`'s values, to take runs from left to right (each within
    /// stored blocks): see [`Pieces::take`].
    pub fn pieces(&self, y: usize) -> Pieces<'_, &[f32]> {
        Pieces::new(
            &self.stored,
            y,
            &self.data[self.starts[y]..self.starts[y + 1]],
        )
    }

    /// Row `y`'s stored values: its stored blocks' values one block after
    /// another, left to right (`BLOCK` values each, fewer for a last block
    /// cut by the width).
    pub fn row_mut(&mut self, y: usize) -> &mut [f32] {
        &mut self.data[self.starts[y]..self.starts[y + 1]]
    }

    /// Row `y`'s stored runs of consecutive blocks, left to right, as
    /// `(x0, values)`.
    pub fn row_runs(&self, y: usize) -> impl Iterator<Item = (usize, &[f32])> {
        let mut pieces = self.pieces(y);
        self.stored
            .runs(y)
            .map(move |(x0, x1)| (x0, pieces.take(x0, x1)))
    }

    /// Row `y`'s stored runs, as [`SparsePlane::row_runs`], to write.
    pub fn row_runs_mut(&mut self, y: usize) -> impl Iterator<Item = (usize, &mut [f32])> {
        let row = &mut self.data[self.starts[y]..self.starts[y + 1]];
        let mut pieces = Pieces::new(&self.stored, y, row);
        self.stored
            .runs(y)
            .map(move |(x0, x1)| (x0, pieces.take(x0, x1)))
    }

    /// The whole plane, zeros included.
    pub fn to_plane(&self) -> Plane {
        let w = self.width();
        let mut plane = Plane::new(w, self.height(), 0.0);
        for (y, row) in plane.data.chunks_exact_mut(w.max(1)).enumerate() {
            for (x0, run) in self.row_runs(y) {
                row[x0..x0 + run.len()].copy_from_slice(run);
            }
        }
        plane
    }
}

/// Where each row's stored values start, one after another, and (last)
/// their total.
fn row_starts(stored: &Coverage) -> Vec<usize> {
    let mut starts = Vec::with_capacity(stored.height() + 1);
    let mut len = 0;
    for y in 0..stored.height() {
        starts.push(len);
        len += stored.runs(y).map(|(x0, x1)| x1 - x0).sum::<usize>();
    }
    starts.push(len);
    starts
}

/// Runs of one row of a [`SparsePlane`], taken left to right: the values
/// as `&[f32]` or `&mut [f32]` (`S`). Walking the row's stored runs
/// alongside, it finds each run's values without counting blocks.
pub struct Pieces<'a, S> {
    y: usize,
    stored: Runs<'a>,
    /// The row's values from column `at` on.
    rest: S,
    at: usize,
    /// End of the stored run that holds column `at`.
    end: usize,
}

/// A slice of values that [`Pieces`] can cut.
pub trait Values: Default {
    /// The first `n` values and the rest.
    fn cut(self, n: usize) -> (Self, Self);
}

impl Values for &[f32] {
    fn cut(self, n: usize) -> (Self, Self) {
        self.split_at(n)
    }
}

impl Values for &mut [f32] {
    fn cut(self, n: usize) -> (Self, Self) {
        self.split_at_mut(n)
    }
}

impl<'a, S: Values> Pieces<'a, S> {
    fn new(stored: &'a Coverage, y: usize, row: S) -> Self {
        Self {
            y,
            stored: stored.runs(y),
            rest: row,
            at: 0,
            end: 0,
        }
    }

    /// The values of columns `x0..x1`, which lie right of every run taken
    /// before and within one run of stored blocks.
    ///
    /// # Panics
    /// When they do not.
    #[inline]
    pub fn take(&mut self, x0: usize, x1: usize) -> S {
        while x1 > self.end {
            // On to the next stored run: drop what is left of this one.
            let left = self.end - self.at;
            self.rest = std::mem::take(&mut self.rest).cut(left).1;
            let Some((s0, s1)) = self.stored.next() else {
                not_stored(self.y, x0, x1)
            };
            (self.at, self.end) = (s0, s1);
        }
        if x0 < self.at || x0 >= x1 {
            not_stored(self.y, x0, x1);
        }
        let tail = std::mem::take(&mut self.rest).cut(x0 - self.at).1;
        let (piece, rest) = tail.cut(x1 - x0);
        (self.rest, self.at) = (rest, x1);
        piece
    }
}

/// The panic of a run that is not all stored (kept out of line, so that
/// the check inlines).
#[cold]
#[inline(never)]
fn not_stored(y: usize, x0: usize, x1: usize) -> ! {
    panic!("columns {x0}..{x1} of row {y} are not stored, or not taken left to right")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coverage::BLOCK;

    /// A plane of distinct positive values on the blocks of `stored`.
    fn numbered(stored: &Coverage) -> (SparsePlane, Plane) {
        let (w, h) = (stored.width(), stored.height());
        let mut sparse = SparsePlane::zeros(stored.clone());
        let mut plane = Plane::new(w, h, 0.0);
        for y in 0..h {
            for (x0, run) in sparse.row_runs_mut(y) {
                for (i, v) in run.iter_mut().enumerate() {
                    *v = (1 + y * w + x0 + i) as f32;
                    plane.data[y * w + x0 + i] = *v;
                }
            }
        }
        (sparse, plane)
    }

    #[test]
    fn runs_read_back_what_was_written_and_the_rest_is_zero() {
        // 70 blocks (two words a row), the last one 11 columns wide.
        let w = 70 * BLOCK - 5;
        let mut p = Plane::new(w, 3, 0.0);
        for (y, blocks) in [(0, &[0usize, 1, 5][..]), (2, &[3, 62, 63, 64, 65, 69])] {
            for &b in blocks {
                p.data[y * w + b * BLOCK] = 1.0;
            }
        }
        let stored = Coverage::of(&p);
        let (sparse, plane) = numbered(&stored);
        // Every value, the zeros outside the stored blocks included.
        assert_eq!(sparse.to_plane(), plane);
        // Runs inside and across stored blocks, past a word's end, to the
        // row's narrower last block, skipping whole stored runs.
        for (y, runs) in [
            (
                0,
                &[(3, 9), (10, 2 * BLOCK), (5 * BLOCK + 2, 5 * BLOCK + 3)][..],
            ),
            (2, &[(62 * BLOCK + 7, 66 * BLOCK), (69 * BLOCK, w)]),
        ] {
            let mut pieces = sparse.pieces(y);
            for &(x0, x1) in runs {
                let want = &plane.data[y * w + x0..y * w + x1];
                assert_eq!(pieces.take(x0, x1), want, "row {y}, {x0}..{x1}");
            }
        }
        // A row's stored values, written in place, are its stored blocks'.
        let mut written = sparse.clone();
        written.row_mut(2).fill(-1.0);
        let mut want = plane.clone();
        for (x0, x1) in sparse.stored().runs(2) {
            want.data[2 * w + x0..2 * w + x1].fill(-1.0);
        }
        assert_eq!(written.to_plane(), want);
        assert!(sparse.row_runs(1).next().is_none());
    }

    #[test]
    fn a_run_outside_the_stored_blocks_is_refused() {
        let mut p = Plane::new(4 * BLOCK, 2, 0.0);
        p.data[BLOCK] = 1.0;
        p.data[3 * BLOCK] = 1.0;
        let sparse = SparsePlane::zeros(Coverage::of(&p));
        assert_eq!(sparse.pieces(0).take(BLOCK, 2 * BLOCK).len(), BLOCK);
        // Across a gap, before the first stored block, on an empty row,
        // out of order.
        for (y, runs) in [
            (0, &[(BLOCK, 3 * BLOCK + 1)][..]),
            (0, &[(0, 1)]),
            (1, &[(BLOCK, BLOCK + 1)]),
            (0, &[(3 * BLOCK, 3 * BLOCK + 2), (BLOCK, BLOCK + 1)]),
        ] {
            let refused = std::panic::catch_unwind(|| {
                let mut pieces = sparse.pieces(y);
                runs.iter()
                    .map(|&(x0, x1)| pieces.take(x0, x1).len())
                    .sum::<usize>()
            });
            assert!(refused.is_err(), "row {y}, {runs:?}");
        }
        assert_eq!(sparse.to_plane().get(2 * BLOCK, 0), 0.0);
    }

    /// Rows appended run by run equal the plane written in place; a row
    /// that appends the wrong count is refused.
    #[test]
    fn planes_made_row_by_row_equal_planes_written_in_place() {
        let w = 70 * BLOCK - 5;
        let mut p = Plane::new(w, 3, 0.0);
        for b in [0usize, 1, 5, 62, 63, 64, 69] {
            p.data[2 * w + b * BLOCK] = 1.0;
        }
        p.data[3] = 1.0;
        let stored = Coverage::of(&p);
        let (written, plane) = numbered(&stored);
        let runs = stored.clone();
        let made = SparsePlane::from_rows(stored, |y, data| {
            for (x0, x1) in runs.runs(y) {
                data.extend_from_slice(&plane.data[y * w + x0..y * w + x1]);
            }
        });
        assert_eq!(made, written);
        let short = std::panic::catch_unwind(|| {
            SparsePlane::from_rows(Coverage::of(&p), |y, data| data.extend(vec![0.5; y]))
        });
        assert!(short.is_err(), "a row's count is checked");
    }

    #[test]
    fn a_dense_plane_keeps_its_values() {
        let plane = Plane::from_vec(3, 2, vec![0.5, 0.0, 1.0, 0.25, 0.75, 0.0]);
        let sparse = SparsePlane::dense(plane.clone());
        assert_eq!(sparse.to_plane(), plane);
        assert_eq!(sparse.pieces(1).take(1, 3), &[0.75, 0.0]);
        let runs: Vec<(usize, Vec<f32>)> =
            sparse.row_runs(0).map(|(x, r)| (x, r.to_vec())).collect();
        assert_eq!(runs, vec![(0, vec![0.5, 0.0, 1.0])]);
    }
}
