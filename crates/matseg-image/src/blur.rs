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

/// Appends `k0 * centre[x] + sum over pairs (k, a, b) of k * (a[x] + b[x])`
/// for every `x` of `centre` to `out`, over equal-length slices so the
/// compiler vectorises it; also compiled for AVX2, picked at run time when
/// the CPU has it.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn append_symmetric_taps(
    out: &mut Vec<f32>,
    centre: &[f32],
    k0: f32,
    pairs: &[(f32, &[f32], &[f32])],
) {
    let start = out.len();
    out.extend(centre.iter().map(|&c| k0 * c));
    let out = &mut out[start..];
    let n = out.len();
    for &(k, a, b) in pairs {
        let (a, b) = (&a[..n], &b[..n]);
        for x in 0..n {
            out[x] += k * (a[x] + b[x]);
        }
    }
}

/// Blurs a plane with an odd Gaussian kernel of size `ksize` (1 = copy).
pub fn gaussian_blur(src: &Plane, ksize: usize) -> Plane {
    gaussian_blur_region(src, ksize, Region::whole(src))
}

/// A rectangle of a plane: columns `x0..x1`, rows `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// First column.
    pub x0: usize,
    /// One past the last column.
    pub x1: usize,
    /// First row.
    pub y0: usize,
    /// One past the last row.
    pub y1: usize,
}

impl Region {
    /// No pixel at all.
    pub const EMPTY: Region = Region {
        x0: 0,
        x1: 0,
        y0: 0,
        y1: 0,
    };

    /// All of `plane`.
    pub fn whole(plane: &Plane) -> Self {
        Region {
            x0: 0,
            x1: plane.width,
            y0: 0,
            y1: plane.height,
        }
    }

    /// The bounding box of the pixels where `plane > 0`, if any.
    pub fn support(plane: &Plane) -> Option<Self> {
        let w = plane.width;
        let mut region: Option<Region> = None;
        for (y, row) in plane.data.chunks_exact(w).enumerate() {
            // Blocks of 16 are tested whole (vectorised); positions are
            // looked for only in the first and last positive block.
            let positive = |block: &[f32]| block.iter().fold(0.0f32, |m, &v| m.max(v)) > 0.0;
            let Some(first) = row.chunks(16).position(positive) else {
                continue;
            };
            let last = row
                .chunks(16)
                .rposition(positive)
                .expect("a positive block");
            let x0 = first * 16
                + row[first * 16..]
                    .iter()
                    .position(|&v| v > 0.0)
                    .expect("in block");
            let tail = &row[..(last * 16 + 16).min(w)];
            let x1 = tail.iter().rposition(|&v| v > 0.0).expect("in block") + 1;
            let r = region.get_or_insert(Region {
                x0,
                x1,
                y0: y,
                y1: y + 1,
            });
            r.x0 = r.x0.min(x0);
            r.x1 = r.x1.max(x1);
            r.y1 = y + 1;
        }
        region
    }
}

/// Like [`gaussian_blur`], but only the pixels inside `region` are computed
/// (exactly as the whole blur would); the rest of the result is 0.
pub fn gaussian_blur_region(src: &Plane, ksize: usize, region: Region) -> Plane {
    if ksize <= 1 || src.is_empty() {
        return src.clone();
    }
    let taps = gaussian_kernel(ksize);
    let r = ksize / 2;
    let (w, h) = (src.width, src.height);
    let Region { x0, x1, y0, y1 } = region;
    let span = x1 - x0;

    // Horizontal pass over the rows the vertical pass will read (only the
    // region's columns): pad each row by reflection, then add mirrored taps
    // in pairs (the kernel is symmetric).
    let (first_row, end_row) = (y0.saturating_sub(r), (y1 + r).min(h));
    let mut horiz = Vec::with_capacity((end_row - first_row) * span);
    let mut padded = vec![0.0f32; w + 2 * r];
    for y in first_row..end_row {
        let row = &src.data[y * w..(y + 1) * w];
        padded[r..r + w].copy_from_slice(row);
        for i in 0..r {
            padded[i] = row[reflect101(i as isize - r as isize, w)];
            padded[r + w + i] = row[reflect101((w + i) as isize, w)];
        }
        let pairs: Vec<_> = (0..r)
            .map(|t| (taps[t], &padded[x0 + t..], &padded[x0 + 2 * r - t..]))
            .collect();
        append_symmetric_taps(&mut horiz, &padded[x0 + r..x0 + r + span], taps[r], &pairs);
    }

    // Vertical pass: each output row is a weighted sum of input rows
    // (reflected rows stay inside the horizontal pass's rows). Rows and
    // columns outside the region are 0.
    let row = |y: isize| &horiz[(reflect101(y, h) - first_row) * span..];
    let mut out = Vec::with_capacity(w * h);
    out.resize(y0 * w, 0.0);
    for y in y0..y1 {
        out.resize(out.len() + x0, 0.0);
        let yi = y as isize;
        let pairs: Vec<_> = (0..r)
            .map(|t| {
                let d = (r - t) as isize;
                (taps[t], row(yi - d), row(yi + d))
            })
            .collect();
        append_symmetric_taps(&mut out, &row(yi)[..span], taps[r], &pairs);
        out.resize(out.len() + w - x1, 0.0);
    }
    out.resize(w * h, 0.0);
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
    fn region_blur_equals_the_whole_blur_inside_the_region() {
        let src = Plane::from_vec(
            23,
            17,
            (0..23 * 17)
                .map(|i| ((i * 37) % 101) as f32 / 100.0)
                .collect(),
        );
        for k in [3, 9, 21] {
            let whole = gaussian_blur(&src, k);
            for region in [
                Region {
                    x0: 0,
                    x1: 5,
                    y0: 0,
                    y1: 4,
                },
                Region {
                    x0: 7,
                    x1: 16,
                    y0: 5,
                    y1: 12,
                },
                Region {
                    x0: 18,
                    x1: 23,
                    y0: 13,
                    y1: 17,
                },
            ] {
                let part = gaussian_blur_region(&src, k, region);
                for y in 0..17 {
                    for x in 0..23 {
                        let inside = (region.x0..region.x1).contains(&x)
                            && (region.y0..region.y1).contains(&y);
                        let want = if inside { whole.get(x, y) } else { 0.0 };
                        assert_eq!(part.get(x, y), want, "k {k} {region:?} ({x}, {y})");
                    }
                }
            }
        }
    }

    #[test]
    fn support_is_the_bounding_box_of_positive_values() {
        let mut p = Plane::new(10, 8, 0.0);
        assert_eq!(Region::support(&p), None);
        p.data[2 * 10 + 7] = 0.5;
        p.data[5 * 10 + 3] = 1.0;
        assert_eq!(
            Region::support(&p),
            Some(Region {
                x0: 3,
                x1: 8,
                y0: 2,
                y1: 6
            })
        );
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
