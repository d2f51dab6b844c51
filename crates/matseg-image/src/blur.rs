//! Separable Gaussian blur with OpenCV's kernel-size-to-sigma rule.

use crate::coverage::Coverage;
use crate::plane::Plane;

/// The sigma OpenCV uses for a kernel of odd size `ksize` when none is given:
/// `0.3 * ((ksize - 1) / 2 - 1) + 0.8`.
pub fn sigma_for_kernel(ksize: usize) -> f32 {
    0.3 * ((ksize as f32 - 1.0) * 0.5 - 1.0) + 0.8
}

/// Normalised 1D Gaussian taps for an odd `ksize`.
pub fn gaussian_kernel(ksize: usize) -> Vec<f32> {
    assert!(ksize % 2 == 1, "Gaussian kernel size must be odd");
    let sigma = sigma_for_kernel(ksize) as f64;
    let r = (ksize / 2) as f64;
    let taps: Vec<f64> = (0..ksize)
        .map(|i| {
            let d = i as f64 - r;
            (-d * d / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let total: f64 = taps.iter().sum();
    taps.iter().map(|t| (t / total) as f32).collect()
}

/// Index `i` (may be outside `0..n`) reflected into range without repeating the
/// edge pixel (OpenCV's default `BORDER_REFLECT_101`).
fn reflect101(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let n = n as isize;
    // Within one reflection of the range (every call the blurs make but
    // for planes narrower than their kernel): no division.
    if (0..n).contains(&i) {
        return i as usize;
    }
    if (1 - n..0).contains(&i) {
        return -i as usize;
    }
    if (n..2 * n - 1).contains(&i) {
        return (2 * (n - 1) - i) as usize;
    }
    let period = 2 * (n - 1);
    let mut j = i.rem_euclid(period);
    if j >= n {
        j = period - j;
    }
    j as usize
}

/// Writes `k0 * base[centre + x] + sum over pairs (k, a, b) of k *
/// (base[a + x] + base[b + x])` to `out[x]` for every `x` of `columns`
/// (the pairs name rows of `base` by where they start, so a blur keeps them
/// from row to row without borrowing); also compiled for AVX2, picked at
/// run time when the CPU has it.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn symmetric_taps(
    out: &mut [f32],
    base: &[f32],
    (centre, k0): (usize, f32),
    pairs: &[(f32, usize, usize)],
    columns: std::ops::Range<usize>,
) {
    // Columns in steps of 32, then 16, then one: each step keeps its sums
    // in registers across the taps (the same additions in the same order
    // as tap by tap over the whole row, so the same values). A sum waits
    // on its previous addition, so wide steps keep more sums in flight.
    let mut x = columns.start;
    while x + 32 <= columns.end {
        taps_step::<32>(&mut out[x..x + 32], base, (centre, k0), pairs, x);
        x += 32;
    }
    while x + 16 <= columns.end {
        taps_step::<16>(&mut out[x..x + 16], base, (centre, k0), pairs, x);
        x += 16;
    }
    for x in x..columns.end {
        taps_step::<1>(&mut out[x..x + 1], base, (centre, k0), pairs, x);
    }
}

/// One step of [`symmetric_taps`]: `LANES` columns from `at`.
#[inline(always)]
fn taps_step<const LANES: usize>(
    out: &mut [f32],
    base: &[f32],
    (centre, k0): (usize, f32),
    pairs: &[(f32, usize, usize)],
    at: usize,
) {
    let mut sum = [0f32; LANES];
    for (s, &c) in sum.iter_mut().zip(&base[centre + at..][..LANES]) {
        *s = k0 * c;
    }
    for &(k, a, b) in pairs {
        let (a, b) = (&base[a + at..][..LANES], &base[b + at..][..LANES]);
        for j in 0..LANES {
            sum[j] += k * (a[j] + b[j]);
        }
    }
    out.copy_from_slice(&sum);
}

/// Blurs a plane with an odd Gaussian kernel of size `ksize` (1 = copy).
pub fn gaussian_blur(src: &Plane, ksize: usize) -> Plane {
    let (w, h) = (src.width, src.height);
    let mut out = Vec::with_capacity(w * h);
    gaussian_blur_covered(
        w,
        h,
        ksize,
        &Coverage::full(w, h),
        |y, x0, run| run.copy_from_slice(&src.data[y * w + x0..][..run.len()]),
        |_, row| out.extend_from_slice(row),
    );
    Plane::from_vec(w, h, out)
}

/// Blurs the `width x height` plane whose columns `x0..x0 + run.len()` of
/// row `y` `source(y, x0, run)` writes, with an odd Gaussian kernel of size
/// `ksize` (1 = none) and reflected borders, computing only the blocks
/// `coverage` covers: each row with a covered block goes to `emit(y, row)`
/// in order, its covered columns exactly as the whole blur has them (the
/// rest of `row` is unspecified). Source rows are asked for in order, only
/// where the blur reads them (the covered blocks and `ksize / 2` columns
/// either side, within `ksize / 2` rows); the horizontal pass keeps `ksize`
/// rows.
pub fn gaussian_blur_covered(
    width: usize,
    height: usize,
    ksize: usize,
    coverage: &Coverage,
    mut source: impl FnMut(usize, usize, &mut [f32]),
    mut emit: impl FnMut(usize, &[f32]),
) {
    let mut blur = CoveredBlur::new(width, height, ksize, coverage);
    for y in 0..height {
        if let Some(row) = blur.row(y, &mut source) {
            emit(y, row);
        }
    }
}

/// [`gaussian_blur_covered`] one output row at a time, for callers that
/// stream several blurs side by side: rows are asked for in increasing
/// order (any may be skipped).
pub struct CoveredBlur<'a> {
    width: usize,
    height: usize,
    r: usize,
    taps: Vec<f32>,
    coverage: &'a Coverage,
    /// The rows and blocks the horizontal pass computes.
    read: Coverage,
    /// The last `2r + 1` rows of the horizontal pass.
    ring: Vec<f32>,
    padded: Vec<f32>,
    out: Vec<f32>,
    /// The tap pairs of a pass: weight and where the two rows start.
    pairs: Vec<(f32, usize, usize)>,
    /// The next source row the horizontal pass takes.
    next: usize,
}

impl<'a> CoveredBlur<'a> {
    /// The blur of a `width x height` plane with an odd kernel of size
    /// `ksize`, on the blocks `coverage` covers.
    pub fn new(width: usize, height: usize, ksize: usize, coverage: &'a Coverage) -> Self {
        let r = if width == 0 { 0 } else { ksize / 2 };
        let slots = 2 * r + 1;
        Self {
            width,
            height,
            r,
            taps: gaussian_kernel(ksize),
            coverage,
            read: coverage.dilated_rows(r),
            ring: vec![0.0; if r == 0 { 0 } else { slots * width }],
            padded: vec![0.0; width + 2 * r],
            out: vec![0.0; width],
            pairs: Vec::with_capacity(r),
            next: 0,
        }
    }

    /// Row `y` of the blur, its covered columns exact, or `None` when the
    /// row has no covered block; `source(y, x0, run)` writes columns `x0..x0
    /// + run.len()` of source row `y`.
    pub fn row(
        &mut self,
        y: usize,
        mut source: impl FnMut(usize, usize, &mut [f32]),
    ) -> Option<&[f32]> {
        let (w, h, r) = (self.width, self.height, self.r);
        if r == 0 {
            if !self.coverage.row_is_covered(y) {
                return None;
            }
            for (x0, x1) in self.coverage.runs(y) {
                source(y, x0, &mut self.out[x0..x1]);
            }
            return Some(&self.out);
        }
        let taps = &self.taps;
        let slots = 2 * r + 1;
        // Horizontal pass, into a ring of the last 2r + 1 rows: pad each
        // source row by reflection, then add mirrored taps in pairs (the
        // kernel is symmetric), on the columns any output row within r rows
        // covers.
        while self.next < h && self.next <= y + r {
            let next = self.next;
            self.next += 1;
            if !self.read.row_is_covered(next) {
                continue;
            }
            // The columns the taps read: each run and r either side (the
            // reflected border columns lie within r of a run at the border).
            let padded = &mut self.padded;
            let (mut first, mut last) = (w, 0);
            for (x0, x1) in self.read.runs(next) {
                let (a, b) = (x0.saturating_sub(r), (x1 + r).min(w));
                source(next, a, &mut padded[r + a..r + b]);
                (first, last) = (first.min(x0), x1);
            }
            // Reflected columns, on the sides where some run's taps reach
            // past the border.
            if first < r {
                for i in 0..r {
                    padded[i] = padded[r + reflect101(i as isize - r as isize, w)];
                }
            }
            if last + r > w {
                for i in 0..r {
                    padded[r + w + i] = padded[r + reflect101((w + i) as isize, w)];
                }
            }
            self.pairs.clear();
            self.pairs.extend((0..r).map(|t| (taps[t], t, 2 * r - t)));
            let slot = &mut self.ring[(next % slots) * w..][..w];
            for (x0, x1) in self.read.runs(next) {
                symmetric_taps(slot, padded, (r, taps[r]), &self.pairs, x0..x1);
            }
        }
        if !self.coverage.row_is_covered(y) {
            return None;
        }
        // Vertical pass: a weighted sum of ring rows (reflected rows stay
        // within r rows of y, so inside the ring). Away from the borders
        // rows y - r..=y + r fill the ring's slots in turn from that of
        // y - r.
        let yi = y as isize;
        self.pairs.clear();
        let centre = if y >= r && y + r < h {
            // Where row y - r + k starts, for k in 0..=2r.
            let first = (y - r) % slots;
            let row = |k: usize| {
                let slot = first + k;
                (if slot >= slots { slot - slots } else { slot }) * w
            };
            self.pairs
                .extend((0..r).map(|t| (taps[t], row(t), row(2 * r - t))));
            row(r)
        } else {
            let row = |y: isize| (reflect101(y, h) % slots) * w;
            self.pairs.extend((0..r).map(|t| {
                let d = (r - t) as isize;
                (taps[t], row(yi - d), row(yi + d))
            }));
            row(yi)
        };
        for (x0, x1) in self.coverage.runs(y) {
            symmetric_taps(
                &mut self.out,
                &self.ring,
                (centre, taps[r]),
                &self.pairs,
                x0..x1,
            );
        }
        Some(&self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opencv_sigma_rule() {
        assert!((sigma_for_kernel(3) - 0.8).abs() < 1e-6);
        assert!((sigma_for_kernel(5) - 1.1).abs() < 1e-6);
        assert!((sigma_for_kernel(9) - 1.7).abs() < 1e-6);
    }

    #[test]
    fn kernel_is_normalised_and_symmetric() {
        for k in [3, 5, 7, 9, 21] {
            let taps = gaussian_kernel(k);
            assert!((taps.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            for i in 0..k {
                assert!((taps[i] - taps[k - 1 - i]).abs() < 1e-7);
            }
        }
    }

    /// The blur on covered blocks equals a direct 2D convolution there.
    #[test]
    fn covered_blur_equals_the_direct_convolution_on_covered_blocks() {
        let (w, h) = (73, 23);
        let src = Plane::from_vec(
            w,
            h,
            (0..w * h)
                .map(|i| ((i * 37) % 101) as f32 / 100.0)
                .collect(),
        );
        // Covered: one pixel's block near the top edge, one in the middle
        // and one block at the bottom right.
        let mut mask = Plane::new(w, h, 0.0);
        for (x, y) in [(3, 0), (20, 11), (40, 22)] {
            mask.data[y * w + x] = 1.0;
        }
        let coverage = Coverage::of(&mask);
        for k in [1, 3, 9, 21] {
            let taps = gaussian_kernel(k);
            let r = (k / 2) as isize;
            let direct = |x: usize, y: usize| -> f32 {
                let mut sum = 0.0f64;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let sx = reflect101(x as isize + dx, w);
                        let sy = reflect101(y as isize + dy, h);
                        let t = taps[(dx + r) as usize] as f64 * taps[(dy + r) as usize] as f64;
                        sum += t * src.get(sx, sy) as f64;
                    }
                }
                sum as f32
            };
            let (mut rows, mut asked) = (Vec::new(), Vec::new());
            gaussian_blur_covered(
                w,
                h,
                k,
                &coverage,
                |y, x0, run: &mut [f32]| {
                    asked.push((y, x0, x0 + run.len()));
                    run.copy_from_slice(&src.data[y * w + x0..][..run.len()]);
                },
                |y, row| {
                    for x in coverage.runs(y).flat_map(|(a, b)| a..b) {
                        assert!((row[x] - direct(x, y)).abs() < 1e-5, "k {k} ({x}, {y})");
                    }
                    rows.push(y);
                },
            );
            assert_eq!(rows, vec![0, 11, 22], "k {k}");
            // Source rows are read in order, only near covered rows, and
            // only on the covered blocks and k / 2 columns either side.
            assert!(
                asked.windows(2).all(|p| p[0].0 <= p[1].0),
                "k {k}: {asked:?}"
            );
            let near = |y: usize| rows.iter().any(|&c| c.abs_diff(y) <= k / 2);
            let column_near = |x: usize| {
                (0..h).any(|c| {
                    coverage
                        .runs(c)
                        .any(|(a, b)| x + k / 2 >= a && x < b + k / 2)
                })
            };
            let blocks_near = |x0: usize, x1: usize| (x0..x1).all(column_near);
            assert!(
                asked
                    .iter()
                    .all(|&(y, x0, x1)| near(y) && blocks_near(x0, x1)),
                "k {k}: {asked:?}"
            );
        }
        // The whole blur has the covered blur's values, bit for bit.
        let whole = gaussian_blur(&src, 9);
        let mut checked = 0;
        gaussian_blur_covered(
            w,
            h,
            9,
            &coverage,
            |y, x0, run| run.copy_from_slice(&src.data[y * w + x0..][..run.len()]),
            |y, row| {
                for x in coverage.runs(y).flat_map(|(a, b)| a..b) {
                    assert_eq!(row[x], whole.get(x, y), "({x}, {y})");
                    checked += 1;
                }
            },
        );
        // Three covered blocks of 16 columns each.
        assert_eq!(checked, 3 * 16);
    }

    #[test]
    fn reflect101_mirrors_without_the_edge() {
        let got: Vec<usize> = (-3..8).map(|i| reflect101(i, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        // Several reflections away (a plane narrower than the kernel).
        let got: Vec<usize> = (-9..13).map(|i| reflect101(i, 3)).collect();
        let period = [0, 1, 2, 1];
        let want: Vec<usize> = (-9..13isize)
            .map(|i| period[i.rem_euclid(4) as usize])
            .collect();
        assert_eq!(got, want);
        assert_eq!(reflect101(-7, 1), 0);
    }

    #[test]
    fn blur_keeps_constants_and_mass() {
        let flat = Plane::new(7, 5, 0.25);
        let b = gaussian_blur(&flat, 5);
        assert!(b.data.iter().all(|v| (v - 0.25).abs() < 1e-6));

        // A centred impulse spreads into the outer product of the taps.
        let mut impulse = Plane::new(9, 9, 0.0);
        impulse.data[4 * 9 + 4] = 1.0;
        let b = gaussian_blur(&impulse, 3);
        let taps = gaussian_kernel(3);
        assert!((b.get(3, 4) - taps[0] * taps[1]).abs() < 1e-6);
        assert!((b.get(4, 4) - taps[1] * taps[1]).abs() < 1e-6);
        assert!((b.sum() - 1.0).abs() < 1e-5);
    }
}
