//! The photo's colours as columns of a selection's classifier, beside the
//! descriptors. Each colour (CIE L*a*b* / 100) becomes [`FEATURES`] random
//! Fourier features, `cos(w . lab + phase)` with `w` drawn from a normal
//! of deviation `1 / BANDWIDTH` (Rahimi and Recht's features of a Gaussian
//! kernel): a linear rule on them is a smooth rule on colours, so the
//! classifier can take dark brown and leave light brown where the
//! descriptors alone do not tell them apart. A cell's row holds the mean
//! features of its pixels; the fitted rule is then applied to each pixel
//! through its colour's bin ([`ColourBins`]), so the decision follows the
//! colours down to single pixels, which speckled materials need.

use crate::colours::{bin_colour, ColourBins, BINS};
use matseg_image::lab::srgb_to_lab;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::LazyLock;

/// Features a colour.
pub const FEATURES: usize = 32;

/// The kernel's width in CIE L*a*b* / 100 (10 units of L*a*b*).
const BANDWIDTH: f32 = 0.1;

/// The features' weight beside the descriptors' (unit vectors): the
/// features of a colour have a length of about this.
const WEIGHT: f32 = 0.5;

/// The largest magnitude a feature takes (a cosine's amplitude): saved
/// features beyond it were made by no colour.
pub fn largest_feature() -> f32 {
    WEIGHT * (2.0 / FEATURES as f32).sqrt()
}

/// Every bin's features ([`BINS`] x [`FEATURES`], bin by bin), the same
/// for every photo.
static OF_BIN: LazyLock<Vec<f32>> = LazyLock::new(|| {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut normal = || {
        // Box and Muller's transform of two uniform draws.
        let u: f32 = rng.random_range(f32::EPSILON..1.0);
        let v: f32 = rng.random_range(0.0..1.0);
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    };
    let frequencies: Vec<[f32; 3]> = (0..FEATURES)
        .map(|_| [normal(), normal(), normal()].map(|w| w / BANDWIDTH))
        .collect();
    let phases: Vec<f32> = (0..FEATURES)
        .map(|_| rng.random_range(0.0..std::f32::consts::TAU))
        .collect();
    let scale = largest_feature();
    (0..BINS)
        .flat_map(|bin| {
            let lab = srgb_to_lab(bin_colour(bin)).map(|v| v / 100.0);
            frequencies
                .iter()
                .zip(&phases)
                .map(move |(w, phase)| {
                    scale * (w[0] * lab[0] + w[1] * lab[1] + w[2] * lab[2] + phase).cos()
                })
                .collect::<Vec<f32>>()
        })
        .collect()
});

/// The features of bin `bin`.
fn of_bin(bin: u16) -> &'static [f32] {
    &OF_BIN[bin as usize * FEATURES..(bin as usize + 1) * FEATURES]
}

/// The mean features of the colours of the bins `bins` (one at least).
fn mean_of(bins: impl Iterator<Item = u16>) -> Vec<f32> {
    let mut sum = vec![0f32; FEATURES];
    let mut count = 0usize;
    for bin in bins {
        for (s, f) in sum.iter_mut().zip(of_bin(bin)) {
            *s += f;
        }
        count += 1;
    }
    let count = count.max(1) as f32;
    sum.iter_mut().for_each(|s| *s /= count);
    sum
}

/// The mean features of the pixels of a `width`-wide photo's `bins` in
/// columns `xs` and rows `ys` (one pixel at least).
pub fn mean_features(
    bins: &ColourBins,
    width: usize,
    xs: Range<usize>,
    ys: Range<usize>,
) -> Vec<f32> {
    let bins = bins.bins();
    mean_of(ys.flat_map(|y| {
        bins[y * width + xs.start..y * width + xs.end]
            .iter()
            .copied()
    }))
}

/// The mean features of the pixels within `radius` of `(x, y)` (the pixel
/// at `(x, y)` at least): a click's colour.
pub fn disc_features(
    bins: &ColourBins,
    (width, height): (usize, usize),
    (x, y): (f32, f32),
    radius: f32,
) -> Vec<f32> {
    let centre = ((x as usize).min(width - 1), (y as usize).min(height - 1));
    let r = radius.max(0.0);
    let span = |c: f32, n: usize| {
        ((c - r).floor().max(0.0) as usize).min(n - 1)..((c + r).floor() as usize + 1).min(n)
    };
    let others = span(y, height)
        .flat_map(|py| span(x, width).map(move |px| (px, py)))
        .filter(|&(px, py)| {
            let inside = (px as f32 + 0.5 - x).powi(2) + (py as f32 + 0.5 - y).powi(2) <= r * r;
            inside && (px, py) != centre
        });
    let bins = bins.bins();
    mean_of(
        std::iter::once(centre)
            .chain(others)
            .map(|(px, py)| bins[py * width + px]),
    )
}

/// Each bin's score under the colour columns' `weights` ([`FEATURES`]
/// values): what a pixel of that colour adds to its decision.
pub fn bin_scores(weights: &[f32]) -> Vec<f32> {
    OF_BIN
        .par_chunks(FEATURES)
        .map(|features| features.iter().zip(weights).map(|(f, w)| f * w).sum())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    #[test]
    fn features_are_alike_for_near_colours_and_unlike_for_far_ones() {
        let photo = RgbImage::from_fn(3, 1, |x, _| {
            image::Rgb([[120, 60, 30], [128, 64, 32], [40, 140, 220]][x as usize])
        });
        let bins = ColourBins::new(&photo);
        let at = |x| mean_features(&bins, 3, x..x + 1, 0..1);
        let dot = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f32>();
        let (brown, browner, blue) = (at(0), at(1), at(2));
        // The kernel's value: WEIGHT^2 for a colour with itself.
        assert!((dot(&brown, &brown) - WEIGHT * WEIGHT).abs() < 0.1);
        assert!(dot(&brown, &browner) > dot(&brown, &blue) + 0.1);
        // A mean over both browns lies between them; a one-pixel disc is
        // its pixel's features.
        let both = mean_features(&bins, 3, 0..2, 0..1);
        for k in 0..FEATURES {
            assert!((both[k] - (brown[k] + browner[k]) / 2.0).abs() < 1e-6);
        }
        assert_eq!(disc_features(&bins, (3, 1), (2.5, 0.5), 0.0), blue);
        // A bin's score is its features' dot product with the weights.
        let weights: Vec<f32> = (0..FEATURES).map(|k| k as f32 / 10.0).collect();
        let scores = bin_scores(&weights);
        let bin = bins.bins()[2] as usize;
        assert!((scores[bin] - dot(&blue, &weights)).abs() < 1e-5);
    }
}
