//! The loss curve of a run as a PNG: raw training losses in light grey, their
//! moving average in blue, validation losses as red dots; the vertical axis
//! runs from 0 to the largest loss, the horizontal over the steps, each with
//! its ends and middle labelled.

use crate::train::{write_atomic, StepMetrics};
use crate::NetError;
use image::{Rgb, RgbImage};
use matseg_image::io::encode_png_rgb;
use std::path::Path;

const WIDTH: u32 = 640;
const HEIGHT: u32 = 360;
/// Room for the vertical axis' labels.
const LEFT: u32 = 52;
/// Room for the horizontal axis' labels.
const BOTTOM: u32 = 26;
/// Margin above and right of the plot.
const MARGIN: u32 = 14;
/// Steps in the moving average.
const WINDOW: usize = 20;
/// Label glyphs are drawn this many pixels per font pixel.
const SCALE: u32 = 2;

/// Draws the curve of `history` into `path` (atomically).
pub fn plot_losses(history: &[StepMetrics], path: &Path) -> Result<(), NetError> {
    write_atomic(path, &encode_png_rgb(&draw(history)))
}

/// The plot as an image.
fn draw(history: &[StepMetrics]) -> RgbImage {
    let mut img = RgbImage::from_pixel(WIDTH, HEIGHT, Rgb([255, 255, 255]));
    let axis = Rgb([0, 0, 0]);
    let (x0, x1, y0, y1) = (LEFT, WIDTH - MARGIN, MARGIN, HEIGHT - BOTTOM);
    for x in x0..=x1 {
        img.put_pixel(x, y1, axis);
    }
    for y in y0..=y1 {
        img.put_pixel(x0, y, axis);
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
    let to_pixel = |step: u64, loss: f64| {
        let x = x0 as f64 + (x1 - x0) as f64 * step as f64 / last as f64;
        let y = y1 as f64 - (y1 - y0) as f64 * loss / top.max(f64::MIN_POSITIVE);
        (x.round() as i64, y.round() as i64)
    };
    let text_height = 5 * SCALE as i64;
    for (step, label) in [(0, 0), (last / 2, last / 2), (last, last)] {
        let (x, _) = to_pixel(step, 0.0);
        dot(&mut img, (x, y1 as i64 + 2), axis, 1);
        let label = label.to_string();
        // Centred under its tick, but kept inside the image.
        let x = (x - text_width(&label) / 2).min(WIDTH as i64 - 1 - text_width(&label));
        draw_text(&mut img, &label, x, y1 as i64 + 6, axis);
    }
    if top > 0.0 {
        for fraction in [0.0, 0.5, 1.0] {
            let (_, y) = to_pixel(0, top * fraction);
            dot(&mut img, (x0 as i64 - 2, y), axis, 1);
            let label = format!("{:.3}", top * fraction);
            let x = x0 as i64 - 6 - text_width(&label);
            draw_text(&mut img, &label, x, y - text_height / 2, axis);
        }
        for &(step, loss) in &losses {
            dot(&mut img, to_pixel(step, loss), Rgb([190, 190, 190]), 0);
        }
        for i in 0..losses.len() {
            let window = &losses[i.saturating_sub(WINDOW - 1)..=i];
            let mean = window.iter().map(|(_, l)| l).sum::<f64>() / window.len() as f64;
            dot(&mut img, to_pixel(losses[i].0, mean), Rgb([30, 80, 200]), 1);
        }
        for m in history {
            if let Some(v) = m.validation {
                dot(&mut img, to_pixel(m.step, v), Rgb([210, 40, 40]), 3);
            }
        }
    }
    img
}

/// Pixel `(x, y)` set to `colour` when it is inside the image.
fn put(img: &mut RgbImage, x: i64, y: i64, colour: Rgb<u8>) {
    if (0..WIDTH as i64).contains(&x) && (0..HEIGHT as i64).contains(&y) {
        img.put_pixel(x as u32, y as u32, colour);
    }
}

/// A square of side `2 * radius + 1` centred on `(x, y)`, clipped.
fn dot(img: &mut RgbImage, (x, y): (i64, i64), colour: Rgb<u8>, radius: i64) {
    for dy in -radius..=radius {
        for dx in -radius..=radius {
            put(img, x + dx, y + dy, colour);
        }
    }
}

/// The 3x5 font of the labels: five rows of three bits, the leftmost pixel
/// in the highest bit. Only what numbers need.
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        _ => [0b000, 0b000, 0b010, 0b000, 0b000],
    }
}

