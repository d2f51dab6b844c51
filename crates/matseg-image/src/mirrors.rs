//! Left-right and top-bottom mirrors of an image, as a mapping of pixel
//! coordinates: a texture is read through it instead of being copied.
//! (Quarter turns are a cached turned copy: `Photo::quarter_turned`.)

use serde::{Deserialize, Serialize};

/// A left-right mirror (`flip_x`), then a top-bottom mirror (`flip_y`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Mirrors {
    /// Mirrored left-right.
    pub flip_x: bool,
    /// Mirrored top-bottom.
    pub flip_y: bool,
}

impl Mirrors {
    /// For pixel `(x, y)` of the mirrored `w x h` image: the pixel of the
    /// original it shows.
    #[inline]
    pub fn source(&self, x: usize, y: usize, w: usize, h: usize) -> (usize, usize) {
        (
            if self.flip_x { w - 1 - x } else { x },
            if self.flip_y { h - 1 - y } else { y },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    #[test]
    fn source_pixels_match_image_flips() {
        let img = RgbImage::from_fn(40, 33, |x, y| image::Rgb([x as u8, y as u8, 7]));
        for bits in 0..4 {
            let m = Mirrors {
                flip_x: bits & 1 != 0,
                flip_y: bits & 2 != 0,
            };
            let mut want = img.clone();
            if m.flip_x {
                image::imageops::flip_horizontal_in_place(&mut want);
            }
            if m.flip_y {
                image::imageops::flip_vertical_in_place(&mut want);
            }
            for (x, y, px) in want.enumerate_pixels() {
                let (sx, sy) = m.source(x as usize, y as usize, 40, 33);
                assert_eq!(img.get_pixel(sx as u32, sy as u32), px, "{m:?} ({x}, {y})");
            }
        }
    }
}
