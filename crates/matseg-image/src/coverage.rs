//! Where a plane is positive, block by block: the part of a material's
//! weight that shading and blending must compute. A 2D scene's weights are
//! sparse (a material is visible on 5-15% of the scene on average, though its
//! bounding box spans most of it), so the work follows the blocks instead of
//! the box.

use crate::plane::Plane;

/// Columns per block of a [`Coverage`].
pub const BLOCK: usize = 16;

/// For each row of a `width x height` plane, the set of [`BLOCK`]-column
/// blocks that hold a positive value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Coverage {
    width: usize,
    height: usize,
    /// 64-bit words per row of the block bit set.
    words: usize,
    /// Row by row, bit `b` of the row's words: block `b` is covered.
    bits: Vec<u64>,
}

impl Coverage {
    /// No block of a `width x height` plane; rows are added with
    /// [`Coverage::add_row`].
    pub fn empty(width: usize, height: usize) -> Self {
        let words = width.div_ceil(BLOCK).div_ceil(64);
        Self {
            width,
            height,
            words,
            bits: vec![0; words * height],
        }
    }

    /// Every block of a `width x height` plane.
    pub fn full(width: usize, height: usize) -> Self {
        let mut c = Self::empty(width, height);
        let blocks = width.div_ceil(BLOCK);
        for row in c.bits.chunks_exact_mut(c.words.max(1)).take(height) {
            for b in 0..blocks {
                row[b / 64] |= 1 << (b % 64);
            }
        }
        c
    }

    /// The blocks of `plane` that hold a value `> 0`, in one pass.
    pub fn of(plane: &Plane) -> Self {
        let mut c = Self::empty(plane.width, plane.height);
        for (y, row) in plane.data.chunks_exact(plane.width.max(1)).enumerate() {
            c.add_row(y, row);
        }
        c
    }

    /// Records row `y` of the plane (`width` values; rows may come in any
    /// order, each once). Inlined so that a caller compiled for AVX2 tests
    /// the blocks with it.
    #[inline(always)]
    pub fn add_row(&mut self, y: usize, row: &[f32]) {
        self.add_run(y, 0, row);
    }

    /// Records the values of row `y` from column `x0` (a multiple of
    /// [`BLOCK`]) on; the row's other columns keep what was recorded. Each
    /// block is recorded once.
    #[inline(always)]
    pub fn add_run(&mut self, y: usize, x0: usize, run: &[f32]) {
        // The whole block is tested at once: an OR of comparisons vectorises
        // (a floating-point maximum, NaN-aware, does not).
        let block_positive = |block: &[f32]| block.iter().fold(false, |any, &v| any | (v > 0.0));
        self.add_run_by(y, x0, run, block_positive);
    }

    /// Records a run of any kind of values: `block_positive` tells whether
    /// a block holds a positive value.
    #[inline(always)]
    pub fn add_run_by<T>(
        &mut self,
        y: usize,
        x0: usize,
        run: &[T],
        block_positive: impl Fn(&[T]) -> bool,
    ) {
        debug_assert!(x0.is_multiple_of(BLOCK), "runs start on a block");
        let mask = &mut self.bits[y * self.words..(y + 1) * self.words];
        // Each block's bit is gathered into a word held in a register and
        // stored once per 64 blocks: no branch on the test (block edges of
        // natural shapes are unpredictable) and no store per block.
        let mut b = x0 / BLOCK;
        let mut word = 0u64;
        let mut record = |positive: bool| {
            word |= u64::from(positive) << (b % 64);
            b += 1;
            if b.is_multiple_of(64) {
                mask[b / 64 - 1] |= word;
                word = 0;
            }
        };
        // Whole blocks apart, so that their test is compiled for 16 values.
        let blocks = run.chunks_exact(BLOCK);
        let tail = blocks.remainder();
        for block in blocks {
            let block: &[T; BLOCK] = block.try_into().expect("a whole block");
            record(block_positive(block));
        }
        if !tail.is_empty() {
            record(block_positive(tail));
        }
        if !b.is_multiple_of(64) {
            mask[b / 64] |= word;
        }
    }

    /// Width of the plane in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the plane in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Blocks per row.
    pub fn blocks_per_row(&self) -> usize {
        self.width.div_ceil(BLOCK)
    }

    /// Whether no block is covered.
    pub fn is_empty(&self) -> bool {
        self.bits.iter().all(|&w| w == 0)
    }

    /// The coverage of every pixel within `r` rows of a covered one: the
    /// rows a vertical filter of radius `r` reads to fill this coverage.
    pub fn dilated_rows(&self, r: usize) -> Self {
        let mut out = self.clone();
        // A coverage dilated by `c` rows, ORed with itself `t <= 2c + 1`
        // rows up and down, is dilated by `c + t` without a gap: radii 1,
        // 4, 13, ... reach `r` in a few passes of three rows each. Rows
        // past an edge read the edge row, which covers all they would.
        let (words, h) = (self.words, self.height);
        let mut reached = 0;
        let mut spread = self.bits.clone();
        while reached < r && h > 0 {
            let t = (2 * reached + 1).min(r - reached);
            spread.copy_from_slice(&out.bits);
            for y in 0..h {
                let (up, down) = (y.saturating_sub(t), (y + t).min(h - 1));
                for i in 0..words {
                    out.bits[y * words + i] |= spread[up * words + i] | spread[down * words + i];
                }
            }
            reached += t;
        }
        out
    }

