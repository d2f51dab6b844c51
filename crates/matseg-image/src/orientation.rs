//! Quarter turns and mirrors of an image, as a mapping of pixel coordinates:
//! a texture is read through it instead of being copied.

use serde::{Deserialize, Serialize};

/// A 90° counter-clockwise turn (if `rot90`), then a left-right mirror
/// (`flip_x`), then a top-bottom mirror (`flip_y`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Orientation {
    /// Turned by 90° counter-clockwise first.
    pub rot90: bool,
    /// Then mirrored left-right.
    pub flip_x: bool,
    /// Then mirrored top-bottom.
    pub flip_y: bool,
}

impl Orientation {
    /// The size of a `w x h` image after the orientation.
    pub fn oriented_size(&self, w: usize, h: usize) -> (usize, usize) {
        if self.rot90 {
            (h, w)
        } else {
            (w, h)
        }
    }

    /// For pixel `(x, y)` of the oriented image, of size `w x h`: the pixel of
    /// the original image it shows.
    #[inline]
    pub fn source(&self, x: usize, y: usize, w: usize, h: usize) -> (usize, usize) {
        let x = if self.flip_x { w - 1 - x } else { x };
        let y = if self.flip_y { h - 1 - y } else { y };
        if self.rot90 {
            // The original is h wide; its column h - 1 - y became row y.
            (h - 1 - y, x)
        } else {
            (x, y)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    #[test]
    fn source_pixels_match_image_rotations_and_flips() {
        let img = RgbImage::from_fn(40, 33, |x, y| image::Rgb([x as u8, y as u8, 7]));
        for bits in 0..8 {
            let o = Orientation {
                rot90: bits & 1 != 0,
                flip_x: bits & 2 != 0,
                flip_y: bits & 4 != 0,
            };
            let mut want = if o.rot90 {
                image::imageops::rotate270(&img)
            } else {
                img.clone()
            };
            if o.flip_x {
                image::imageops::flip_horizontal_in_place(&mut want);
            }
            if o.flip_y {
                image::imageops::flip_vertical_in_place(&mut want);
            }
            let (w, h) = o.oriented_size(40, 33);
            assert_eq!((w as u32, h as u32), want.dimensions());
            for (x, y, px) in want.enumerate_pixels() {
                let (sx, sy) = o.source(x as usize, y as usize, w, h);
                assert_eq!(img.get_pixel(sx as u32, sy as u32), px, "{o:?} ({x}, {y})");
            }
        }
    }
}
