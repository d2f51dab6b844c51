//! Separable Gaussian blur with OpenCV's kernel-size-to-sigma rule.

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
    let period = 2 * (n - 1);
    let mut j = i.rem_euclid(period);
    if j >= n {
        j = period - j;
    }
    j as usize
}

/// `out[x] = k0 * centre[x] + sum over pairs (k, a, b) of k * (a[x] + b[x])`,
/// written over equal-length slices so the compiler vectorises it.
fn symmetric_taps(out: &mut [f32], centre: &[f32], k0: f32, pairs: &[(f32, &[f32], &[f32])]) {
    let n = out.len();
    let centre = &centre[..n];
    for x in 0..n {
        out[x] = k0 * centre[x];
    }
    for &(k, a, b) in pairs {
        let (a, b) = (&a[..n], &b[..n]);
        for x in 0..n {
            out[x] += k * (a[x] + b[x]);
        }
    }
}

/// Blurs a plane with an odd Gaussian kernel of size `ksize` (1 = copy).
pub fn gaussian_blur(src: &Plane, ksize: usize) -> Plane {
    if ksize <= 1 || src.is_empty() {
        return src.clone();
    }
    let taps = gaussian_kernel(ksize);
    let r = ksize / 2;
    let (w, h) = (src.width, src.height);

    // Horizontal pass: pad each row by reflection, then add mirrored taps in
    // pairs (the kernel is symmetric) over whole rows.
    let mut horiz = vec![0.0f32; w * h];
    let mut padded = vec![0.0f32; w + 2 * r];
    for y in 0..h {
        let row = &src.data[y * w..(y + 1) * w];
        padded[r..r + w].copy_from_slice(row);
        for i in 0..r {
            padded[i] = row[reflect101(i as isize - r as isize, w)];
            padded[r + w + i] = row[reflect101((w + i) as isize, w)];
        }
        let pairs: Vec<_> = (0..r)
            .map(|t| (taps[t], &padded[t..], &padded[2 * r - t..]))
            .collect();
        symmetric_taps(
            &mut horiz[y * w..(y + 1) * w],
            &padded[r..r + w],
            taps[r],
            &pairs,
        );
    }

    // Vertical pass: each output row is a weighted sum of whole input rows.
    let mut out = vec![0.0f32; w * h];
    let row = |y: isize| &horiz[reflect101(y, h) * w..];
    for y in 0..h {
        let yi = y as isize;
        let pairs: Vec<_> = (0..r)
            .map(|t| {
                let d = (r - t) as isize;
                (taps[t], row(yi - d), row(yi + d))
            })
            .collect();
        symmetric_taps(
            &mut out[y * w..(y + 1) * w],
            &horiz[y * w..(y + 1) * w],
            taps[r],
            &pairs,
        );
    }
    Plane::from_vec(w, h, out)
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

    #[test]
    fn reflect101_mirrors_without_the_edge() {
        let got: Vec<usize> = (-3..8).map(|i| reflect101(i, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
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
