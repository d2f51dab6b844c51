//! The loss curve of a run as a PNG: raw training losses in light grey, their
//! moving average in blue, validation losses as red dots; the vertical axis
//! runs from 0 to the largest loss, the horizontal over the steps.

use crate::train::{write_atomic, StepMetrics};
use crate::NetError;
use image::{Rgb, RgbImage};
use matseg_image::io::encode_png_rgb;
use std::path::Path;

const WIDTH: u32 = 640;
const HEIGHT: u32 = 360;
const MARGIN: u32 = 20;
/// Steps in the moving average.
const WINDOW: usize = 20;

/// Draws the curve of `history` into `path` (atomically).
pub fn plot_losses(history: &[StepMetrics], path: &Path) -> Result<(), NetError> {
    let mut img = RgbImage::from_pixel(WIDTH, HEIGHT, Rgb([255, 255, 255]));
    let axis = Rgb([0, 0, 0]);
    for x in MARGIN..WIDTH - MARGIN {
        img.put_pixel(x, HEIGHT - MARGIN, axis);
    }
    for y in MARGIN..=HEIGHT - MARGIN {
        img.put_pixel(MARGIN, y, axis);
    }
    let losses: Vec<(u64, f64)> = history
        .iter()
        .filter_map(|m| m.loss.map(|l| (m.step, l)))
        .collect();
    let top = history
        .iter()
        .flat_map(|m| m.loss.into_iter().chain(m.validation))
        .fold(0f64, f64::max);
    let last = history.last().map_or(1, |m| m.step.max(1));
    if top > 0.0 {
        let to_pixel = |step: u64, loss: f64| {
            let x = MARGIN as f64 + (WIDTH - 2 * MARGIN) as f64 * step as f64 / last as f64;
            let y = (HEIGHT - MARGIN) as f64 - (HEIGHT - 2 * MARGIN) as f64 * loss / top;
            (x.round() as i64, y.round() as i64)
        };
        let mut dot = |(x, y): (i64, i64), colour: Rgb<u8>, radius: i64| {
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (px, py) = (x + dx, y + dy);
                    if (0..WIDTH as i64).contains(&px) && (0..HEIGHT as i64).contains(&py) {
                        img.put_pixel(px as u32, py as u32, colour);
                    }
                }
            }
        };
        for &(step, loss) in &losses {
            dot(to_pixel(step, loss), Rgb([190, 190, 190]), 0);
        }
        for i in 0..losses.len() {
            let window = &losses[i.saturating_sub(WINDOW - 1)..=i];
            let mean = window.iter().map(|(_, l)| l).sum::<f64>() / window.len() as f64;
            dot(to_pixel(losses[i].0, mean), Rgb([30, 80, 200]), 1);
        }
        for m in history {
            if let Some(v) = m.validation {
                dot(to_pixel(m.step, v), Rgb([210, 40, 40]), 3);
            }
        }
    }
    write_atomic(path, &encode_png_rgb(&img))
}