    /// The coverage of every pixel within `r` rows and `r` columns of a
    /// covered one (whole blocks): what a separable filter of radius `r`
    /// can make positive.
    pub fn dilated(&self, r: usize) -> Self {
        let reach = r.div_ceil(BLOCK);
        let blocks = self.blocks_per_row();
        let mut wide = self.clone();
        let words = self.words.max(1);
        let mut before = vec![0u64; words];
        for out in wide.bits.chunks_exact_mut(words) {
            // Dilated by one block a step (`reach` is 1 for any kernel up
            // to 33 taps): each word ORed with itself moved one block
            // either way, the bit that crosses a word boundary carried.
            for _ in 0..reach {
                before.copy_from_slice(out);
                for (i, o) in out.iter_mut().enumerate() {
                    let below = if i > 0 { before[i - 1] >> 63 } else { 0 };
                    let above = before.get(i + 1).map_or(0, |w| w << 63);
                    *o |= (before[i] << 1) | below | (before[i] >> 1) | above;
                }
            }
            // No block past the row's last.
            if !blocks.is_multiple_of(64) {
                if let Some(last) = out.last_mut() {
                    *last &= (1u64 << (blocks % 64)) - 1;
                }
            }
        }
        wide.dilated_rows(r)
    }

    /// Whether row `y` has a covered block.
    #[inline]
    pub fn row_is_covered(&self, y: usize) -> bool {
        self.row(y).iter().any(|&w| w != 0)
    }

    /// The covered columns of row `y` as maximal runs `(x0, x1)` of
    /// consecutive covered blocks, left to right (`x1` clamped to the width).
    #[inline]
    pub fn runs(&self, y: usize) -> Runs<'_> {
        let words = self.row(y);
        Runs {
            words,
            index: 0,
            current: words.first().copied().unwrap_or(0),
            width: self.width,
        }
    }

    /// Row `y`'s block bit set: bit `b % 64` of word `b / 64` is block `b`.
    #[inline]
    pub fn row(&self, y: usize) -> &[u64] {
        &self.bits[y * self.words..(y + 1) * self.words]
    }
}

/// The runs of covered blocks of one row; see [`Coverage::runs`].
pub struct Runs<'a> {
    words: &'a [u64],
    /// The word being scanned.
    index: usize,
    /// Its bits not yet returned.
    current: u64,
    width: usize,
}

