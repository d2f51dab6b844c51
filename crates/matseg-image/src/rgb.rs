//! Float RGB images (values on the 0..255 scale) for composition.

use crate::plane::round_to_u8;
use image::RgbImage;

/// A row-major RGB image with `f32` channels on the 0..255 scale.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbF32 {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` pixels, row by row.
    pub data: Vec<[f32; 3]>,
}

impl RgbF32 {
    /// An image filled with one colour.
    pub fn filled(width: usize, height: usize, color: [f32; 3]) -> Self {
        Self {
            width,
            height,
            data: vec![color; width * height],
        }
    }

    /// Converts an 8-bit RGB image.
    pub fn from_rgb8(img: &RgbImage) -> Self {
        let data = img
            .pixels()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect();
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            data,
        }
    }

    /// Rounds and clamps to an 8-bit RGB image.
    pub fn to_rgb8(&self) -> RgbImage {
        let mut raw = Vec::with_capacity(self.data.len() * 3);
        for px in &self.data {
            for &c in px {
                raw.push(round_to_u8(c));
            }
        }
        RgbImage::from_raw(self.width as u32, self.height as u32, raw)
            .expect("buffer length matches the image size")
    }
}
