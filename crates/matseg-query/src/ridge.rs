//! A linear classifier fitted on the fly on a photo's rows: ridge
//! regression of targets in -0.5..0.5 on each row's values and a
//! constant. A row's values may come in blocks of columns held apart (the
//! descriptors, the colours), so no joined copy of the rows is made. The
//! rows' regularised Gram matrix is factorised once per photo
//! ([`Ridge::new`], Cholesky in f64); each fit then solves with its few
//! weighted extra rows (clicks) by the Woodbury identity, a handful of
//! triangular solves instead of a new factorisation.

use rayon::prelude::*;

/// A block of columns of every row: `width` values a row, row by row.
#[derive(Clone, Copy)]
pub struct Columns<'a> {
    /// The values.
    pub values: &'a [f32],
    /// Values a row.
    pub width: usize,
}

/// A photo's rows, each with a constant 1 appended, ready to be fitted:
/// the Cholesky factor of their Gram matrix plus `lambda`.
pub struct Ridge {
    /// Values a row (without the constant).
    dim: usize,
    /// The lower Cholesky factor of `Gram + lambda I`, `(dim + 1) x (dim
    /// + 1)`, row by row.
    factor: Vec<f64>,
}

/// A row the fit weighs more than the photo's: a click's values (every
/// block's, joined), its weight and its target (0.5 wanted, -0.5 not).
pub struct WeightedRow<'a> {
    /// The values (`dim` of them).
    pub values: &'a [f32],
    /// How many photo rows it counts as.
    pub weight: f64,
    /// Its target.
    pub target: f64,
}

/// Rows summed in f32 before their sum joins the f64 total.
const ROWS_A_CHUNK: usize = 256;

