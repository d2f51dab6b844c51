//! A point benchmark's annotations drawn on its photo, to check them by
//! eye: each point as a ring of its disc's radius in its material's colour
//! (outlined in black so it shows on light and dark ground), with the
//! material's id written beside it.

use crate::points::BenchImage;
use image::{Rgb, RgbImage};

/// Ring colours, one per material in the order of the image's ids (then
/// repeated): saturated and far apart, so neighbouring materials differ.
const COLOURS: [[u8; 3]; 8] = [
    [255, 40, 40],
    [40, 255, 40],
    [40, 140, 255],
    [255, 40, 255],
    [255, 255, 40],
    [40, 255, 255],
    [255, 150, 40],
    [255, 255, 255],
];

/// Drawn rings are at least this many pixels in radius, so that small
/// discs still show.
const MIN_RING: f32 = 4.0;

/// 3x5 glyphs of the digits 0-9, one row a byte (bit 2 is the left column).
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

/// `photo` with `image`'s points drawn on it; the photo is magnified by
/// `scale` (whole pixels) first, so that the rings of small photos can be
/// seen.
pub fn draw_points(photo: &RgbImage, image: &BenchImage, scale: u32) -> RgbImage {
    let scale = scale.max(1);
    let mut canvas = image::imageops::resize(
        photo,
        photo.width() * scale,
        photo.height() * scale,
        image::imageops::FilterType::Nearest,
    );
    let s = scale as f32;
    for (m, (id, points)) in image.material_ids.iter().zip(&image.points).enumerate() {
        let colour = Rgb(COLOURS[m % COLOURS.len()]);
        for p in points {
            let (x, y) = ((p.x + 0.5) * s, (p.y + 0.5) * s);
            let r = (p.r * s).max(MIN_RING);
            ring(&mut canvas, x, y, r + 1.0, Rgb([0, 0, 0]));
            ring(&mut canvas, x, y, r, colour);
            ring(&mut canvas, x, y, r - 1.0, Rgb([0, 0, 0]));
            label(&mut canvas, x + r + 2.0, y - 5.0, id, colour);
        }
    }
    canvas
}

/// A one-pixel circle of radius `r` around `(x, y)`, clipped to the image.
fn ring(img: &mut RgbImage, x: f32, y: f32, r: f32, colour: Rgb<u8>) {
    let steps = ((r * std::f32::consts::TAU).ceil() as usize * 2).max(16);
    for k in 0..steps {
        let t = k as f32 / steps as f32 * std::f32::consts::TAU;
        put(
            img,
            (x + r * t.cos()).floor(),
            (y + r * t.sin()).floor(),
            colour,
        );
    }
}

/// `text`'s digits in 3x5 glyphs doubled to 6x10, on a black box, with
/// the top left at `(x, y)`; other characters are left as gaps.
fn label(img: &mut RgbImage, x: f32, y: f32, text: &str, colour: Rgb<u8>) {
    let (x, y) = (x.floor(), y.floor());
    let width = 8.0 * text.chars().count() as f32;
    for dy in -1..11 {
        for dx in -1..width as i32 {
            put(img, x + dx as f32, y + dy as f32, Rgb([0, 0, 0]));
        }
    }
    for (i, c) in text.chars().enumerate() {
        let Some(glyph) = c.to_digit(10).map(|d| DIGITS[d as usize]) else {
            continue;
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for (ox, oy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let px = x + (8 * i + 2 * col + ox) as f32;
                        put(img, px, y + (2 * row + oy) as f32, colour);
                    }
                }
            }
        }
    }
}

/// Sets the pixel at `(x, y)` when it lies inside the image.
fn put(img: &mut RgbImage, x: f32, y: f32, colour: Rgb<u8>) {
    if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, colour);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::points::BenchPoint;

    fn bench_image() -> BenchImage {
        BenchImage {
            name: "a".into(),
            image_path: "a.jpg".into(),
            material_ids: vec!["1".into(), "2".into()],
            points: vec![
                vec![BenchPoint {
                    x: 10.0,
                    y: 10.0,
                    r: 5.0,
                }],
                vec![BenchPoint {
                    x: 30.0,
                    y: 20.0,
                    r: 2.0,
                }],
            ],
            weights: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
            has_relations: false,
        }
    }

    #[test]
    fn rings_sit_on_each_disc_in_its_materials_colour() {
        let photo = RgbImage::from_pixel(50, 40, Rgb([128, 128, 128]));
        let out = draw_points(&photo, &bench_image(), 1);
        assert_eq!(out.dimensions(), (50, 40));
        // Material 1's ring passes 5 px right of its point's centre pixel;
        // the centre itself is untouched.
        assert_eq!(out.get_pixel(15, 10).0, COLOURS[0]);
        assert_eq!(out.get_pixel(10, 10).0, [128, 128, 128]);
        // Material 2's disc of radius 2 is drawn at the minimum ring size.
        assert_eq!(out.get_pixel(30, 16).0, COLOURS[1]);
    }

    #[test]
    fn magnified_photos_scale_the_points_alike() {
        let photo = RgbImage::from_pixel(50, 40, Rgb([128, 128, 128]));
        let out = draw_points(&photo, &bench_image(), 2);
        assert_eq!(out.dimensions(), (100, 80));
        // (10, 10) r 5 becomes (21, 21) r 10.
        assert_eq!(out.get_pixel(31, 21).0, COLOURS[0]);
    }

    #[test]
    fn labels_write_the_materials_digits() {
        let mut img = RgbImage::new(20, 12);
        label(&mut img, 1.0, 1.0, "1", Rgb([255, 0, 0]));
        // The glyph of 1: top row .X. doubled, so columns 3-4 lit, 1-2 dark.
        assert_eq!(img.get_pixel(3, 1).0, [255, 0, 0]);
        assert_eq!(img.get_pixel(1, 1).0, [0, 0, 0]);
    }
}