/// Pixels `text` takes across: 3 per glyph and 1 between, scaled.
fn text_width(text: &str) -> i64 {
    (4 * text.chars().count() as i64 - 1).max(0) * SCALE as i64
}

/// Draws `text` with its top-left corner at `(x, y)`, clipped.
fn draw_text(img: &mut RgbImage, text: &str, x: i64, y: i64, colour: Rgb<u8>) {
    let s = SCALE as i64;
    for (i, c) in text.chars().enumerate() {
        let left = x + 4 * s * i as i64;
        for (row, bits) in glyph(c).iter().enumerate() {
            for column in 0..3 {
                if bits >> (2 - column) & 1 == 1 {
                    for (dx, dy) in (0..s).flat_map(|dx| (0..s).map(move |dy| (dx, dy))) {
                        put(img, left + column * s + dx, y + row as i64 * s + dy, colour);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The font pixels of `text` read back from an image it was drawn on.
    fn read_back(img: &RgbImage, text: &str, x: i64, y: i64) -> Vec<[u8; 5]> {
        let s = SCALE as i64;
        (0..text.chars().count() as i64)
            .map(|i| {
                std::array::from_fn(|row| {
                    (0..3).fold(0u8, |bits, column| {
                        let px = (x + 4 * s * i + column * s) as u32;
                        let py = (y + row as i64 * s) as u32;
                        bits << 1 | u8::from(img.get_pixel(px, py).0 == [0, 0, 0])
                    })
                })
            })
            .collect()
    }

    #[test]
    fn labels_are_drawn_in_the_font_and_digits_differ() {
        let digits: Vec<[u8; 5]> = "0123456789".chars().map(glyph).collect();
        for (i, a) in digits.iter().enumerate() {
            assert!(digits[i + 1..].iter().all(|b| a != b), "digit {i} repeats");
        }
        let mut img = RgbImage::from_pixel(WIDTH, HEIGHT, Rgb([255, 255, 255]));
        draw_text(&mut img, "0.375", 10, 20, Rgb([0, 0, 0]));
        let expected: Vec<[u8; 5]> = "0.375".chars().map(glyph).collect();
        assert_eq!(read_back(&img, "0.375", 10, 20), expected);
        assert_eq!(text_width("0.375"), (5 * 4 - 1) * SCALE as i64);
    }

    #[test]
    fn the_axes_carry_the_largest_loss_and_the_last_step() {
        let history: Vec<StepMetrics> = (0..=40)
            .map(|step| StepMetrics {
                step,
                loss: Some(0.5 - step as f64 / 100.0),
                lr: 1e-4,
                images: 2,
                width: 32,
                height: 32,
                seconds: 0.1,
                data_seconds: 0.0,
                validation: None,
                val_points: None,
            })
            .collect();
        let img = draw(&history);
        // "0.500" left of the top of the vertical axis, "40" under the
        // right end of the horizontal one.
        let text_height = 5 * SCALE as i64;
        let top = "0.500";
        let x = LEFT as i64 - 6 - text_width(top);
        let y = MARGIN as i64 - text_height / 2;
        assert_eq!(
            read_back(&img, top, x, y),
            top.chars().map(glyph).collect::<Vec<_>>()
        );
        let x = (WIDTH - MARGIN) as i64 - text_width("40") / 2;
        let y = (HEIGHT - BOTTOM) as i64 + 6;
        assert_eq!(
            read_back(&img, "40", x, y),
            "40".chars().map(glyph).collect::<Vec<_>>()
        );
    }
}