impl Ridge {
    /// The rows whose columns are `blocks` (each block of as many rows),
    /// to be fitted with `lambda` times the squared weights added.
    pub fn new(blocks: &[Columns<'_>], lambda: f64) -> Self {
        let dim: usize = blocks.iter().map(|b| b.width).sum();
        let side = dim + 1;
        let mut factor = gram(blocks);
        for i in 0..side {
            factor[i * side + i] += lambda;
        }
        cholesky(&mut factor, side);
        Self { dim, factor }
    }

    /// Values a row, without the constant.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The weights (a value per column, in the blocks' order, then the
    /// constant's) that best map the rows (`blocks`, as given to
    /// [`Ridge::new`]) to `targets`, and each extra row to its target.
    pub fn fit(
        &self,
        blocks: &[Columns<'_>],
        targets: &[f32],
        extra: &[WeightedRow<'_>],
    ) -> Vec<f32> {
        // The right-hand side: the rows and the extra rows times their
        // targets.
        let mut b = weighted_sums(blocks, targets);
        let extended: Vec<Vec<f64>> = extra
            .iter()
            .map(|row| row.values.iter().map(|&v| v as f64).chain([1.0]).collect())
            .collect();
        for (row, x) in extra.iter().zip(&extended) {
            for (bi, xi) in b.iter_mut().zip(x) {
                *bi += row.weight * row.target * xi;
            }
        }
        // (A + X W X')^-1 b = y - Z (W^-1 + X' Z)^-1 X' y, with y = A^-1 b
        // and Z = A^-1 X.
        let y = self.solve(b);
        let z: Vec<Vec<f64>> = extended.iter().map(|x| self.solve(x.clone())).collect();
        let k = extra.len();
        let mut small = vec![0f64; k * k];
        for i in 0..k {
            for j in 0..k {
                small[i * k + j] = dot(&extended[i], &z[j]);
            }
            small[i * k + i] += 1.0 / extra[i].weight;
        }
        let mut c: Vec<f64> = extended.iter().map(|x| dot(x, &y)).collect();
        cholesky(&mut small, k);
        substitute(&small, &mut c, k);
        let mut weights = y;
        for (zi, ci) in z.iter().zip(&c) {
            for (w, v) in weights.iter_mut().zip(zi) {
                *w -= ci * v;
            }
        }
        weights.into_iter().map(|v| v as f32).collect()
    }

    /// `(Gram + lambda I)^-1 b`.
    fn solve(&self, mut b: Vec<f64>) -> Vec<f64> {
        substitute(&self.factor, &mut b, self.dim + 1);
        b
    }
}

/// The Gram matrix of the rows whose columns are `blocks`, with a
/// constant 1 appended to each: `(dim + 1) x (dim + 1)`, row by row.
fn gram(blocks: &[Columns<'_>]) -> Vec<f64> {
    let dim: usize = blocks.iter().map(|b| b.width).sum();
    let n = blocks
        .first()
        .map_or(0, |b| b.values.len() / b.width.max(1));
    let side = dim + 1;
    let mut gram = vec![0f64; side * side];
    let mut first = 0;
    for (i, a) in blocks.iter().enumerate() {
        let mut second = first;
        for b in &blocks[i..] {
            let product = cross(a, b, n);
            for r in 0..a.width {
                for c in 0..b.width {
                    let v = product[r * b.width + c] as f64;
                    gram[(first + r) * side + second + c] = v;
                    gram[(second + c) * side + first + r] = v;
                }
            }
            second += b.width;
        }
        first += a.width;
    }
    let sums = weighted_sums(blocks, &vec![1.0; n]);
    for (i, &s) in sums[..dim].iter().enumerate() {
        gram[i * side + dim] = s;
        gram[dim * side + i] = s;
    }
    gram[dim * side + dim] = n as f64;
    gram
}

/// `a' b` for two blocks of `n` rows: `a.width x b.width`, row by row.
fn cross(a: &Columns<'_>, b: &Columns<'_>, n: usize) -> Vec<f32> {
    let mut product = vec![0f32; a.width * b.width];
    // SAFETY: a holds n x a.width values and b n x b.width (read with
    // their row strides), the product a.width x b.width.
    unsafe {
        matrixmultiply::sgemm(
            a.width,
            n,
            b.width,
            1.0,
            a.values.as_ptr(),
            1,
            a.width as isize,
            b.values.as_ptr(),
            b.width as isize,
            1,
            0.0,
            product.as_mut_ptr(),
            b.width as isize,
            1,
        );
    }
    product
}

/// The sum of the rows whose columns are `blocks` (a constant 1
/// appended), each times its weight in `weights`: `dim + 1` values.
fn weighted_sums(blocks: &[Columns<'_>], weights: &[f32]) -> Vec<f64> {
    let mut sums: Vec<f64> = blocks
        .iter()
        .flat_map(|b| weighted_sum(b, weights))
        .collect();
    sums.push(weights.iter().map(|&w| w as f64).sum());
    sums
}

/// The sum of a block's rows, each times its weight in `weights`.
fn weighted_sum(block: &Columns<'_>, weights: &[f32]) -> Vec<f64> {
    let width = block.width;
    block
        .values
        .par_chunks(width * ROWS_A_CHUNK)
        .zip(weights.par_chunks(ROWS_A_CHUNK))
        .map(|(rows, weights)| {
            let mut sum = vec![0f32; width];
            for (row, &w) in rows.chunks_exact(width).zip(weights) {
                if w != 0.0 {
                    for (s, &v) in sum.iter_mut().zip(row) {
                        *s += v * w;
                    }
                }
            }
            sum.into_iter().map(f64::from).collect::<Vec<f64>>()
        })
        .reduce(
            || vec![0f64; width],
            |mut a, b| {
                for (x, y) in a.iter_mut().zip(b) {
                    *x += y;
                }
                a
            },
        )
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Replaces the symmetric positive definite `a` (`n x n`, row by row)
/// with its lower Cholesky factor `L` (`a = L L'`) in its lower triangle.
fn cholesky(a: &mut [f64], n: usize) {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        let d = d.max(1e-12).sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
}

/// Solves `L L' x = b` for the factor `L` of [`cholesky`]; `b` becomes `x`.
fn substitute(factor: &[f64], b: &mut [f64], n: usize) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= factor[i * n + k] * b[k];
        }
        b[i] = s / factor[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= factor[k * n + i] * b[k];
        }
        b[i] = s / factor[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn whole(values: &[f32], width: usize) -> [Columns<'_>; 1] {
        [Columns { values, width }]
    }

    #[test]
    fn a_fit_recovers_a_linear_rule() {
        // Targets +0.5 where x0 > x1, -0.5 elsewhere, on a grid of 2-d rows.
        let rows: Vec<f32> = (0..100)
            .flat_map(|i| [(i % 10) as f32 / 10.0, (i / 10) as f32 / 10.0])
            .collect();
        let targets: Vec<f32> = rows
            .chunks_exact(2)
            .map(|r| if r[0] > r[1] { 0.5 } else { -0.5 })
            .collect();
        let blocks = whole(&rows, 2);
        assert_eq!(gram(&blocks)[2 * 3 + 2], 100.0);
        let ridge = Ridge::new(&blocks, 1e-6);
        let w = ridge.fit(&blocks, &targets, &[]);
        let right = rows
            .chunks_exact(2)
            .zip(&targets)
            .filter(|(r, &t)| (r[0] * w[0] + r[1] * w[1] + w[2] > 0.0) == (t > 0.0))
            .count();
        assert!(right >= 95, "{right} of 100");
        // A heavy extra row moves the rule to its side.
        let heavy = [WeightedRow {
            values: &[0.0, 0.9],
            weight: 1e4,
            target: 0.5,
        }];
        let w = ridge.fit(&blocks, &targets, &heavy);
        assert!(0.9 * w[1] + w[2] > 0.0);
    }

    #[test]
    fn blocks_and_extra_rows_by_woodbury_match_a_direct_solve() {
        // 600 rows of 5 pseudo-random values (more than a chunk), held as
        // blocks of 3 and 2 columns; three heavy extra rows.
        let value = |i: usize| ((i * 7919 % 1009) as f32 / 1009.0) - 0.5;
        let (dim, side) = (5, 6);
        let rows: Vec<f32> = (0..600 * dim).map(value).collect();
        let (left, right): (Vec<f32>, Vec<f32>) = {
            let (mut l, mut r) = (Vec::new(), Vec::new());
            for row in rows.chunks_exact(dim) {
                l.extend_from_slice(&row[..3]);
                r.extend_from_slice(&row[3..]);
            }
            (l, r)
        };
        let blocks = [
            Columns {
                values: &left,
                width: 3,
            },
            Columns {
                values: &right,
                width: 2,
            },
        ];
        let targets: Vec<f32> = (0..600).map(|i| value(i * 13) - 0.1).collect();
        let extra_values: Vec<Vec<f32>> = (0..3)
            .map(|k| (0..dim).map(|j| value(5000 + 31 * k + j)).collect())
            .collect();
        let extra: Vec<WeightedRow<'_>> = extra_values
            .iter()
            .enumerate()
            .map(|(k, values)| WeightedRow {
                values,
                weight: 50.0 * (k + 1) as f64,
                target: if k == 1 { -0.5 } else { 0.5 },
            })
            .collect();
        let lambda = 0.3;
        let w = Ridge::new(&blocks, lambda).fit(&blocks, &targets, &extra);
        // The normal equations of the joined rows, made whole and
        // factorised.
        let joined = whole(&rows, dim);
        let mut a = gram(&joined);
        for (x, y) in a.iter().zip(gram(&blocks)) {
            assert!(
                (x - y).abs() < 1e-3,
                "the blocks' Gram matrix is the joined rows'"
            );
        }
        let mut b = weighted_sums(&joined, &targets);
        for i in 0..side {
            a[i * side + i] += lambda;
        }
        for row in &extra {
            let x: Vec<f64> = row.values.iter().map(|&v| v as f64).chain([1.0]).collect();
            for i in 0..side {
                b[i] += row.weight * row.target * x[i];
                for j in 0..side {
                    a[i * side + j] += row.weight * x[i] * x[j];
                }
            }
        }
        cholesky(&mut a, side);
        substitute(&a, &mut b, side);
        for (fitted, direct) in w.iter().zip(&b) {
            assert!(
                (*fitted as f64 - direct).abs() < 1e-5,
                "{w:?} against {b:?}"
            );
        }
    }

    #[test]
    fn cholesky_solves_a_small_system() {
        let mut a = vec![4.0, 2.0, 2.0, 3.0];
        let mut b = vec![2.0, 1.0];
        cholesky(&mut a, 2);
        substitute(&a, &mut b, 2);
        // 4x + 2y = 2, 2x + 3y = 1: x = 0.5, y = 0.
        assert!((b[0] - 0.5).abs() < 1e-12 && b[1].abs() < 1e-12);
    }
}
