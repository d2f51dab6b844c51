//! Training augmentation (pipeline.md §8): flips (of the image and its ground
//! truth), blur, brightness x U(0.5, 1.15), partial or full greyscale and
//! Gaussian noise, each drawn independently.

use crate::training::TrainingSample;
use image::imageops;
use image::RgbImage;
use rand::Rng;

/// Chance of each flip.
pub const P_FLIP: f64 = 0.5;
/// Chance of a Gaussian blur, and its sigma range in pixels.
pub const P_BLUR: f64 = 0.25;
/// Blur sigma range.
pub const BLUR_SIGMA: (f32, f32) = (0.5, 2.0);
/// Chance of a brightness change, and its factor range.
pub const P_BRIGHTNESS: f64 = 0.5;
/// Brightness factor range.
pub const BRIGHTNESS: (f32, f32) = (0.5, 1.15);
/// Chance of greyscale; then the chance that it is full (else a partial mix).
pub const P_GREY: f64 = 0.25;
/// Chance that greyscale is full rather than partial.
pub const P_FULL_GREY: f64 = 0.5;
/// Chance of Gaussian noise, and its standard deviation range (8-bit levels).
pub const P_NOISE: f64 = 0.25;
/// Noise standard deviation range.
pub const NOISE_SIGMA: (f32, f32) = (2.0, 10.0);

/// Augments `sample` in place.
pub fn augment<R: Rng + ?Sized>(sample: &mut TrainingSample, rng: &mut R) {
    let (w, h) = (sample.width, sample.height);
    if rng.random_bool(P_FLIP) {
        flip(sample, |x, y| (w - 1 - x, y));
    }
    if rng.random_bool(P_FLIP) {
        flip(sample, |x, y| (x, h - 1 - y));
    }
    if rng.random_bool(P_BLUR) {
        let sigma = rng.random_range(BLUR_SIGMA.0..BLUR_SIGMA.1);
        let img = RgbImage::from_raw(w as u32, h as u32, std::mem::take(&mut sample.rgb))
            .expect("RGB size");
        sample.rgb = imageops::blur(&img, sigma).into_raw();
    }
    let mut rgb: Vec<f32> = sample.rgb.iter().map(|&v| v as f32).collect();
    if rng.random_bool(P_BRIGHTNESS) {
        let factor = rng.random_range(BRIGHTNESS.0..BRIGHTNESS.1);
        rgb.iter_mut().for_each(|v| *v *= factor);
    }
    if rng.random_bool(P_GREY) {
        let amount = if rng.random_bool(P_FULL_GREY) {
            1.0
        } else {
            rng.random_range(0.2f32..0.8)
        };
        for p in rgb.chunks_exact_mut(3) {
            let grey = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
            p.iter_mut().for_each(|v| *v += amount * (grey - *v));
        }
    }
    if rng.random_bool(P_NOISE) {
        let sigma = rng.random_range(NOISE_SIGMA.0..NOISE_SIGMA.1);
        for v in rgb.iter_mut() {
            *v += sigma * standard_normal(rng);
        }
    }
    sample.rgb = rgb
        .iter()
        .map(|v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
}

/// Moves every pixel (image, weights, ROI) to `to(x, y)`.
fn flip(sample: &mut TrainingSample, to: impl Fn(usize, usize) -> (usize, usize)) {
    let (w, h) = (sample.width, sample.height);
    let mut rgb = vec![0u8; sample.rgb.len()];
    let mut planes: Vec<Vec<f32>> = sample.weights.iter().map(|p| vec![0.0; p.len()]).collect();
    let mut roi = vec![0.0; sample.roi.len()];
    for y in 0..h {
        for x in 0..w {
            let (i, (tx, ty)) = (y * w + x, to(x, y));
            let j = ty * w + tx;
            rgb[3 * j..3 * j + 3].copy_from_slice(&sample.rgb[3 * i..3 * i + 3]);
            for (dst, src) in planes.iter_mut().zip(&sample.weights) {
                dst[j] = src[i];
            }
            roi[j] = sample.roi[i];
        }
    }
    sample.rgb = rgb;
    sample.weights = planes;
    sample.roi = roi;
}

/// A standard normal draw (Box-Muller).
fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f32 {
    let u1: f32 = rng.random_range(f32::EPSILON..1.0);
    let u2: f32 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}
