//! A linear classifier fitted on the fly on a photo's descriptors: ridge
//! regression of targets in -0.5..0.5 on the descriptors and a constant.
//! The rows' Gram matrix is computed once per photo ([`Ridge::new`]); each
//! fit then adds its weighted extra rows (clicks) and solves a system of
//! the descriptors' size (Cholesky, in f64).

/// The Gram matrix of a photo's descriptor rows, each with a constant 1
/// appended.
pub struct Ridge {
    /// Descriptor values a row (without the constant).
    dim: usize,
    /// `(dim + 1) x (dim + 1)`, row by row.
    gram: Vec<f64>,
}

/// A row the fit weighs more than the photo's: a click's descriptor, its
/// weight and its target (0.5 wanted, -0.5 not).
pub struct WeightedRow<'a> {
    /// The descriptor (`dim` values).
    pub values: &'a [f32],
    /// How many photo rows it counts as.
    pub weight: f64,
    /// Its target.
    pub target: f64,
}

impl Ridge {
    /// The Gram matrix of `rows` (`dim` values each, row by row).
    pub fn new(rows: &[f32], dim: usize) -> Self {
        let n = rows.len() / dim.max(1);
        let mut product = vec![0f32; dim * dim];
        // SAFETY: the slices hold n x dim (A, B) and dim x dim (C) values,
        // with the strides given.
        unsafe {
            matrixmultiply::sgemm(
                dim,
                n,
                dim,
                1.0,
                rows.as_ptr(),
                1,
                dim as isize,
                rows.as_ptr(),
                dim as isize,
                1,
                0.0,
                product.as_mut_ptr(),
                dim as isize,
                1,
            );
        }
        let side = dim + 1;
        let mut gram = vec![0f64; side * side];
        for i in 0..dim {
            for j in 0..dim {
                gram[i * side + j] = product[i * dim + j] as f64;
            }
        }
        let mut sums = vec![0f64; dim];
        for row in rows.chunks_exact(dim) {
            for (s, &v) in sums.iter_mut().zip(row) {
                *s += v as f64;
            }
        }
        for (i, s) in sums.into_iter().enumerate() {
            gram[i * side + dim] = s;
            gram[dim * side + i] = s;
        }
        gram[dim * side + dim] = n as f64;
        Self { dim, gram }
    }

    /// The weights (`dim` values, then the constant's) that best map
    /// `rows` (the rows of [`Ridge::new`]) to `targets`, and each extra
    /// row to its target, with `lambda` times the squared weights added.
    pub fn fit(
        &self,
        rows: &[f32],
        targets: &[f32],
        extra: &[WeightedRow<'_>],
        lambda: f64,
    ) -> Vec<f32> {
        let (dim, side) = (self.dim, self.dim + 1);
        let mut a = self.gram.clone();
        for i in 0..side {
            a[i * side + i] += lambda;
        }
        let mut b = vec![0f64; side];
        for (row, &t) in rows.chunks_exact(dim).zip(targets) {
            if t != 0.0 {
                for (bi, &v) in b.iter_mut().zip(row) {
                    *bi += v as f64 * t as f64;
                }
                b[dim] += t as f64;
            }
        }
        for row in extra {
            let x: Vec<f64> = row.values.iter().map(|&v| v as f64).chain([1.0]).collect();
            for i in 0..side {
                b[i] += row.weight * x[i] * row.target;
                for j in 0..side {
                    a[i * side + j] += row.weight * x[i] * x[j];
                }
            }
        }
        solve_positive_definite(&mut a, &mut b, side);
        b.into_iter().map(|v| v as f32).collect()
    }
}

/// Solves `a x = b` for a symmetric positive definite `a` (`n x n`, row
/// by row) by Cholesky's factorisation; `b` becomes `x`.
fn solve_positive_definite(a: &mut [f64], b: &mut [f64], n: usize) {
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
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let ridge = Ridge::new(&rows, 2);
        assert_eq!(ridge.gram[2 * 3 + 2], 100.0);
        let w = ridge.fit(&rows, &targets, &[], 1e-6);
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
        let w = ridge.fit(&rows, &targets, &heavy, 1e-6);
        assert!(0.9 * w[1] + w[2] > 0.0);
    }

    #[test]
    fn cholesky_solves_a_small_system() {
        let mut a = vec![4.0, 2.0, 2.0, 3.0];
        let mut b = vec![2.0, 1.0];
        solve_positive_definite(&mut a, &mut b, 2);
        // 4x + 2y = 2, 2x + 3y = 1: x = 0.5, y = 0.
        assert!((b[0] - 0.5).abs() < 1e-12 && b[1].abs() < 1e-12);
    }
}