impl Iterator for Runs<'_> {
    type Item = (usize, usize);

    #[inline]
    fn next(&mut self) -> Option<(usize, usize)> {
        while self.current == 0 {
            self.index += 1;
            self.current = *self.words.get(self.index)?;
        }
        let start = self.index * 64 + self.current.trailing_zeros() as usize;
        // Bits at and above the run's start that are clear.
        let clear_above = !self.current & (!0u64 << self.current.trailing_zeros());
        let end = if clear_above != 0 {
            let e = clear_above.trailing_zeros();
            self.current &= !0u64 << e;
            self.index * 64 + e as usize
        } else {
            // The run goes on into the next words.
            self.index += 1;
            while self.words.get(self.index) == Some(&!0) {
                self.index += 1;
            }
            match self.words.get(self.index) {
                None => {
                    self.current = 0;
                    self.words.len() * 64
                }
                Some(&w) => {
                    let e = (!w).trailing_zeros();
                    self.current = w & (!0u64 << e);
                    self.index * 64 + e as usize
                }
            }
        };
        Some((start * BLOCK, (end * BLOCK).min(self.width)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The covered columns of row `y`, pixel by pixel.
    fn covered_columns(c: &Coverage, y: usize) -> Vec<usize> {
        c.runs(y).flat_map(|(a, b)| a..b).collect()
    }

    #[test]
    fn empty_until_a_positive_value() {
        let mut p = Plane::new(10, 8, 0.0);
        p.data[3] = -1.0;
        assert!(Coverage::of(&p).is_empty());
        p.data[5 * 10 + 3] = 1e-30;
        assert!(!Coverage::of(&p).is_empty());
        assert!(Coverage::full(0, 0).is_empty() && !Coverage::full(1, 1).is_empty());
    }

    #[test]
    fn runs_are_the_blocks_holding_positive_values() {
        // 70 blocks: the bit set spans two words, and one run crosses them.
        let w = 70 * BLOCK - 5;
        let mut p = Plane::new(w, 3, 0.0);
        let positive_blocks = [0usize, 1, 5, 62, 63, 64, 65, 69];
        for &b in &positive_blocks {
            p.data[w + b * BLOCK + 3] = 0.25;
        }
        p.data[2 * w + 40] = -1.0;
        let c = Coverage::of(&p);
        assert!(!c.row_is_covered(0) && c.row_is_covered(1) && !c.row_is_covered(2));
        let runs: Vec<_> = c.runs(1).collect();
        let b = |i: usize| i * BLOCK;
        assert_eq!(
            runs,
            vec![(0, b(2)), (b(5), b(6)), (b(62), b(66)), (b(69), w)]
        );
        let want: Vec<usize> = positive_blocks
            .iter()
            .flat_map(|&i| b(i)..b(i + 1).min(w))
            .collect();
        assert_eq!(covered_columns(&c, 1), want);
        assert_eq!(c.runs(0).count(), 0);

        let full = Coverage::full(w, 3);
        assert_eq!(full.runs(2).collect::<Vec<_>>(), vec![(0, w)]);
        // A run to the last block of a row whose last word is full.
        let whole_words = Coverage::full(128 * BLOCK, 1);
        assert_eq!(
            whole_words.runs(0).collect::<Vec<_>>(),
            vec![(0, 128 * BLOCK)]
        );
    }

    /// Rows recorded whole or in runs from any block (across the 64-block
    /// words, to a cut last block) cover exactly the blocks holding a
    /// positive value.
    #[test]
    fn runs_recorded_in_parts_cover_the_positive_blocks() {
        let w = 130 * BLOCK - 7;
        let mut p = Plane::new(w, 4, 0.0);
        for (i, v) in p.data.iter_mut().enumerate() {
            // Positive in scattered blocks, some of them next to each other.
            if (i / BLOCK) % 7 == 3 || (i / BLOCK).is_multiple_of(11) || i % 97 == 5 {
                *v = 0.5;
            }
        }
        let mut whole = Coverage::empty(w, 4);
        for y in 0..4 {
            for b in 0..w.div_ceil(BLOCK) {
                let block = &p.data[y * w..(y + 1) * w][b * BLOCK..((b + 1) * BLOCK).min(w)];
                if block.iter().any(|&v| v > 0.0) {
                    whole.bits[y * whole.words + b / 64] |= 1 << (b % 64);
                }
            }
        }
        assert_eq!(Coverage::of(&p), whole);
        for cuts in [
            vec![0, w],
            vec![0, 60 * BLOCK, 70 * BLOCK, w],
            vec![0, BLOCK, 127 * BLOCK, 128 * BLOCK, w],
        ] {
            let mut parts = Coverage::empty(w, 4);
            for y in 0..4 {
                for pair in cuts.windows(2) {
                    parts.add_run(y, pair[0], &p.data[y * w + pair[0]..y * w + pair[1]]);
                }
            }
            assert_eq!(parts, whole, "{cuts:?}");
        }
    }

    /// Dilation equals the direct definition: a block is covered when a
    /// covered block lies within `r` rows and `r.div_ceil(BLOCK)` blocks.
    #[test]
    fn dilations_match_their_definition() {
        // 70 blocks (two words per row) and a single-word width.
        for w in [70 * BLOCK - 5, 9 * BLOCK + 1] {
            let h = 23;
            let mut p = Plane::new(w, h, 0.0);
            for (x, y) in [
                (0, 0),
                (63 * BLOCK, 5),
                (64 * BLOCK + 2, 11),
                (w - 1, 22),
                (5, 13),
            ] {
                if x < w {
                    p.data[y * w + x] = 1.0;
                }
            }
            let c = Coverage::of(&p);
            let blocks = c.blocks_per_row();
            let covered =
                |c: &Coverage, b: usize, y: usize| c.row(y)[b / 64] & (1 << (b % 64)) != 0;
            for r in [0, 1, 2, 4, 5, 10, 17, 30] {
                let (rows, both) = (c.dilated_rows(r), c.dilated(r));
                let reach = r.div_ceil(BLOCK);
                for y in 0..h {
                    for b in 0..blocks {
                        let near = |reach: usize| {
                            (y.saturating_sub(r)..(y + r + 1).min(h)).any(|sy| {
                                (b.saturating_sub(reach)..(b + reach + 1).min(blocks))
                                    .any(|sb| covered(&c, sb, sy))
                            })
                        };
                        assert_eq!(covered(&rows, b, y), near(0), "rows r {r} ({b}, {y})");
                        assert_eq!(covered(&both, b, y), near(reach), "both r {r} ({b}, {y})");
                    }
                    // Nothing past the last block.
                    let past = (blocks..c.words * 64).any(|b| covered(&both, b, y));
                    assert!(!past, "r {r} row {y}");
                }
            }
        }
    }

    #[test]
    fn dilation_covers_every_row_within_the_radius() {
        let mut p = Plane::new(40, 9, 0.0);
        p.data[4 * 40 + 20] = 1.0;
        let c = Coverage::of(&p).dilated_rows(2);
        let covered: Vec<bool> = (0..9).map(|y| c.row_is_covered(y)).collect();
        assert_eq!(
            covered,
            [false, false, true, true, true, true, true, false, false]
        );
        assert_eq!(covered_columns(&c, 6), (16..32).collect::<Vec<_>>());
    }
}
